"""The BBW solver's small kernels: Cholesky row deletion, dense solves, and K^-1 entries
by sparse forward solves on the elimination tree (tested without CHOLMOD: the lower
factor comes from a dense Cholesky of a permuted matrix)."""

from __future__ import annotations

import importlib

import numpy as np
import pytest
import scipy.sparse as sp

from rigs import u_shape
from stbs.weights._dense import chol_solve, delete_rows, delete_rows_py
from stbs.weights._reach import Lower, ReachGreen
from stbs.weights.bbw import BBWSolver
from stbs.weights.boundary import boundary_conditions

bbw_mod = importlib.import_module("stbs.weights.bbw")


def spd(s, rng):
    A = rng.standard_normal((s, s + 2))
    return A @ A.T


@pytest.mark.parametrize("s,ks", [(1, [0]), (2, [1]), (2, [0]), (7, [0, 6]), (40, [3, 4, 5, 39]),
                                  (120, list(range(0, 120, 11)))])
def test_delete_rows_matches_refactorization(s, ks):
    rng = np.random.default_rng(s)
    H = spd(s, rng)
    R = np.zeros((s + 3, s + 3))
    R[:s, :s] = np.linalg.cholesky(H)
    R2, R3 = R.copy(), R.copy()
    ks = np.array(ks, dtype=np.int64)
    delete_rows(R2, s, ks)
    delete_rows_py(R3, s, ks)
    keep = np.setdiff1d(np.arange(s), ks)
    q = keep.size
    np.testing.assert_allclose(R2[:q, :q] @ R2[:q, :q].T, H[np.ix_(keep, keep)], atol=1e-9)
    np.testing.assert_allclose(R2, R3, atol=1e-9)
    assert np.all(R2[q:] == 0) and np.all(np.triu(R2, 1) == 0)


def test_chol_solve_uses_the_leading_block_only():
    rng = np.random.default_rng(1)
    H = spd(30, rng)
    R = np.full((40, 40), np.nan)           # the rest of the buffer must not be read
    R[:30, :30] = np.tril(np.linalg.cholesky(H))
    b = rng.standard_normal(30)
    np.testing.assert_allclose(chol_solve(R, 30, b), np.linalg.solve(H, b), rtol=1e-9)
    assert chol_solve(R, 0, np.zeros(0)).shape == (0,)


def dense_lower(K, rng):
    """(L, p) with L L^T = K[p][:, p], from a dense Cholesky after a random permutation."""
    n = K.shape[0]
    p = rng.permutation(n)
    Kp = K.toarray()[np.ix_(p, p)]
    L = np.linalg.cholesky(Kp)
    L[np.abs(L) < 1e-300] = 0.0
    return sp.csc_matrix(L), p


@pytest.fixture(scope="module")
def u_problem():
    V, F, sk = u_shape()
    b, bc = boundary_conditions(V, sk, F=F)
    return V, F, b, bc


def test_reach_green_gives_the_inverse_entries(u_problem):
    V, F, b, bc = u_problem
    solver = BBWSolver(V, F)
    U = np.setdiff1d(np.arange(V.shape[0]), b)
    K = sp.csc_matrix(solver.Q[U][:, U])
    rng = np.random.default_rng(0)
    # a band-structured ordering gives a real elimination tree (not a path)
    from scipy.sparse.csgraph import reverse_cuthill_mckee
    p = reverse_cuthill_mckee(sp.csr_matrix(K), symmetric_mode=True)
    L = sp.csc_matrix(np.linalg.cholesky(K.toarray()[np.ix_(p, p)]))
    L.eliminate_zeros()
    rg = ReachGreen(Lower(L, p))
    Kinv = np.linalg.inv(K.toarray())
    order = []
    for k in (1, 5, 17, 40):
        v = rng.choice(U.size, size=k, replace=False)
        G12, G22 = rg.add(v)
        np.testing.assert_allclose(G22, Kinv[np.ix_(v, v)], rtol=1e-8, atol=1e-12 * Kinv.max())
        if order:
            prev = np.concatenate(order)
            np.testing.assert_allclose(G12, Kinv[np.ix_(prev, v)], rtol=1e-8,
                                       atol=1e-12 * Kinv.max())
        else:
            assert G12.shape == (0, k)
        order.append(v)
        R, Y = rg.forward(v[:1])
        assert R.size < U.size                      # a reach, not the whole tree
    assert rg.nbytes > 0


def test_solver_with_forward_solves_matches_whole_columns(u_problem, monkeypatch):
    V, F, b, bc = u_problem
    W_cols = BBWSolver(V, F, backend="scipy").solve(b, bc, restrict=False)
    rng = np.random.default_rng(3)

    def lower(self):
        if self._lower is None:
            self._lower = Lower(*dense_lower(self.K, rng))
        return self._lower

    monkeypatch.setattr(bbw_mod._Prepared, "lower", property(lower))
    used = []
    orig = bbw_mod._Green.add_reach
    monkeypatch.setattr(bbw_mod._Green, "add_reach",
                        lambda self, cv: used.append(cv.size) or orig(self, cv))
    W = BBWSolver(V, F, backend="scipy").solve(b, bc, restrict=False)
    assert sum(used) > 10
    np.testing.assert_allclose(W, W_cols, atol=1e-9)
    Wp = BBWSolver(V, F, backend="scipy").solve(b, bc, partition_of_unity=True)
    used.clear()
    monkeypatch.setattr(bbw_mod._Prepared, "lower", property(lambda self: None))
    Wp_cols = BBWSolver(V, F, backend="scipy").solve(b, bc, partition_of_unity=True)
    assert not used
    np.testing.assert_allclose(Wp, Wp_cols, atol=1e-9)


def test_forward_solves_hand_over_to_columns_when_memory_runs_out(u_problem, monkeypatch):
    V, F, b, bc = u_problem
    W_cols = BBWSolver(V, F, backend="scipy").solve(b, bc, restrict=False)
    rng = np.random.default_rng(4)
    monkeypatch.setattr(bbw_mod._Prepared, "lower",
                        property(lambda self: Lower(*dense_lower(self.K, rng))))
    monkeypatch.setattr(bbw_mod, "_REACH_BYTES", 0)     # full after the first batch
    used, cols = [], []
    orig_r, orig_c = bbw_mod._Green.add_reach, bbw_mod._Green.add
    monkeypatch.setattr(bbw_mod._Green, "add_reach",
                        lambda self, cv: used.append(cv.size) or orig_r(self, cv))
    monkeypatch.setattr(bbw_mod._Green, "add",
                        lambda self, cv, Y: cols.append(cv.size) or orig_c(self, cv, Y))
    W = BBWSolver(V, F, backend="scipy").solve(b, bc, restrict=False)
    assert len(used) == 1 and cols
    np.testing.assert_allclose(W, W_cols, atol=1e-9)
