"""Small dense kernels for the BBW working set: deleting rows of a Cholesky factor.

Removing constraint ``k`` from the working set removes row and column ``k`` of the
dense SPD matrix ``H = R R^T`` (``R`` lower triangular). Its factor is ``R`` without
row ``k`` and column ``k``, except that the trailing block must absorb the deleted
column: ``R33' R33'^T = R33 R33^T + r r^T`` with ``r = R[k+1:, k]``, a rank-one
Cholesky update (Givens-like, ``O((s - k)^2)``), instead of a new ``O(s^3)``
factorization. Compiled with numba, like the skinning kernels.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from .._jit import cache_enabled

_CACHE = cache_enabled(__file__)
_JIT = dict(nogil=True, cache=_CACHE, error_model="numpy")


@nb.njit(**_JIT)
def _delete_one(R: np.ndarray, s: int, k: int) -> None:
    """Delete row and column ``k`` of the leading ``s x s`` lower factor ``R`` in place."""
    m = s - k - 1
    r = np.empty(m)
    for i in range(m):
        r[i] = R[k + 1 + i, k]
    # shift rows below k up by one and columns right of k left by one (lower part)
    for i in range(k, s - 1):
        for j in range(0, k):
            R[i, j] = R[i + 1, j]
        for j in range(k, i + 1):
            R[i, j] = R[i + 1, j + 1]
    for j in range(s):
        R[s - 1, j] = 0.0
        R[j, s - 1] = 0.0
    # rank-one update of the trailing block R[k:s-1, k:s-1] by r r^T
    for c in range(m):
        d = R[k + c, k + c]
        rr = np.sqrt(d * d + r[c] * r[c])
        cs = rr / d
        sn = r[c] / d
        R[k + c, k + c] = rr
        for i in range(c + 1, m):
            R[k + i, k + c] = (R[k + i, k + c] + sn * r[i]) / cs
            r[i] = cs * r[i] - sn * R[k + i, k + c]


@nb.njit(**_JIT)
def delete_rows(R: np.ndarray, s: int, ks: np.ndarray) -> None:
    """Delete the rows/columns ``ks`` (sorted ascending, unique) of the leading ``s x s``
    lower Cholesky factor ``R`` in place; the factor of the remaining ``s - len(ks)``
    slots (in their old order) ends up in the leading block."""
    for q in range(ks.size - 1, -1, -1):
        _delete_one(R, s, ks[q])
        s -= 1


def refactor_without(R: np.ndarray, s: int, ks: np.ndarray) -> None:
    """Same result as :func:`delete_rows`, by a new factorization of the kept block of
    ``H = R R^T`` (``O(s^3)``): cheaper when many rows go at once."""
    keep = np.setdiff1d(np.arange(s), ks)
    Rk = R[keep, :s]
    H = Rk @ Rk.T
    R[:s, :s] = 0.0
    if keep.size:
        R[:keep.size, :keep.size] = np.linalg.cholesky(H)


@nb.njit(**_JIT)
def chol_solve(R: np.ndarray, s: int, b: np.ndarray) -> np.ndarray:
    """Solve ``(R R^T) x = b`` with the leading ``s x s`` lower factor of the buffer ``R``
    (no copy of the buffer, unlike LAPACK on a strided view)."""
    y = b.copy()
    for i in range(s):                      # R y = b, by rows
        acc = y[i]
        for j in range(i):
            acc -= R[i, j] * y[j]
        y[i] = acc / R[i, i]
    for i in range(s - 1, -1, -1):          # R^T x = y, by rows of R (axpy form)
        y[i] /= R[i, i]
        yi = y[i]
        for j in range(i):
            y[j] -= R[i, j] * yi
    return y
