"""Segment occlusion queries for bone-heat visibility (Baran & Popović 2007, §4).

One question, asked for many segments at once: does the segment ``o + t d``,
``t in [0, 1]``, cross the shape's boundary?

- 3D: the boundary is a triangle surface ``(V, F)``. Backends: ``"embree"`` (Intel
  Embree through the optional ``embreex`` binding, single precision) and
  ``"numpy"`` (a bounding-volume hierarchy built and traversed breadth-first with
  NumPy, double precision, no compiled code). ``"auto"`` takes Embree when it is
  installed.
- 2D: the boundary is the set of boundary edges of a triangle mesh; segments are
  tested against them with NumPy (boundary edges are few, O(sqrt(n))).

:func:`occluded_brute` tests every segment against every triangle and is the oracle
the tests compare both backends with.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

RayBackend = Literal["auto", "embree", "numpy"]
RAY_BACKENDS: tuple[str, ...] = ("auto", "embree", "numpy")

# Segments per batch: bounds the (segment, node) frontier of the NumPy traversal.
_CHUNK = 4096
# Triangles per BVH leaf (between _LEAF and 2 * _LEAF after median splits).
_LEAF = 8
# A zero direction component is replaced by this, so 1/d stays finite (no overflow).
_TINY = 1e-30


def embree_available() -> bool:
    """True when the optional ``embreex`` package can be imported."""
    try:
        import embreex  # noqa: F401
    except ImportError:
        return False
    return True


def _moller_trumbore(o, d, v0, e1, e2) -> np.ndarray:
    """Row-wise segment/triangle test (Möller & Trumbore 1997), ``t`` in [0, 1], closed edges."""
    pvec = np.cross(d, e2)
    det = np.einsum("ij,ij->i", e1, pvec)
    ok = det != 0
    inv = np.divide(1.0, det, out=np.zeros_like(det), where=ok)
    tvec = o - v0
    u = np.einsum("ij,ij->i", tvec, pvec) * inv
    qvec = np.cross(tvec, e1)
    v = np.einsum("ij,ij->i", d, qvec) * inv
    t = np.einsum("ij,ij->i", e2, qvec) * inv
    return ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t >= 0) & (t <= 1)


def occluded_brute(V, F, O, D) -> np.ndarray:
    """Every segment against every triangle, in chunks (the reference for the tests).

    Parameters
    ----------
    V : (n, 3) float
    F : (f, 3) int
    O, D : (k, 3) float
        Segment origins and vectors: the segment is ``O + t D``, ``t in [0, 1]``.

    Returns
    -------
    (k,) bool
    """
    V = np.asarray(V, dtype=float)
    F = np.asarray(F, dtype=np.int64)
    O = np.asarray(O, dtype=float)
    D = np.asarray(D, dtype=float)
    v0 = V[F[:, 0]]
    e1 = V[F[:, 1]] - v0
    e2 = V[F[:, 2]] - v0
    out = np.zeros(len(O), dtype=bool)
    f = max(len(F), 1)
    step = max(1, 2_000_000 // f)
    for s in range(0, len(O), step):
        k = min(step, len(O) - s)
        r = np.repeat(np.arange(s, s + k), len(F))
        t = np.tile(np.arange(len(F)), k)
        hit = _moller_trumbore(O[r], D[r], v0[t], e1[t], e2[t])
        out[s:s + k] = hit.reshape(k, len(F)).any(axis=1)
    return out


class _TriangleBVH:
    """An implicit, balanced BVH: level ``L`` has ``2**L`` nodes; node ``k`` covers the
    triangles ``perm[k f // 2**L : (k + 1) f // 2**L]`` (median splits along the
    longest axis, done for a whole level at once with one lexsort)."""

    def __init__(self, V: np.ndarray, F: np.ndarray):
        f = len(F)
        tri = V[F]
        lo, hi = tri.min(axis=1), tri.max(axis=1)
        cen = 0.5 * (lo + hi)
        pad = 1e-9 * max(float(np.ptp(V, axis=0).max()), 1e-300)
        self.depth = int(np.floor(np.log2(f / _LEAF))) if f > _LEAF else 0
        perm = np.arange(f)
        self.lo: list[np.ndarray] = []
        self.hi: list[np.ndarray] = []
        for L in range(self.depth + 1):
            k = 2**L
            starts = (np.arange(k) * f) // k
            self.lo.append(np.minimum.reduceat(lo[perm], starts, axis=0) - pad)
            self.hi.append(np.maximum.reduceat(hi[perm], starts, axis=0) + pad)
            if L < self.depth:
                axis = np.argmax(self.hi[L] - self.lo[L], axis=1)
                node = np.repeat(np.arange(k), np.diff(np.append(starts, f)))
                perm = perm[np.lexsort((cen[perm, axis[node]], node))]
        k = 2**self.depth
        starts = (np.arange(k) * f) // k
        self.leaf_start = starts
        self.leaf_count = np.diff(np.append(starts, f))
        Fp = F[perm]
        self.v0 = V[Fp[:, 0]]
        self.e1 = V[Fp[:, 1]] - self.v0
        self.e2 = V[Fp[:, 2]] - self.v0

    def occluded(self, O: np.ndarray, D: np.ndarray) -> np.ndarray:
        out = np.zeros(len(O), dtype=bool)
        for s in range(0, len(O), _CHUNK):
            out[s:s + _CHUNK] = self._chunk(O[s:s + _CHUNK], D[s:s + _CHUNK])
        return out

    def _chunk(self, O: np.ndarray, D: np.ndarray) -> np.ndarray:
        Dsafe = np.where(np.abs(D) < _TINY, _TINY, D)
        inv = 1.0 / Dsafe
        rays = np.arange(len(O))
        nodes = np.zeros(len(O), dtype=np.int64)
        for L in range(self.depth + 1):
            o, iv = O[rays], inv[rays]
            t1 = (self.lo[L][nodes] - o) * iv
            t2 = (self.hi[L][nodes] - o) * iv
            tmin = np.minimum(t1, t2).max(axis=1)
            tmax = np.maximum(t1, t2).min(axis=1)
            keep = (tmax >= np.maximum(tmin, 0.0)) & (tmin <= 1.0)
            rays, nodes = rays[keep], nodes[keep]
            if L < self.depth:
                rays = np.repeat(rays, 2)
                nodes = (2 * nodes[:, None] + np.array([0, 1])).ravel()
        cnt = self.leaf_count[nodes]
        r = np.repeat(rays, cnt)
        first = np.repeat(np.cumsum(cnt) - cnt, cnt)
        t = np.repeat(self.leaf_start[nodes], cnt) + (np.arange(cnt.sum()) - first)
        hit = _moller_trumbore(O[r], D[r], self.v0[t], self.e1[t], self.e2[t])
        out = np.zeros(len(O), dtype=bool)
        out[r[hit]] = True
        return out


class _EmbreeScene:
    """Embree occlusion queries (float32) through ``embreex``."""

    def __init__(self, V: np.ndarray, F: np.ndarray):
        try:
            from embreex import rtcore_scene
            from embreex.mesh_construction import TriangleMesh
        except ImportError:
            raise ImportError(
                "backend='embree' needs the optional embreex package: "
                "pip install 'stbs-skinning[embree]' (or pip install embreex), "
                "or use backend='numpy'") from None
        self._scene = rtcore_scene.EmbreeScene()
        # Keep a reference: the binding does not copy the buffers in every version.
        self._V = np.ascontiguousarray(V, dtype=np.float32)
        self._F = np.ascontiguousarray(F, dtype=np.int32)
        TriangleMesh(scene=self._scene, vertices=self._V, indices=self._F)

    def occluded(self, O: np.ndarray, D: np.ndarray) -> np.ndarray:
        length = np.linalg.norm(D, axis=1)
        out = np.zeros(len(O), dtype=bool)
        ok = length > 0
        if not ok.any():
            return out
        o = np.ascontiguousarray(O[ok], dtype=np.float32)
        d = np.ascontiguousarray(D[ok] / length[ok, None], dtype=np.float32)
        dist = np.ascontiguousarray(length[ok], dtype=np.float32)
        res = self._scene.run(o, d, dists=dist, query="OCCLUDED")
        out[ok] = np.asarray(res) != -1
        return out


def _boundary_edges(F: np.ndarray) -> np.ndarray:
    """(e, 2) edges used by exactly one triangle, oriented as in that triangle."""
    edges = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    from ..geometry import unique_rows

    _, _, inv, cnt = unique_rows(np.sort(edges, axis=1))
    return edges[cnt[inv] == 1]


def _cross2(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


class _Edges2D:
    """Segment crossings against the boundary edges of a 2D triangle mesh."""

    def __init__(self, V: np.ndarray, F: np.ndarray):
        edges = _boundary_edges(F)
        self.p = V[edges[:, 0]]
        self.r = V[edges[:, 1]] - self.p

    def occluded(self, O: np.ndarray, D: np.ndarray) -> np.ndarray:
        out = np.zeros(len(O), dtype=bool)
        m = len(self.p)
        if m == 0:
            return out
        step = max(1, 2_000_000 // m)
        for s in range(0, len(O), step):
            o = O[s:s + step, None, :]
            d = D[s:s + step, None, :]
            den = _cross2(d, self.r[None])
            qp = self.p[None] - o
            ok = den != 0
            dsafe = np.where(ok, den, 1.0)
            t = _cross2(qp, self.r[None]) / dsafe
            u = _cross2(qp, d) / dsafe
            hit = ok & (t >= 0) & (t <= 1) & (u >= 0) & (u <= 1)
            out[s:s + step] = hit.any(axis=1)
        return out


class SegmentCaster:
    """Occlusion of many segments by a shape's boundary; built once, queried often.

    Parameters
    ----------
    V : (n, 3) or (n, 2) float
    F : (f, 3) int
        3D: the surface triangles. 2D: the triangles of the shape; its boundary
        edges are what blocks segments.
    backend : {"auto", "embree", "numpy"}
        3D only (2D always uses NumPy). ``"auto"``: Embree when ``embreex`` is
        installed, else the NumPy BVH.

    Attributes
    ----------
    backend : str
        The backend in use: ``"embree"``, ``"numpy"`` or ``"numpy-2d"``.
    """

    def __init__(self, V, F, *, backend: RayBackend = "auto"):
        V = np.asarray(V, dtype=float)
        F = np.asarray(F, dtype=np.int64)
        if backend not in RAY_BACKENDS:
            raise ValueError(f"backend must be one of {', '.join(map(repr, RAY_BACKENDS))}, "
                             f"got {backend!r}")
        if V.shape[1] == 2:
            self._impl = _Edges2D(V, F)
            self.backend = "numpy-2d"
            return
        if backend == "auto":
            backend = "embree" if embree_available() else "numpy"
        self._impl = _EmbreeScene(V, F) if backend == "embree" else _TriangleBVH(V, F)
        self.backend = backend

    def occluded(self, O, D) -> np.ndarray:
        """Whether each segment ``O[k] + t D[k]``, ``t in [0, 1]``, crosses the boundary.

        Parameters
        ----------
        O, D : (k, d) float

        Returns
        -------
        (k,) bool
        """
        O = np.asarray(O, dtype=float)
        D = np.asarray(D, dtype=float)
        if len(O) == 0:
            return np.zeros(0, dtype=bool)
        return self._impl.occluded(O, D)
