"""Weights in request bodies: JSON rows or raw little-endian arrays, checked once.

Used by ``POST /api/save-rig`` (new ``W`` and ``E``) and by the endpoint weight
requests (the page's current ``W``). Every check names the field, the expectation and
what arrived, as a :class:`stbs.viewer.refusal.Refusal` (400).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .._checks import PARTITION_TOL
from ..rig import Rig
from .refusal import Refusal, one_line, show

__all__ = ["rows", "with_weights", "binary_weights", "json_weights", "WEIGHT_DTYPES"]

#: The dtypes raw weights may be sent in.
WEIGHT_DTYPES = ("float32", "float64")


def _what_rows(X: Any, b: int) -> str:
    """What arrived where (n, b) rows of numbers were expected: the first thing wrong."""
    if not isinstance(X, list):
        return show(X)
    for k, row in enumerate(X):
        if not isinstance(row, list):
            return f"{show(row)} as row {k}"
        if len(row) != b:
            return f"row {k} of length {len(row)}"
        for j, x in enumerate(row):
            if isinstance(x, bool) or not isinstance(x, (int, float)):
                return f"{show(x)} at [{k}][{j}]"
            if isinstance(x, int) and abs(x) >= 2**63:
                return f"{show(x)} at [{k}][{j}], too large"
    return f"{len(X)} rows"


def rows(key: str, X: Any, n: int, b: int) -> np.ndarray:
    """``X`` (JSON rows, or an array read from a binary body) as an (n, b) float64 array,
    else 400 naming the field, the expectation and what arrived."""
    A = None
    if isinstance(X, np.ndarray):
        A = X
    elif isinstance(X, list):
        try:
            A = np.array(X)     # no dtype: strings, bools and ragged rows stay visible
        except (ValueError, TypeError, OverflowError):
            A = None
    if A is None or A.dtype.kind not in "iuf" or A.ndim != 2:
        raise Refusal(400, f'"{key}": expected {n} rows of {b} numbers (vertices x bones), '
                           f"got {_what_rows(X, b)}")
    if A.shape != (n, b):
        raise Refusal(400, f"{key} must have shape ({n}, {b}) (vertices, bones), got "
                           f"{A.shape}")
    return A.astype(np.float64)


def _checked(key: str, X: np.ndarray) -> np.ndarray:
    if not np.isfinite(X).all():
        raise Refusal(400, f"{key} must be finite")
    lo, hi = float(X.min(initial=0)), float(X.max(initial=0))
    if lo < 0 or (key == "E" and hi > 1):
        raise Refusal(400, f"{key} must lie in {'[0, 1]' if key == 'E' else '[0, inf)'}, got "
                           f"{lo if lo < 0 else hi:.6g}")
    if key == "W":
        off = np.abs(X.sum(axis=1) - 1.0)
        if off.max(initial=0) > PARTITION_TOL:
            i = int(np.argmax(off))
            raise Refusal(400, f"W rows must sum to 1, row {i} sums to {X[i].sum():.6g}")
    return X


def with_weights(rig: Rig, W=None, E=None) -> Rig:
    """``rig`` with new bone and/or endpoint weights (None: kept), each checked: (n, b),
    finite, ``W`` >= 0 with rows summing to 1, ``E`` in [0, 1]."""
    n, b = len(rig.V), rig.skeleton.n_bones
    changes = {key: _checked(key, rows(key, X, n, b))
               for key, X in (("W", W), ("E", E)) if X is not None}
    try:
        return rig.replace(**changes)
    except (ValueError, TypeError) as exc:
        raise Refusal(400, one_line(exc)) from None


def json_weights(obj: Any, n: int, b: int, *, keys=("W", "E"), also=()) -> dict:
    """``{"W": [[...]], "E": [[...]]}`` (each optional) as (n, b) arrays; ``also``: other
    keys the object may hold, returned as they are."""
    if not isinstance(obj, dict) or set(obj) - {*keys, *also}:
        allowed = ", ".join(f'"{k}"' for k in (*keys, *also))
        raise Refusal(400, f"request body: expected a JSON object with {allowed} (each "
                           "optional), or raw weights with Content-Type "
                           "application/octet-stream")
    out = {k: None if obj.get(k) is None else rows(k, obj[k], n, b) for k in keys}
    out.update({k: obj[k] for k in also if k in obj})
    return out


def binary_weights(data: bytes, names_header: str | None, dtype_header: str | None,
                   n: int, b: int) -> dict:
    """Raw weights: ``X-Stbs-Arrays`` (``W``, ``E`` or ``W,E``; default ``W``) arrays of
    n x b values of ``X-Stbs-Dtype`` (float32 by default, or float64), little-endian,
    one after the other."""
    names = [s.strip() for s in (names_header or "W").split(",")]
    if not names or len(set(names)) != len(names) or set(names) - {"W", "E"}:
        raise Refusal(400, f"X-Stbs-Arrays: expected W, E or W,E, got {names!r}")
    dtype = (dtype_header or "float32").strip().lower()
    if dtype not in WEIGHT_DTYPES:
        raise Refusal(400, f"X-Stbs-Dtype: expected float32 or float64, got {dtype!r}")
    dt = np.dtype(dtype).newbyteorder("<")
    want = len(names) * n * b * dt.itemsize
    if len(data) != want:
        raise Refusal(400, f"request body: expected {want} bytes ({', '.join(names)}: "
                           f"{n} x {b} {dtype} each), got {len(data)}")
    flat = np.frombuffer(data, dtype=dt).astype(np.float64).reshape(len(names), n, b)
    got = dict(zip(names, flat, strict=True))
    return {"W": got.get("W"), "E": got.get("E")}
