"""stbs.shapes grid shapes: cigar, box, bar, box_tets, sections."""

import numpy as np
import pytest

import stbs
from stbs.geometry import boundary_faces, tet_volumes
from stbs.shapes import bar, box, box_tets, cigar, sections


def closed_outward(V, F):
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    volume = np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6
    directed = np.vstack([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    _, count = np.unique(directed, axis=0, return_counts=True)
    undirected = np.unique(np.sort(directed, axis=1), axis=0)
    area = np.linalg.norm(np.cross(b - a, c - a), axis=1)
    # Closed and consistently oriented: every edge used once in each direction.
    return (volume > 0 and count.max() == 1 and len(undirected) * 2 == len(directed)
            and area.min() > 0)


@pytest.mark.parametrize("make", [lambda: cigar(6), lambda: cigar(20), lambda: box(4, 2, 3),
                                  lambda: bar(8, 3, 2)])
def test_shapes_are_closed_outward_meshes_with_valid_weights(make):
    V, F, sk, W = make()
    assert V.shape[1] == 3 and F.dtype == np.int64 and F.min() == 0 and F.max() == len(V) - 1
    assert closed_outward(V, F)
    assert isinstance(sk, stbs.Skeleton) and W.shape == (len(V), sk.n_bones)
    np.testing.assert_allclose(W.sum(axis=1), 1)
    assert W.min() >= 0


def test_cigar_extends_beyond_both_bone_ends():
    V, _, sk, _ = cigar(10)
    assert V[:, 0].min() == pytest.approx(-2) and V[:, 0].max() == pytest.approx(2)
    np.testing.assert_allclose(sk.C, [[-1, 0, 0], [1, 0, 0]])
    np.testing.assert_allclose(np.abs(V[:, 1:]).max(), 0.5, atol=1e-3)


def test_box_and_bar_skeletons():
    V, _, sk, _ = box(4, 2, 2)
    np.testing.assert_allclose(sk.C, [[0, 0, 0], [4, 0, 0]])
    np.testing.assert_allclose(V.min(axis=0), [0, -0.5, -0.5])
    V, _, sk, W = bar(8, 2, 2)
    assert sk.names == ["upper", "lower"] and sk.parents.tolist() == [-1, 0]
    np.testing.assert_allclose(W[V[:, 0] <= 1.5], [[1, 0]] * int((V[:, 0] <= 1.5).sum()))
    np.testing.assert_allclose(W[V[:, 0] == 2.0, 1], 0.5)
    with pytest.raises(ValueError, match="nx must be even"):
        box(5, 2, 2)
    with pytest.raises(ValueError, match="n must be an integer >= 3"):
        cigar(2)


def test_box_tets_fill_the_box_and_bound_it():
    V, T, F = box_tets(lo=(0, 0, 0), hi=(2, 1, 1), h=0.25)
    assert V.shape == (9 * 5 * 5, 3) and T.shape == (6 * 8 * 4 * 4, 4)
    vol = tet_volumes(V, T)
    assert vol.min() > 0 and vol.sum() == pytest.approx(2.0)
    assert closed_outward(V, F)
    # The same boundary as stbs.geometry's, in the tetrahedra's order.
    ref = boundary_faces(T, V)
    assert sorted(map(tuple, F)) == sorted(map(tuple, ref))
    np.testing.assert_allclose(V.min(axis=0), [0, 0, 0])
    np.testing.assert_allclose(V.max(axis=0), [2, 1, 1])
    with pytest.raises(ValueError, match="box_tets needs h > 0"):
        box_tets(h=0.0)
    with pytest.raises(ValueError, match="lo must have shape"):
        box_tets(lo=(0, 0))


def test_sections_group_vertices_by_x():
    V, _, _, _ = box(4, 2, 2)
    secs = sections(V)
    assert [x for x, _ in secs] == [0.0, 1.0, 2.0, 3.0, 4.0]
    assert sum(len(i) for _, i in secs) == len(V)
    for x, i in secs:
        assert np.all(V[i, 0] == x)
