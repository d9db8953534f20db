"""The BBW solver's dense working-set kernels: Cholesky row deletion and solves on the
leading block of a buffer."""

from __future__ import annotations

import numpy as np
import pytest

from stbs.weights._dense import chol_solve, delete_rows, refactor_without


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
    refactor_without(R3, s, ks)
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
