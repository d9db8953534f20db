"""Batched rotations, quaternions and unit dual quaternions.

Conventions: quaternions are ``(w, x, y, z)``, scalar first; points are
row vectors; every function accepts arbitrary leading batch axes.
A unit dual quaternion is a pair ``(qr, qd)`` of (..., 4) arrays with
``qd = 0.5 * (0, t) * qr`` for the rigid map ``x -> R x + t``.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "quat_mul", "quat_conj", "quat_normalize", "quat_to_matrix", "matrix_to_quat",
    "axis_angle_to_quat", "axis_angle_to_matrix", "quat_to_axis_angle", "quat_slerp",
    "rotation_between", "rotation_2d", "angle_2d", "embed_rotation_2d",
    "dq_from_rt", "dq_to_rt", "dq_mul", "dq_apply", "dq_normalize", "dq_blend",
    "rotate", "matrix_slerp",
]


def quat_mul(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product ``p * q`` of (..., 4) quaternions."""
    p = np.asarray(p, dtype=float)
    q = np.asarray(q, dtype=float)
    pw, px, py, pz = np.moveaxis(p, -1, 0)
    qw, qx, qy, qz = np.moveaxis(q, -1, 0)
    return np.stack([
        pw * qw - px * qx - py * qy - pz * qz,
        pw * qx + px * qw + py * qz - pz * qy,
        pw * qy - px * qz + py * qw + pz * qx,
        pw * qz + px * qy - py * qx + pz * qw,
    ], axis=-1)


def quat_conj(q: np.ndarray) -> np.ndarray:
    """Conjugate ``(w, -x, -y, -z)``."""
    q = np.asarray(q, dtype=float)
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def quat_normalize(q: np.ndarray) -> np.ndarray:
    """Unit quaternions; raises ``ValueError`` on a zero quaternion."""
    q = np.asarray(q, dtype=float)
    n = np.linalg.norm(q, axis=-1, keepdims=True)
    if np.any(n == 0):
        raise ValueError("quaternion must be non-zero, got (0, 0, 0, 0)")
    return q / n


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """(..., 4) unit quaternions to (..., 3, 3) rotation matrices."""
    q = quat_normalize(q)
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], axis=-2)


def matrix_to_quat(R: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotations to (..., 4) unit quaternions with ``w >= 0``.

    Shepperd's method: pick the largest of the four squared components to divide by,
    so it stays accurate near 180 degrees.
    """
    R = np.asarray(R, dtype=float)
    m = R.reshape(-1, 3, 3)
    tr = m[:, 0, 0] + m[:, 1, 1] + m[:, 2, 2]
    cand = np.stack([tr, m[:, 0, 0], m[:, 1, 1], m[:, 2, 2]], axis=-1)
    k = np.argmax(cand, axis=-1)
    q = np.empty((m.shape[0], 4))
    r = np.arange(m.shape[0])
    s = np.sqrt(np.maximum(1.0 + 2.0 * cand[r, k] - tr, 1e-300)) * 2.0  # 4 * |largest|
    # k == 0: w largest
    i0 = k == 0
    q[i0, 0] = 0.25 * s[i0]
    q[i0, 1] = (m[i0, 2, 1] - m[i0, 1, 2]) / s[i0]
    q[i0, 2] = (m[i0, 0, 2] - m[i0, 2, 0]) / s[i0]
    q[i0, 3] = (m[i0, 1, 0] - m[i0, 0, 1]) / s[i0]
    i1 = k == 1
    q[i1, 0] = (m[i1, 2, 1] - m[i1, 1, 2]) / s[i1]
    q[i1, 1] = 0.25 * s[i1]
    q[i1, 2] = (m[i1, 0, 1] + m[i1, 1, 0]) / s[i1]
    q[i1, 3] = (m[i1, 0, 2] + m[i1, 2, 0]) / s[i1]
    i2 = k == 2
    q[i2, 0] = (m[i2, 0, 2] - m[i2, 2, 0]) / s[i2]
    q[i2, 1] = (m[i2, 0, 1] + m[i2, 1, 0]) / s[i2]
    q[i2, 2] = 0.25 * s[i2]
    q[i2, 3] = (m[i2, 1, 2] + m[i2, 2, 1]) / s[i2]
    i3 = k == 3
    q[i3, 0] = (m[i3, 1, 0] - m[i3, 0, 1]) / s[i3]
    q[i3, 1] = (m[i3, 0, 2] + m[i3, 2, 0]) / s[i3]
    q[i3, 2] = (m[i3, 1, 2] + m[i3, 2, 1]) / s[i3]
    q[i3, 3] = 0.25 * s[i3]
    q *= np.where(q[:, :1] < 0, -1.0, 1.0)
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    return q.reshape(R.shape[:-2] + (4,))


def axis_angle_to_quat(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rotation by ``angle`` (radians) about ``axis`` (..., 3; normalised here)."""
    axis = np.asarray(axis, dtype=float)
    n = np.linalg.norm(axis, axis=-1, keepdims=True)
    if np.any(n == 0):
        raise ValueError("axis must be non-zero, got a zero vector")
    half = 0.5 * np.asarray(angle, dtype=float)[..., None]
    return np.concatenate([np.cos(half), np.sin(half) * axis / n], axis=-1)


def axis_angle_to_matrix(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation by ``angle`` about ``axis``."""
    return quat_to_matrix(axis_angle_to_quat(axis, angle))


def quat_to_axis_angle(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit axis (..., 3) and angle in [0, pi] (...,); axis is x for the identity."""
    q = quat_normalize(q)
    q = q * np.where(q[..., :1] < 0, -1.0, 1.0)
    v = q[..., 1:]
    s = np.linalg.norm(v, axis=-1)
    angle = 2.0 * np.arctan2(s, q[..., 0])
    axis = np.where(s[..., None] > 1e-300, v / np.maximum(s, 1e-300)[..., None],
                    np.array([1.0, 0.0, 0.0]))
    return axis, angle


def quat_slerp(q0: np.ndarray, q1: np.ndarray, t) -> np.ndarray:
    """Shortest-path spherical interpolation between unit quaternions."""
    q0 = quat_normalize(q0)
    q1 = quat_normalize(q1)
    t = np.asarray(t, dtype=float)[..., None]
    d = np.sum(q0 * q1, axis=-1, keepdims=True)
    q1 = np.where(d < 0, -q1, q1)
    d = np.abs(d)
    theta = np.arccos(np.clip(d, -1.0, 1.0))
    sin_t = np.sin(theta)
    small = sin_t < 1e-8
    safe = np.where(small, 1.0, sin_t)
    a = np.where(small, 1.0 - t, np.sin((1.0 - t) * theta) / safe)
    b = np.where(small, t, np.sin(t * theta) / safe)
    return quat_normalize(a * q0 + b * q1)


def rotation_2d(angle) -> np.ndarray:
    """(..., 2, 2) counter-clockwise rotation by ``angle``."""
    angle = np.asarray(angle, dtype=float)
    c, s = np.cos(angle), np.sin(angle)
    return np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)


def angle_2d(R: np.ndarray) -> np.ndarray:
    """Angle of (..., 2, 2) rotations."""
    R = np.asarray(R, dtype=float)
    return np.arctan2(R[..., 1, 0], R[..., 0, 0])


def embed_rotation_2d(R: np.ndarray) -> np.ndarray:
    """(..., 2, 2) rotations as (..., 3, 3) rotations about z."""
    R = np.asarray(R, dtype=float)
    out = np.zeros(R.shape[:-2] + (3, 3))
    out[..., :2, :2] = R
    out[..., 2, 2] = 1.0
    return out


def matrix_slerp(R0: np.ndarray, R1: np.ndarray, t) -> np.ndarray:
    """Interpolate (..., d, d) rotations (d = 2 or 3) along the shortest arc."""
    R0 = np.asarray(R0, dtype=float)
    R1 = np.asarray(R1, dtype=float)
    if R0.shape[-1] == 2:
        a0, a1 = angle_2d(R0), angle_2d(R1)
        da = np.mod(a1 - a0 + np.pi, 2 * np.pi) - np.pi
        return rotation_2d(a0 + np.asarray(t) * da)
    return quat_to_matrix(quat_slerp(matrix_to_quat(R0), matrix_to_quat(R1), t))


def rotation_between(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Smallest rotation (..., d, d) taking direction ``u`` to direction ``v`` (d = 2, 3).

    For antiparallel 3D vectors any half-turn about an axis perpendicular to ``u``
    is smallest; we pick the one about the axis most perpendicular to ``u``.
    """
    u = np.asarray(u, dtype=float)
    v = np.asarray(v, dtype=float)
    nu = np.linalg.norm(u, axis=-1, keepdims=True)
    nv = np.linalg.norm(v, axis=-1, keepdims=True)
    if np.any(nu == 0) or np.any(nv == 0):
        raise ValueError("rotation_between needs non-zero vectors, got a zero vector")
    u = u / nu
    v = v / nv
    if u.shape[-1] == 2:
        ang = np.arctan2(u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0], np.sum(u * v, -1))
        return rotation_2d(ang)
    c = np.sum(u * v, axis=-1)
    axis = np.cross(u, v)
    q = np.concatenate([(1.0 + c)[..., None], axis], axis=-1)
    anti = (1.0 + c) < 1e-12
    if np.any(anti):
        uu = u[anti]
        e = np.eye(3)[np.argmin(np.abs(uu), axis=-1)]
        perp = np.cross(uu, e)
        q[anti] = np.concatenate([np.zeros((uu.shape[0], 1)), perp], axis=-1)
    return quat_to_matrix(quat_normalize(q))


def rotate(q: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Rotate (..., 3) points ``x`` by unit quaternions ``q``."""
    q = np.asarray(q, dtype=float)
    x = np.asarray(x, dtype=float)
    w = q[..., :1]
    r = q[..., 1:]
    t = 2.0 * np.cross(r, x)
    return x + w * t + np.cross(r, t)


def dq_from_rt(q: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit dual quaternion of ``x -> R(q) x + t``."""
    q = np.asarray(q, dtype=float)
    t = np.asarray(t, dtype=float)
    tq = np.concatenate([np.zeros(t.shape[:-1] + (1,)), t], axis=-1)
    return q, 0.5 * quat_mul(tq, q)


def dq_to_rt(qr: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation quaternion and translation of a (not necessarily unit) dual quaternion."""
    qr, qd = dq_normalize(qr, qd)
    t = 2.0 * quat_mul(qd, quat_conj(qr))[..., 1:]
    return qr, t


def dq_mul(a: tuple[np.ndarray, np.ndarray], b: tuple[np.ndarray, np.ndarray]):
    """Dual-quaternion product ``a * b`` (apply ``b`` first)."""
    return quat_mul(a[0], b[0]), quat_mul(a[0], b[1]) + quat_mul(a[1], b[0])


def dq_normalize(qr: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Project onto unit dual quaternions (|qr| = 1, qr . qd = 0)."""
    qr = np.asarray(qr, dtype=float)
    qd = np.asarray(qd, dtype=float)
    n = np.linalg.norm(qr, axis=-1, keepdims=True)
    if np.any(n == 0):
        raise ValueError("dual quaternion has a zero real part; cannot normalise")
    qr = qr / n
    qd = qd / n
    qd = qd - np.sum(qr * qd, axis=-1, keepdims=True) * qr
    return qr, qd


def dq_apply(qr: np.ndarray, qd: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Apply (normalised here) dual quaternions to (..., 3) points."""
    q, t = dq_to_rt(qr, qd)
    return rotate(q, x) + t


def dq_blend(w: np.ndarray, qr: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Blend (..., m) weights of (..., m, 4) dual quaternions with pivot hemisphere flip.

    Each quaternion is flipped into the hemisphere of the one with the largest weight
    (the pivot), then the weighted sum is normalised.
    """
    w = np.asarray(w, dtype=float)
    piv = np.take_along_axis(qr, np.argmax(w, axis=-1)[..., None, None], axis=-2)
    sign = np.where(np.sum(qr * piv, axis=-1) < 0, -1.0, 1.0)
    ws = (w * sign)[..., None]
    return dq_normalize(np.sum(ws * qr, axis=-2), np.sum(ws * qd, axis=-2))
