"""The builtin 2D quality mesher: Ruppert's Delaunay refinement, in batches.

Ruppert (1995), "A Delaunay refinement algorithm for quality 2-dimensional mesh
generation", with Shewchuk's (2002) "concentric shells" splitting and his rule of
leaving alone triangles whose small angle is an input angle, and Üngör's (2004)
off-centres instead of circumcentres where they are nearer. Each round rebuilds the
(unconstrained) Delaunay triangulation with ``scipy.spatial.Delaunay`` and then
either splits every encroached segment (one whose diametral circle holds a point:
so every segment ends up a Delaunay edge, the mesh is *conforming*) or inserts the
circumcentres of a well-separated subset of the bad triangles. About as many
vertices as Triangle, 3 to 100 times slower (one Qhull call per round, 10 to 60
rounds), pure NumPy/SciPy: fine for the few thousand triangles a BBW solve wants.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
from scipy.sparse import coo_array
from scipy.sparse.csgraph import connected_components
from scipy.spatial import Delaunay, cKDTree

from ._geometry import circumcenters, points_in_loops, triangle_angles, triangle_areas
from ._pslg import PSLG

MAX_ROUNDS = 400
SEPARATION = 1.0  # in circumradii; measured: 0.5 gives ~25% more points, 1.5 no fewer


def _edge_keys(a: np.ndarray, b: np.ndarray, n: int) -> np.ndarray:
    return np.minimum(a, b) * n + np.maximum(a, b)


def _split_points(pslg: PSLG, P, S, seg_bone, seg_t, apex, k):
    """Split points for segments ``k``: concentric shells around an apex, else midpoints."""
    p0, p1 = P[S[k, 0]], P[S[k, 1]]
    L = np.linalg.norm(p1 - p0, axis=1)
    a0, a1 = apex[S[k, 0]], apex[S[k, 1]]
    # One end an apex: split at the power of two in [L/3, 2L/3] from it (Shewchuk's
    # shells), so that splits around a small input angle stay at equal distances.
    shell = 2.0 ** np.floor(np.log2(2.0 * L / 3.0)) / L
    f = np.where(a0 & ~a1, shell, np.where(a1 & ~a0, 1.0 - shell, 0.5))
    bone = seg_bone[k]
    t = seg_t[k, 0] + f * (seg_t[k, 1] - seg_t[k, 0])
    X = p0 + f[:, None] * (p1 - p0)
    on = bone >= 0
    # Points on bones are computed from the bone, a + t (b - a), exactly as the samples.
    X[on] = pslg.A[bone[on]] + t[on, None] * (pslg.B[bone[on]] - pslg.A[bone[on]])
    return X, np.where(on, t, np.nan)


def refine(pslg: PSLG, *, min_angle: float, max_area: float | None,
           max_points: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Quality conforming Delaunay mesh of ``pslg``.

    Returns ``(V, F, point_bone, point_t)``; ``V`` starts with ``pslg.P`` unchanged.
    """
    P = pslg.P.copy()
    S = pslg.S.copy()
    seg_bone = pslg.seg_bone.copy()
    seg_t = pslg.seg_t.copy()
    seg_root = np.arange(S.shape[0])  # the input segment a piece came from
    root_ends = pslg.S.copy()
    apex = pslg.apex.copy()
    pb, pt = pslg.point_bone.copy(), pslg.point_t.copy()
    root = np.full(P.shape[0], -1, dtype=np.int64)  # input segment a Steiner point lies on
    cos_min = math.cos(min_angle)
    done = False
    for _ in range(MAX_ROUNDS):
        n = P.shape[0]
        tri = Delaunay(P)
        T = tri.simplices.astype(np.int64)
        # Half-edges (a, b) of every triangle with the vertex opposite.
        ha = np.concatenate([T[:, 1], T[:, 2], T[:, 0]])
        hb = np.concatenate([T[:, 2], T[:, 0], T[:, 1]])
        ho = np.concatenate([T[:, 0], T[:, 1], T[:, 2]])
        key = _edge_keys(ha, hb, n)
        order = np.argsort(key, kind="stable")
        skey, sopp = key[order], ho[order]
        seg_key = _edge_keys(S[:, 0], S[:, 1], n)
        lo = np.searchsorted(skey, seg_key, "left")
        hi = np.searchsorted(skey, seg_key, "right")
        missing = hi == lo
        enc = missing.copy()
        p0, p1 = P[S[:, 0]], P[S[:, 1]]
        for off in (0, 1):
            has = (hi - lo) > off
            o = sopp[np.minimum(lo + off, skey.size - 1)]
            # Encroached: the opposite vertex sees the segment at an angle > 90 degrees.
            d = np.einsum("ij,ij->i", p0 - P[o], p1 - P[o])
            enc |= has & (d < 0)
        if enc.any():
            S, seg_bone, seg_t, seg_root, P, pb, pt, apex, root = _split(
                pslg, np.flatnonzero(enc), S, seg_bone, seg_t, seg_root, P, pb, pt, apex, root)
            continue
        # Every segment is a Delaunay edge now: label the regions they cut out.
        inside = _inside_triangles(tri, T, seg_key, n, pslg.polygons)
        if len(P) > max_points:
            break
        Ti = T[inside]
        ang = triangle_angles(P, Ti)
        area = triangle_areas(P, Ti)
        small = ang.min(axis=1)
        bad = np.cos(small) > cos_min  # angle < min_angle, compared without rounding noise
        bad &= ~_input_angle(Ti, ang, S, seg_key, n, P, root, root_ends, apex)
        if max_area is not None:
            bad |= np.abs(area) > max_area
        if not bad.any():
            done = True
            break
        Tb = Ti[bad]
        C, R2 = circumcenters(P[Tb])
        R = np.sqrt(R2)
        _off_centres(P[Tb], ang[bad], C, min_angle)
        # Circumcentres that encroach a segment split it instead (Ruppert).
        mid = (P[S[:, 0]] + P[S[:, 1]]) / 2
        rad = np.linalg.norm(P[S[:, 1]] - P[S[:, 0]], axis=1) / 2
        pairs = cKDTree(C).sparse_distance_matrix(cKDTree(mid), float(rad.max()),
                                                  output_type="ndarray")
        ci, sj = pairs["i"], pairs["j"]
        hit = pairs["v"] < rad[sj] * (1 - 1e-12)
        enc_segs = np.unique(sj[hit])
        blocked = np.zeros(C.shape[0], dtype=bool)
        blocked[ci[hit]] = True
        # With no segment encroached, circumcentres lie inside the domain (Ruppert's
        # lemma); one outside through rounding is replaced by the centroid.
        outside = ~blocked & ~points_in_loops(C, pslg.polygons)
        C[outside] = P[Tb[outside]].mean(axis=1)
        # A well-separated subset, worst triangles first.
        cand = np.flatnonzero(~blocked)
        pri = cand[np.argsort(small[bad][cand], kind="stable")]
        chosen = _separated(C, R, pri)
        if enc_segs.size == 0 and chosen.size == 0:
            done = True
            break
        if enc_segs.size:
            S, seg_bone, seg_t, seg_root, P, pb, pt, apex, root = _split(
                pslg, enc_segs, S, seg_bone, seg_t, seg_root, P, pb, pt, apex, root)
            continue
        P = np.vstack([P, C[chosen]])
        pb = np.concatenate([pb, np.full(chosen.size, -1)])
        pt = np.concatenate([pt, np.full(chosen.size, np.nan)])
        apex = np.concatenate([apex, np.zeros(chosen.size, dtype=bool)])
        root = np.concatenate([root, np.full(chosen.size, -1)])
    if not done:
        warnings.warn(f"triangulate_2d: the builtin mesher stopped at {P.shape[0]} points "
                      "before reaching the requested quality; lower min_angle, raise "
                      "max_area or install the 'triangle' extra", UserWarning, stacklevel=3)
        tri = Delaunay(P)
        T = tri.simplices.astype(np.int64)
        inside = _inside_triangles(tri, T, _edge_keys(S[:, 0], S[:, 1], P.shape[0]),
                                   P.shape[0], pslg.polygons)
    F = T[inside]
    return P, F, pb, pt


def _split(pslg, k, S, seg_bone, seg_t, seg_root, P, pb, pt, apex, root):
    X, t = _split_points(pslg, P, S, seg_bone, seg_t, apex, k)
    new = P.shape[0] + np.arange(k.size)
    S2 = np.stack([new, S[k, 1]], axis=1)
    seg_t2 = np.stack([t, seg_t[k, 1]], axis=1)  # t is NaN on outline segments
    seg_t = seg_t.copy()
    seg_t[k, 1] = t
    S = S.copy()
    S[k, 1] = new
    return (np.vstack([S, S2]), np.concatenate([seg_bone, seg_bone[k]]),
            np.vstack([seg_t, seg_t2]), np.concatenate([seg_root, seg_root[k]]),
            np.vstack([P, X]), np.concatenate([pb, seg_bone[k]]), np.concatenate([pt, t]),
            np.concatenate([apex, np.zeros(k.size, dtype=bool)]),
            np.concatenate([root, seg_root[k]]))


def _inside_triangles(tri, T, seg_key, n, polygons) -> np.ndarray:
    """Triangles inside the outline: regions between segments, one parity test each."""
    nb = tri.neighbors
    t = np.repeat(np.arange(T.shape[0]), 3)
    u = nb.ravel()
    # neighbors[:, k] is across the edge opposite vertex k.
    a = T[:, [1, 2, 0]].ravel()
    b = T[:, [2, 0, 1]].ravel()
    cut = np.isin(_edge_keys(a, b, n), seg_key)
    keep = (u >= 0) & ~cut
    G = coo_array((np.ones(int(keep.sum())), (t[keep], u[keep])), shape=(T.shape[0],) * 2)
    _, label = connected_components(G, directed=False)
    first = np.unique(label, return_index=True)[1]
    rep = tri.points[T[first]].mean(axis=1)
    comp_in = points_in_loops(rep, polygons)
    # Qhull may close a straight stretch of the convex hull with a flat triangle.
    P = tri.points
    area = np.abs(triangle_areas(P, T))
    ext = P.max(axis=0) - P.min(axis=0)
    return comp_in[label] & (area > 1e-14 * float(ext @ ext))


def _input_angle(Ti, ang, S, seg_key, n, P, root, root_ends, apex) -> np.ndarray:
    """Bad triangles to leave alone because their small angle comes from the input.

    Either both edges at the smallest angle are segments (an input angle, which no
    refinement can widen), or the shortest edge joins two points on different input
    segments at the same distance from a shared apex (the triangle that the shells
    leave inside a small input angle).
    """
    k = np.argmin(ang, axis=1)
    r = np.arange(Ti.shape[0])
    v = Ti[r, k]
    w1, w2 = Ti[r, (k + 1) % 3], Ti[r, (k + 2) % 3]
    e1 = np.isin(_edge_keys(v, w1, n), seg_key)
    e2 = np.isin(_edge_keys(v, w2, n), seg_key)
    skip = e1 & e2
    # The shortest edge is opposite the smallest angle: (w1, w2).
    r1, r2 = root[w1], root[w2]
    both = (r1 >= 0) & (r2 >= 0) & (r1 != r2)
    if both.any():
        ends1, ends2 = root_ends[np.maximum(r1, 0)], root_ends[np.maximum(r2, 0)]
        shared = np.where((ends1[:, 0] == ends2[:, 0]) | (ends1[:, 0] == ends2[:, 1]),
                          ends1[:, 0], np.where((ends1[:, 1] == ends2[:, 0])
                                                | (ends1[:, 1] == ends2[:, 1]), ends1[:, 1], -1))
        ok = both & (shared >= 0)
        ok &= apex[np.maximum(shared, 0)]
        d1 = np.linalg.norm(P[w1] - P[np.maximum(shared, 0)], axis=1)
        d2 = np.linalg.norm(P[w2] - P[np.maximum(shared, 0)], axis=1)
        skip |= ok & (np.abs(d1 - d2) <= 1e-6 * np.maximum(d1, d2))
    return skip


def _separated(C: np.ndarray, R: np.ndarray, order: np.ndarray) -> np.ndarray:
    """The greedy subset of ``C[order]`` (best first): a point is taken unless a point
    taken before it lies within ``SEPARATION * R`` (its triangle's circumradius), so
    one round's insertions do not crowd each other.

    Computed in rounds over the conflict pairs rather than point by point: a point is
    decided once every better point near it is.
    """
    if order.size == 0:
        return order
    X, r = C[order], R[order] * SEPARATION
    pairs = cKDTree(X).query_pairs(float(r.max()), output_type="ndarray")
    if pairs.size == 0:
        return order
    i, j = pairs[:, 0], pairs[:, 1]  # i < j: i ranks better
    near = np.linalg.norm(X[i] - X[j], axis=1) < r[j]
    i, j = i[near], j[near]
    state = np.zeros(order.size, dtype=np.int8)  # 0 undecided, 1 taken, -1 left out
    while np.any(state == 0):
        waiting = np.zeros(order.size, dtype=bool)
        waiting[j[state[i] >= 0]] = True  # a better point is taken or undecided
        state[(state == 0) & ~waiting] = 1
        out = np.zeros(order.size, dtype=bool)
        out[j[state[i] == 1]] = True
        state[(state == 0) & out] = -1
    return order[state == 1]


def _off_centres(Pt: np.ndarray, ang: np.ndarray, C: np.ndarray, min_angle: float) -> None:
    """Replace circumcentres by off-centres where those are nearer (in place).

    Ungor (2004), as Triangle does: for a skinny triangle with shortest edge pq, the
    point on pq's bisector that makes a triangle with pq whose apex angle is about
    ``min_angle`` (Triangle's constant 0.475 rather than 0.5), when that is closer to
    pq than the circumcentre. Fewer, better placed Steiner points.
    """
    if min_angle <= 0:
        return
    k = np.argmin(ang, axis=1)  # the shortest edge is opposite the smallest angle
    r = np.arange(Pt.shape[0])
    p, q = Pt[r, (k + 1) % 3], Pt[r, (k + 2) % 3]
    m = (p + q) / 2
    to_c = C - m
    dc = np.linalg.norm(to_c, axis=1)
    d = 0.475 * np.linalg.norm(q - p, axis=1) / math.tan(min_angle / 2)
    use = (d < dc) & (dc > 0)
    C[use] = m[use] + (d[use] / dc[use])[:, None] * to_c[use]
