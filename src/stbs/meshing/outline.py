"""2D outlines: a mesh's boundary loops, polygon lists, Triangle ``.poly`` files, images.

An *outline* is a set of closed polygons read with the even-odd rule: a point is
inside the shape when a ray from it crosses the polygons an odd number of times.
So holes (and islands inside holes) need no labels and no particular orientation;
:func:`outline_from_image` still returns outer loops counter-clockwise and holes
clockwise, the usual convention.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from .. import _checks
from ..geometry import boundary_loops
from ._geometry import (
    REL_TOL,
    cycles,
    orient2d,
    points_in_loops,
    scale_of,
    segments_intersect,
    signed_area,
    triangle_areas,
)
from ._samples import fmt_point

__all__ = ["outline_from_image"]


# ----------------------------------------------------------------------------- normalisation


@dataclass
class Outline:
    """Points and loops of an outline, as the 2D mesher consumes them.

    ``P[:n_input]`` are the input points in input order; ``loops`` index into ``P``.
    ``mesh`` is True when the points came from a mesh (all of its vertices, interior
    ones included).
    """

    P: np.ndarray
    loops: list[np.ndarray]
    mesh: bool

    @property
    def segments(self) -> np.ndarray:
        return np.concatenate([np.stack([L, np.roll(L, -1)], axis=1) for L in self.loops])

    def polygons(self) -> list[np.ndarray]:
        return [self.P[L] for L in self.loops]


def _is_mesh_pair(outline) -> bool:
    if not isinstance(outline, tuple) or len(outline) != 2:
        return False
    F = np.asarray(outline[1])
    return F.ndim == 2 and F.shape[1:] == (3,) and F.dtype.kind in "iu"


def as_outline(outline) -> Outline:
    """Validate an outline given as a :class:`stbs.io.Mesh`, a tuple ``(V, F)``, one
    polygon (k, 2) or a sequence of polygons; see :func:`stbs.meshing.triangulate_2d`."""
    if hasattr(outline, "V") and hasattr(outline, "F") and not isinstance(outline, tuple):
        # a stbs.io.Mesh (or any object with V and F)
        if outline.F is None:
            raise ValueError("outline: the Mesh has no triangles (F is None); give a 2-D "
                             "triangle mesh or a list of polygons")
        return _mesh_outline(outline.V, outline.F)
    if _is_mesh_pair(outline):
        return _mesh_outline(*outline)
    if isinstance(outline, np.ndarray) and outline.ndim == 2:
        polys = [outline]
    elif isinstance(outline, (list, tuple)) and len(outline) > 0:
        polys = list(outline)
    else:
        raise ValueError("outline must be a Mesh, a tuple (V, F), a (k, 2) polygon or a "
                         f"non-empty list of polygons, got {type(outline).__name__}")
    loops, pts, n = [], [], 0
    for i, poly in enumerate(polys):
        P = _checks.real_array(f"outline polygon {i}", poly, ndim=2)
        if P.shape[1] != 2:
            raise ValueError(f"outline polygon {i} must have shape (k, 2) (2-D points), got "
                             f"{P.shape}; a 2-D mesh needs a 2-D outline")
        if P.shape[0] > 1 and np.array_equal(P[0], P[-1]):
            P = P[:-1]  # a closing repeat of the first point
        if P.shape[0] < 3:
            raise ValueError(f"outline polygon {i} must have at least 3 distinct vertices, "
                             f"got {P.shape[0]}")
        pts.append(P)
        loops.append(np.arange(n, n + P.shape[0]))
        n += P.shape[0]
    out = Outline(np.vstack(pts), loops, mesh=False)
    check_outline(out)
    return out


def _mesh_outline(V, F) -> Outline:
    V = _checks.real_array("outline V", V, ndim=2)
    if V.shape[1] != 2:
        raise ValueError(f"outline V must have shape (n, 2) (a 2-D mesh), got {V.shape}; "
                         "read a planar file with stbs.io.read_mesh(path, dim=2), or use "
                         "tetrahedralize for a 3-D surface")
    F = _checks.index_array("outline F", F, ndim=2, shape=(None, 3))
    n = V.shape[0]
    if F.shape[0] == 0:
        raise ValueError("outline F must hold at least one triangle, got shape (0, 3)")
    if F.min() < 0 or F.max() >= n:
        bad = int(F.min()) if F.min() < 0 else int(F.max())
        raise ValueError(f"outline F must hold vertex indices in 0..{n - 1}, got {bad}")
    rep = (F[:, 0] == F[:, 1]) | (F[:, 1] == F[:, 2]) | (F[:, 2] == F[:, 0])
    area = np.abs(triangle_areas(V, F))
    tiny = rep | (area <= REL_TOL * scale_of(V) ** 2)
    if tiny.any():
        k = int(np.argmax(tiny))
        raise ValueError(f"outline F: triangle {k} {F[k].tolist()} is degenerate (zero area); "
                         f"{int(tiny.sum())} such triangles — remove them first")
    used = np.zeros(n, dtype=bool)
    used[F.ravel()] = True
    if not used.all():
        k = int(np.argmin(used))
        raise ValueError(f"outline V: {int((~used).sum())} vertices are in no triangle (e.g. "
                         f"vertex {k}); all vertices of a mesh outline are kept, so remove "
                         "them, or pass boundary polygons instead")
    loops = boundary_loops(F)
    if not loops:
        raise ValueError("outline F: the mesh has no boundary edges, so it has no outline")
    out = Outline(V, loops, mesh=True)
    check_outline(out)
    return out


def check_outline(out: Outline) -> None:
    """Raise ValueError for coincident points, zero-area or intersecting polygons."""
    P = out.P
    scale = scale_of(P)
    tol = REL_TOL * scale
    pairs = cKDTree(P).query_pairs(tol, output_type="ndarray")
    if pairs.size:
        a, b = pairs[0]
        raise ValueError(f"outline: points {a} and {b} coincide at {fmt_point(P[a])}; "
                         "remove duplicate points")
    for i, L in enumerate(out.loops):
        if abs(signed_area(P[L])) <= tol * scale:
            raise ValueError(f"outline polygon {i} has zero area; outlines must enclose area")
    S = out.segments
    A, B = P[S[:, 0]], P[S[:, 1]]
    L = np.linalg.norm(B - A, axis=1)
    cand = cKDTree((A + B) / 2).query_pairs(float(L.max()) * (1 + 1e-9), output_type="ndarray")
    if cand.size == 0:
        return
    s, t = cand[:, 0], cand[:, 1]
    share = (S[s, :, None] == S[t, None, :]).any(axis=(1, 2))
    hit = np.zeros(s.size, dtype=bool)
    ns = ~share
    hit[ns] = segments_intersect(A[s[ns]], B[s[ns]], A[t[ns]], B[t[ns]], tol=tol)
    # Adjacent segments meet at their shared point; they are bad only when they fold back.
    sh = np.flatnonzero(share)
    if sh.size:
        ss, tt = S[s[sh]], S[t[sh]]
        common = np.where((ss[:, 0] == tt[:, 0]) | (ss[:, 0] == tt[:, 1]), ss[:, 0], ss[:, 1])
        u = np.where(ss[:, 0] == common, ss[:, 1], ss[:, 0])
        w = np.where(tt[:, 0] == common, tt[:, 1], tt[:, 0])
        q, pu, pw = P[common], P[u], P[w]
        du, dw = pu - q, pw - q
        flat = np.abs(orient2d(q, pu, pw)) <= \
            REL_TOL * np.linalg.norm(du, axis=1) * np.linalg.norm(dw, axis=1)
        hit[sh] = flat & (np.einsum("ij,ij->i", du, dw) > 0)
    if hit.any():
        k = int(np.argmax(hit))
        sa, sb = S[s[k]], S[t[k]]
        where = (P[sa[0]] + P[sa[1]] + P[sb[0]] + P[sb[1]]) / 4
        raise ValueError(
            f"outline: boundary segments {sa.tolist()} and {sb.tolist()} intersect near "
            f"{fmt_point(where)}; the outline must be simple, non-overlapping polygons"
            + (" (the mesh overlaps itself)" if out.mesh else ""))


# ----------------------------------------------------------------------------- images

# Marching squares: for each corner-inside pattern (bit k = corner k inside; corners
# 0 top-left, 1 top-right, 2 bottom-right, 3 bottom-left), the pairs of cell edges
# (0 top, 1 right, 2 bottom, 3 left) joined by a contour segment. The saddles 5 and
# 10 have two variants, chosen by the value at the cell centre.
_CASES = {
    1: [(3, 0)], 2: [(0, 1)], 3: [(3, 1)], 4: [(1, 2)], 6: [(0, 2)], 7: [(3, 2)],
    8: [(2, 3)], 9: [(0, 2)], 11: [(1, 2)], 12: [(1, 3)], 13: [(0, 1)], 14: [(3, 0)],
}
_SADDLE = {  # (centre outside, centre inside)
    5: ([(3, 0), (1, 2)], [(0, 1), (3, 2)]),
    10: ([(0, 1), (2, 3)], [(3, 0), (1, 2)]),
}


def _field(image, *, alpha: bool) -> np.ndarray:
    a = np.asarray(image)
    if a.ndim == 3 and a.shape[2] in (3, 4):
        pass
    elif a.ndim != 2:
        raise ValueError(f"image must have shape (H, W), (H, W, 3) or (H, W, 4), got {a.shape}")
    if a.dtype == bool:
        f = a.astype(np.float64)
    elif a.dtype.kind == "u":
        f = a.astype(np.float64) / np.iinfo(a.dtype).max
    elif a.dtype.kind in "fi":
        f = a.astype(np.float64)
    else:
        raise ValueError(f"image must be a bool, integer or float array, got dtype {a.dtype}")
    if not np.all(np.isfinite(f)):
        raise ValueError("image must be finite, got NaN or inf values")
    if f.ndim == 3:
        if alpha and f.shape[2] == 4:
            f = f[..., 3]
        else:  # Rec. 601 luma of the colour channels
            f = f[..., :3] @ np.array([0.299, 0.587, 0.114])
    if min(f.shape) < 1:
        raise ValueError(f"image must have at least one pixel, got shape {a.shape}")
    return f


def _march(g: np.ndarray) -> list[np.ndarray]:
    """Closed contours of ``g > 0`` as (k, 2) arrays of (row, col) positions.

    ``g`` must be negative on its border, so every contour closes.
    """
    H, W = g.shape
    inside = g > 0
    c0, c1, c2, c3 = inside[:-1, :-1], inside[:-1, 1:], inside[1:, 1:], inside[1:, :-1]
    case = c0 * 1 + c1 * 2 + c2 * 4 + c3 * 8
    centre = (g[:-1, :-1] + g[:-1, 1:] + g[1:, 1:] + g[1:, :-1]) > 0
    ci, cj = np.nonzero((case != 0) & (case != 15))
    cs, cc = case[ci, cj], centre[ci, cj]
    # Edge-point ids: horizontal edge (i, j)-(i, j+1) -> i*(W-1)+j; vertical (i, j)-(i+1, j)
    # -> nh + i*W + j.
    nh = H * (W - 1)

    def edge_id(i, j, e):
        return np.select([e == 0, e == 1, e == 2, e == 3],
                         [i * (W - 1) + j, nh + i * W + j + 1, (i + 1) * (W - 1) + j,
                          nh + i * W + j])

    seg_a, seg_b, seg_i, seg_j = [], [], [], []
    variants = [(k, cs == k, pairs) for k, pairs in _CASES.items()]
    variants += [(k, (cs == k) & (cc == flag), pairs) for k, (out_pairs, in_pairs)
                 in _SADDLE.items() for flag, pairs in ((False, out_pairs), (True, in_pairs))]
    for _, m, pairs in variants:
        for ea, eb in pairs:
            seg_a.append(edge_id(ci[m], cj[m], np.full(m.sum(), ea)))
            seg_b.append(edge_id(ci[m], cj[m], np.full(m.sum(), eb)))
            seg_i.append(ci[m])
            seg_j.append(cj[m])
    a = np.concatenate(seg_a)
    b = np.concatenate(seg_b)
    if a.size == 0:
        return []
    ids = np.unique(np.concatenate([a, b]))
    # Positions of the edge points, linearly interpolated where g crosses 0; kept at
    # least 5% of a pixel from grid points so that separate contours never touch.
    horiz = ids < nh
    i = np.where(horiz, ids // (W - 1), (ids - nh) // W)
    j = np.where(horiz, ids % (W - 1), (ids - nh) % W)
    i2, j2 = np.where(horiz, i, i + 1), np.where(horiz, j + 1, j)
    ga, gb = g[i, j], g[i2, j2]
    s = np.clip(ga / (ga - gb), 0.05, 0.95)
    pos = np.stack([i + s * (i2 - i), j + s * (j2 - j)], axis=1)
    ia, ib = np.searchsorted(ids, a), np.searchsorted(ids, b)
    # Direct every segment with the inside on its left: the corner of its cell nearest
    # to it on the left must be inside (nearest, so a saddle's far corner never counts).
    cell_i, cell_j = np.concatenate(seg_i), np.concatenate(seg_j)
    P, Q = pos[ia], pos[ib]
    corners = np.array([[0, 0], [0, 1], [1, 1], [1, 0]])
    best = np.full(a.size, np.inf)
    left_inside = np.zeros(a.size, dtype=bool)
    for di, dj in corners:
        C = np.stack([cell_i + di, cell_j + dj], axis=1).astype(np.float64)
        cross = (Q[:, 0] - P[:, 0]) * (C[:, 1] - P[:, 1]) - (Q[:, 1] - P[:, 1]) * (C[:, 0]
                                                                                  - P[:, 0])
        closer = (cross > 0) & (cross < best)
        best[closer] = cross[closer]
        left_inside[closer] = inside[cell_i[closer] + di, cell_j[closer] + dj]
    src = np.where(left_inside, ia, ib)
    dst = np.where(left_inside, ib, ia)
    if np.unique(src).size != ids.size:  # pragma: no cover - a broken case table
        raise RuntimeError("marching squares: contour segments do not chain (internal error)")
    succ = np.empty(ids.size, dtype=np.int64)
    succ[src] = dst
    return [pos[c] for c in cycles(succ)]


def _douglas_peucker(P: np.ndarray, tol: float) -> np.ndarray:
    """Simplify a closed polygon: keep the vertices needed to stay within ``tol``."""
    n = P.shape[0]
    if n <= 4 or tol <= 0:
        return P
    far = int(np.argmax(np.linalg.norm(P - P[0], axis=1)))
    keep = np.zeros(n, dtype=bool)
    keep[[0, far]] = True
    stack = [(0, far), (far, n)]
    while stack:
        s, e = stack.pop()
        if e - s < 2:
            continue
        a, b = P[s], P[e % n]
        Q = P[s + 1:e]
        ab = b - a
        L = np.linalg.norm(ab)
        if L > 0:
            d = np.abs(ab[0] * (Q[:, 1] - a[1]) - ab[1] * (Q[:, 0] - a[0])) / L
        else:
            d = np.linalg.norm(Q - a, axis=1)
        k = int(np.argmax(d))
        if d[k] > tol:
            m = s + 1 + k
            keep[m] = True
            stack += [(s, m), (m, e)]
    out = P[keep]
    return out if out.shape[0] >= 3 else P


def outline_from_image(image, *, threshold: float = 0.5, alpha: bool = True,
                       invert: bool = False, tolerance: float = 0.5,
                       min_area: float = 4.0) -> list[np.ndarray]:
    """Trace the shape in an image into polygons (marching squares + Douglas–Peucker).

    Parameters
    ----------
    image : (H, W) or (H, W, 3) or (H, W, 4) array
        bool, unsigned integers (scaled to [0, 1] by their maximum) or floats in [0, 1].
    threshold : float, keyword-only
        The shape is where the traced value exceeds ``threshold`` (0.5 by default).
        Contours are interpolated at this level, so anti-aliased edges give
        sub-pixel positions.
    alpha : bool, keyword-only
        For an RGBA image, trace the alpha channel (default); otherwise, and for RGB
        images, trace the luma (0.299 R + 0.587 G + 0.114 B).
    invert : bool, keyword-only
        Trace where the value is *below* the threshold (a dark shape on a light
        background).
    tolerance : float, keyword-only
        Douglas–Peucker tolerance in pixels (0 keeps every contour point). A loop
        that simplification would make cross itself or another loop is simplified
        with a smaller tolerance instead.
    min_area : float, keyword-only
        Drop loops enclosing less than this many square pixels (specks and pinholes).

    Returns
    -------
    list of (k, 2) float64
        Closed polygons (not repeating the first point) in pixel units with the
        y axis up: pixel ``image[r, c]`` is centred at ``(x, y) = (c, H - 1 - r)``.
        Outer boundaries are counter-clockwise, holes clockwise; the list is
        ordered by decreasing area. Empty when the image holds no shape.

    Examples
    --------
    >>> import numpy as np
    >>> yy, xx = np.mgrid[:64, :64]
    >>> disc = (xx - 32) ** 2 + (yy - 32) ** 2 < 20 ** 2
    >>> [p.shape[1] for p in outline_from_image(disc)]
    [2]
    """
    f = _field(image, alpha=alpha)
    threshold = float(threshold)
    if not np.isfinite(threshold):
        raise ValueError(f"threshold must be finite, got {threshold}")
    tolerance, min_area = float(tolerance), float(min_area)
    if not tolerance >= 0:
        raise ValueError(f"tolerance must be >= 0 (pixels), got {tolerance}")
    if not min_area >= 0:
        raise ValueError(f"min_area must be >= 0 (square pixels), got {min_area}")
    g = (threshold - f) if invert else (f - threshold)
    # The border is background (0, or 1 when inverted): every contour closes.
    border = (threshold - max(float(f.max()), 1.0)) if invert else (min(float(f.min()), 0.0)
                                                                    - threshold)
    if not border < 0:
        want = "below the background value 1 (invert=True)" if invert else \
            "above the background value 0"
        raise ValueError(f"threshold must lie {want}, got {threshold}")
    H = f.shape[0]
    g = np.pad(g, 1, constant_values=border)
    raw = []
    for L in _march(g):
        xy = np.stack([L[:, 1] - 1.0, (H - 1) - (L[:, 0] - 1.0)], axis=1)
        a = signed_area(xy)
        if abs(a) >= max(min_area, 1e-12):
            raw.append(xy)
    if not raw:
        return []
    # Nesting depth decides orientation: even depth is an outer boundary (ccw).
    depth = np.zeros(len(raw), dtype=np.int64)
    for i, P in enumerate(raw):
        for k, Q in enumerate(raw):
            if k != i and points_in_loops(P[:1], [Q])[0]:
                depth[i] += 1
    polys = []
    for P, d in zip(raw, depth, strict=True):
        ccw = signed_area(P) > 0
        polys.append(P if ccw == (d % 2 == 0) else P[::-1].copy())
    simple = [_douglas_peucker(P, tolerance) for P in polys]
    for it in range(8):
        bad = _crossing_loops(simple)
        if not bad:
            break
        for i in bad:  # halve the tolerance; the raw contours (last resort) are simple
            simple[i] = _douglas_peucker(polys[i], tolerance * 0.5 ** (it + 1)) \
                if it < 7 else polys[i]
    order = np.argsort([-abs(signed_area(P)) for P in simple], kind="stable")
    return [simple[i] for i in order]


def _crossing_loops(polys: list[np.ndarray]) -> list[int]:
    """Indices of polygons involved in an intersection (themselves or another)."""
    out = Outline(np.vstack(polys), [], mesh=False)
    n = 0
    for P in polys:
        out.loops.append(np.arange(n, n + P.shape[0]))
        n += P.shape[0]
    which = np.repeat(np.arange(len(polys)), [P.shape[0] for P in polys])
    bad: set[int] = set()
    S = out.segments
    A, B = out.P[S[:, 0]], out.P[S[:, 1]]
    L = np.linalg.norm(B - A, axis=1)
    cand = cKDTree((A + B) / 2).query_pairs(float(L.max()) * (1 + 1e-9), output_type="ndarray")
    if cand.size == 0:
        return []
    s, t = cand[:, 0], cand[:, 1]
    share = (S[s, :, None] == S[t, None, :]).any(axis=(1, 2))
    s, t = s[~share], t[~share]
    hit = segments_intersect(A[s], B[s], A[t], B[t])
    for k in np.flatnonzero(hit):
        bad.add(int(which[S[s[k], 0]]))
        bad.add(int(which[S[t[k], 0]]))
    return sorted(bad)
