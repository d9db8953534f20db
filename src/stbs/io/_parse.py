"""Small helpers shared by the readers: path checks, suffix dispatch, text blocks, ``dim``."""

from __future__ import annotations

import errno
import json
import math
import os
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Literal

import numpy as np

from ._inputs import note_input
from .errors import FormatError

Dim = Literal["auto", 2, 3]


def input_path(path: str | os.PathLike, what: str) -> Path:
    """``path`` as a Path that exists and is a file, else FileNotFoundError/IsADirectoryError."""
    try:
        p = Path(os.fspath(path))
    except TypeError:
        raise TypeError(f"{what} path must be a str or os.PathLike, "
                        f"got {type(path).__name__}") from None
    if not p.exists():
        raise FileNotFoundError(errno.ENOENT, f"{what} file not found", str(p))
    if p.is_dir():
        raise IsADirectoryError(errno.EISDIR, f"{what} path is a folder, expected a file", str(p))
    note_input(p)
    return p


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


#: JSON documents stbs reads (poses, clips, manifests, mappings, glTF, request bodies)
#: may nest at most this deep; real ones nest under 10.
JSON_MAX_DEPTH = 64
#: Integers in JSON documents may have at most this many digits (beyond it they are not
#: indices, counts or coordinates, and Python would spend time converting them).
JSON_MAX_DIGITS = 20
_JSON_STRING = re.compile(rb'"(?:[^"\\]|\\.)*"', re.DOTALL)


class JsonError(ValueError):
    """A document that is not JSON stbs accepts; the message names it."""


_STEP = np.zeros(256, dtype=np.int8)
_STEP[[ord("["), ord("{")]] = 1
_STEP[[ord("]"), ord("}")]] = -1
_DIGIT = np.zeros(256, dtype=bool)
_DIGIT[ord("0"):ord("9") + 1] = True


def _json_scan(bare: bytes) -> tuple[int, bool]:
    """For a document with its strings emptied: the deepest nesting of arrays and
    objects (counted without recursion), and whether it holds a run of more than
    JSON_MAX_DIGITS digits or an exponent of 3 digits (a number that may be too long
    or not finite)."""
    a = np.frombuffer(bare, dtype=np.uint8)
    if a.size == 0:
        return 0, False
    depth = int(np.cumsum(_STEP[a], dtype=np.int64).max())
    d = np.concatenate([[False], _DIGIT[a], [False]])
    edges = np.flatnonzero(d[1:] != d[:-1])
    runs = edges[1::2] - edges[::2]
    long_run = bool(runs.size and runs.max() > JSON_MAX_DIGITS)
    e = np.flatnonzero((a == ord("e")) | (a == ord("E")))
    pad = np.concatenate([_DIGIT[a], np.zeros(5, dtype=bool)])
    sign = np.concatenate([(a == ord("+")) | (a == ord("-")), np.zeros(5, dtype=bool)])
    big_exp = bool(np.any((pad[e + 1] & pad[e + 2] & pad[e + 3])
                          | (sign[e + 1] & pad[e + 2] & pad[e + 3] & pad[e + 4])))
    return max(depth, 0), long_run or big_exp


def load_json(data: str | bytes, where: str, *, what: str = "JSON") -> Any:
    """Parse a JSON document from a file or request ``where`` names, safely.

    Refused with one :class:`JsonError` naming ``where``: text that is not UTF-8,
    nesting deeper than :data:`JSON_MAX_DEPTH` (checked before parsing, without
    recursion), integers longer than :data:`JSON_MAX_DIGITS` digits, numbers that are
    not finite (``NaN``, ``Infinity``, ``1e999``) and invalid JSON (with its line and
    column).
    """
    if isinstance(data, str):
        raw = data.encode("utf-8", "surrogatepass")
        text = data
    else:
        raw = bytes(data)
        try:
            text = raw.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise JsonError(f"{where}: expected UTF-8 {what} text, found an undecodable byte "
                            f"at offset {exc.start}") from None
    bare = _JSON_STRING.sub(b'""', raw)
    depth, suspect = _json_scan(bare)
    if depth > JSON_MAX_DEPTH:
        raise JsonError(f"{where}: expected {what} nested at most {JSON_MAX_DEPTH} deep, "
                        f"found nesting {depth} deep")

    def number(s: str) -> float:
        v = float(s)
        if not math.isfinite(v):
            raise _Bad(f"a finite number, found {s[:40]!r}")
        return v

    def integer(s: str) -> int:
        if len(s.lstrip("-")) > JSON_MAX_DIGITS:
            raise _Bad(f"integers of at most {JSON_MAX_DIGITS} digits, found one of "
                       f"{len(s.lstrip('-'))} digits")
        return int(s)

    def constant(s: str):
        raise _Bad(f"finite numbers, found {s}")

    # The number hooks cost time; only documents with a long digit run or a 3-digit
    # exponent (where an integer may be too long or a number not finite) need them.
    hooks = {"parse_constant": constant}
    if suspect:
        hooks.update(parse_float=number, parse_int=integer)
    try:
        return json.loads(text, **hooks)
    except _Bad as exc:
        raise JsonError(f"{where}: expected {what} with {exc}") from None
    except json.JSONDecodeError as exc:
        raise JsonError(f"{where}, line {exc.lineno}, column {exc.colno}: not valid {what} "
                        f"({exc.msg})") from None
    except RecursionError:      # not reached after the depth check; kept as a guard
        raise JsonError(f"{where}: {what} nested too deeply") from None


class _Bad(Exception):
    pass


def read_json(path: str | os.PathLike, what: str) -> tuple[Path, Any]:
    """A JSON file read with :func:`load_json` (``what`` names it in errors), after
    :func:`input_path`; its size is checked against :data:`JSON_MAX_BYTES` first."""
    p = input_path(path, what)
    size = p.stat().st_size
    if size > JSON_MAX_BYTES:
        raise JsonError(f"{p}: expected a {what} file of at most {JSON_MAX_BYTES >> 20} MiB, "
                        f"found {size >> 20} MiB")
    return p, load_json(p.read_bytes(), str(p), what=f"{what} JSON")


#: JSON files (poses, clips, manifests, mappings) larger than this are refused unread.
JSON_MAX_BYTES = 256 * 2**20
