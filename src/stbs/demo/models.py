"""Built-in models for the demo, generated in code: arm, leg, torso, character, 2D shapes.

The 3D models are zero level sets of signed-distance functions (capsules and round
cones blended with a smooth minimum), meshed by :func:`implicit_surface`: marching
tetrahedra on a regular grid, then a few steps of tangential relaxation that move
the vertices back onto the level set. The 2D models are outlines traced from a
sampled distance field or an image alpha mask and triangulated with their skeleton
as constrained segments (:func:`stbs.triangulate_2d`).

Every model is a :class:`Model` ``(V, F, sk, name, extra)``; characters have y up.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from .. import _checks
from ..skeleton import Skeleton

__all__ = ["Model", "MODELS", "implicit_surface", "capsule_sdf", "sphere_sdf",
           "ellipsoid_sdf", "box_sdf", "smooth_union", "arm", "leg", "torso", "character",
           "long_necked_animal_2d", "picture_2d"]


# ============================================================================ the model


@dataclass(frozen=True, eq=False)
class Model:
    """A built-in shape with its skeleton.

    Attributes
    ----------
    V : (n, 3) or (n, 2) float64
        Rest positions.
    F : (f, 3) int64
        Triangles: a closed, outward-oriented surface in 3D; counter-clockwise
        triangles of the shape in 2D, with every bone a chain of edges.
    sk : Skeleton
        Bones strictly inside the shape.
    name : str
        The model's name (the key in :data:`MODELS`).
    extra : dict
        Model-specific data, listed in each model's docstring.
    """

    V: np.ndarray
    F: np.ndarray
    sk: Skeleton
    name: str
    extra: dict = field(default_factory=dict)

    @property
    def dim(self) -> int:
        """2 or 3."""
        return int(self.V.shape[1])

    def __repr__(self) -> str:
        return (f"Model({self.name!r}, {self.V.shape[0]} vertices, {self.F.shape[0]} "
                f"triangles, {self.sk.n_bones} bones, {self.dim}-D)")


def _flag(name: str, x) -> bool:
    if not isinstance(x, (bool, np.bool_)):
        raise ValueError(f"{name} must be True or False, got {x!r}")
    return bool(x)


# ============================================================================ distance fields


def _points(P) -> np.ndarray:
    P = np.asarray(P, dtype=np.float64)
    if P.ndim < 1 or P.shape[-1] not in (2, 3):
        raise ValueError(f"P must have shape (..., 2) or (..., 3), got {P.shape}")
    return P


def sphere_sdf(P, center, r: float) -> np.ndarray:
    """Signed distance to a sphere (a disc in 2D), negative inside.

    Parameters
    ----------
    P : (..., d) float
        Query points, d = 2 or 3.
    center : (d,) float
        Centre.
    r : float
        Radius.

    Returns
    -------
    (...,) float64
    """
    P = _points(P)
    return np.linalg.norm(P - np.asarray(center, dtype=float), axis=-1) - float(r)


def capsule_sdf(P, a, b, r) -> np.ndarray:
    """Signed distance to a capsule whose radius may vary linearly (a round cone).

    The shape is the union of the balls centred on the segment ``a b`` with radius
    going linearly from ``r_a`` at ``a`` to ``r_b`` at ``b``: the convex hull of the
    two end balls. The distance is exact (Quilez's round cone, one square root per
    point).

    Parameters
    ----------
    P : (..., d) float
        Query points, d = 2 or 3.
    a, b : (d,) float
        End points of the axis.
    r : float or (2,) float
        Radius, or the radii ``(r_a, r_b)`` at ``a`` and ``b``; ``|r_a - r_b|`` must be
        less than ``|b - a|`` (otherwise one end ball holds the other).

    Returns
    -------
    (...,) float64
        Negative inside.
    """
    P = _points(P)
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    ra, rb = np.broadcast_to(np.asarray(r, dtype=float), (2,))
    ba = b - a
    l2 = float(ba @ ba)
    rr = ra - rb
    a2 = l2 - rr * rr
    if not a2 > 0:
        raise ValueError(f"r must satisfy |r_a - r_b| < |b - a| = {np.sqrt(l2):g}, got "
                         f"({ra:g}, {rb:g})")
    pa = P - a
    y = pa @ ba
    z = y - l2
    x2 = np.sum((pa * l2 - y[..., None] * ba) ** 2, axis=-1)
    y2 = y * y * l2
    z2 = z * z * l2
    k = np.sign(rr) * rr * rr * x2
    body = (np.sqrt(np.maximum(x2 * a2 / l2, 0.0)) + y * rr) / l2 - ra
    out = np.where(np.sign(y) * a2 * y2 < k, np.sqrt(x2 + y2) / l2 - ra, body)
    return np.where(np.sign(z) * a2 * z2 > k, np.sqrt(x2 + z2) / l2 - rb, out)


def ellipsoid_sdf(P, center, radii) -> np.ndarray:
    """Approximate signed distance to an axis-aligned ellipsoid (an ellipse in 2D).

    Quilez's bound ``k0 (k0 - 1) / k1`` with ``k0 = |p / r|``, ``k1 = |p / r^2|``:
    exact on the surface's zero set, close to the distance near it.

    Parameters
    ----------
    P : (..., d) float
        Query points.
    center : (d,) float
        Centre.
    radii : (d,) float
        Semi-axes, all > 0.

    Returns
    -------
    (...,) float64
    """
    P = _points(P)
    q = P - np.asarray(center, dtype=float)
    R = np.asarray(radii, dtype=float)
    k0 = np.linalg.norm(q / R, axis=-1)
    k1 = np.linalg.norm(q / (R * R), axis=-1)
    return np.where(k1 > 0, k0 * (k0 - 1.0) / np.where(k1 > 0, k1, 1.0), -R.min())


def box_sdf(P, center, half, rounding: float = 0.0) -> np.ndarray:
    """Signed distance to an axis-aligned box with rounded edges.

    Parameters
    ----------
    P : (..., d) float
        Query points.
    center : (d,) float
        Centre.
    half : (d,) float
        Half edge lengths of the box *before* rounding; the rounded box reaches
        ``half + rounding`` from the centre.
    rounding : float
        Radius of the rounded edges and corners (0: sharp).

    Returns
    -------
    (...,) float64
    """
    P = _points(P)
    q = np.abs(P - np.asarray(center, dtype=float)) - np.asarray(half, dtype=float)
    outside = np.linalg.norm(np.maximum(q, 0.0), axis=-1)
    inside = np.minimum(q.max(axis=-1), 0.0)
    return outside + inside - float(rounding)


def smooth_union(d1, d2, k: float) -> np.ndarray:
    """Polynomial smooth minimum of two distance fields (a blended union).

    ``h = clip(1/2 + (d2 - d1) / (2 k), 0, 1)``; ``d = d2 (1 - h) + d1 h - k h (1 - h)``.
    Equal to ``min(d1, d2)`` where the two differ by more than ``k``; the blend adds
    a fillet of size about ``k / 4`` where they meet.

    Parameters
    ----------
    d1, d2 : (...,) float
        Signed distances (negative inside).
    k : float
        Blend width (>= 0); 0 gives the plain union ``min(d1, d2)``.

    Returns
    -------
    (...,) float64
    """
    d1 = np.asarray(d1, dtype=float)
    d2 = np.asarray(d2, dtype=float)
    k = float(k)
    if not k >= 0:
        raise ValueError(f"k must be >= 0, got {k}")
    if k == 0:
        return np.minimum(d1, d2)
    h = np.clip(0.5 + 0.5 * (d2 - d1) / k, 0.0, 1.0)
    return d2 + (d1 - d2) * h - k * h * (1.0 - h)


def _blend(ds, k: float) -> np.ndarray:
    """Smooth union of several fields, in order."""
    out = ds[0]
    for d in ds[1:]:
        out = smooth_union(out, d, k)
    return out


# ============================================================================ marching tetrahedra

# The six tetrahedra of a cube sharing its main diagonal (Kuhn / Freudenthal): for each
# order (a, b, c) of the axes, the path 0 -> e_a -> e_a + e_b -> e_a + e_b + e_c. Every
# cube face is split along the same diagonal from both sides, so the pieces fit.
_KUHN = np.array([[[0, 0, 0], np.eye(3, dtype=int)[a], np.eye(3, dtype=int)[a]
                   + np.eye(3, dtype=int)[b], [1, 1, 1]]
                  for a, b in ((0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1))])


def _mt_table() -> tuple[np.ndarray, np.ndarray]:
    """Triangles (as pairs of tet corners, i.e. tet edges) for the 16 sign cases."""
    tri = np.zeros((16, 2, 3, 2), dtype=np.int64)
    count = np.zeros(16, dtype=np.int64)
    for code in range(16):
        inside = [v for v in range(4) if code >> v & 1]
        outside = [v for v in range(4) if not code >> v & 1]
        if len(inside) in (1, 3):
            lone, rest = (inside[0], outside) if len(inside) == 1 else (outside[0], inside)
            tri[code, 0] = [[lone, rest[0]], [lone, rest[1]], [lone, rest[2]]]
            count[code] = 1
        elif len(inside) == 2:
            (p, q), (r, s) = inside, outside
            # The quad (p r)(p s)(q s)(q r) in cyclic order, as two triangles.
            tri[code, 0] = [[p, r], [p, s], [q, s]]
            tri[code, 1] = [[p, r], [q, s], [q, r]]
            count[code] = 2
    return tri, count


_MT_TRI, _MT_COUNT = _mt_table()


def _grid_shape(lo, hi, resolution) -> tuple[np.ndarray, np.ndarray, tuple[int, int, int]]:
    lo = _checks.real_array("lo", lo, shape=(3,))
    hi = _checks.real_array("hi", hi, shape=(3,))
    if not np.all(hi > lo):
        raise ValueError(f"hi must be greater than lo on every axis, got lo={lo.tolist()}, "
                         f"hi={hi.tolist()}")
    r = np.asarray(resolution)
    if r.dtype.kind not in "iu" or r.ndim > 1 or (r.ndim == 1 and r.shape != (3,)):
        raise ValueError("resolution must be an integer >= 2 or three of them, got "
                         f"{resolution!r}")
    if np.any(r < 2):
        raise ValueError(f"resolution must be >= 2 (grid cells per axis), got {resolution!r}")
    if r.ndim == 0:
        h = float((hi - lo).max()) / int(r)
        cells = np.maximum(np.ceil((hi - lo) / h - 1e-9).astype(np.int64), 2)
        hi = lo + cells * h  # cubic cells: the box grows to a whole number of them
    else:
        cells = r.astype(np.int64)
    if np.prod(cells + 1) > 50_000_000:
        raise ValueError(f"resolution {resolution!r} asks for {int(np.prod(cells + 1))} grid "
                         "samples; at most 50 million are allowed")
    return lo, hi, (int(cells[0]), int(cells[1]), int(cells[2]))


def _eval_sdf(sdf, X: np.ndarray) -> np.ndarray:
    d = np.asarray(sdf(X), dtype=np.float64)
    if d.shape != (X.shape[0],):
        raise ValueError(f"sdf must map points (m, 3) to distances (m,), got shape {d.shape} "
                         f"for m = {X.shape[0]}")
    if not np.all(np.isfinite(d)):
        k = int(np.argmin(np.isfinite(d)))
        raise ValueError(f"sdf must return finite values, got {d[k]} at {X[k].tolist()}")
    return d


def implicit_surface(sdf: Callable[[np.ndarray], np.ndarray], lo, hi, resolution, *,
                     relax: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """Closed triangle surface of the zero level set of a signed-distance function.

    Marching tetrahedra on a regular grid: every cube is split into six tetrahedra
    around its main diagonal, the same way in every cube, so the pieces of surface
    meet without cracks; vertices are shared per grid edge. Grid values within
    ``1e-3`` cell of zero are pushed off it, so no vertex lands on a grid point
    (where several would coincide). Marching tetrahedra leaves thin triangles where
    the surface passes near a grid point; ``relax`` steps of tangential smoothing,
    each followed by a Newton step back onto the level set (and one more at the
    end), even them out without shrinking the shape. A 60^3 grid takes about 0.1 s,
    relaxation as much again for 30k vertices.

    Parameters
    ----------
    sdf : callable
        ``sdf(X)`` for points ``X`` (m, 3) float64 returns (m,) signed distances,
        negative inside. It need not be an exact distance, but should grow about
        like one across the surface (a smooth union of distances does).
    lo, hi : (3,) float
        Corners of the box sampled. The shape must lie strictly inside it: the
        function must be positive on the box's boundary.
    resolution : int or (3,) int
        Grid cells along the box's longest side (cubic cells; the box is extended
        to a whole number of cells along the others), or along each axis. At least 2.
    relax : int, keyword-only
        Steps of relaxation (default 4); 0 returns the raw marching-tetrahedra
        surface.

    Returns
    -------
    V : (n, 3) float64
        Vertices, on the zero set to within the projection's accuracy.
    F : (f, 3) int64
        Triangles, oriented outwards (counter-clockwise seen from outside). Closed
        and manifold; one component per connected piece of the shape.

    Raises
    ------
    ValueError
        Bad ``lo``/``hi``/``resolution``/``relax``, an ``sdf`` that returns the wrong
        shape or non-finite values, a shape reaching the box's boundary, or a level
        set that the grid does not resolve at all (no surface found).

    Notes
    -----
    The raw surface (``relax=0``) is the level set of the piecewise-linear
    interpolant on the tetrahedra, so it never crosses itself; on symmetric shapes
    it may hold exactly coplanar neighbouring triangles. Relaxation keeps that
    property where the grid resolves the shape; parts thinner than about two cells
    (or creases sharper than a cell) can fold, so check such surfaces with
    :func:`stbs.meshing.check_surface`. The built-in models are checked in the tests.

    Examples
    --------
    >>> import numpy as np
    >>> V, F = implicit_surface(lambda X: np.linalg.norm(X, axis=1) - 1.0,
    ...                         [-1.2] * 3, [1.2] * 3, 24)
    >>> bool(np.allclose(np.linalg.norm(V, axis=1), 1.0, atol=1e-6))
    True
    """
    if not callable(sdf):
        raise ValueError(f"sdf must be callable, got {type(sdf).__name__}")
    if isinstance(relax, bool) or not isinstance(relax, (int, np.integer)) or relax < 0:
        raise ValueError(f"relax must be an integer >= 0, got {relax!r}")
    lo, hi, cells = _grid_shape(lo, hi, resolution)
    shape = tuple(c + 1 for c in cells)
    axes = [np.linspace(lo[i], hi[i], shape[i]) for i in range(3)]
    X = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    D = _eval_sdf(sdf, X).reshape(shape)
    h = float(np.min((hi - lo) / np.array(cells)))
    boundary = np.concatenate([D[[0, -1]].ravel(), D[:, [0, -1]].ravel(),
                               D[:, :, [0, -1]].ravel()])
    if boundary.min() <= 0:
        g = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)
        onb = np.zeros(shape, dtype=bool)
        onb[[0, -1]] = onb[:, [0, -1]] = onb[:, :, [0, -1]] = True
        k = np.argwhere(onb & (D <= 0))[0]
        raise ValueError(f"sdf must be positive on the boundary of the box lo..hi (the shape "
                         f"must lie inside it), got {D[tuple(k)]:.4g} at "
                         f"{g[tuple(k)].round(4).tolist()}")
    eps = 1e-3 * h
    D = np.where(np.abs(D) < eps, np.where(D < 0, -eps, eps), D)
    V, F = _march(X, D, shape)
    if F.shape[0] == 0:
        raise ValueError("sdf has no zero level set the grid resolves (no negative values "
                         f"among the {D.size} samples); raise resolution")
    for _ in range(int(relax)):
        V = _relax_step(V, F, sdf, h)
    if relax:
        V = _project(V, sdf, h)
    return V, F


def _march(X: np.ndarray, D: np.ndarray, shape) -> tuple[np.ndarray, np.ndarray]:
    nx, ny, nz = shape
    inside = D < 0
    # Cubes with corners on both sides: the only ones the surface crosses.
    corner = [inside[dx:nx - 1 + dx, dy:ny - 1 + dy, dz:nz - 1 + dz]
              for dx, dy, dz in np.ndindex(2, 2, 2)]
    nin = np.sum(corner, axis=0)
    ijk = np.argwhere((nin > 0) & (nin < 8))
    strides = np.array([ny * nz, nz, 1])
    # (m, 6, 4) grid indices of the six tetrahedra of each active cube.
    G = ((ijk[:, None, None, :] + _KUHN[None]) @ strides).reshape(-1, 4)
    code = (inside.ravel()[G] * np.array([1, 2, 4, 8])).sum(axis=1)
    keep = _MT_COUNT[code] > 0
    G, code = G[keep], code[keep]
    tris = []
    for t in (0, 1):
        sel = _MT_COUNT[code] > t
        loc = _MT_TRI[code[sel], t]  # (m, 3, 2) tet corners
        g = np.take_along_axis(G[sel], loc.reshape(-1, 6), axis=1)
        tris.append(g.reshape(-1, 3, 2))
    E = np.concatenate(tris)  # (f, 3, 2) grid edges, one per triangle corner
    # Every vertex lies on a grid edge from an inside to an outside sample: weld per edge.
    Din = D.ravel()
    a, b = E[..., 0], E[..., 1]
    n_grid = D.size
    key = np.minimum(a, b) * n_grid + np.maximum(a, b)
    uk, inv = np.unique(key.ravel(), return_inverse=True)
    ea, eb = uk // n_grid, uk % n_grid
    da, db = Din[ea], Din[eb]
    t = (da / (da - db))[:, None]
    V = X[ea] + t * (X[eb] - X[ea])
    F = inv.reshape(-1, 3).astype(np.int64)
    # Outward: the normal points from the inside sample of an edge to the outside one.
    P = V[F]
    nrm = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
    a0, b0 = a[:, 0], b[:, 0]
    out_minus_in = np.where((Din[a0] < 0)[:, None], X[b0] - X[a0], X[a0] - X[b0])
    flip = np.einsum("ij,ij->i", nrm, out_minus_in) < 0
    F[flip] = F[flip][:, ::-1]
    return V, F


def _face_normals(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Area-weighted normals (f, 3): twice the triangles' areas in length."""
    P = V[F]
    return np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])


def _vertex_normals(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    fn = _face_normals(V, F)
    N = np.zeros_like(V)
    for k in range(3):
        np.add.at(N, F[:, k], fn)
    return N / np.maximum(np.linalg.norm(N, axis=1, keepdims=True), 1e-300)


def _relax_step(V: np.ndarray, F: np.ndarray, sdf, h: float) -> np.ndarray:
    """Move each vertex halfway to its neighbours' centroid within the tangent plane,
    then back onto the zero set by a Newton step on the distance field."""
    n = V.shape[0]
    E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])  # each edge once per way
    S = np.zeros_like(V)
    np.add.at(S, E[:, 0], V[E[:, 1]])
    deg = np.bincount(E[:, 0], minlength=n)[:, None]
    L = S / deg - V
    N = _vertex_normals(V, F)
    L -= np.einsum("ij,ij->i", L, N)[:, None] * N
    return _project(V + 0.5 * L, sdf, h)


def _project(V: np.ndarray, sdf, h: float) -> np.ndarray:
    """One Newton step towards the zero set: ``p - d(p) grad d / |grad d|^2``."""
    n = V.shape[0]
    step = 1e-4 * h
    Q = np.concatenate([V, V + [step, 0, 0], V + [0, step, 0], V + [0, 0, step]])
    d = _eval_sdf(sdf, Q).reshape(4, n)
    g = (d[1:] - d[0]).T / step  # forward differences: accurate enough for a Newton step
    g2 = np.einsum("ij,ij->i", g, g)
    ok = g2 > 1e-12
    move = np.zeros_like(V)
    move[ok] = (d[0, ok] / g2[ok])[:, None] * g[ok]
    # Never further than a cell: the field may be far from a distance in places.
    mlen = np.linalg.norm(move, axis=1, keepdims=True)
    move *= np.minimum(1.0, h / np.maximum(mlen, 1e-300))
    return V - move


# ============================================================================ 3D models


@dataclass(frozen=True)
class _Part:
    """One primitive of a blended shape: a round cone, an ellipsoid or a rounded box."""

    kind: str
    args: tuple
    k: float  # blend width into the shape built so far

    def sdf(self, X: np.ndarray) -> np.ndarray:
        if self.kind == "cone":
            a, b, ra, rb = self.args
            return capsule_sdf(X, a, b, (ra, rb))
        if self.kind == "ellipsoid":
            return ellipsoid_sdf(X, *self.args)
        return box_sdf(X, *self.args)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        if self.kind == "cone":
            a, b, ra, rb = (np.asarray(x, dtype=float) for x in self.args)
            return np.minimum(a - ra, b - rb), np.maximum(a + ra, b + rb)
        if self.kind == "ellipsoid":
            c, r = (np.asarray(x, dtype=float) for x in self.args)
            return c - r, c + r
        c, half, rounding = self.args
        c, half = np.asarray(c, dtype=float), np.asarray(half, dtype=float)
        return c - half - rounding, c + half + rounding


def _cone(a, b, ra, rb=None, k=0.0) -> _Part:
    return _Part("cone", (tuple(a), tuple(b), ra, ra if rb is None else rb), k)


def _ellipsoid(c, radii, k=0.0) -> _Part:
    return _Part("ellipsoid", (tuple(c), tuple(radii)), k)


def _box(c, half, rounding, k=0.0) -> _Part:
    return _Part("box", (tuple(c), tuple(half), rounding), k)


def _field(parts: list[_Part], min_k: float = 0.0) -> Callable[[np.ndarray], np.ndarray]:
    """The parts' smooth union; blends at least ``min_k`` wide, so that a coarse grid
    does not meet creases sharper than it can follow."""
    def sdf(X: np.ndarray) -> np.ndarray:
        d = parts[0].sdf(X)
        for p in parts[1:]:
            d = smooth_union(d, p.sdf(X), max(p.k, min_k))
        return d
    return sdf


def _mirror(parts: list[_Part]) -> list[_Part]:
    """The parts reflected in the plane x = 0."""
    def flip(x):
        return (-x[0],) + tuple(x[1:])

    out = []
    for p in parts:
        args = list(p.args)
        args[0] = flip(args[0])
        if p.kind == "cone":
            args[1] = flip(args[1])
        out.append(_Part(p.kind, tuple(args), p.k))
    return out


def _mesh_parts(parts: list[_Part], h: float, *, relax: int = 4):
    """Mesh the blended parts on a grid of cell ``h`` (the box with two cells of margin)."""
    lo = np.min([p.bounds()[0] for p in parts], axis=0) - 2.0 * h
    hi = np.max([p.bounds()[1] for p in parts], axis=0) + 2.0 * h
    res = int(np.ceil(float((hi - lo).max()) / h))
    return implicit_surface(_field(parts, h), lo, hi, res, relax=relax)


def _model3d(name: str, parts: list[_Part], h: float, C, BE, names, extra=None) -> Model:
    V, F = _mesh_parts(parts, h)
    sk = Skeleton(np.asarray(C, dtype=float), np.asarray(BE, dtype=np.int64), names=names)
    extra = {} if extra is None else dict(extra)
    extra.setdefault("sdf", _field(parts, h))
    return Model(V, F, sk, name, extra)


def arm(*, quick: bool = False) -> Model:
    """An arm with a (mitten) hand along x, three bones: the paper's Figs. 1 and 5.

    Shoulder at the origin, elbow at x = 1.45, wrist at x = 2.65, hand tip at x = 3.4;
    the palm faces -y and the thumb points towards +z, so a 180 degree wrist twist
    turns the thumb to -z. One watertight surface of blended round cones (upper arm,
    biceps, forearm, palm, mitten, thumb), about 4 units long.

    Parameters
    ----------
    quick : bool, keyword-only
        A coarser mesh (about 1.8k vertices instead of 6.5k) for fast runs.

    Returns
    -------
    Model
        ``sk``: bones ``"upper"`` (shoulder -> elbow), ``"fore"`` (elbow -> wrist),
        ``"hand"`` (wrist -> hand tip). ``extra``: ``"wrist"`` (3,) the wrist joint,
        ``"wrist_axis"`` (3,) the forearm's unit axis, ``"hand"`` (n,) bool, the
        vertices beyond the wrist plane (for a hand-volume measure), ``"sdf"`` the
        distance field of the shape.
    """
    quick = _flag("quick", quick)
    C = [[0.0, 0.0, 0.0], [1.45, 0.0, 0.0], [2.65, 0.0, 0.0], [3.4, 0.0, 0.0]]
    parts = [
        _cone((-0.05, 0.0, 0.0), C[1], 0.26, 0.19),                        # upper arm
        _ellipsoid((0.7, 0.05, 0.0), (0.5, 0.22, 0.21), k=0.2),             # biceps
        _cone(C[1], C[2], 0.18, 0.12, k=0.1),                               # forearm
        _ellipsoid((1.85, 0.02, 0.0), (0.45, 0.19, 0.2), k=0.2),            # its muscles
        _ellipsoid((2.5, 0.0, 0.0), (0.25, 0.11, 0.15), k=0.1),             # flat wrist
        _ellipsoid((2.95, 0.0, 0.0), (0.3, 0.1, 0.21), k=0.12),             # palm
        _ellipsoid((3.33, -0.01, 0.0), (0.27, 0.08, 0.18), k=0.08),         # mitten
        _cone((2.85, -0.02, 0.14), (3.08, -0.05, 0.31), 0.075, 0.065, k=0.1),  # thumb
    ]
    m = _model3d("arm", parts, 0.11 if quick else 0.06, C, [[0, 1], [1, 2], [2, 3]],
                 ["upper", "fore", "hand"])
    wrist = np.array(C[2])
    axis = np.array([1.0, 0.0, 0.0])
    m.extra.update(wrist=wrist, wrist_axis=axis, hand=(m.V - wrist) @ axis > 0)
    return m


def leg(*, quick: bool = False) -> Model:
    """A leg bent at the knee, y up, toes towards +z: the paper's Fig. 4.

    Hip at y = 2, knee bent forwards (z = 0.3) at y = 1.1, ankle at y = 0.25, the
    foot on the ground plane y = 0. One watertight surface (thigh, knee cap, calf,
    shin, foot).

    Parameters
    ----------
    quick : bool, keyword-only
        A coarser mesh (about 1.5k vertices instead of 5k).

    Returns
    -------
    Model
        ``sk``: bones ``"thigh"`` (hip -> knee), ``"shin"`` (knee -> ankle) and
        ``"foot"`` (ankle -> toes). ``extra``: ``"sdf"``.
    """
    quick = _flag("quick", quick)
    C = [[0.0, 2.0, 0.0], [0.0, 1.1, 0.38], [0.0, 0.25, 0.0], [0.0, 0.1, 0.42]]
    parts = [
        _cone((0.0, 2.2, -0.02), C[1], 0.3, 0.19),                          # thigh
        _ellipsoid((0.0, 1.95, -0.1), (0.3, 0.3, 0.25), k=0.15),            # buttock
        _ellipsoid((0.0, 1.55, 0.14), (0.24, 0.4, 0.22), k=0.15),           # front thigh
        _ellipsoid((0.0, 1.1, 0.5), (0.12, 0.12, 0.08), k=0.1),             # knee cap
        _cone(C[1], C[2], 0.18, 0.1, k=0.08),                               # shin
        _ellipsoid((0.0, 0.8, 0.16), (0.16, 0.3, 0.16), k=0.12),            # calf
        _ellipsoid((0.0, 0.11, 0.17), (0.13, 0.1, 0.33), k=0.1),            # foot
        _cone(C[2], (0.0, 0.12, 0.3), 0.1, 0.07, k=0.08),                   # instep
    ]
    return _model3d("leg", parts, 0.11 if quick else 0.06, C, [[0, 1], [1, 2], [2, 3]],
                    ["thigh", "shin", "foot"])


def torso(*, quick: bool = False) -> Model:
    """A torso along y with one bone from the pelvis to the chest: the paper's Fig. 10.

    Pelvis (with leg stubs) around y = 0, a narrower abdomen, the chest around
    y = 1.25 with shoulder stubs along x and a neck stub up to y = 1.9. The cross
    sections are wider in x than in z, so a twist about y shows.

    Parameters
    ----------
    quick : bool, keyword-only
        A coarser mesh (about 2k vertices instead of 7k).

    Returns
    -------
    Model
        ``sk``: one bone ``"spine"`` from ``(0, 0.1, 0)`` to ``(0, 1.35, 0)``.
        ``extra``: ``"abdomen"`` and ``"chest"``, the (2,) y-ranges of the two
        regions (the spline filter should move the twist into the abdomen);
        ``"sdf"``.
    """
    quick = _flag("quick", quick)
    C = [[0.0, 0.1, 0.0], [0.0, 1.35, 0.0]]
    parts = [
        _ellipsoid((0.0, 0.1, 0.0), (0.5, 0.3, 0.3)),                       # pelvis
        _cone((0.25, 0.0, 0.0), (0.28, -0.4, 0.02), 0.22, 0.2, k=0.1),      # leg stubs
        _cone((-0.25, 0.0, 0.0), (-0.28, -0.4, 0.02), 0.22, 0.2, k=0.1),
        _ellipsoid((0.0, 0.6, 0.01), (0.4, 0.45, 0.26), k=0.2),             # abdomen
        _ellipsoid((0.0, 1.2, 0.02), (0.55, 0.45, 0.31), k=0.2),            # chest
        _cone((-0.3, 1.5, 0.0), (-0.8, 1.42, 0.0), 0.18, 0.14, k=0.12),     # shoulders
        _cone((0.3, 1.5, 0.0), (0.8, 1.42, 0.0), 0.18, 0.14, k=0.12),
        _cone((0.0, 1.5, 0.0), (0.0, 1.85, 0.02), 0.15, 0.12, k=0.1),       # neck
    ]
    m = _model3d("torso", parts, 0.12 if quick else 0.065, C, [[0, 1]], ["spine"])
    m.extra.update(abdomen=np.array([0.3, 0.85]), chest=np.array([0.85, 1.7]))
    return m


def character(*, quick: bool = False) -> Model:
    """A small humanoid, y up, facing +z, 15 bones: the paper's Fig. 6.

    Head, neck, chest, belly, pelvis, arms held down and out, legs; about 3.1 units
    tall, standing on y = 0. One watertight surface.

    Parameters
    ----------
    quick : bool, keyword-only
        A coarser mesh (about 2.8k vertices instead of 7.4k).

    Returns
    -------
    Model
        ``sk``: bones ``spine``, ``neck``, ``head``, ``clavicle_l``, ``upper_arm_l``,
        ``forearm_l`` (and ``_r``), ``hip_l``, ``thigh_l``, ``shin_l`` (and ``_r``);
        ``_l`` is the character's left, at +x. ``extra``: ``"sdf"``.
    """
    quick = _flag("quick", quick)
    C = np.array([
        [0.0, 1.55, 0.0],    # 0 pelvis
        [0.0, 2.2, 0.0],     # 1 chest
        [0.0, 2.5, 0.0],     # 2 neck
        [0.0, 2.92, 0.03],   # 3 head top
        [0.42, 2.38, 0.0],   # 4 shoulder
        [0.8, 2.0, 0.0],     # 5 elbow
        [1.1, 1.64, 0.04],   # 6 wrist
        [0.21, 1.42, 0.0],   # 7 hip
        [0.24, 0.82, 0.05],  # 8 knee
        [0.25, 0.22, 0.0],   # 9 ankle
    ])
    left = C[4:]
    right = left * [-1.0, 1.0, 1.0]
    C = np.vstack([C, right])  # right side: joints 10..15
    r = 6
    BE = [[0, 1], [1, 2], [2, 3],
          [1, 4], [4, 5], [5, 6], [1, 4 + r], [4 + r, 5 + r], [5 + r, 6 + r],
          [0, 7], [7, 8], [8, 9], [0, 7 + r], [7 + r, 8 + r], [8 + r, 9 + r]]
    names = ["spine", "neck", "head",
             "clavicle_l", "upper_arm_l", "forearm_l", "clavicle_r", "upper_arm_r", "forearm_r",
             "hip_l", "thigh_l", "shin_l", "hip_r", "thigh_r", "shin_r"]
    body = [
        _ellipsoid((0.0, 1.5, 0.0), (0.36, 0.24, 0.23)),                    # pelvis
        _ellipsoid((0.0, 1.85, 0.01), (0.32, 0.3, 0.22), k=0.15),           # belly
        _ellipsoid((0.0, 2.2, 0.0), (0.42, 0.3, 0.25), k=0.15),             # chest
        _cone((0.0, 2.3, 0.0), (0.0, 2.62, 0.01), 0.13, 0.11, k=0.1),       # neck
        _ellipsoid((0.0, 2.78, 0.03), (0.23, 0.26, 0.24), k=0.08),          # head
        _ellipsoid((0.0, 2.75, 0.26), (0.05, 0.07, 0.06), k=0.04),          # nose
    ]
    side = [
        _cone((0.2, 2.33, 0.0), tuple(left[0]), 0.15, 0.13, k=0.1),        # shoulder
        _cone(tuple(left[0]), tuple(left[1]), 0.13, 0.105, k=0.06),         # upper arm
        _cone(tuple(left[1]), tuple(left[2]), 0.105, 0.09, k=0.05),         # forearm
        _cone(tuple(left[2]), (1.22, 1.48, 0.06), 0.1, 0.09, k=0.05),       # hand
        _cone((0.21, 1.5, 0.0), tuple(left[4]), 0.18, 0.13, k=0.08),       # thigh
        _cone(tuple(left[4]), tuple(left[5]), 0.13, 0.1, k=0.05),          # shin
        _ellipsoid((0.25, 0.08, 0.1), (0.1, 0.08, 0.2), k=0.06),           # foot
    ]
    parts = body + side + _mirror(side)
    return _model3d("character", parts, 0.105 if quick else 0.066, C, BE, names)


# ============================================================================ 2D models


def _resample_loop(P: np.ndarray, spacing: float) -> np.ndarray:
    """A closed polygon resampled at (nearly) equal arc-length steps of about ``spacing``."""
    Q = np.vstack([P, P[:1]])
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(Q, axis=0), axis=1))])
    m = max(int(round(s[-1] / spacing)), 8)
    t = np.arange(m) * (s[-1] / m)
    return np.stack([np.interp(t, s, Q[:, 0]), np.interp(t, s, Q[:, 1])], axis=1)


def _project_2d(P: np.ndarray, sdf, step: float, iterations: int = 3) -> np.ndarray:
    """Newton steps onto the zero set of a 2D field (finite-difference gradient)."""
    for _ in range(iterations):
        d = sdf(P)
        g = np.stack([(sdf(P + [step, 0.0]) - d) / step, (sdf(P + [0.0, step]) - d) / step],
                     axis=1)
        g2 = np.maximum(np.einsum("ij,ij->i", g, g), 1e-12)
        P = P - (d / g2)[:, None] * g
    return P


def _outline_of_field(sdf, lo, hi, spacing: float) -> list[np.ndarray]:
    """The zero set of a 2D field as polygons: traced on a grid of pixels a third of
    ``spacing`` wide, resampled every ``spacing`` and moved onto the zero set."""
    from ..meshing import outline_from_image

    px = spacing / 3.0
    lo = np.asarray(lo, dtype=float) - 4 * px
    hi = np.asarray(hi, dtype=float) + 4 * px
    W, H = (np.ceil((hi - lo) / px).astype(int) + 1).tolist()
    xs = lo[0] + px * np.arange(W)
    ys = lo[1] + px * np.arange(H)[::-1]  # image row 0 is the top
    X = np.stack(np.meshgrid(xs, ys), axis=-1).reshape(-1, 2)
    img = np.clip(0.5 - sdf(X).reshape(H, W) / (4 * px), 0.0, 1.0)
    loops = outline_from_image(img, tolerance=0.0)
    # outline_from_image puts pixel (r, c) at (c, H - 1 - r): row H - 1 is y = lo.
    return [_project_2d(_resample_loop(lo + L * px, spacing), sdf, 1e-4 * spacing)
            for L in loops]


def _model2d(name: str, outline, sk: Skeleton, spacing: float, extra: dict) -> Model:
    from ..meshing import triangulate_2d

    tm = triangulate_2d(outline, sk, max_area=0.5 * spacing * spacing)
    extra = dict(extra)
    extra["mesh"] = tm
    return Model(tm.V, tm.F, sk, name, extra)


def long_necked_animal_2d(*, quick: bool = False) -> Model:
    """A 2D giraffe-like animal in profile (facing +x, y up): the paper's Fig. 7.

    Body, a long neck rising to the upper right, a head with snout and horn, four
    legs standing on y = 0 and a tail, blended into one smooth outline (a sampled
    distance field, traced and resampled evenly) and triangulated with the skeleton
    as constrained segments. About 3.5 units long and 3.8 tall.

    Parameters
    ----------
    quick : bool, keyword-only
        A coarser mesh (about 800 vertices instead of 3k).

    Returns
    -------
    Model
        2D: ``V`` (n, 2), counter-clockwise ``F``. ``sk``: bones ``"body"`` (hip ->
        shoulder), ``"neck"`` (shoulder -> head), ``"head"`` (to the snout), ``"tail"``
        (from the hip), and four legs ``"front_leg_a"``, ``"front_leg_b"``,
        ``"back_leg_a"``, ``"back_leg_b"`` (each its own root, from the body down to the
        hoof). ``extra``: ``"neck"`` the neck's bone index, ``"head"`` (n,) bool, the
        vertices of the head, ``"mesh"`` the :class:`stbs.meshing.TriMesh` (joint
        vertices, bone samples), ``"sdf"`` the shape's distance field.
    """
    quick = _flag("quick", quick)
    C = np.array([[-0.7, 1.68], [0.62, 1.72], [1.45, 3.3], [1.95, 3.32],       # hip .. snout
                  [0.45, 1.45], [0.4, 0.12], [0.8, 1.45], [0.88, 0.12],        # front legs
                  [-0.55, 1.45], [-0.5, 0.12], [-0.88, 1.45], [-0.95, 0.12],   # back legs
                  [-1.33, 1.2]])                                               # tail tip
    BE = [[0, 1], [1, 2], [2, 3], [0, 12], [4, 5], [6, 7], [8, 9], [10, 11]]
    names = ["body", "neck", "head", "tail", "front_leg_a", "front_leg_b", "back_leg_a",
             "back_leg_b"]
    head = [
        _ellipsoid((1.6, 3.4), (0.27, 0.16)),
        _cone((1.62, 3.4), (2.02, 3.3), 0.14, 0.08, k=0.08),                 # snout
        _cone((1.5, 3.5), (1.43, 3.74), 0.035, 0.045, k=0.04),              # horn
    ]
    parts = [
        _ellipsoid((0.0, 1.72), (0.95, 0.4)),                               # body
        _ellipsoid((0.6, 1.8), (0.42, 0.42), k=0.2),                        # chest
        _ellipsoid((-0.72, 1.62), (0.35, 0.36), k=0.2),                     # haunch
        _cone((0.62, 1.8), (1.45, 3.3), 0.22, 0.1, k=0.15),                 # neck
        *[_Part(p.kind, p.args, 0.1) for p in head],
        _cone(tuple(C[0]), tuple(C[12]), 0.05, 0.03, k=0.06),               # tail
        _ellipsoid((-1.37, 1.1), (0.06, 0.11), k=0.04),                     # tuft
    ]
    for top, foot in ((4, 5), (6, 7), (8, 9), (10, 11)):
        parts.append(_cone(tuple(C[top]), tuple(C[foot] + [0.0, -0.04]), 0.085, 0.06, k=0.06))
        parts.append(_ellipsoid(tuple(C[foot] - [0.0, 0.04]), (0.085, 0.06), k=0.03))  # hoof
    sdf = _field(parts)
    lo = np.min([p.bounds()[0] for p in parts], axis=0)
    hi = np.max([p.bounds()[1] for p in parts], axis=0)
    spacing = 0.08 if quick else 0.04
    sk = Skeleton(C, BE, names=names)
    m = _model2d("long_necked_animal_2d", _outline_of_field(sdf, lo, hi, spacing), sk, spacing,
                 {"neck": 1, "sdf": sdf})
    m.extra["head"] = _field(head)(m.V) <= 1e-9
    return m


def _gingerbread(size: int) -> tuple[np.ndarray, dict]:
    """The picture, RGBA (size, size, 4) uint8, and the skeleton's joints in pixel
    units (x = column, y = size - 1 - row, as :func:`stbs.outline_from_image`)."""
    s = size / 256.0  # the design below is in pixels of a 256 x 256 image
    head = ((128 * s, 194 * s), 36 * s)
    arm = ((128 * s, 150 * s), (44 * s, 172 * s), 22 * s, 17 * s)
    leg = ((112 * s, 100 * s), (84 * s, 30 * s), 24 * s, 20 * s)
    parts = [
        _cone((128 * s, 140 * s), (128 * s, 100 * s), 44 * s),              # body
        _ellipsoid(head[0], (head[1], head[1]), k=10 * s),
        _cone(*arm[:2], *arm[2:], k=10 * s),
        _cone((256 * s - arm[0][0], arm[0][1]), (256 * s - arm[1][0], arm[1][1]), *arm[2:],
              k=10 * s),
        _cone(*leg[:2], *leg[2:], k=10 * s),
        _cone((256 * s - leg[0][0], leg[0][1]), (256 * s - leg[1][0], leg[1][1]), *leg[2:],
              k=10 * s),
    ]
    sdf = _field(parts)
    yy, xx = np.mgrid[:size, :size]
    P = np.stack([xx, size - 1 - yy], axis=-1).reshape(-1, 2).astype(float)
    d = sdf(P).reshape(size, size)
    x, y = P[:, 0].reshape(size, size), P[:, 1].reshape(size, size)

    def disc(c, r):
        return np.hypot(x - c[0], y - c[1]) - r

    rgb = np.empty((size, size, 3))
    rgb[:] = (0.71, 0.42, 0.2)  # dough, also outside the shape, so edges sample well
    stripe = np.sin(2 * np.pi * (x + 0.6 * y) / (22 * s)) > 0.55
    rgb[stripe] = (0.6, 0.33, 0.14)
    icing = np.abs(d + 6 * s + 1.2 * s * np.sin(x / (3 * s)) * np.cos(y / (3 * s))) < 1.6 * s
    rgb[icing] = (0.98, 0.97, 0.94)
    # Zig-zag icing across each wrist and ankle.
    for (a, b, _, _), mirror in ((arm, 1), (arm, -1), (leg, 1), (leg, -1)):
        a = np.array([128 * s + mirror * (a[0] - 128 * s), a[1]])
        b = np.array([128 * s + mirror * (b[0] - 128 * s), b[1]])
        u = (b - a) / np.linalg.norm(b - a)
        along = (x - a[0]) * u[0] + (y - a[1]) * u[1]
        across = -(x - a[0]) * u[1] + (y - a[1]) * u[0]
        zig = 0.7 * np.linalg.norm(b - a) + 5 * s * np.abs(((across / (5 * s)) % 2) - 1)
        rgb[(np.abs(along - zig) < 1.8 * s) & (d < -8 * s)] = (0.98, 0.97, 0.94)
    for c, col in (((128, 150), (0.86, 0.12, 0.15)), ((128, 124), (0.1, 0.62, 0.25)),
                   ((128, 98), (0.15, 0.35, 0.85))):  # buttons with a white rim
        c = (c[0] * s, c[1] * s)
        rgb[disc(c, 9 * s) < 0] = (0.98, 0.97, 0.94)
        rgb[disc(c, 7 * s) < 0] = col
    cheeks = (disc((106 * s, 186 * s), 6 * s) < 0) | (disc((150 * s, 186 * s), 6 * s) < 0)
    rgb[cheeks] = 0.5 * rgb[cheeks] + 0.5 * np.array([0.95, 0.45, 0.5])
    for ex in (114, 142):  # eyes with a highlight
        rgb[disc((ex * s, 202 * s), 6 * s) < 0] = (0.12, 0.06, 0.03)
        rgb[disc(((ex + 2) * s, 204 * s), 2 * s) < 0] = (1.0, 1.0, 1.0)
    smile = (np.abs(disc((128 * s, 196 * s), 17 * s)) < 2.2 * s) & (y < 188 * s)
    rgb[smile] = (0.45, 0.1, 0.08)
    alpha = np.clip(0.5 - d / (1.5 * s), 0.0, 1.0)  # anti-aliased edge, 1.5 px wide
    img = np.concatenate([rgb, alpha[..., None]], axis=-1)
    texture = np.round(255 * img).astype(np.uint8)
    joints = {
        "pelvis": (128, 98), "chest": (128, 150), "head": (128, 206),
        "elbow_l": (88, 160), "hand_l": (52, 170), "elbow_r": (168, 160), "hand_r": (204, 170),
        "knee_l": (99, 66), "foot_l": (87, 36), "knee_r": (157, 66), "foot_r": (169, 36),
    }
    return texture, {k: (v[0] * s, v[1] * s) for k, v in joints.items()}


def picture_2d(*, quick: bool = False, size: int = 256) -> Model:
    """A gingerbread man drawn in code, with texture coordinates: the paper's Fig. 12.

    An RGBA picture (a biscuit with a striped dough, an icing border, zig-zag icing
    at wrists and ankles, buttons, eyes and a smile) is drawn with NumPy; its alpha
    mask is traced with :func:`stbs.outline_from_image` and triangulated with the
    skeleton inside. Model units: the picture is 3 units wide, y up, its lower left
    corner at the origin.

    Parameters
    ----------
    quick : bool, keyword-only
        A coarser mesh (about 500 vertices instead of 2.4k).
    size : int, keyword-only
        The picture's width and height in pixels (>= 64; default 256).

    Returns
    -------
    Model
        2D: ``V`` (n, 2), counter-clockwise ``F``. ``sk``: bones ``"spine"`` (pelvis
        -> chest), ``"head"``, ``"upper_arm_l"``, ``"forearm_l"``, ``"thigh_l"``,
        ``"shin_l"`` and the same with ``_r`` (``_l`` on the left of the picture).
        ``extra``: ``"texture"`` (size, size, 4) uint8, RGBA, row 0 at the top;
        ``"uv"`` (n, 2) float64 in [0, 1], OpenGL convention: ``u`` across from the
        left edge, ``v`` up from the bottom edge, so that vertex ``k`` shows pixel
        ``(row, col) = ((1 - v) size - 1/2, u size - 1/2)``; ``"scale"``, model
        units per pixel; ``"mesh"`` the :class:`stbs.meshing.TriMesh`.
    """
    from ..meshing import outline_from_image

    quick = _flag("quick", quick)
    if isinstance(size, bool) or not isinstance(size, (int, np.integer)) or size < 64:
        raise ValueError(f"size must be an integer >= 64 (pixels), got {size!r}")
    size = int(size)
    texture, J = _gingerbread(size)
    scale = 3.0 / size
    names = ["spine", "head", "upper_arm_l", "forearm_l", "upper_arm_r", "forearm_r",
             "thigh_l", "shin_l", "thigh_r", "shin_r"]
    order = list(J)
    pairs = [("pelvis", "chest"), ("chest", "head"), ("chest", "elbow_l"),
             ("elbow_l", "hand_l"), ("chest", "elbow_r"), ("elbow_r", "hand_r"),
             ("pelvis", "knee_l"), ("knee_l", "foot_l"), ("pelvis", "knee_r"),
             ("knee_r", "foot_r")]
    C = np.array([J[k] for k in order]) * scale
    BE = [[order.index(a), order.index(b)] for a, b in pairs]
    sk = Skeleton(C, BE, names=names)
    spacing = 0.1 if quick else 0.045
    loops = [_resample_loop(L * scale, spacing)
             for L in outline_from_image(texture, tolerance=0.25)]
    m = _model2d("picture_2d", loops, sk, spacing, {"texture": texture, "scale": scale})
    m.extra["uv"] = np.clip((m.V / scale + 0.5) / size, 0.0, 1.0)
    return m


#: The models by name: ``MODELS[name](quick=...)`` builds one.
MODELS: dict[str, Callable[..., Model]] = {
    "arm": arm,
    "leg": leg,
    "torso": torso,
    "character": character,
    "long_necked_animal_2d": long_necked_animal_2d,
    "picture_2d": picture_2d,
}
