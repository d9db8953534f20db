"""Least squares on the probability simplex, many small problems at once.

Bone weights at a vertex are bounded (``w >= 0``), sum to one and are sparse (at most
``k`` bones). Fitting them to examples is one small quadratic programme per vertex::

    minimise   ||A w - y||^2 + lam ||w - prior||^2
    subject to w >= 0,  sum(w) = 1,  at most k entries of w non-zero

:func:`simplex_lsq` takes that form; :func:`simplex_qp` takes the normal equations
(``H = A^T A + lam I``, ``g = A^T y + lam prior``) for callers that accumulate them
without ever building ``A``. Both solve all n problems together: a primal active-set
method run in lock step over the rows (NumPy, one batched KKT solve per step, no Python
loop over rows), exact up to rounding for the bounded, sum-to-one problem.

The count limit makes the problem combinatorial. The support is chosen by an active-set
rule: solve without the limit; rows that already have at most k non-zeros are done;
for the others take a *pool* of the ``pool`` most promising bones (largest weights,
then the zero weights whose KKT multipliers are smallest, i.e. the bones that would
enter next) and solve the bounded, sum-to-one problem exactly on every k-subset of the
pool, keeping the best. When the pool holds all m unknowns this is the exact k-sparse
optimum (every support is tried); otherwise it is exact among the pool's supports.
"""

from __future__ import annotations

from itertools import combinations

import numpy as np

from .._arrays import real_array

__all__ = ["simplex_lsq", "simplex_qp", "simplex_objective"]

#: Ridge added to H, relative to its mean diagonal, so that rank-deficient problems
#: (fewer equations than unknowns, ``lam = 0``) still have a unique KKT solution.
RIDGE = 1e-12
#: Extra pool members beyond k by default (see the module docs).
POOL_EXTRA = 2


def simplex_objective(H: np.ndarray, g: np.ndarray, w: np.ndarray) -> np.ndarray:
    """``0.5 w^T H w - g^T w`` per row: (n,) for H (n, m, m), g (n, m), w (n, m)."""
    return 0.5 * np.einsum("ni,nij,nj->n", w, H, w) - np.einsum("ni,ni->n", g, w)


def simplex_lsq(A, y, *, k: int | None = None, prior=None, lam=0.0,
                pool: int | None = None) -> np.ndarray:
    """Per-row least squares on the simplex, optionally k-sparse and pulled to a prior.

    Minimises ``||A[r] w - y[r]||^2 + lam[r] ||w - prior[r]||^2`` over ``w >= 0``,
    ``sum(w) = 1`` and (with ``k``) at most ``k`` non-zeros, for every row r at once.

    Parameters
    ----------
    A : (n, q, m) float
        One design matrix per row (q equations, m unknowns, e.g. the m bones' predicted
        positions of a vertex over all frames and coordinates).
    y : (n, q) float
        Targets.
    k : int, optional
        Largest number of non-zeros per row (None: no limit).
    prior : (n, m) float, optional
        What ``lam`` pulls each row towards (e.g. the neighbours' average weights);
        default zero (then ``lam`` is a ridge that spreads the weights).
    lam : float or (n,) float
        Weight of the prior term, ``>= 0``; 0 turns it off.
    pool : int, optional
        Candidate bones per row from which the k-sparse support is picked (module
        docs); default ``k + 2``. ``pool >= m`` tries every support (exact).

    Returns
    -------
    w : (n, m) float
        Rows ``>= 0`` summing to 1, each with at most k non-zeros.

    Examples
    --------
    >>> import numpy as np
    >>> A = np.eye(3)[None]; y = np.array([[0.6, 0.6, -0.2]])
    >>> simplex_lsq(A, y).round(6)
    array([[0.5, 0.5, 0. ]])
    """
    A = real_array("A", A, ndim=3)
    n, q, m = A.shape
    y = real_array("y", y, shape=(n, q))
    lam = _lam(lam, n)
    if prior is None:
        prior = np.zeros((n, m))
    prior = real_array("prior", prior, shape=(n, m))
    H = np.einsum("nqi,nqj->nij", A, A)
    H[:, np.arange(m), np.arange(m)] += lam[:, None]
    g = np.einsum("nqi,nq->ni", A, y) + lam[:, None] * prior
    return simplex_qp(H, g, k=k, pool=pool)


def simplex_qp(H, g, *, k: int | None = None, pool: int | None = None) -> np.ndarray:
    """Per-row ``min 0.5 w^T H w - g^T w`` over the simplex, optionally k-sparse.

    The normal-equations form of :func:`simplex_lsq` (``H = A^T A + lam I``,
    ``g = A^T y + lam prior``).

    Parameters
    ----------
    H : (n, m, m) float
        Symmetric positive semi-definite matrices (a relative ridge of ``RIDGE`` is
        added so that singular ones still give a unique answer).
    g : (n, m) float
    k, pool
        As for :func:`simplex_lsq`.

    Returns
    -------
    w : (n, m) float
        Rows ``>= 0`` summing to 1, each with at most k non-zeros.
    """
    H = real_array("H", H, ndim=3)
    n, m, m2 = H.shape
    if m != m2:
        raise ValueError(f"H must have shape (n, m, m), got {H.shape}")
    if m == 0:
        raise ValueError(f"H must have at least one unknown (m >= 1), got shape {H.shape}")
    g = real_array("g", g, shape=(n, m))
    k = _count("k", k, m)
    pool = _count("pool", pool, m)
    H = 0.5 * (H + np.swapaxes(H, 1, 2))
    scale = np.maximum(np.einsum("nii->n", H) / m, np.finfo(float).tiny)
    H = H + (RIDGE * scale)[:, None, None] * np.eye(m)
    w, lam = _active_set(H, g)
    if k is None or k >= m:
        return w
    over = np.flatnonzero(np.count_nonzero(w, axis=1) > k)
    if over.size:
        p = min(m, max(k, k + POOL_EXTRA if pool is None else pool))
        w[over] = _best_support(H[over], g[over], w[over], lam[over], k, p)
    return w


# ---------------------------------------------------------------------------- helpers
def _lam(lam, n: int) -> np.ndarray:
    lam = real_array("lam", lam)
    if lam.ndim not in (0, 1) or (lam.ndim == 1 and lam.shape != (n,)):
        raise ValueError(f"lam must be a number or have shape ({n},), got shape {lam.shape}")
    if np.any(lam < 0):
        raise ValueError(f"lam must be >= 0, got {float(lam.min()):.6g}")
    return np.broadcast_to(lam, (n,)).astype(float)


def _count(name: str, value, m: int) -> int | None:
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ValueError(f"{name} must be a positive integer or None, got {value!r}")
    return int(value)


def _kkt_solve(H: np.ndarray, g: np.ndarray, free: np.ndarray):
    """Minimiser of 0.5 w'Hw - g'w with w = 0 off ``free`` and sum(w) = 1, and the
    multiplier ``nu`` of the sum (H w - g + nu = 0 on the free set), per row."""
    r, m = g.shape
    M = np.zeros((r, m + 1, m + 1))
    both = free[:, :, None] & free[:, None, :]
    M[:, :m, :m] = np.where(both, H, 0.0)
    idx = np.arange(m)
    M[:, idx, idx] += ~free                      # fixed unknowns: w_j = 0
    M[:, :m, m] = free
    M[:, m, :m] = free
    rhs = np.concatenate([np.where(free, g, 0.0), np.ones((r, 1))], axis=1)
    z = np.linalg.solve(M, rhs[..., None])[..., 0]
    return z[:, :m], z[:, m]


def _active_set(H: np.ndarray, g: np.ndarray, max_iter: int | None = None):
    """Bounded, sum-to-one QP per row by a primal active-set method, rows in lock step.

    Starts at the best vertex of the simplex (one unknown at 1); each step either moves
    to the equality-constrained optimum of the free set (then frees the unknown with the
    most negative multiplier, if any) or stops at the first bound it meets (that unknown
    becomes fixed at 0). Returns the solution and the multipliers ``Hw - g + nu`` (0 on
    the support, >= 0 off it at the optimum).
    """
    n, m = g.shape
    diag = np.einsum("nii->ni", H)
    j0 = np.argmin(0.5 * diag - g, axis=1)
    w = np.zeros((n, m))
    w[np.arange(n), j0] = 1.0
    free = w > 0
    lam = np.zeros((n, m))
    tol = 1e-12 * (np.abs(diag).max(axis=1) + np.abs(g).max(axis=1) + 1e-300)
    todo = np.arange(n)
    for _ in range(max_iter or 4 * m + 20):
        if todo.size == 0:
            break
        Ht, gt, wt, ft = H[todo], g[todo], w[todo], free[todo]
        z, nu = _kkt_solve(Ht, gt, ft)
        neg = ft & (z < 0)
        blocked = neg.any(axis=1)
        # rows whose free-set optimum is feasible: take it, then look at the multipliers
        ok = ~blocked
        wt[ok] = np.where(ft[ok], z[ok], 0.0)
        lt = np.einsum("nij,nj->ni", Ht, wt) - gt + nu[:, None]
        lt = np.where(ft, 0.0, lt)
        jmin = np.argmin(lt, axis=1)
        enter = ok & (lt[np.arange(todo.size), jmin] < -tol[todo])
        ft[enter, jmin[enter]] = True
        # rows that hit a bound: step to it and fix the blocking unknown
        if blocked.any():
            wb, zb = wt[blocked], z[blocked]
            with np.errstate(divide="ignore", invalid="ignore"):
                ratio = np.where(neg[blocked], wb / (wb - zb), np.inf)
            jb = np.argmin(ratio, axis=1)
            alpha = np.clip(ratio[np.arange(jb.size), jb], 0.0, 1.0)
            wb = wb + alpha[:, None] * (zb - wb)
            wb = np.where(ft[blocked], np.maximum(wb, 0.0), 0.0)
            wb[np.arange(jb.size), jb] = 0.0
            fb = ft[blocked]
            fb[np.arange(jb.size), jb] = False
            wt[blocked], ft[blocked] = wb, fb
        w[todo], free[todo], lam[todo] = wt, ft, lt
        todo = todo[blocked | enter]
    w = np.maximum(w, 0.0)
    w /= w.sum(axis=1, keepdims=True)
    return w, lam


def _best_support(H, g, w, lam, k: int, p: int) -> np.ndarray:
    """Exact bounded, sum-to-one solves on every k-subset of each row's p-bone pool."""
    r, m = g.shape
    # rank: positive weights first (largest first), then zeros by their multipliers
    key = np.where(w > 0, -w, lam + 1.0 + np.abs(lam).max())
    cand = np.argsort(key, axis=1, kind="stable")[:, :p]
    rows = np.arange(r)[:, None]
    best = np.full(r, np.inf)
    out = np.zeros((r, m))
    for combo in combinations(range(p), k):
        S = cand[:, list(combo)]                              # (r, k)
        Hs = H[rows[:, :, None], S[:, :, None], S[:, None, :]]
        gs = g[rows, S]
        ws, _ = _active_set(Hs, gs)
        f = simplex_objective(Hs, gs, ws)
        better = f < best
        if better.any():
            best[better] = f[better]
            out[better] = 0.0
            out[rows[better], S[better]] = ws[better]
    return out
