"""Compiled point-versus-surface queries (numba, parallel over the query points)."""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from .._jit import cache_enabled

_CACHE = cache_enabled(__file__)
_JIT = dict(nogil=True, cache=_CACHE, parallel=True, error_model="numpy")


@nb.njit(inline="always", cache=_CACHE)
def _closest(px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz):
    """Closest point of triangle abc to p (Ericson, Real-Time Collision Detection 5.1.5).

    Returns (x, y, z, region): region 0 the face, 1/2/3 the vertex a/b/c, 4/5/6 the
    edge ab/bc/ca.
    """
    abx, aby, abz = bx - ax, by - ay, bz - az
    acx, acy, acz = cx - ax, cy - ay, cz - az
    apx, apy, apz = px - ax, py - ay, pz - az
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    if d1 <= 0.0 and d2 <= 0.0:
        return ax, ay, az, 1
    bpx, bpy, bpz = px - bx, py - by, pz - bz
    d3 = abx * bpx + aby * bpy + abz * bpz
    d4 = acx * bpx + acy * bpy + acz * bpz
    if d3 >= 0.0 and d4 <= d3:
        return bx, by, bz, 2
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        v = d1 / (d1 - d3)
        return ax + v * abx, ay + v * aby, az + v * abz, 4
    cpx, cpy, cpz = px - cx, py - cy, pz - cz
    d5 = abx * cpx + aby * cpy + abz * cpz
    d6 = acx * cpx + acy * cpy + acz * cpz
    if d6 >= 0.0 and d5 <= d6:
        return cx, cy, cz, 3
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        w = d2 / (d2 - d6)
        return ax + w * acx, ay + w * acy, az + w * acz, 6
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        return bx + w * (cx - bx), by + w * (cy - by), bz + w * (cz - bz), 5
    denom = 1.0 / (va + vb + vc)
    v = vb * denom
    w = vc * denom
    return ax + abx * v + acx * w, ay + aby * v + acy * w, az + abz * v + acz * w, 0


@nb.njit(**_JIT)
def _signed(Q, V, F, PN, ptr, idx, dist, side):
    for k in nb.prange(Q.shape[0]):
        px, py, pz = Q[k, 0], Q[k, 1], Q[k, 2]
        best = np.inf
        bf, br = -1, 0
        bx = by = bz = 0.0
        for c in range(ptr[k], ptr[k + 1]):
            f = idx[c]
            i, j, m = F[f, 0], F[f, 1], F[f, 2]
            x, y, z, r = _closest(px, py, pz, V[i, 0], V[i, 1], V[i, 2], V[j, 0], V[j, 1],
                                  V[j, 2], V[m, 0], V[m, 1], V[m, 2])
            d = (px - x) ** 2 + (py - y) ** 2 + (pz - z) ** 2
            if d < best:
                best, bf, br, bx, by, bz = d, f, r, x, y, z
        if bf < 0:
            dist[k] = np.inf
            side[k] = 0
            continue
        dist[k] = math.sqrt(best)
        # Angle-weighted pseudonormal of the closest feature (Baerentzen & Aanaes 2005):
        # its sign against p - closest is exact for a closed, manifold surface.
        s = ((px - bx) * PN[bf, br, 0] + (py - by) * PN[bf, br, 1]
             + (pz - bz) * PN[bf, br, 2])
        side[k] = 1 if s > 0 else (-1 if s < 0 else 0)


def pseudonormals(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """(f, 7, 3): for each triangle, the pseudonormal of its face, vertices a, b, c and
    edges ab, bc, ca, in the region order of ``_closest``. ``F`` faces outwards."""
    from ._geometry import unique_edges

    P = V[F]
    N = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
    N /= np.linalg.norm(N, axis=1, keepdims=True)
    PN = np.empty((F.shape[0], 7, 3))
    PN[:, 0] = N
    VN = np.zeros_like(V)
    for k in range(3):
        u = P[:, (k + 1) % 3] - P[:, k]
        w = P[:, (k + 2) % 3] - P[:, k]
        ang = np.arctan2(np.linalg.norm(np.cross(u, w), axis=1), np.einsum("ij,ij->i", u, w))
        np.add.at(VN, F[:, k], ang[:, None] * N)
    for k in range(3):
        PN[:, 1 + k] = VN[F[:, k]]
    _, inv, _ = unique_edges(F)
    f = F.shape[0]
    EN = np.zeros((inv.max() + 1, 3))
    np.add.at(EN, inv, np.tile(N, (3, 1)))
    for k in range(3):  # half-edge k * f + face runs from corner k to corner k + 1
        PN[:, 4 + k] = EN[inv[k * f:(k + 1) * f]]
    return PN


class SurfaceIndex:
    """Closest-point queries on a closed surface ``(V, F)`` (outward faces).

    Triangles are bucketed by size (powers of two of their bounding radius) with one
    k-d tree of centroids per bucket, so that a few large triangles do not widen
    every search.
    """

    def __init__(self, V: np.ndarray, F: np.ndarray):
        from scipy.spatial import cKDTree

        self.V = np.ascontiguousarray(V, dtype=np.float64)
        self.F = np.ascontiguousarray(F, dtype=np.int64)
        P = self.V[self.F]
        C = P.mean(axis=1)
        R = np.linalg.norm(P - C[:, None], axis=2).max(axis=1)
        self.PN = pseudonormals(self.V, self.F)
        self.tree = cKDTree(C)
        med = float(np.median(R))
        level = np.clip(np.ceil(np.log2(np.maximum(R, 1e-300) / med)), 0, None).astype(int)
        self.buckets = []
        for lv in np.unique(level):
            ids = np.flatnonzero(level == lv)
            self.buckets.append((cKDTree(C[ids]), ids, float(R[ids].max())))

    def _run(self, Q, ptr, idx):
        dist = np.empty(Q.shape[0])
        side = np.empty(Q.shape[0], dtype=np.int64)
        if Q.shape[0]:
            _signed(Q, self.V, self.F, self.PN, ptr, idx, dist, side)
        return dist, side

    def closest_side(self, Q: np.ndarray, radius) -> tuple[np.ndarray, np.ndarray]:
        """Distance to the surface and side (+1 outside, -1 inside, 0 on) of points ``Q``.

        Exact for points within ``radius`` (scalar or per point) of the surface; for
        the others the distance is ``inf`` and the side 0.
        """
        import itertools

        Q = np.ascontiguousarray(Q, dtype=np.float64)
        q = Q.shape[0]
        radius = np.broadcast_to(np.asarray(radius, dtype=np.float64), (q,))
        # The triangle with the nearest centroid bounds the distance from above.
        f0 = self.tree.query(Q)[1].astype(np.int64)
        ub, _ = self._run(Q, np.arange(q + 1), f0)
        r = np.minimum(radius, ub)
        pts, faces = [np.arange(q)], [f0]
        for tree, ids, Rb in self.buckets:
            lists = tree.query_ball_point(Q, r + Rb, return_sorted=False)
            cnt = np.fromiter(map(len, lists), dtype=np.int64, count=q)
            flat = np.fromiter(itertools.chain.from_iterable(lists), dtype=np.int64,
                               count=int(cnt.sum()))
            pts.append(np.repeat(np.arange(q), cnt))
            faces.append(ids[flat])
        pts, faces = np.concatenate(pts), np.concatenate(faces)
        order = np.argsort(pts, kind="stable")
        idx = faces[order]
        ptr = np.concatenate([[0], np.cumsum(np.bincount(pts, minlength=q))])
        dist, side = self._run(Q, ptr, idx)
        far = dist > radius
        dist[far] = np.inf
        side[far] = 0
        return dist, side
