"""Bounded biharmonic weights (Jacobson, Baran, Popovic & Sorkine, SIGGRAPH 2011).

Each weight function ``w`` minimises the discrete Laplacian energy

    1/2 w^T Q w,    Q = L M^-1 L      (L: cotangent Laplacian, M: lumped mass)

subject to the boundary conditions ``w[b] = bc`` and the bounds ``0 <= w <= 1``; with
``partition_of_unity=True`` all functions are solved together under ``sum_j w_j = 1``.

The solver (see ``docs/bbw.md`` for the derivation and measurements)
--------------------------------------------------------------------
With ``U`` the unknown vertices, ``K = Q[U, U]`` and ``c = Q[U, b] bc``, the KKT
conditions say ``K x + c = mu`` with multipliers ``mu`` that are non-zero only where a
bound is active -- and for the biharmonic obstacle problem only on a thin band at the
edge of the region where ``w = 0`` (inside that region ``K x + c = 0`` already). So

    x = x_u + K^-1 E_S sigma,      x_u = -K^-1 c    (the unconstrained solution)

where ``S`` is the small *working set* of constrained vertices. The method is a dual
active-set (Schur complement) method on ``S``:

1. factor ``K`` **once** (sparse Cholesky, :mod:`._cholesky`) for all weight functions
   and all iterations, and warm-start every function from ``x_u``;
2. add the vertices where the bounds are violated most (local maxima of the
   violation over the 1-ring, in batches) to ``S``; their columns of ``K^-1`` come
   from one multi-right-hand-side solve shared by all functions;
3. solve the dense Schur complement system ``(K^-1)[S, S] sigma = target - x_u[S]``
   with a Cholesky factor that grows by block updates;
4. drop constraints whose multipliers have the wrong sign; recompute ``x`` with one
   solve; repeat until no bound is violated by more than ``tol / 4``.

The result is checked against the KKT conditions of the original QP on every vertex
(the *natural residual* ``max |x - clip(x - (K x + c) / diag K, 0, 1)|``, in weight
units); a function that misses ``tol`` is finished by a primal active-set
(semismooth Newton) polish with sparse factorizations of the free-variable system.

Steps 2-4, the KKT check and the polish are the box-constrained QP solver of
:mod:`stbs.weights.qp`, which knows no mesh: this module brings the mesh (``L``,
``M``, the 1-ring as the graph of step 2), the boundary conditions, the factor and
its threads, the parts of the mesh and their scheduling, and the
partition-of-unity variant (which couples the functions, from the same pieces).
"""

from __future__ import annotations

import contextlib
import threading
import time
import warnings
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from .. import _checks
from ..methods import BONE_METHODS
from ..skeleton import Skeleton
from . import _cholmod
from ._cholesky import Factor
from ._deprecate import renamed
from ._progress import Guard, check_callable
from .laplacian import MASS_TYPES, cotmatrix, massmatrix
from .qp import DualActiveSet, _Green, _Schur

__all__ = ["BBWSolver", "BBWReport", "BBWConvergenceWarning", "bbw", "bone_weights",
           "BONE_METHODS"]

BoneMethod = Literal["bbw", "heat"]

_REGION_MAX = 0.2     # a function whose part exceeds this share of the mesh uses the whole
_MARGIN_RINGS = 3     # rings added around a function's cells
_GROW_RINGS = 4       # rings added around vertices where the KKT check failed
_GROW_MAX = 4         # times a part is grown before the function is solved on the whole


class BBWConvergenceWarning(UserWarning):
    """A weight function did not reach the requested KKT tolerance."""


@dataclass
class BBWReport:
    """Convergence of the last :meth:`BBWSolver.solve`, one entry per weight function.

    Attributes
    ----------
    iterations : (m,) int
        Rounds of the dual active-set method (plus polish iterations, if any).
    kkt_residual : (m,) float
        Final natural KKT residual of the QP, in weight units (see module doc).
    n_lower, n_upper : (m,) int
        Unknown vertices where the weight sits at 0 or at 1 (the active set).
    n_constraints : (m,) int
        Size of the final working set S (vertices with a non-zero bound multiplier).
    n_polish : (m,) int
        Primal active-set iterations of the fallback polish (0 when not needed).
    converged : (m,) bool
        ``kkt_residual <= tol``.
    partition_of_unity : bool
    tol : float
    backend : str
        Sparse Cholesky backend.
    n_solves : int
        Right-hand sides solved with the shared factor (all functions together).
    seconds : dict
        Wall time of the phases: ``"factor"``, ``"solve"``, ``"total"``.
    """

    iterations: np.ndarray
    kkt_residual: np.ndarray
    n_lower: np.ndarray
    n_upper: np.ndarray
    n_constraints: np.ndarray
    n_polish: np.ndarray
    converged: np.ndarray
    partition_of_unity: bool
    tol: float
    backend: str
    n_solves: int = 0
    seconds: dict = field(default_factory=dict)

    @property
    def all_converged(self) -> bool:
        return bool(np.all(self.converged))

    def __str__(self) -> str:
        lines = [f"BBW: {self.iterations.size} functions, backend {self.backend}, "
                 f"tol {self.tol:g}, partition of unity {self.partition_of_unity}, "
                 f"{self.n_solves} solves, "
                 + ", ".join(f"{k} {v:.3f}s" for k, v in self.seconds.items()),
                 " fn  iters  polish  |S|  at0  at1  kkt_residual  converged"]
        for j in range(self.iterations.size):
            lines.append(f"{j:3d}  {self.iterations[j]:5d}  {self.n_polish[j]:6d}  "
                         f"{self.n_constraints[j]:4d}  {self.n_lower[j]:4d}  "
                         f"{self.n_upper[j]:4d}  {self.kkt_residual[j]:12.3e}  "
                         f"{bool(self.converged[j])}")
        return "\n".join(lines)


# --------------------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------------------
def _blas_threads(threads: int | None):
    """Limit BLAS threads while solving (threadpoolctl, when installed).

    The work is many mid-sized dense and multi-right-hand-side triangular solves: on a
    busy or small machine extra BLAS threads (numpy's and CHOLMOD's pools compete)
    cost more than they bring, several times over on the 2-core machines we measured.
    """
    if threads is None:
        return contextlib.nullcontext()
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover - optional
        return contextlib.nullcontext()
    # threadpoolctl limits only the BLAS libraries loaded when the limit is taken. The
    # system CHOLMOD brings its own (e.g. libopenblas) when it is first loaded, which
    # would otherwise happen inside the limit, at the first factorization, leaving
    # CHOLMOD's BLAS threads unlimited: measured 2.5x slower at 50k (142 s against
    # 56 s) in a fresh process.
    _cholmod.library()
    return threadpool_limits(limits=threads, user_api="blas")


def _simplex_projection(Y: np.ndarray) -> np.ndarray:
    """Project each row of Y (n, m) onto the probability simplex (sort-based, vectorised)."""
    n, m = Y.shape
    S = -np.sort(-Y, axis=1)
    css = np.cumsum(S, axis=1) - 1.0
    k = np.arange(1, m + 1)
    cond = S - css / k > 0
    r = m - 1 - np.argmax(cond[:, ::-1], axis=1)
    theta = css[np.arange(n), r] / (r + 1)
    return np.maximum(Y - theta[:, None], 0.0)


@dataclass
class _Prepared:
    """Everything that depends on (mesh, b) only: shared by all solves with the same b."""

    key: bytes
    U: np.ndarray            # (n_u,) unknown vertex ids
    K: sp.csr_array          # Q[U, U]
    QUb: sp.csr_array        # Q[U, b_sorted]
    b_sorted: np.ndarray
    dK: np.ndarray
    backend: str
    threads: int = 1
    factor_seconds: float = 0.0
    _factor: Factor | None = None
    _lock: threading.Lock = field(default_factory=threading.Lock)

    @property
    def factor(self) -> Factor:
        """Sparse Cholesky factor of K, computed on first use (regions may not need it)."""
        with self._lock:
            return self._make_factor()

    def _make_factor(self) -> Factor:
        if self._factor is None:
            t = time.perf_counter()
            try:
                self._factor = Factor(self.K, self.backend, self.threads)
            except np.linalg.LinAlgError as exc:
                raise ValueError(f"the bilaplacian restricted to the free vertices is not "
                                 f"positive definite ({exc}); is the mesh degenerate?") from exc
            self.factor_seconds += time.perf_counter() - t
        return self._factor


class BBWSolver:
    """Precomputed operators for bounded biharmonic weights on one mesh.

    Parameters
    ----------
    V : (n, d) float
        Vertex positions, d = 2 or 3.
    Ele : (f, 3) int or (t, 4) int
        The elements: triangles ``F`` (a 2D mesh, or a surface in 3D) or tetrahedra
        ``T`` (3D volume). The keyword ``E=`` is deprecated (``E`` means endpoint
        weights in stbs).
    backend : {"auto", "cholmod", "cholespy", "scipy"}
        Sparse Cholesky backend (:mod:`stbs.weights._cholesky`).
    mass : {"default", "voronoi", "barycentric"}
        Lumped mass matrix (libigl's default: voronoi for triangles, barycentric for tets).
    degenerate : {"raise", "skip"}
        Zero-measure elements: an error, or left out (:mod:`stbs.weights.laplacian`).
    blas_threads : int or None
        BLAS threads while solving (needs ``threadpoolctl``); None leaves them alone.
    threads : int or None
        Threads for the many-right-hand-side sparse solves and for the functions
        solved on parts of the mesh, each with ``blas_threads`` BLAS threads (the
        ``"cholmod"`` backend through ctypes; the others use one). None: the cores this
        process may use, at most 8.

    Attributes
    ----------
    V : (n, d) float64
    Ele : (e, 3) or (e, 4) int64
        The mesh, as validated.
    L : (n, n) sparse
        Cotangent Laplacian (negative semi-definite).
    M : (n, n) sparse diagonal
        Lumped mass matrix.
    Q : (n, n) sparse
        Bilaplacian ``L M^-1 L``.
    last_report : BBWReport or None
        Convergence of the last :meth:`solve`.

    Examples
    --------
    A 4 x 1 strip of 8 triangles, one function held at 1 on the left edge and one on
    the right edge (``b``: vertex ids, ``bc``: one column per function):

    >>> import numpy as np
    >>> x, y = np.meshgrid(np.arange(5.0), np.arange(2.0), indexing="ij")
    >>> V = np.c_[x.ravel(), y.ravel()]           # vertex 2 i + j at (i, j)
    >>> q = 2 * np.arange(4)
    >>> F = np.r_[np.c_[q, q + 2, q + 3], np.c_[q, q + 3, q + 1]]
    >>> solver = BBWSolver(V, F)
    >>> W = solver.solve([0, 1, 8, 9], [[1, 0], [1, 0], [0, 1], [0, 1]])
    >>> W.shape, bool(W.min() >= 0 and W.max() <= 1), solver.last_report.all_converged
    ((10, 2), True, True)
    >>> W[4].round(6)                             # the middle: equally far from both ends
    array([0.5, 0.5])
    """

    @renamed("E", "Ele")
    def __init__(self, V, Ele, *,
                 backend: Literal["auto", "cholmod", "cholespy", "scipy"] = "auto",
                 mass: Literal["default", "voronoi", "barycentric"] = "default",
                 degenerate: Literal["raise", "skip"] = "raise",
                 blas_threads: int | None = 1, threads: int | None = None):
        V = _checks.vertices(V)
        Ele = _checks.index_array("Ele", Ele, ndim=2)
        if Ele.shape[1] not in (3, 4) or Ele.shape[0] == 0:
            raise ValueError(f"Ele must have shape (f, 3) (triangles) or (t, 4) (tetrahedra) "
                             f"with at least one element, got {Ele.shape}")
        _checks.choice("backend", backend, ("auto", "cholmod", "cholespy", "scipy"))
        _checks.choice("mass", mass, MASS_TYPES)
        self.V, self.Ele, self.backend = V, Ele, backend
        if blas_threads is not None and int(blas_threads) < 1:
            raise ValueError(f"blas_threads must be >= 1 or None, got {blas_threads}")
        self.blas_threads = blas_threads
        if threads is not None and int(threads) < 1:
            raise ValueError(f"threads must be >= 1 or None, got {threads}")
        self.threads = _cholmod.default_threads() if threads is None else int(threads)
        self.n = int(V.shape[0])
        self.L = cotmatrix(V, Ele, degenerate=degenerate)
        self.M = massmatrix(V, Ele, type=mass, degenerate=degenerate)
        m = self.M.diagonal()
        minv = np.divide(1.0, m, out=np.zeros_like(m), where=m > 0)
        self.Q = sp.csr_array(self.L @ sp.diags_array(minv) @ self.L)
        self.Q.sum_duplicates()
        A = sp.csr_array(self.L.copy())
        A.setdiag(0)
        A.eliminate_zeros()
        A.data[:] = 1.0
        self._referenced = np.zeros(self.n, dtype=bool)
        self._referenced[Ele.ravel()] = True
        # Every row has an entry (the 1-ring graph of the QP's candidate rule and of the
        # parts' rings): an isolated vertex points to itself.
        self._adj = sp.csr_array(A + sp.diags_array((np.diff(A.indptr) == 0).astype(float)))
        self._n_comp, self._comp = connected_components(A, directed=False)
        self._prepared: _Prepared | None = None
        self._graph: sp.csr_array | None = None
        self.last_report: BBWReport | None = None

    @property
    def E(self) -> np.ndarray:
        """Deprecated name of :attr:`Ele` (``E`` means endpoint weights)."""
        warnings.warn("BBWSolver.E is deprecated and will be removed in the next release: "
                      "the elements are BBWSolver.Ele (E means endpoint weights in stbs)",
                      DeprecationWarning, stacklevel=2)
        return self.Ele

    # ----------------------------------------------------------------------------------
    def _check_bc(self, b, bc, partition_of_unity: bool) -> tuple[np.ndarray, np.ndarray]:
        b = _checks.index_array("b", b, ndim=1)
        bc = np.asarray(bc, dtype=float) if not sp.issparse(bc) else bc.toarray()
        if bc.ndim == 1:
            bc = bc[:, None]
        bc = _checks.real_array("bc", bc, ndim=2)
        if bc.shape[0] != b.shape[0]:
            raise ValueError(f"bc must have one row per entry of b: expected shape "
                             f"({b.shape[0]}, m), got {bc.shape}")
        if b.size == 0 or bc.shape[1] == 0:
            raise ValueError(f"b and bc must constrain at least one vertex and one function, "
                             f"got b {b.shape}, bc {bc.shape}")
        if b.min() < 0 or b.max() >= self.n:
            bad = int(b.min()) if b.min() < 0 else int(b.max())
            raise ValueError(f"b must hold vertex indices in 0..{self.n - 1}, got {bad}")
        u, cnt = np.unique(b, return_counts=True)
        if np.any(cnt > 1):
            raise ValueError(f"b must not repeat a vertex, got vertex {u[cnt > 1][0]} "
                             f"{cnt.max()} times")
        if bc.min() < -1e-12 or bc.max() > 1 + 1e-12:
            raise ValueError(f"bc must lie in [0, 1] (the bounds of the weights), got values "
                             f"in [{bc.min():.6g}, {bc.max():.6g}]")
        if partition_of_unity:
            s = bc.sum(axis=1)
            if np.any(np.abs(s - 1) > 1e-8):
                i = int(np.argmax(np.abs(s - 1)))
                raise ValueError(f"partition_of_unity needs rows of bc summing to 1, but row "
                                 f"{i} (vertex {b[i]}) sums to {s[i]:.6g}")
        order = np.argsort(b)
        return b[order], np.clip(bc[order], 0.0, 1.0)

    def _prepare(self, b: np.ndarray) -> _Prepared:
        key = b.tobytes()
        if self._prepared is not None and self._prepared.key == key:
            return self._prepared
        lone = ~self._referenced
        lone[b] = False
        if lone.any():
            i = int(np.flatnonzero(lone)[0])
            raise ValueError(f"V: vertex {i} belongs to no element ({int(lone.sum())} such "
                             "vertices); remove unreferenced vertices or constrain them in b")
        hit = np.zeros(self._n_comp, dtype=bool)
        hit[self._comp[b]] = True
        if not hit.all():
            c = int(np.flatnonzero(~hit)[0])
            members = np.flatnonzero(self._comp == c)
            raise ValueError(f"b constrains no vertex of a connected part of the mesh "
                             f"({members.size} vertices, e.g. vertex {members[0]}): its "
                             "weights would be undetermined; add a handle there or remove it")
        U = np.setdiff1d(np.arange(self.n), b)
        QU = self.Q[U]
        K = sp.csr_array(QU[:, U])
        QUb = sp.csr_array(QU[:, b])
        self._prepared = _Prepared(key, U, K, QUb, b, K.diagonal(), self.backend,
                                    self.threads)
        return self._prepared

    # ----------------------------------------------------------------------------------
    def solve(self, b, bc, *, partition_of_unity: bool = False, tol: float = 1e-10,
              max_iter: int = 200, restrict: bool = True,
              progress: Callable[[int, int], None] | None = None) -> np.ndarray:
        """Bounded biharmonic weights for the boundary conditions ``w[b] = bc``.

        Parameters
        ----------
        b : (k,) int
            Constrained vertex indices (no repeats).
        bc : (k, m) float in [0, 1]
            Their values, one column per weight function. With
            ``partition_of_unity=True`` each row must sum to 1.
        partition_of_unity : bool
            Solve all functions jointly under ``sum_j w_j = 1`` (then ``w <= 1`` is
            implied). Without it each function is an independent QP and rows sum to 1
            only approximately (BBW's weights "nearly" partition unity).
        tol : float
            KKT tolerance: the natural residual of every function, in weight units.
        max_iter : int
            Rounds of the active-set method per function.
        restrict : bool
            Solve each function only on the part of the mesh where it can be
            non-zero (its handles' geodesic cells and the neighbouring cells), with
            ``w = 0`` fixed elsewhere; the KKT conditions are then checked on the
            whole mesh and the part is grown until they hold, so the answer is the
            same as without. Functions whose part would cover most of the mesh
            share one factorization of the whole. Ignored with
            ``partition_of_unity``.
        progress : callable, optional
            ``progress(done, total)``: ``done`` of the ``total = m`` functions are
            finished; called after each function and at every round of the active-set
            method (and of the polish), so at least once per solver iteration. Raise
            any exception from it to cancel: the solve stops at its next report, the
            exception propagates, and ``progress`` is not called again (worker
            threads included).

        Returns
        -------
        W : (n, m) float64
            The raw QP solution, ``0 <= W <= 1`` exactly and ``W[b] = bc``. Convergence
            per function is in :attr:`last_report`; a function that misses ``tol``
            raises a :class:`BBWConvergenceWarning`.
        """
        tol = float(tol)
        if not tol > 0:
            raise ValueError(f"tol must be > 0, got {tol}")
        if int(max_iter) < 1:
            raise ValueError(f"max_iter must be >= 1, got {max_iter}")
        guard = Guard(progress)
        with _blas_threads(self.blas_threads):
            return self._solve(b, bc, bool(partition_of_unity), tol, int(max_iter),
                               bool(restrict), guard)

    def _solve(self, b, bc, partition_of_unity: bool, tol: float, max_iter: int,
               restrict: bool, progress: Guard) -> np.ndarray:
        t0 = time.perf_counter()
        b, bc = self._check_bc(b, bc, partition_of_unity)
        m = bc.shape[1]
        if b.size == self.n:                    # nothing to solve for
            W = np.empty((self.n, m))
            W[b] = bc
            zero = np.zeros(m, dtype=np.int64)
            self.last_report = BBWReport(
                zero, np.zeros(m), zero, zero, zero, zero, np.ones(m, dtype=bool),
                partition_of_unity, tol, self.backend, 0,
                {"factor": 0.0, "solve": 0.0, "total": time.perf_counter() - t0})
            progress(m, m)
            return W
        P = self._prepare(b)
        f0 = P.factor_seconds
        C = np.asarray(P.QUb @ bc)
        if partition_of_unity:
            progress(0, m)
            Xu = -P.factor.solve(C)
            run = _Run(self, P, tol, max_iter, on_done=lambda k: progress(0, m))
            run.n_solves += C.shape[1]
            X, rep = run.pou(Xu, C)
            rep.n_solves = run.n_solves
            progress(m, m)
            t_factor = P.factor_seconds - f0
        else:
            X, rep, t_region = self._solve_boxes(P, C, bc, tol, max_iter, restrict, progress)
            t_factor = P.factor_seconds - f0 + t_region
        W = np.empty((self.n, bc.shape[1]))
        W[P.b_sorted] = bc
        W[P.U] = X
        total = time.perf_counter() - t0
        rep.seconds = {"factor": t_factor, "solve": total - t_factor, "total": total}
        self.last_report = rep
        if not rep.all_converged:
            bad = np.flatnonzero(~rep.converged)
            warnings.warn(f"BBW: {bad.size} of {bc.shape[1]} weight functions (first: "
                          f"{bad[0]}) missed the KKT tolerance {tol:g}; worst residual "
                          f"{rep.kkt_residual.max():.3g} (see solver.last_report)",
                          BBWConvergenceWarning, stacklevel=3)
        return W

    # ---- independent functions, each on its own part of the mesh ------------------------
    def _solve_boxes(self, P: _Prepared, C, bc, tol, max_iter, restrict, progress):
        nu, m = C.shape
        masks = self._regions(P, bc) if restrict and m > 1 else [None] * m
        X = np.zeros((nu, m))
        stats = {k: np.zeros(m, dtype=dt) for k, dt in (
            ("iterations", np.int64), ("kkt_residual", float), ("n_constraints", np.int64),
            ("n_polish", np.int64))}
        totals = {"n_solves": 0, "t_region": 0.0, "done": 0}
        lock = threading.Lock()

        def tick(k: int) -> None:
            """k more functions finished (0: a solver round): report."""
            with lock:
                totals["done"] += k
                done = totals["done"]
            progress(done, m)

        def keep(cols, x, rep, n_solves=0, t_region=0.0):
            X[:, cols] = x
            for k in stats:
                stats[k][cols] = getattr(rep, k)
            with lock:
                totals["n_solves"] += n_solves
                totals["t_region"] += t_region

        def region(j, threads=None) -> bool:
            out = self._solve_in_region(P, C[:, j], masks[j], tol, max_iter, threads,
                                        lambda k: tick(0))
            if out is None:                 # the part kept growing: solve on the whole
                return False
            x, rep, ns, tf = out
            keep([j], x[:, None], rep, ns, tf)
            tick(1)
            return True

        def whole(cols, Xu) -> None:
            run = _Run(self, P, tol, max_iter, on_done=tick)
            x, rep = run.boxes(Xu, C[:, cols])
            keep(cols, x, rep, run.n_solves)

        glob = [j for j in range(m) if masks[j] is None]
        parts = [j for j in range(m) if masks[j] is not None]
        workers = self._workers(len(parts))
        tick(0)
        if workers > 1:
            # Functions on parts of the mesh, each with its own factor, on separate
            # threads (CHOLMOD through ctypes and the dense kernels release the GIL).
            with ThreadPoolExecutor(workers, thread_name_prefix="stbs-bbw") as ex:
                ok = progress.join([ex.submit(region, j, 1) for j in parts])
        else:
            ok = [region(j) for j in parts]
        glob += [j for j, good in zip(parts, ok, strict=True) if not good]
        if glob:
            # Functions on the whole mesh together: one factor, and each round's new
            # columns of all of them in one solve (split over the threads).
            glob = sorted(glob)
            Xu = -P.factor.solve(C[:, glob])
            totals["n_solves"] += len(glob)
            whole(glob, Xu)
        res = stats["kkt_residual"]
        return X, BBWReport(
            iterations=stats["iterations"], kkt_residual=res,
            n_lower=np.sum(X <= 0.0, axis=0), n_upper=np.sum(X >= 1.0, axis=0),
            n_constraints=stats["n_constraints"], n_polish=stats["n_polish"],
            converged=res <= tol, partition_of_unity=False, tol=tol, backend=self.backend
            if self.backend != "auto" else _concrete_backend(),
            n_solves=totals["n_solves"]), totals["t_region"]

    def _workers(self, m: int) -> int:
        """Threads for m independent functions: 1 unless the solves can run at once."""
        return parallel_workers(self.threads, m, self.backend)

    def _labels(self, P: _Prepared, bc: np.ndarray) -> np.ndarray:
        """Per vertex: the function whose handle is geodesically nearest (-1: an all-zero one)."""
        from scipy.sparse.csgraph import dijkstra

        if self._graph is None:
            A = sp.triu(self._adj, k=1, format="coo")
            w = np.linalg.norm(self.V[A.row] - self.V[A.col], axis=1)
            self._graph = sp.csr_array((np.maximum(w, 1e-300), (A.row, A.col)),
                                       shape=(self.n, self.n))
        lab_b = np.where(bc.max(axis=1) > 0, np.argmax(bc, axis=1), -1)
        _, _, src = dijkstra(self._graph, directed=False, indices=P.b_sorted, min_only=True,
                             return_predecessors=True)
        lab = np.full(self.n, -1, dtype=np.int64)
        of_vertex = np.full(self.n, -1, dtype=np.int64)
        of_vertex[P.b_sorted] = lab_b
        reached = src >= 0
        lab[reached] = of_vertex[src[reached]]
        return lab

    def _regions(self, P: _Prepared, bc: np.ndarray) -> list:
        """For each function: a mask over U of where it may be non-zero, or None (whole mesh).

        The part of function j: the cells (vertices nearest, along mesh edges, to a
        handle of some function) of j, of every function with a non-zero handle value
        in column j, and of the functions whose cells touch those.
        """
        nu, m = P.U.size, bc.shape[1]
        lab = self._labels(P, bc)
        A = sp.triu(self._adj, k=1, format="coo")
        la, lb = lab[A.row], lab[A.col]
        cross = (la != lb) & (la >= 0) & (lb >= 0)
        touch = np.zeros((m, m), dtype=bool)
        touch[la[cross], lb[cross]] = True
        touch |= touch.T
        np.fill_diagonal(touch, True)
        labU = lab[P.U]
        self._labU = labU
        masks = []
        for j in range(m):
            own = np.zeros(m, dtype=bool)
            own[np.unique(np.argmax(bc[bc[:, j] > 0], axis=1))] = True
            own[j] = True
            allowed = touch[own].any(axis=0)
            mask = np.zeros(nu, dtype=bool)
            ok = labU >= 0
            mask[ok] = allowed[labU[ok]]
            mask = self._dilate(P, mask, _MARGIN_RINGS)
            masks.append(mask if mask.sum() <= _REGION_MAX * nu else None)
        return masks

    def _solve_in_region(self, P: _Prepared, c: np.ndarray, mask: np.ndarray, tol, max_iter,
                         threads: int | None = None, report: Callable[[int], None] | None = None):
        """One function on ``mask`` (w = 0 outside), grown until the whole QP's KKT hold;
        ``report(0)`` at every solver round."""
        nu = P.U.size
        n_solves, t_factor = 0, 0.0
        for _ in range(_GROW_MAX):
            if mask.sum() > _REGION_MAX * nu:
                return None
            R = np.flatnonzero(mask)
            K = sp.csr_array(P.K[R][:, R])
            Pr = _Prepared(b"", P.U[R], K, None, P.b_sorted, K.diagonal(), self.backend,
                           self.threads)
            cr = c[R][:, None]
            run = _Run(self, Pr, tol, max_iter, threads=threads,
                       on_done=None if report is None else (lambda k: report(0)))
            xu = -Pr.factor.solve(cr, threads=threads)
            run.n_solves += 1
            xr, rep = run.boxes(xu, cr)
            n_solves, t_factor = n_solves + run.n_solves, t_factor + Pr.factor_seconds
            x = np.zeros(nu)
            x[R] = xr[:, 0]
            # Outside the part x = 0: its bound multiplier z = K x + c must be >= 0 there.
            z = P.K @ x + c
            viol = ~mask & (-z / P.dK > tol)
            res_out = float(np.max(np.where(mask, 0.0, np.maximum(-z / P.dK, 0.0)),
                                   initial=0.0))
            rep.kkt_residual = np.maximum(rep.kkt_residual, res_out)
            if not viol.any():
                return x, rep, n_solves, t_factor
            mask = self._grow(P, mask, viol)
        return None

    def _dilate(self, P: _Prepared, mask: np.ndarray, rings: int) -> np.ndarray:
        """``mask`` (over U) grown by ``rings`` rings of mesh neighbours."""
        full = np.zeros(self.n, dtype=bool)
        full[P.U[mask]] = True
        for _ in range(rings):
            full[self._adj.indices[np.repeat(full, np.diff(self._adj.indptr))]] = True
        return full[P.U]

    def _grow(self, P: _Prepared, mask: np.ndarray, viol: np.ndarray) -> np.ndarray:
        """Add the violating vertices and their neighbourhoods to the part."""
        return mask | self._dilate(P, viol, _GROW_RINGS)


def parallel_workers(threads: int, m: int, backend: str = "auto") -> int:
    """Threads for m independent solves: several only on CHOLMOD through ctypes, which
    releases Python's lock while factoring and solving; 1 otherwise."""
    if threads == 1 or m < 2:
        return 1
    backend = backend if backend != "auto" else _concrete_backend()
    if backend != "cholmod" or _cholmod.library() is None:
        return 1
    return min(threads, m)


def _concrete_backend() -> str:
    from ._cholesky import available_backends

    return available_backends()[0]


class _Run:
    """One call of :meth:`BBWSolver.solve` on the free block of ``P``.

    The box QPs (``0 <= w <= 1``) are :class:`.qp.DualActiveSet`'s, given the shared
    factor (with this run's solve threads) and the mesh's 1-ring among the free
    vertices as the graph of its candidate rule; the partition-of-unity variant
    couples the functions and uses the same pieces.
    """

    def __init__(self, solver: BBWSolver, P: _Prepared, tol: float, max_iter: int,
                 on_done: Callable[[int], None] | None = None, threads: int | None = None):
        self.s, self.P, self.tol, self.max_iter = solver, P, tol, max_iter
        self.threads = threads          # for the sparse solves (None: the factor's own)
        self.on_done = on_done
        self.delta = 0.25 * tol
        self.n_solves = 0
        self.nu = P.U.size

    def _qp(self) -> DualActiveSet:
        """The QP engine; the factor exists by now (the caller solved for ``Xu``)."""
        P, U = self.P, self.P.U
        bounds = np.zeros(self.nu), np.ones(self.nu)
        return DualActiveSet(P.K, lambda B: P.factor.solve(B, threads=self.threads),
                             lo=bounds[0], hi=bounds[1], tol=self.tol,
                             max_iter=self.max_iter, neighbors=self.s._adj[U][:, U],
                             backend=P.factor.backend, dK=P.dK, on_done=self.on_done)

    # ---- independent functions, 0 <= w <= 1 --------------------------------------------
    def boxes(self, Xu: np.ndarray, C: np.ndarray):
        res = self._qp().run(Xu, C)
        self.n_solves += res.n_solves
        return res.x, res

    # ---- all functions jointly, w >= 0 and sum_j w_j = 1 --------------------------------
    def pou(self, Xu: np.ndarray, C: np.ndarray):
        """Dual active set with the partition-of-unity multiplier eliminated.

        Stationarity ``K x_j + c_j - mu_j + lam = 0`` with ``sum_j x_j = 1`` gives
        ``lam = mean_j mu_j``, so ``x_j = x_u,j + K^-1 (mu_j - mean_l mu_l)`` and the
        dual system couples the functions through ``(delta_jl - 1/m) K^-1``.

        That elimination uses BBW's own structure: constants are in the null space of
        ``Q`` (``L 1 = 0``) and the rows of ``bc`` sum to 1, so ``K 1 + sum_j c_j = 0``
        and the unconstrained ``x_u`` already sums to 1. It is not a general
        simplex-constrained QP, which is why it lives here and not in :mod:`.qp`
        (whose pieces it uses).
        """
        nu, m = Xu.shape
        qp = self._qp()
        X = Xu.copy()
        green = _Green(nu, None)                  # the coupled system needs every pair
        schur = _Schur(j=np.int64, v=np.int64)    # constraint w_j(v) = 0
        iters = 0
        for _ in range(self.max_iter):
            if self.on_done is not None:
                self.on_done(0)              # a round: report (and let a cancel stop it)
            cj, cv = schur.get("j"), schur.get("v")
            excl = np.zeros((nu, m), dtype=bool)
            excl[cv, cj] = True
            full = excl.sum(axis=1) >= m - 1      # a last free function must stay free
            new_j, new_v = [], []
            for j in range(m):
                cand = qp.candidates(-X[:, j], excl[:, j] | full)
                new_j.append(np.full(cand.size, j))
                new_v.append(cand)
            new_j, new_v = np.concatenate(new_j), np.concatenate(new_v)
            if new_v.size == 0:
                break
            iters += 1
            add = np.unique(new_v)
            add = add[green.pos[add] < 0]
            for cv_, Y in qp.solve_unit(add):
                green.add(cv_, Y)
            if new_v.size:
                aj, av = schur.meta["j"], schur.meta["v"]
                coef12 = (aj[:, None] == new_j[None, :]) - 1.0 / m
                coef22 = (new_j[:, None] == new_j[None, :]) - 1.0 / m
                schur.append(coef12 * green.block(av, new_v),
                             coef22 * green.block(new_v, new_v), j=new_j, v=new_v)
            while True:
                cj, cv = schur.get("j"), schur.get("v")
                mu = schur.solve(-Xu[cv, cj])
                bad = mu / self.P.dK[cv] < -self.delta
                if not bad.any():
                    break
                schur.drop(bad)
            rhs = np.zeros((nu, m))
            np.add.at(rhs, (cv, cj), mu)
            rhs -= rhs.sum(axis=1, keepdims=True) / m
            X = Xu + self.P.factor.solve(rhs)
            self.n_solves += m
        self.n_solves += qp.n_solves
        cons_j, cons_v = schur.get("j"), schur.get("v")
        X = np.maximum(X, 0.0)
        X[cons_v, cons_j] = 0.0
        X /= X.sum(axis=1, keepdims=True)
        Z = self.P.K @ X + C
        R = np.abs(X - _simplex_projection(X - Z / self.P.dK[:, None]))
        res = R.max(axis=0, initial=0.0)
        return X, BBWReport(
            iterations=np.full(m, iters), kkt_residual=res,
            n_lower=np.sum(X <= 0.0, axis=0), n_upper=np.sum(X >= 1.0, axis=0),
            n_constraints=np.bincount(cons_j, minlength=m), n_polish=np.zeros(m, np.int64),
            converged=res <= self.tol, partition_of_unity=True, tol=self.tol,
            backend=self.P.factor.backend)


# --------------------------------------------------------------------------------------
@renamed("E", "Ele")
def bbw(V, Ele, b, bc, *, partition_of_unity: bool = False, tol: float = 1e-10,
        max_iter: int = 200, backend: Literal["auto", "cholmod", "cholespy", "scipy"] = "auto"
        ) -> np.ndarray:
    """One-shot bounded biharmonic weights: ``BBWSolver(V, Ele).solve(b, bc, ...)``.

    Parameters
    ----------
    V : (n, d) float
    Ele : (f, 3) or (t, 4) int
        Triangles or tetrahedra (the keyword ``E=`` is deprecated).
    b : (k,) int
    bc : (k, m) float
    partition_of_unity, tol, max_iter, backend
        See :class:`BBWSolver` and :meth:`BBWSolver.solve`.

    Returns
    -------
    W : (n, m) float64
    """
    return BBWSolver(V, Ele, backend=backend).solve(
        b, bc, partition_of_unity=partition_of_unity, tol=tol, max_iter=max_iter)


def _heat_bone_weights(V: np.ndarray, sk: Skeleton, F, T, options: dict, progress):
    """``bone_weights(method="heat")``: bone heat on the 3D surface ``F`` (as ``stbs rig``)."""
    from .heat import bone_heat

    for name, value in options.items():
        if value is not None:
            raise ValueError(f"{name} applies to method='bbw' only, got {name}={value!r} "
                             "with method='heat'")
    if sk.dim != 3:
        raise ValueError("method='heat' needs a 3D triangle surface F; for a 2D shape use "
                         "method='bbw' (or stbs.weights.bone_heat, which takes 2D triangles)")
    if T is not None:
        raise ValueError("method='heat' works on the surface triangles F (visibility and "
                         "diffusion live on it), not on tetrahedra T"
                         + (": leave T out" if F is not None else "; pass F, got T only"))
    if F is None:
        raise ValueError("method='heat' needs the 3D triangle surface F (f, 3), got F=None")
    return bone_heat(V, F, sk, progress=progress)


def bone_weights(V, sk: Skeleton, *, method: BoneMethod = "bbw", F=None, T=None,
                 partition_of_unity: bool | None = None, samples: int | None = None,
                 tol: float | None = None,
                 progress: Callable[[int, int], None] | None = None) -> np.ndarray:
    """Bone weights W (n, b) for a skeleton, rows summing to 1 (docs/weights.md).

    Parameters
    ----------
    V : (n, d) float
        Rest vertex positions, d = ``sk.dim``.
    sk : Skeleton
    method : {"bbw", "heat"}
        ``"bbw"``: bounded biharmonic weights on a triangle mesh ``F`` (2D) or a
        tetrahedral mesh ``T`` (3D). ``"heat"``: bone heat (Baran & Popović 2007,
        :func:`stbs.weights.bone_heat`) on a 3D triangle surface ``F``, as
        ``stbs rig --bone heat``.
    F : (f, 3) int, optional
        Triangles: required in 2D (``"bbw"``), and the surface for ``"heat"``.
    T : (t, 4) int, optional
        Tetrahedra; required in 3D for ``"bbw"``.
    partition_of_unity : bool, optional
        ``"bbw"`` only: solve with ``sum_i w_i = 1`` as a constraint (slower);
        otherwise (the default) the independent solutions are normalised afterwards,
        as in the BBW paper.
    samples : int, optional
        ``"bbw"`` only: samples per bone for meshes without bone vertices (see
        :func:`stbs.weights.boundary.boundary_conditions`).
    tol : float, optional
        ``"bbw"`` only: KKT tolerance of the QP (default 1e-10).
    progress : callable, optional
        ``progress(done, total)``: ``"bbw"``, as :meth:`BBWSolver.solve` (after each
        bone's function and at every solver round); ``"heat"``, as
        :func:`stbs.weights.bone_heat`. Raise any exception from it to cancel: it
        propagates, and ``progress`` is not called again.

    Returns
    -------
    W : (n, b) float64
        ``W >= 0``, rows sum to 1. ``"bbw"``: ``W[:, i] = 1`` on the vertices lying on
        bone i only.

    Raises
    ------
    TypeError
        When ``sk`` is not a :class:`stbs.Skeleton`.
    ValueError
        For an unknown method, a ``"bbw"`` option given with ``"heat"``, mismatched
        dimensions, missing elements (naming the ones needed), a bone no vertex can be
        attached to, or a vertex that all weights leave at 0.

    Examples
    --------
    A 4 x 2 grid of squares, two bones along its middle line:

    >>> import numpy as np
    >>> import stbs
    >>> x, y = np.meshgrid(np.arange(5.0), np.arange(3.0), indexing="ij")
    >>> V = np.c_[x.ravel(), y.ravel()]           # vertex 3 i + j at (i, j)
    >>> q = np.array([3 * i + j for i in range(4) for j in range(2)])
    >>> F = np.r_[np.c_[q, q + 3, q + 4], np.c_[q, q + 4, q + 1]]
    >>> sk = stbs.Skeleton([[0.0, 1.0], [2.0, 1.0], [4.0, 1.0]], [[0, 1], [1, 2]])
    >>> W = bone_weights(V, sk, F=F)
    >>> W.shape, bool(np.allclose(W.sum(axis=1), 1))
    ((15, 2), True)
    >>> W[[1, 7, 13]].round(6)                    # on bone 0, the shared joint, on bone 1
    array([[1. , 0. ],
           [0.5, 0.5],
           [0. , 1. ]])
    """
    from .boundary import boundary_conditions

    _checks.choice("method", method, BONE_METHODS)
    V = _checks.skeleton(sk, V)
    check_callable(progress)
    if method == "heat":
        return _heat_bone_weights(V, sk, F, T, {"partition_of_unity": partition_of_unity,
                                                "samples": samples, "tol": tol}, progress)
    partition_of_unity = bool(partition_of_unity)
    tol = 1e-10 if tol is None else tol
    if sk.dim == 2:
        if T is not None:
            raise ValueError("T (tetrahedra) was given for a 2D mesh; 2D BBW needs triangles F")
        if F is None:
            raise ValueError("method='bbw' in 2D needs triangles F (f, 3), got F=None")
        Ele = _checks.index_array("F", F, ndim=2, shape=(None, 3))
    else:
        if T is None:
            raise ValueError("method='bbw' in 3D needs a tetrahedral mesh T (t, 4) of the "
                             "volume, got T=None" + (" (F alone is a surface: tetrahedralise "
                                                     "it first)" if F is not None else ""))
        Ele = _checks.index_array("T", T, ndim=2, shape=(None, 4))
    if Ele.size and (Ele.min() < 0 or Ele.max() >= V.shape[0]):
        name = "F" if Ele.shape[1] == 3 else "T"
        bad = int(Ele.min()) if Ele.min() < 0 else int(Ele.max())
        raise ValueError(f"{name} must hold vertex indices in 0..{V.shape[0] - 1}, got {bad}")
    b, bc = boundary_conditions(V, sk, F=Ele if Ele.shape[1] == 3 else None,
                                T=Ele if Ele.shape[1] == 4 else None, samples=samples)
    solver = BBWSolver(V, Ele)
    W = solver.solve(b, bc, partition_of_unity=partition_of_unity, tol=tol, progress=progress)
    s = W.sum(axis=1)
    if np.any(s <= 1e-12):
        i = int(np.argmin(s))
        raise ValueError(f"BBW left vertex {i} with all weights 0; solve with "
                         "partition_of_unity=True or add bone samples near it")
    if not partition_of_unity:
        W = W / s[:, None]
    return W
