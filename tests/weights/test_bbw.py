"""Bounded biharmonic weights: bounds, interpolation, KKT optimality, shape awareness, libigl."""

from __future__ import annotations

import sys
import warnings

import numpy as np
import pytest

import stbs
from rigs import u_shape
from stbs.io import read_mesh, read_tgf
from stbs.weights._cholesky import available_backends
from stbs.weights.bbw import BBWConvergenceWarning, BBWSolver, bbw, bone_weights
from stbs.weights.boundary import boundary_conditions


@pytest.fixture(scope="module")
def u_case():
    V, F, sk = u_shape()
    b, bc = boundary_conditions(V, sk, F=F)
    solver = BBWSolver(V, F)
    W = solver.solve(b, bc)
    return V, F, sk, b, bc, solver, W, solver.last_report


def kkt_box(Q, W, b, tol):
    """Check the KKT conditions of min 1/2 w'Qw, 0 <= w <= 1, w[b] = bc, per column."""
    U = np.setdiff1d(np.arange(W.shape[0]), b)
    Z = (Q @ W)[U]                       # gradient at the unknowns
    d = Q.diagonal()[U][:, None]
    X = W[U]
    free = (X > 0) & (X < 1)
    assert np.abs(Z[free] / np.broadcast_to(d, X.shape)[free]).max() <= tol
    assert (Z[X <= 0] / np.broadcast_to(d, X.shape)[X <= 0]).min(initial=0) >= -tol
    assert (Z[X >= 1] / np.broadcast_to(d, X.shape)[X >= 1]).max(initial=0) <= tol


def project_simplex_rows(Y):
    out = np.empty_like(Y)
    for i, y in enumerate(Y):
        u = np.sort(y)[::-1]
        css = np.cumsum(u) - 1
        r = np.nonzero(u - css / np.arange(1, y.size + 1) > 0)[0][-1]
        out[i] = np.maximum(y - css[r] / (r + 1), 0)
    return out


# -- the QP solution ---------------------------------------------------------------------
def test_bounds_and_interpolation(u_case):
    V, F, sk, b, bc, solver, W, rep = u_case
    assert W.shape == (V.shape[0], 3)
    assert W.min() >= 0.0 and W.max() <= 1.0           # exactly, not just within 1e-8
    np.testing.assert_array_equal(W[b], bc)            # boundary conditions interpolated
    assert rep.all_converged and np.all(rep.kkt_residual <= 1e-10)


def test_kkt_optimality(u_case):
    V, F, sk, b, bc, solver, W, rep = u_case
    kkt_box(solver.Q, W, b, 1e-9)
    # the bounds do bite: this is not the unconstrained solution
    assert np.all(rep.n_lower > 0) and np.all(rep.n_constraints > 0)


def test_nearly_partition_of_unity_without_the_constraint(u_case):
    W = u_case[6]
    s = W.sum(axis=1)
    assert np.abs(s - 1).max() < 0.5
    assert np.median(np.abs(s - 1)) < 0.05


def test_shape_aware_and_local(u_case):
    V, F, sk, b, bc, solver, W, rep = u_case
    right_arm = (V[:, 0] > 2) & (V[:, 1] > 1.5)
    left_arm = (V[:, 0] < 1) & (V[:, 1] > 1.5)
    # the left bone's weight never reaches across the notch (Euclidean distance 2 there)
    assert W[right_arm, 1].max() < 1e-3
    assert W[left_arm, 2].max() < 1e-3
    # and it vanishes exactly on part of the far arm (BBW's locality)
    assert np.count_nonzero(W[right_arm, 1] == 0) > 0.3 * right_arm.sum()
    # each bone dominates near itself
    near_left = np.linalg.norm(V - [0.5, 2.0], axis=1) < 0.3
    assert np.all(W[near_left, 1] > 0.8)


def test_report(u_case):
    rep = u_case[7]
    assert rep.iterations.shape == (3,) and np.all(rep.iterations >= 1)
    assert np.all(rep.n_polish == 0)
    assert rep.n_solves > 0 and rep.backend in available_backends()
    assert set(rep.seconds) == {"factor", "solve", "total"}
    text = str(rep)
    assert "kkt_residual" in text and text.count("\n") == 4


def test_factorization_is_reused_for_the_same_b(u_case):
    V, F, sk, b, bc, solver, W, rep = u_case
    W2 = solver.solve(b[::-1], bc[::-1])               # order of b does not matter
    np.testing.assert_allclose(W2, W, atol=1e-12)
    assert solver.last_report.seconds["factor"] == 0.0


def test_partition_of_unity_jointly(u_case):
    V, F, sk, b, bc, solver, W, rep = u_case
    Wp = solver.solve(b, bc, partition_of_unity=True)
    r = solver.last_report
    assert r.partition_of_unity and r.all_converged
    np.testing.assert_allclose(Wp.sum(axis=1), 1.0, atol=1e-12)
    assert Wp.min() >= 0.0 and Wp.max() <= 1.0
    np.testing.assert_array_equal(Wp[b], bc)
    # KKT for the simplex constraints: x = P_simplex(x - grad / diag Q) at every unknown
    U = np.setdiff1d(np.arange(V.shape[0]), b)
    Z = (solver.Q @ Wp)[U] / solver.Q.diagonal()[U][:, None]
    assert np.abs(Wp[U] - project_simplex_rows(Wp[U] - Z)).max() <= 1e-9
    # a genuinely different solution from normalising the independent ones
    assert np.abs(Wp - W / W.sum(axis=1, keepdims=True)).max() > 1e-4


@pytest.mark.parametrize("backend", available_backends())
def test_backends_agree(u_case, backend):
    V, F, sk, b, bc, solver, W, rep = u_case
    Wb = BBWSolver(V, F, backend=backend).solve(b, bc)
    np.testing.assert_allclose(Wb, W, atol=1e-9)
    # the column solves split over threads (cholmod through ctypes) give the same answer
    for threads in (1, 3):
        Wt = BBWSolver(V, F, backend=backend, threads=threads).solve(b, bc)
        np.testing.assert_allclose(Wt, W, atol=1e-9)


def test_one_shot_and_single_function(u_case):
    V, F, sk, b, bc, solver, W, rep = u_case
    np.testing.assert_allclose(bbw(V, F, b, bc), W, atol=1e-12)
    w1 = bbw(V, F, b, bc[:, 1])                       # a vector bc is one function
    np.testing.assert_allclose(w1[:, 0], W[:, 1], atol=1e-12)


def test_primal_polish_finishes_an_interrupted_run(u_case):
    V, F, sk, b, bc, solver, W, rep = u_case
    with warnings.catch_warnings():
        warnings.simplefilter("error", BBWConvergenceWarning)
        W2 = solver.solve(b, bc, max_iter=2)        # two dual rounds only
    r = solver.last_report
    assert np.all(r.n_polish > 0) and r.all_converged
    np.testing.assert_allclose(W2, W, atol=1e-10)


def test_missed_tolerance_warns():
    V, F, sk = u_shape()
    b, bc = boundary_conditions(V, sk, F=F)
    solver = BBWSolver(V, F)
    with pytest.warns(BBWConvergenceWarning, match="missed the KKT tolerance"):
        solver.solve(b, bc[:, :1], tol=1e-300, max_iter=3)
    assert not solver.last_report.all_converged


def test_3d_tets_kkt():
    rng = np.random.default_rng(3)
    from scipy.spatial import Delaunay
    P = np.r_[rng.random((300, 3)) * [3, 1, 1], [[0.2, 0.5, 0.5], [2.8, 0.5, 0.5]]]
    T = Delaunay(P).simplices
    b = np.array([300, 301])
    bc = np.eye(2)
    solver = BBWSolver(P, T)
    W = solver.solve(b, bc)
    assert solver.last_report.all_converged
    kkt_box(solver.Q, W, b, 1e-9)
    assert W.min() >= 0 and W.max() <= 1


# -- errors ----------------------------------------------------------------------------------
def test_bad_boundary_conditions(u_case):
    V, F, sk, b, bc, solver, W, rep = u_case
    with pytest.raises(ValueError, match=r"bc must have one row per entry of b"):
        solver.solve(b, bc[:-1])
    with pytest.raises(ValueError, match="bc must lie in"):
        solver.solve(b, bc * 2)
    with pytest.raises(ValueError, match="must not repeat a vertex"):
        solver.solve(np.r_[b, b[:1]], np.r_[bc, bc[:1]])
    with pytest.raises(ValueError, match="b must hold vertex indices"):
        solver.solve(np.r_[b[:-1], 10**6], bc)
    bad = bc.copy()
    bad[0] = [0.5, 0.2, 0.1]
    with pytest.raises(ValueError, match=r"partition_of_unity needs rows of bc summing to 1"):
        solver.solve(b, bad, partition_of_unity=True)
    with pytest.raises(ValueError, match="tol must be > 0"):
        solver.solve(b, bc, tol=0)


def test_unconstrained_part_and_stray_vertex():
    V, F, sk = u_shape()
    b, bc = boundary_conditions(V, sk, F=F)
    # a second, separate triangle that no handle touches
    V2 = np.r_[V, [[5.0, 5.0], [6.0, 5.0], [5.0, 6.0]]]
    F2 = np.r_[F, [[V.shape[0], V.shape[0] + 1, V.shape[0] + 2]]]
    with pytest.raises(ValueError, match="constrains no vertex of a connected part of the mesh"):
        BBWSolver(V2, F2).solve(b, bc)
    V3 = np.r_[V, [[9.0, 9.0]]]
    with pytest.raises(ValueError, match=f"vertex {V.shape[0]} belongs to no element"):
        BBWSolver(V3, F).solve(b, bc)


def test_bad_solver_input():
    V, F, sk = u_shape()
    with pytest.raises(ValueError, match="Ele must have shape"):
        BBWSolver(V, F[:, :2])
    with pytest.raises(ValueError, match="backend must be one of"):
        BBWSolver(V, F, backend="mkl")
    with pytest.raises(ValueError, match="threads must be >= 1 or None, got 0"):
        BBWSolver(V, F, threads=0)


# -- bone_weights --------------------------------------------------------------------------
def test_bone_weights_2d():
    V, F, sk = u_shape()
    W = bone_weights(V, sk, F=F)
    assert W.shape == (V.shape[0], 3)
    np.testing.assert_allclose(W.sum(axis=1), 1.0, atol=1e-12)
    assert W.min() >= 0
    b, bc = boundary_conditions(V, sk, F=F)
    np.testing.assert_allclose(W[b], bc, atol=1e-12)
    stbs.deform(V, sk, stbs.Pose.rest(sk), W, method="lbs")   # accepted by the deformer
    Wp = bone_weights(V, sk, F=F, partition_of_unity=True)
    np.testing.assert_allclose(Wp.sum(axis=1), 1.0, atol=1e-12)


def test_bone_weights_validation():
    V, F, sk = u_shape()
    with pytest.raises(ValueError, match=r"in 2D needs triangles F"):
        bone_weights(V, sk)
    with pytest.raises(ValueError, match=r"T \(tetrahedra\) was given for a 2D mesh"):
        bone_weights(V, sk, F=F, T=np.zeros((1, 4), dtype=int))
    with pytest.raises(ValueError, match=r"V must have shape \(\d+, 2\) to match the 2D"):
        bone_weights(np.c_[V, np.zeros(len(V))], sk, F=F)
    with pytest.raises(ValueError, match="method must be one of 'bbw', 'heat'"):
        bone_weights(V, sk, method="harmonic", F=F)
    with pytest.raises(ValueError, match="method='heat' needs a 3D triangle surface F"):
        bone_weights(V, sk, method="heat", F=F)
    with pytest.raises(ValueError, match=r"F must have shape \(\?, 3\)"):
        bone_weights(V, sk, F=np.zeros((2, 4), dtype=int))
    sk3 = stbs.Skeleton(np.array([[0, 0, 0.0], [0, 0, 1]]), np.array([[0, 1]]))
    V3 = np.random.default_rng(0).random((10, 3))
    with pytest.raises(ValueError, match=r"3D needs a tetrahedral mesh T .*F alone is a surface"):
        bone_weights(V3, sk3, F=np.array([[0, 1, 2]]))
    with pytest.raises(ValueError, match="T must hold vertex indices"):
        bone_weights(V3, sk3, T=np.array([[0, 1, 2, 30]]))


# -- libigl reference ----------------------------------------------------------------------
def test_matches_libigl_2d(u_case):
    igl = pytest.importorskip("igl")
    V, F, sk, b, bc, solver, W, rep = u_case
    Wi = igl.bbw(V, F, b, bc)
    assert np.abs(W - Wi).max() <= 1e-6


def test_matches_libigl_on_hand(shared_data):
    igl = pytest.importorskip("igl")
    m = read_mesh(shared_data / "libigl-tutorial-data/hand.mesh")
    C, BE = read_tgf(shared_data / "libigl-tutorial-data/hand.tgf")
    e = np.zeros((0, 2), dtype=np.int64)
    b, bc = igl.boundary_conditions(m.V, m.T, C, np.zeros(0, dtype=np.int64),
                                    BE.astype(np.int64), e, np.zeros((0, 3), dtype=np.int64))
    cols = [0, 11]                  # two of the 20 functions keep the libigl run short
    solver = BBWSolver(m.V, m.T)
    with warnings.catch_warnings():
        warnings.simplefilter("error", BBWConvergenceWarning)
        W = solver.solve(b, bc[:, cols])
    Wi = igl.bbw(m.V, m.T, b, bc[:, cols])
    assert np.abs(W - Wi).max() <= 1e-3
    assert solver.last_report.all_converged
    kkt_box(solver.Q, W, b, 1e-9)


# -- the sparse Cholesky wrapper -------------------------------------------------------------
@pytest.mark.parametrize("backend", available_backends())
def test_cholesky_backends(backend):
    import scipy.sparse as sp

    from stbs.weights._cholesky import factorize

    rng = np.random.default_rng(4)
    A = sp.random(60, 60, density=0.1, random_state=5)
    A = sp.csc_matrix(A @ A.T + sp.eye(60))
    f = factorize(A, backend=backend)
    assert f.backend == backend and f.n == 60
    B = rng.normal(size=(60, 3))
    np.testing.assert_allclose(A @ f.solve(B), B, atol=1e-10)
    np.testing.assert_allclose(A @ f.solve(B[:, 0]), B[:, 0], atol=1e-10)
    assert f.solve(np.zeros((60, 0))).shape == (60, 0)
    with pytest.raises(ValueError, match=r"B must have shape \(60,\)"):
        f.solve(np.ones(5))
    with pytest.raises(np.linalg.LinAlgError):
        factorize(sp.csc_matrix(-A), backend=backend)


def test_cholesky_missing_backend(monkeypatch):
    import scipy.sparse as sp

    from stbs.weights import _cholesky, _cholmod

    monkeypatch.setattr(_cholmod, "library", lambda: None)
    monkeypatch.setattr(_cholesky, "_importable", lambda module: module == "scipy")
    assert _cholesky.available_backends() == ["scipy"]
    assert _cholesky.factorize(sp.eye(3)).backend == "scipy"
    with pytest.raises(ImportError, match=r"pip install 'stbs-skinning\[weights\]'"):
        _cholesky.factorize(sp.eye(3), backend="cholespy")
    with pytest.raises(ValueError, match="backend must be one of"):
        _cholesky.factorize(sp.eye(3), backend="mkl")


def test_every_vertex_constrained():
    V = np.array([[0.0, 0], [1, 0], [0, 1]])
    bc = np.array([[1.0, 0], [0, 1], [0.5, 0.5]])
    solver = BBWSolver(V, np.array([[0, 1, 2]]))
    W = solver.solve([2, 0, 1], bc[[2, 0, 1]])
    np.testing.assert_array_equal(W, bc)
    assert solver.last_report.all_converged


# ---------------------------------------------------------------- parts of the mesh
def strip_chain(bones=10):
    """A 2D strip 10 x 1 (spacing 0.1) with a chain of bones along its middle line."""
    nx, ny = 100, 10
    I, J = np.meshgrid(np.arange(nx + 1), np.arange(ny + 1), indexing="ij")
    V = np.c_[I.ravel(), J.ravel()] / 10.0
    idx = np.arange(V.shape[0]).reshape(nx + 1, ny + 1)
    a, b = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel()
    c, d = idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    F = np.r_[np.c_[a, b, c], np.c_[a, c, d]]
    x = np.linspace(0.5, 9.5, bones + 1)
    C = np.c_[x, np.full_like(x, 0.5)]
    BE = np.c_[np.arange(bones), np.arange(1, bones + 1)]
    return V, F, stbs.Skeleton(C, BE)


@pytest.mark.parametrize("threads", [1, 2])
def test_parts_give_the_whole_mesh_answer(monkeypatch, threads):
    import importlib
    import threading

    from stbs.weights import _cholmod

    mod = importlib.import_module("stbs.weights.bbw")

    V, F, sk = strip_chain(10)
    b, bc = boundary_conditions(V, sk, F=F)
    whole = BBWSolver(V, F)
    W0 = whole.solve(b, bc, restrict=False)
    monkeypatch.setattr(mod, "_REGION_MAX", 0.5)      # each part is about 0.35 here
    calls = []
    orig = BBWSolver._solve_in_region
    monkeypatch.setattr(BBWSolver, "_solve_in_region", lambda self, *a: calls.append(
        threading.current_thread().name) or orig(self, *a))
    seen = []
    solver = BBWSolver(V, F, threads=threads)
    W = solver.solve(b, bc, progress=lambda done, total: seen.append((done, total)))
    assert len(calls) >= 6                  # the inner bones' parts are small
    # with threads (and CHOLMOD through ctypes) the parts are solved on worker threads
    parallel = threads > 1 and _cholmod.library() is not None
    assert all(name.startswith("stbs-bbw") == parallel for name in calls)
    np.testing.assert_allclose(W, W0, atol=1e-7)
    assert solver.last_report.all_converged
    assert kkt_box(solver.Q, W, b, 1e-8) is None
    assert seen[-1] == (10, 10) and [d for d, _ in seen] == sorted(d for d, _ in seen)
    # a part far too small fails the whole mesh's KKT check and is grown until it holds
    grows = []
    orig_grow = BBWSolver._grow
    monkeypatch.setattr(mod, "_MARGIN_RINGS", 0)
    monkeypatch.setattr(BBWSolver, "_grow",
                        lambda self, *a: grows.append(1) or orig_grow(self, *a))
    orig_regions = BBWSolver._regions

    def own_cell_only(self, P, bc):
        masks = orig_regions(self, P, bc)
        lab = self._labU
        return [None if mk is None else (lab == j) for j, mk in enumerate(masks)]

    monkeypatch.setattr(BBWSolver, "_regions", own_cell_only)
    W2 = BBWSolver(V, F, threads=threads).solve(b, bc)
    assert grows
    np.testing.assert_allclose(W2, W0, atol=1e-7)


def test_progress_must_be_callable(u_case):
    V, F, sk, b, bc, solver, W, rep = u_case
    with pytest.raises(TypeError, match="progress must be callable"):
        solver.solve(b, bc, progress=3)
    seen = []
    solver.solve(b, bc, partition_of_unity=True, progress=lambda d, t: seen.append((d, t)))
    # every round of the coupled solve reports (nothing done yet), then all three
    assert seen[-1] == (3, 3) and set(seen[:-1]) == {(0, 3)} and len(seen) >= 3


def test_solve_chunk_rule_and_small_chunks_give_the_same_answer(u_case, monkeypatch):
    mod = sys.modules["stbs.weights.qp"]           # the QP engine chunks the unit solves
    assert mod.solve_chunk(1) == 512 and mod.solve_chunk(10**8) == 64
    sizes = [mod.solve_chunk(n) for n in (5_000, 20_000, 50_000, 200_000)]
    assert sizes == sorted(sizes, reverse=True) and sizes[0] == 512 and 64 < sizes[2] < 512
    V, F, sk, b, bc, solver, W, rep = u_case
    calls = []
    real = mod.DualActiveSet.solve_unit

    def spy(self, verts):
        for cv, Y in real(self, verts):
            calls.append(cv.size)
            yield cv, Y

    monkeypatch.setattr(mod, "solve_chunk", lambda nu: 8)   # cut every batch into 8s
    monkeypatch.setattr(mod.DualActiveSet, "solve_unit", spy)
    W2 = BBWSolver(V, F).solve(b, bc, restrict=False)
    assert max(calls) == 8 and len(calls) > 20
    np.testing.assert_allclose(W2, W, atol=1e-9)


# -- API: bone heat through bone_weights, keyword-only options, the elements' name ---------------
def test_bone_weights_heat_is_bone_heat_on_a_surface():
    from rigs import icosphere
    from stbs.weights.heat import bone_heat

    V, F = icosphere(2)
    sk = stbs.Skeleton([[0, 0, -0.5], [0, 0, 0.0], [0, 0, 0.5]], [[0, 1], [1, 2]])
    seen = []
    W = bone_weights(V, sk, method="heat", F=F, progress=lambda d, t: seen.append((d, t)))
    np.testing.assert_array_equal(W, bone_heat(V, F, sk))
    # a visibility round per rank of nearness (two bones: at most two), then the solve
    assert seen[0] == (0, 3) and seen[-1] == (3, 3) and seen == sorted(seen)
    assert len(seen) in (2, 3)
    with pytest.raises(ValueError, match=r"method='heat' needs the 3D triangle surface F"):
        bone_weights(V, sk, method="heat")
    T = np.array([[0, 1, 2, 3]])
    with pytest.raises(ValueError, match="not on tetrahedra T; pass F, got T only"):
        bone_weights(V, sk, method="heat", T=T)
    with pytest.raises(ValueError, match="not on tetrahedra T: leave T out"):
        bone_weights(V, sk, method="heat", F=F, T=T)
    for option in ("partition_of_unity", "samples", "tol"):
        with pytest.raises(ValueError, match=f"{option} applies to method='bbw' only"):
            bone_weights(V, sk, method="heat", F=F, **{option: 1})


def test_options_are_keyword_only():
    V, F, sk = u_shape()
    with pytest.raises(TypeError):
        bone_weights(V, sk, "bbw", F=F)
    with pytest.raises(TypeError):
        BBWSolver(V, F, "scipy")


def test_elements_keyword_E_is_deprecated(u_case):
    V, F, sk, b, bc, solver, W, rep = u_case
    with pytest.warns(DeprecationWarning, match=r"BBWSolver\(E=...\) is deprecated.*Ele"):
        old = BBWSolver(V, E=F)
    np.testing.assert_array_equal(old.solve(b, bc), W)
    np.testing.assert_array_equal(old.Ele, F)
    with pytest.warns(DeprecationWarning, match=r"BBWSolver.E is deprecated"):
        np.testing.assert_array_equal(old.E, F)
    with pytest.warns(DeprecationWarning, match=r"bbw\(E=...\) is deprecated"):
        np.testing.assert_array_equal(bbw(V, b=b, bc=bc, E=F), W)
    np.testing.assert_array_equal(bbw(V, Ele=F, b=b, bc=bc), W)
    with pytest.raises(TypeError, match="got both 'Ele' and its deprecated name 'E'"):
        BBWSolver(V, F, E=F)
    with pytest.raises(TypeError, match="got both 'Ele' and its deprecated name 'E'"):
        bbw(V, F, b, bc, E=F)
    import inspect
    assert list(inspect.signature(BBWSolver).parameters)[:2] == ["V", "Ele"]
    assert list(inspect.signature(bbw).parameters)[:4] == ["V", "Ele", "b", "bc"]
