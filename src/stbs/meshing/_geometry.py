"""Small vectorised geometric predicates shared by the 2D and 3D meshers.

Everything here is plain floating point (no exact arithmetic): inputs are checked
with a tolerance relative to the size of the shape, and the callers turn a hit
into an error that names the offending input.
"""

from __future__ import annotations

import numpy as np

from ..geometry import (  # noqa: F401  (the shared ones, re-exported for the meshers)
    boundary_faces,
    cycles,
    points_in_loops,
    signed_area,
    tet_volumes,
    triangle_areas,
    unique_edges,
    unique_rows,
)

#: Relative tolerance (times the bounding-box diagonal) for "on a segment" and
#: "coincident" tests.
REL_TOL = 1e-10


def scale_of(X: np.ndarray) -> float:
    """Bounding-box diagonal of the rows of ``X`` (1.0 for a single point)."""
    if X.shape[0] < 2:
        return 1.0
    d = float(np.linalg.norm(X.max(axis=0) - X.min(axis=0)))
    return d if d > 0 else 1.0


# ----------------------------------------------------------------------------- 2D


def orient2d(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Twice the signed area of triangles ``(a, b, c)``, all (..., 2); > 0 counter-clockwise."""
    return ((b[..., 0] - a[..., 0]) * (c[..., 1] - a[..., 1])
            - (b[..., 1] - a[..., 1]) * (c[..., 0] - a[..., 0]))


def segments_intersect(p1, p2, q1, q2, *, tol: float = 0.0) -> np.ndarray:
    """Whether segments ``p1 p2`` and ``q1 q2`` (all (..., 2), broadcast) meet.

    Closed segments: touching and collinear overlap count. ``tol`` is an
    absolute distance below which an endpoint counts as lying on the other
    segment.
    """
    d1 = orient2d(q1, q2, p1)
    d2 = orient2d(q1, q2, p2)
    d3 = orient2d(p1, p2, q1)
    d4 = orient2d(p1, p2, q2)
    proper = (((d1 > 0) & (d2 < 0)) | ((d1 < 0) & (d2 > 0))) & \
             (((d3 > 0) & (d4 < 0)) | ((d3 < 0) & (d4 > 0)))
    touch = (point_segment_distance(p1, q1, q2) <= tol) | \
            (point_segment_distance(p2, q1, q2) <= tol) | \
            (point_segment_distance(q1, p1, p2) <= tol) | \
            (point_segment_distance(q2, p1, p2) <= tol)
    return proper | touch


def point_segment_distance(p, a, b) -> np.ndarray:
    """Distance from points ``p`` to segments ``a b`` (broadcast, any dimension)."""
    ab = b - a
    L2 = np.einsum("...i,...i->...", ab, ab)
    t = np.einsum("...i,...i->...", p - a, ab) / np.where(L2 > 0, L2, 1.0)
    t = np.clip(t, 0.0, 1.0)
    return np.linalg.norm(p - (a + t[..., None] * ab), axis=-1)


def project_on_segment(p, a, b) -> tuple[np.ndarray, np.ndarray]:
    """``(t, dist)``: clamped parameter of the projection of ``p`` on ``a b`` and the distance."""
    ab = b - a
    L2 = np.einsum("...i,...i->...", ab, ab)
    t = np.clip(np.einsum("...i,...i->...", p - a, ab) / L2, 0.0, 1.0)
    return t, np.linalg.norm(p - (a + t[..., None] * ab), axis=-1)


def triangle_angles(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Interior angles (f, 3) in radians, angle k at corner ``F[:, k]`` (2D or 3D)."""
    P = V[F]
    ang = np.empty(F.shape, dtype=np.float64)
    for k in range(3):
        u = P[:, (k + 1) % 3] - P[:, k]
        w = P[:, (k + 2) % 3] - P[:, k]
        if V.shape[1] == 2:
            cross = np.abs(u[:, 0] * w[:, 1] - u[:, 1] * w[:, 0])
        else:
            cross = np.linalg.norm(np.cross(u, w), axis=-1)
        ang[:, k] = np.arctan2(cross, np.einsum("ij,ij->i", u, w))
    return ang


def circumcenters(P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Circumcentres (f, 2) and squared circumradii (f,) of 2D triangles ``P`` (f, 3, 2)."""
    a = P[:, 0]
    b = P[:, 1] - a
    c = P[:, 2] - a
    d = 2.0 * (b[:, 0] * c[:, 1] - b[:, 1] * c[:, 0])
    b2 = np.einsum("ij,ij->i", b, b)
    c2 = np.einsum("ij,ij->i", c, c)
    ux = (c[:, 1] * b2 - b[:, 1] * c2) / d
    uy = (b[:, 0] * c2 - c[:, 0] * b2) / d
    return a + np.stack([ux, uy], axis=1), ux * ux + uy * uy


# ----------------------------------------------------------------------------- 3D


def orient3d(a, b, c, d) -> np.ndarray:
    """Six times the signed volume of tetrahedra ``(a, b, c, d)`` (broadcast, (..., 3))."""
    return np.einsum("...i,...i->...", np.cross(b - a, c - a), d - a)


def segment_hits_triangle(p, q, a, b, c) -> np.ndarray:
    """Whether closed segments ``p q`` meet triangles ``a b c`` (broadcast, (..., 3)).

    A touch counts. Coplanar configurations are reported as no hit (the callers
    use this on generic data: a bone against a surface, or two surface triangles),
    coplanar to rounding included: an end within ``1e-12`` relative of the
    triangle's plane is on it (two coplanar triangles of a cylinder's flat quads,
    meeting at a vertex, were once reported as crossing).
    """
    sp = orient3d(a, b, c, p)
    sq = orient3d(a, b, c, q)
    area2 = np.linalg.norm(np.cross(b - a, c - a), axis=-1)
    reach = np.maximum(np.linalg.norm(p - a, axis=-1), np.linalg.norm(q - a, axis=-1))
    flat = 1e-12 * area2 * np.maximum(reach, np.linalg.norm(b - a, axis=-1))
    sp = np.where(np.abs(sp) <= flat, 0.0, sp)
    sq = np.where(np.abs(sq) <= flat, 0.0, sq)
    straddle = ((sp >= 0) & (sq <= 0)) | ((sp <= 0) & (sq >= 0))
    straddle &= ~((sp == 0) & (sq == 0))
    s1 = orient3d(p, q, a, b)
    s2 = orient3d(p, q, b, c)
    s3 = orient3d(p, q, c, a)
    same = ((s1 >= 0) & (s2 >= 0) & (s3 >= 0)) | ((s1 <= 0) & (s2 <= 0) & (s3 <= 0))
    return straddle & same
