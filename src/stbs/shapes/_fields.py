"""Signed distance functions and blended primitives (negative inside, 2D or 3D)."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

__all__ = ["sphere_sdf", "capsule_sdf", "ellipsoid_sdf", "box_sdf", "smooth_union",
           "Primitive", "round_cone", "ellipsoid", "rounded_box", "blend", "mirror",
           "bounds"]


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

    Examples
    --------
    >>> from stbs.shapes import sphere_sdf
    >>> sphere_sdf([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0]], [0, 0, 0], 1.0).tolist()
    [-1.0, 1.0]
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

    Examples
    --------
    >>> from stbs.shapes import capsule_sdf
    >>> capsule_sdf([[0.5, 0.0], [2.0, 0.0]], [0, 0], [1, 0], 0.25).tolist()
    [-0.25, 0.75]
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

    Examples
    --------
    >>> from stbs.shapes import ellipsoid_sdf
    >>> ellipsoid_sdf([[2.0, 0.0], [0.0, 0.0]], [0, 0], [2.0, 1.0]).tolist()
    [0.0, -1.0]
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

    Examples
    --------
    >>> from stbs.shapes import box_sdf
    >>> box_sdf([[0.0, 0.0], [2.0, 0.0]], [0, 0], [1.0, 0.5]).tolist()
    [-0.5, 1.0]
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

    Examples
    --------
    >>> from stbs.shapes import smooth_union
    >>> smooth_union([0.0, -1.0], [0.0, 1.0], 0.4).tolist()  # a fillet where they meet
    [-0.1, -1.0]
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



# ---------------------------------------------------------------------- blended primitives
@dataclass(frozen=True)
class Primitive:
    """One primitive of a blended shape: a round cone, an ellipsoid or a rounded box.

    Made by :func:`round_cone`, :func:`ellipsoid` and :func:`rounded_box`; a list of
    them is one shape, their :func:`blend` (meshed by
    :func:`stbs.shapes.mesh_primitives`).

    Attributes
    ----------
    kind : {"cone", "ellipsoid", "box"}
    args : tuple
        ``(a, b, r_a, r_b)`` for a cone (:func:`capsule_sdf`), ``(center, radii)`` for
        an ellipsoid, ``(center, half, rounding)`` for a box (:func:`box_sdf`).
    k : float
        Blend width into the shape built by the primitives before it
        (:func:`smooth_union`); 0 for a plain union.
    """

    kind: Literal["cone", "ellipsoid", "box"]
    args: tuple
    k: float = 0.0

    def sdf(self, X) -> np.ndarray:
        """Signed distance (...,) of the points ``X`` (..., d) to this primitive."""
        if self.kind == "cone":
            a, b, ra, rb = self.args
            return capsule_sdf(X, a, b, (ra, rb))
        if self.kind == "ellipsoid":
            return ellipsoid_sdf(X, *self.args)
        return box_sdf(X, *self.args)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """The corners ``(lo, hi)``, each (d,), of the primitive's bounding box."""
        if self.kind == "cone":
            a, b, ra, rb = (np.asarray(x, dtype=float) for x in self.args)
            return np.minimum(a - ra, b - rb), np.maximum(a + ra, b + rb)
        if self.kind == "ellipsoid":
            c, r = (np.asarray(x, dtype=float) for x in self.args)
            return c - r, c + r
        c, half, rounding = self.args
        c, half = np.asarray(c, dtype=float), np.asarray(half, dtype=float)
        return c - half - rounding, c + half + rounding


def round_cone(a, b, ra: float, rb: float | None = None, *, k: float = 0.0) -> Primitive:
    """A round cone (a capsule whose radius goes linearly from ``ra`` to ``rb``).

    Parameters
    ----------
    a, b : (d,) float
        End points of the axis.
    ra : float
        Radius at ``a``.
    rb : float, optional
        Radius at ``b`` (default ``ra``).
    k : float, keyword-only
        Blend width into the shape before it (see :class:`Primitive`).

    Returns
    -------
    Primitive

    Examples
    --------
    >>> from stbs.shapes import round_cone
    >>> cone = round_cone((0, 0, 0), (1, 0, 0), 0.3, 0.2)
    >>> cone.sdf([[0.5, 0.0, 0.0], [2.0, 0.0, 0.0]]).round(3).tolist()
    [-0.25, 0.8]
    """
    return Primitive("cone", (tuple(a), tuple(b), ra, ra if rb is None else rb), k)


def ellipsoid(center, radii, *, k: float = 0.0) -> Primitive:
    """An axis-aligned ellipsoid (an ellipse in 2D), see :func:`ellipsoid_sdf`.

    Parameters
    ----------
    center, radii : (d,) float
        Centre and semi-axes.
    k : float, keyword-only
        Blend width into the shape before it (see :class:`Primitive`).

    Returns
    -------
    Primitive
    """
    return Primitive("ellipsoid", (tuple(center), tuple(radii)), k)


def rounded_box(center, half, rounding: float = 0.0, *, k: float = 0.0) -> Primitive:
    """An axis-aligned box with rounded edges, see :func:`box_sdf`.

    Parameters
    ----------
    center, half : (d,) float
        Centre and half edge lengths before rounding.
    rounding : float
        Radius of the rounded edges.
    k : float, keyword-only
        Blend width into the shape before it (see :class:`Primitive`).

    Returns
    -------
    Primitive
    """
    return Primitive("box", (tuple(center), tuple(half), rounding), k)


def blend(parts: Sequence[Primitive], min_k: float = 0.0) -> Callable[[np.ndarray], np.ndarray]:
    """The smooth union of primitives, in order, as one distance function.

    Each primitive is blended into the union of those before it with its own width
    ``k`` (:func:`smooth_union`), at least ``min_k``: a coarse grid then meets no
    crease sharper than it can follow.

    Parameters
    ----------
    parts : sequence of Primitive
        At least one.
    min_k : float
        Smallest blend width (e.g. the grid's cell size when meshing).

    Returns
    -------
    callable
        ``sdf(X)`` for points ``X`` (..., d) returns (...,) float64.

    Examples
    --------
    >>> from stbs.shapes import blend, ellipsoid, round_cone
    >>> sdf = blend([round_cone((0, 0), (1, 0), 0.2), ellipsoid((1, 0), (0.3, 0.3), k=0.1)])
    >>> bool(sdf([[0.5, 0.0]])[0] < 0), bool(sdf([[1.35, 0.0]])[0] > 0)
    (True, True)
    """
    parts = list(parts)
    if not parts or not all(isinstance(p, Primitive) for p in parts):
        raise ValueError(f"parts must be a non-empty sequence of Primitive, got {parts!r}")

    def sdf(X: np.ndarray) -> np.ndarray:
        d = parts[0].sdf(X)
        for p in parts[1:]:
            d = smooth_union(d, p.sdf(X), max(p.k, min_k))
        return d
    return sdf


def mirror(parts: Sequence[Primitive]) -> list[Primitive]:
    """The primitives reflected in the plane x = 0 (the line x = 0 in 2D).

    Parameters
    ----------
    parts : sequence of Primitive

    Returns
    -------
    list of Primitive
        Same kinds, sizes and blend widths, centres and axes with x negated.
    """
    def flip(x):
        return (-x[0],) + tuple(x[1:])

    out = []
    for p in parts:
        args = list(p.args)
        args[0] = flip(args[0])
        if p.kind == "cone":
            args[1] = flip(args[1])
        out.append(dataclasses.replace(p, args=tuple(args)))
    return out


def bounds(parts: Sequence[Primitive]) -> tuple[np.ndarray, np.ndarray]:
    """The corners ``(lo, hi)``, each (d,), of the box around all the primitives."""
    lo = np.min([p.bounds()[0] for p in parts], axis=0)
    hi = np.max([p.bounds()[1] for p in parts], axis=0)
    return lo, hi
