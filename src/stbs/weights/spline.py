"""Spline filters on endpoint weights (paper Fig. 10): ``e_i <- f(e_i)`` per bone.

``f`` is the monotone cubic (Fritsch–Carlson / PCHIP) interpolant of control points
``(x, y)`` in the unit square, with ``f(0) = 0`` and ``f(1) = 1`` always among them,
so a filtered endpoint weight is still 0 at ``a_i``, 1 at ``b_i``, in [0, 1] and as
smooth as before away from the control points (C1 there). With no control points
``f`` is the identity.

Example (Fig. 10, a spine bone from the hips ``a`` to the neck ``b``, twisted at
``b``): ``SplineFilter([(0.25, 0.6), (0.5, 0.9)])`` makes ``f`` rise quickly
over small ``e`` (the abdomen) and stay near 1 over large ``e`` (the chest), so
the twist happens in the abdomen and the chest turns almost rigidly.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import scipy.sparse as sp

from .. import _checks
from ..skeleton import Skeleton

__all__ = ["SplineFilter", "spline_filter"]


class SplineFilter:
    """A monotone curve ``f: [0, 1] -> [0, 1]`` with ``f(0) = 0``, ``f(1) = 1``.

    Parameters
    ----------
    points : (k, 2) float, optional
        Control points ``(x, y)`` in [0, 1]^2, in any order. ``(0, 0)`` and ``(1, 1)``
        are added when absent. ``y`` must not decrease as ``x`` increases; ``x``
        values must be distinct. None or empty: the identity.

    Raises
    ------
    ValueError
        For points outside the unit square, repeated ``x``, a decreasing ``y``, or an
        end point other than ``(0, 0)`` / ``(1, 1)``; the message names the point.

    Examples
    --------
    >>> import numpy as np
    >>> f = SplineFilter([(0.25, 0.6), (0.5, 0.9)])
    >>> f(np.array([[0.0], [0.25], [0.5], [1.0]]))[:, 0]    # E (n, b) -> f(E)
    array([0. , 0.6, 0.9, 1. ])
    """

    def __init__(self, points=None):
        P = np.zeros((0, 2)) if points is None else np.asarray(points, dtype=float)
        if P.size == 0:
            P = np.zeros((0, 2))
        P = _checks.real_array("points", P, ndim=2, shape=(None, 2))
        out = np.flatnonzero(((P < 0) | (P > 1)).any(axis=1))
        if out.size:
            raise ValueError(f"points must lie in [0, 1]^2, got {P[out[0]].tolist()} "
                             f"(point {out[0]})")
        P = P[np.argsort(P[:, 0], kind="stable")]
        dup = np.flatnonzero(np.diff(P[:, 0]) == 0)
        if dup.size:
            raise ValueError(f"points must have distinct x, got x = {P[dup[0], 0]} twice")
        for x, y in ((0.0, 0.0), (1.0, 1.0)):
            at = np.flatnonzero(P[:, 0] == x)
            if at.size and P[at[0], 1] != y:
                raise ValueError(f"points: f({x:g}) must be {y:g} (endpoint weights stay 0 at "
                                 f"a and 1 at b), got the point {P[at[0]].tolist()}")
        if not np.any(P[:, 0] == 0.0):
            P = np.vstack([[0.0, 0.0], P])
        if not np.any(P[:, 0] == 1.0):
            P = np.vstack([P, [1.0, 1.0]])
        drop = np.flatnonzero(np.diff(P[:, 1]) < 0)
        if drop.size:
            k = int(drop[0])
            raise ValueError(f"points must be monotone (y non-decreasing in x), but y drops "
                             f"from {P[k].tolist()} to {P[k + 1].tolist()}")
        self.points = P
        self.points.setflags(write=False)
        self._identity = P.shape[0] == 2 or bool(np.all(P[:, 0] == P[:, 1]))
        if not self._identity:
            from scipy.interpolate import PchipInterpolator
            self._f = PchipInterpolator(P[:, 0], P[:, 1], extrapolate=False)

    @property
    def is_identity(self) -> bool:
        """True when ``f(x) = x`` (no control points off the diagonal)."""
        return self._identity

    def __call__(self, E):
        """Apply ``f`` entry-wise; dense stays dense, sparse stays sparse.

        Parameters
        ----------
        E : array_like or scipy.sparse, values in [0, 1]

        Returns
        -------
        Same shape (and sparsity) as ``E``, float64.
        """
        if sp.issparse(E):
            X = sp.csr_array(E, dtype=np.float64, copy=True)
            X.data = self._apply(X.data)    # f(0) = 0 keeps the sparsity pattern
            return X
        return self._apply(np.asarray(E, dtype=float))

    def _apply(self, x: np.ndarray) -> np.ndarray:
        if x.size and (np.nanmin(x) < -1e-12 or np.nanmax(x) > 1 + 1e-12):
            bad = np.nanmin(x) if np.nanmin(x) < 0 else np.nanmax(x)
            raise ValueError(f"E must lie in [0, 1] to be filtered, got {bad:.6g}")
        x = np.clip(x, 0.0, 1.0)
        if self._identity:
            return x.copy()
        y = np.clip(self._f(x), 0.0, 1.0)
        # Exact ends (the cubic may round 1 to 1 - 1e-16): e stays 1 at b.
        return np.where(x == 1.0, 1.0, np.where(x == 0.0, 0.0, y))

    def __repr__(self) -> str:
        inner = self.points[1:-1].tolist()
        return f"SplineFilter({inner})"


def _as_filter(f: Any) -> SplineFilter:
    return f if isinstance(f, SplineFilter) else SplineFilter(f)


def spline_filter(E, filters, *, bones: Sequence[int | str] | None = None,
                  sk: Skeleton | None = None):
    """Filter endpoint weights per bone: ``E[:, i] <- f_i(E[:, i])``.

    Parameters
    ----------
    E : (n, b) float, dense or scipy.sparse
        Endpoint weights in [0, 1].
    filters : SplineFilter, (k, 2) control points, or mapping
        One filter for the bones in ``bones``, or a mapping ``{bone: filter or
        points}`` with a filter per bone (then ``bones`` must be None).
    bones : sequence of int or str, optional
        Bones (indices, or names with ``sk``) the single filter applies to; default all.
    sk : Skeleton, optional
        Needed to name bones by name; its bone count must match ``E``.

    Returns
    -------
    (n, b) float64
        A new array (sparse in, sparse out); unfiltered columns are copied.
    """
    if sk is not None:
        _checks.skeleton(sk)
    sparse = sp.issparse(E)
    if sparse:
        X = sp.csc_array(E, dtype=np.float64, copy=True)
    else:
        X = np.array(_checks.real_array("E", E, ndim=2), dtype=float)
    n, b = X.shape
    if sk is not None and sk.n_bones != b:
        raise ValueError(f"E must have shape ({n}, {sk.n_bones}) to match the skeleton, "
                         f"got {X.shape}")
    if isinstance(filters, Mapping):
        if bones is not None:
            raise ValueError("bones must be None when filters is a mapping {bone: filter}")
        plan = {_bone(k, b, sk): _as_filter(f) for k, f in filters.items()}
    else:
        f = _as_filter(filters)
        idx = range(b) if bones is None else [_bone(k, b, sk) for k in bones]
        plan = dict.fromkeys(idx, f)
    for i, f in plan.items():
        if sparse:
            lo, hi = X.indptr[i], X.indptr[i + 1]
            X.data[lo:hi] = f(X.data[lo:hi])
        else:
            X[:, i] = f(X[:, i])
    return sp.csr_array(X) if sparse else X


def _bone(key: int | str, b: int, sk: Skeleton | None) -> int:
    if sk is not None:
        return sk.bone_index(key)
    if isinstance(key, (int, np.integer)) and not isinstance(key, bool) and 0 <= key < b:
        return int(key)
    raise ValueError(f"bone {key!r} does not exist: E has bones 0..{b - 1} "
                     "(pass sk= to name bones by name)")
