"""Differentiable forward kinematics on the array API (DESIGN §2, way 3)."""

from __future__ import annotations

from typing import NamedTuple

import array_api_compat
import numpy as np

from .. import _checks
from . import _backend as bk
from ._inputs import _arr, _tail, embed_matrices
from .rotations import (
    angle_to_matrix,
    axis_angle_to_quat,
    quat_normalize,
    quat_to_matrix,
    rot6d_to_matrix,
)

__all__ = ["forward_kinematics", "rest_joints", "FKResult"]


class FKResult(NamedTuple):
    """World pose arrays from :func:`forward_kinematics`, ready for ``Skinner`` or ``skin``.

    Attributes
    ----------
    rotations : (*B, b, d, d)
        World rotations ``R_i``.
    origins : (*B, b, d)
        Posed start joints ``a'_i``.
    stretch : (*B, b)
    twist : (*B, b, 2)
        Per-bone twist angles at start and end (radians); zeros in 2D.
    """

    rotations: object
    origins: object
    stretch: object
    twist: object


def _skeleton(sk):
    _checks.skeleton(sk)
    return sk


def rest_joints(sk, lengths, *, C=None, backend=None):
    """Rest joint positions (j, d) of ``sk`` with its bones resized to ``lengths``.

    Each bone keeps its rest direction; a bone's end joint sits ``lengths[i]`` along it
    from its start, a connected child starts there, an offset child keeps its offset
    from the point where it hangs on its parent (at the same fraction ``t_c`` of the
    parent's length), and the start joints of root bones stay put. Differentiable with
    respect to ``lengths`` (and ``C``).

    Parameters
    ----------
    sk : Skeleton
    lengths : (b,) float array
        New bone lengths (> 0).
    C : (j, d) float array, optional
        Rest joints to resize instead of ``sk.C`` (same bones).
    backend : str or module, optional
        Inferred from ``lengths`` and ``C`` when None.

    Returns
    -------
    C : (j, d) float array of the backend
    """
    sk = _skeleton(sk)
    xp = bk.namespace(backend, lengths, C)
    L = _arr(xp, "lengths", lengths, None, None)
    if tuple(L.shape) != (sk.n_bones,):
        raise ValueError(f"lengths must have shape ({sk.n_bones},), got {tuple(L.shape)}")
    C0 = bk.asarray(xp, sk.C if C is None else C, dtype=L.dtype)
    if tuple(C0.shape) != sk.C.shape:
        raise ValueError(f"C must have shape {sk.C.shape}, got {tuple(C0.shape)}")
    BE, par = sk.BE, sk.parents
    vec = xp.take(C0, bk.index(xp, BE[:, 1], C0), axis=0) - xp.take(
        C0, bk.index(xp, BE[:, 0], C0), axis=0)
    u = vec / xp.sqrt(xp.sum(vec * vec, axis=-1, keepdims=True))
    joint = {}
    for level in sk.levels():
        for i in (int(x) for x in level):
            a_j, b_j = int(BE[i, 0]), int(BE[i, 1])
            if a_j not in joint:
                p = int(par[i])
                if p < 0:
                    joint[a_j] = C0[a_j, :]
                else:
                    t = float(sk.hang[i])
                    hang_old = C0[int(BE[p, 0]), :] + t * vec[p, :]
                    joint[a_j] = joint[int(BE[p, 0])] + t * L[p] * u[p, :] + (
                        C0[a_j, :] - hang_old)
            joint[b_j] = joint[a_j] + L[i] * u[i, :]
    rows = [joint.get(j, C0[j, :]) for j in range(sk.n_joints)]
    return xp.stack(rows, axis=0)


def _local_rotations(xp, sk, rotations, quaternions, rot6d, dtype, device):
    b, d = sk.n_bones, sk.dim
    if sum(x is not None for x in (rotations, quaternions, rot6d)) > 1:
        raise ValueError("give the local rotations in one form only (rotations, "
                         "quaternions or rot6d)")
    if quaternions is not None:
        q = _arr(xp, "quaternions", quaternions, dtype, device)
        return quat_to_matrix(quat_normalize(q, xp=xp), xp=xp), _tail(
            "quaternions", q, (b, 4), "(w, x, y, z)")
    if rot6d is not None:
        x6 = _arr(xp, "rot6d", rot6d, dtype, device)
        return rot6d_to_matrix(x6, xp=xp), _tail("rot6d", x6, (b, 6), "6D rotations")
    if rotations is None:
        return None, ()
    L = _arr(xp, "rotations", rotations, dtype, device)
    if d == 2 and L.ndim >= 1 and L.shape[-1] == b and not (
            L.ndim >= 3 and tuple(L.shape[-3:]) == (b, 2, 2)):
        batch = _tail("rotations", L, (b,), "2D angles")
        return embed_matrices(xp, angle_to_matrix(L, xp=xp)), batch
    batch = _tail("rotations", L, (b, d, d), "local rotation matrices, or 2D angles (*B, b)")
    return (embed_matrices(xp, L) if d == 2 else L), batch


def forward_kinematics(sk, rotations=None, stretch=None, twist=None, translation=None, *,
                       quaternions=None, rot6d=None, lengths=None, C=None, backend=None,
                       dtype=None, device=None) -> FKResult:
    """World pose arrays from local rotations, per-bone stretch, per-joint twist and a
    translation, batched over leading axes ``*B`` and differentiable in every input.

    Equals :func:`stbs.forward_kinematics` (children hang in their parent's frame
    ``F_p = R_p K_p(t_c)``, offset children where they hang; a twist at a joint grows
    along the bone ending there and is carried rigidly below it).

    Parameters
    ----------
    sk : Skeleton
        Fixes the bones, the hierarchy and where each child hangs (``sk.hang``, static).
    rotations : (*B, b, d, d) float, optional
        Local rotation of each bone about its start, in the frame its parent carries it
        in (world for roots); identity by default. 2D also takes (*B, b) angles.
    stretch : (*B, b) float, optional
    twist : (*B, j) float, optional
        Per-joint twist in radians (3D only); any angle, past 2 pi included.
    translation : (*B, d) or (*B, b, d) float, optional
        Added to the start of every root bone, or each bone's own offset (in the frame
        its parent carries it in). It is per bone when its last two axes are (b, d) and
        it has at least as many leading axes as the other inputs.
    quaternions : (*B, b, 4) float, optional
        Local rotations as (w, x, y, z) quaternions (normalised here), instead of
        ``rotations``.
    rot6d : (*B, b, 6) float, optional
        Local rotations in the 6D form (:func:`rot6d_to_matrix`).
    lengths : (b,) float, optional
        Rest bone lengths to use instead of the skeleton's (see :func:`rest_joints`).
    C : (j, d) float, optional
        Rest joint positions to use instead of ``sk.C`` (a differentiable array).
    backend, dtype, device
        As for :class:`Skinner`; inferred from the arrays when None.

    Returns
    -------
    FKResult
        ``(rotations (*B, b, d, d), origins (*B, b, d), stretch (*B, b),
        twist (*B, b, 2))``; pass them on as
        ``skinner(*fk)`` or ``skin(V, C, BE, W, E, *fk)``.
    """
    sk = _skeleton(sk)
    b, d, j = sk.n_bones, sk.dim, sk.n_joints
    xp = bk.namespace(backend, rotations, quaternions, rot6d, stretch, twist, translation,
                      lengths, C)
    like = next((x for x in (rotations, quaternions, rot6d, stretch, twist, translation,
                             lengths, C) if x is not None and hasattr(x, "dtype")), None)
    dtype = bk.float_dtype(xp, dtype, like)
    L, batch_l = _local_rotations(xp, sk, rotations, quaternions, rot6d, dtype, device)
    shapes = [("rotations", batch_l)]
    sigma = _arr(xp, "stretch", stretch, dtype, device)
    if sigma is not None:
        shapes.append(("stretch", _tail("stretch", sigma, (b,), "per bone")))
    tau = _arr(xp, "twist", twist, dtype, device)
    if tau is not None:
        shapes.append(("twist", _tail("twist", tau, (j,), "per joint, radians")))
        if d == 2 and (bk.is_traced(tau) or bool(xp.any(tau != 0))):
            raise ValueError("twist must be 0 in 2D, got a non-zero twist")
    D = _arr(xp, "translation", translation, dtype, device)
    per_bone = False
    if D is not None:
        others = bk.broadcast_batch(shapes)
        per_bone = D.ndim >= 2 and tuple(D.shape[-2:]) == (b, d) and D.ndim - 2 >= len(others)
        shapes.append(("translation", _tail("translation", D, (b, d) if per_bone else (d,),
                                            "root or per-bone translation")))
    batch = bk.broadcast_batch(shapes)
    if C is None and lengths is None:
        C0 = bk.asarray(xp, sk.C, dtype=dtype, device=device)
    elif lengths is not None:
        C0 = rest_joints(sk, _arr(xp, "lengths", lengths, dtype, device),
                         C=None if C is None else _arr(xp, "C", C, dtype, device),
                         backend=xp)
    else:
        C0 = _arr(xp, "C", C, dtype, device)
        if tuple(C0.shape) != sk.C.shape:
            raise ValueError(f"C must have shape {sk.C.shape}, got {tuple(C0.shape)}")
    return _fk(xp, sk, C0, L, sigma, tau, D, per_bone, batch, dtype)


def _fk(xp, sk, C0, L, sigma, tau, D, per_bone, batch, dtype):
    b, d = sk.n_bones, sk.dim
    if d == 2:
        C0 = xp.concat([C0, xp.zeros_like(C0[:, :1])], axis=-1)
        if D is not None:
            D = xp.concat([D, xp.zeros_like(D[..., :1])], axis=-1)
    BE = sk.BE
    A = xp.take(C0, bk.index(xp, BE[:, 0], C0), axis=0)
    vec = xp.take(C0, bk.index(xp, BE[:, 1], C0), axis=0) - A
    u = vec / xp.sqrt(xp.sum(vec * vec, axis=-1, keepdims=True))
    eye = xp.eye(3, dtype=dtype, device=array_api_compat.device(C0))
    theta = None
    if tau is not None and d == 3:
        # per-joint twist to per-bone (theta_a, theta_b), as stbs.pose.joint_twists
        ends = np.zeros(sk.n_joints, dtype=bool)
        ends[BE[:, 1]] = True
        free = ~ends[BE[:, 0]]
        ta = xp.where(xp.asarray(free, device=array_api_compat.device(tau)),
                      xp.take(tau, bk.index(xp, BE[:, 0], tau), axis=-1),
                      xp.zeros_like(tau[..., :1]))
        theta = xp.stack([ta, ta + xp.take(tau, bk.index(xp, BE[:, 1], tau), axis=-1)], axis=-1)
        theta = xp.broadcast_to(theta, batch + (b, 2))
    Rs, Os = [None] * b, [None] * b
    for level in sk.levels():
        for i in (int(x) for x in level):
            Li = eye if L is None else L[..., i, :, :]
            Di = None
            if D is not None:
                Di = D[..., i, :] if per_bone else (D if sk.parents[i] < 0 else None)
            p = int(sk.parents[i])
            if p < 0:
                Rs[i] = xp.broadcast_to(Li, batch + (3, 3))
                Os[i] = xp.broadcast_to(A[i, :] if Di is None else A[i, :] + Di, batch + (3,))
                continue
            t = float(sk.hang[i])
            F = Rs[p]
            if theta is not None:
                ang = (1.0 - t) * theta[..., p, 0] + t * theta[..., p, 1]
                K = quat_to_matrix(axis_angle_to_quat(u[p, :], ang, xp=xp), xp=xp)
                F = F @ K
            rel = A[i, :] - A[p, :]
            if t != 0.0 and sigma is not None:
                rel = rel + (t * (sigma[..., p] - 1.0))[..., None] * vec[p, :]
            if Di is not None:
                rel = rel + Di
            Os[i] = Os[p] + xp.sum(F * rel[..., None, :], axis=-1)
            Rs[i] = F @ Li
    R = xp.stack(Rs, axis=-3)
    O = xp.stack(Os, axis=-2)
    if d == 2:
        R, O = R[..., :2, :2], O[..., :2]
    ones = xp.ones(batch + (b,), dtype=dtype)
    S = ones if sigma is None else xp.broadcast_to(sigma, batch + (b,))
    Th = xp.zeros(batch + (b, 2), dtype=dtype) if theta is None else theta
    return FKResult(R, O, S, Th)
