"""libigl's DMAT dense-matrix files, ASCII and binary.

ASCII::

    cols rows            <- columns first!
    v_00                 <- then rows*cols values in column-major order,
    v_10                    whitespace separated (libigl writes one per line)
    ...

Binary (libigl ``writeDMAT(..., ascii=false)``)::

    0 0\\n
    cols rows\\n
    <rows*cols little-endian float64, column-major>
"""

from __future__ import annotations

import os

import numpy as np
import scipy.sparse as sp

from .. import _checks
from ._atomic import atomic_open
from ._parse import input_path, quote, suffix
from .errors import FormatError

__all__ = ["read_dmat", "write_dmat"]


def _header(p, line: bytes, ln: int) -> tuple[int, int]:
    t = line.split()
    try:
        if len(t) != 2:
            raise ValueError
        cols, rows = int(t[0]), int(t[1])
        if cols < 0 or rows < 0:
            raise ValueError
    except ValueError:
        raise FormatError(p, "a header 'cols rows' of two non-negative integers",
                          quote(line.decode("latin-1")), line=ln) from None
    return rows, cols


def read_dmat(path: str | os.PathLike) -> np.ndarray:
    """Read a DMAT matrix (ASCII or binary).

    Parameters
    ----------
    path : str or os.PathLike
        A ``.dmat`` file (any extension is accepted).

    Returns
    -------
    X : (rows, cols) float64
        C-contiguous. Note the file header says ``cols rows``.

    Raises
    ------
    FileNotFoundError
        ``path`` does not exist.
    FormatError
        Empty file, a bad header, a non-number or non-finite value, fewer or
        more values than ``rows * cols`` (ASCII), or a payload that is not
        ``8 * rows * cols`` bytes (binary).
    """
    p = input_path(path, "matrix")
    data = p.read_bytes()
    if not data.strip():
        raise FormatError(p, "a header 'cols rows'", "an empty file")
    nl = data.find(b"\n")
    nl = len(data) if nl < 0 else nl
    rows, cols = _header(p, data[:nl], 1)
    rest = data[nl + 1:]
    if rows == 0 and cols == 0 and rest.strip():
        return _read_binary(p, rest)
    text = rest.decode("latin-1")
    toks = text.split()
    want = rows * cols
    if len(toks) != want:
        raise FormatError(p, f"{want} values after the header '{cols} {rows}' (cols rows)",
                          f"{len(toks)} values{' (truncated?)' if len(toks) < want else ''}")
    try:
        vals = np.array(toks, dtype=np.float64)
        if not np.all(np.isfinite(vals)):
            raise ValueError
    except ValueError:
        _locate_bad_value(p, text)
        raise
    return np.ascontiguousarray(vals.reshape(cols, rows).T)


def _locate_bad_value(p, text: str) -> None:
    """Raise a FormatError naming the line of the first non-number or non-finite value."""
    for k, line in enumerate(text.split("\n")):
        for tok in line.split():
            try:
                v = float(tok)
            except ValueError:
                raise FormatError(p, "a number", quote(tok), line=k + 2) from None
            if not np.isfinite(v):
                raise FormatError(p, "a finite number", quote(tok), line=k + 2)


def _read_binary(p, rest: bytes) -> np.ndarray:
    nl = rest.find(b"\n")
    if nl < 0:
        raise FormatError(p, "a second header line 'cols rows' after '0 0' (binary DMAT)",
                          "end of file", line=2)
    rows, cols = _header(p, rest[:nl], 2)
    payload = rest[nl + 1:]
    want = 8 * rows * cols
    if len(payload) != want:
        raise FormatError(p, f"{want} bytes of float64 for {rows} rows x {cols} cols after the "
                          "binary header", f"{len(payload)} bytes"
                          f"{' (truncated)' if len(payload) < want else ''}")
    vals = np.frombuffer(payload, dtype="<f8").astype(np.float64)
    if not np.all(np.isfinite(vals)):
        k = int(np.flatnonzero(~np.isfinite(vals))[0])
        raise FormatError(p, "finite values", f"{vals[k]} at row {k % rows}, col {k // rows}")
    return np.ascontiguousarray(vals.reshape(cols, rows).T)


def write_dmat(path: str | os.PathLike, X, *, binary: bool = False) -> None:
    """Write a matrix as DMAT, atomically.

    Parameters
    ----------
    path : str or os.PathLike
        Destination ``.dmat`` file; its folder must exist.
    X : (rows, cols) float, or (rows,) as one column; dense or scipy.sparse
        Finite values.
    binary : bool, keyword-only
        False (default): ASCII, one value per line, shortest text that reads
        back to the same float64. True: libigl's binary variant (little-endian
        float64), smaller and faster.

    Raises
    ------
    ValueError
        Wrong extension, non-2-D or non-finite ``X``.
    """
    suffix(path, (".dmat",), "write_dmat")
    if sp.issparse(X):
        X = X.toarray()
    X = _checks.real_array("X", X)
    if X.ndim == 1:
        X = X[:, None]
    if X.ndim != 2:
        raise ValueError(f"X must be a 1-D or 2-D array, got shape {X.shape}")
    rows, cols = X.shape
    colmajor = np.ascontiguousarray(X.T)
    with atomic_open(path, "wb") as f:
        if binary:
            f.write(f"0 0\n{cols} {rows}\n".encode("ascii"))
            f.write(colmajor.astype("<f8").tobytes())
        else:
            f.write(f"{cols} {rows}\n".encode("ascii"))
            f.write("".join(f"{v!r}\n" for v in colmajor.ravel().tolist()).encode("ascii"))
