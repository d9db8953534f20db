"""Differentiable rotation parameterisations on any array-API backend.

Quaternions are ``(w, x, y, z)``, scalar first, as everywhere in stbs. Every function
takes arbitrary leading batch axes, uses only array-API operations (so one code path
runs on NumPy, PyTorch, JAX and CuPy) and is differentiable wherever the
parameterisation itself is smooth:

- :func:`quat_to_matrix` normalises its input; smooth except at ``q = 0``.
- :func:`matrix_to_quat` (Shepperd's method, four candidates chosen per rotation by the
  largest diagonal term) is smooth at and through 180 degrees; where the choice switches,
  the output may change sign (``q`` and ``-q`` are the same rotation), which the
  dual-quaternion blends of :mod:`stbs.skin` do not see.
- :func:`rot6d_to_matrix` (the continuous 6D form of Zhou et al. 2019: the first two
  columns, completed by Gram-Schmidt) is smooth except where the two columns are
  parallel or one is zero.
- :func:`angle_to_matrix` (2D) is smooth everywhere.
"""

from __future__ import annotations

from typing import Any

import array_api_compat

__all__ = ["quat_to_matrix", "matrix_to_quat", "rot6d_to_matrix", "matrix_to_rot6d",
           "angle_to_matrix", "angle_to_quat", "axis_angle_to_quat", "quat_mul",
           "quat_normalize"]


def _xp(*arrays):
    return array_api_compat.array_namespace(*arrays)


def _c(q, i: int):
    """Component i of the last axis, keeping the axis (length 1)."""
    return q[..., i:i + 1]


def quat_normalize(q, *, xp=None):
    """(..., 4) quaternions divided by their norm (not defined at q = 0)."""
    xp = xp or _xp(q)
    return q / xp.sqrt(xp.sum(q * q, axis=-1, keepdims=True))


def quat_mul(p, q, *, xp=None):
    """Hamilton product ``p * q`` of (..., 4) quaternions."""
    xp = xp or _xp(p, q)
    pw, px, py, pz = (_c(p, i) for i in range(4))
    qw, qx, qy, qz = (_c(q, i) for i in range(4))
    return xp.concat([
        pw * qw - px * qx - py * qy - pz * qz,
        pw * qx + px * qw + py * qz - pz * qy,
        pw * qy - px * qz + py * qw + pz * qx,
        pw * qz + px * qy - py * qx + pz * qw], axis=-1)


def quat_to_matrix(q, *, xp=None):
    """(..., 4) quaternions (normalised here) to (..., 3, 3) rotation matrices.

    Parameters
    ----------
    q : (..., 4) float
        Quaternions ``(w, x, y, z)``; ``q`` and ``-q`` give the same matrix.

    Returns
    -------
    R : (..., 3, 3) float
    """
    xp = xp or _xp(q)
    q = quat_normalize(q, xp=xp)
    w, x, y, z = (q[..., i] for i in range(4))
    rows = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]]
    return xp.stack([xp.stack(r, axis=-1) for r in rows], axis=-2)


def matrix_to_quat(R, *, xp=None):
    """(..., 3, 3) rotation matrices to (..., 4) unit quaternions.

    Shepperd's method: of the four ways to recover ``q`` the one dividing by the
    largest component is chosen per matrix, so the result is accurate and
    differentiable at and through 180 degrees. The sign of ``q`` is not normalised
    (the component divided by is positive); ``-q`` is the same rotation.

    Parameters
    ----------
    R : (..., 3, 3) float

    Returns
    -------
    q : (..., 4) float
    """
    xp = xp or _xp(R)
    m = [[R[..., i, j] for j in range(3)] for i in range(3)]
    tr = m[0][0] + m[1][1] + m[2][2]
    cand = [tr, m[0][0], m[1][1], m[2][2]]
    # 4 |largest component| for each choice; clamped so the unused choices stay finite
    # (their gradients are multiplied by zero, and a NaN there would poison them)
    tiny = 1e-12 if R.dtype == xp.float64 else 1e-6
    s = [2.0 * xp.sqrt(xp.clip(1.0 + 2.0 * c - tr, tiny, None)) for c in cand]
    d21, d02, d10 = m[2][1] - m[1][2], m[0][2] - m[2][0], m[1][0] - m[0][1]
    s01, s02, s12 = m[0][1] + m[1][0], m[0][2] + m[2][0], m[1][2] + m[2][1]
    opts = [
        (0.25 * s[0], d21 / s[0], d02 / s[0], d10 / s[0]),
        (d21 / s[1], 0.25 * s[1], s01 / s[1], s02 / s[1]),
        (d02 / s[2], s01 / s[2], 0.25 * s[2], s12 / s[2]),
        (d10 / s[3], s02 / s[3], s12 / s[3], 0.25 * s[3])]
    # argmax over the four candidates without data-dependent control flow; ties take
    # the first, as np.argmax does
    pick1 = (cand[1] > cand[0])
    best = xp.where(pick1, cand[1], cand[0])
    pick2 = cand[2] > best
    best = xp.where(pick2, cand[2], best)
    pick3 = cand[3] > best
    comps = []
    for c in range(4):
        v = xp.where(pick1, opts[1][c], opts[0][c])
        v = xp.where(pick2, opts[2][c], v)
        comps.append(xp.where(pick3, opts[3][c], v))
    return quat_normalize(xp.stack(comps, axis=-1), xp=xp)


def axis_angle_to_quat(axis, angle, *, xp=None):
    """Quaternion (..., 4) of a rotation by ``angle`` (...,) about unit ``axis`` (..., 3)."""
    xp = xp or _xp(axis, angle)
    half = 0.5 * angle[..., None]
    return xp.concat([xp.cos(half) + 0.0 * axis[..., :1], xp.sin(half) * axis], axis=-1)


def rot6d_to_matrix(x, *, xp=None):
    """The continuous 6D form (Zhou et al. 2019) to (..., 3, 3) rotation matrices.

    Parameters
    ----------
    x : (..., 6) float
        Two 3-vectors ``(a1, a2)``: the matrix's first column is ``a1 / |a1|``, its
        second the part of ``a2`` orthogonal to it, normalised (Gram-Schmidt), its third
        their cross product. Not defined where ``a1 = 0`` or ``a2`` is parallel to ``a1``.

    Returns
    -------
    R : (..., 3, 3) float
    """
    xp = xp or _xp(x)
    a1, a2 = x[..., 0:3], x[..., 3:6]
    b1 = a1 / xp.sqrt(xp.sum(a1 * a1, axis=-1, keepdims=True))
    v = a2 - xp.sum(b1 * a2, axis=-1, keepdims=True) * b1
    b2 = v / xp.sqrt(xp.sum(v * v, axis=-1, keepdims=True))
    b3 = cross(b1, b2, xp=xp)
    return xp.stack([b1, b2, b3], axis=-1)


def matrix_to_rot6d(R, *, xp=None):
    """(..., 3, 3) rotation matrices to their 6D form (..., 6): the first two columns."""
    xp = xp or _xp(R)
    return xp.concat([R[..., :, 0], R[..., :, 1]], axis=-1)


def angle_to_matrix(angle, *, xp=None):
    """2D rotation angles (...,) in radians to (..., 2, 2) matrices ``[[c, -s], [s, c]]``."""
    xp = xp or _xp(angle)
    c, s = xp.cos(angle), xp.sin(angle)
    return xp.stack([xp.stack([c, -s], axis=-1), xp.stack([s, c], axis=-1)], axis=-2)


def angle_to_quat(angle, *, xp=None):
    """2D rotation angles (...,) to (..., 4) quaternions about z."""
    xp = xp or _xp(angle)
    half = 0.5 * angle
    z = xp.zeros_like(half)
    return xp.stack([xp.cos(half), z, z, xp.sin(half)], axis=-1)


def cross(a, b, *, xp: Any = None):
    """Cross product of (..., 3) vectors, from rolled copies (no per-component slicing)."""
    xp = xp or _xp(a, b)
    return (xp.roll(a, -1, axis=-1) * xp.roll(b, -2, axis=-1)
            - xp.roll(a, -2, axis=-1) * xp.roll(b, -1, axis=-1))
