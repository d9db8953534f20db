"""The system CHOLMOD library called directly (ctypes), so that solves run on several cores.

scikit-sparse holds Python's global interpreter lock while CHOLMOD solves, so two
threads solving with one factor take turns. A ``ctypes`` call releases the lock: here
each worker thread calls ``cholmod_l_solve`` on its share of the right-hand sides with
its own ``cholmod_common`` (CHOLMOD's workspace; the factor itself is only read).

Only the small, stable part of CHOLMOD's C interface is used (``cholmod_l_start``,
``_analyze``, ``_factorize``, ``_solve``, the ``_free_*`` calls and the
``cholmod_sparse`` / ``cholmod_dense`` structs, unchanged since SuiteSparse 4). The one
two fields of ``cholmod_common`` we write (``print``, to keep CHOLMOD quiet, and
``supernodal``, to always get a supernodal LL^T that detects an indefinite matrix) sit
at version-dependent offsets: :func:`library` checks the defaults ``cholmod_l_start``
writes there and around them, and declines the library (the caller falls back to
scikit-sparse) when they are not where SuiteSparse 4-7 put them.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import struct
import threading
import weakref
from concurrent.futures import ThreadPoolExecutor
from ctypes import POINTER, byref, c_double, c_int, c_size_t, c_void_p

import numpy as np
import scipy.sparse as sp

__all__ = ["library", "CholmodFactor", "default_threads"]

_COMMON_BYTES = 1 << 16      # cholmod_common is ~2.7 kB (SuiteSparse 5); room for growth
_PRINT_OFFSET = 144          # offsetof(cholmod_common, print)
_SUPERNODAL_OFFSET = 48      # offsetof(cholmod_common, supernodal)
_MIN_COLS = 8                # right-hand sides per thread below which one thread solves
_CHOLMOD_LONG, _CHOLMOD_REAL, _CHOLMOD_DOUBLE, _CHOLMOD_A, _CHOLMOD_SUPERNODAL = 2, 1, 0, 0, 2


class _Sparse(ctypes.Structure):
    _fields_ = [("nrow", c_size_t), ("ncol", c_size_t), ("nzmax", c_size_t),
                ("p", c_void_p), ("i", c_void_p), ("nz", c_void_p), ("x", c_void_p),
                ("z", c_void_p), ("stype", c_int), ("itype", c_int), ("xtype", c_int),
                ("dtype", c_int), ("sorted", c_int), ("packed", c_int)]


class _Dense(ctypes.Structure):
    _fields_ = [("nrow", c_size_t), ("ncol", c_size_t), ("nzmax", c_size_t),
                ("d", c_size_t), ("x", c_void_p), ("z", c_void_p), ("xtype", c_int),
                ("dtype", c_int)]


def default_threads() -> int:
    """Cores this process may run on (at most 8)."""
    try:
        n = len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        n = os.cpu_count() or 1
    return max(1, min(n, 8))


_LIB: list = []              # [library or None], filled once
_LOCK = threading.Lock()


def _candidates() -> list[str]:
    names = []
    found = ctypes.util.find_library("cholmod")
    if found:
        names.append(found)
    names += [f"libcholmod.so.{v}" for v in (5, 4, 3)] + ["libcholmod.dylib"]
    return names


def _bind(lib) -> None:
    lib.cholmod_l_start.argtypes = [c_void_p]
    lib.cholmod_l_finish.argtypes = [c_void_p]
    lib.cholmod_l_analyze.restype = c_void_p
    lib.cholmod_l_analyze.argtypes = [POINTER(_Sparse), c_void_p]
    lib.cholmod_l_factorize.argtypes = [POINTER(_Sparse), c_void_p, c_void_p]
    lib.cholmod_l_solve.restype = POINTER(_Dense)
    lib.cholmod_l_solve.argtypes = [c_int, c_void_p, POINTER(_Dense), c_void_p]
    lib.cholmod_l_free_dense.argtypes = [POINTER(POINTER(_Dense)), c_void_p]
    lib.cholmod_l_free_factor.argtypes = [POINTER(c_void_p), c_void_p]


def _layout_ok(lib) -> bool:
    """Does ``cholmod_common`` start as in SuiteSparse 4-7 (so ``print`` is where we write)?"""
    buf = ctypes.create_string_buffer(_COMMON_BYTES)
    lib.cholmod_l_start(buf)
    try:
        # dbound, grow0, grow1 (double), grow2, maxrank (size_t), supernodal_switch
        # (double), supernodal, final_asis (int) ... print (int) at _PRINT_OFFSET
        head = struct.unpack_from("3d2Nd2i", buf, 0)
        prt = struct.unpack_from("i", buf, _PRINT_OFFSET)[0]
        return head == (0.0, 1.2, 1.2, 5, 8, 40.0, 1, 1) and prt == 3
    finally:
        lib.cholmod_l_finish(buf)


def library():
    """The system CHOLMOD through ctypes, or None where it is missing or unrecognised."""
    with _LOCK:
        if not _LIB:
            lib = None
            if struct.calcsize("N") == 8:
                for name in _candidates():
                    try:
                        cand = ctypes.CDLL(name)
                        _bind(cand)
                        if _layout_ok(cand):
                            lib = cand
                            break
                    except (OSError, AttributeError):
                        continue
            _LIB.append(lib)
        return _LIB[0]


def _common(lib):
    buf = ctypes.create_string_buffer(_COMMON_BYTES)
    lib.cholmod_l_start(buf)
    c_int.from_buffer(buf, _PRINT_OFFSET).value = 0      # no messages on stdout
    # Always supernodal LL^T: a simplicial LDL^T would factor an indefinite matrix.
    c_int.from_buffer(buf, _SUPERNODAL_OFFSET).value = _CHOLMOD_SUPERNODAL
    return buf


def _release(lib, L, commons: list) -> None:
    handle = c_void_p(L)
    c0 = _common(lib)
    lib.cholmod_l_free_factor(byref(handle), c0)
    for c in commons + [c0]:
        lib.cholmod_l_finish(c)


_POOL: dict[int, ThreadPoolExecutor] = {}


def _pool(threads: int) -> ThreadPoolExecutor:
    with _LOCK:
        if threads not in _POOL:
            _POOL[threads] = ThreadPoolExecutor(threads, thread_name_prefix="stbs-cholmod")
        return _POOL[threads]


class CholmodFactor:
    """Supernodal Cholesky of an SPD matrix; :meth:`solve` splits columns over threads.

    Parameters
    ----------
    A : (n, n) sparse, symmetric positive definite (its upper triangle is read)
    threads : int
        Worker threads for multi-column solves (1: the calling thread only).

    Any number of threads may call :meth:`solve` at once: each thread has its own
    ``cholmod_common``.

    Raises
    ------
    ValueError
        When CHOLMOD finds A not positive definite (naming the failing column).
    """

    def __init__(self, A, threads: int = 1):
        lib = library()
        if lib is None:
            raise RuntimeError("the system CHOLMOD library is not usable through ctypes")
        self._lib = lib
        A = sp.csc_matrix(A, dtype=np.float64)
        A.sort_indices()
        self.n = int(A.shape[0])
        self.threads = max(1, int(threads))
        ip = A.indptr.astype(np.int64)
        ii = A.indices.astype(np.int64)
        x = np.ascontiguousarray(A.data)
        sA = _Sparse(self.n, self.n, A.nnz, ip.ctypes.data, ii.ctypes.data, None,
                     x.ctypes.data, None, 1, _CHOLMOD_LONG, _CHOLMOD_REAL, _CHOLMOD_DOUBLE,
                     1, 1)
        self._commons: list = []           # one per thread that has solved; freed with L
        self._local = threading.local()
        c0 = self._common()
        L = lib.cholmod_l_analyze(byref(sA), c0)
        if not L:
            raise MemoryError("CHOLMOD could not analyse the matrix (out of memory?)")
        self._L = L
        self._fin = weakref.finalize(self, _release, lib, L, self._commons)
        lib.cholmod_l_factorize(byref(sA), L, c0)
        minor = c_size_t.from_address(L + ctypes.sizeof(c_size_t)).value   # L->minor
        if minor < self.n:
            raise ValueError(f"matrix is not positive definite (CHOLMOD stopped at column "
                             f"{minor} of {self.n})")

    def _common(self):
        c = getattr(self._local, "common", None)
        if c is None:
            c = _common(self._lib)
            with _LOCK:
                self._commons.append(c)
            self._local.common = c
        return c

    def _solve_into(self, B: np.ndarray, out: np.ndarray) -> None:
        common = self._common()
        n, k = B.shape
        d = _Dense(n, k, n * k, n, B.ctypes.data, None, _CHOLMOD_REAL, _CHOLMOD_DOUBLE)
        X = self._lib.cholmod_l_solve(_CHOLMOD_A, self._L, byref(d), common)
        if not X:
            raise MemoryError("CHOLMOD solve failed (out of memory?)")
        try:
            ptr = ctypes.cast(X.contents.x, POINTER(c_double))
            out[...] = np.ctypeslib.as_array(ptr, shape=(k, n)).T
        finally:
            self._lib.cholmod_l_free_dense(byref(X), common)

    def solve(self, B: np.ndarray, threads: int | None = None) -> np.ndarray:
        """Solve ``A X = B`` for B (n,) or (n, k), on ``threads`` threads (None: as built)."""
        B = np.asarray(B, dtype=np.float64)
        vec = B.ndim == 1
        B2 = np.asfortranarray(B[:, None] if vec else B)
        k = B2.shape[1]
        out = np.empty((self.n, k), order="F")
        threads = self.threads if threads is None else max(1, int(threads))
        parts = min(threads, k // _MIN_COLS)
        if parts <= 1:
            self._solve_into(B2, out)
        else:
            cuts = np.linspace(0, k, parts + 1).astype(int)
            jobs = [(B2[:, lo:hi], out[:, lo:hi])
                    for lo, hi in zip(cuts[:-1], cuts[1:], strict=True)]
            futures = [_pool(threads).submit(self._solve_into, *job) for job in jobs[1:]]
            self._solve_into(*jobs[0])
            for f in futures:
                f.result()
        return out[:, 0] if vec else out
