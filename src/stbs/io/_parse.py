"""Small helpers shared by the readers: path checks, suffix dispatch, text blocks, ``dim``."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Literal

import numpy as np

from .._inputs import input_path as input_path  # re-exported for the readers
from .errors import FormatError

Dim = Literal["auto", 2, 3]


def suffix(path: str | os.PathLike, supported: Sequence[str], what: str) -> str:
    """Lower-case extension of ``path``; ValueError listing ``supported`` when unknown."""
    ext = Path(os.fspath(path)).suffix.lower()
    if ext not in supported:
        got = repr(ext) if ext else "no extension"
        raise ValueError(f"{what}: cannot handle {os.fspath(path)!r} ({got}); "
                         f"supported extensions are {', '.join(supported)}")
    return ext


def read_lines(p: Path) -> list[str]:
    """All lines of a text file, without line ends (LF or CRLF)."""
    # latin-1 never fails to decode; a stray byte then shows up in a parse error
    # with its line number instead of as a UnicodeDecodeError without one.
    text = p.read_bytes().decode("latin-1")
    lines = text.split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    return [s[:-1] if s.endswith("\r") else s for s in lines]


def check_dim(dim) -> Dim:
    """Validate the ``dim`` keyword."""
    if isinstance(dim, str) and dim == "auto":
        return "auto"
    if isinstance(dim, (int, np.integer)) and not isinstance(dim, bool) and int(dim) in (2, 3):
        return int(dim)  # type: ignore[return-value]
    raise ValueError(f"dim must be 'auto', 2 or 3, got {dim!r}")


def apply_dim(X: np.ndarray, dim: Dim, path: Path, what: str) -> np.ndarray:
    """Return ``X`` (n, 2|3) with the requested number of columns.

    ``"auto"`` drops a z column that is exactly 0 everywhere; ``2`` requires z == 0
    (never projects silently); ``3`` pads 2-column input with z = 0.
    """
    if X.shape[1] == 3:
        planar = X.shape[0] > 0 and not np.any(X[:, 2])
        if dim == 2 and not planar and X.shape[0] > 0:
            z = float(np.abs(X[:, 2]).max())
            raise ValueError(f"{path}: dim=2 asks for planar {what}, but z is not 0 "
                             f"everywhere (max |z| = {z:.6g}); use dim=3 or dim='auto'")
        if dim == 2 or (dim == "auto" and planar):
            return np.ascontiguousarray(X[:, :2])
        return X
    if X.shape[1] == 2 and dim == 3:
        return np.hstack([X, np.zeros((X.shape[0], 1))])
    return X


def quote(s: str) -> str:
    s = s.strip()
    return repr(s if len(s) <= 60 else s[:57] + "...")


def parse_block(path: Path, lines: Sequence[str], first_line: int | Sequence[int], ncols: int,
                what: str, *, dtype=np.float64, exact: bool = False) -> np.ndarray:
    """Parse ``lines`` (one record each) into an (m, ncols) array of ``dtype``.

    Each line needs at least ``ncols`` whitespace-separated numbers (exactly
    ``ncols`` when ``exact``); further columns are ignored. ``first_line`` is
    the 1-based line number of ``lines[0]`` (or one number per line), used in
    error messages.
    """
    toks = [s.split() for s in lines]
    try:
        if exact:
            out = np.array(toks, dtype=dtype) if toks else np.zeros((0, ncols), dtype)
            if out.ndim != 2 or out.shape[1] != ncols:
                raise ValueError
        else:
            out = np.array([t[:ncols] for t in toks], dtype=dtype)
            if toks and (out.ndim != 2 or out.shape[1] != ncols):
                raise ValueError
            out = out.reshape(len(toks), ncols)
        if dtype == np.float64 and not np.all(np.isfinite(out)):
            raise ValueError
        return out
    except (ValueError, OverflowError):
        pass
    # Slow path only to say where the problem is.
    conv = float if np.dtype(dtype).kind == "f" else int
    for k, t in enumerate(toks):
        ln = first_line + k if isinstance(first_line, int) else int(first_line[k])
        if len(t) < ncols or (exact and len(t) != ncols):
            want = f"{'exactly' if exact else 'at least'} {ncols} numbers for {what}"
            raise FormatError(path, want, f"{len(t)}: {quote(lines[k])}", line=ln)
        for x in t[:ncols]:
            try:
                v = conv(x)
            except ValueError:
                kind = "a number" if conv is float else "an integer"
                raise FormatError(path, f"{kind} in {what}", quote(x), line=ln) from None
            if conv is float and not np.isfinite(v):
                raise FormatError(path, f"a finite number in {what}", quote(x), line=ln)
    ln = first_line if isinstance(first_line, int) else (first_line[0] if first_line else None)
    raise FormatError(path, f"numbers for {what}", "unparsable data", line=ln)
