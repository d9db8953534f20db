"""Poses of a skeleton: per-bone rotation, posed start joint, stretch and twist."""

from __future__ import annotations

import numpy as np

from . import _checks
from . import transforms as tf
from .skeleton import Skeleton

__all__ = ["Pose", "forward_kinematics"]


def _check_skeleton(sk) -> Skeleton:
    _checks.skeleton(sk)
    return sk


def _rotations(name: str, R, b: int, d: int) -> np.ndarray:
    """(b, d, d) proper rotations; in 2D (b,) angles are accepted too."""
    R = np.asarray(R, dtype=float) if not isinstance(R, np.ndarray) else R
    if d == 2 and np.ndim(R) == 1:
        R = tf.rotation_2d(_checks.real_array(name, R, shape=(b,)))
    R = _checks.real_array(name, R, shape=(b, d, d))
    err = np.abs(np.einsum("bij,bkj->bik", R, R) - np.eye(d)).max(axis=(1, 2))
    det = np.linalg.det(R)
    bad = np.flatnonzero((err > 1e-6) | (det < 0))
    if bad.size:
        i = int(bad[0])
        raise ValueError(f"{name}[{i}] must be a rotation (orthonormal, det +1), got "
                         f"orthonormality error {err[i]:.3g} and det {det[i]:.6g}")
    return R


def _check_same_skeleton(pose: Pose, other) -> None:
    if not isinstance(other, Pose):
        raise TypeError(f"other must be a stbs.Pose, got {type(other).__name__}")
    if other.skeleton != pose.skeleton:
        raise ValueError(f"other must be a pose of an equal skeleton (same joints, bones and "
                         f"names), got {other.skeleton!r} for {pose.skeleton!r}")


class Pose:
    """A pose: for each bone a rotation ``R_i``, posed start ``a'_i``, stretch and twist.

    Parameters
    ----------
    sk : Skeleton
    rotations : (b, d, d) float
        ``R_i``, taking the rest direction of bone i to its posed direction.
        In 2D, (b,) angles in radians are accepted.
    origins : (b, d) float
        Posed start joints ``a'_i``.
    stretch : (b,) float, optional
        ``sigma_i > 0``, posed length / rest length; default 1.
    twist : (b, 2) float, optional
        Twist angles (radians) at the start and end joint about the bone's own axis;
        default 0. Must be 0 in 2D.
    """

    def __init__(self, sk: Skeleton, *, rotations, origins, stretch=None, twist=None):
        sk = _check_skeleton(sk)
        b, d = sk.n_bones, sk.dim
        self.skeleton = sk
        self.rotations = _rotations("rotations", rotations, b, d)
        self.origins = _checks.real_array("origins", origins, shape=(b, d))
        if stretch is None:
            stretch = np.ones(b)
        self.stretch = _checks.real_array("stretch", stretch, shape=(b,))
        if np.any(self.stretch <= 0):
            i = int(np.argmin(self.stretch))
            raise ValueError(f"stretch must be > 0, got {self.stretch[i]:.6g} for bone {i} "
                             f"({sk.names[i]!r})")
        if twist is None:
            twist = np.zeros((b, 2))
        self.twist = _checks.real_array("twist", twist, shape=(b, 2))
        if d == 2 and np.any(self.twist != 0):
            i = int(np.flatnonzero(np.any(self.twist != 0, axis=1))[0])
            raise ValueError(f"twist must be 0 in 2D, got {self.twist[i].tolist()} for bone {i} "
                             f"({sk.names[i]!r})")
        for a in (self.rotations, self.origins, self.stretch, self.twist):
            a.setflags(write=False)

    # ------------------------------------------------------------------ constructors
    @classmethod
    def rest(cls, sk: Skeleton) -> Pose:
        """The rest pose: R = I, a' = a, sigma = 1, theta = 0."""
        sk = _check_skeleton(sk)
        return cls(sk, rotations=np.tile(np.eye(sk.dim), (sk.n_bones, 1, 1)), origins=sk.A)

    @classmethod
    def from_joints(cls, sk: Skeleton, C_posed, twist=None) -> Pose:
        """Pose from posed joint positions (dragging joints).

        Parameters
        ----------
        C_posed : (j, d) float
            Posed joint positions.
        twist : (b, 2) float, optional
            Twist angles in radians at each bone's start and end.
        """
        sk = _check_skeleton(sk)
        Cp = _checks.real_array("C_posed", C_posed, shape=(sk.n_joints, sk.dim))
        vec = Cp[sk.BE[:, 1]] - Cp[sk.BE[:, 0]]
        length = np.linalg.norm(vec, axis=1)
        zero = np.flatnonzero(length <= 1e-12 * max(float(np.abs(Cp).max()), 1.0))
        if zero.size:
            i = int(zero[0])
            raise ValueError(f"C_posed: bone {i} ({sk.names[i]!r}) has zero posed length; "
                             "its direction is undefined")
        R = tf.rotation_between(sk.B - sk.A, vec)
        return cls(sk, rotations=R, origins=Cp[sk.BE[:, 0]], stretch=length / sk.lengths,
                   twist=twist)

    # ------------------------------------------------------------------ derived
    @property
    def ends(self) -> np.ndarray:
        """(b, d) posed end joints ``b'_i = a'_i + sigma_i R_i (b_i - a_i)``."""
        sk = self.skeleton
        return self.origins + self.stretch[:, None] * np.einsum(
            "bij,bj->bi", self.rotations, sk.B - sk.A)

    def joints(self) -> np.ndarray:
        """(j, d) posed joint positions (mean over the bones touching a joint)."""
        sk = self.skeleton
        acc = np.zeros_like(sk.C)
        cnt = np.zeros(sk.n_joints)
        np.add.at(acc, sk.BE[:, 0], self.origins)
        np.add.at(acc, sk.BE[:, 1], self.ends)
        np.add.at(cnt, sk.BE.ravel(), 1.0)
        out = sk.C.copy()
        used = cnt > 0
        out[used] = acc[used] / cnt[used, None]
        return out

    def twist_rotations(self, t) -> np.ndarray:
        """(b, 3, 3) twist ``K_i(t)`` at parameter t (scalar or (b,)); identity in 2D."""
        sk = self.skeleton
        t = np.broadcast_to(np.asarray(t, dtype=float), (sk.n_bones,))
        ang = (1 - t) * self.twist[:, 0] + t * self.twist[:, 1]
        if sk.dim == 2:
            return np.tile(np.eye(2), (sk.n_bones, 1, 1))
        return tf.axis_angle_to_matrix(sk.axes, ang)

    def is_rest(self, *, tol: float = 0.0) -> bool:
        """True if this is the rest pose (to ``tol``)."""
        sk = self.skeleton
        return bool(np.abs(self.rotations - np.eye(sk.dim)).max() <= tol
                    and np.abs(self.origins - sk.A).max() <= tol
                    and np.abs(self.stretch - 1).max() <= tol
                    and np.abs(self.twist).max() <= tol)

    # ------------------------------------------------------------------ algebra
    def transformed(self, R, t) -> Pose:
        """This pose followed by the rigid motion ``x -> R x + t`` of the whole skeleton."""
        d = self.skeleton.dim
        R = _rotations("R", np.asarray(R, dtype=float)[None], 1, d)[0]
        t = _checks.real_array("t", t, shape=(d,))
        return Pose(self.skeleton, rotations=R @ self.rotations, origins=self.origins @ R.T + t,
                    stretch=self.stretch, twist=self.twist)

    def compose(self, other: Pose) -> Pose:
        """``other`` applied after this pose, bone by bone.

        Each bone's rigid part ``x -> a'_i + R_i (x - a_i)`` is composed as maps
        (``other``'s after ``self``'s); stretches multiply and twists add. Composing
        with the rest pose on either side gives the pose back.
        """
        _check_same_skeleton(self, other)
        A = self.skeleton.A
        R = np.einsum("bij,bjk->bik", other.rotations, self.rotations)
        origins = other.origins + np.einsum("bij,bj->bi", other.rotations, self.origins - A)
        return Pose(self.skeleton, rotations=R, origins=origins,
                    stretch=self.stretch * other.stretch, twist=self.twist + other.twist)

    def interpolate(self, other: Pose, t: float) -> Pose:
        """Pose at ``t`` in [0, 1] between this (t=0) and ``other`` (t=1).

        Rotations are slerped along the shortest arc; origins, stretch and twist are
        interpolated linearly (so twists past 360 degrees are kept, not wrapped).
        """
        _check_same_skeleton(self, other)
        t = float(t)
        if not np.isfinite(t):
            raise ValueError(f"t must be finite, got {t}")
        R = tf.matrix_slerp(self.rotations, other.rotations, t)
        return Pose(self.skeleton, rotations=R,
                    origins=(1 - t) * self.origins + t * other.origins,
                    stretch=(1 - t) * self.stretch + t * other.stretch,
                    twist=(1 - t) * self.twist + t * other.twist)

    def __repr__(self) -> str:
        return f"Pose({self.skeleton!r})"


def forward_kinematics(sk: Skeleton, rotations=None, stretch=None, twist=None,
                       translation=None) -> Pose:
    """Pose from local rotations, per-bone stretch, per-joint twist and a root translation.

    Parameters
    ----------
    sk : Skeleton
    rotations : (b, d, d) float, optional
        Local rotation of each bone about its start joint, in its parent's frame
        (world frame for roots); identity by default. 2D also accepts (b,) angles.
    stretch : (b,) float, optional
        Per-bone stretch sigma_i; children start at the stretched parent's end.
    twist : (j,) float, optional
        Per-joint twist (radians, 3D only). A twist at joint J grows along the bone
        ending at J (theta_b) and is carried rigidly by every bone below J, because
        children inherit the parent's full end rotation ``R_p K_p(1)``.
        At a root joint (where no bone ends) it turns the bones starting there rigidly.
    translation : (d,) float, optional
        Added to the start of every root bone.
    """
    sk = _check_skeleton(sk)
    b, d, j = sk.n_bones, sk.dim, sk.n_joints
    L = np.tile(np.eye(d), (b, 1, 1)) if rotations is None else _rotations(
        "rotations", rotations, b, d)
    sigma = np.ones(b) if stretch is None else _checks.real_array("stretch", stretch, shape=(b,))
    tau = np.zeros(j) if twist is None else _checks.real_array("twist", twist, shape=(j,))
    if d == 2 and np.any(tau != 0):
        raise ValueError(f"twist must be 0 in 2D, got {tau[np.flatnonzero(tau)[0]]:.6g} "
                         f"at joint {int(np.flatnonzero(tau)[0])}")
    shift = np.zeros(d) if translation is None else _checks.real_array(
        "translation", translation, shape=(d,))
    if np.any(sigma <= 0):
        i = int(np.argmin(sigma))
        raise ValueError(f"stretch must be > 0, got {sigma[i]:.6g} for bone {i} ({sk.names[i]!r})")
    A, vec = sk.A, sk.B - sk.A
    R = np.empty((b, d, d))
    origins = np.empty((b, d))
    # Twists do not depend on the rotations: theta_a is the root joint's twist (roots
    # only), theta_b adds the end joint's; all end twists K_i(1) in one batch.
    theta = np.zeros((b, 2))
    roots = sk.parents < 0
    theta[roots, 0] = tau[sk.BE[roots, 0]]
    theta[:, 1] = theta[:, 0] + tau[sk.BE[:, 1]]
    K = tf.axis_angle_to_matrix(sk.axes, theta[:, 1]) if d == 3 else None
    G = np.empty((b, d, d))  # full end rotation R_i K_i(1), inherited by children
    for i in sk.order:
        p = sk.parents[i]
        if p < 0:
            R[i] = L[i]
            origins[i] = A[i] + shift
        else:
            R[i] = G[p] @ L[i]
            origins[i] = origins[p] + sigma[p] * (R[p] @ vec[p])
        G[i] = R[i] @ K[i] if d == 3 else R[i]
    return Pose(sk, rotations=R, origins=origins, stretch=sigma, twist=theta)


def local_transforms(sk: Skeleton, rotations, origins=None):
    """Each bone's rotation, and posed start, in its parent bone's frame: the joint
    transforms of a scene graph (glTF nodes, USD joints) that give these world poses.

    Parameters
    ----------
    sk : Skeleton
    rotations : (..., b, d, d) float
        World rotations ``R_i`` (e.g. ``Pose.rotations``, or a stack of them).
    origins : (..., b, d) float, optional
        Posed starts ``a'_i``.

    Returns
    -------
    local_rotations : (..., b, d, d)
        ``R_p^T R_i`` (``R_i`` for a root).
    local_origins : (..., b, d), only with ``origins``
        ``R_p^T (a'_i - a'_p)`` (``a'_i`` for a root).
    """
    R = np.asarray(rotations, dtype=float)
    par = sk.parents
    has = par >= 0
    LR = R.copy()
    LR[..., has, :, :] = np.einsum("...bji,...bjk->...bik", R[..., par[has], :, :],
                                   R[..., has, :, :])
    if origins is None:
        return LR
    O = np.asarray(origins, dtype=float)
    LT = O.copy()
    LT[..., has, :] = np.einsum("...bji,...bj->...bi", R[..., par[has], :, :],
                                O[..., has, :] - O[..., par[has], :])
    return LR, LT

