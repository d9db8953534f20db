"""The box-constrained QP (stbs.weights.qp): cases solved by hand, scipy as a reference."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.optimize import lsq_linear

from stbs.weights import qp
from stbs.weights.qp import box_qp, kkt_residual


# -- by hand -------------------------------------------------------------------------------
def test_1d_upper_bound_active():
    # 1/2 2 x^2 - 4 x: minimum at x = 2, outside [0, 1], so x = 1 with gradient -2 <= 0
    res = box_qp([[2.0]], [-4.0])
    assert res.x.tolist() == [1.0]
    assert res.n_constraints.tolist() == [1] and res.all_converged
    assert res.kkt_residual[0] == 0.0


def test_2d_both_bounds_active():
    # separable: x0 -> 2 (clamped to 1), x1 -> -0.5 (clamped to 0)
    res = box_qp(np.diag([2.0, 2.0]), [-4.0, 1.0], lo=0.0, hi=1.0)
    assert res.x.tolist() == [1.0, 0.0]
    assert res.n_constraints.tolist() == [2]


def test_2d_coupled_one_bound_active():
    # Q = [[2, 1], [1, 2]], c = (-1, 1): unconstrained (1, -1). With x1 = 0 the first row
    # gives 2 x0 - 1 = 0, x0 = 1/2 inside; the gradient at x1 is x0 + 1 = 3/2 >= 0: optimal.
    Q = np.array([[2.0, 1.0], [1.0, 2.0]])
    c = np.array([-1.0, 1.0])
    res = box_qp(Q, c)
    np.testing.assert_allclose(res.x, [0.5, 0.0], atol=1e-15)
    assert res.x[1] == 0.0                              # the bound holds exactly
    np.testing.assert_allclose(Q @ res.x + c, [0.0, 1.5], atol=1e-15)


def test_3d_chain_both_bounds_and_a_free_middle():
    # Q the 1D Laplacian [[2,-1,0],[-1,2,-1],[0,-1,2]], c = (-3, 0, 3): unconstrained
    # Q^-1 (3, 0, -3) = (1.5, 0, -1.5). With x0 = 1 and x2 = 0 the middle row gives
    # 2 x1 - 1 = 0, x1 = 1/2; the gradients g0 = 2 - 1/2 - 3 = -3/2 <= 0 (upper bound)
    # and g2 = -1/2 + 3 = 5/2 >= 0 (lower bound) have the right signs: optimal.
    Q = sp.csr_array(np.array([[2.0, -1, 0], [-1, 2, -1], [0, -1, 2]]))
    c = np.array([-3.0, 0.0, 3.0])
    res = box_qp(Q, c)
    np.testing.assert_allclose(res.x, [1.0, 0.5, 0.0], atol=1e-15)
    assert res.x[0] == 1.0 and res.x[2] == 0.0 and res.n_constraints.tolist() == [2]
    np.testing.assert_allclose(Q @ res.x + c, [-1.5, 0.0, 2.5], atol=1e-15)


def test_fixed_variables_and_an_upper_bound():
    # The 1D Laplacian chain with x0 = x2 = 1 held: x1 would be (x0 + x2) / 2 = 1, but hi = 0.8.
    Q = sp.csr_array(np.array([[2.0, -1, 0], [-1, 2, -1], [0, -1, 2]]))
    res = box_qp(Q, np.zeros(3), fixed=[0, 2], values=[1.0, 1.0], hi=0.8)
    assert res.x.tolist() == [1.0, 0.8, 1.0]            # the bounds do not apply to fixed ones
    res = box_qp(Q, np.zeros(3), fixed=[2, 0], values=[0.0, 1.0])
    np.testing.assert_allclose(res.x, [1.0, 0.5, 0.0], atol=1e-15)
    assert res.n_constraints.tolist() == [0]


def test_interior_minimum_needs_no_constraint():
    res = box_qp(np.diag([1.0, 4.0]), [-0.5, -2.0])
    np.testing.assert_allclose(res.x, [0.5, 0.5], atol=1e-15)
    assert res.iterations.tolist() == [0] and res.n_constraints.tolist() == [0]
    assert res.n_polish.tolist() == [0] and res.n_solves == 1


def test_one_sided_and_per_variable_bounds():
    # unconstrained (-1, 1); x0 >= 0 and x1 <= 0.5 bite, the other sides are infinite
    res = box_qp(np.eye(2), [1.0, -1.0], lo=[0.0, -np.inf], hi=[np.inf, 0.5])
    assert res.x.tolist() == [0.0, 0.5]


def test_columns_are_independent_problems():
    Q = np.array([[2.0, 1.0], [1.0, 2.0]])
    C = np.array([[-1.0, -4.0, -0.5], [1.0, 1.0, -0.5]])
    res = box_qp(Q, C)
    assert res.x.shape == (2, 3) and res.kkt_residual.shape == (3,)
    for j in range(3):
        np.testing.assert_allclose(res.x[:, j], box_qp(Q, C[:, j]).x, atol=1e-15)
    np.testing.assert_allclose(res.x[:, 0], [0.5, 0.0], atol=1e-15)
    np.testing.assert_allclose(res.x[:, 2], [1 / 6, 1 / 6], atol=1e-15)   # (1/2, 1/2) Q^-1


def test_kkt_residual_of_known_points():
    Q, c = np.array([[2.0]]), np.array([-4.0])
    assert kkt_residual(Q, np.array([1.0]), c) == 0.0            # the minimum
    # x = 0.5: gradient -3, the step x - g / Q = 2 is clipped to 1: residual 0.5
    assert kkt_residual(Q, np.array([0.5]), c) == 0.5
    # without bounds it is the Newton step |g / Q| = 1.5
    assert kkt_residual(Q, np.array([0.5]), c, lo=-np.inf, hi=np.inf) == 1.5
    # several columns, one residual each
    r = kkt_residual(np.eye(2), np.array([[0.0, 1.0], [0.0, 1.0]]), np.zeros((2, 2)))
    np.testing.assert_allclose(r, [0.0, 1.0])


def test_every_variable_fixed():
    res = box_qp(np.eye(2), [1.0, 1.0], fixed=[0, 1], values=[3.0, -1.0])
    assert res.x.tolist() == [3.0, -1.0] and res.all_converged and res.n_solves == 0


# -- against scipy ---------------------------------------------------------------------------
def reference(Q, c, lo, hi):
    """min 1/2 x'Qx + c'x on the box as bounded least squares: |R x + R^-T c|^2 / 2, Q = R'R."""
    R = np.linalg.cholesky(Q).T
    rhs = -np.linalg.solve(R.T, c)
    return lsq_linear(R, rhs, bounds=(lo, hi), method="bvls", tol=1e-14).x


def random_spd(rng, n, density=0.3):
    A = sp.random(n, n, density=density, random_state=rng).toarray()
    return A @ A.T + 0.1 * np.eye(n)


@pytest.mark.parametrize("seed", range(8))
def test_matches_scipy_on_random_problems(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(5, 25))
    Q = random_spd(rng, n)
    c = rng.normal(size=n) * 3
    lo = -rng.random(n)
    hi = rng.random(n) + 0.05
    res = box_qp(sp.csr_array(Q), c, lo=lo, hi=hi, tol=1e-12)
    x = reference(Q, c, lo, hi)
    assert res.all_converged
    assert np.all(res.x >= lo) and np.all(res.x <= hi)            # exactly
    np.testing.assert_allclose(res.x, x, atol=1e-7)
    f = lambda y: 0.5 * y @ Q @ y + c @ y                         # noqa: E731
    assert f(res.x) <= f(x) + 1e-10
    assert kkt_residual(Q, res.x, c, lo=lo, hi=hi) <= 1e-12


@pytest.mark.parametrize("seed", range(4))
def test_fixed_variables_match_the_reduced_problem(seed):
    rng = np.random.default_rng(100 + seed)
    n = 15
    Q = random_spd(rng, n)
    c = rng.normal(size=n)
    fixed = rng.choice(n, size=4, replace=False)
    values = rng.normal(size=4)
    res = box_qp(Q, c, fixed=fixed, values=values)
    U = np.setdiff1d(np.arange(n), fixed)
    x = reference(Q[np.ix_(U, U)], c[U] + Q[np.ix_(U, fixed)] @ values, 0.0, 1.0)
    np.testing.assert_array_equal(res.x[fixed], values)
    np.testing.assert_allclose(res.x[U], x, atol=1e-7)


def test_candidate_graph_and_polish_change_the_path_not_the_answer():
    rng = np.random.default_rng(7)
    n = 40
    Q = random_spd(rng, n, density=0.15)
    c = rng.normal(size=n) * 5
    x = reference(Q, c, 0.0, 1.0)
    alone = sp.csr_array((n, n))                                 # every violation a peak
    everyone = sp.csr_array(np.ones((n, n)))                     # one constraint per round
    a = box_qp(Q, c, neighbors=alone)
    b = box_qp(Q, c, neighbors=everyone)
    np.testing.assert_allclose(a.x, x, atol=1e-7)
    np.testing.assert_allclose(b.x, x, atol=1e-7)
    assert b.iterations[0] > a.iterations[0]
    # one round cannot finish it: the primal active-set polish does
    p = box_qp(Q, c, neighbors=everyone, max_iter=1)
    assert p.n_polish[0] > 0 and p.all_converged
    np.testing.assert_allclose(p.x, x, atol=1e-7)


def test_engine_counts_solves_and_reports_done_columns():
    Q = sp.csr_array(np.array([[2.0, 1.0], [1.0, 2.0]]))
    C = np.array([[-1.0, -0.5], [1.0, -0.5]])
    done = []
    from stbs.weights._cholesky import Factor

    f = Factor(Q)
    eng = qp.DualActiveSet(Q, f.solve, lo=np.zeros(2), hi=np.ones(2), tol=1e-10, max_iter=10,
                           neighbors=Q, backend=f.backend, on_done=done.append)
    res = eng.run(-f.solve(C), C)
    np.testing.assert_allclose(res.x, [[0.5, 1 / 6], [0.0, 1 / 6]], atol=1e-15)
    assert sum(done) == 2 and res.n_solves == eng.n_solves > 0


# -- bad input ---------------------------------------------------------------------------------
def test_bad_input():
    Q = np.eye(2)
    with pytest.raises(ValueError, match="lo must be < hi"):
        box_qp(Q, [0.0, 0.0], lo=1.0, hi=1.0)
    with pytest.raises(ValueError, match="Q must be symmetric"):
        box_qp(np.array([[1.0, 0.5], [0.0, 1.0]]), [0.0, 0.0])
    with pytest.raises(ValueError, match="not positive definite"):
        box_qp(np.array([[1.0, 2.0], [2.0, 1.0]]), [0.0, 0.0])
    with pytest.raises(ValueError, match="square"):
        box_qp(np.ones((2, 3)), [0.0, 0.0])
    with pytest.raises(ValueError, match=r"c must have shape \(2,\) or \(2, m\)"):
        box_qp(Q, [0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="fixed and values go together"):
        box_qp(Q, [0.0, 0.0], fixed=[0])
    with pytest.raises(ValueError, match="fixed must not repeat"):
        box_qp(Q, [0.0, 0.0], fixed=[0, 0], values=[1.0, 1.0])
    with pytest.raises(ValueError, match=r"fixed must hold indices in 0..1"):
        box_qp(Q, [0.0, 0.0], fixed=[2], values=[1.0])
    with pytest.raises(ValueError, match=r"values must have shape"):
        box_qp(Q, [0.0, 0.0], fixed=[0], values=[1.0, 2.0])
    with pytest.raises(ValueError, match=r"lo must be a number or have shape \(2,\)"):
        box_qp(Q, [0.0, 0.0], lo=[0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="tol must be > 0"):
        box_qp(Q, [0.0, 0.0], tol=0)
    with pytest.raises(ValueError, match="backend must be one of"):
        box_qp(Q, [0.0, 0.0], backend="mkl")
    with pytest.raises(ValueError, match="Q must have a positive diagonal"):
        kkt_residual(np.zeros((1, 1)), np.zeros(1), np.zeros(1))
    with pytest.raises(TypeError):
        box_qp(Q, [0.0, 0.0], 0.0)                     # the bounds are keyword-only
