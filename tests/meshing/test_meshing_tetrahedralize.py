"""tetrahedralize and check_surface: surface kept first, bone samples, real data, bad input."""

from __future__ import annotations

import importlib.util
import sys
import warnings

import numpy as np
import pytest
from meshing_checks import (
    ENGINES_3D,
    box,
    check_tetmesh,
    enclosed_volume,
    extrude,
    icosphere,
)

import stbs
from stbs.geometry import boundary_faces, winding_numbers
from stbs.io import read_mesh, read_skeleton
from stbs.meshing import check_surface, tetrahedra, tetrahedralize, triangulate_2d
from stbs.meshing._kernels import SurfaceIndex

HAS_TETGEN = importlib.util.find_spec("tetgen") is not None
BONE_X = stbs.Skeleton([[0.2, 0.5, 0.5], [0.5, 0.5, 0.5], [0.8, 0.55, 0.5]], [[0, 1], [1, 2]],
                       names=["upper", "lower"])


def _exact(engine: str) -> float:
    # TetGen fills the surface exactly; the builtin lattice mesher approximately.
    return 1e-9 if engine == "tetgen" else 0.02


@pytest.fixture(scope="module")
def u_prism():
    """A closed U-shaped prism (concave), and a skeleton along the U."""
    U = np.array([[0, 0], [6, 0], [6, 6], [4, 6], [4, 2], [2, 2], [2, 6], [0, 6]], float)
    sk2 = stbs.Skeleton([[1, 5], [1, 1], [5, 1], [5, 5]], [[1, 0], [1, 2], [2, 3]])
    t = triangulate_2d(U, sk2, max_area=0.5, engine="builtin")
    V, F = extrude(t.V, t.F, 2.0)
    sk = stbs.Skeleton([[1, 5, 1], [1, 1, 1], [5, 1, 1], [5, 5, 1]], [[1, 0], [1, 2], [2, 3]])
    return V, F, sk


# ----------------------------------------------------------------------------- by hand


@pytest.mark.parametrize("engine", ENGINES_3D)
def test_unit_box(engine):
    V, F = box()
    m = tetrahedralize(V, F, BONE_X, engine=engine)
    assert m.engine == engine
    check_tetmesh(m, BONE_X, V, volume=1.0, rel=1e-9)
    # Joints right after the surface, then the bone samples.
    assert np.array_equal(m.V[8:11], BONE_X.C)
    assert np.all(m.on_bone[11:11 + np.count_nonzero(m.on_bone >= 0)] >= 0)


@pytest.mark.parametrize("engine", ENGINES_3D)
def test_bone_samples_requested(engine):
    V, F = box()
    m = tetrahedralize(V, F, BONE_X, bone_samples=[3, 1], engine=engine)
    idx, t = m.bone_vertices(0, BONE_X.BE)
    assert np.array_equal(t, [0, 0.25, 0.5, 0.75, 1])
    assert np.array_equal(m.V[idx[1:-1]], [[0.275, 0.5, 0.5], [0.35, 0.5, 0.5],
                                          [0.425, 0.5, 0.5]])
    check_tetmesh(m, BONE_X, V, volume=1.0)


@pytest.mark.parametrize("engine", ENGINES_3D)
def test_concave_prism(engine, u_prism):
    V, F, sk = u_prism
    m = tetrahedralize(V, F, sk, max_volume=0.1, engine=engine)
    check_tetmesh(m, sk, V, volume=enclosed_volume(V, F), rel=_exact(engine))
    # Nothing fills the U's gap (x in (2, 4), y > 2).
    cen = m.V[m.T].mean(axis=1)
    assert not np.any((cen[:, 0] > 2.05) & (cen[:, 0] < 3.95) & (cen[:, 1] > 2.05))


@pytest.mark.parametrize("engine", ENGINES_3D)
def test_cavity_is_left_empty(engine):
    Vo, Fo = icosphere(2, 2.0)
    Vi, Fi = icosphere(1, 1.0)
    V = np.vstack([Vo, Vi])
    F = np.vstack([Fo, Fi[:, ::-1] + len(Vo)])  # the inner sphere faces inwards
    sk = stbs.Skeleton([[1.2, 0, 0], [1.5, 0.3, 0.1], [1.2, 0.6, 0.2]], [[0, 1], [1, 2]])
    m = tetrahedralize(V, F, sk, engine=engine)
    check_tetmesh(m, sk, V, volume=enclosed_volume(V, F), rel=_exact(engine))
    assert np.linalg.norm(m.V[m.T].mean(axis=1), axis=1).min() > 0.95


@pytest.mark.parametrize("engine", ENGINES_3D)
def test_inward_facing_surface_is_accepted(engine):
    V, F = box()
    m = tetrahedralize(V, F[:, ::-1], BONE_X, engine=engine)
    check_tetmesh(m, BONE_X, V, volume=1.0)


def test_tetgen_keeps_the_surface():
    pytest.importorskip("tetgen")
    V, F = icosphere(2)
    sk = stbs.Skeleton([[-0.5, 0, 0], [0.5, 0, 0]], [[0, 1]])
    m = tetrahedralize(V, F, sk, max_volume=0.01, engine="tetgen")
    assert m.V.shape[0] > V.shape[0] + 10  # refined inside
    same = np.sort(np.sort(boundary_faces(m.T), axis=1), axis=0)
    assert np.array_equal(same, np.sort(np.sort(F, axis=1), axis=0))
    m2 = tetrahedralize(V, F, sk, max_volume=0.01, keep_surface=False, engine="tetgen")
    assert np.array_equal(m2.V[:V.shape[0]], V)
    check_tetmesh(m2, sk, V, volume=enclosed_volume(V, F))


def test_builtin_lattice_is_refined_by_max_volume():
    V, F = icosphere(2)
    sk = stbs.Skeleton([[-0.5, 0, 0], [0.5, 0, 0]], [[0, 1]])
    coarse = tetrahedralize(V, F, sk, engine="builtin")
    fine = tetrahedralize(V, F, sk, max_volume=0.002, engine="builtin")
    assert fine.V.shape[0] > 2 * coarse.V.shape[0]
    check_tetmesh(fine, sk, V, volume=enclosed_volume(V, F), rel=0.02)


def test_auto_without_tetgen_uses_builtin(monkeypatch):
    monkeypatch.setitem(sys.modules, "tetgen", None)
    V, F = box()
    assert tetrahedralize(V, F, BONE_X).engine == "builtin"
    with pytest.raises(ImportError, match=r"stbs-skinning\[tetgen\].*AGPL"):
        tetrahedralize(V, F, BONE_X, engine="tetgen")


def test_tetgen_failure_is_reported_and_contained(tmp_path, monkeypatch):
    pytest.importorskip("tetgen")
    monkeypatch.chdir(tmp_path)
    V1, F1 = box()
    V2, F2 = box((0.5, 0.5, 0.5), (1.5, 1.5, 1.5))
    V, F = np.vstack([V1, V2]), np.vstack([F1, F2 + 8])
    sk = stbs.Skeleton([[0.1, 0.1, 0.1], [0.4, 0.2, 0.2]], [[0, 1]])
    # TetGen either reports the self-intersections or its process dies (glibc aborts
    # it on the heap it corrupted); both must come back as one RuntimeError
    with pytest.raises(RuntimeError, match="TetGen failed with switches '[^']+': "
                                           "(.*self-intersections|.*pointer|killed by signal)"):
        tetrahedralize(V, F, sk, engine="tetgen", self_intersections=False)
    with pytest.warns(UserWarning, match="TetGen failed.*using the builtin"):
        m = tetrahedralize(V, F, sk, self_intersections=False)
    assert m.engine == "builtin"
    assert list(tmp_path.iterdir()) == []  # no files left behind by TetGen


def test_auto_falls_back_when_tetgen_fails(monkeypatch):
    pytest.importorskip("tetgen")
    def broken(*args, **kwargs):
        raise RuntimeError("TetGen failed with switches 'pQ': test")

    monkeypatch.setattr(tetrahedra, "_tetgen", broken)
    V, F = box()
    with pytest.warns(UserWarning, match="TetGen failed.*builtin"):
        m = tetrahedralize(V, F, BONE_X)
    assert m.engine == "builtin"
    with pytest.raises(RuntimeError, match="TetGen failed"):
        tetrahedralize(V, F, BONE_X, engine="tetgen")


# ----------------------------------------------------------------------------- real data


@pytest.mark.parametrize("engine", ENGINES_3D)
def test_decimated_knight(shared_data, engine):
    mesh = read_mesh(shared_data / "libigl-tutorial-data" / "decimated-knight.off")
    sk = read_skeleton(shared_data / "computer-graphics-kinematics" / "knight.tgf")
    m = tetrahedralize(mesh.V, mesh.F, sk, engine=engine)
    check_tetmesh(m, sk, mesh.V, volume=enclosed_volume(mesh.V, mesh.F), rel=_exact(engine))


def test_arm_with_tetgen(shared_data):
    pytest.importorskip("tetgen")
    mesh = read_mesh(shared_data / "libigl-tutorial-data" / "arm.obj")
    sk = read_skeleton(shared_data / "libigl-tutorial-data" / "arm.tgf")
    m = tetrahedralize(mesh.V, mesh.F, sk, engine="tetgen", self_intersections=False)
    check_tetmesh(m, sk, mesh.V, volume=enclosed_volume(mesh.V, mesh.F))


def test_arm_with_builtin(shared_data):
    mesh = read_mesh(shared_data / "libigl-tutorial-data" / "arm.obj")
    sk = read_skeleton(shared_data / "libigl-tutorial-data" / "arm.tgf")
    m = tetrahedralize(mesh.V, mesh.F, sk, max_volume=1e-5, engine="builtin")
    check_tetmesh(m, sk, mesh.V, volume=enclosed_volume(mesh.V, mesh.F), rel=0.01)


def test_elephant_skeleton_tips_outside(shared_data):
    # elephant.tgf's trunk tip sits 0.05 outside the surface.
    mesh = read_mesh(shared_data / "libigl-tutorial-data" / "elephant.obj")
    sk = read_skeleton(shared_data / "libigl-tutorial-data" / "elephant.tgf")
    with pytest.raises(ValueError, match=r"bone 5 .*its joint 6 .* is outside the surface by "
                       r"0\.045\d "):
        tetrahedralize(mesh.V, mesh.F, sk, self_intersections=False)
    # Meshed with the tips clipped: the 2 joints outside left out, the rest (joint 24,
    # 0.2 inside, too) exactly in place.
    with pytest.warns(UserWarning, match=r"2 skeleton point\(s\) .* left out \(2 joint"):
        m = tetrahedralize(mesh.V, mesh.F, sk, self_intersections=False, clip_skeleton=True)
    assert np.array_equal(np.flatnonzero(m.joint_vertex < 0), [6, 19])
    kept = m.joint_vertex >= 0
    assert np.array_equal(m.V[m.joint_vertex[kept]], sk.C[kept])


def test_robot_arm_has_degenerate_triangles(shared_data):
    mesh = read_mesh(shared_data / "computer-graphics-kinematics" / "robot-arm.ply")
    with pytest.raises(ValueError, match=r"triangle \d+ .* degenerate \(zero area\); 92 such"):
        check_surface(mesh.V, mesh.F)


def test_winding_numbers_and_sides_on_real_data(shared_data):
    mesh = read_mesh(shared_data / "libigl-tutorial-data" / "decimated-knight.off")
    V, F = mesh.V, mesh.F
    rng = np.random.default_rng(0)
    lo, hi = V.min(axis=0), V.max(axis=0)
    Q = lo + rng.random((300, 3)) * (hi - lo)
    w = winding_numbers(Q, V, F)
    assert np.all((np.abs(w) < 1e-6) | (np.abs(w - 1) < 1e-6))
    d, side = SurfaceIndex(V, F).closest_side(Q, np.inf)
    assert np.array_equal(side < 0, w > 0.5)
    # Distances against brute force over the vertices (an upper bound) and triangles.
    near_vertex = np.linalg.norm(Q[:, None] - V[None], axis=2).min(axis=1)
    assert np.all(d <= near_vertex + 1e-12)


# ----------------------------------------------------------------------------- bad input


def test_open_surface():
    V, F = icosphere(1)
    with pytest.raises(ValueError, match=r"surface is open: 3 edges .* fill its holes"):
        tetrahedralize(V, np.delete(F, 5, axis=0), stbs.Skeleton([[0, 0, 0], [0.1, 0, 0]],
                                                                 [[0, 1]]))


def test_inconsistent_orientation():
    V, F = box()
    F = F.copy()
    F[3] = F[3, ::-1]
    with pytest.raises(ValueError, match="orientation is inconsistent"):
        check_surface(V, F)


def test_non_manifold_edge():
    V, F = box()
    # A fin: an extra triangle on an existing edge.
    V2 = np.vstack([V, [[0.5, -1.0, 0.5]]])
    F2 = np.vstack([F, [[0, 1, 8]], [[1, 0, 8]]])
    with pytest.raises(ValueError, match="shared by (3|4) triangles"):
        check_surface(V2, F2)


def test_non_manifold_vertex():
    # Two boxes touching at one corner.
    V1, F1 = box()
    V2, F2 = box((1, 1, 1), (2, 2, 2))
    V = np.vstack([V1, V2[1:]])
    remap = np.r_[7, np.arange(8, 15)]  # V2's vertex 0 is V1's vertex 7
    F = np.vstack([F1, remap[F2]])
    with pytest.raises(ValueError, match="vertex 7 .* joins 2 separate fans"):
        check_surface(V, F)


def test_self_intersection():
    V1, F1 = box()
    V2, F2 = box((0.5, 0.5, 0.5), (1.5, 1.5, 1.5))
    V = np.vstack([V1, V2])
    F = np.vstack([F1, F2 + 8])
    if HAS_TETGEN:      # (without it, engine="tetgen" is an ImportError: tested elsewhere)
        with pytest.raises(ValueError, match="intersect.*MeshFix.*or pass engine='auto'"):
            tetrahedralize(V, F, BONE_X, engine="tetgen")
    with pytest.raises(ValueError, match="intersect.*MeshFix"):
        check_surface(V, F)
    # Turning the test off hands the surface to the mesher as it is.
    check_surface(V, F, self_intersections=False)


def test_builtin_keeps_detail_far_below_the_shape_size():
    # A pebble 1e-4 the size of the shape: its tetrahedra are 1e-12 of the shape's
    # size cubed, yet not flat (a flatness test by the shape's size lost them).
    V1, F1 = icosphere(2, radius=100.0)
    V2, F2 = icosphere(2, radius=0.01, center=(50.0, 0.0, 0.0))
    V, F = np.vstack([V1, V2]), np.vstack([F1, F2 + len(V1)])
    sk = stbs.Skeleton([[-50.0, 0, 0], [0.0, 0, 0]], [[0, 1]])
    m = tetrahedralize(V, F, sk, engine="builtin", self_intersections=False)
    check_tetmesh(m, sk, V, volume=enclosed_volume(V, F), rel=0.02)
    pebble = np.isin(m.T, np.arange(len(V1), len(V))).any(axis=1)
    assert pebble.any()


def test_self_intersecting_surface_meshed_by_winding_number():
    # Two overlapping spheres, one surface: TetGen cannot mesh it; the builtin mesher
    # fills the union, the bones crossing the inner sheets.
    V1, F1 = icosphere(3)
    V = np.vstack([V1, V1 + [0.93, 0.07, 0.05]])
    F = np.vstack([F1, F1 + len(V1)])
    sk = stbs.Skeleton([[-0.5, 0, 0], [0.5, 0, 0], [1.5, 0, 0]], [[0, 1], [1, 2]])
    rng = np.random.default_rng(0)
    lo, hi = V.min(axis=0), V.max(axis=0)
    Q = lo + rng.random((40_000, 3)) * (hi - lo)
    union = np.mean(np.abs(winding_numbers(Q, V, F)) > 0.5) * np.prod(hi - lo)  # +-0.5 %
    for engine in ("auto", "builtin"):
        with pytest.warns(UserWarning, match="intersects itself.*builtin mesher"):
            m = tetrahedralize(V, F, sk, engine=engine)
        assert m.engine == "builtin"
        check_tetmesh(m, sk, V, volume=union, rel=0.01)
    if HAS_TETGEN:
        with pytest.raises(ValueError, match="intersects itself"):
            tetrahedralize(V, F, sk, engine="tetgen")


def test_degenerate_and_unused_and_duplicate():
    V, F = box()
    F2 = F.copy()
    F2[0] = [0, 0, 1]
    with pytest.raises(ValueError, match="triangle 0 .* degenerate"):
        check_surface(V, F2)
    with pytest.raises(ValueError, match="vertices are in no triangle.*vertex 8"):
        check_surface(np.vstack([V, [[5, 5, 5]]]), F)
    # Vertex 8 is a copy of vertex 0, used by one of vertex 0's triangles: the surface
    # is cut there (the usual result of a UV seam in an OBJ file).
    V3 = np.vstack([V, V[:1]])
    F3 = F.copy()
    F3[0, F3[0] == 0] = 8
    with pytest.raises(ValueError, match="vertices 0 and 8 coincide"):
        check_surface(V3, F3)


def test_bone_crossing_the_surface_names_the_bone(u_prism):
    V, F, _ = u_prism
    # Joints in the two arms of the U, the bone across the gap; with one sample the
    # sample sits in the gap, so both checks are exercised.
    sk = stbs.Skeleton([[1, 5, 1], [5, 5, 1]], [[0, 1]], names=["bridge"])
    with pytest.raises(ValueError, match=r"bone 0 \('bridge'.*leaves the shape"):
        tetrahedralize(V, F, sk)
    sk2 = stbs.Skeleton([[1, 5, 1], [5, 5, 1]], [[0, 1]], names=["bridge"])
    with pytest.raises(ValueError, match=r"bone 0 \('bridge'.*crosses the surface"):
        tetrahedralize(V, F, sk2, bone_samples=[0])


def test_skeleton_outside():
    V, F = box()
    sk = stbs.Skeleton([[0.5, 0.5, 0.5], [1.5, 0.5, 0.5]], [[0, 1]], names=["out"])
    # The joint is 0.5 from the face x = 1; the box's diagonal is sqrt(3).
    with pytest.raises(ValueError, match=r"bone 0 \('out'.*joint 1 .* outside the surface by "
                       r"0\.5 \(29 % of the shape's size; \d+ skeleton point.*clip_skeleton"):
        tetrahedralize(V, F, sk)


@pytest.mark.parametrize("engine", ENGINES_3D)
def test_clip_skeleton_meshes_the_inside_part(engine):
    V, F = box()
    sk = stbs.Skeleton([[0.3, 0.5, 0.5], [0.5, 0.5, 0.5], [1.5, 0.5, 0.5]], [[0, 1], [1, 2]],
                       names=["in", "tip"])
    with pytest.warns(UserWarning, match=r"left out \(1 joint\(s\)\); the farthest is 0\.5 "
                      r"outside"):
        m = tetrahedralize(V, F, sk, bone_samples=[1, 9], engine=engine, clip_skeleton=True)
    n = V.shape[0]
    assert np.array_equal(m.joint_vertex, [n, n + 1, -1])
    assert np.array_equal(m.V[m.joint_vertex[:2]], sk.C[:2])
    assert np.array_equal(m.V[:n], V) and tet_volumes_ok(m)
    # Bone 1's samples at t = 0.1 .. 0.9 lie at x = 0.6 .. 1.4. Kept: those farther
    # inside than a tenth of the sample spacing (the mean surface edge: 0.12 here).
    idx, t = m.bone_vertices(1, sk.BE)
    assert idx[0] == n + 1 and t[0] == 0.0
    np.testing.assert_allclose(t[1:], [0.1, 0.2, 0.3])
    np.testing.assert_allclose(m.V[idx[1:], 0], [0.6, 0.7, 0.8])
    on = m.on_joint
    assert np.array_equal(np.flatnonzero(on >= 0), [n, n + 1]) and on[n + 1] == 1
    assert np.all(np.abs(winding_numbers(m.V[n:n + 6], V, F)) > 0.5)
    # The weights find every bone on the clipped mesh.
    W = stbs.bone_weights(m.V, sk, T=m.T, tol=1e-8)
    assert W[idx[-1], 1] == pytest.approx(1.0) and W[n, 0] == pytest.approx(1.0)


def tet_volumes_ok(m) -> bool:
    from stbs.geometry import tet_volumes

    return bool(tet_volumes(m.V, m.T).min() > 0)


def test_clip_skeleton_crossing_bone_and_bone_wholly_outside(u_prism):
    V, F, _ = u_prism
    # A bone across the U's gap: its samples in the gap are left out, both joints kept.
    sk = stbs.Skeleton([[1, 5, 1], [5, 5, 1]], [[0, 1]], names=["bridge"])
    with pytest.warns(UserWarning, match=r"left out \(0 joint\(s\)\)"):
        m = tetrahedralize(V, F, sk, bone_samples=[7], clip_skeleton=True)
    assert (m.joint_vertex >= 0).all()
    _, t = m.bone_vertices(0, sk.BE)
    x = 1 + 4 * t
    assert np.all((x <= 2) | (x >= 4)) and t.size == 2 + 2  # samples at x = 1.5, 4.5
    away = stbs.Skeleton([[1, 3, 1], [1, 5, 1], [9, 3, 1], [9, 5, 1]], [[0, 1], [2, 3]],
                         names=["arm", "away"])
    with pytest.raises(ValueError, match=r"bone 1 \('away'.*lies outside the surface"):
        tetrahedralize(V, F, away, clip_skeleton=True)


def test_dimension_mismatch():
    V, F = box()
    sk2 = stbs.Skeleton([[0.2, 0.5], [0.8, 0.5]], [[0, 1]])
    with pytest.raises(ValueError, match="sk must be a 3-D skeleton.*got a 2-D"):
        tetrahedralize(V, F, sk2)
    with pytest.raises(ValueError, match=r"V must have shape \(n, 3\).*triangulate_2d"):
        tetrahedralize(V[:, :2], F, BONE_X)


@pytest.mark.parametrize("kwargs, match", [
    (dict(max_volume=-1), "max_volume must be a positive"),
    (dict(max_radius_edge=0.5), "max_radius_edge must be >= 1.0"),
    (dict(engine="cgal"), "engine must be one of 'auto', 'tetgen', 'builtin'"),
    (dict(bone_samples=[1]), r"bone_samples must be None, an int or 2 ints"),
])
def test_bad_options(kwargs, match):
    V, F = box()
    with pytest.raises(ValueError, match=match):
        tetrahedralize(V, F, BONE_X, **kwargs)


def test_too_few_triangles_and_bad_indices():
    V, F = box()
    with pytest.raises(ValueError, match="at least 4 triangles"):
        check_surface(V, F[:3])
    with pytest.raises(ValueError, match="vertex indices in 0..7, got 9"):
        check_surface(V, np.where(F == 7, 9, F))


def test_repr_and_no_warnings():
    V, F = box()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        m = tetrahedralize(V, F, BONE_X, engine="builtin")
    assert "TetMesh(" in repr(m) and m.dim == 3


@pytest.mark.parametrize("high, low", [(50, 0), (2**40, 0), (50, -5)])
def test_unique_rows_is_numpys_row_unique(high, low):
    # Packed int64 keys (small values) and NumPy's row sort (large or negative ones)
    # give NumPy's answer: rows in lexicographic order, first indices, inverse, counts.
    from stbs.geometry import unique_rows

    A = np.random.default_rng(1).integers(low, high, size=(5000, 3))
    A[100:200] = A[:100]                       # repeats
    U, idx, inv, cnt = unique_rows(A)
    U0, idx0, inv0, cnt0 = np.unique(A, axis=0, return_index=True, return_inverse=True,
                                     return_counts=True)
    for got, want in ((U, U0), (idx, idx0), (inv, inv0.ravel()), (cnt, cnt0)):
        assert np.array_equal(got, want)
    assert np.array_equal(U[inv], A)


def test_candidate_pairs_miss_no_overlapping_bounding_spheres():
    # Size classes must not lose a pair: against all pairs, on spheres of sizes
    # spread over three orders of magnitude.
    from stbs.meshing.surface import _candidate_pairs

    rng = np.random.default_rng(2)
    C = rng.random((600, 3))
    R = 0.002 * 10 ** rng.uniform(0, 3, 600)
    i, j = np.triu_indices(600, 1)
    overlap = np.linalg.norm(C[i] - C[j], axis=1) <= R[i] + R[j]
    want = set(map(tuple, np.stack([i[overlap], j[overlap]], axis=1).tolist()))
    pairs = _candidate_pairs(C, R)
    assert np.all(pairs[:, 0] < pairs[:, 1])
    got = set(map(tuple, pairs.tolist()))
    assert len(got) == len(pairs)                      # no pair twice
    assert want <= got
    assert len(got) < 0.5 * i.size                     # and it does prune


def test_cylinder_quads_are_not_self_intersections(shared_data):
    # cylinder.obj: flat quads, split in two; neighbouring triangles along the axis
    # are coplanar and meet at a vertex. Rounding made them "cross" (347 pairs).
    mesh = read_mesh(shared_data / "libigl-tutorial-data" / "cylinder.obj")
    check_surface(mesh.V, mesh.F)
    sk = stbs.Skeleton([[0, -1.2, 0], [0, 0, 0], [0, 1.2, 0]], [[0, 1], [1, 2]])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        m = tetrahedralize(mesh.V, mesh.F, sk)
    check_tetmesh(m, sk, mesh.V, volume=enclosed_volume(mesh.V, mesh.F),
                  rel=_exact(m.engine))
