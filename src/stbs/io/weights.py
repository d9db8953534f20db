"""Read a weight matrix (``W``, ``E`` or joint weights ``J``) from a file."""

from __future__ import annotations

import os
import zipfile
import zlib

import numpy as np
import scipy.sparse as sp

from ._npz import Budget
from ._parse import input_path, parse_block, read_lines, suffix
from .dmat import read_dmat
from .errors import FormatError

__all__ = ["read_weights", "WEIGHT_READ_EXTENSIONS"]

#: Extensions :func:`read_weights` understands.
WEIGHT_READ_EXTENSIONS = (".dmat", ".npy", ".npz", ".csv")

_SPARSE_KEYS = {"format", "shape", "data", "indices", "indptr"}


def _as_matrix(p, X, where: str):
    if sp.issparse(X):
        X = sp.csr_array(X, dtype=np.float64)
        if not np.all(np.isfinite(X.data)):
            raise FormatError(p, f"finite weights in {where}", "non-finite stored values")
        return X
    X = np.asarray(X)
    if X.dtype.kind not in "fiub":
        raise FormatError(p, f"a numeric array in {where}", f"dtype {X.dtype}")
    X = X.astype(np.float64)
    if X.ndim == 1:
        X = X[:, None]
    if X.ndim != 2:
        raise FormatError(p, f"a 1-D or 2-D array (n, b) in {where}", f"shape {X.shape}")
    if not np.all(np.isfinite(X)):
        bad = tuple(int(i) for i in np.argwhere(~np.isfinite(X))[0])
        raise FormatError(p, f"finite weights in {where}", f"{X[bad]} at (row, col) = {bad}")
    return np.ascontiguousarray(X)


def read_weights(path: str | os.PathLike):
    """Read an (n, b) weight matrix: one row per vertex, one column per bone (or joint).

    Parameters
    ----------
    path : str or os.PathLike
        - ``.dmat``: libigl DMAT, ASCII or binary (:func:`read_dmat`);
        - ``.npy``: one numeric array (read with ``allow_pickle=False``);
        - ``.npz``: a single array, or the array under key ``W``, or a sparse
          matrix saved by ``scipy.sparse.save_npz``;
        - ``.csv``: comma-separated rows, no header, ``#`` comments.

    Returns
    -------
    W : (n, b) float64 ndarray, or scipy.sparse.csr_array for a sparse ``.npz``
        A 1-D array is returned as one column. Values are returned as stored:
        partition of unity and bounds are checked (and rows renormalised with
        a warning) where the weights are used, not here, because some real
        files are unnormalised (``hand.dmat``, ``woody.dmat``).

    Raises
    ------
    FileNotFoundError
        ``path`` does not exist.
    ValueError
        Unknown extension (the message lists the supported ones).
    FormatError
        Malformed or empty file, non-numeric or non-finite data, an ``.npz``
        holding several arrays but no ``W``, or object arrays (never unpickled).
    """
    ext = suffix(path, WEIGHT_READ_EXTENSIONS, "read_weights")
    p = input_path(path, "weights")
    if p.stat().st_size == 0:
        raise FormatError(p, f"a {ext} weight matrix", "an empty file")
    if ext == ".dmat":
        return read_dmat(p)
    if ext == ".csv":
        return _read_csv(p)
    # np.load is given an open handle so that a broken archive cannot leak it.
    with open(p, "rb") as fh:
        if ext == ".npy":
            return _as_matrix(p, Budget(p).npy(fh), "the .npy array")
        try:
            obj = np.load(fh, allow_pickle=False)
        except (ValueError, OSError, EOFError, zipfile.BadZipFile) as exc:
            raise FormatError(p, f"a NumPy {ext} file without pickled objects",
                              f"an unreadable file ({exc})") from None
        if not hasattr(obj, "files"):
            raise FormatError(p, "an .npz archive", f"a {type(obj).__name__}")
        with obj:
            try:
                return _from_npz(p, obj)
            except (zipfile.BadZipFile, zlib.error, OSError, EOFError) as exc:
                raise FormatError(p, "an undamaged .npz archive", str(exc)) from None


def _from_npz(p, obj):
    keys = list(obj.files)
    budget = Budget(p)
    try:
        if _SPARSE_KEYS <= set(keys):
            for k in _SPARSE_KEYS:
                budget.check_member(obj, k)
            return _as_matrix(p, sp.load_npz(p), "the sparse matrix")
        if "W" in keys:
            return _as_matrix(p, budget.npz_member(obj, "W"), "key 'W'")
        if len(keys) == 1:
            return _as_matrix(p, budget.npz_member(obj, keys[0]), f"key {keys[0]!r}")
    except ValueError as exc:
        if isinstance(exc, FormatError):
            raise
        raise FormatError(p, "numeric arrays without pickled objects", str(exc)) from None
    raise FormatError(p, "an .npz with a single array or the key 'W'",
                      f"keys {keys}" if keys else "no arrays")


def _read_csv(p) -> np.ndarray:
    lines = read_lines(p)
    recs = [(k + 1, s.split("#", 1)[0].replace(",", " ")) for k, s in enumerate(lines)]
    recs = [(k, s) for k, s in recs if s.strip()]
    if not recs:
        raise FormatError(p, "comma-separated rows of numbers", "no data")
    ncols = len(recs[0][1].split())
    X = parse_block(p, [s for _, s in recs], [k for k, _ in recs], ncols,
                    "a comma-separated row", exact=True)
    return np.ascontiguousarray(X)
