"""stbs.fit.fit_endpoint_weights / fit_weights: weights recovered from example meshes in
known poses, and the simplex least-squares solver they use (stbs.fit._lsq)."""

from __future__ import annotations

from itertools import combinations

import numpy as np
import pytest
from scipy.optimize import minimize

import stbs
from rigs import random_rotations, random_weights
from stbs import transforms as tf
from stbs.fit import fit_endpoint_weights, fit_weights
from stbs.fit._lsq import simplex_lsq, simplex_qp

#: Entries of E checked for recovery: the bone's weight at the vertex is at least this.
#: In noise-free examples any e_i with w_i > 0 is determined, but the descent stops once
#: a sweep moves no point by more than ``tol`` (it weighs each change of e_i by w_i), so
#: e_i is pinned to about tol / w_i; 1e-3 keeps that far below the 1e-3 asked of E.
W_MIN = 1e-3


# ---------------------------------------------------------------------------- rigs
def tube(rings: int = 20, around: int = 16, length: float = 3.0, radius: float = 0.3):
    """A closed-ring tube along x: V (rings * around, 3) and its triangles F."""
    t = np.linspace(0.0, length, rings)
    a = np.linspace(0.0, 2 * np.pi, around, endpoint=False)
    T, A = np.meshgrid(t, a, indexing="ij")
    V = np.c_[T.ravel(), radius * np.cos(A.ravel()), radius * np.sin(A.ravel())]
    i, j = np.meshgrid(np.arange(rings - 1), np.arange(around), indexing="ij")
    v00 = (i * around + j).ravel()
    v01 = (i * around + (j + 1) % around).ravel()
    v10, v11 = v00 + around, v01 + around
    F = np.r_[np.c_[v00, v10, v11], np.c_[v00, v11, v01]]
    return V, F


def chain(b: int = 3, length: float = 3.0) -> stbs.Skeleton:
    C = np.c_[np.linspace(0.0, length, b + 1), np.zeros((b + 1, 2))]
    return stbs.Skeleton(C, np.c_[np.arange(b), np.arange(1, b + 1)])


def smooth_E(rng, V, b: int) -> np.ndarray:
    """Smooth endpoint weights in [0.05, 0.95]: a random low-frequency wave per bone."""
    k = rng.normal(size=(b, 3)) * 1.5
    ph = rng.uniform(0, 2 * np.pi, b)
    return 0.5 + 0.45 * np.sin(V @ k.T + ph)


def random_poses(rng, sk, m: int, *, twist: float = 3 * np.pi):
    """m poses with random rotations, stretch in [0.5, 2] and twists up to +-``twist``
    (past 360 degrees by default) at both ends of every bone."""
    b, d = sk.n_bones, sk.dim
    return [stbs.Pose(sk, rotations=random_rotations(rng, b, d),
                      origins=sk.A + rng.normal(size=(b, d)) * 0.3,
                      stretch=rng.uniform(0.5, 2.0, b),
                      twist=rng.uniform(-twist, twist, (b, 2)) if d == 3 else None)
            for _ in range(m)]


def fk_poses(rng, sk, m: int, *, angle: float, twist: float):
    """m forward-kinematics poses: local rotations up to ``angle``, joint twists up to
    ``twist``, stretch in [0.6, 1.6], a random root translation."""
    b = sk.n_bones
    out = []
    for _ in range(m):
        L = tf.axis_angle_to_matrix(rng.normal(size=(b, 3)), rng.uniform(-angle, angle, b))
        out.append(stbs.forward_kinematics(sk, rotations=L, stretch=rng.uniform(0.6, 1.6, b),
                                           twist=rng.uniform(-twist, twist, sk.n_joints),
                                           translation=rng.normal(size=3)))
    return out


def frames_of(V, sk, poses, W, E, method="stbs-lbs"):
    return np.stack([stbs.deform(V, sk, p, W, E, method=method) for p in poses])


def residual(V, sk, poses, frames, W, E, method="stbs-lbs") -> float:
    return float(np.sum((frames_of(V, sk, poses, W, E, method) - frames) ** 2))


@pytest.fixture(scope="module")
def tube_rig():
    """Tube (320 vertices), a 3-bone chain, W random with 2 bones per vertex, smooth E,
    20 random poses that stretch and twist every bone past 360 degrees."""
    rng = np.random.default_rng(7)
    V, F = tube()
    sk = chain()
    W, _ = random_weights(rng, V.shape[0], sk.n_bones, k=2)
    E = smooth_E(rng, V, sk.n_bones)
    poses = random_poses(rng, sk, 20)
    return V, F, sk, W, E, poses, frames_of(V, sk, poses, W, E)


def recovered(Efit, E, W, tol):
    """Largest error of E where it is identifiable (w >= W_MIN), checked against tol."""
    err = np.abs(Efit - E)[W >= W_MIN]
    assert err.size > 0
    assert err.max() < tol, f"E error {err.max():.3g} (>= {tol}) at {np.sum(err >= tol)} entries"
    return err.max()


# ---------------------------------------------------------------------------- E from poses
def test_fit_endpoint_weights_recovers_E(tube_rig):
    V, F, sk, W, E, poses, frames = tube_rig
    E0 = stbs.endpoint_weights(V, sk, method="projection")
    Efit = fit_endpoint_weights(V, sk, W, poses, frames)
    recovered(Efit, E, W, 1e-3)
    # entries whose bone has no weight at the vertex keep the start (projection) values
    np.testing.assert_array_equal(Efit[W == 0], E0[W == 0])
    assert Efit.min() >= 0 and Efit.max() <= 1


def test_sparse_W_and_given_E0(tube_rig):
    import scipy.sparse as sp
    V, F, sk, W, E, poses, frames = tube_rig
    E0 = np.full_like(E, 0.5)
    Efit = fit_endpoint_weights(V, sk, sp.csr_array(W), poses, frames, E0=E0)
    recovered(Efit, E, W, 1e-3)
    np.testing.assert_array_equal(Efit[W == 0], 0.5)


def test_bone_without_stretch_or_twist_keeps_E0(tube_rig):
    V, F, sk, W, E, poses, _ = tube_rig
    # bone 1 rotates but neither stretches nor twists along itself (uniform twist only)
    still = []
    for p in poses:
        s, t = p.stretch.copy(), p.twist.copy()
        s[1], t[1] = 1.0, [0.7, 0.7]
        still.append(stbs.Pose(sk, rotations=p.rotations, origins=p.origins, stretch=s, twist=t))
    frames = frames_of(V, sk, still, W, E)
    E0 = np.full_like(E, 0.25)
    Efit = fit_endpoint_weights(V, sk, W, still, frames, E0=E0)
    np.testing.assert_array_equal(Efit[:, 1], 0.25)
    keep = np.ones_like(W, bool)
    keep[:, 1] = False
    err = np.abs(Efit - E)[keep & (W >= W_MIN)]
    assert err.max() < 1e-3


def test_stretch_only_bone_is_a_parabola_step(tube_rig):
    """No twist anywhere: each step is the clamped vertex of a parabola."""
    V, F, sk, W, E, poses, _ = tube_rig
    flat = [stbs.Pose(sk, rotations=p.rotations, origins=p.origins, stretch=p.stretch)
            for p in poses]
    frames = frames_of(V, sk, flat, W, E)
    recovered(fit_endpoint_weights(V, sk, W, flat, frames), E, W, 1e-3)


def test_two_dimensional_rig():
    rng = np.random.default_rng(3)
    C = np.array([[0.0, 0.0], [1.0, 0.2], [2.0, 0.0], [1.0, 1.2]])
    sk = stbs.Skeleton(C, [[0, 1], [1, 2], [1, 3]])
    V = rng.uniform([-0.3, -0.5], [2.3, 1.5], size=(150, 2))
    W, _ = random_weights(rng, V.shape[0], 3, k=2)
    E = smooth_E(rng, np.c_[V, np.zeros(len(V))], 3)
    poses = random_poses(rng, sk, 8)
    frames = frames_of(V, sk, poses, W, E)
    recovered(fit_endpoint_weights(V, sk, W, poses, frames), E, W, 1e-3)
    # stbs-dqs in 2D, bones turned by at most 1 rad (the blend is continuous in E)
    poses = [stbs.Pose(sk, rotations=rng.uniform(-1, 1, 3), stretch=rng.uniform(0.5, 2, 3),
                       origins=sk.A + rng.normal(size=(3, 2)) * 0.2) for _ in range(8)]
    frames = frames_of(V, sk, poses, W, E, "stbs-dqs")
    recovered(fit_endpoint_weights(V, sk, W, poses, frames, method="stbs-dqs"), E, W, 1e-3)


def test_noisy_frames_fit_no_worse_than_the_truth(tube_rig):
    V, F, sk, W, E, poses, frames = tube_rig
    rng = np.random.default_rng(11)
    noisy = frames + rng.normal(scale=0.01, size=frames.shape)
    Efit = fit_endpoint_weights(V, sk, W, poses, noisy)
    r_fit, r_true = residual(V, sk, poses, noisy, W, Efit), residual(V, sk, poses, noisy, W, E)
    assert r_fit <= r_true + 1e-9 * r_true
    # and it is a fit: projection endpoint weights explain the frames far worse
    assert residual(V, sk, poses, noisy, W, stbs.endpoint_weights(V, sk)) > 10 * r_fit


def test_stbs_dqs_recovers_E():
    """stbs-dqs: the same descent on the dual-quaternion model, a local method. Recovery
    to 1e-3 is asked where the blend is continuous in E: joint twists up to 90 degrees
    and bends up to 1 rad keep any two bones at a vertex less than 180 degrees apart, so
    no quaternion crosses its pivot's hemisphere as e moves. (Past that, the true E can
    sit in a narrow valley between two such jumps, which coordinate moves miss.)"""
    rng = np.random.default_rng(5)
    V, _ = tube(rings=12, around=10)
    sk = chain()
    W, _ = random_weights(rng, V.shape[0], 3, k=2)
    E = smooth_E(rng, V, 3)
    poses = fk_poses(rng, sk, 10, angle=1.0, twist=0.5 * np.pi)
    frames = frames_of(V, sk, poses, W, E, "stbs-dqs")
    Efit = fit_endpoint_weights(V, sk, W, poses, frames, method="stbs-dqs")
    r0 = residual(V, sk, poses, frames, W, stbs.endpoint_weights(V, sk), "stbs-dqs")
    r = residual(V, sk, poses, frames, W, Efit, "stbs-dqs")
    assert r < 1e-8 * r0
    recovered(Efit, E, W, 1e-3)


# ---------------------------------------------------------------------------- W and E
def test_fit_weights_recovers_W_and_E(tube_rig):
    V, F, sk, W, E, poses, frames = tube_rig
    Wfit, Efit = fit_weights(V, sk, poses, frames, F=F, smoothness=0.0, max_influences=2,
                             iterations=6)
    assert Wfit.shape == W.shape and Wfit.min() >= 0
    np.testing.assert_allclose(Wfit.sum(axis=1), 1.0, atol=1e-12)
    assert np.count_nonzero(Wfit, axis=1).max() <= 2
    assert np.abs(Wfit - W).max() < 1e-2
    recovered(Efit, E, W, 1e-3)
    # noise-free examples are fitted to rounding within a few rounds (the joint steps;
    # alternating W and E alone is still ~1e-4 away after 6 rounds)
    assert residual(V, sk, poses, frames, Wfit, Efit) < 1e-20 * np.sum(frames ** 2)


def test_fit_weights_noisy_residual_and_smoothness(tube_rig):
    V, F, sk, W, E, poses, frames = tube_rig
    rng = np.random.default_rng(12)
    noisy = frames + rng.normal(scale=0.01, size=frames.shape)
    W0, E0 = fit_weights(V, sk, poses, noisy, F=F, smoothness=0.0, iterations=4)
    assert residual(V, sk, poses, noisy, W0, E0) <= residual(V, sk, poses, noisy, W, E) * (
        1 + 1e-6)
    # rounds never raise the objective (the same seed replays the same first rounds)
    r = [residual(V, sk, poses, noisy, *fit_weights(V, sk, poses, noisy, smoothness=0.0,
                                                     iterations=it)) for it in (1, 2)]
    assert r[0] >= r[1] >= residual(V, sk, poses, noisy, W0, E0)
    # the smoothness term pulls each vertex's weights towards its neighbours'
    W1, _ = fit_weights(V, sk, poses, noisy, F=F, smoothness=1.0, iterations=2)
    edges = np.r_[F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]

    def rough(X):
        return float(np.sum((X[edges[:, 0]] - X[edges[:, 1]]) ** 2))
    assert rough(W1) < 0.5 * rough(W0)
    np.testing.assert_allclose(W1.sum(axis=1), 1.0, atol=1e-12)


def test_shared_arm_subsampled(shared_data):
    """The libigl arm rig, 300 of its vertices: its own W, projection E scaled into
    [0.1, 0.9], poses by forward kinematics with stretch and twists past 360 degrees."""
    from stbs import io
    d = shared_data / "libigl-tutorial-data"
    V = io.read_mesh(d / "arm.obj").V
    sk = io.read_skeleton(d / "arm.tgf")
    W = np.asarray(io.read_dmat(d / "arm-weights.dmat"), float)
    keep = np.random.default_rng(0).choice(V.shape[0], 300, replace=False)
    V, W = V[keep], W[keep]
    W = np.where(W > 1e-3, W, 0.0)
    W /= W.sum(axis=1, keepdims=True)
    E = 0.1 + 0.8 * stbs.endpoint_weights(V, sk)
    rng = np.random.default_rng(1)
    poses = fk_poses(rng, sk, 20, angle=1.2, twist=3 * np.pi)
    frames = frames_of(V, sk, poses, W, E)
    recovered(fit_endpoint_weights(V, sk, W, poses, frames), E, W, 1e-3)
    Wfit, Efit = fit_weights(V, sk, poses, frames, smoothness=0.0, max_influences=sk.n_bones)
    assert np.abs(Wfit - W).max() < 1e-2
    recovered(Efit, E, W, 1e-3)


# ---------------------------------------------------------------------------- progress
def test_progress_reports_and_cancels(tube_rig):
    V, F, sk, W, E, poses, frames = tube_rig
    calls = []
    fit_endpoint_weights(V, sk, W, poses[:4], frames[:4], iterations=3,
                         progress=lambda *a: calls.append(a))
    assert calls[0] == ("endpoint weights", 0, 0)
    assert [c[1] for c in calls] == list(range(len(calls)))
    assert len(calls) > 3 and all(c == ("endpoint weights", c[1], 9) for c in calls[1:])

    class Stop(Exception):
        pass

    seen = []

    def cancel(stage, done, total):
        seen.append((stage, done))
        if done == 2:
            raise Stop

    with pytest.raises(Stop):
        fit_endpoint_weights(V, sk, W, poses, frames, progress=cancel)
    assert seen[-1] == ("endpoint weights", 2)
    seen.clear()
    with pytest.raises(Stop):
        fit_weights(V, sk, poses, frames, progress=cancel)
    assert seen[-1][1] == 2 and len(seen) == 4        # fit weights 0, endpoint 0, 1, 2
    with pytest.raises(TypeError, match="progress must be callable"):
        fit_weights(V, sk, poses, frames, progress=3)


def test_seed_orders_the_sweeps_only(tube_rig):
    V, F, sk, W, E, poses, frames = tube_rig
    a = fit_endpoint_weights(V, sk, W, poses[:6], frames[:6], seed=1)
    b = fit_endpoint_weights(V, sk, W, poses[:6], frames[:6], seed=2)
    np.testing.assert_allclose(a[W >= W_MIN], b[W >= W_MIN], atol=1e-5)


# ---------------------------------------------------------------------------- bad input
@pytest.mark.parametrize("case, match", [
    ("frame_shape", r"frames must have shape \(m, 320, 3\).*V \(320, 3\).*\(2, 319, 3\)"),
    ("one_frame", r"got one mesh of shape \(320, 3\)"),
    ("count", "got 3 poses and 2 frames"),
    ("nan", "frames must be finite, got nan at frame 1, vertex 5"),
    ("W_shape", r"W must have shape \(320, 3\), got \(320, 2\)"),
    ("method", "method must be one of 'stbs-lbs', 'stbs-dqs', got 'dqs'"),
    ("empty", "poses must hold at least one stbs.Pose, got none"),
    ("iterations", "iterations must be a positive integer, got 0"),
    ("pose_type", r"poses\[0\] must be a stbs.Pose"),
])
def test_bad_input_endpoint(tube_rig, case, match):
    V, F, sk, W, E, poses, frames = tube_rig
    args = dict(V=V, sk=sk, W=W, poses=poses[:2], frames=frames[:2])
    kw = {}
    if case == "frame_shape":
        args["frames"] = frames[:2, :-1]
    elif case == "one_frame":
        args["frames"], args["poses"] = frames[0], poses[:1]
    elif case == "count":
        args["poses"] = poses[:3]
    elif case == "nan":
        args["frames"] = frames[:2].copy()
        args["frames"][1, 5, 2] = np.nan
    elif case == "W_shape":
        args["W"] = W[:, :2]
    elif case == "method":
        kw["method"] = "dqs"
    elif case == "empty":
        args["frames"], args["poses"] = frames[:0], []
    elif case == "iterations":
        kw["iterations"] = 0
    elif case == "pose_type":
        args["poses"] = ["rest", "rest"]
    with pytest.raises((ValueError, TypeError), match=match):
        fit_endpoint_weights(*args.values(), **kw)


@pytest.mark.parametrize("kw, match", [
    (dict(method="stbs-dqs"), "method must be one of 'stbs-lbs', got 'stbs-dqs'"),
    (dict(max_influences=0), "max_influences must be a positive integer, got 0"),
    (dict(smoothness=-1.0), "smoothness must be a finite number >= 0, got -1.0"),
    (dict(F=np.array([[0, 1, 400]])), r"F must hold vertex indices in 0..319"),
])
def test_bad_input_weights(tube_rig, kw, match):
    V, F, sk, W, E, poses, frames = tube_rig
    with pytest.raises(ValueError, match=match):
        fit_weights(V, sk, poses[:2], frames[:2], **kw)


# ---------------------------------------------------------------------------- _lsq
def _slsqp(A, y, support, prior=None, lam=0.0):
    """scipy's SLSQP on one row restricted to ``support``: the reference optimum."""
    S = list(support)
    prior = np.zeros(A.shape[1]) if prior is None else prior

    def f(x):
        return np.sum((A[:, S] @ x - y) ** 2) + lam * np.sum((x - prior[S]) ** 2)
    res = minimize(f, np.full(len(S), 1 / len(S)), method="SLSQP", bounds=[(0, 1)] * len(S),
                   constraints=[{"type": "eq", "fun": lambda x: x.sum() - 1}],
                   options=dict(ftol=1e-15, maxiter=1000))
    return res.fun


def _objective(A, y, w, prior=None, lam=0.0):
    prior = np.zeros_like(w) if prior is None else prior
    return np.sum((A @ w - y) ** 2) + lam * np.sum((w - prior) ** 2)


def test_simplex_lsq_by_hand():
    # projection of (0.6, 0.6, -0.2) onto the simplex: (0.5, 0.5, 0)
    w = simplex_lsq(np.eye(3)[None], np.array([[0.6, 0.6, -0.2]]))
    np.testing.assert_allclose(w, [[0.5, 0.5, 0.0]], atol=1e-14)
    # inside the simplex: the unconstrained solution itself
    w = simplex_lsq(np.eye(3)[None], np.array([[0.2, 0.3, 0.5]]))
    np.testing.assert_allclose(w, [[0.2, 0.3, 0.5]], atol=1e-14)


def test_simplex_lsq_matches_slsqp_bounded_sum_to_one():
    rng = np.random.default_rng(0)
    n, q, m = 40, 7, 5
    A, y = rng.normal(size=(n, q, m)), rng.normal(size=(n, q))
    prior = rng.dirichlet(np.ones(m), size=n)
    for lam in (0.0, 0.7):
        w = simplex_lsq(A, y, prior=prior, lam=lam)
        assert w.min() >= 0
        np.testing.assert_allclose(w.sum(axis=1), 1.0, atol=1e-13)
        for r in range(n):
            ref = _slsqp(A[r], y[r], range(m), prior[r], lam)
            assert _objective(A[r], y[r], w[r], prior[r], lam) <= ref + 1e-9


def test_simplex_lsq_k_sparse_matches_brute_force():
    rng = np.random.default_rng(1)
    n, q, m, k = 30, 6, 5, 2
    A, y = rng.normal(size=(n, q, m)), rng.normal(size=(n, q))
    w = simplex_lsq(A, y, k=k, pool=m)          # the pool holds every bone: exact
    assert np.count_nonzero(w, axis=1).max() <= k and w.min() >= 0
    np.testing.assert_allclose(w.sum(axis=1), 1.0, atol=1e-13)
    for r in range(n):
        best = min(_slsqp(A[r], y[r], S) for S in combinations(range(m), k))
        assert abs(_objective(A[r], y[r], w[r]) - best) <= 1e-8 * max(1.0, best)
    # the default pool (k + 2 candidates) finds the same optimum on most rows, and each
    # row's weights are optimal on their own support
    wd = simplex_lsq(A, y, k=k)
    assert np.count_nonzero(wd, axis=1).max() <= k
    for r in range(n):
        S = np.flatnonzero(wd[r])
        assert _objective(A[r], y[r], wd[r]) <= _slsqp(A[r], y[r], S) + 1e-9


def test_simplex_qp_rank_deficient_and_prior_equivalence():
    rng = np.random.default_rng(2)
    A, y = rng.normal(size=(20, 2, 6)), rng.normal(size=(20, 2))   # 2 equations, 6 unknowns
    w = simplex_lsq(A, y)
    assert np.all(np.isfinite(w)) and w.min() >= 0
    np.testing.assert_allclose(w.sum(axis=1), 1.0, atol=1e-13)
    for r in range(20):
        assert _objective(A[r], y[r], w[r]) <= _slsqp(A[r], y[r], range(6)) + 1e-9
    # the prior term is the same as extra rows sqrt(lam) (w - prior) in the design
    prior, lam = rng.dirichlet(np.ones(6), size=20), 0.3
    stacked = np.concatenate([A, np.broadcast_to(np.sqrt(lam) * np.eye(6), (20, 6, 6))], 1)
    ys = np.concatenate([y, np.sqrt(lam) * prior], axis=1)
    np.testing.assert_allclose(simplex_lsq(A, y, prior=prior, lam=lam), simplex_lsq(stacked, ys),
                               atol=1e-8)
    H = np.einsum("nqi,nqj->nij", A, A)
    g = np.einsum("nqi,nq->ni", A, y)
    np.testing.assert_allclose(simplex_qp(H, g, k=2), simplex_lsq(A, y, k=2), atol=1e-12)


@pytest.mark.parametrize("call, match", [
    (lambda: simplex_lsq(np.ones((2, 3)), np.ones((2, 3))), "A must be a 3-D array"),
    (lambda: simplex_lsq(np.ones((2, 3, 4)), np.ones((2, 4))), r"y must have shape \(2, 3\)"),
    (lambda: simplex_lsq(np.ones((2, 3, 4)), np.ones((2, 3)), k=0), "k must be a positive"),
    (lambda: simplex_lsq(np.ones((2, 3, 4)), np.ones((2, 3)), lam=-1), "lam must be >= 0"),
    (lambda: simplex_qp(np.ones((2, 3, 4)), np.ones((2, 3))), r"H must have shape \(n, m, m\)"),
])
def test_simplex_lsq_bad_input(call, match):
    with pytest.raises(ValueError, match=match):
        call()
