"""stbs.geometry: hand-computed cases, properties against NumPy, and a real surface."""

import numpy as np
import pytest

from stbs.geometry import (
    boundary_faces,
    boundary_loops,
    cycles,
    face_normals,
    points_in_loops,
    polygons_area,
    signed_area,
    tet_volumes,
    triangle_areas,
    unique_edges,
    unique_rows,
    vertex_normals,
    winding_numbers,
)


def sq(x0, y0, s):
    return np.array([[x0, y0], [x0 + s, y0], [x0 + s, y0 + s], [x0, y0 + s]], float)


def cube():
    """The unit cube as 5 positively oriented tetrahedra (a hand-made decomposition)."""
    V = np.array([[x, y, z] for z in (0, 1) for y in (0, 1) for x in (0, 1)], float)
    T = np.array([[0, 1, 2, 4], [1, 3, 2, 7], [1, 2, 4, 7], [1, 4, 5, 7], [2, 6, 4, 7]])
    vol = tet_volumes(V, T)
    T[vol < 0] = T[vol < 0][:, [0, 2, 1, 3]]
    return V, T


def test_polygons_area_by_nesting():
    # Two separate shapes add up; a hole subtracts; an island in the hole adds again.
    assert polygons_area([sq(0, 0, 10), sq(20, 0, 2)]) == pytest.approx(104)
    assert polygons_area([sq(0, 0, 10), sq(2, 2, 6)[::-1]]) == pytest.approx(64)
    assert polygons_area([sq(0, 0, 10), sq(2, 2, 6), sq(4, 4, 2)]) == pytest.approx(68)


def test_signed_area_and_points_in_loops():
    assert signed_area(sq(0, 0, 2)) == 4.0
    assert signed_area(sq(0, 0, 2)[::-1]) == -4.0
    inside = points_in_loops([[1, 1], [3, 3], [5, 5], [-1, 0]], [sq(0, 0, 6), sq(2, 2, 2)])
    assert inside.tolist() == [True, False, True, False]


def test_unique_rows_matches_numpy_on_both_paths():
    rng = np.random.default_rng(0)
    for A in (rng.integers(0, 50, (400, 3)), rng.integers(-5, 5, (300, 2)),
              rng.integers(0, 2**40, (100, 3))):          # packed, negative, too wide to pack
        U, idx, inv, cnt = unique_rows(A)
        U0, idx0, inv0, cnt0 = np.unique(A, axis=0, return_index=True, return_inverse=True,
                                         return_counts=True)
        np.testing.assert_array_equal(U, U0)
        np.testing.assert_array_equal(cnt, cnt0)
        np.testing.assert_array_equal(U[inv], A)
        np.testing.assert_array_equal(A[idx], U)


def test_unique_edges_counts_boundary_and_interior():
    E, inv, cnt = unique_edges(np.array([[0, 1, 2], [2, 1, 3]]))
    assert E.tolist() == [[0, 1], [0, 2], [1, 2], [1, 3], [2, 3]]
    assert cnt.tolist() == [1, 1, 2, 1, 1]
    assert inv.shape == (6,)


def test_boundary_faces_of_a_cube_point_outwards_whatever_the_tet_orientation():
    V, T = cube()
    F = boundary_faces(T)
    assert F.shape == (12, 3)                             # 6 squares, 2 triangles each
    n = face_normals(V, F)
    centre = V[F].mean(axis=1) - 0.5
    assert np.all(np.einsum("ij,ij->i", n, centre) > 0)
    flipped = T.copy()
    flipped[::2] = flipped[::2][:, [1, 0, 2, 3]]          # mixed orientations
    G = boundary_faces(flipped, V)
    assert np.all(np.einsum("ij,ij->i", face_normals(V, G), V[G].mean(axis=1) - 0.5) > 0)
    np.testing.assert_array_equal(np.sort(np.sort(G, 1), 0), np.sort(np.sort(F, 1), 0))
    # without V, a flipped tetrahedron's faces come out inwards: V is what fixes that
    H = boundary_faces(flipped)
    assert np.any(np.einsum("ij,ij->i", face_normals(V, H), V[H].mean(axis=1) - 0.5) < 0)
    with pytest.raises(ValueError, match="T must"):
        boundary_faces(np.zeros((2, 3), int))


def test_boundary_faces_of_two_tets_of_mixed_orientation():
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1.0]])
    T = np.array([[0, 1, 2, 3], [1, 2, 3, 4]])
    T[1] = T[1, [1, 0, 2, 3]]
    F = boundary_faces(T, V)
    assert F.shape == (6, 3)  # 8 faces, the shared one dropped
    normals = face_normals(V, F)
    assert np.all(np.einsum("ij,ij->i", normals, V[F[:, 0]] - V.mean(axis=0)) > 0)


def test_vertex_normals_of_a_tetrahedron_and_an_isolated_vertex():
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [9, 9, 9]], float)
    F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    N = vertex_normals(V, F)
    # vertex 0 sees three unit-area-halves faces with normals -x, -y, -z
    np.testing.assert_allclose(N[0], -np.ones(3) / np.sqrt(3))
    np.testing.assert_allclose(np.linalg.norm(N[:4], axis=1), 1.0)
    assert np.all(N[4] == 0)


def test_areas_and_volumes_signed():
    V2 = np.array([[0, 0], [2, 0], [0, 1]], float)
    assert triangle_areas(V2, [[0, 1, 2], [0, 2, 1]]).tolist() == [1.0, -1.0]
    V, T = cube()
    assert tet_volumes(V, T).sum() == pytest.approx(1.0)


def test_boundary_loops_and_cycles():
    # a square with a square hole, triangulated by hand (8 triangles)
    V = np.vstack([sq(0, 0, 3), sq(1, 1, 1)])
    F = np.array([[0, 1, 5], [0, 5, 4], [1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6],
                  [3, 0, 4], [3, 4, 7]])
    loops = boundary_loops(F)
    assert [sorted(L.tolist()) for L in loops] == [[0, 1, 2, 3], [4, 5, 6, 7]]
    assert signed_area(V[loops[0]]) > 0 > signed_area(V[loops[1]])
    assert [c.tolist() for c in cycles(np.array([1, 2, 0, 4, 3]))] == [[0, 1, 2], [3, 4]]


def test_winding_numbers_of_a_cube_surface():
    V, T = cube()
    F = boundary_faces(T)
    w = winding_numbers([[0.5, 0.5, 0.5], [0.1, 0.9, 0.2], [2, 0, 0]], V, F)
    np.testing.assert_allclose(w, [1, 1, 0], atol=1e-12)
    np.testing.assert_allclose(winding_numbers(np.zeros((0, 3)), V, F), [])
    flipped = F[:, ::-1]
    np.testing.assert_allclose(winding_numbers([[0.5, 0.5, 0.5]], V, flipped), [-1], atol=1e-12)


def test_on_a_real_surface(shared_data):
    from stbs.io import read_mesh

    m = read_mesh(shared_data / "libigl-tutorial-data" / "hand.mesh")
    F = boundary_faces(m.T, m.V)
    n = face_normals(m.V, F)
    # outward: the enclosed volume by the divergence theorem equals the tets' volume
    vol = np.einsum("ij,ij->", m.V[F[:, 0]], n) / 6.0
    assert vol == pytest.approx(np.abs(tet_volumes(m.V, m.T)).sum(), rel=1e-9)
    w = winding_numbers(m.V[m.T].mean(axis=1)[:200], m.V, F)
    np.testing.assert_allclose(w, 1.0, atol=1e-6)
