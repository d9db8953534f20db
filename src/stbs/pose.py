"""Poses of a skeleton: per-bone rotation, posed start joint, stretch and twist."""

from __future__ import annotations

import numpy as np

from . import _checks
from . import transforms as tf
from .skeleton import Skeleton

__all__ = ["Pose", "forward_kinematics", "fk_arrays", "local_arrays", "joint_twists"]


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

    @classmethod
    def from_local(cls, sk: Skeleton, rotations=None, *, stretch=None, twist=None,
                   offsets=None) -> Pose:
        """Pose from the local (forward-kinematics) frame: the inverse of :meth:`local`.

        Parameters
        ----------
        rotations : (b, d, d) float, optional
            Each bone's rotation in the frame its parent carries it in (world for a
            root); identity by default. 2D also accepts (b,) angles.
        stretch : (b,) float, optional
        twist : (b, 2) float, optional
            Each bone's own twist angles at its start and end (radians), on top of the
            frame it inherits.
        offsets : (b, d) float, optional
            Each bone's start offset, in that frame (world for a root).
        """
        sk = _check_skeleton(sk)
        b, d = sk.n_bones, sk.dim
        L = np.tile(np.eye(d), (b, 1, 1)) if rotations is None else _rotations(
            "rotations", rotations, b, d)
        sigma = np.ones(b) if stretch is None else _checks.real_array("stretch", stretch,
                                                                       shape=(b,))
        theta = np.zeros((b, 2)) if twist is None else _checks.real_array("twist", twist,
                                                                          shape=(b, 2))
        D = np.zeros((b, d)) if offsets is None else _checks.real_array("offsets", offsets,
                                                                         shape=(b, d))
        if np.any(sigma <= 0):
            i = int(np.argmin(sigma))
            raise ValueError(f"stretch must be > 0, got {sigma[i]:.6g} for bone {i} "
                             f"({sk.names[i]!r})")
        R, O = fk_arrays(sk, L, sigma, theta, D)
        return cls(sk, rotations=R, origins=O, stretch=sigma, twist=theta)

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

        Interpolated in the local (forward-kinematics) frame, as glTF, BVH and USD
        animation do: each bone's rotation relative to its parent's frame is slerped
        along the shortest arc; stretch, twist (past 360 degrees kept) and each bone's
        offset from where it hangs are interpolated linearly; forward kinematics then
        builds the pose, so chains never tear or shrink in between.
        """
        _check_same_skeleton(self, other)
        t = float(t)
        if not np.isfinite(t):
            raise ValueError(f"t must be finite, got {t}")
        sk = self.skeleton
        L0, D0 = self.local()
        L1, D1 = other.local()
        L = tf.matrix_slerp(L0, L1, t)
        sigma = (1 - t) * self.stretch + t * other.stretch
        theta = (1 - t) * self.twist + t * other.twist
        R, O = fk_arrays(sk, L, sigma, theta, (1 - t) * D0 + t * D1)
        return Pose(sk, rotations=R, origins=O, stretch=sigma, twist=theta)

    def local(self) -> tuple[np.ndarray, np.ndarray]:
        """This pose in the local (forward-kinematics) frame.

        Returns
        -------
        rotations : (b, d, d) float
            Each bone's rotation in the frame it hangs in, ``F_p^T R_i`` with
            ``F_p = R_p K_p(t_c)`` (``R_i`` for a root).
        offsets : (b, d) float
            How far each bone's start lies from where its parent carries it, in that
            frame: ``F_p^T (a'_i - a'_p) - t_c s_p - (a_i - a_p)`` (``a'_i - a_i`` for a
            root); zero for every bone of a pose made by forward kinematics without
            per-bone translation.

        :func:`fk_arrays` with these, the stretch and the twist gives the pose back.
        """
        return local_arrays(self.skeleton, self.rotations, self.origins, self.stretch,
                            self.twist)

    def __repr__(self) -> str:
        return f"Pose({self.skeleton!r})"


def pose_list(poses, sk: Skeleton, *, name: str = "poses") -> list[Pose]:
    """``poses`` as a non-empty list of poses of ``sk``, checked (TypeError: not a
    sequence of :class:`Pose`; ValueError: empty, or a pose of another skeleton)."""
    if isinstance(poses, Pose) or isinstance(poses, (str, bytes)) or not hasattr(
            poses, "__iter__"):
        raise TypeError(f"{name} must be a sequence of stbs.Pose, got "
                        f"{type(poses).__name__}" + ("; wrap a single Pose in a list"
                                                     if isinstance(poses, Pose) else ""))
    poses = list(poses)
    if not poses:
        raise ValueError(f"{name} must hold at least one stbs.Pose, got none")
    for k, pose in enumerate(poses):
        if not isinstance(pose, Pose):
            raise TypeError(f"{name}[{k}] must be a stbs.Pose, got {type(pose).__name__}")
        if pose.skeleton != sk:
            raise ValueError(f"{name}[{k}] must be a pose of the skeleton {sk!r}, got a pose "
                             f"of {pose.skeleton!r}")
    return poses


def _hang_frames(sk: Skeleton, R, theta, idx) -> np.ndarray:
    """(..., k, d, d) frames ``F_p = R_p K_p(t_c)`` the bones ``idx`` hang in."""
    p = sk.parents[idx]
    F = R[..., p, :, :]
    if sk.dim == 3:
        t = sk.hang[idx]
        ang = (1 - t) * theta[..., p, 0] + t * theta[..., p, 1]
        if np.any(ang):         # untwisted: K_p is the identity, F_p = R_p exactly
            F = F @ tf.axis_angle_to_matrix(sk.axes[p], ang)
    return F


def fk_arrays(sk: Skeleton, L, sigma, theta, D) -> tuple[np.ndarray, np.ndarray]:
    """Forward kinematics on arrays, batched over any leading axes (DESIGN §2, way 3).

    A root bone turns by ``L_i`` about its start and moves by ``D_i``; a child hangs in
    its parent's frame ``F_p = R_p K_p(t_c)`` at ``t_c`` (:attr:`Skeleton.hang`):
    ``R_i = F_p L_i`` and ``a'_i = a'_p + F_p (t_c s_p + a_i - a_p + D_i)``. Bones are
    computed a depth level at a time, every batch entry at once.

    Parameters
    ----------
    sk : Skeleton
    L : (..., b, d, d) float
        Local rotations.
    sigma : (..., b) float
        Stretches.
    theta : (..., b, 2) float
        Twist angles (radians) at each bone's start and end.
    D : (..., b, d) float
        Offsets of the bones' starts (see :meth:`Pose.local`).

    Returns
    -------
    R : (..., b, d, d) float
        World rotations ``R_i``.
    origins : (..., b, d) float
        Posed starts ``a'_i``.
    """
    L = np.asarray(L, dtype=float)
    sigma = np.asarray(sigma, dtype=float)
    D = np.asarray(D, dtype=float)
    theta = np.asarray(theta, dtype=float)
    A, vec = sk.A, sk.B - sk.A
    R = np.empty(L.shape)
    O = np.empty(D.shape)
    levels = sk.levels()
    r = levels[0]
    R[..., r, :, :] = L[..., r, :, :]
    O[..., r, :] = A[r] + D[..., r, :]
    for idx in levels[1:]:
        p = sk.parents[idx]
        F = _hang_frames(sk, R, theta, idx)
        rel = (sk.hang[idx, None] * (sigma[..., p, None] - 1) * vec[p] + (A[idx] - A[p])
               + D[..., idx, :])
        O[..., idx, :] = O[..., p, :] + np.einsum("...bij,...bj->...bi", F, rel)
        R[..., idx, :, :] = F @ L[..., idx, :, :]
    return R, O


def local_arrays(sk: Skeleton, R, origins, sigma, theta) -> tuple[np.ndarray, np.ndarray]:
    """Poses (batched over leading axes) in the local frame: the inverse of
    :func:`fk_arrays`. See :meth:`Pose.local`.

    Returns
    -------
    L : (..., b, d, d) float
    D : (..., b, d) float
    """
    R = np.asarray(R, dtype=float)
    O = np.asarray(origins, dtype=float)
    sigma = np.asarray(sigma, dtype=float)
    A, vec = sk.A, sk.B - sk.A
    L = R.copy()
    D = O - A
    idx = np.flatnonzero(sk.parents >= 0)
    if idx.size:
        p = sk.parents[idx]
        F = _hang_frames(sk, R, theta, idx)
        Ft = np.swapaxes(F, -1, -2)
        L[..., idx, :, :] = Ft @ R[..., idx, :, :]
        D[..., idx, :] = (np.einsum("...bij,...bj->...bi", Ft, O[..., idx, :] - O[..., p, :])
                          - sk.hang[idx, None] * (sigma[..., p, None] - 1) * vec[p]
                          - (A[idx] - A[p]))
    return L, D


def joint_twists(sk: Skeleton, twist) -> np.ndarray:
    """(..., b, 2) bone twists from (..., j) per-joint twists (see forward_kinematics)."""
    tau = np.asarray(twist, dtype=float)
    ends = np.zeros(sk.n_joints, dtype=bool)
    ends[sk.BE[:, 1]] = True
    theta = np.zeros(tau.shape[:-1] + (sk.n_bones, 2))
    free = ~ends[sk.BE[:, 0]]
    theta[..., free, 0] = tau[..., sk.BE[free, 0]]
    theta[..., 1] = theta[..., 0] + tau[..., sk.BE[:, 1]]
    return theta


def forward_kinematics(sk: Skeleton, rotations=None, stretch=None, twist=None,
                       translation=None) -> Pose:
    """Pose from local rotations, per-bone stretch, per-joint twist and a translation.

    Parameters
    ----------
    sk : Skeleton
    rotations : (b, d, d) float, optional
        Local rotation of each bone about its start joint, in the frame its parent
        carries it in (world frame for roots); identity by default. 2D also accepts
        (b,) angles.
    stretch : (b,) float, optional
        Per-bone stretch sigma_i; connected children start at the stretched parent's
        end, offset children where they hang on it (DESIGN §2).
    twist : (j,) float, optional
        Per-joint twist (radians, 3D only). A twist at joint J grows along the bone
        ending at J (theta_b) and is carried rigidly by every bone below J, because
        children inherit the parent's full end rotation ``R_p K_p(1)``.
        At a joint where no bone ends (a root's, an offset child's) it turns the
        bones starting there rigidly.
    translation : (d,) or (b, d) float, optional
        (d,): added to the start of every root bone. (b, d): each bone's own offset,
        world for a root, in the frame its parent carries it in for a child (an
        animated joint translation of glTF/BVH).

    Examples
    --------
    Turning the hips turns the leg hanging off them (an offset child):

    >>> import numpy as np
    >>> import stbs
    >>> sk = stbs.Skeleton([[0, 0, 0], [0, 1, 0], [0.2, 0, 0], [0.2, -1, 0]],
    ...                    [[0, 1], [2, 3]], P=[-1, 0])
    >>> Rz = np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1.0]])
    >>> pose = stbs.forward_kinematics(sk, rotations=[Rz, np.eye(3)])
    >>> np.round(pose.origins[1], 12).tolist(), np.round(pose.ends[1], 12).tolist()
    ([0.0, 0.2, 0.0], [1.0, 0.2, 0.0])
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
    D = np.zeros((b, d))
    if translation is not None:
        tr = np.asarray(translation, dtype=float) if not isinstance(
            translation, np.ndarray) else translation
        if np.ndim(tr) == 2:
            D = _checks.real_array("translation", tr, shape=(b, d)).copy()
        else:
            D[sk.roots] = _checks.real_array("translation", tr, shape=(d,))
    if np.any(sigma <= 0):
        i = int(np.argmin(sigma))
        raise ValueError(f"stretch must be > 0, got {sigma[i]:.6g} for bone {i} ({sk.names[i]!r})")
    theta = joint_twists(sk, tau)
    R, origins = fk_arrays(sk, L, sigma, theta, D)
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

