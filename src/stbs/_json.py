"""JSON from strangers, parsed safely (poses, clips, mappings, manifests, glTF documents,
the viewer's request bodies).

Python's parser recurses on nesting, converts integers of any length and accepts
``NaN``; :func:`load_json` checks the nesting first, without recursion (a byte scan),
and refuses long integers, numbers that are not finite and, on request, repeated keys,
each as one :class:`JsonError` naming the document.
"""

from __future__ import annotations

import json
import math
import os
import re
from pathlib import Path
from typing import Any

import numpy as np

from ._inputs import input_path

__all__ = ["load_json", "read_json", "JsonError", "JSON_MAX_DEPTH", "JSON_MAX_DIGITS",
           "JSON_MAX_BYTES"]

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


def load_json(data: str | bytes, where: str, *, what: str = "JSON",
              unique_keys: bool = False) -> Any:
    """Parse a JSON document from a file or request ``where`` names, safely.

    Refused with one :class:`JsonError` naming ``where``: text that is not UTF-8,
    nesting deeper than :data:`JSON_MAX_DEPTH` (checked before parsing, without
    recursion), integers longer than :data:`JSON_MAX_DIGITS` digits, numbers that are
    not finite (``NaN``, ``Infinity``, ``1e999``), invalid JSON (with its line and
    column) and, with ``unique_keys``, a key repeated in an object (which JSON parsers
    otherwise keep silently, the last one winning).
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
    hooks: dict[str, Any] = {"parse_constant": constant}
    if unique_keys:
        hooks["object_pairs_hook"] = _unique
    if suspect:
        hooks.update(parse_float=number, parse_int=integer)
    try:
        return json.loads(text, **hooks)
    except _Bad as exc:
        raise JsonError(f"{where}: expected {what} with {exc}") from None
    except _Repeated as exc:
        raise JsonError(f"{where}: expected each key once in a JSON object, found "
                        f"{_short(exc.args[0])} twice") from None
    except json.JSONDecodeError as exc:
        raise JsonError(f"{where}, line {exc.lineno}, column {exc.colno}: not valid {what} "
                        f"({exc.msg})") from None
    except RecursionError:      # not reached after the depth check; kept as a guard
        raise JsonError(f"{where}: {what} nested too deeply") from None


class _Bad(Exception):
    pass


class _Repeated(Exception):
    pass


def _unique(pairs: list[tuple[str, Any]]) -> dict:
    seen: set[str] = set()
    for k, _ in pairs:
        if k in seen:
            raise _Repeated(k)
        seen.add(k)
    return dict(pairs)


def _short(key: str) -> str:
    return json.dumps(key if len(key) <= 60 else key[:57] + "...")


#: JSON files (poses, clips, manifests, mappings) larger than this are refused unread.
JSON_MAX_BYTES = 256 * 2**20


def read_json(path: str | os.PathLike, what: str, *, unique_keys: bool = False
              ) -> tuple[Path, Any]:
    """A JSON file read with :func:`load_json` (``what`` names it in errors;
    ``unique_keys``: a key repeated in an object is an error), noted as an input of the
    run; its size is checked against :data:`JSON_MAX_BYTES` first."""
    p = input_path(path, what)
    size = p.stat().st_size
    if size > JSON_MAX_BYTES:
        raise JsonError(f"{p}: expected a {what} file of at most {JSON_MAX_BYTES >> 20} MiB, "
                        f"found {size >> 20} MiB")
    return p, load_json(p.read_bytes(), str(p), what=f"{what} JSON", unique_keys=unique_keys)
