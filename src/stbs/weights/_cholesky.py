"""A small sparse Cholesky wrapper: factor a symmetric positive definite matrix once, solve often.

SciPy has no sparse Cholesky. Backends, tried in this order by ``backend="auto"``:

``"cholmod"``
    SuiteSparse CHOLMOD (supernodal, system BLAS), the fastest. The system library
    (``libcholmod``) is called directly through ``ctypes`` where :mod:`._cholmod`
    finds and recognises it, so that ``threads > 1`` solves several right-hand sides
    at once on separate cores; otherwise through scikit-sparse (``sksparse.cholmod``,
    the ``cholmod`` extra), which solves on one core.
``"cholespy"``
    ``cholespy`` (CHOLMOD bundled in a binary wheel, BSD-3). The ``weights`` extra
    installs it; no system packages needed.
``"scipy"``
    ``scipy.sparse.linalg.splu`` in symmetric mode (minimum-degree ordering on
    ``A + A^T``, diagonal pivots). Always there; about half as fast at solving.

Every backend's :meth:`Factor.solve` takes a vector or a matrix of right-hand sides.
Heavy imports happen on first use only.
"""

from __future__ import annotations

import importlib.util
from typing import Literal

import numpy as np
import scipy.sparse as sp

__all__ = ["Factor", "factorize", "BACKENDS", "available_backends"]

#: Backend names accepted by :func:`factorize`.
BACKENDS: tuple[str, ...] = ("auto", "cholmod", "cholespy", "scipy")
_ORDER = ("cholmod", "cholespy", "scipy")
_MODULE = {"cholmod": "sksparse", "cholespy": "cholespy", "scipy": "scipy"}


def _importable(module: str) -> bool:
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):
        return False


def _available(backend: str) -> bool:
    if backend == "cholmod":
        from . import _cholmod

        return _cholmod.library() is not None or _importable("sksparse")
    return _importable(_MODULE[backend])


def available_backends() -> list[str]:
    """The concrete backends usable here, fastest first."""
    return [b for b in _ORDER if _available(b)]


class Factor:
    """A factorization of an SPD matrix ``A`` (n, n); call :meth:`solve`.

    Attributes
    ----------
    backend : str
        The concrete backend used.
    n : int
        Size of ``A``.
    threads : int
        Threads a multi-column :meth:`solve` may use (the ``"cholmod"`` backend through
        ctypes only; the others solve on the calling thread).
    parallel : bool
        Whether solves run outside Python's global interpreter lock (the ``"cholmod"``
        backend through ctypes), so that threads calling :meth:`solve` run at once.
    """

    def __init__(self, A, backend: Literal["auto", "cholmod", "cholespy", "scipy"] = "auto",
                 threads: int = 1):
        if backend not in BACKENDS:
            raise ValueError(f"backend must be one of {', '.join(map(repr, BACKENDS))}, "
                             f"got {backend!r}")
        A = sp.csc_matrix(A, dtype=np.float64)
        if A.shape[0] != A.shape[1]:
            raise ValueError(f"A must be square, got shape {A.shape}")
        A.sum_duplicates()
        A.sort_indices()
        self.n = int(A.shape[0])
        if int(threads) < 1:
            raise ValueError(f"threads must be >= 1, got {threads}")
        self.threads = int(threads)
        self.parallel = False
        if backend == "auto":
            backend = available_backends()[0]
        elif not _available(backend):
            if backend == "cholmod":
                raise ImportError("backend 'cholmod' needs SuiteSparse's CHOLMOD library "
                                  "(Debian: apt-get install libsuitesparse-dev "
                                  "libopenblas0-pthread), or the package 'scikit-sparse' "
                                  "built against it; backend 'cholespy' (pip install "
                                  "'stbs-skinning[weights]') brings CHOLMOD in a wheel")
            raise ImportError(f"backend {backend!r} needs the package {_MODULE[backend]!r}: "
                              f"pip install 'stbs-skinning[weights]'")
        self.backend = backend
        try:
            getattr(self, f"_init_{backend}")(A)
        except (RuntimeError, ValueError, ArithmeticError) as exc:
            # CHOLMOD reports a non-positive-definite matrix in several ways
            raise np.linalg.LinAlgError(f"sparse Cholesky ({backend}) failed: {exc}") from exc

    # -- backends ---------------------------------------------------------------------------
    def _init_cholmod(self, A):
        from . import _cholmod

        if _cholmod.library() is not None:
            self._f = _cholmod.CholmodFactor(A, threads=self.threads)
            self._solve = self._f.solve
            self.parallel = True
            return
        self.threads = 1
        from sksparse.cholmod import CholmodNotPositiveDefiniteError, cholesky

        try:
            self._f = cholesky(A, mode="supernodal")
        except CholmodNotPositiveDefiniteError as exc:
            raise ValueError(str(exc)) from exc
        self._solve = self._f

    def _init_cholespy(self, A):
        self.threads = 1
        from cholespy import CholeskySolverD, MatrixType

        self._f = CholeskySolverD(self.n, A.indptr.astype(np.int32), A.indices.astype(np.int32),
                                  np.ascontiguousarray(A.data), MatrixType.CSC)

        def solve(B):
            B = np.ascontiguousarray(B, dtype=np.float64)
            X = np.empty_like(B)
            self._f.solve(B, X)
            return X

        self._solve = solve
        # cholespy does not report a failed factorization: check one solve.
        e = np.ones(self.n)
        x = solve(e)
        scale = np.abs(A) @ np.abs(x) + 1.0            # backward error, not forward
        if not np.all(np.isfinite(x)) or np.max(np.abs(A @ x - e) / scale) > 1e-8:
            raise ValueError("matrix is not positive definite (the factor does not solve it)")

    def _init_scipy(self, A):
        self.threads = 1
        from scipy.sparse.linalg import splu

        # Symmetric mode: minimum degree on A + A^T and pivots from the diagonal, i.e. a
        # Cholesky-like LU for SPD matrices with half the fill of the default COLAMD.
        lu = splu(A, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                  options={"SymmetricMode": True})
        if not np.all(np.isfinite(lu.U.diagonal())) or np.any(lu.U.diagonal() <= 0):
            raise ValueError("matrix is not positive definite (non-positive pivot)")
        self._solve = lu.solve

    def solve(self, B, threads: int | None = None) -> np.ndarray:
        """Solve ``A X = B``.

        Parameters
        ----------
        B : (n,) or (n, k) float
        threads : int, optional
            Threads for this solve (default :attr:`threads`); any thread may call
            :meth:`solve` while others do.

        Returns
        -------
        X : same shape as B, float64
        """
        B = np.asarray(B, dtype=np.float64)
        if B.shape[0] != self.n or B.ndim not in (1, 2):
            raise ValueError(f"B must have shape ({self.n},) or ({self.n}, k), got {B.shape}")
        if B.ndim == 2 and B.shape[1] == 0:
            return np.zeros_like(B)
        if self.parallel:
            return np.asarray(self._f.solve(B, threads)).reshape(B.shape)
        return np.asarray(self._solve(B)).reshape(B.shape)


def factorize(A, *, backend: Literal["auto", "cholmod", "cholespy", "scipy"] = "auto",
              threads: int = 1) -> Factor:
    """Factor the SPD sparse matrix ``A`` with the chosen backend (see module doc)."""
    return Factor(A, backend, threads)
