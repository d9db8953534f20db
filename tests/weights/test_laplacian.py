"""Cotangent Laplacian and lumped mass matrix: hand cases, properties, libigl reference."""

from __future__ import annotations

import numpy as np
import pytest

from stbs.io import read_mesh
from stbs.weights.laplacian import cotmatrix, element_measures, massmatrix

RIGHT_V = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
RIGHT_F = np.array([[0, 1, 2]])


def regular_tet(l: float = 1.0):
    V = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], dtype=float)
    return V * l / np.sqrt(8.0), np.array([[0, 1, 2, 3]])   # edge length l


def rotation(rng):
    Q, R = np.linalg.qr(rng.normal(size=(3, 3)))
    return Q * np.sign(np.diag(R))


# -- hand-computed cases ---------------------------------------------------------------
def test_right_triangle_by_hand():
    L = cotmatrix(RIGHT_V, RIGHT_F).toarray()
    # angles 90 deg at v0 and 45 deg at v1, v2: L_ij = cot(opposite angle) / 2
    expect = np.array([[-1.0, 0.5, 0.5],
                       [0.5, -0.5, 0.0],
                       [0.5, 0.0, -0.5]])
    np.testing.assert_allclose(L, expect, atol=1e-15)
    Mv = massmatrix(RIGHT_V, RIGHT_F, type="voronoi").diagonal()
    np.testing.assert_allclose(Mv, [0.25, 0.125, 0.125], atol=1e-15)
    Mb = massmatrix(RIGHT_V, RIGHT_F, type="barycentric").diagonal()
    np.testing.assert_allclose(Mb, [1 / 6] * 3, atol=1e-15)
    assert element_measures(RIGHT_V, RIGHT_F) == pytest.approx([0.5])


def test_right_triangle_in_3d_is_the_same():
    rng = np.random.default_rng(0)
    V3 = np.c_[RIGHT_V, np.zeros(3)] @ rotation(rng).T + rng.normal(size=3)
    np.testing.assert_allclose(cotmatrix(V3, RIGHT_F).toarray(),
                               cotmatrix(RIGHT_V, RIGHT_F).toarray(), atol=1e-14)
    np.testing.assert_allclose(massmatrix(V3, RIGHT_F).diagonal(), [0.25, 0.125, 0.125])


def test_obtuse_triangle_mass_is_mixed_voronoi():
    V = np.array([[0.0, 0.0], [4.0, 0.0], [2.0, 0.5]])     # obtuse at v2
    area = 1.0
    M = massmatrix(V, RIGHT_F).diagonal()
    np.testing.assert_allclose(M, [area / 4, area / 4, area / 2])


@pytest.mark.parametrize("l", [1.0, 0.3])
def test_regular_tetrahedron_by_hand(l):
    V, T = regular_tet(l)
    L = cotmatrix(V, T).toarray()
    # every dihedral angle is arccos(1/3): L_ij = l cot(theta) / 6 = l / (12 sqrt 2)
    off = l / (12 * np.sqrt(2))
    expect = np.full((4, 4), off) - np.eye(4) * 4 * off
    np.testing.assert_allclose(L, expect, rtol=1e-13, atol=1e-15)
    vol = l**3 / (6 * np.sqrt(2))
    np.testing.assert_allclose(massmatrix(V, T).diagonal(), [vol / 4] * 4, rtol=1e-13)
    assert element_measures(V, T)[0] == pytest.approx(vol, rel=1e-13)


# -- properties ------------------------------------------------------------------------
@pytest.mark.parametrize("kind", ["tri2", "tri3", "tet"])
def test_properties_on_random_meshes(kind):
    rng = np.random.default_rng(1)
    if kind == "tet":
        V = rng.normal(size=(40, 3))
        from scipy.spatial import Delaunay
        Ele = Delaunay(V).simplices
    else:
        P = rng.random((40, 2))
        from scipy.spatial import Delaunay
        Ele = Delaunay(P).simplices
        V = P if kind == "tri2" else np.c_[P, 0.3 * np.sin(3 * P[:, 0])]
    L = cotmatrix(V, Ele)
    M = massmatrix(V, Ele)
    A = L.toarray()
    np.testing.assert_allclose(A, A.T, atol=1e-12)
    np.testing.assert_allclose(A.sum(axis=1), 0.0, atol=1e-10)
    assert np.linalg.eigvalsh(A).max() < 1e-10 * np.abs(A).max()    # negative semi-definite
    assert M.diagonal().sum() == pytest.approx(element_measures(V, Ele).sum(), rel=1e-12)
    assert np.all(M.diagonal() > 0)
    # a linear function has zero Laplacian at interior vertices
    f = V @ rng.normal(size=V.shape[1])
    if kind != "tri3":
        from scipy.spatial import ConvexHull
        hull = np.unique(ConvexHull(V).simplices)
        interior = np.setdiff1d(np.arange(V.shape[0]), hull)
        np.testing.assert_allclose((L @ f)[interior], 0.0, atol=1e-10)
    # rigid motions change nothing
    if V.shape[1] == 3:
        W = V @ rotation(rng).T + 5.0
        np.testing.assert_allclose(cotmatrix(W, Ele).toarray(), A, atol=1e-10)


def test_scaling():
    rng = np.random.default_rng(2)
    V = rng.normal(size=(30, 3))
    from scipy.spatial import Delaunay
    T = Delaunay(V).simplices
    s = 2.5
    np.testing.assert_allclose(cotmatrix(s * V, T).toarray(), s * cotmatrix(V, T).toarray(),
                               rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(massmatrix(s * V, T).diagonal(), s**3 * massmatrix(V, T).diagonal())


# -- degenerate elements and bad input -------------------------------------------------
def test_zero_area_triangle_is_an_error_naming_it():
    V = np.array([[0.0, 0], [1, 0], [0, 1], [2, 0]])
    F = np.array([[0, 1, 2], [0, 1, 3]])      # the second is flat
    with pytest.raises(ValueError, match=r"triangle 1 \(vertices \[0, 1, 3\]\) is degenerate"):
        cotmatrix(V, F)
    with pytest.raises(ValueError, match="degenerate"):
        massmatrix(V, F)
    L = cotmatrix(V, F, degenerate="skip")
    np.testing.assert_allclose(L.toarray()[:3, :3], cotmatrix(V[:3], F[:1]).toarray())
    assert np.all(np.isfinite(L.toarray()))
    np.testing.assert_allclose(massmatrix(V, F, degenerate="skip").diagonal()[:3],
                               massmatrix(V[:3], F[:1]).diagonal())


def test_flat_tetrahedron_and_repeated_vertex():
    V, T = regular_tet()
    V = np.vstack([V, [0.0, 0.0, 0.0]])
    flat = np.array([[0, 1, 2, 0]])
    with pytest.raises(ValueError, match="tetrahedron 0 .*zero volume"):
        cotmatrix(V, flat)
    Vp = np.vstack([V, V[:3].mean(axis=0)])   # a point in the plane of face 0,1,2
    with pytest.raises(ValueError, match="degenerate"):
        cotmatrix(Vp, np.array([[0, 1, 2, 5]]))


def test_bad_input():
    with pytest.raises(ValueError, match=r"Ele must have shape \(f, 3\)"):
        cotmatrix(RIGHT_V, np.array([[0, 1]]))
    with pytest.raises(ValueError, match="tetrahedra need 3D vertices"):
        cotmatrix(RIGHT_V, np.array([[0, 1, 2, 0]]))
    with pytest.raises(ValueError, match="indices in 0..2"):
        cotmatrix(RIGHT_V, np.array([[0, 1, 3]]))
    with pytest.raises(ValueError, match="type must be one of"):
        massmatrix(RIGHT_V, RIGHT_F, type="full")
    V, T = regular_tet()
    with pytest.raises(ValueError, match="voronoi"):
        massmatrix(V, T, type="voronoi")
    with pytest.raises(ValueError, match="degenerate must be one of"):
        cotmatrix(RIGHT_V, RIGHT_F, degenerate="ignore")


# -- libigl reference ------------------------------------------------------------------
@pytest.mark.parametrize("path", ["libigl-tutorial-data/hand.mesh",
                                  "libigl-tutorial-data/octopus-low.mesh",
                                  "fast_support_reduction/woody.obj",
                                  "libigl-tutorial-data/arm.obj"])
def test_matches_libigl(shared_data, path):
    igl = pytest.importorskip("igl")
    m = read_mesh(shared_data / path)
    Ele = m.T if m.T is not None else m.F
    L, Li = cotmatrix(m.V, Ele), igl.cotmatrix(m.V, Ele)
    assert abs(L - Li).max() <= 1e-10 * abs(Li).max()     # libigl: also negative semi-definite
    M, Mi = massmatrix(m.V, Ele), igl.massmatrix(m.V, Ele)
    assert abs(M - Mi).max() <= 1e-12 * abs(Mi).max()
    if Ele.shape[1] == 3:
        Mb = massmatrix(m.V, Ele, type="barycentric")
        Mbi = igl.massmatrix(m.V, Ele, igl.MASSMATRIX_TYPE_BARYCENTRIC)
        assert abs(Mb - Mbi).max() <= 1e-12 * abs(Mbi).max()


# -- the elements' name (E means endpoint weights) ----------------------------------------------
@pytest.mark.parametrize("func", [cotmatrix, massmatrix, element_measures])
def test_elements_keyword_E_is_deprecated(func):
    want = func(RIGHT_V, RIGHT_F)
    want = want.toarray() if hasattr(want, "toarray") else want
    got = func(RIGHT_V, Ele=RIGHT_F)
    np.testing.assert_array_equal(got.toarray() if hasattr(got, "toarray") else got, want)
    with pytest.warns(DeprecationWarning, match=rf"{func.__name__}\(E=...\) is deprecated.*Ele"):
        old = func(RIGHT_V, E=RIGHT_F)
    np.testing.assert_array_equal(old.toarray() if hasattr(old, "toarray") else old, want)
    with pytest.raises(TypeError, match="got both 'Ele' and its deprecated name 'E'"):
        func(RIGHT_V, RIGHT_F, E=RIGHT_F)
    with pytest.raises(TypeError, match="got both"):
        func(RIGHT_V, Ele=RIGHT_F, E=RIGHT_F)


def test_options_are_keyword_only():
    with pytest.raises(TypeError):
        massmatrix(RIGHT_V, RIGHT_F, "voronoi")
    with pytest.raises(TypeError):
        cotmatrix(RIGHT_V, RIGHT_F, "skip")
