"""Boundary conditions for bone weights: exact bone samples, joints, nearest-vertex fallback."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import stbs
from stbs.io import read_mesh, read_tgf
from stbs.weights.boundary import boundary_conditions, segment_distances


def grid(nx: int, ny: int, scale: int = 10):
    """Triangulated grid with vertex (i, j) at (i/scale, j/scale) (exact decimal nodes)."""
    I, J = np.meshgrid(np.arange(nx + 1), np.arange(ny + 1), indexing="ij")
    V = np.c_[I.ravel(), J.ravel()] / scale
    idx = np.arange(V.shape[0]).reshape(nx + 1, ny + 1)
    a, b = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel()
    c, d = idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    F = np.r_[np.c_[a, b, c], np.c_[a, c, d]]
    return V, F


def chain():
    """Two bones meeting at the joint (1, 1) of a 2x2 grid with spacing 0.1."""
    V, F = grid(20, 20)
    sk = stbs.Skeleton(np.array([[0.5, 1.0], [1.0, 1.0], [1.0, 1.7]]), np.array([[0, 1], [1, 2]]))
    return V, F, sk


def test_exact_samples_and_shared_joint():
    V, F, sk = chain()
    b, bc = boundary_conditions(V, sk, F=F)
    D = segment_distances(V, sk.A, sk.B)
    on0, on1 = np.flatnonzero(D[:, 0] < 1e-12), np.flatnonzero(D[:, 1] < 1e-12)
    assert on0.size == 6 and on1.size == 8             # grid nodes on each segment
    np.testing.assert_array_equal(b, np.union1d(on0, on1))
    assert np.all(np.diff(b) > 0)
    np.testing.assert_allclose(bc.sum(axis=1), 1.0)
    joint = np.flatnonzero(np.all(V == [1.0, 1.0], axis=1))[0]
    row = bc[np.searchsorted(b, joint)]
    np.testing.assert_array_equal(row, [0.5, 0.5])      # libigl's rule: 1/k per bone
    for i, on in enumerate((on0, on1)):
        only = np.setdiff1d(on, [joint])
        np.testing.assert_array_equal(bc[np.searchsorted(b, only)], np.eye(2)[[i] * only.size])


def test_matches_libigl_on_hand(shared_data):
    igl = pytest.importorskip("igl")
    m = read_mesh(shared_data / "libigl-tutorial-data/hand.mesh")
    C, BE = read_tgf(shared_data / "libigl-tutorial-data/hand.tgf")
    b, bc = boundary_conditions(m.V, stbs.Skeleton(C, BE), T=m.T)
    e = np.zeros((0, 2), dtype=np.int64)
    bi, bci = igl.boundary_conditions(m.V, m.T, C, np.zeros(0, dtype=np.int64),
                                      BE.astype(np.int64), e, np.zeros((0, 3), dtype=np.int64))
    order = np.argsort(bi)
    np.testing.assert_array_equal(b, bi[order])
    np.testing.assert_allclose(bc, bci[order], atol=1e-15)
    assert bc.shape == (221, 20)


def test_fallback_to_nearest_vertices_warns_with_distance():
    V, F = grid(20, 20)
    # bones between grid lines: no vertex lies on them
    sk = stbs.Skeleton(np.array([[0.52, 0.33], [1.52, 0.33], [1.52, 1.83]]),
                       np.array([[0, 1], [1, 2]]), names=["upper", "lower"])
    with pytest.warns(UserWarning, match=r"no mesh vertex lies on bone 0 \('upper'\), "
                                         r"bone 1 \('lower'\).*farthest at"):
        b, bc = boundary_conditions(V, sk, F=F)
    assert np.all((bc > 0).sum(axis=0) >= 3)
    np.testing.assert_allclose(bc.sum(axis=1), 1.0)
    D = segment_distances(V[b], sk.A, sk.B)
    assert D.min(axis=1).max() <= 0.1 * np.sqrt(0.5) + 1e-12     # nearest grid nodes
    # every constrained vertex belongs to the nearer bone
    owner = np.argmax(bc, axis=1)
    assert np.all(D[np.arange(b.size), owner] <= D.min(axis=1) + 1e-12)


def test_partial_samples_fall_back_only_for_the_missing_bone():
    V, F = grid(20, 20)
    sk = stbs.Skeleton(np.array([[0.5, 0.5], [1.5, 0.5], [1.53, 1.5]]), np.array([[0, 1], [1, 2]]))
    with pytest.warns(UserWarning, match=r"bone 1 \('bone1'\)") as rec:
        b, bc = boundary_conditions(V, sk, F=F)
    assert "bone 0" not in str(rec[0].message)
    on0 = np.flatnonzero(segment_distances(V, sk.A[:1], sk.B[:1])[:, 0] < 1e-12)
    assert np.isin(on0, b).all()


def test_no_warning_when_samples_exist():
    V, F, sk = chain()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        boundary_conditions(V, sk, F=F)


def test_bone_without_any_vertex_is_an_error_naming_it():
    V, F = grid(20, 20)
    # bone 1 runs right next to bone 0 (which lies on a grid line): its nearest vertices
    # all lie on bone 0, so nothing is left for it
    sk = stbs.Skeleton(np.array([[0.5, 1.0], [1.5, 1.0], [0.7, 1.01], [1.3, 1.01]]),
                       np.array([[0, 1], [2, 3]]), names=["femur", "ghost"])
    with pytest.warns(UserWarning), \
            pytest.raises(ValueError, match=r"no vertex can be attached to bone 1 \('ghost'\)"):
        boundary_conditions(V, sk, F=F)


def test_only_element_vertices_are_used():
    V, F, sk = chain()
    V2 = np.vstack([V, [[0.75, 1.0]]])            # a stray vertex on bone 0, in no triangle
    b, _ = boundary_conditions(V2, sk, F=F)
    assert V2.shape[0] - 1 not in b
    b_all, _ = boundary_conditions(V2, sk)        # without elements every vertex counts
    assert V2.shape[0] - 1 in b_all


def test_3d_bone_samples():
    # a column of vertices along z, bones on it
    z = np.linspace(0, 1, 11)
    V = np.r_[np.c_[np.zeros(11), np.zeros(11), z], np.c_[np.ones(11), np.zeros(11), z]]
    sk = stbs.Skeleton(np.array([[0, 0, 0.0], [0, 0, 0.5], [0, 0, 1.0]]),
                       np.array([[0, 1], [1, 2]]))
    b, bc = boundary_conditions(V, sk)
    np.testing.assert_array_equal(b, np.arange(11))
    np.testing.assert_allclose(bc[5], [0.5, 0.5])
    np.testing.assert_allclose(bc[:5, 0], 1.0)
    np.testing.assert_allclose(bc[6:, 1], 1.0)


def test_bad_input():
    V, F, sk = chain()
    with pytest.raises(ValueError, match=r"V must have shape \(441, 2\)"):
        boundary_conditions(np.c_[V, np.zeros(len(V))], sk)
    with pytest.raises(ValueError, match="F must hold vertex indices"):
        boundary_conditions(V, sk, F=F + 1000)
    with pytest.raises(ValueError, match=r"T must have shape \(\?, 4\)"):
        boundary_conditions(V, sk, T=F)
    with pytest.raises(ValueError, match="samples must be >= 1"):
        boundary_conditions(V, sk, samples=0)
    with pytest.raises(TypeError, match="Skeleton"):
        boundary_conditions(V, (sk.C, sk.BE))
