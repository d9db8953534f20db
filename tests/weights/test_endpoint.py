"""Endpoint weights: projection, idw, heat, bbw, bbw-joints (paper §2.2-2.3, Figs. 7-8)."""

from __future__ import annotations

import importlib.util
import warnings

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.optimize import lsq_linear

import stbs
import stbs.io
from stbs.shapes import box_tets
from stbs.weights import endpoint as ep
from stbs.weights.laplacian import cotmatrix, massmatrix

HAS_BBW = importlib.util.find_spec("stbs.weights.bbw") is not None


# -- meshes --------------------------------------------------------------------------------
def grid_2d(keep, x1, y1, h):
    """Triangulated grid over [0, x1] x [0, y1], keeping cells whose centre passes ``keep``."""
    nx, ny = int(round(x1 / h)), int(round(y1 / h))
    xs, ys = np.linspace(0, x1, nx + 1), np.linspace(0, y1, ny + 1)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    V = np.stack([X.ravel(), Y.ravel()], axis=1)
    vid = np.arange(V.shape[0]).reshape(nx + 1, ny + 1)
    CX, CY = np.meshgrid((xs[:-1] + xs[1:]) / 2, (ys[:-1] + ys[1:]) / 2, indexing="ij")
    i, j = np.nonzero(keep(CX, CY))
    a, b, c, d = vid[i, j], vid[i + 1, j], vid[i + 1, j + 1], vid[i, j + 1]
    F = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    used = np.unique(F)
    remap = -np.ones(V.shape[0], dtype=int)
    remap[used] = np.arange(used.size)
    return V[used], remap[F]


def u_shape(h=0.25):
    """A U: arms x in [0, 1] and [2, 3] up to y = 4, joined by the bottom y < 1."""
    return grid_2d(lambda x, y: (y < 1) | (x < 1) | (x > 2), 3.0, 4.0, h)


class LsqBBW:
    """Stand-in bounded biharmonic solver with ``BBWSolver``'s interface (tests only).

    min |M^-1/2 L x|^2 subject to x[b] = bc and 0 <= x <= 1, one column at a time,
    as a bounded least-squares problem. Exact but slow: small meshes only.
    """

    def __init__(self, V, T):
        L = cotmatrix(V, T)
        m = massmatrix(V, T).diagonal()
        self.A = (sp.diags_array(1.0 / np.sqrt(m)) @ L).toarray()
        self.n = V.shape[0]

    def solve(self, b, bc, tol=1e-10, progress=None):   # bvls solves to its own 1e-12
        if progress is not None:
            progress(0, 1)                      # a cancel point, as the real solver's
        b = np.asarray(b)
        bc = np.asarray(bc, dtype=float).reshape(len(b), -1)
        free = np.setdiff1d(np.arange(self.n), b)
        Af, Ab = self.A[:, free], self.A[:, b]
        X = np.zeros((self.n, bc.shape[1]))
        for k in range(bc.shape[1]):
            res = lsq_linear(Af, -(Ab @ bc[:, k]), bounds=(0.0, 1.0), method="bvls",
                             tol=1e-12)
            X[free, k] = res.x
            X[b, k] = bc[:, k]
        return X


def _real_solver():
    from stbs.weights.bbw import BBWSolver
    return BBWSolver


@pytest.fixture(params=["stand-in", pytest.param(
    "bbw", marks=pytest.mark.skipif(not HAS_BBW, reason="stbs.weights.bbw not there yet"))])
def bbw_solver(request, monkeypatch):
    """Run the BBW endpoint tests with the stand-in and, once it exists, the real solver."""
    cls = LsqBBW if request.param == "stand-in" else _real_solver()
    monkeypatch.setattr(ep, "_bbw_solver_class", lambda: cls)
    return request.param


# -- projection and IDW -------------------------------------------------------------------
def bar():
    return stbs.Skeleton([[0.0, 0, 0], [2.0, 0, 0]], [[0, 1]])


def test_projection_and_eq7_by_hand():
    sk = bar()
    V = np.array([[-1.0, 1, 0], [0.5, 3, 0], [1.0, 0, 0], [5, 0, 0]])
    np.testing.assert_allclose(ep.projection(V, sk)[:, 0], [0, 0.25, 0.5, 1])
    J = np.array([[1.0, 0.0], [0.5, 0.5], [0.0, 1.0], [0.25, 0.25]])
    np.testing.assert_allclose(ep.joints_to_endpoint(J, sk)[:, 0], [0, 0.5, 1, 0.5])


def test_idw_by_hand():
    sk = bar()
    # d_a = 1, d_b = 1 ... and d_a = 1, d_b = 3: e = d_a^2 / (d_a^2 + d_b^2)
    V = np.array([[1.0, 0, 0], [-1.0, 0, 0], [0.0, 0, 0], [2.0, 0, 0]])
    np.testing.assert_allclose(ep.idw(V, sk)[:, 0], [0.5, 0.1, 0.0, 1.0])
    np.testing.assert_allclose(ep.idw(V, sk, alpha=4)[:, 0], [0.5, 1 / 82, 0.0, 1.0])


@pytest.mark.parametrize("normalize", ["bone", "all"])
def test_idw_bounds_and_interpolation(normalize):
    rng = np.random.default_rng(3)
    sk = stbs.Skeleton(rng.normal(size=(5, 3)), [[0, 1], [1, 2], [2, 3], [1, 4]])
    V = rng.normal(scale=2.0, size=(500, 3))
    E = ep.idw(V, sk, alpha=2.5, normalize=normalize)
    assert E.shape == (500, 4) and E.min() >= 0 and E.max() <= 1
    Ej = ep.idw(sk.C, sk, normalize=normalize)                 # at the joints themselves
    np.testing.assert_allclose(Ej[sk.BE[:, 0], np.arange(4)], 0.0, atol=1e-15)
    np.testing.assert_allclose(Ej[sk.BE[:, 1], np.arange(4)], 1.0, atol=1e-15)
    J = ep.idw_joint_weights(V, sk)
    np.testing.assert_allclose(J.sum(axis=1), 1.0)
    # Fall-off: far away, e regresses to 0.5 (paper §2.3).
    far = ep.idw(np.array([[1e4, 3e4, -2e4]]), sk, normalize=normalize)
    np.testing.assert_allclose(far, 0.5, atol=1e-3)


def test_idw_bone_and_all_differ_near_a_neighbouring_joint():
    sk = stbs.Skeleton([[0.0, 0, 0], [1, 0, 0], [2, 0, 0]], [[0, 1], [1, 2]])
    p = np.array([[1.9, 0.0, 0.0]])                           # near bone 1's end joint
    # "bone": only bone 0's joints count, d_a = 1.9, d_b = 0.9 -> e = 0.817
    assert ep.idw(p, sk, normalize="bone")[0, 0] == pytest.approx(1.9**2 / (1.9**2 + 0.9**2))
    assert ep.idw(p, sk, normalize="all")[0, 0] == pytest.approx(0.5, abs=0.02)


def test_fig7_projection_is_only_c0_at_the_ends():
    """Fig. 7 as numbers: de/dt along the axis jumps from 1 to 0 at b for projection."""
    sk = bar()
    h = 1e-4

    def slopes(method):
        t = np.array([1 - 2 * h, 1 - h, 1 + h, 1 + 2 * h, -2 * h, -h, h, 2 * h])
        V = np.stack([2 * t, 0.2 + 0 * t, 0 * t], axis=1)   # a line beside the bone
        e = stbs.endpoint_weights(V, sk, method=method)[:, 0]
        return np.array([(e[1] - e[0]) / h, (e[3] - e[2]) / h,
                         (e[5] - e[4]) / h, (e[7] - e[6]) / h])

    s = slopes("projection")
    assert abs(s[0] - s[1]) == pytest.approx(1.0, abs=1e-6)    # jump at b
    assert abs(s[2] - s[3]) == pytest.approx(1.0, abs=1e-6)    # jump at a
    s = slopes("idw")
    assert abs(s[0] - s[1]) < 1e-2 and abs(s[2] - s[3]) < 1e-2  # smooth


# -- validation -----------------------------------------------------------------------------
def test_methods_and_options_are_validated():
    sk = bar()
    V = np.zeros((3, 3))
    assert ep.ENDPOINT_METHODS == ("projection", "idw", "heat", "bbw", "bbw-joints")
    with pytest.raises(ValueError, match="method must be one of 'projection', 'idw'"):
        stbs.endpoint_weights(V, sk, method="geodesic")
    with pytest.raises(ValueError, match="alpha applies to method='idw' only"):
        stbs.endpoint_weights(V, sk, method="projection", alpha=3)
    with pytest.raises(ValueError, match="backend applies to method='heat' only"):
        stbs.endpoint_weights(V, sk, method="idw", backend="numpy")
    with pytest.raises(ValueError, match="tol applies to method='bbw' or method='bbw-joints'"):
        stbs.endpoint_weights(V, sk, method="heat", tol=1e-6)
    with pytest.raises(ValueError, match="alpha must be a finite number >= 2"):
        stbs.endpoint_weights(V, sk, method="idw", alpha=1)
    with pytest.raises(ValueError, match="normalize must be one of 'bone', 'all'"):
        stbs.endpoint_weights(V, sk, method="idw", normalize="joints")
    with pytest.raises(ValueError, match=r"threshold must be a number in \[0, 1\)"):
        stbs.endpoint_weights(V, sk, method="idw", threshold=2.0)
    with pytest.raises(ValueError, match="method='heat' needs triangles F"):
        stbs.endpoint_weights(V, sk, method="heat")
    with pytest.raises(ValueError, match=r"tetrahedra T \(t, 4\) in 3D.*F only"):
        stbs.endpoint_weights(V, sk, method="bbw", F=[[0, 1, 2]])
    with pytest.raises(ValueError, match=r"T must have shape \(t, 4\)"):
        stbs.endpoint_weights(V, sk, method="bbw-joints", T=[[0, 1, 2]])
    with pytest.raises(ValueError, match="to match the 3D skeleton"):
        stbs.endpoint_weights(np.zeros((3, 2)), sk, method="idw")


# -- heat --------------------------------------------------------------------------------------
def test_fig8_heat_endpoint_weights_fall_short_beyond_the_handles():
    """Fig. 8: a box twisted 360 degrees at b; with heat joints the far end lags behind."""
    V, _, F = box_tets(h=0.25)
    sk = stbs.Skeleton([[1.0, 0.5, 0.5], [3.0, 0.5, 0.5]], [[0, 1]])
    E = stbs.endpoint_weights(V, sk, method="heat", F=F)
    surf = np.unique(F)
    far = surf[V[surf, 0] == 4.0]
    near = surf[V[surf, 0] == 0.0]
    twist_at_far_end = 360 * E[far, 0].max()          # 340 degrees
    assert twist_at_far_end < 360 * (1 - 0.03), f"heat reached {twist_at_far_end:.0f} degrees"
    assert E[near, 0].min() > 0.03                      # and the near end is not untwisted
    assert E[surf].min() >= 0 and E[surf].max() <= 1
    mid = surf[V[surf, 0] == 2.0]
    np.testing.assert_allclose(E[mid, 0], 0.5, atol=1e-6)   # symmetric box


@pytest.mark.parametrize("restricted", [False, True])
def test_heat_endpoint_joint_outside_the_shape_stands_in_from_inside(restricted):
    # The bone runs past the box's end (x = 4) to x = 5: joint 1 sees no vertex from
    # inside, so it is replaced, as a heat handle, by the bone's last point inside.
    V, _, F = box_tets(h=0.25)
    sk = stbs.Skeleton([[1.0, 0.5, 0.5], [5.0, 0.5, 0.5]], [[0, 1]])
    W = np.ones((V.shape[0], 1)) if restricted else None
    with pytest.warns(UserWarning, match=r"1 joint\(s\) lie outside the shape.*joint 1 "
                      r"\(bone 0\): 26 % of the bone inwards"):
        E = stbs.endpoint_weights(V, sk, method="heat", F=F, W=W)
    surf = np.unique(F)
    assert E[surf].min() >= 0 and E[surf].max() <= 1
    line = surf[np.isclose(V[surf, 1], 0.0) & np.isclose(V[surf, 2], 0.0)]
    line = line[np.argsort(V[line, 0])]
    assert np.all(np.diff(E[line, 0]) >= -1e-9)         # grows along the bone
    assert E[line[-1], 0] > 0.9 and E[line[0], 0] < 0.1  # 0 at the start, ~1 at the end
    # A joint inside is left alone: no warning.
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        stbs.endpoint_weights(V, stbs.Skeleton([[1.0, 0.5, 0.5], [3.0, 0.5, 0.5]], [[0, 1]]),
                              method="heat", F=F, W=W)


def test_fig8_bbw_endpoint_weights_reach_the_full_twist(bbw_solver):
    V, T, _ = box_tets(h=0.5 if bbw_solver == "stand-in" else 0.25)   # the stand-in is slow
    sk = stbs.Skeleton([[1.0, 0.5, 0.5], [3.0, 0.5, 0.5]], [[0, 1]])
    E = stbs.endpoint_weights(V, sk, method="bbw", T=T)
    far = V[:, 0] == 4.0
    assert 360 * E[far, 0].min() > 360 * 0.99
    assert E[V[:, 0] == 0.0, 0].max() < 0.01
    on = np.isclose(V[:, 1], 0.5) & np.isclose(V[:, 2], 0.5) & (V[:, 0] >= 1) & (V[:, 0] <= 3)
    np.testing.assert_allclose(E[on, 0], (V[on, 0] - 1) / 2, atol=1e-12)   # linear on the bone


def test_u_shape_idw_is_shape_unaware_heat_is_not():
    """Bone down the left arm of a U; the right arm's tip is Euclidean-near a but lies
    beyond b along the shape, so a shape-aware e is near 1 there."""
    V, F = u_shape()
    sk = stbs.Skeleton([[0.5, 3.5], [0.5, 1.5]], [[0, 1]])
    tip = (V[:, 0] >= 2) & (V[:, 1] >= 3.5)
    e_idw = stbs.endpoint_weights(V, sk, method="idw")[tip, 0]
    assert e_idw.max() < 0.5                             # pulled toward a across the gap
    e_heat = stbs.endpoint_weights(V, sk, method="heat", F=F)[tip, 0]
    assert e_heat.min() > 0.5


@pytest.mark.parametrize("joints", [False, True])
def test_u_shape_bbw_is_shape_aware(bbw_solver, joints):
    V, F = u_shape(h=0.5)
    sk = stbs.Skeleton([[0.5, 3.5], [0.5, 1.5]], [[0, 1]])
    method = "bbw-joints" if joints else "bbw"
    E = stbs.endpoint_weights(V, sk, method=method, F=F)
    # a looser KKT tolerance reaches the solver (fewer rounds) and stays close
    seen = []
    cls = ep._bbw_solver_class()
    orig = cls.solve
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(cls, "solve", lambda self, *a, **k: seen.append(k["tol"]) or orig(
            self, *a, **k))
        E6 = stbs.endpoint_weights(V, sk, method=method, F=F, tol=1e-6)
    assert seen and set(seen) == {1e-6}
    assert np.abs(E6 - E).max() < 1e-4
    tip = (V[:, 0] >= 2) & (V[:, 1] >= 3.5)
    assert E[tip, 0].min() > 0.75
    assert E.min() >= 0 and E.max() <= 1
    a = np.all(V == [0.5, 3.5], axis=1)
    b = np.all(V == [0.5, 1.5], axis=1)
    assert E[a, 0] == pytest.approx(0.0, abs=1e-9) and E[b, 0] == pytest.approx(1.0, abs=1e-9)
    if not joints:                                       # 2D: linear along the bone
        on = (V[:, 0] == 0.5) & (V[:, 1] >= 1.5) & (V[:, 1] <= 3.5)
        np.testing.assert_allclose(E[on, 0], (3.5 - V[on, 1]) / 2, atol=1e-12)


def test_restriction_solves_only_where_the_bone_has_weight():
    V, _, F = box_tets(h=0.25)
    sk = stbs.Skeleton([[0.5, 0.5, 0.5], [2.0, 0.5, 0.5], [3.5, 0.5, 0.5]], [[0, 1], [1, 2]])
    W = np.zeros((V.shape[0], 2))
    W[:, 0] = np.clip((2.5 - V[:, 0]) / 1.0, 0, 1)           # bone 0: nothing beyond x = 2.5
    W[:, 1] = 1 - W[:, 0]
    E = stbs.endpoint_weights(V, sk, method="heat", F=F, W=sp.csr_array(W))
    P = ep.projection(V, sk)
    surf = np.unique(F)
    outside = surf[V[surf, 0] > 2.5 + 0.25]                 # beyond the support's triangles
    np.testing.assert_allclose(E[outside, 0], P[outside, 0])
    inside = surf[V[surf, 0] <= 2.0]
    full = stbs.endpoint_weights(V, sk, method="heat", F=F)
    assert not np.allclose(E[inside, 0], P[inside, 0])
    assert np.abs(E[inside, 0] - full[inside, 0]).max() < 0.1   # restriction changes little
    np.testing.assert_array_equal(
        stbs.endpoint_weights(V, sk, method="heat", F=F, W=W, threshold=None), full)


def test_restricted_bbw_leaves_the_rest_to_projection(bbw_solver):
    V, F = grid_2d(lambda x, y: np.ones_like(x, dtype=bool), 4.0, 1.0, 0.25)
    sk = stbs.Skeleton([[0.5, 0.5], [2.0, 0.5], [3.5, 0.5]], [[0, 1], [1, 2]])
    W = np.zeros((V.shape[0], 2))
    W[:, 0] = np.clip(2.5 - V[:, 0], 0, 1)
    W[:, 1] = 1 - W[:, 0]
    for method in ("bbw", "bbw-joints"):
        E = stbs.endpoint_weights(V, sk, method=method, F=F, W=W)
        beyond = V[:, 0] > 2.75
        np.testing.assert_allclose(E[beyond, 0], ep.projection(V, sk)[beyond, 0])
        assert E.min() >= 0 and E.max() <= 1


def test_arm_heat_endpoint_weights(shared_data):
    data = shared_data / "libigl-tutorial-data"
    mesh = stbs.io.read_mesh(data / "arm.obj")
    sk = stbs.io.read_skeleton(data / "arm.tgf")
    from stbs.weights.heat import bone_heat
    W = bone_heat(mesh.V, mesh.F, sk)
    E = stbs.endpoint_weights(mesh.V, sk, method="heat", F=mesh.F, W=W)
    assert E.min() >= 0 and E.max() <= 1
    P = ep.projection(mesh.V, sk)
    for i in range(sk.n_bones):
        mine = W[:, i] > 0.5
        # e grows from a to b: mean e over bands of the projection parameter increases.
        band = np.digitize(P[mine, i], [0.1, 0.3, 0.5, 0.7, 0.9])
        means = [E[mine, i][band == k].mean() for k in range(6)]
        assert np.all(np.diff(means) > 0.05), f"bone {i}: {np.round(means, 2)}"
        # The forearm bones follow the projection closely (r = 0.99); the hand bone less
        # (r = 0.77): its fingers lie beyond b and feel the heat fall-off of Fig. 8.
        corr = np.corrcoef(E[mine, i], P[mine, i])[0, 1]
        assert corr > (0.98 if i < 3 else 0.7), f"bone {i}: correlation {corr:.2f}"


def test_bbw_joint_off_the_mesh_uses_the_nearest_vertex_and_says_how_far(bbw_solver):
    V, F = grid_2d(lambda x, y: np.ones_like(x, dtype=bool), 3.0, 1.0, 0.5)
    sk = stbs.Skeleton([[0.6, 0.5], [2.0, 0.5]], [[0, 1]])
    with pytest.warns(UserWarning, match=r"joint 0 -> vertex \d+ at distance 0\.1\b"):
        E = stbs.endpoint_weights(V, sk, method="bbw", F=F)
    assert E[np.all(V == [0.5, 0.5], axis=1), 0] == pytest.approx(0.0, abs=1e-9)
    close = stbs.Skeleton([[0.6, 0.5], [0.7, 0.5]], [[0, 1]])
    for method in ("bbw", "bbw-joints"):
        with pytest.raises(ValueError, match="joints 0 and 1 map to the same mesh vertex"), \
                pytest.warns(UserWarning):
            stbs.endpoint_weights(V, close, method=method, F=F)


@pytest.mark.skipif(not HAS_BBW, reason="stbs.weights.bbw not there yet")
def test_hand_bbw_endpoint_weights_restricted(shared_data):
    """libigl's hand.mesh carries 12 samples on each of its 20 bones: e interpolates them."""
    data = shared_data / "libigl-tutorial-data"
    mesh = stbs.io.read_mesh(data / "hand.mesh")
    sk = stbs.io.read_skeleton(data / "hand.tgf")
    V, T = mesh.V, mesh.T
    # Compact, shape-unaware bone weights: enough to exercise the restriction cheaply.
    A, D = sk.A, sk.B - sk.A
    t = np.clip(np.einsum("nbd,bd->nb", V[:, None] - A, D) / sk.lengths**2, 0, 1)
    dist = np.linalg.norm(V[:, None] - (A + t[..., None] * D), axis=-1)
    W = np.exp(-(dist / (0.5 * dist.min(axis=1, keepdims=True) + 0.02 * np.ptp(V)))**2)
    W /= W.sum(axis=1, keepdims=True)
    E = stbs.endpoint_weights(V, sk, method="bbw", T=T, W=W, threshold=1e-3)
    assert E.min() >= 0 and E.max() <= 1
    P = ep.projection(V, sk)
    tol = 1e-6 * np.linalg.norm(np.ptp(V, axis=0))
    for i in range(sk.n_bones):
        on = dist[:, i] <= tol
        assert on.sum() >= 12
        np.testing.assert_allclose(E[on, i], t[on, i], atol=1e-9)   # linear along the bone
        mine = W[:, i] > 0.5
        band = np.digitize(P[mine, i], [0.25, 0.5, 0.75])
        means = [E[mine, i][band == k].mean() for k in range(4) if np.any(band == k)]
        assert np.all(np.diff(means) > 0), f"bone {i}: {np.round(means, 2)}"
        outside = W[:, i] <= 1e-3
        touched = np.zeros(len(V), dtype=bool)
        touched[np.unique(T[(W[T, i] > 1e-3).any(axis=1)])] = True
        far = outside & ~touched
        np.testing.assert_allclose(E[far, i], P[far, i])             # projection outside


@pytest.mark.skipif(not HAS_BBW, reason="stbs.weights.bbw not there yet")
@pytest.mark.parametrize("restricted", [True, False])
@pytest.mark.parametrize("method", ["bbw", "bbw-joints"])
def test_bones_on_threads_match_one_thread(monkeypatch, restricted, method):
    """Per-bone BBW solves on worker threads give the one-thread answer, bar by bar.

    Unrestricted, every bone shares the whole-mesh solver (built once, under a lock).
    """
    V, T, _ = box_tets(h=0.25)
    sk = stbs.Skeleton([[0.5, 0.5, 0.5], [1.5, 0.5, 0.5], [2.5, 0.5, 0.5], [3.5, 0.5, 0.5]],
                       [[0, 1], [1, 2], [2, 3]])
    t = np.clip(V[:, 0] - 0.5, 0, 3)
    W = np.maximum(0.0, 1.0 - np.abs(t[:, None] - np.array([0.5, 1.5, 2.5])))
    W /= W.sum(axis=1, keepdims=True)
    kw = dict(T=T, W=W, threshold=1e-3 if restricted else None)
    from threadpoolctl import threadpool_info

    from stbs.weights.bbw import BBWSolver

    made = []

    class Spy(BBWSolver):
        def __init__(self, *a, **kw):
            made.append(kw)
            super().__init__(*a, **kw)

    monkeypatch.setattr(ep, "_bbw_solver_class", lambda: Spy)
    blas = [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]
    runs = {}
    for workers in (1, 3):
        calls = []
        made.clear()
        monkeypatch.setattr(ep, "_bone_workers", lambda cls, b, w=workers: min(w, b))
        runs[workers] = stbs.endpoint_weights(V, sk, method=method, progress=lambda d, b, c=calls:
                                              c.append((d, b)), **kw)
        # unrestricted joint weights are one solve for all joints
        one = method == "bbw-joints" and not restricted
        if one:     # reported at the solver's rounds, scaled to bones
            assert calls[-1] == (3, 3) and calls == sorted(calls) and len(calls) > 1
        else:
            assert calls == [(1, 3), (2, 3), (3, 3)]
        # on threads, the solvers leave BLAS alone: the pool holds one process-wide limit
        threaded = workers > 1 and not one
        assert made and all(("blas_threads" in kw) == threaded for kw in made)
        assert all(kw["blas_threads"] is None for kw in made if threaded)
    assert [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"] == blas
    np.testing.assert_allclose(runs[3], runs[1], atol=1e-9)
    assert runs[1].min() >= 0 and runs[1].max() <= 1


def test_a_failing_bone_on_a_thread_raises_its_error(monkeypatch):
    from stbs.weights.bbw import BBWSolver

    V, T, _ = box_tets(h=0.5)
    sk = stbs.Skeleton([[0.5, 0.5, 0.5], [2.0, 0.5, 0.5], [3.5, 0.5, 0.5]], [[0, 1], [1, 2]])
    class Failing(BBWSolver):
        def solve(self, b, bc, **kw):
            raise ValueError("bone region broke")

    monkeypatch.setattr(ep, "_bbw_solver_class", lambda: Failing)
    monkeypatch.setattr(ep, "_bone_workers", lambda cls, b: 2)
    for W in (None, np.full((len(V), 2), 0.5)):      # the shared solver, and per region
        with pytest.raises(ValueError, match="bone region broke"):
            stbs.endpoint_weights(V, sk, method="bbw", T=T, W=W)


def test_bone_workers_only_for_our_solver_on_cholmod(monkeypatch):
    from stbs.weights import _cholmod
    from stbs.weights.bbw import BBWSolver

    assert ep._bone_workers(LsqBBW, 5) == 1           # a stand-in: never threads
    assert ep._bone_workers(BBWSolver, 1) == 1
    monkeypatch.setattr(_cholmod, "library", lambda: None)
    assert ep._bone_workers(BBWSolver, 5) == 1        # scikit-sparse, cholespy: hold the GIL
