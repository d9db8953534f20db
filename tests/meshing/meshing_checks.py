"""Shared checks and shapes for the meshing tests."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from rigs import icosphere  # noqa: F401  (re-exported for the meshing tests)
from stbs.meshing import _optional, boundary_loops
from stbs.meshing._geometry import (
    orient2d,
    point_segment_distance,
    tet_volumes,
    triangle_angles,
    triangle_areas,
)

ENGINES_2D = [
    "builtin",
    pytest.param("triangle", marks=pytest.mark.skipif(
        not _optional.available("triangle"), reason="the 'triangle' extra is not installed")),
]
ENGINES_3D = [
    "builtin",
    pytest.param("tetgen", marks=pytest.mark.skipif(
        not _optional.available("tetgen"), reason="the 'tetgen' extra is not installed")),
]


def scale(V) -> float:
    return float(np.linalg.norm(V.max(axis=0) - V.min(axis=0)))


def edges_of(F) -> np.ndarray:
    k = F.shape[1]
    E = np.concatenate([F[:, [i, j]] for i, j in itertools.combinations(range(k), 2)])
    return np.unique(np.sort(E, axis=1), axis=0)


def check_skeleton_record(m, sk, *, on_tol: float = 1e-12) -> None:
    """Joints exact, samples on their bones, every bone a chain of mesh edges."""
    V = m.V
    n = V.shape[0]
    assert m.on_bone.shape == (n,) and m.t_bone.shape == (n,)
    # Exact, unless an input mesh vertex already sat on the joint (woody.obj: within
    # rounding of the file's 4 decimals) and is used instead.
    assert np.abs(V[m.joint_vertex] - sk.C).max() <= on_tol * scale(V)
    assert np.array_equal(V[m.joint_vertex[m.joint_vertex >= m.n_input]],
                          sk.C[m.joint_vertex >= m.n_input])
    on = np.flatnonzero(m.on_bone >= 0)
    assert np.all(np.isnan(m.t_bone[m.on_bone < 0]))
    t = m.t_bone[on]
    assert np.all((t > 0) & (t < 1))
    b = m.on_bone[on]
    expect = sk.A[b] + t[:, None] * (sk.B[b] - sk.A[b])
    assert np.abs(V[on] - expect).max() <= on_tol * scale(V)
    assert np.all(point_segment_distance(V[on], sk.A[b], sk.B[b]) <= on_tol * scale(V))
    assert not np.isin(on, m.joint_vertex).any()
    # In 2D bones are constrained segments: every piece between samples is a mesh edge.
    # (In 3D the samples are vertices; TetGen takes no segment constraints.)
    E = {tuple(e) for e in edges_of(m.F).tolist()} if m.dim == 2 else None
    for i in range(sk.n_bones):
        idx, tt = m.bone_vertices(i, sk.BE)
        assert idx.size >= 3, f"bone {i} has no inner sample"
        assert np.all(np.diff(tt) > 0)
        if E is not None:
            for a, c in zip(idx[:-1], idx[1:], strict=True):
                assert (min(a, c), max(a, c)) in E, f"bone {i}: piece {a}-{c} is not an edge"


def check_trimesh(m, sk, *, min_angle_deg: float | None = None, max_area: float | None = None,
                  record: bool = True) -> None:
    """Mesh validity and quality; with ``record``, also the skeleton's record."""
    V, F = m.V, m.F
    assert V.dtype == np.float64 and F.dtype == np.int64
    assert V.shape[1] == 2 and F.shape[1] == 3
    assert np.all(np.isfinite(V))
    assert F.min() >= 0 and F.max() < V.shape[0]
    assert np.unique(F).size == V.shape[0], "unused vertices"
    area = triangle_areas(V, F)
    assert area.min() > 0, "triangles must be counter-clockwise with positive area"
    if max_area is not None:
        assert area.max() <= max_area * (1 + 1e-9)
    if min_angle_deg is not None:
        assert np.degrees(triangle_angles(V, F).min()) >= min_angle_deg - 1e-6
    if record:
        check_skeleton_record(m, sk)
        check_bones_not_crossed(m, sk)


def check_bones_not_crossed(m, sk) -> None:
    """No mesh edge crosses a bone: each edge is on one side (or has an end on it)."""
    E = edges_of(m.F)
    P, Q = m.V[E[:, 0]], m.V[E[:, 1]]
    for i in range(sk.n_bones):
        a, b = sk.A[i], sk.B[i]
        s1, s2 = orient2d(a, b, P), orient2d(a, b, Q)
        s3, s4 = orient2d(P, Q, a[None]), orient2d(P, Q, b[None])
        crossing = (s1 * s2 < 0) & (s3 * s4 < 0)
        # Rounding: an endpoint on the bone gives |s| ~ 1e-16; demand a clear crossing.
        tol = 1e-9 * scale(m.V) ** 2
        crossing &= (np.abs(s1) > tol) & (np.abs(s2) > tol)
        assert not crossing.any(), f"an edge crosses bone {i}"


def check_covers_outline(m, polygons) -> None:
    """The mesh area is the even-odd area of the polygons, its boundary their perimeter."""
    from stbs.meshing._geometry import points_in_loops, signed_area

    depth = [sum(points_in_loops(P[:1], [Q])[0] for Q in polygons if Q is not P)
             for P in polygons]
    area = sum(abs(signed_area(P)) * (-1) ** d for P, d in zip(polygons, depth, strict=True))
    assert triangle_areas(m.V, m.F).sum() == pytest.approx(area, rel=1e-9)
    loops = boundary_loops(m.F)
    perim = sum(np.linalg.norm(np.roll(m.V[L], -1, axis=0) - m.V[L], axis=1).sum()
                for L in loops)
    want = sum(np.linalg.norm(np.roll(P, -1, axis=0) - P, axis=1).sum() for P in polygons)
    assert perim == pytest.approx(want, rel=1e-9)
    assert len(loops) == len(polygons)


def check_tetmesh(m, sk, V_in, *, volume: float | None = None, rel: float = 1e-9) -> None:
    V, T = m.V, m.T
    n = V_in.shape[0]
    assert m.n_input == n
    assert np.array_equal(V[:n], V_in), "surface vertices must come first, unchanged"
    assert T.dtype == np.int64 and T.shape[1] == 4
    assert np.unique(T).size == V.shape[0], "unused vertices"
    vol = tet_volumes(V, T)
    assert vol.min() > 0
    if volume is not None:
        assert vol.sum() == pytest.approx(volume, rel=rel)
    assert np.array_equal(m.joint_vertex, n + np.arange(sk.n_joints))
    check_skeleton_record(m, sk)
    # F is the outward boundary of T.
    from stbs.meshing._geometry import boundary_faces

    assert np.array_equal(np.sort(np.sort(m.F, axis=1), axis=0),
                          np.sort(np.sort(boundary_faces(T), axis=1), axis=0))


def enclosed_volume(V, F) -> float:
    P = V[F]
    return float(np.einsum("ij,ij->i", P[:, 0], np.cross(P[:, 1], P[:, 2])).sum()) / 6.0


def box(lo=(0.0, 0.0, 0.0), hi=(1.0, 1.0, 1.0)) -> tuple[np.ndarray, np.ndarray]:
    """A closed, outward-facing box surface (8 vertices, 12 triangles)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    V = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    V = lo + V * (hi - lo)
    # Vertex index = 4x + 2y + z.
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    F = np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])
    return V, F


def extrude(P2: np.ndarray, F2: np.ndarray, height: float) -> tuple[np.ndarray, np.ndarray]:
    """A closed prism from a counter-clockwise 2D triangle mesh."""
    n = P2.shape[0]
    V = np.vstack([np.c_[P2, np.zeros(n)], np.c_[P2, np.full(n, height)]])
    F = [F2[:, ::-1], F2 + n]
    for L in boundary_loops(F2):
        a, b = L, np.roll(L, -1)
        F += [np.stack([a, b, b + n], axis=1), np.stack([a, b + n, a + n], axis=1)]
    return V, np.vstack(F)


