"""The system CHOLMOD through ctypes (stbs.weights._cholmod): answers, threads, errors."""

import struct

import numpy as np
import pytest
import scipy.sparse as sp

from stbs.weights import _cholesky, _cholmod

needs_lib = pytest.mark.skipif(_cholmod.library() is None,
                               reason="no system CHOLMOD (make install-test installs it)")


def _spd(n, seed):
    A = sp.random(n, n, density=0.05, random_state=seed)
    return sp.csc_matrix(A @ A.T + sp.eye(n))


@needs_lib
@pytest.mark.parametrize("threads", [1, 2, 3])
def test_solve_many_columns_on_threads(threads):
    A = _spd(200, 1)
    f = _cholmod.CholmodFactor(A, threads=threads)
    B = np.random.default_rng(2).normal(size=(200, 70))      # several parts per thread
    X = f.solve(B)
    assert X.shape == B.shape
    np.testing.assert_allclose(A @ X, B, atol=1e-9)
    # the threaded split gives the same columns as one solve per column
    one = np.column_stack([f.solve(B[:, j]) for j in (0, 35, 69)])
    np.testing.assert_allclose(X[:, [0, 35, 69]], one, atol=1e-12)
    # C-ordered input, a vector, few columns (one thread), no columns
    np.testing.assert_allclose(f.solve(np.ascontiguousarray(B)), X, atol=1e-12)
    np.testing.assert_allclose(A @ f.solve(B[:, 3]), B[:, 3], atol=1e-9)
    np.testing.assert_allclose(A @ f.solve(B[:, :5]), B[:, :5], atol=1e-9)


@needs_lib
def test_factor_matches_scipy_and_reads_upper_triangle():
    A = _spd(120, 3)
    b = np.arange(120.0)
    x = _cholmod.CholmodFactor(sp.triu(A, format="csc")).solve(b)   # stype = upper
    np.testing.assert_allclose(x, sp.linalg.spsolve(A, b), rtol=1e-9)


@needs_lib
def test_not_positive_definite_is_an_error():
    A = _spd(50, 4).tolil()
    A[10, 10] = -5.0
    with pytest.raises(ValueError, match=r"not positive definite \(CHOLMOD stopped at column"):
        _cholmod.CholmodFactor(A.tocsc())
    with pytest.raises(np.linalg.LinAlgError, match="sparse Cholesky"):
        _cholesky.factorize(A.tocsc(), backend="cholmod", threads=2)


@needs_lib
def test_factor_backend_uses_ctypes_and_threads():
    f = _cholesky.factorize(_spd(40, 5), backend="cholmod", threads=2)
    assert isinstance(f._f, _cholmod.CholmodFactor) and f.threads == 2
    with pytest.raises(ValueError, match="threads must be >= 1, got 0"):
        _cholesky.factorize(_spd(40, 5), threads=0)


class _FakeLib:
    """Stands in for libcholmod: cholmod_l_start writes the given defaults."""

    def __init__(self, head, prt):
        self.head, self.prt = head, prt

    def cholmod_l_start(self, buf):
        struct.pack_into("3d2Nd2i", buf, 0, *self.head)
        struct.pack_into("i", buf, _cholmod._PRINT_OFFSET, self.prt)

    def cholmod_l_finish(self, buf):
        pass


def test_layout_check_declines_an_unknown_common():
    good = (0.0, 1.2, 1.2, 5, 8, 40.0, 1, 1)
    assert _cholmod._layout_ok(_FakeLib(good, 3))
    assert not _cholmod._layout_ok(_FakeLib(good, 0))                 # print moved
    assert not _cholmod._layout_ok(_FakeLib((0.0, 1.2, 1.2, 5, 4, 40.0, 1, 1), 3))


def test_without_the_library_scikit_sparse_or_nothing(monkeypatch):
    monkeypatch.setattr(_cholmod, "library", lambda: None)
    if _cholesky._importable("sksparse"):
        f = _cholesky.factorize(_spd(30, 6), backend="cholmod", threads=2)
        assert f.threads == 1                  # scikit-sparse solves on one thread
        np.testing.assert_allclose(_spd(30, 6) @ f.solve(np.ones(30)), np.ones(30), atol=1e-9)
    monkeypatch.setattr(_cholesky, "_importable", lambda module: module == "scipy")
    assert _cholesky.available_backends() == ["scipy"]
    with pytest.raises(ImportError, match=r"libsuitesparse-dev.*stbs-skinning\[weights\]"):
        _cholesky.factorize(sp.eye(3), backend="cholmod")


_FRESH = r"""
import json
from threadpoolctl import threadpool_info
from stbs.weights import _cholmod
from stbs.weights.bbw import BBWSolver
import numpy as np

seen = []
real = _cholmod.CholmodFactor.__init__

def spy(self, *a, **k):   # inside BBWSolver.solve, where BLAS is held at one thread
    seen.extend((i["filepath"], i["num_threads"]) for i in threadpool_info()
                if i["user_api"] == "blas")
    real(self, *a, **k)

_cholmod.CholmodFactor.__init__ = spy
k = 12
x, y = np.meshgrid(np.arange(k), np.arange(k))
V = np.column_stack([x.ravel(), y.ravel()]).astype(float)
a = (np.arange(k - 1)[None, :] + k * np.arange(k - 1)[:, None]).ravel()
F = np.concatenate([np.column_stack([a, a + 1, a + k + 1]), np.column_stack([a, a + k + 1, a + k])])
BBWSolver(V, F, backend="cholmod").solve(np.array([0, k * k - 1]), np.eye(2))
print(json.dumps(seen))
"""


@needs_lib
def test_cholmods_own_blas_is_limited_in_a_fresh_process():
    """threadpoolctl limits only libraries already loaded: CHOLMOD (and its BLAS) must be
    loaded before the solve takes the limit, or its BLAS threads stay unlimited (2.5x
    slower at 50k). Needs a fresh interpreter: here the library is loaded long ago."""
    import json
    import subprocess
    import sys

    pytest.importorskip("threadpoolctl")
    out = subprocess.run([sys.executable, "-c", _FRESH], check=True, capture_output=True,
                         text=True, timeout=120).stdout
    seen = json.loads(out.strip().splitlines()[-1])
    assert seen, "no BLAS library seen at the factorization"
    assert all(n == 1 for _, n in seen), seen
