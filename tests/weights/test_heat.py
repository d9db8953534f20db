"""Bone heat (Baran & Popović 2007) and its visibility ray casting."""

from __future__ import annotations

import numpy as np
import pytest

import stbs
import stbs.io
from stbs.weights import _raycast
from stbs.weights.heat import BoneHeatSolver, BoneHeatWarning, bone_heat, heat_joint_weights

HAS_EMBREE = _raycast.embree_available()


def box_surface(lo=(0.0, 0.0, 0.0), hi=(4.0, 1.0, 1.0), h=0.25):
    """Closed, outward-oriented triangulated surface of an axis-aligned box (grid spacing h)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    m = np.maximum(np.round((hi - lo) / h).astype(int), 1)
    axes = [np.linspace(lo[k], hi[k], m[k] + 1) for k in range(3)]
    G = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)
    idx = -np.ones(m + 1, dtype=int)
    onb = np.zeros(m + 1, dtype=bool)
    onb[[0, -1], :, :] = onb[:, [0, -1], :] = onb[:, :, [0, -1]] = True
    idx[onb] = np.arange(onb.sum())
    V = G[onb]
    F = []
    for k in range(3):                      # the two faces normal to axis k
        for side in (0, m[k]):
            sl = [slice(None)] * 3
            sl[k] = side
            I = idx[tuple(sl)]                # 2D grid of vertex ids on that face
            quads = np.stack([I[:-1, :-1], I[1:, :-1], I[1:, 1:], I[:-1, 1:]], -1).reshape(-1, 4)
            F.append(np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]]))
    F = np.concatenate(F)
    # Orient outward: the normal must point away from the box centre.
    cen = 0.5 * (lo + hi)
    n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    out = np.einsum("ij,ij->i", n, V[F].mean(axis=1) - cen) < 0
    F[out] = F[out][:, ::-1]
    return V, F


def test_box_surface_is_closed_and_outward():
    V, F = box_surface(h=0.5)
    E = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    _, cnt = np.unique(E, axis=0, return_counts=True)
    assert np.all(cnt == 2)
    vol = np.einsum("ij,ij->", V[F[:, 0]], np.cross(V[F[:, 1]], V[F[:, 2]])) / 6
    assert vol == pytest.approx(4.0)


# -- ray casting -----------------------------------------------------------------------
def test_segment_triangle_by_hand():
    V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    F = np.array([[0, 1, 2]])
    O = np.array([[0.2, 0.2, 1], [0.2, 0.2, 1], [0.2, 0.2, 1], [2, 2, 1], [0.2, 0.2, -1]])
    D = np.array([[0, 0, -2], [0, 0, -0.5], [0, 0, 2], [0, 0, -2], [0, 0, 3]])
    want = [True, False, False, False, True]   # through, short, away, beside, from below
    np.testing.assert_array_equal(_raycast.occluded_brute(V, F, O, D), want)
    for backend in ["numpy"] + (["embree"] if HAS_EMBREE else []):
        caster = _raycast.SegmentCaster(V, F, backend=backend)
        np.testing.assert_array_equal(caster.occluded(O, D), want)


@pytest.mark.parametrize("backend", [
    "numpy", pytest.param("embree", marks=pytest.mark.skipif(not HAS_EMBREE,
                                                             reason="embreex not installed"))])
def test_backends_agree_with_brute_force(backend):
    rng = np.random.default_rng(7)
    V, F = box_surface(h=0.5)
    V = V + rng.normal(scale=0.03, size=V.shape)      # not axis-aligned any more
    O = rng.uniform([-0.5, -0.5, -0.5], [4.5, 1.5, 1.5], size=(3000, 3))
    D = rng.normal(scale=0.8, size=(3000, 3))
    ref = _raycast.occluded_brute(V, F, O, D)
    got = _raycast.SegmentCaster(V, F, backend=backend).occluded(O, D)
    assert 0.1 < ref.mean() < 0.9
    # Embree works in single precision: a grazing hit may flip, nothing more.
    assert np.count_nonzero(got != ref) <= (0 if backend == "numpy" else 3)


def test_2d_boundary_blocks_segments():
    # A U: the gap between its arms is outside the shape.
    V, F = u_shape()
    caster = _raycast.SegmentCaster(V, F)
    O = np.array([[0.5, 3.5], [0.5, 3.5], [0.5, 0.5]])
    D = np.array([[2.0, 0.0], [0.0, -3.0], [2.0, 0.0]])
    np.testing.assert_array_equal(caster.occluded(O, D), [True, False, False])


def test_unknown_backend_is_rejected():
    V, F = box_surface(h=1.0)
    with pytest.raises(ValueError, match="backend must be one of 'auto', 'embree', 'numpy'"):
        _raycast.SegmentCaster(V, F, backend="optix")


def u_shape(h=0.25):
    """2D U: arms x in [0,1] and [2,3] up to y = 4, joined by the bottom y in [0,1]."""
    nx, ny = int(round(3 / h)), int(round(4 / h))
    xs, ys = np.linspace(0, 3, nx + 1), np.linspace(0, 4, ny + 1)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    V = np.stack([X.ravel(), Y.ravel()], axis=1)
    vid = np.arange(V.shape[0]).reshape(nx + 1, ny + 1)
    cx = (xs[:-1] + xs[1:]) / 2
    cy = (ys[:-1] + ys[1:]) / 2
    CX, CY = np.meshgrid(cx, cy, indexing="ij")
    keep = (CY < 1) | (CX < 1) | (CX > 2)
    i, j = np.nonzero(keep)
    a, b, c, d = vid[i, j], vid[i + 1, j], vid[i + 1, j + 1], vid[i, j + 1]
    F = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    used = np.unique(F)
    remap = -np.ones(V.shape[0], dtype=int)
    remap[used] = np.arange(used.size)
    return V[used], remap[F]


# -- bone heat -------------------------------------------------------------------------
def test_single_bone_gets_all_the_weight():
    V, F = box_surface(h=0.5)
    sk = stbs.Skeleton([[1.0, 0.5, 0.5], [3.0, 0.5, 0.5]], [[0, 1]])
    W, report = bone_heat(V, F, sk, return_report=True)
    np.testing.assert_allclose(W, 1.0, atol=1e-12)
    assert report.n_nearest[0] == V.shape[0] and report.empty == ()


def test_two_bones_symmetric_partition_and_nearest():
    V, F = box_surface(h=0.25)
    sk = stbs.Skeleton([[0.5, 0.5, 0.5], [2.0, 0.5, 0.5], [3.5, 0.5, 0.5]], [[0, 1], [1, 2]])
    W, report = bone_heat(V, F, sk, backend="numpy", return_report=True)
    assert W.shape == (V.shape[0], 2)
    assert W.min() >= 0 and W.max() <= 1
    np.testing.assert_allclose(W.sum(axis=1), 1.0, atol=1e-10)
    # Mirror symmetry x -> 4 - x swaps the bones.
    mirror = np.array([np.flatnonzero(np.all(np.isclose(V, [4 - p[0], p[1], p[2]]), axis=1))[0]
                       for p in V])
    np.testing.assert_allclose(W[mirror, 0], W[:, 1], atol=1e-8)
    far0 = V[:, 0] <= 0.5
    assert W[far0, 0].min() > 0.95
    mid = np.isclose(V[:, 0], 2.0)
    np.testing.assert_allclose(W[mid], 0.5, atol=1e-8)   # tie: p = 1/2, H = 2 c / d^2
    assert report.n_nearest.sum() >= V.shape[0]


def test_report_lists_every_bone():
    V, F = box_surface(h=0.5)
    sk = stbs.Skeleton([[0.5, 0.5, 0.5], [2.0, 0.5, 0.5], [3.5, 0.5, 0.5]], [[0, 1], [1, 2]],
                       names=["upper", "lower"])
    _, report = bone_heat(V, F, sk, return_report=True)
    text = str(report)
    assert "bone 0 ('upper')" in text and "bone 1 ('lower')" in text
    assert report.n_blind == 0 and report.n_components == 1


@pytest.mark.skipif(not HAS_EMBREE, reason="embreex not installed")
def test_embree_and_numpy_give_the_same_weights():
    V, F = box_surface(h=0.25)
    sk = stbs.Skeleton([[0.5, 0.5, 0.5], [2.0, 0.6, 0.4], [3.5, 0.5, 0.5]], [[0, 1], [1, 2]])
    W1 = bone_heat(V, F, sk, backend="numpy")
    W2 = bone_heat(V, F, sk, backend="embree")
    np.testing.assert_allclose(W1, W2, atol=1e-9)


def test_bone_outside_the_shape_is_an_error_naming_it():
    V, F = box_surface(h=0.5)
    # bone 1 lies just above the box: the top face is nearer to it but cannot see it.
    sk = stbs.Skeleton([[0.5, 0.5, 0.5], [3.5, 0.5, 0.5], [0.5, 1.3, 0.5], [3.5, 1.3, 0.5]],
                       [[0, 1], [2, 3]], names=["inside", "outside"])
    with pytest.raises(ValueError, match=r"bone 1 \('outside'\).*outside the shape"):
        bone_heat(V, F, sk)
    with pytest.warns(BoneHeatWarning, match="bone 1"):
        W, report = bone_heat(V, F, sk, on_empty="warn", return_report=True)
    assert report.empty == (1,) and report.n_occluded[1] > 0
    np.testing.assert_allclose(W[:, 0], 1.0, atol=1e-12)


def test_disconnected_pieces_are_solved_separately():
    V1, F1 = box_surface((0, 0, 0), (2, 1, 1), h=0.25)
    V2, F2 = box_surface((0, 3, 0), (2, 4, 1), h=0.25)
    V = np.vstack([V1, V2])
    F = np.vstack([F1, F2 + len(V1)])
    sk = stbs.Skeleton([[0.5, 0.5, 0.5], [1.5, 0.5, 0.5], [0.5, 3.5, 0.5], [1.5, 3.5, 0.5]],
                       [[0, 1], [2, 3]])
    W, report = bone_heat(V, F, sk, return_report=True)
    assert report.n_components == 2 and report.blind_components == ()
    np.testing.assert_allclose(W[:len(V1), 0], 1.0, atol=1e-10)
    np.testing.assert_allclose(W[len(V1):, 1], 1.0, atol=1e-10)


def test_piece_that_sees_no_bone_uses_the_nearest_with_a_warning():
    V1, F1 = box_surface((0, 0, 0), (4, 1, 1), h=0.25)
    V2, F2 = box_surface((0, 2, 0), (4, 3, 1), h=0.5)      # no bone inside
    V = np.vstack([V1, V2])
    F = np.vstack([F1, F2 + len(V1)])
    sk = stbs.Skeleton([[0.5, 0.5, 0.5], [2.0, 0.5, 0.5], [3.5, 0.5, 0.5]], [[0, 1], [1, 2]])
    with pytest.warns(BoneHeatWarning, match=r"component 1 \(\d+ vertices.*sees no handle"):
        W, report = bone_heat(V, F, sk, return_report=True)
    assert report.blind_components == (1,)
    second = W[len(V1):]
    np.testing.assert_allclose(second.sum(axis=1), 1.0, atol=1e-10)   # never all zero
    left = V2[:, 0] < 1.0
    assert np.all(second[left].argmax(axis=1) == 0)


def test_inside_out_surface_gives_the_same_weights():
    V, F = box_surface(h=0.25)
    sk = stbs.Skeleton([[0.5, 0.5, 0.5], [2.0, 0.5, 0.5], [3.5, 0.5, 0.5]], [[0, 1], [1, 2]])
    np.testing.assert_allclose(bone_heat(V, F[:, ::-1], sk), bone_heat(V, F, sk), atol=1e-12)


def test_heat_joint_weights_on_a_box():
    V, F = box_surface(h=0.25)
    sk = stbs.Skeleton([[1.0, 0.5, 0.5], [3.0, 0.5, 0.5]], [[0, 1]])
    J, report = heat_joint_weights(V, F, sk, return_report=True)
    np.testing.assert_allclose(J.sum(axis=1), 1.0, atol=1e-10)
    assert report.labels == ("joint 0", "joint 1")
    assert J[V[:, 0] == 0, 0].min() > 0.8 and J[V[:, 0] == 4, 1].min() > 0.8


def test_bad_inputs_name_the_argument():
    V, F = box_surface(h=1.0)
    sk = stbs.Skeleton([[1.0, 0.5, 0.5], [3.0, 0.5, 0.5]], [[0, 1]])
    with pytest.raises(ValueError, match=r"F must have shape \(\?, 3\)"):
        bone_heat(V, F[:, :2], sk)
    with pytest.raises(ValueError, match="F must hold vertex indices"):
        bone_heat(V, F + len(V), sk)
    with pytest.raises(ValueError, match="c must be a finite number > 0"):
        bone_heat(V, F, sk, c=0.0)
    with pytest.raises(ValueError, match="on_empty must be one of"):
        bone_heat(V, F, sk, on_empty="ignore")
    with pytest.raises(ValueError, match="to match the 2D skeleton"):
        bone_heat(V, F, stbs.Skeleton([[0.0, 0], [1, 0]], [[0, 1]]))
    with pytest.raises(ValueError, match="offset must be"):
        BoneHeatSolver(V, F, offset=-1.0)


def test_arm_top_weight_is_the_nearest_visible_bone(shared_data):
    data = shared_data / "libigl-tutorial-data"
    mesh = stbs.io.read_mesh(data / "arm.obj")
    sk = stbs.io.read_skeleton(data / "arm.tgf")
    solver = BoneHeatSolver(mesh.V, mesh.F)
    W, report = solver.solve(sk.A, sk.B, labels=[f"bone {i}" for i in range(sk.n_bones)])
    assert W.min() >= 0 and W.max() <= 1
    np.testing.assert_allclose(W.sum(axis=1), 1.0, atol=1e-8)
    assert report.empty == () and np.all(report.n_nearest > 500)
    near = solver._nearest(sk.A, sk.B).near           # (n, b) nearest visible bones
    sees = near.any(axis=1)
    assert sees.mean() > 0.7     # the fingers hide the hand bone from ~23% of vertices
    top = W.argmax(axis=1)
    top_is_near = near[np.arange(len(top)), top]
    assert top_is_near[sees].mean() > 0.9       # 91%: the rest lie in blend zones
    # Where the nearest visible bone is also the Euclidean-nearest one: 99.8%.
    clear = sees & (near.argmax(axis=1) == solver._nearest(sk.A, sk.B).D.argmin(axis=1))
    assert top_is_near[clear].mean() > 0.99


def test_2d_bone_heat_does_not_leak_across_a_gap():
    V, F = u_shape()
    sk = stbs.Skeleton([[0.5, 3.5], [0.5, 1.5], [2.5, 1.5], [2.5, 3.5]], [[0, 1], [2, 3]])
    W, report = bone_heat(V, F, sk, return_report=True)
    assert report.backend == "numpy-2d" and report.n_blind > 0   # between the arms
    np.testing.assert_allclose(W.sum(axis=1), 1.0, atol=1e-10)
    left_tip = (V[:, 0] <= 1) & (V[:, 1] >= 3)
    right_tip = (V[:, 0] >= 2) & (V[:, 1] >= 3)
    assert W[left_tip, 0].min() > 0.99 and W[right_tip, 1].min() > 0.99
    mirror = np.array([np.flatnonzero(np.all(np.isclose(V, [3 - p[0], p[1]]), axis=1))[0]
                       for p in V])
    np.testing.assert_allclose(W[mirror, 0], W[:, 1], atol=1e-8)
