"""Convex quadratic programs with box constraints, by a dual active-set method.

For a sparse symmetric positive definite ``Q`` (n, n) and one or several linear terms
``c`` (the columns of an (n, m) array, solved together because they share ``Q``)::

    minimise  1/2 x^T Q x + c^T x    subject to  lo <= x <= hi,   x[fixed] = values

This is the QP of bounded biharmonic weights (:mod:`stbs.weights.bbw`: ``Q`` the
bilaplacian, ``lo = 0``, ``hi = 1``, the handles fixed), and nothing here knows about
meshes, skeletons or threads: :func:`box_qp` takes the matrix and the bounds, and the
engine :class:`DualActiveSet` takes a factorization of the free block as a callback.

The method
----------
The fixed variables are eliminated (``K = Q[U, U]``, ``c_U = c[U] + Q[U, fixed] values``
over the free variables ``U``). The KKT conditions are ``K x + c_U = mu`` with bound
multipliers ``mu`` (``mu >= 0`` where ``x = lo``, ``mu <= 0`` where ``x = hi``, ``0``
elsewhere), so with ``S`` the *working set* of variables held at a bound

    x = x_u + K^-1 E_S sigma,      x_u = -K^-1 c_U   (the unconstrained minimiser)

and each round

1. adds the variables violating a bound most -- in a batch, only those whose
   violation is at least every neighbour's (``neighbors``; by default the sparsity
   graph of ``Q``), so one round adds spread-out constraints -- to ``S``; their columns
   of ``K^-1`` come from one multi-right-hand-side solve shared by all columns of ``c``;
2. solves the dense Schur complement system ``(K^-1)[S, S] sigma = target - x_u[S]``
   (``target``: the bound each holds) by a Cholesky factor grown by block updates;
3. drops constraints whose multipliers have the wrong sign; recomputes ``x`` with one
   solve; stops when no bound is violated by more than ``tol / 4``.

The result is checked against the KKT conditions of the QP on every variable by the
*natural residual* (:func:`kkt_residual`); a column that misses ``tol`` is finished by
a primal active-set (semismooth Newton) polish with sparse factorizations of the
free-variable system.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Literal

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from .. import _checks
from ._cholesky import BACKENDS, Factor
from ._dense import chol_solve, delete_rows, refactor_without

__all__ = ["box_qp", "kkt_residual", "BoxQPResult", "DualActiveSet", "solve_chunk"]

_BATCH = 256          # constraints added per column and round, at most
_SOLVE_BYTES = 48 * 2**20   # right-hand-side block per sparse solve call (solve_chunk)
_CACHE_BYTES = 256 * 2**20   # dense K^-1 block kept on constrained variables (all columns)
_POLISH_ITER = 50     # primal active-set iterations of the fallback polish


@dataclass
class BoxQPResult:
    """The solution of :func:`box_qp` and how it was reached, one entry per column of ``c``.

    Attributes
    ----------
    x : (n,) or (n, m) float64
        The minimiser, shaped like ``c``: ``lo <= x <= hi`` exactly on the free
        variables, ``x[fixed] = values``.
    kkt_residual : (m,) float
        Natural KKT residual (:func:`kkt_residual`) on the free variables.
    iterations : (m,) int
        Rounds of the dual active-set method plus polish iterations.
    n_constraints : (m,) int
        Size of the final working set (variables with a non-zero bound multiplier).
    n_polish : (m,) int
        Primal active-set iterations of the fallback polish (0 when not needed).
    converged : (m,) bool
        ``kkt_residual <= tol``.
    n_solves : int
        Right-hand sides solved with the factor of the free block.
    tol : float
    """

    x: np.ndarray
    kkt_residual: np.ndarray
    iterations: np.ndarray
    n_constraints: np.ndarray
    n_polish: np.ndarray
    converged: np.ndarray
    n_solves: int
    tol: float

    @property
    def all_converged(self) -> bool:
        return bool(np.all(self.converged))


# --------------------------------------------------------------------------------------
# dense SPD matrix with a growing Cholesky factor (the Schur complement on S)
# --------------------------------------------------------------------------------------
class _Schur:
    """The dense SPD system on the working set, ``H = (K^-1)[S, S]``, by its Cholesky factor.

    Slots are appended by block Cholesky updates and removed by rank-one updates of
    the factor (:mod:`._dense`), so neither costs a refactorization; slots stay
    compact (every slot is a live constraint). ``meta`` holds per-slot arrays
    (variable, bound, column) for the caller.
    """

    def __init__(self, **meta: np.dtype):
        self._R = np.zeros((0, 0))           # a buffer; the factor is its leading block
        self.s = 0
        self.meta = {k: np.zeros(0, dtype=dt) for k, dt in meta.items()}

    @property
    def size(self) -> int:
        return self.s

    @property
    def R(self) -> np.ndarray:
        return self._R[:self.s, :self.s]

    def get(self, key: str) -> np.ndarray:
        """Per-slot values of the constraints."""
        return self.meta[key]

    def append(self, H12: np.ndarray, H22: np.ndarray, **meta: np.ndarray) -> np.ndarray:
        """Append k slots (``H12``: rows over all current slots); return which were kept.

        A constraint that is (numerically) a combination of others is not added.
        """
        k = H22.shape[0]
        H22 = 0.5 * (H22 + H22.T)
        R21 = (sla.solve_triangular(self.R, H12, lower=True, check_finite=False).T if self.s
               else np.zeros((k, 0)))
        try:
            R22 = np.linalg.cholesky(H22 - R21 @ R21.T)
            ok = bool(np.all(np.diag(R22) > 1e-10 * np.sqrt(np.maximum(np.diag(H22), 1e-300))))
        except np.linalg.LinAlgError:
            ok = False
        if ok:
            self._grow(H12, H22, R21, R22)
            keep = np.ones(k, dtype=bool)
        else:  # rare: add one at a time, skipping dependent ones
            keep = np.zeros(k, dtype=bool)
            for q in range(k):
                kept = np.flatnonzero(keep)
                h12 = np.concatenate([H12[:, q], H22[kept, q]])
                r = (sla.solve_triangular(self.R, h12, lower=True, check_finite=False) if self.s
                     else np.zeros(0))
                d = H22[q, q] - r @ r
                if d > 1e-20 * max(H22[q, q], 1e-300):
                    self._grow(h12[:, None], H22[q:q + 1, q:q + 1], r[None, :],
                               np.array([[np.sqrt(d)]]))
                    keep[q] = True
        for key in self.meta:
            self.meta[key] = np.concatenate([self.meta[key], meta[key][keep]])
        return keep

    def _grow(self, H12, H22, R21, R22):
        s, k = self.s, H22.shape[0]
        if s + k > self._R.shape[0]:        # a geometrically grown buffer
            cap = max(s + k, 2 * self._R.shape[0], 64)
            Rb = np.zeros((cap, cap))
            Rb[:s, :s] = self.R
            self._R = Rb
        self._R[s:s + k, :s], self._R[s:s + k, s:s + k] = R21, R22
        self.s = s + k

    def drop(self, bad: np.ndarray) -> None:
        """Remove the constraints flagged in ``bad`` (a mask over the slots)."""
        ks = np.flatnonzero(bad)
        if ks.size == 0:
            return
        keep = ~bad
        s, q = self.s, int(keep.sum())
        if ks.size > max(8, s // 8):       # many at once: a new factorization is cheaper
            refactor_without(self._R, s, ks)
        else:
            delete_rows(self._R, s, ks.astype(np.int64))
        self.s = q
        self.meta = {k: v[keep] for k, v in self.meta.items()}

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """Solve ``H sigma = rhs``."""
        if self.s == 0:
            return np.zeros(0)
        return chol_solve(self._R, self.s, np.ascontiguousarray(rhs, dtype=float))


class _Green:
    """Entries of ``K^-1`` between constrained variables, shared by all columns of ``c``.

    A variable joins when its column ``K^-1 e_i`` is solved; the rows of that column at
    the variables already here complete the dense symmetric block. Columns whose
    working sets overlap (in BBW: neighbouring bones), and constraints dropped and
    added again, then cost no further solve. ``cap`` bounds the memory (variables).
    """

    def __init__(self, nu: int, cap: int | None):
        self.pos = np.full(nu, -1, dtype=np.int64)
        self.verts = np.zeros(0, dtype=np.int64)
        self.G = np.zeros((0, 0))
        self.cap = cap

    @property
    def size(self) -> int:
        return self.verts.size

    def room(self) -> float:
        return np.inf if self.cap is None else self.cap - self.size

    def has(self, v: np.ndarray) -> bool:
        return bool(np.all(self.pos[v] >= 0))

    def add(self, cv: np.ndarray, Y: np.ndarray) -> None:
        """Add variables ``cv`` (not yet here) given their full columns ``Y`` (nu, k)."""
        s, k = self.size, cv.size
        if s + k > self.G.shape[0]:
            cap = max(s + k, int(1.5 * self.G.shape[0]), 64)
            if self.cap is not None:
                cap = min(cap, max(self.cap, s + k))
            G = np.empty((cap, cap))
            G[:s, :s] = self.G[:s, :s]
            self.G = G
        self.G[:s, s:s + k] = Y[self.verts]
        self.G[s:s + k, :s] = self.G[:s, s:s + k].T
        B = Y[cv]
        self.G[s:s + k, s:s + k] = 0.5 * (B + B.T)
        self.pos[cv] = np.arange(s, s + k)
        self.verts = np.concatenate([self.verts, cv])

    def block(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        return self.G[np.ix_(self.pos[rows], self.pos[cols])]


def solve_chunk(nu: int) -> int:
    """Right-hand sides per sparse solve call for ``nu`` unknowns: a block of about
    ``_SOLVE_BYTES``, 64 to 512 columns.

    Per column, CHOLMOD's multi-column solve is cheapest with the block of right-hand
    sides near the cache sizes: at 50k unknowns (two threads) 3.5 ms with 128 columns
    against 4.1-4.4 ms with 512, while at 10k and 20k 256-512 are best (measured,
    ``docs/bbw.md``).
    """
    return int(np.clip(_SOLVE_BYTES // (8 * max(int(nu), 1)), 64, 512))


def _local_maxima(v: np.ndarray, adj: sp.csr_array) -> np.ndarray:
    """Mask of variables whose value is >= every neighbour's (True with no neighbour)."""
    out = np.ones(v.size, dtype=bool)
    rows = np.flatnonzero(np.diff(adj.indptr) > 0)
    if rows.size:
        nb = np.maximum.reduceat(v[adj.indices], adj.indptr[rows])
        out[rows] = v[rows] >= nb
    return out


def _natural_residual(K, x, c, dK, lo, hi) -> float:
    z = K @ x + c
    return float(np.max(np.abs(x - np.clip(x - z / dK, lo, hi)), initial=0.0))


# --------------------------------------------------------------------------------------
class DualActiveSet:
    """The dual active-set iterations for ``m`` box QPs sharing the free block ``K``.

    The engine of :func:`box_qp` and of :class:`stbs.weights.BBWSolver` (which brings
    its own factorization, threads and graph); the fixed variables are already
    eliminated.

    Parameters
    ----------
    K : (nu, nu) scipy.sparse csr
        The SPD free block ``Q[U, U]``.
    solve : callable
        ``solve(B)`` returns ``K^-1 B`` for a (nu, k) Fortran-ordered float64 array
        (a sparse Cholesky factor's solve).
    lo, hi : (nu,) float
        The bounds, ``lo < hi`` (either may be infinite).
    tol : float
        KKT tolerance of the natural residual.
    max_iter : int
        Rounds per column.
    neighbors : (nu, nu) scipy.sparse csr
        The graph of the candidate rule (module doc, step 1).
    backend : str
        Sparse Cholesky backend of the polish (:class:`._cholesky.Factor`).
    dK : (nu,) float, optional
        ``K.diagonal()``, when the caller has it.
    on_done : callable, optional
        ``on_done(k)`` when k more columns have finished their rounds, and
        ``on_done(0)`` at the start of every round (of the polish too), so that a
        caller can report progress, or cancel by raising from it.

    Attributes
    ----------
    n_solves : int
        Right-hand sides passed to ``solve`` so far.
    """

    def __init__(self, K: sp.csr_array, solve: Callable[[np.ndarray], np.ndarray], *,
                 lo: np.ndarray, hi: np.ndarray, tol: float, max_iter: int,
                 neighbors: sp.csr_array, backend: str, dK: np.ndarray | None = None,
                 on_done: Callable[[int], None] | None = None):
        self.K, self.solve, self.tol, self.max_iter = K, solve, tol, max_iter
        self.dK = K.diagonal() if dK is None else dK
        self.lo, self.hi = lo, hi
        self.neighbors, self.backend, self.on_done = neighbors, backend, on_done
        self.delta = 0.25 * tol
        self.n_solves = 0
        self.nu = K.shape[0]

    # ---- pieces (also used by BBW's partition-of-unity variant) -------------------------
    def solve_unit(self, verts: np.ndarray) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """Yield (chunk of variables, ``K^-1 E_chunk``) for unit right-hand sides at ``verts``."""
        chunk = solve_chunk(self.nu)
        for i in range(0, verts.size, chunk):
            cv = verts[i:i + chunk]
            unit = np.zeros((self.nu, cv.size), order="F")     # CHOLMOD's layout: no copy
            unit[cv, np.arange(cv.size)] = 1.0
            self.n_solves += cv.size
            yield cv, self.solve(unit)

    def candidates(self, v: np.ndarray, excluded: np.ndarray) -> np.ndarray:
        """Variables to constrain next: violated (``v > tol / 4``) local maxima of the
        violation ``v``, largest first, at most ``_BATCH``."""
        v = np.where(excluded, 0.0, v)
        viol = v > self.delta
        if not viol.any():
            return np.zeros(0, dtype=np.int64)
        peak = _local_maxima(v, self.neighbors)
        cand = np.flatnonzero(viol & peak)
        return cand[np.argsort(-v[cand], kind="stable")][:_BATCH]

    def residual(self, x: np.ndarray, c: np.ndarray) -> float:
        """Natural KKT residual of one column (:func:`kkt_residual`)."""
        return _natural_residual(self.K, x, c, self.dK, self.lo, self.hi)

    # ---- the iterations -----------------------------------------------------------------
    def run(self, Xu: np.ndarray, C: np.ndarray) -> BoxQPResult:
        """Solve from the unconstrained minimisers ``Xu = -K^-1 C`` (nu, m).

        Returns the :class:`BoxQPResult` (its ``x``: (nu, m)); ``n_solves`` counts the
        solves of this call, not those that made ``Xu``.
        """
        nu, m = Xu.shape
        lo, hi = self.lo, self.hi
        n0 = self.n_solves
        X = Xu.copy()
        schur = [_Schur(v=np.int64, upper=bool) for _ in range(m)]   # working set S_j
        green = _Green(nu, max(64, int(np.sqrt(_CACHE_BYTES / 8))))
        iters = np.zeros(m, dtype=np.int64)
        done = np.zeros(m, dtype=bool)
        for _ in range(self.max_iter):
            if self.on_done is not None:
                self.on_done(0)          # a round: report (and let a cancel stop it)
            new = {}
            for j in np.flatnonzero(~done):
                x, sj = X[:, j], schur[j]
                excl = np.zeros(nu, dtype=bool)
                excl[sj.get("v")] = True
                cand = self.candidates(np.maximum(lo - x, x - hi), excl)
                if cand.size == 0:
                    done[j] = True
                    if self.on_done is not None:
                        self.on_done(1)
                    continue
                iters[j] += 1
                new[j] = cand          # a dropped constraint that is violated again is new
            if not new:
                break
            blocks = self._columns(green, new, {j: schur[j].meta["v"] for j in new})
            rhs = np.zeros((nu, len(new)), order="F")
            for col, (j, cand) in enumerate(new.items()):
                sj = schur[j]
                A, s = blocks[j], sj.size
                sj.append(A[:s], A[s:], v=cand, upper=X[cand, j] > hi[cand])
                sig = self._multipliers(sj, Xu[:, j])
                rhs[sj.get("v"), col] = sig
            Y = self.solve(rhs)
            self.n_solves += rhs.shape[1]
            for col, j in enumerate(new):
                X[:, j] = Xu[:, j] + Y[:, col]
        if self.on_done is not None and not done.all():
            self.on_done(int((~done).sum()))
        return self._finish(X, C, schur, iters, n0)

    def _columns(self, green: _Green, new: dict, slots: dict) -> dict:
        """For each column j: ``K^-1[slots_j + new_j, new_j]``, solving only what is missing.

        The new variables of all columns are solved together (one multi-RHS solve);
        the cache serves repeats across columns and rounds.
        """
        if not new:
            return {}
        need = np.unique(np.concatenate(list(new.values())))
        fresh = need[green.pos[need] < 0]
        cache_all = fresh.size <= green.room()
        direct = {j for j, cand in new.items()
                  if not green.has(slots[j]) or (not cache_all and not green.has(cand))}
        if direct:           # the cache is full: these columns take rows of fresh solves
            fresh = np.unique(np.concatenate([fresh] + [new[j] for j in direct]))
        rows = {j: np.concatenate([slots[j], new[j]]) for j in direct}
        blocks = {j: np.empty((rows[j].size, new[j].size)) for j in direct}
        posmap = np.full(self.nu, -1, dtype=np.int64)
        for cv, Y in self.solve_unit(fresh):
            if cache_all:
                out = green.pos[cv] < 0
                green.add(cv[out], Y[:, out])
            posmap[cv] = np.arange(cv.size)
            for j in direct:
                p = posmap[new[j]]
                here = p >= 0
                if here.any():
                    blocks[j][:, here] = Y[np.ix_(rows[j], p[here])]
            posmap[cv] = -1
        for j, cand in new.items():
            if j not in direct:
                blocks[j] = green.block(np.concatenate([slots[j], cand]), cand)
        return blocks

    def _multipliers(self, sj: _Schur, xu: np.ndarray) -> np.ndarray:
        """Solve for the live multipliers; drop those of the wrong sign until none is.

        ``x_S = x_u[S] + H sigma`` must equal the bounds; ``sigma = (K x + c)[S]`` is
        ``mu >= 0`` at a lower bound and ``-mu <= 0`` at an upper one.
        """
        while True:
            v, upper = sj.get("v"), sj.get("upper")
            sig = sj.solve(np.where(upper, self.hi[v], self.lo[v]) - xu[v])
            mu = np.where(upper, -sig, sig) / self.dK[v]
            bad = mu < -self.delta
            if not bad.any():
                return sig
            sj.drop(bad)

    def _finish(self, X, C, schur, iters, n0) -> BoxQPResult:
        nu, m = X.shape
        res = np.zeros(m)
        n_polish = np.zeros(m, dtype=np.int64)
        for j in range(m):
            x = np.clip(X[:, j], self.lo, self.hi)
            v, upper = schur[j].get("v"), schur[j].get("upper")
            x[v] = np.where(upper, self.hi[v], self.lo[v])
            r = self.residual(x, C[:, j])
            if r > self.tol:
                x, r, n_polish[j] = self._polish(x, C[:, j])
            X[:, j], res[j] = x, r
        return BoxQPResult(
            x=X, kkt_residual=res, iterations=iters + n_polish,
            n_constraints=np.array([sj.size for sj in schur]), n_polish=n_polish,
            converged=res <= self.tol, n_solves=self.n_solves - n0, tol=self.tol)

    def _polish(self, x: np.ndarray, c: np.ndarray):
        """Primal active-set (semismooth Newton) iterations from x; sparse factor each time."""
        K, dK, lo, hi = self.K, self.dK, self.lo, self.hi
        at_lo, at_hi = x <= lo, x >= hi
        best = (x, self.residual(x, c))
        for it in range(1, _POLISH_ITER + 1):
            if self.on_done is not None:
                self.on_done(0)
            F = np.flatnonzero(~(at_lo | at_hi))
            y = np.where(at_hi, hi, np.where(at_lo, lo, 0.0))
            if F.size:
                rhs = -(c + K @ y)[F]
                y[F] = Factor(K[F][:, F], self.backend).solve(rhs)
            z = K @ y + c
            yc = np.clip(y, lo, hi)
            r = self.residual(yc, c)
            if r < best[1]:
                best = (yc, r)
            if r <= self.tol:
                return yc, r, it
            ztol = self.delta * dK
            new_lo = (y < lo) | (at_lo & (z >= -ztol))
            new_hi = (y > hi) | (at_hi & (z <= ztol))
            if np.array_equal(new_lo, at_lo) and np.array_equal(new_hi, at_hi):
                break
            at_lo, at_hi = new_lo, new_hi
        return best[0], best[1], it


# --------------------------------------------------------------------------------------
def _matrix(Q) -> sp.csr_array:
    if sp.issparse(Q):
        Q = sp.csr_array(Q, dtype=np.float64)
    else:
        Q = sp.csr_array(_checks.real_array("Q", Q, ndim=2))
    if Q.ndim != 2 or Q.shape[0] != Q.shape[1] or Q.shape[0] == 0:
        raise ValueError(f"Q must be a square (n, n) matrix with n >= 1, got shape {Q.shape}")
    Q.sum_duplicates()
    if not np.all(np.isfinite(Q.data)):
        raise ValueError("Q must be finite, got non-finite stored values")
    asym = abs(Q - Q.T).max() if Q.nnz else 0.0
    if asym > 1e-12 * max(abs(Q).max(), 1e-300):
        raise ValueError(f"Q must be symmetric, got max |Q - Q^T| = {asym:.3g}")
    return Q


def _bounds(name: str, x, n: int) -> np.ndarray:
    a = np.asarray(x, dtype=np.float64)
    if a.ndim == 0:
        a = np.full(n, float(a))
    if a.shape != (n,):
        raise ValueError(f"{name} must be a number or have shape ({n},), got {a.shape}")
    if np.any(np.isnan(a)):
        raise ValueError(f"{name} must not hold NaN")
    return a


def kkt_residual(Q, x, c, *, lo=0.0, hi=1.0):
    """Natural KKT residual of ``min 1/2 x^T Q x + c^T x, lo <= x <= hi`` at ``x``.

    ``r = max_i |x_i - clip(x_i - g_i / Q_ii, lo_i, hi_i)|`` with the gradient
    ``g = Q x + c``: zero exactly at the minimiser, and measured in the units of ``x``
    (the projected gradient step scaled by the diagonal).

    Parameters
    ----------
    Q : (n, n) float, dense or scipy.sparse
        Symmetric with a positive diagonal.
    x : (n,) or (n, m) float
    c : (n,) or (n, m) float
        Shaped like ``x``.
    lo, hi : float or (n,) float

    Returns
    -------
    r : float, or (m,) float64 for 2-D ``x``

    Examples
    --------
    >>> import numpy as np
    >>> Q, c = np.array([[2.0]]), np.array([-4.0])       # minimum at x = 2, outside [0, 1]
    >>> float(kkt_residual(Q, np.array([1.0]), c))       # x = 1 is the constrained minimum
    0.0
    >>> float(kkt_residual(Q, np.array([0.5]), c))       # a step of 1.5, clipped to 0.5
    0.5
    """
    Q = _matrix(Q)
    n = Q.shape[0]
    X = _checks.real_array("x", x)
    Cm = _checks.real_array("c", c, shape=X.shape)
    if X.ndim not in (1, 2) or X.shape[0] != n:
        raise ValueError(f"x must have shape ({n},) or ({n}, m), got {X.shape}")
    d = Q.diagonal()
    if np.any(d <= 0):
        raise ValueError(f"Q must have a positive diagonal, got Q[{int(np.argmin(d))}, "
                         f"{int(np.argmin(d))}] = {d.min():.6g}")
    lo, hi = _bounds("lo", lo, n), _bounds("hi", hi, n)
    if X.ndim == 1:
        return _natural_residual(Q, X, Cm, d, lo, hi)
    return np.array([_natural_residual(Q, X[:, j], Cm[:, j], d, lo, hi)
                     for j in range(X.shape[1])])


def box_qp(Q, c, *, lo=0.0, hi=1.0, fixed=None, values=None, tol: float = 1e-10,
           max_iter: int = 200, neighbors=None,
           backend: Literal["auto", "cholmod", "cholespy", "scipy"] = "auto") -> BoxQPResult:
    """Minimise ``1/2 x^T Q x + c^T x`` subject to ``lo <= x <= hi`` and ``x[fixed] = values``.

    The dual active-set method of the module docstring; the columns of a 2-D ``c`` are
    independent problems sharing ``Q`` (one factorization).

    Parameters
    ----------
    Q : (n, n) float, dense or scipy.sparse
        Symmetric, and positive definite on the free variables.
    c : (n,) or (n, m) float
        Linear term(s).
    lo, hi : float or (n,) float
        Bounds of the free variables, ``lo < hi``; ``-inf`` / ``inf`` for none.
    fixed : (k,) int, optional
        Variables held at ``values`` (no repeats); the bounds do not apply to them.
    values : (k,) or (k, m) float, optional
        Their values (a 1-D array serves every column).
    tol : float
        KKT tolerance of the natural residual (:func:`kkt_residual`), in units of x.
    max_iter : int
        Rounds of the active-set method per column.
    neighbors : (n, n) scipy.sparse, optional
        Graph of the variables: one round constrains only variables whose violation is
        at least every neighbour's (default: the sparsity pattern of ``Q``).
    backend : {"auto", "cholmod", "cholespy", "scipy"}
        Sparse Cholesky backend.

    Returns
    -------
    BoxQPResult
        ``.x`` shaped like ``c``; convergence per column. A column that misses ``tol``
        is reported in ``.converged`` (no warning).

    Raises
    ------
    ValueError
        For bad shapes, ``lo >= hi``, a non-symmetric ``Q``, or a ``Q`` that is not
        positive definite on the free variables.

    Examples
    --------
    >>> import numpy as np
    >>> Q = np.array([[2.0, 0.0], [0.0, 2.0]])
    >>> c = np.array([-4.0, 1.0])                  # unconstrained minimum (2, -0.5)
    >>> box_qp(Q, c, lo=0.0, hi=1.0).x             # both clamped: x0 at 1, x1 at 0
    array([1., 0.])
    """
    Q = _matrix(Q)
    n = Q.shape[0]
    Cm = _checks.real_array("c", c)
    if Cm.ndim not in (1, 2) or Cm.shape[0] != n:
        raise ValueError(f"c must have shape ({n},) or ({n}, m), got {Cm.shape}")
    vector = Cm.ndim == 1
    Cm = Cm.reshape(n, -1)
    m = Cm.shape[1]
    lo, hi = _bounds("lo", lo, n), _bounds("hi", hi, n)
    if np.any(lo >= hi):
        i = int(np.flatnonzero(lo >= hi)[0])
        raise ValueError(f"lo must be < hi, got lo[{i}] = {lo[i]:g} >= hi[{i}] = {hi[i]:g} "
                         "(hold a variable with fixed= and values=)")
    tol = float(tol)
    if not tol > 0:
        raise ValueError(f"tol must be > 0, got {tol}")
    if int(max_iter) < 1:
        raise ValueError(f"max_iter must be >= 1, got {max_iter}")
    _checks.choice("backend", backend, BACKENDS)
    if (fixed is None) != (values is None):
        raise ValueError("fixed and values go together: give both or neither")
    b = np.zeros(0, dtype=np.int64) if fixed is None else _checks.index_array(
        "fixed", fixed, ndim=1)
    xb = np.zeros((0, m))
    if fixed is not None:
        if b.size and (b.min() < 0 or b.max() >= n):
            bad = int(b.min()) if b.min() < 0 else int(b.max())
            raise ValueError(f"fixed must hold indices in 0..{n - 1}, got {bad}")
        if np.unique(b).size != b.size:
            raise ValueError("fixed must not repeat a variable")
        xb = _checks.real_array("values", values)
        if xb.ndim == 1:
            xb = np.repeat(xb[:, None], m, axis=1)
        if xb.shape != (b.size, m):
            raise ValueError(f"values must have shape ({b.size},) or ({b.size}, {m}), "
                             f"got {xb.shape}")
    if neighbors is None:
        G = sp.csr_array(Q, copy=True)
    else:
        G = sp.csr_array(neighbors)
        if G.shape != (n, n):
            raise ValueError(f"neighbors must have shape ({n}, {n}), got {G.shape}")
    U = np.setdiff1d(np.arange(n), b)
    X = np.empty((n, m))
    X[b] = xb
    if U.size == 0:
        z = np.zeros(m, dtype=np.int64)
        return BoxQPResult(X[:, 0] if vector else X, np.zeros(m), z, z, z,
                           np.ones(m, dtype=bool), 0, tol)
    QU = Q[U]
    K = sp.csr_array(QU[:, U])
    CU = Cm[U] + (np.asarray(QU[:, b] @ xb) if b.size else 0.0)
    try:
        factor = Factor(K, backend)
    except np.linalg.LinAlgError as exc:
        raise ValueError(f"Q restricted to the free variables is not positive definite "
                         f"({exc})") from exc
    Xu = -factor.solve(CU)
    GU = sp.csr_array(G[U][:, U])
    engine = DualActiveSet(K, factor.solve, lo=lo[U], hi=hi[U], tol=tol,
                           max_iter=int(max_iter), neighbors=GU, backend=factor.backend)
    res = engine.run(Xu, CU)
    X[U] = res.x
    res.x = X[:, 0] if vector else X
    res.n_solves += m
    return res
