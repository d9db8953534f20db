"""Shared checks and fields for the stbs.shapes tests."""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_array
from scipy.sparse.csgraph import connected_components

from stbs.meshing import check_surface


def volume(V, F) -> float:
    P = V[F]
    return float(np.einsum("ij,ij->i", P[:, 0], np.cross(P[:, 1], P[:, 2])).sum()) / 6.0


def edges(F) -> np.ndarray:
    H = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    return np.unique(np.sort(H, axis=1), axis=0)


def components(n, F) -> int:
    E = edges(F)
    G = coo_array((np.ones(E.shape[0]), (E[:, 0], E[:, 1])), shape=(n, n))
    return int(connected_components(G, directed=False)[0])


def assert_closed_outward(V, F, *, self_intersections=True):
    """Closed, consistently outward, manifold, no zero-area triangle, no self-crossing.

    The raw marching-tetrahedra surface cannot cross itself (each triangle lies in its
    own tetrahedron) but may hold exactly coplanar neighbours on symmetric shapes,
    which check_surface's floating-point crossing test can mistake for a crossing.
    """
    # Every directed edge once and every edge in two triangles: closed and oriented.
    H = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    assert np.unique(H, axis=0).shape[0] == H.shape[0]
    assert 2 * edges(F).shape[0] == H.shape[0]
    assert volume(V, F) > 0
    V2, F2 = check_surface(V, F, self_intersections=self_intersections)
    assert np.array_equal(F2, F)  # not flipped: already outward


def sphere(r=1.0):
    return lambda X: np.linalg.norm(X, axis=1) - r


def torus(R=1.0, r=0.35):
    def sdf(X):
        q = np.stack([np.linalg.norm(X[:, :2], axis=1) - R, X[:, 2]], axis=1)
        return np.linalg.norm(q, axis=1) - r
    return sdf
