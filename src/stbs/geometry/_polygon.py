"""Closed 2D polygons: signed area, even-odd inclusion, area by nesting."""

from __future__ import annotations

import numpy as np


def signed_area(P) -> float:
    """Signed area of a closed polygon (shoelace formula).

    Parameters
    ----------
    P : (k, 2) float
        The polygon's corners in order; the last joins the first.

    Returns
    -------
    float
        > 0 for a counter-clockwise polygon, < 0 for a clockwise one.

    Examples
    --------
    >>> from stbs.geometry import signed_area
    >>> signed_area([[0, 0], [2, 0], [2, 1], [0, 1]])
    2.0
    """
    P = np.asarray(P, dtype=np.float64)
    x, y = P[:, 0], P[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def points_in_loops(Q, loops, *, chunk: int = 2_000_000) -> np.ndarray:
    """Even-odd inclusion of 2D points in the region bounded by closed polygons.

    A point is inside when a ray from it crosses the loops an odd number of times, so
    holes, and islands inside holes, need no labels. Points exactly on a loop get
    either answer.

    Parameters
    ----------
    Q : (q, 2) float
        Query points.
    loops : sequence of (k, 2) float
        Closed polygons, each with its last corner joined to its first.
    chunk : int, optional
        Point-edge pairs tested at once (bounds the memory used).

    Returns
    -------
    (q,) bool

    Examples
    --------
    >>> from stbs.geometry import points_in_loops
    >>> square = [[0, 0], [4, 0], [4, 4], [0, 4]]
    >>> hole = [[1, 1], [3, 1], [3, 3], [1, 3]]
    >>> points_in_loops([[0.5, 0.5], [2, 2], [5, 5]], [square, hole]).tolist()
    [True, False, False]
    """
    Q = np.asarray(Q, dtype=np.float64).reshape(-1, 2)
    loops = [np.asarray(L, dtype=np.float64) for L in loops]
    A = np.concatenate(loops)
    B = np.concatenate([np.roll(L, -1, axis=0) for L in loops])
    inside = np.zeros(Q.shape[0], dtype=bool)
    step = max(1, chunk // max(A.shape[0], 1))
    for s in range(0, Q.shape[0], step):
        q = Q[s:s + step, None, :]
        straddle = (A[None, :, 1] > q[..., 1]) != (B[None, :, 1] > q[..., 1])
        dy = np.where(straddle, B[:, 1] - A[:, 1], 1.0)
        x = A[:, 0] + (q[..., 1] - A[:, 1]) * (B[:, 0] - A[:, 0]) / dy
        inside[s:s + step] = (np.count_nonzero(straddle & (q[..., 0] < x), axis=1) % 2) == 1
    return inside


def polygons_area(polygons) -> float:
    """Area inside closed polygons read with the even-odd rule.

    A polygon inside an odd number of the others is a hole and subtracts; separate
    shapes add, and an island inside a hole adds again. Orientation does not matter.

    Parameters
    ----------
    polygons : sequence of (k, 2) float
        Closed, simple polygons that do not cross each other.

    Returns
    -------
    float
        The area (>= 0).

    Examples
    --------
    >>> from stbs.geometry import polygons_area
    >>> square = [[0, 0], [4, 0], [4, 4], [0, 4]]
    >>> hole = [[1, 1], [1, 3], [3, 3], [3, 1]]
    >>> far = [[10, 0], [11, 0], [11, 1], [10, 1]]
    >>> polygons_area([square, hole, far])
    13.0
    """
    polygons = [np.asarray(P, dtype=np.float64) for P in polygons]
    total = 0.0
    for i, P in enumerate(polygons):
        others = [Q for k, Q in enumerate(polygons) if k != i]
        depth = sum(bool(points_in_loops(P[:1], [Q])[0]) for Q in others)
        a = abs(signed_area(P))
        total += -a if depth % 2 else a
    return max(total, 0.0)
