"""Generalised winding numbers: the exact kernel, and a hierarchical one for many points.

Both are numba kernels, parallel over the query points. The exact one sums the solid
angle of every triangle for every point (Jacobson et al. 2013); its cost is points x
triangles. :class:`WindingTree` is the fast winding number of Barill et al. (2018,
"Fast winding numbers for soups and clouds"): a bounding-volume tree over the
triangles, whose far clusters are summed as one dipole each (the first-order term of
the solid angle's expansion), so a query costs about log(triangles) cluster visits
plus the exact sum over the triangles near it.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from .._jit import cache_enabled

_CACHE = cache_enabled(__file__)
_JIT = dict(nogil=True, cache=_CACHE, parallel=True, error_model="numpy")
_JIT1 = dict(nogil=True, cache=_CACHE, error_model="numpy")

#: Triangles per leaf of :class:`WindingTree`.
LEAF_SIZE = 8
#: Default accuracy of :class:`WindingTree`: a cluster is summed as one dipole when the
#: query is farther than ``BETA`` times its radius from its centre. Measured on real
#: characters (open, multi-part, self-intersecting), 2.0 stays within 0.02 of the exact
#: winding number away from the surface (see docs/bbw.md).
BETA = 2.0


@nb.njit(inline="always", **_JIT1)
def _solid_angle(qx, qy, qz, V, i, j, m):
    # The signed solid angle of triangle (i, j, m) seen from q, by Van Oosterom &
    # Strackee (1983); over 4 pi it is the triangle's share of the winding number.
    ax, ay, az = V[i, 0] - qx, V[i, 1] - qy, V[i, 2] - qz
    bx, by, bz = V[j, 0] - qx, V[j, 1] - qy, V[j, 2] - qz
    cx, cy, cz = V[m, 0] - qx, V[m, 1] - qy, V[m, 2] - qz
    la = math.sqrt(ax * ax + ay * ay + az * az)
    lb = math.sqrt(bx * bx + by * by + bz * bz)
    lc = math.sqrt(cx * cx + cy * cy + cz * cz)
    det = (ax * (by * cz - bz * cy) - ay * (bx * cz - bz * cx)
           + az * (bx * cy - by * cx))
    den = (la * lb * lc + (ax * bx + ay * by + az * bz) * lc
           + (bx * cx + by * cy + bz * cz) * la + (cx * ax + cy * ay + cz * az) * lb)
    return 2.0 * math.atan2(det, den)


@nb.njit(**_JIT)
def _winding(Q, V, F, out):
    # Generalised winding number (Jacobson et al. 2013): the solid angles of the
    # triangles seen from q, summed over 4 pi.
    for k in nb.prange(Q.shape[0]):
        qx, qy, qz = Q[k, 0], Q[k, 1], Q[k, 2]
        total = 0.0
        for f in range(F.shape[0]):
            total += _solid_angle(qx, qy, qz, V, F[f, 0], F[f, 1], F[f, 2])
        out[k] = total / (4.0 * math.pi)


def winding_numbers(Q: np.ndarray, V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Generalised winding numbers (q,) of points ``Q`` (q, 3) for the surface ``(V, F)``.

    About 1 inside a closed, outward-oriented surface, 0 outside.
    """
    out = np.empty(Q.shape[0])
    if Q.shape[0]:
        _winding(np.ascontiguousarray(Q, dtype=np.float64),
                 np.ascontiguousarray(V, dtype=np.float64),
                 np.ascontiguousarray(F, dtype=np.int64), out)
    return out


# --------------------------------------------------------------------------------------
# The hierarchical (fast) winding number
# --------------------------------------------------------------------------------------
@nb.njit(**_JIT1)
def _build(C, leaf):
    """A binary tree over the triangle centroids ``C`` (f, 3): each node a range of
    ``order``, split at the median of its longest side. Returns (order, start, end,
    left, right, n_nodes); a leaf has left = -1."""
    f = C.shape[0]
    cap = 2 * (f // max(leaf, 1) + 1) * 2 + 4
    start = np.empty(cap, np.int64)
    end = np.empty(cap, np.int64)
    left = np.full(cap, -1, np.int64)
    right = np.full(cap, -1, np.int64)
    order = np.arange(f)
    stack = np.empty(cap, np.int64)
    start[0], end[0] = 0, f
    n_nodes = 1
    top = 0
    stack[0] = 0
    while top >= 0:
        node = stack[top]
        top -= 1
        s, e = start[node], end[node]
        if e - s <= leaf:
            continue
        lo = np.full(3, np.inf)
        hi = np.full(3, -np.inf)
        for k in range(s, e):
            for d in range(3):
                x = C[order[k], d]
                lo[d] = min(lo[d], x)
                hi[d] = max(hi[d], x)
        axis = int(np.argmax(hi - lo))
        seg = order[s:e].copy()
        keys = np.empty(e - s)
        for k in range(e - s):
            keys[k] = C[seg[k], axis]
        order[s:e] = seg[np.argsort(keys)]
        mid = (s + e) // 2
        a, b = n_nodes, n_nodes + 1
        n_nodes += 2
        start[a], end[a], start[b], end[b] = s, mid, mid, e
        left[node], right[node] = a, b
        stack[top + 1] = a
        stack[top + 2] = b
        top += 2
    return order, start[:n_nodes], end[:n_nodes], left[:n_nodes], right[:n_nodes]


@nb.njit(**_JIT1)
def _moments(V, F, order, start, end):
    """Per node: the area-weighted normal (a dipole's moment), the area-weighted
    centroid p, the radius of a ball about p holding the node's triangles, and the
    second moment ``sum_t a_t (c_t - p)^T`` (a_t: area-weighted normal, c_t: centroid)."""
    m = start.shape[0]
    N = np.zeros((m, 3))
    P = np.zeros((m, 3))
    R = np.zeros(m)
    C = np.zeros((m, 3, 3))
    for node in range(m):
        area = 0.0
        for k in range(start[node], end[node]):
            t = order[k]
            i, j, l = F[t, 0], F[t, 1], F[t, 2]
            ux, uy, uz = V[j, 0] - V[i, 0], V[j, 1] - V[i, 1], V[j, 2] - V[i, 2]
            vx, vy, vz = V[l, 0] - V[i, 0], V[l, 1] - V[i, 1], V[l, 2] - V[i, 2]
            nx, ny, nz = 0.5 * (uy * vz - uz * vy), 0.5 * (uz * vx - ux * vz), \
                0.5 * (ux * vy - uy * vx)
            N[node, 0] += nx
            N[node, 1] += ny
            N[node, 2] += nz
            a = math.sqrt(nx * nx + ny * ny + nz * nz)
            area += a
            for d in range(3):
                P[node, d] += a * (V[i, d] + V[j, d] + V[l, d]) / 3.0
        if area > 0:
            for d in range(3):
                P[node, d] /= area
        else:
            t = order[start[node]]
            for d in range(3):
                P[node, d] = V[F[t, 0], d]
        r = 0.0
        for k in range(start[node], end[node]):
            t = order[k]
            i, j, l = F[t, 0], F[t, 1], F[t, 2]
            for c in range(3):
                v = F[t, c]
                dx, dy, dz = V[v, 0] - P[node, 0], V[v, 1] - P[node, 1], V[v, 2] - P[node, 2]
                r = max(r, dx * dx + dy * dy + dz * dz)
            # second moment: sum over triangles of a_t (c_t - p)^T
            ux, uy, uz = V[j, 0] - V[i, 0], V[j, 1] - V[i, 1], V[j, 2] - V[i, 2]
            vx, vy, vz = V[l, 0] - V[i, 0], V[l, 1] - V[i, 1], V[l, 2] - V[i, 2]
            a0, a1, a2 = 0.5 * (uy * vz - uz * vy), 0.5 * (uz * vx - ux * vz), \
                0.5 * (ux * vy - uy * vx)
            for d in range(3):
                cd = (V[i, d] + V[j, d] + V[l, d]) / 3.0 - P[node, d]
                C[node, 0, d] += a0 * cd
                C[node, 1, d] += a1 * cd
                C[node, 2, d] += a2 * cd
        R[node] = math.sqrt(r)
    return N, P, R, C


@nb.njit(**_JIT)
def _fast_winding(Q, V, F, order, start, end, left, right, N, P, R, C, beta, out):
    inv4pi = 1.0 / (4.0 * math.pi)
    for k in nb.prange(Q.shape[0]):
        qx, qy, qz = Q[k, 0], Q[k, 1], Q[k, 2]
        stack = np.empty(128, np.int64)
        top = 0
        stack[0] = 0
        total = 0.0
        while top >= 0:
            node = stack[top]
            top -= 1
            dx, dy, dz = P[node, 0] - qx, P[node, 1] - qy, P[node, 2] - qz
            d2 = dx * dx + dy * dy + dz * dz
            rb = beta * R[node]
            if d2 > rb * rb:
                # Far: the Taylor expansion of (x - q) / |x - q|^3 about the cluster's
                # centre p, r = p - q, to second order (Barill et al. 2018, eq. 10):
                # a . r / |r|^3 + (tr C / |r|^3 - 3 r^T C r / |r|^5), over 4 pi.
                d = math.sqrt(d2)
                d3 = d2 * d
                first = (dx * N[node, 0] + dy * N[node, 1] + dz * N[node, 2]) / d3
                trc = C[node, 0, 0] + C[node, 1, 1] + C[node, 2, 2]
                rcr = (dx * (C[node, 0, 0] * dx + C[node, 0, 1] * dy + C[node, 0, 2] * dz)
                       + dy * (C[node, 1, 0] * dx + C[node, 1, 1] * dy + C[node, 1, 2] * dz)
                       + dz * (C[node, 2, 0] * dx + C[node, 2, 1] * dy + C[node, 2, 2] * dz))
                total += (first + trc / d3 - 3.0 * rcr / (d3 * d2)) * inv4pi
            elif left[node] < 0:
                s = 0.0
                for i in range(start[node], end[node]):
                    t = order[i]
                    s += _solid_angle(qx, qy, qz, V, F[t, 0], F[t, 1], F[t, 2])
                total += s * inv4pi
            else:
                stack[top + 1] = left[node]
                stack[top + 2] = right[node]
                top += 2
        out[k] = total


class WindingTree:
    """Fast generalised winding numbers of many points for one triangle surface.

    The tree is built once (about a second per million triangles); each query is
    ``O(log f)`` cluster visits plus exact sums over the nearby triangles, in parallel
    over the points.

    Parameters
    ----------
    V : (n, 3) float
        Surface vertices.
    F : (f, 3) int
        Triangles: any soup (open, several parts, self-intersecting, non-manifold).
    beta : float, keyword-only
        Accuracy: a cluster of radius r is summed as one dipole for points farther
        than ``beta * r`` from it (Barill et al. use 2). Larger is more exact and
        slower; the exact sum is the limit.

    Examples
    --------
    >>> import numpy as np
    >>> from stbs.geometry import WindingTree
    >>> V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    >>> F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    >>> np.round(WindingTree(V, F)([[0.1, 0.1, 0.1], [2, 2, 2]]), 6) + 0.0
    array([1., 0.])
    """

    def __init__(self, V, F, *, beta: float = BETA):
        V = np.ascontiguousarray(V, dtype=np.float64)
        F = np.ascontiguousarray(F, dtype=np.int64)
        if V.ndim != 2 or V.shape[1] != 3:
            raise ValueError(f"V must have shape (n, 3), got {V.shape}")
        if F.ndim != 2 or F.shape[1] != 3:
            raise ValueError(f"F must have shape (f, 3), got {F.shape}")
        if F.size and (F.min() < 0 or F.max() >= V.shape[0]):
            raise ValueError(f"F must hold vertex indices in 0..{V.shape[0] - 1}")
        beta = float(beta)
        if not (math.isfinite(beta) and beta > 0):
            raise ValueError(f"beta must be a positive number, got {beta!r}")
        self.V, self.F, self.beta = V, F, beta
        if F.shape[0]:
            C = V[F].mean(axis=1)
            self._tree = _build(C, LEAF_SIZE)
            self._moments = _moments(V, F, self._tree[0], self._tree[1], self._tree[2])

    def __call__(self, Q) -> np.ndarray:
        """Winding numbers (q,) of the points ``Q`` (q, 3)."""
        Q = np.ascontiguousarray(np.asarray(Q, dtype=np.float64).reshape(-1, 3))
        out = np.zeros(Q.shape[0])
        if Q.shape[0] and self.F.shape[0]:
            _fast_winding(Q, self.V, self.F, *self._tree, *self._moments, self.beta, out)
        return out
