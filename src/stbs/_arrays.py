"""Array checks at the public boundary: finite real arrays and integer index arrays.

The lowest of the package's checks: it imports nothing of stbs, so both
:mod:`stbs.skeleton` and :mod:`stbs._checks` (which re-exports these and checks skeleton
arguments) build on it without importing each other in a circle.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["real_array", "index_array"]


def _check_shape(name: str, a: np.ndarray, shape: tuple) -> None:
    """``shape`` may hold ``None`` for a free axis."""
    if a.ndim != len(shape) or any(
            s is not None and s != t for s, t in zip(shape, a.shape, strict=True)):
        want = "(" + ", ".join("?" if s is None else str(s) for s in shape) + ")"
        raise ValueError(f"{name} must have shape {want}, got {a.shape}")


def real_array(name: str, x: Any, *, ndim: int | None = None, shape: tuple | None = None,
               dtype=np.float64) -> np.ndarray:
    """Convert ``x`` to a finite float array, checking ``ndim`` and ``shape``.

    ``shape`` may hold ``None`` for a free axis.
    """
    try:
        a = np.asarray(x, dtype=dtype)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a numeric array, got {type(x).__name__}: {exc}") from None
    if ndim is not None and a.ndim != ndim:
        raise ValueError(f"{name} must be a {ndim}-D array, got shape {a.shape}")
    if shape is not None:
        _check_shape(name, a, shape)
    if not np.all(np.isfinite(a)):
        bad = np.argwhere(~np.isfinite(a))[0]
        at = tuple(int(i) for i in bad)
        raise ValueError(f"{name} must be finite, got {a[at]} at index {at}")
    return a


def index_array(name: str, x: Any, *, ndim: int, shape: tuple | None = None) -> np.ndarray:
    """Convert ``x`` to an int64 index array; floats must be whole numbers."""
    a = np.asarray(x)
    if a.size == 0:
        a = a.astype(np.int64)
    if a.dtype.kind == "f":
        if not np.all(np.isfinite(a)) or np.any(a != np.round(a)):
            raise ValueError(f"{name} must hold integer indices, got non-integer values")
    elif a.dtype.kind not in "iu":
        raise ValueError(f"{name} must be an integer array, got dtype {a.dtype}")
    a = a.astype(np.int64)
    if a.ndim != ndim:
        raise ValueError(f"{name} must be a {ndim}-D array, got shape {a.shape}")
    if shape is not None:
        _check_shape(name, a, shape)
    return a
