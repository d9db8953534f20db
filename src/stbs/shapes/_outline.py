"""2D outlines: the zero set of a distance field as polygons, evenly resampled."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .. import _checks

__all__ = ["outline_of_field", "resample_loop"]


def resample_loop(P, spacing: float) -> np.ndarray:
    """A closed polygon resampled at equal arc-length steps of about ``spacing``.

    Parameters
    ----------
    P : (k, 2) float
        The polygon's corners in order, the first not repeated at the end.
    spacing : float
        The wanted distance between consecutive points (> 0).

    Returns
    -------
    (m, 2) float64
        ``m = max(round(perimeter / spacing), 8)`` points, the first at ``P[0]``,
        equally spaced along the polygon's perimeter.

    Examples
    --------
    >>> from stbs.shapes import resample_loop
    >>> resample_loop([[0, 0], [2, 0], [2, 2], [0, 2]], 1.0).shape
    (8, 2)
    """
    P = _checks.real_array("P", P, ndim=2)
    if P.shape[1] != 2 or P.shape[0] < 3:
        raise ValueError(f"P must have shape (k, 2) with k >= 3, got {P.shape}")
    spacing = float(spacing)
    if not spacing > 0:
        raise ValueError(f"spacing must be > 0, got {spacing}")
    return _resample(P, spacing)


def _resample(P: np.ndarray, spacing: float) -> np.ndarray:
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


def outline_of_field(sdf: Callable[[np.ndarray], np.ndarray], lo, hi,
                     spacing: float) -> list[np.ndarray]:
    """The zero set of a 2D distance field as closed polygons with evenly spaced points.

    The field is sampled on pixels a third of ``spacing`` wide, traced by
    :func:`stbs.outline_from_image`, resampled every ``spacing``
    (:func:`resample_loop`) and moved onto the zero set by three Newton steps.
    The polygons are ready for :func:`stbs.triangulate_2d`.

    Parameters
    ----------
    sdf : callable
        ``sdf(X)`` for points ``X`` (m, 2) float64 returns (m,) signed distances,
        negative inside.
    lo, hi : (2,) float
        Corners of a box holding the shape (a margin is added).
    spacing : float
        Distance between consecutive outline points (> 0).

    Returns
    -------
    list of (k, 2) float64
        Outer boundaries counter-clockwise, holes clockwise, by decreasing area.

    Examples
    --------
    >>> import numpy as np
    >>> from stbs.shapes import capsule_sdf, outline_of_field
    >>> loops = outline_of_field(lambda X: capsule_sdf(X, [0, 0], [1, 0], 0.3),
    ...                          [-0.3, -0.3], [1.3, 0.3], 0.1)
    >>> len(loops), bool(np.abs(capsule_sdf(loops[0], [0, 0], [1, 0], 0.3)).max() < 1e-6)
    (1, True)
    """
    from ..meshing import outline_from_image

    if not callable(sdf):
        raise ValueError(f"sdf must be callable, got {type(sdf).__name__}")
    lo = _checks.real_array("lo", lo, shape=(2,))
    hi = _checks.real_array("hi", hi, shape=(2,))
    if not np.all(hi > lo):
        raise ValueError(f"hi must be greater than lo on both axes, got lo={lo.tolist()}, "
                         f"hi={hi.tolist()}")
    spacing = float(spacing)
    if not spacing > 0:
        raise ValueError(f"spacing must be > 0, got {spacing}")
    px = spacing / 3.0
    lo = lo - 4 * px
    hi = hi + 4 * px
    W, H = (np.ceil((hi - lo) / px).astype(int) + 1).tolist()
    xs = lo[0] + px * np.arange(W)
    ys = lo[1] + px * np.arange(H)[::-1]  # image row 0 is the top
    X = np.stack(np.meshgrid(xs, ys), axis=-1).reshape(-1, 2)
    img = np.clip(0.5 - sdf(X).reshape(H, W) / (4 * px), 0.0, 1.0)
    loops = outline_from_image(img, tolerance=0.0)
    # outline_from_image puts pixel (r, c) at (c, H - 1 - r): row H - 1 is y = lo.
    return [_project_2d(_resample(lo + L * px, spacing), sdf, 1e-4 * spacing)
            for L in loops]
