"""stbs.meshing.volume_mesh: a tetrahedral mesh of the inside of any surface by winding
number, the skeleton's points as vertices, weights carried back by interpolation."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import stbs
from stbs.meshing import VolumeMesh, volume_mesh
from stbs.meshing._geometry import tet_volumes
from stbs.meshing.tetrahedra import _min_dihedral
from stbs.meshing.volume import SLIVER_DEGREES
from surfaces import box, join, merged, tube

TUBE_SK = stbs.Skeleton([[0.5, 0, 0], [2.5, 0, 0], [5.0, 0, 0]], [[0, 1], [1, 2]],
                        names=["upper", "tip"])


def _mesh(V, F, sk, **kw):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        vm = volume_mesh(V, F, sk, **kw)
    return vm, [str(w.message) for w in caught if issubclass(w.category, UserWarning)]


def test_open_tube_with_a_bone_poking_out():
    V, F = tube()
    vm, said = _mesh(V, F, TUBE_SK, size=0.15)
    assert isinstance(vm, VolumeMesh)
    # the part of bone 1 past the open end (x > 4) is left out, and the warning says so
    assert len(said) == 1 and "1 bone(s) leave the shape" in said[0]
    assert "bone 1 ('tip', joints 1->2): 40 % outside" in said[0]
    assert set(vm.bones_outside) == {1}
    # the skeleton's points inside are vertices, exactly where they belong
    on = vm.on_bone >= 0
    A, B = TUBE_SK.A[vm.on_bone[on]], TUBE_SK.B[vm.on_bone[on]]
    np.testing.assert_allclose(vm.V[on], A + vm.t_bone[on, None] * (B - A), atol=1e-12)
    assert vm.joint_vertex[2] == -1 and (vm.joint_vertex[:2] >= 0).all()
    np.testing.assert_array_equal(vm.V[vm.joint_vertex[:2]], TUBE_SK.C[:2])
    assert vm.V[vm.on_bone == 1, 0].max() < 4.0 + 1e-9      # nothing past the open end
    assert vm.bone_points(TUBE_SK).tolist()[0] >= 5
    # positively oriented, no slivers (the skeleton's own may keep one each)
    assert tet_volumes(vm.V, vm.T).min() > 0
    bad = np.degrees(_min_dihedral(vm.V, vm.T)) < SLIVER_DEGREES
    assert bad.sum() <= on.sum() + 3
    # every vertex is used, the kinds are recorded
    assert np.array_equal(np.unique(vm.T), np.arange(vm.V.shape[0]))
    assert set(np.unique(vm.kind)) == {0, 1, 2}


def test_interpolation_rows_are_convex_and_reproduce_positions():
    V, F = tube()
    vm, _ = _mesh(V, F, TUBE_SK, size=0.15)
    P = vm.interpolation(V)
    assert P.shape == (V.shape[0], vm.V.shape[0])
    P = P.toarray()
    assert P.min() >= 0
    np.testing.assert_allclose(P.sum(axis=1), 1.0, atol=1e-12)
    err = np.linalg.norm(P @ vm.V - V, axis=1)
    # inside a tetrahedron the position is reproduced; a vertex just outside the meshed
    # inside moves to the nearest point of the nearest tetrahedron, within the spacing
    assert np.mean(err < 1e-9) > 0.3
    assert err.max() < vm.size
    # far outside: still a convex combination, from the nearest part
    Q = vm.interpolation([[2.0, 3.0, 0.0]]).toarray()
    assert Q.min() >= 0 and Q.sum() == pytest.approx(1.0)
    assert np.linalg.norm(Q @ vm.V - [2.0, 0.5, 0.0]) < 2 * vm.size


def test_cost_follows_the_shape_not_the_surface_resolution():
    coarse, fine = tube(24, 17), tube(120, 161)           # 408 and 19,320 vertices
    a, _ = _mesh(*coarse, TUBE_SK, vertices=2000)
    b, _ = _mesh(*fine, TUBE_SK, vertices=2000)
    assert fine[0].shape[0] > 40 * coarse[0].shape[0]
    assert a.V.shape[0] == pytest.approx(b.V.shape[0], rel=0.2)
    assert a.size == pytest.approx(b.size, rel=0.15)
    assert 1200 < b.V.shape[0] < 3200                    # about the budget


def test_parts_self_intersections_and_a_non_manifold_edge():
    # two boxes side by side, a third through one of them, a fourth touching the first
    # along an edge only (that edge is in four triangles)
    A, B = box([0, 0, 0], [1, 1, 1]), box([2, 0, 0], [3, 1, 1])
    C = box([0.5, 0.25, -0.5], [0.75, 0.75, 1.5])
    D = box([1, 1, 0], [2, 2, 1])
    V, F = merged(*join(A, B, C, D))
    sk = stbs.Skeleton([[0.2, 0.5, 0.5], [0.8, 0.5, 0.5], [2.5, 0.5, 0.5],
                        [0.6, 0.5, -0.4], [1.5, 1.5, 0.5], [2.0, 5.0, 5.0], [3.0, 5.0, 5.0]],
                       [[0, 1], [1, 2], [3, 0], [1, 4], [5, 6]])
    vm, said = _mesh(V, F, sk, size=0.1)
    # bone 1 crosses the gap between A and B; bone 5 is nowhere near the shape
    assert len(said) == 1
    assert "bone 1 ('bone1', joints 1->2)" in said[0] and "bone 4 ('bone4'" in said[0]
    assert "the 1 farther than 2 times the spacing (0.1) get no bone weight (bone 4" \
        in said[0]
    assert vm.bones_outside[4][0] == 1.0 and 0 < vm.bones_outside[1][0] < 1
    assert vm.bones_outside[4][2] > 3.0                    # its nearest point's distance
    # the overlapping box and the one touching along an edge are meshed too
    for p in ([0.6, 0.5, -0.3], [2.5, 0.5, 0.5], [1.5, 1.5, 0.5]):
        assert np.linalg.norm(vm.V - p, axis=1).min() < 0.1
    b, bc, stand_in = vm.boundary_conditions(sk)
    np.testing.assert_allclose(bc.sum(axis=1), 1.0)
    assert stand_in == {} and not bc[:, 4].any()           # too far to hold anything


def test_a_bone_wholly_outside_but_near_holds_the_nearest_vertices():
    V, F = box([0, 0, 0], [2, 1, 1], 8)
    # a "toe" just under the floor, as a Mixamo toe bone lies on the sole
    sk = stbs.Skeleton([[0.2, 0.5, 0.5], [1.0, 0.5, 0.5], [1.2, 0.5, -0.03], [1.8, 0.5, -0.03]],
                       [[0, 1], [2, 3]], names=["leg", "toe"])
    vm, said = _mesh(V, F, sk, size=0.1)
    assert "bone 1 ('toe', joints 2->3): 100 % outside" in said[0]
    assert "the 1 wholly outside but near it hold the volume's vertices nearest them" in said[0]
    b, bc, stand_in = vm.boundary_conditions(sk)
    assert set(stand_in) == {1} and stand_in[1] < 0.1
    held = b[bc[:, 1] > 0]
    assert held.size >= 2 and (vm.on_bone[held] < 0).all()
    assert np.all(vm.V[held, 2] < 0.15) and np.all(vm.V[held, 0] > 1.0)


def test_a_skeleton_wholly_outside_is_an_error():
    V, F = box([0, 0, 0], [1, 1, 1])
    away = stbs.Skeleton([[3.0, 0, 0], [4.0, 0, 0]], [[0, 1]])
    with pytest.raises(ValueError, match="no joint or bone of the skeleton lies inside"), \
            pytest.warns(UserWarning, match="wholly outside"):
        volume_mesh(V, F, away)


@pytest.mark.parametrize("kw, match", [
    (dict(size=0.0), "size must be a positive number"),
    (dict(size=float("nan")), "size must be a positive number"),
    (dict(vertices=10), "vertices must be an int >= 100"),
    (dict(refine=9), "refine must be an int in 0..5"),
    (dict(size=1e-5), "pass a larger size"),
])
def test_bad_options(kw, match):
    V, F = box([0, 0, 0], [1, 1, 1])
    sk = stbs.Skeleton([[0.2, 0.5, 0.5], [0.8, 0.5, 0.5]], [[0, 1]])
    with pytest.raises(ValueError, match=match):
        volume_mesh(V, F, sk, **kw)


def test_bad_arrays():
    V, F = box([0, 0, 0], [1, 1, 1])
    sk = stbs.Skeleton([[0.2, 0.5, 0.5], [0.8, 0.5, 0.5]], [[0, 1]])
    with pytest.raises(ValueError, match="F must hold vertex indices"):
        volume_mesh(V, F + 1000, sk)
    with pytest.raises(ValueError, match="non-degenerate triangle"):
        volume_mesh(V, np.zeros((3, 3), int), sk)
    with pytest.raises(ValueError, match="3-D skeleton"):
        volume_mesh(V, F, stbs.Skeleton([[0.0, 0], [1, 0]], [[0, 1]]))


def test_refinement_where_bones_lie_close_together():
    # a "hand": three thin fingers 0.12 apart on a palm; the fingers get a finer spacing
    palm = box([0, 0, 0], [1, 1, 0.2])
    fingers = [box([1, y - 0.04, 0.06], [1.6, y + 0.04, 0.14]) for y in (0.3, 0.5, 0.7)]
    V, F = join(palm, *fingers)
    C = [[0.1, 0.5, 0.1], [0.9, 0.5, 0.1]] + [[x, y, 0.1] for y in (0.3, 0.5, 0.7)
                                               for x in (0.95, 1.55)]
    BE = [[0, 1], [2, 3], [4, 5], [6, 7]]
    sk = stbs.Skeleton(C, BE)
    flat, _ = _mesh(V, F, sk, size=0.1, refine=0)
    fine, _ = _mesh(V, F, sk, size=0.1)
    on_finger = lambda vm: (vm.V[:, 0] > 1.05) & (vm.V[:, 0] < 1.5)   # noqa: E731
    assert on_finger(fine).sum() > 3 * on_finger(flat).sum()
    # away from the fingers the spacing stays the coarse one
    palm_far = lambda vm: vm.V[:, 0] < 0.4                             # noqa: E731
    assert palm_far(fine).sum() < 2 * palm_far(flat).sum()
