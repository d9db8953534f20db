"""Pose inputs of any parameterisation to 3D world arrays (``_core.PoseArrays``)."""

from __future__ import annotations

import array_api_compat
import numpy as np

from . import _backend as bk
from ._core import PoseArrays
from .rotations import angle_to_matrix, angle_to_quat, quat_normalize, rot6d_to_matrix


def _arr(xp, name, x, dtype, device):
    if x is None:
        return None
    if isinstance(x, (list, tuple)):
        x = np.asarray(x, dtype=float)
    if not hasattr(x, "shape"):
        raise TypeError(f"{name} must be an array, got {type(x).__name__}")
    x = bk.asarray(xp, x, dtype=dtype, device=device)
    if not bk.is_traced(x) and x.shape and bk.prod(x.shape) and not bool(
            xp.all(xp.isfinite(x))):
        raise ValueError(f"{name} must be finite, got NaN or infinity")
    return x


def _tail(name, x, tail: tuple, what: str) -> tuple:
    """The batch shape of ``x`` whose trailing axes must be ``tail``."""
    k = len(tail)
    if x.ndim < k or tuple(x.shape[x.ndim - k:]) != tail:
        raise ValueError(f"{name} must have shape (*B, {', '.join(map(str, tail))}) "
                         f"({what}), got {tuple(x.shape)}")
    return tuple(x.shape[:x.ndim - k])


def embed_matrices(xp, R):
    """(..., 2, 2) to (..., 3, 3) rotations about z."""
    z = xp.zeros_like(R[..., :, :1])
    top = xp.concat([R, z], axis=-1)
    last = xp.concat([xp.zeros_like(R[..., :1, :]), xp.ones_like(R[..., :1, :1])], axis=-1)
    return xp.concat([top, last], axis=-2)


def embed_points(xp, X):
    return xp.concat([X, xp.zeros_like(X[..., :1])], axis=-1)


def _rotation_inputs(xp, b, d, rotations, quaternions, angles, rot6d, dtype, device, shapes):
    """(R (..., 3, 3) or None, q (..., 4) or None) from the one rotation form given."""
    given = [k for k, v in (("rotations", rotations), ("quaternions", quaternions),
                            ("angles", angles), ("rot6d", rot6d)) if v is not None]
    if len(given) > 1:
        raise ValueError(f"give the rotations in one form only, got {' and '.join(given)}")
    if given and given[0] != "rotations" and (d == 3) != (given[0] != "angles"):
        want = "angles=(*B, b) or rotations=(*B, b, 2, 2)" if d == 2 else \
            "rotations, quaternions or rot6d"
        raise ValueError(f"{given[0]} do not fit a {d}D skeleton; give {want}")
    R = q = None
    if rotations is not None:
        R = _arr(xp, "rotations", rotations, dtype, device)
        shapes.append(("rotations", _tail("rotations", R, (b, d, d), "rotation matrices")))
        if d == 2:
            R = embed_matrices(xp, R)
    elif quaternions is not None:
        q = _arr(xp, "quaternions", quaternions, dtype, device)
        shapes.append(("quaternions", _tail("quaternions", q, (b, 4), "(w, x, y, z)")))
        q = quat_normalize(q, xp=xp)
    elif rot6d is not None:
        x6 = _arr(xp, "rot6d", rot6d, dtype, device)
        shapes.append(("rot6d", _tail("rot6d", x6, (b, 6), "6D rotations")))
        R = rot6d_to_matrix(x6, xp=xp)
    elif angles is not None:
        ang = _arr(xp, "angles", angles, dtype, device)
        shapes.append(("angles", _tail("angles", ang, (b,), "radians")))
        q = angle_to_quat(ang, xp=xp)
        R = embed_matrices(xp, angle_to_matrix(ang, xp=xp))
    return R, q


def pose_arrays(xp, b: int, d: int, A, *, rotations=None, origins=None, stretch=None,
                twist=None, quaternions=None, angles=None, rot6d=None, dtype=None,
                device=None):
    """Check and convert one batch of world poses; returns (PoseArrays, batch shape).

    ``A`` (b, d) backend array: the rest starts, used when ``origins`` is None.
    """
    shapes = []
    R, q = _rotation_inputs(xp, b, d, rotations, quaternions, angles, rot6d, dtype, device,
                            shapes)
    if origins is None:
        O = bk.asarray(xp, A, dtype=dtype, device=device)
    else:
        O = _arr(xp, "origins", origins, dtype, device)
        shapes.append(("origins", _tail("origins", O, (b, d), "posed start joints")))
    if d == 2:
        O = embed_points(xp, O)
    sigma = _arr(xp, "stretch", stretch, dtype, device)
    if sigma is not None:
        shapes.append(("stretch", _tail("stretch", sigma, (b,), "posed / rest length")))
        if not bk.is_traced(sigma) and bk.prod(sigma.shape) and bool(xp.any(sigma <= 0)):
            raise ValueError(f"stretch must be > 0, got {float(xp.min(sigma)):.6g}")
    theta = _arr(xp, "twist", twist, dtype, device)
    if theta is not None:
        shapes.append(("twist", _tail("twist", theta, (b, 2), "radians at start and end")))
        if d == 2:
            if bk.is_traced(theta) or bool(xp.any(theta != 0)):
                raise ValueError("twist must be 0 in 2D (bones of a 2D skeleton cannot "
                                 "twist), got a non-zero twist")
            theta = None
    batch = bk.broadcast_batch(shapes)
    if R is None and q is None:
        eye = xp.eye(3, dtype=O.dtype, device=array_api_compat.device(O))
        R = xp.broadcast_to(eye, batch + (b, 3, 3))
        q = None

    def bc(x, k):
        return None if x is None else xp.broadcast_to(x, batch + tuple(x.shape[x.ndim - k:]))

    return PoseArrays(bc(R, 3), bc(q, 2), bc(O, 2), bc(sigma, 1), bc(theta, 2)), batch
