"""triangulate_2d: bones as constrained segments, quality, real outlines, bad input."""

from __future__ import annotations

import math
import sys
import warnings
from types import SimpleNamespace

import numpy as np
import pytest
from meshing_checks import (
    ENGINES_2D,
    check_bones_not_crossed,
    check_covers_outline,
    check_skeleton_record,
    check_trimesh,
    edges_of,
)

import stbs
from stbs.io import Mesh, read_mesh, read_skeleton
from stbs.meshing import boundary_loops, triangulate_2d
from stbs.meshing._geometry import triangle_angles

SQUARE = np.array([[0, 0], [4, 0], [4, 2], [0, 2]], float)
U_SHAPE = np.array([[0, 0], [6, 0], [6, 6], [4, 6], [4, 2], [2, 2], [2, 6], [0, 6]], float)
U_SKELETON = stbs.Skeleton([[1, 5], [1, 1], [3, 1], [5, 1], [5, 5]],
                           [[2, 1], [1, 0], [2, 3], [3, 4]])
OUTER = np.array([[0, 0], [10, 0], [10, 10], [0, 10]], float)
HOLE = np.array([[4, 4], [6, 4], [6, 6], [4, 6]], float)
HOLE_SKELETON = stbs.Skeleton([[1, 1], [1, 9], [9, 9], [9, 1]], [[0, 1], [1, 2], [2, 3]])


@pytest.fixture(scope="module")
def data(shared_data):
    return shared_data


# ----------------------------------------------------------------------------- by hand


@pytest.mark.parametrize("engine", ENGINES_2D)
def test_square_with_two_bones(engine):
    sk = stbs.Skeleton([[0.5, 1], [2, 1], [3.5, 1.5]], [[0, 1], [1, 2]])
    m = triangulate_2d(SQUARE, sk, max_area=0.05, engine=engine)
    assert m.engine == engine
    assert m.n_input == 4 and np.array_equal(m.V[:4], SQUARE)
    # Joints follow the input points, in order.
    assert np.array_equal(m.joint_vertex, [4, 5, 6])
    check_trimesh(m, sk, min_angle_deg=30, max_area=0.05)
    check_covers_outline(m, [SQUARE])


@pytest.mark.parametrize("engine", ENGINES_2D)
def test_bone_samples_at_requested_parameters(engine):
    sk = stbs.Skeleton([[1, 1], [3, 1]], [[0, 1]])
    m = triangulate_2d(SQUARE, sk, bone_samples=3, engine=engine)
    idx, t = m.bone_vertices(0, sk.BE)
    # The three requested samples are there, at t = 1/4, 1/2, 3/4 exactly.
    assert np.isin([0.25, 0.5, 0.75], t).all()
    k = idx[np.isin(t, [0.25, 0.5, 0.75])]
    assert np.array_equal(m.V[k], [[1.5, 1], [2, 1], [2.5, 1]])
    check_trimesh(m, sk, min_angle_deg=30)


@pytest.mark.parametrize("engine", ENGINES_2D)
def test_u_shape(engine):
    m = triangulate_2d(U_SHAPE, U_SKELETON, max_area=0.05, engine=engine)
    check_trimesh(m, U_SKELETON, min_angle_deg=30, max_area=0.05)
    check_covers_outline(m, [U_SHAPE])


@pytest.mark.parametrize("engine", ENGINES_2D)
def test_square_with_a_hole(engine):
    m = triangulate_2d([OUTER, HOLE[::-1]], HOLE_SKELETON, max_area=0.5, engine=engine)
    check_trimesh(m, HOLE_SKELETON, min_angle_deg=30, max_area=0.5)
    check_covers_outline(m, [OUTER, HOLE])
    # Nothing inside the hole.
    cen = m.V[m.F].mean(axis=1)
    assert not np.any(np.all((cen > 4) & (cen < 6), axis=1))


@pytest.mark.parametrize("engine", ENGINES_2D)
def test_mesh_outline_keeps_every_vertex(engine):
    # A 2x2 grid of squares, with the centre vertex on the bone.
    x = np.array([[i, j] for j in range(3) for i in range(3)], float)
    F = np.array([[0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4], [3, 4, 7], [3, 7, 6],
                  [4, 5, 8], [4, 8, 7]])
    sk = stbs.Skeleton([[0.25, 1], [1.75, 1]], [[0, 1]])
    for outline in ((x, F), Mesh(x, F)):
        m = triangulate_2d(outline, sk, engine=engine)
        assert m.n_input == 9 and np.array_equal(m.V[:9], x)
        assert m.on_bone[4] == 0 and m.t_bone[4] == pytest.approx(0.5)
        check_trimesh(m, sk, min_angle_deg=30)


@pytest.mark.parametrize("engine", ENGINES_2D)
@pytest.mark.parametrize("seed", [0, 1])
def test_quality_and_area_bounds(engine, seed):
    rng = np.random.default_rng(seed)
    k = 9
    ang = np.sort(rng.uniform(0, 2 * np.pi, k))
    ang = np.linspace(0, 2 * np.pi, k, endpoint=False) + rng.uniform(-0.2, 0.2, k)
    P = np.c_[np.cos(ang), np.sin(ang)] * rng.uniform(2.0, 3.0, (k, 1))
    sk = stbs.Skeleton([[-0.8, 0.1], [0.0, 0.0], [0.9, 0.3], [0.1, -1.0]],
                       [[1, 0], [1, 2], [1, 3]])
    for min_deg, max_area in ((30, None), (25, 0.02), (20, 0.2)):
        m = triangulate_2d(P, sk, min_angle=math.radians(min_deg), max_area=max_area,
                           engine=engine)
        check_trimesh(m, sk, min_angle_deg=min_deg, max_area=max_area)
        check_covers_outline(m, [P])


@pytest.mark.parametrize("engine", ENGINES_2D)
def test_small_input_angles_are_left_alone(engine):
    # Two bones meeting at 15 degrees: triangles between them cannot reach 30 degrees,
    # but refinement stops, and the few triangles below the bound sit in the wedge
    # with all their corners on the skeleton.
    box = np.array([[-1, -1], [10, -1], [10, 6], [-1, 6]], float)
    a = math.radians(15)
    sk = stbs.Skeleton([[0, 0], [9, 0], [9 * math.cos(a), 9 * math.sin(a)]], [[0, 1], [0, 2]])
    m = triangulate_2d(box, sk, max_area=0.05, engine=engine)
    check_trimesh(m, sk, max_area=0.05)
    bad = np.degrees(triangle_angles(m.V, m.F).min(axis=1)) < 30 - 1e-6
    assert 0 < bad.sum() <= 4
    on_skeleton = (m.on_bone >= 0) | (m.on_joint >= 0)
    assert on_skeleton[m.F[bad]].all()


def test_engines_agree_on_the_domain():
    pytest.importorskip("triangle")
    a = triangulate_2d(U_SHAPE, U_SKELETON, max_area=0.1, engine="triangle")
    b = triangulate_2d(U_SHAPE, U_SKELETON, max_area=0.1, engine="builtin")
    for m in (a, b):
        check_covers_outline(m, [U_SHAPE])
    # Similar sizes (the builtin inserts in batches, so somewhat more points).
    assert 0.8 < b.V.shape[0] / a.V.shape[0] < 1.6


def test_auto_without_triangle_uses_builtin(monkeypatch):
    monkeypatch.setitem(sys.modules, "triangle", None)
    sk = stbs.Skeleton([[1, 1], [3, 1]], [[0, 1]])
    m = triangulate_2d(SQUARE, sk, engine="auto")
    assert m.engine == "builtin"
    with pytest.raises(ImportError, match=r"stbs-skinning\[triangle\]"):
        triangulate_2d(SQUARE, sk, engine="triangle")


def test_builtin_stops_at_max_points_with_a_warning():
    sk = stbs.Skeleton([[1, 1], [3, 1]], [[0, 1]])
    with pytest.warns(UserWarning, match="stopped at"):
        m = triangulate_2d(SQUARE, sk, max_area=1e-4, engine="builtin", max_points=200)
    check_trimesh(m, sk)


# ----------------------------------------------------------------------------- real data


@pytest.mark.parametrize("engine", ENGINES_2D)
def test_woody_mesh_with_its_skeleton(data, engine):
    mesh = read_mesh(data / "fast_support_reduction" / "woody.obj")
    sk = read_skeleton(data / "fast_support_reduction" / "woody.tgf")
    m = triangulate_2d(mesh, sk, engine=engine)
    n = mesh.V.shape[0]
    assert m.n_input == n and np.array_equal(m.V[:n], mesh.V)
    # woody.obj was meshed around this skeleton and saved with 4 decimals: its
    # vertices on the bones are recognised (within 1e-6 of the size) and kept.
    on_input = np.flatnonzero(m.on_bone[:n] >= 0)
    assert on_input.size > 50
    check_skeleton_record(m, sk, on_tol=1e-6)
    assert np.degrees(triangle_angles(m.V, m.F).min()) >= 30 - 1e-6
    check_covers_outline(m, [mesh.V[L] for L in boundary_loops(mesh.F)])


@pytest.mark.parametrize("engine", ENGINES_2D)
def test_woody_outline_remeshed(data, engine):
    mesh = read_mesh(data / "common-3d-test-models" / "woody.obj")
    sk = read_skeleton(data / "fast_support_reduction" / "woody.tgf")
    polys = [mesh.V[L] for L in boundary_loops(mesh.F)]
    m = triangulate_2d(polys, sk, max_area=100.0, engine=engine)
    check_trimesh(m, sk, min_angle_deg=30, max_area=100.0)
    check_covers_outline(m, polys)


@pytest.mark.parametrize("engine", ENGINES_2D)
def test_cantilever(data, engine):
    mesh = read_mesh(data / "fast_support_reduction" / "cantilever_S.obj")
    sk = read_skeleton(data / "fast_support_reduction" / "cantilever_S.tgf")
    m = triangulate_2d((mesh.V, mesh.F), sk, engine=engine)
    assert np.array_equal(m.V[:mesh.V.shape[0]], mesh.V)
    check_skeleton_record(m, sk, on_tol=1e-6)
    assert np.degrees(triangle_angles(m.V, m.F).min()) >= 30 - 1e-6


# ----------------------------------------------------------------------------- bad input


def test_joint_outside_the_outline_names_the_bone():
    sk = stbs.Skeleton([[1, 1], [5, 1]], [[0, 1]], names=["arm"])
    with pytest.raises(ValueError, match=r"bone 0 \('arm'.*joint 1.*outside the outline"):
        triangulate_2d(SQUARE, sk)


def test_bone_crossing_the_outline_names_the_bone():
    # Both joints inside the U, the bone across its gap.
    sk = stbs.Skeleton([[1, 5], [5, 5]], [[0, 1]], names=["bridge"])
    with pytest.raises(ValueError, match=r"bone 0 \('bridge'.*crosses the outline.*"
                       r"clip_skeleton=True"):
        triangulate_2d(U_SHAPE, sk)


@pytest.mark.parametrize("engine", ENGINES_2D)
def test_clip_skeleton_meshes_the_parts_inside(engine):
    # "tip" leaves the U through its top (y = 6) at t = 0.5; "bridge" crosses the gap
    # between the arms (2 < x < 4) and is inside for t < 0.25 and t > 0.75.
    sk = stbs.Skeleton([[1, 1], [1, 5], [1, 7], [5, 1], [5, 5]],
                       [[0, 1], [1, 2], [0, 3], [3, 4], [1, 4]],
                       names=["left", "tip", "base", "right", "bridge"])
    with pytest.raises(ValueError, match=r"joint 2 .* outside the outline.*clip_skeleton=True"):
        triangulate_2d(U_SHAPE, sk, engine=engine)
    with pytest.warns(UserWarning, match=r"2 bone\(s\) cross the outline .*\(1 joint\(s\) "
                      r"outside left out, the farthest 1 outside"):
        m = triangulate_2d(U_SHAPE, sk, max_area=0.05, engine=engine, clip_skeleton=True)
    check_trimesh(m, sk, record=False)   # the record of a clipped skeleton: below
    check_covers_outline(m, [U_SHAPE])
    assert m.joint_vertex[2] == -1
    kept = np.array([0, 1, 3, 4])
    assert np.array_equal(m.V[m.joint_vertex[kept]], sk.C[kept])
    edges = {tuple(e) for e in edges_of(m.F).tolist()}
    gaps = {"tip": (0.5, 1.0), "bridge": (0.25, 0.75)}   # the parts outside
    pieces = []
    for i, name in enumerate(sk.names):
        idx, t = m.bone_vertices(i, sk.BE)
        assert np.all(np.diff(t) > 0)
        expect = sk.A[i] + t[:, None] * (sk.B[i] - sk.A[i])
        assert np.abs(m.V[idx] - expect).max() <= 1e-12 * 7
        lo, hi = gaps.get(name, (2.0, 2.0))
        assert not np.any((t > lo) & (t < hi)), name      # nothing meshed outside
        # The part inside reaches to within a tenth of the bone of the crossing.
        if name in gaps:
            assert np.any(t > lo - 0.1) and (name == "tip" or np.any(t < hi + 0.1))
        for a, c, ta, tc in zip(idx[:-1], idx[1:], t[:-1], t[1:], strict=True):
            if not (ta <= lo and tc >= hi):               # pieces are chains of edges
                assert (min(a, c), max(a, c)) in edges, name
                pieces.append((m.V[a], m.V[c]))
    A, B = (np.array(x) for x in zip(*pieces, strict=True))
    check_bones_not_crossed(m, SimpleNamespace(A=A, B=B, n_bones=len(pieces)))
    # Bone and endpoint weights on the clipped mesh: e = t along every bone.
    W = stbs.bone_weights(m.V, sk, F=m.F, tol=1e-8)
    with warnings.catch_warnings():
        # The joint left out is outside the mesh: no nearest-vertex stand-in (and no
        # warning about one), e = t along the part inside is all.
        warnings.simplefilter("error")
        E = stbs.endpoint_weights(m.V, sk, method="bbw", W=W, F=m.F, tol=1e-8)
    for i in range(sk.n_bones):
        idx, t = m.bone_vertices(i, sk.BE)
        np.testing.assert_allclose(E[idx, i], t, atol=1e-9)
    # Where "tip" leaves the shape (t = 0.5), e goes on smoothly from its cut end
    # (t = 0.46 with this max_area), not to the 1 of the joint beyond.
    top = np.argmin(np.linalg.norm(m.V - [1.0, 6.0], axis=1))
    assert 0.45 < E[top, 1] < 0.6


def test_clip_skeleton_bone_wholly_outside():
    sk = stbs.Skeleton([[1, 1], [3, 1], [8, 1], [9, 1]], [[0, 1], [2, 3]], names=["in", "out"])
    with pytest.raises(ValueError, match=r"bone 1 \('out'.*lies outside the outline"):
        triangulate_2d(SQUARE, sk, clip_skeleton=True)
    # A skeleton wholly inside is meshed as without clipping, and no warning.
    inner = stbs.Skeleton([[1, 1], [3, 1]], [[0, 1]])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        a = triangulate_2d(SQUARE, inner, clip_skeleton=True)
    b = triangulate_2d(SQUARE, inner)
    assert np.array_equal(a.V, b.V) and np.array_equal(a.F, b.F)


def test_bone_crossing_a_hole():
    sk = stbs.Skeleton([[1, 5], [9, 5]], [[0, 1]])
    with pytest.raises(ValueError, match="crosses the outline"):
        triangulate_2d([OUTER, HOLE], sk)


def test_joint_in_a_hole():
    sk = stbs.Skeleton([[1, 1], [5, 5]], [[0, 1]])
    with pytest.raises(ValueError, match="outside the outline"):
        triangulate_2d([OUTER, HOLE], sk)


def test_crossing_bones():
    sk = stbs.Skeleton([[0.5, 0.5], [3.5, 1.5], [0.5, 1.5], [3.5, 0.5]], [[0, 1], [2, 3]])
    with pytest.raises(ValueError, match="cross or overlap"):
        triangulate_2d(SQUARE, sk)


def test_skeleton_3d_with_2d_outline():
    sk = stbs.Skeleton([[1, 1, 0], [3, 1, 0]], [[0, 1]])
    with pytest.raises(ValueError, match="sk must be a 2-D skeleton.*got a 3-D"):
        triangulate_2d(SQUARE, sk)


def test_3d_outline():
    sk = stbs.Skeleton([[1, 1], [3, 1]], [[0, 1]])
    with pytest.raises(ValueError, match=r"polygon 0 must have shape \(k, 2\).*got \(4, 3\)"):
        triangulate_2d(np.c_[SQUARE, np.zeros(4)], sk)
    V = np.c_[SQUARE, np.zeros(4)]
    with pytest.raises(ValueError, match=r"outline V must have shape \(n, 2\).*dim=2"):
        triangulate_2d((V, np.array([[0, 1, 2], [0, 2, 3]])), sk)


@pytest.mark.parametrize("poly, match", [
    ([[0, 0], [1, 0]], "at least 3 distinct vertices"),
    ([[0, 0], [1, 0], [2, 0]], "zero area"),
    ([[0, 0], [4, 0], [1, 2], [4, 2]], "intersect"),  # a bow tie
    ([[0, 0], [4, 0], [4, 0], [4, 2]], "coincide"),
    ([[0, 0], [4, 0], [4, 2], [np.nan, 2]], "must be finite"),
])
def test_bad_polygons(poly, match):
    sk = stbs.Skeleton([[1, 0.5], [2, 0.5]], [[0, 1]])
    with pytest.raises(ValueError, match=match):
        triangulate_2d(np.array(poly, float), sk)


def test_overlapping_polygons():
    sk = stbs.Skeleton([[1, 1], [2, 1]], [[0, 1]])
    with pytest.raises(ValueError, match="intersect"):
        triangulate_2d([SQUARE, SQUARE + [1, 1]], sk)


def test_bad_mesh_outlines():
    sk = stbs.Skeleton([[0.2, 0.2], [0.5, 0.3]], [[0, 1]])
    V = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [2, 2]], float)
    F = np.array([[0, 1, 2], [0, 2, 3]])
    with pytest.raises(ValueError, match="vertices are in no triangle.*vertex 4"):
        triangulate_2d((V, F), sk)
    with pytest.raises(ValueError, match="triangle 1 .* degenerate"):
        triangulate_2d((V[:4], np.array([[0, 1, 2], [0, 2, 2]])), sk)
    # Two triangles touching at one vertex: a pinched outline.
    Vp = np.array([[0, 0], [1, 0], [0.5, 0.5], [1, 1], [0, 1]], float)
    with pytest.raises(ValueError, match="pinched"):
        triangulate_2d((Vp, np.array([[0, 1, 2], [2, 3, 4]])), sk)
    with pytest.raises(ValueError, match="outline F must hold vertex indices"):
        triangulate_2d((V[:4], np.array([[0, 1, 7]])), sk)


@pytest.mark.parametrize("kwargs, match", [
    (dict(min_angle=30), r"radians.*math.radians\(30\)"),
    (dict(min_angle=-0.1), "min_angle must be in"),
    (dict(max_area=0), "max_area must be a positive"),
    (dict(engine="gmsh"), "engine must be one of 'auto', 'triangle', 'builtin'"),
    (dict(bone_samples=[1, 2]), r"bone_samples must be None, an int or 1 ints"),
    (dict(bone_samples=-1), "bone_samples must be >= 0"),
    (dict(engine="builtin", min_angle=math.radians(33)), "at most .* with the builtin"),
])
def test_bad_options(kwargs, match):
    sk = stbs.Skeleton([[1, 1], [3, 1]], [[0, 1]])
    with pytest.raises(ValueError, match=match):
        triangulate_2d(SQUARE, sk, **kwargs)


def test_not_a_skeleton():
    with pytest.raises(TypeError, match="sk must be a stbs.Skeleton"):
        triangulate_2d(SQUARE, np.zeros((2, 2)))


def test_result_is_read_only_and_bone_vertices_checks_index():
    sk = stbs.Skeleton([[1, 1], [3, 1]], [[0, 1]])
    m = triangulate_2d(SQUARE, sk, engine="builtin")
    with pytest.raises(ValueError):
        m.V[0, 0] = 1.0
    with pytest.raises(ValueError, match="bone index in 0..0"):
        m.bone_vertices(1, sk.BE)
    assert "TriMesh(" in repr(m)
    assert m.dim == 2 and m.n_vertices == m.V.shape[0]
    assert np.array_equal(np.flatnonzero(m.on_joint >= 0), m.joint_vertex)
    assert edges_of(m.F).shape[1] == 2
