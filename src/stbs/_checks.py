"""Input validation at the public boundary (STYLE habit 3: check once, trust inside).

Every function raises ``ValueError`` (or ``TypeError``) whose message names the
argument, what was expected and what arrived. The array checks themselves live in
:mod:`stbs._arrays` (re-exported here), so that :mod:`stbs.skeleton` can use them while
this module checks skeleton arguments against :class:`stbs.Skeleton`.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from typing import Any

import numpy as np
import scipy.sparse as sp

from ._arrays import index_array, real_array
from .skeleton import Skeleton

__all__ = ["choice", "real_array", "index_array", "bone_list", "vertices", "skeleton",
           "bone_weights", "endpoint_weights", "dtype_choice", "PARTITION_TOL", "NEGATIVE_TOL"]

#: Tolerance on row sums of W before rows are renormalised (with a warning).
PARTITION_TOL = 1e-6
#: Negative weights down to this value are treated as rounding and clipped to 0.
NEGATIVE_TOL = 1e-10


def choice(name: str, value: Any, valid: Sequence[str]) -> str:
    """Return ``value`` if it is one of ``valid``, else raise naming the choices."""
    if not isinstance(value, str) or value not in valid:
        raise ValueError(f"{name} must be one of {', '.join(map(repr, valid))}, got {value!r}")
    return value


def vertices(V: Any, *, name: str = "V") -> np.ndarray:
    """Rest positions ``V`` (n, d) with d in {2, 3}, as float64."""
    a = real_array(name, V, ndim=2)
    if a.shape[1] not in (2, 3):
        raise ValueError(f"{name} must have shape (n, 2) or (n, 3), got {a.shape}")
    if a.shape[0] == 0:
        raise ValueError(f"{name} must hold at least one vertex, got shape {a.shape}")
    return a


def skeleton(sk: Any, V: Any = None, *, name: str = "V") -> np.ndarray | None:
    """Check that ``sk`` is a :class:`stbs.Skeleton` and, given ``V``, that it fits it.

    The one check of a skeleton argument (the weights functions all call it), so a
    wrong one reads the same everywhere: ``TypeError`` for something that is not a
    Skeleton, ``ValueError`` when ``V`` (validated by :func:`vertices`) has not
    ``sk.dim`` columns. Returns ``V`` as float64 (None when not given).
    """
    if not isinstance(sk, Skeleton):
        raise TypeError(f"sk must be a stbs.Skeleton, got {type(sk).__name__}")
    if V is None:
        return None
    V = vertices(V, name=name)
    if V.shape[1] != sk.dim:
        raise ValueError(f"{name} must have shape ({V.shape[0]}, {sk.dim}) to match the "
                         f"{sk.dim}D skeleton sk, got {V.shape}")
    return V


def _dense_or_sparse(name: str, X: Any, n: int, b: int) -> np.ndarray | sp.csr_array:
    if sp.issparse(X):
        X = sp.csr_array(X, dtype=np.float64)
        if X.shape != (n, b):
            raise ValueError(f"{name} must have shape ({n}, {b}), got {X.shape}")
        if not np.all(np.isfinite(X.data)):
            raise ValueError(f"{name} must be finite, got non-finite stored values")
        return X
    if n and b and np.ndim(X) == 1 and b == 1:
        X = np.asarray(X).reshape(-1, 1)
    return real_array(name, X, shape=(n, b))


def bone_weights(W: Any, n: int, b: int, *, name: str = "W") -> np.ndarray | sp.csr_array:
    """Validate bone weights (n, b): no negatives, rows summing to 1.

    Policy (documented in docs/weights.md): entries below ``-NEGATIVE_TOL`` are
    an error; tiny negatives from solvers are clipped to 0. A row summing to 0 is
    an error (that vertex follows no bone). Rows whose sum differs from 1 by more
    than ``PARTITION_TOL`` are renormalised with a ``UserWarning``, as libigl's
    tutorials do for painted weights.
    """
    X = _dense_or_sparse(name, W, n, b)
    data = X.data if sp.issparse(X) else X
    if data.size and data.min() < -NEGATIVE_TOL:
        if sp.issparse(X):
            coo = X.tocoo()
            k = int(np.argmin(coo.data))
            where = (int(coo.row[k]), int(coo.col[k]))
        else:
            where = tuple(int(i) for i in np.unravel_index(np.argmin(X), X.shape))
        raise ValueError(f"{name} must be >= 0, got {data.min():.6g} at (vertex, bone) = {where}")
    if data.size and data.min() < 0:
        data = np.maximum(data, 0.0)
        if sp.issparse(X):
            X = sp.csr_array((data, X.indices, X.indptr), shape=X.shape)
        else:
            X = data
    s = np.asarray(X.sum(axis=1)).ravel()
    zero = np.flatnonzero(s <= 0)
    if zero.size:
        raise ValueError(f"{name} rows must sum to 1, but row {zero[0]} sums to 0 "
                         f"({zero.size} such rows): that vertex is attached to no bone")
    off = np.abs(s - 1.0) > PARTITION_TOL
    if np.any(off):
        warnings.warn(f"{name}: {int(off.sum())} of {n} rows do not sum to 1 "
                      f"(range [{s.min():.4g}, {s.max():.4g}]); renormalising them",
                      UserWarning, stacklevel=3)
        if sp.issparse(X):
            X = sp.csr_array(sp.diags_array(1.0 / s) @ X)
        else:
            X = X / s[:, None]
    return X


def endpoint_weights(E: Any, n: int, b: int, *, name: str = "E") -> np.ndarray | sp.csr_array:
    """Validate endpoint weights (n, b) in [0, 1]; values outside are an error."""
    X = _dense_or_sparse(name, E, n, b)
    data = X.data if sp.issparse(X) else X
    if data.size:
        lo, hi = data.min(), data.max()
        if lo < -1e-12 or hi > 1 + 1e-12:
            bad = lo if lo < -1e-12 else hi
            raise ValueError(f"{name} must lie in [0, 1], got {bad:.6g}")
    return X


def dtype_choice(dtype: Any) -> np.dtype:
    """float32 or float64."""
    dt = np.dtype(dtype)
    if dt not in (np.dtype(np.float32), np.dtype(np.float64)):
        raise ValueError(f"dtype must be float32 or float64, got {dt}")
    return dt


def bone_list(bones, b: int) -> list[int]:
    """``bones`` (None: all ``b``) as a sorted list of distinct bone indices, checked."""
    if bones is None:
        return list(range(b))
    todo = np.unique(index_array("bones", bones, ndim=1)).tolist()
    if todo and (todo[0] < 0 or todo[-1] >= b):
        raise ValueError(f"bones must hold bone indices in 0..{b - 1}, got {list(bones)!r}")
    return todo


def progress(callback: Any, form: str = "progress(done, total)") -> None:
    """A ``TypeError`` unless a progress ``callback`` is None or callable."""
    if callback is not None and not callable(callback):
        raise TypeError(f"progress must be callable as {form} or None, "
                        f"got {type(callback).__name__}")
