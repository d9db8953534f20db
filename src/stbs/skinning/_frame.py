"""Per-frame, per-bone constants for the kernels (float64, b rows; cheap NumPy).

All tables are 3D: 2D rigs are embedded with z = 0 and rotations about z.
"""

from __future__ import annotations

import numpy as np

from .. import transforms as tf
from ..pose import Pose


def _embed(pose: Pose) -> tuple[np.ndarray, ...]:
    """Rest starts a, unit axes u, lengths l, rotations R, posed starts a' in 3D."""
    sk = pose.skeleton
    a, u, R, ap = sk.A, sk.axes, pose.rotations, pose.origins
    if sk.dim == 2:
        pad = np.zeros((sk.n_bones, 1))
        a, u, ap = (np.hstack([x, pad]) for x in (a, u, ap))
        R = tf.embed_rotation_2d(R)
    return a, u, sk.lengths, R, ap


def lbs_table(pose: Pose) -> np.ndarray:
    """(b, 16): columns of [A_i | t_i], each padded to 4 rows (eq. 1-3).

    A_i = R_i S_i and t_i = a'_i - A_i a_i; column c sits at ``[4c, 4c + 4)``.
    """
    a, u, _, R, ap = _embed(pose)
    S = np.eye(3) + (pose.stretch - 1.0)[:, None, None] * np.einsum("bi,bj->bij", u, u)
    A = R @ S
    t = ap - np.einsum("bij,bj->bi", A, a)
    T = np.zeros((len(a), 4, 4))
    T[:, :3, :3] = np.swapaxes(A, 1, 2)
    T[:, 3, :3] = t
    return np.ascontiguousarray(T.reshape(-1, 16))


def dqs_tables(pose: Pose) -> tuple[np.ndarray, np.ndarray, bool]:
    """(b, 8) rigid dual quaternions, (b, 7) stretch terms, and whether any bone stretches."""
    a, u, _, R, ap = _embed(pose)
    q = tf.matrix_to_quat(R)
    t = ap - np.einsum("bij,bj->bi", R, a)
    qr, qd = tf.dq_from_rt(q, t)
    Q = np.ascontiguousarray(np.hstack([qr, qd]))
    c = (pose.stretch - 1.0)[:, None] * u
    S = np.ascontiguousarray(np.hstack([c, u, np.sum(u * a, axis=1)[:, None]]))
    return Q, S, bool(np.any(pose.stretch != 1.0))


def _cross_matrix(u: np.ndarray) -> np.ndarray:
    X = np.zeros(u.shape[:-1] + (3, 3))
    X[..., 0, 1], X[..., 0, 2] = -u[..., 2], u[..., 1]
    X[..., 1, 0], X[..., 1, 2] = u[..., 2], -u[..., 0]
    X[..., 2, 0], X[..., 2, 1] = -u[..., 1], u[..., 0]
    return X


def stbs_lbs_table(pose: Pose) -> np.ndarray:
    """(b, 35) constants of eq. 5 (layout in ``_kernels.stbs_lbs``)."""
    a, u, ell, R, ap = _embed(pose)
    Ru = np.einsum("bij,bj->bi", R, u)
    RX = R @ _cross_matrix(u)
    st = ((pose.stretch - 1.0) * ell)[:, None] * Ru
    th = pose.twist
    return np.ascontiguousarray(np.hstack([
        R.reshape(-1, 9), RX.reshape(-1, 9), Ru, a, ap, st, u,
        th[:, :1], (th[:, 1] - th[:, 0])[:, None]]))


def stbs_dqs_table(pose: Pose) -> np.ndarray:
    """(b, 19) constants of eq. 6 in dual-quaternion bilinear form (``_kernels.stbs_dqs``).

    X = T(a') Rot(qR) = (R1, Xd); the map is X T(e s) Rot(qK) T(-a). With U = (0, u),
    alpha = -(0, a) / 2: R2 = R1 U, D1 = R1 alpha + Xd, D2 = R1 U alpha + Xd U,
    c = (sigma - 1) l / 2.
    """
    a, u, ell, R, ap = _embed(pose)
    zeros = np.zeros((len(u), 1))
    U = np.hstack([zeros, u])
    alpha = -0.5 * np.hstack([zeros, a])
    R1 = tf.matrix_to_quat(R)
    Xd = 0.5 * tf.quat_mul(np.hstack([zeros, ap]), R1)
    R2 = tf.quat_mul(R1, U)
    D1 = tf.quat_mul(R1, alpha) + Xd
    D2 = tf.quat_mul(R2, alpha) + tf.quat_mul(Xd, U)
    c = 0.5 * (pose.stretch - 1.0) * ell
    th = pose.twist
    return np.ascontiguousarray(np.hstack([
        R1, R2, D1, D2, c[:, None], 0.5 * th[:, :1], 0.5 * (th[:, 1] - th[:, 0])[:, None]]))
