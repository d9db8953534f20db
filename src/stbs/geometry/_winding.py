"""The generalised winding number kernel (numba, parallel over the query points)."""

from __future__ import annotations

import math

import numba as nb
import numpy as np

_JIT = dict(nogil=True, cache=True, parallel=True, error_model="numpy")


@nb.njit(**_JIT)
def _winding(Q, V, F, out):
    # Generalised winding number (Jacobson et al. 2013): the solid angles of the
    # triangles seen from q, summed over 4 pi; each by Van Oosterom & Strackee (1983).
    for k in nb.prange(Q.shape[0]):
        qx, qy, qz = Q[k, 0], Q[k, 1], Q[k, 2]
        total = 0.0
        for f in range(F.shape[0]):
            i, j, m = F[f, 0], F[f, 1], F[f, 2]
            ax, ay, az = V[i, 0] - qx, V[i, 1] - qy, V[i, 2] - qz
            bx, by, bz = V[j, 0] - qx, V[j, 1] - qy, V[j, 2] - qz
            cx, cy, cz = V[m, 0] - qx, V[m, 1] - qy, V[m, 2] - qz
            la = math.sqrt(ax * ax + ay * ay + az * az)
            lb = math.sqrt(bx * bx + by * by + bz * bz)
            lc = math.sqrt(cx * cx + cy * cy + cz * cz)
            det = (ax * (by * cz - bz * cy) - ay * (bx * cz - bz * cx)
                   + az * (bx * cy - by * cx))
            den = (la * lb * lc + (ax * bx + ay * by + az * bz) * lc
                   + (bx * cx + by * cy + bz * cz) * la + (cx * ax + cy * ay + cz * az) * lb)
            total += 2.0 * math.atan2(det, den)
        out[k] = total / (4.0 * math.pi)


def winding_numbers(Q: np.ndarray, V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Generalised winding numbers (q,) of points ``Q`` (q, 3) for the surface ``(V, F)``.

    About 1 inside a closed, outward-oriented surface, 0 outside.
    """
    out = np.empty(Q.shape[0])
    if Q.shape[0]:
        _winding(np.ascontiguousarray(Q, dtype=np.float64),
                 np.ascontiguousarray(V, dtype=np.float64),
                 np.ascontiguousarray(F, dtype=np.int64), out)
    return out


