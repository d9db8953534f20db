"""The glTF 2.0 container both ways: the JSON document, GLB chunks and buffers.

:class:`GltfFile` opens a ``.gltf`` or ``.glb`` for reading; :func:`glb_bytes` writes
a GLB. The container is parsed here rather than by a library because the reader must
be safe on files from anywhere, and the rules are short enough to own:

- a GLB's header and chunk lengths are checked against the file's size before any
  slicing; the JSON chunk comes first, at most one BIN chunk follows, others are
  skipped (as the specification asks);
- the JSON is parsed by the safe loader (:func:`stbs._json.load_json`): numbers
  that are not finite (``NaN``, ``Infinity``, ``1e999``), integers of more than 20
  digits and nesting deeper than 64 are one error, not a crash (nor a copy written
  back that no JSON reader reads);
- a buffer is opened the first time an accessor needs it, never before, so a rig
  read never touches the buffers only animations or images use. Its URI is a
  ``data:`` URI or a relative path that stays inside the file's own folder (no
  scheme, no absolute path, no ``..`` or symbolic link leading out), and its declared
  ``byteLength`` is checked against the bytes really there (the GLB chunk, the
  data URI's length, the file's size) before anything is decoded;
- every array decoded from the file is counted against a budget of
  :data:`BUDGET_BASE` plus :data:`BUDGET_FACTOR` times the bytes of the file and the
  buffers opened, so a small file cannot make the reader allocate gigabytes (an
  accessor's ``count`` with no data behind it, a weights matrix over a hundred
  thousand joint nodes, an animation keyed over thousands of bones).

Every problem is a :class:`stbs.io.FormatError` naming the file, what was expected
and what was found.
"""

from __future__ import annotations

import base64
import binascii
import json
import os
import re
import struct
from pathlib import Path
from typing import Any
from urllib.parse import unquote

from ..._inputs import note_input
from ..._json import load_json
from .._parse import input_path
from ..errors import FormatError

__all__ = ["GltfFile", "glb_bytes", "pad4", "BUDGET_BASE", "BUDGET_FACTOR"]

#: Arrays decoded from one file may take this many bytes plus BUDGET_FACTOR times the
#: file's own bytes (and those of the buffers it opened).
BUDGET_BASE = 256 * 2**20
BUDGET_FACTOR = 32

_GLB_MAGIC = b"glTF"
_JSON, _BIN = 0x4E4F534A, 0x004E4942
_SCHEME = re.compile(r"^[A-Za-z][A-Za-z0-9+.\-]*:")
_MISSING = object()


def pad4(data: bytes | bytearray, fill: bytes = b"\0") -> bytes:
    """``data`` padded with ``fill`` to a multiple of 4 bytes (GLB chunks, buffer views)."""
    return bytes(data) + fill * (-len(data) % 4)


def glb_bytes(doc: dict, blob: bytes | None) -> bytes:
    """A GLB file: the 12-byte header, the JSON chunk (space-padded) and, when ``blob``
    is given, the BIN chunk (zero-padded), each to 4 bytes as the specification asks."""
    js = pad4(json.dumps(doc, separators=(",", ":"), allow_nan=False).encode("utf-8"), b" ")
    out = [struct.pack("<II", len(js), _JSON), js]
    if blob is not None:
        b = pad4(blob)
        out += [struct.pack("<II", len(b), _BIN), b]
    body = b"".join(out)
    return struct.pack("<4sII", _GLB_MAGIC, 2, 12 + len(body)) + body


#: get()'s kinds of values
_KINDS = {"index": lambda v: isinstance(v, int) and not isinstance(v, bool) and v >= 0,
          "count": lambda v: isinstance(v, int) and not isinstance(v, bool) and v >= 1,
          "number": lambda v: isinstance(v, (int, float)) and not isinstance(v, bool),
          "string": lambda v: isinstance(v, str),
          "object": lambda v: isinstance(v, dict),
          "array": lambda v: isinstance(v, list),
          "bool": lambda v: isinstance(v, bool)}


class GltfFile:
    """A glTF 2.0 file opened for reading (see the module docs).

    Parameters
    ----------
    path : str or os.PathLike
        A ``.gltf`` (JSON) or ``.glb`` file; the content decides, not the extension.

    Attributes
    ----------
    path : Path
    doc : dict
        The JSON document.
    size : int
        Bytes of the file itself.
    """

    def __init__(self, path: str | os.PathLike):
        self.path = input_path(path, "glTF")
        raw = self.path.read_bytes()
        self.size = len(raw)
        self._bin: memoryview | None = None
        if raw[:4] == _GLB_MAGIC:
            text = self._glb(raw)
        else:
            if self.path.suffix.lower() == ".glb":
                raise self.error("a binary glTF file (starting with the bytes 'glTF')",
                                 f"{raw[:4]!r} at the start")
            text = memoryview(raw)
        try:
            # the safe loader: no NaN, infinities (1e999) or 5000-digit integers, which
            # a copy written back could not hold, and no nesting deep enough to crash
            # (a GLB's JSON chunk padded with NUL bytes, as some exporters write it,
            # reads as if padded with spaces, as the specification asks)
            doc = load_json(bytes(text).rstrip(b"\0"), "", what="glTF JSON")
        except ValueError as exc:
            msg = " ".join(str(exc).split()).lstrip(":, ")
            raise self.error("a glTF 2.0 file (JSON .gltf or binary .glb)",
                             f"unreadable JSON ({msg[:160]})") from None
        if not isinstance(doc, dict):
            raise self.error("a glTF 2.0 JSON object", f"a JSON {type(doc).__name__}")
        asset = doc.get("asset")
        version = asset.get("version") if isinstance(asset, dict) else None
        if not isinstance(version, str) or not version.startswith("2."):
            raise self.error("a glTF 2.0 asset (asset.version '2.0')",
                             f"asset.version {version!r}")
        self.doc = doc
        self._buffers: dict[int, memoryview] = {}
        self._opened = 0
        self._used = 0
        self.cache: dict[Any, Any] = {}

    # ------------------------------------------------------------------ errors
    def error(self, expected: str, found: str) -> FormatError:
        """A :class:`FormatError` about this file."""
        return FormatError(self.path, expected, found)

    # ------------------------------------------------------------------ GLB
    def _glb(self, raw: bytes) -> memoryview:
        if len(raw) < 12:
            raise self.error("a GLB header of 12 bytes", f"a file of {len(raw)} bytes")
        _, version, length = struct.unpack_from("<4sII", raw, 0)
        if version != 2:
            raise self.error("a GLB of version 2", f"version {version}")
        if length > len(raw) or length < 20:
            raise self.error(f"a GLB of {length} bytes (as its header says)",
                             f"{len(raw)} bytes (a truncated or damaged file)")
        at, k, text = 12, 0, None
        while at < length:
            if at + 8 > length:
                raise self.error(f"GLB chunk {k}: an 8-byte chunk header inside the file's "
                                 f"{length} bytes", f"one starting at byte {at}")
            n, kind = struct.unpack_from("<II", raw, at)
            end = at + 8 + n
            if end > length:
                raise self.error(f"GLB chunk {k} inside the file's {length} bytes",
                                 f"a chunk length of {n} reaching byte {end}")
            body = memoryview(raw)[at + 8:end]
            if k == 0:
                if kind != _JSON:
                    raise self.error("a JSON chunk first in the GLB", f"chunk type {kind:#x}")
                text = body
            elif kind == _BIN:
                if k != 1:
                    raise self.error("at most one BIN chunk, second in the GLB",
                                     f"a BIN chunk as chunk {k}")
                self._bin = body
            elif kind == _JSON:
                raise self.error("one JSON chunk in the GLB", f"another as chunk {k}")
            at, k = end, k + 1
        if text is None:
            raise self.error("a JSON chunk in the GLB", "none")
        return text

    # ------------------------------------------------------------------ JSON access
    def items(self, name: str) -> list:
        """The top-level array ``name`` (``"nodes"``, ``"accessors"``...), [] when absent."""
        x = self.doc.get(name, [])
        if not isinstance(x, list):
            raise self.error(f"{name}: a JSON array", f"a JSON {type(x).__name__}")
        return x

    def item(self, name: str, i: Any, what: str) -> dict:
        """Element ``i`` of the top-level array ``name``, an object; ``what`` names the
        reference in the error."""
        arr = self.items(name)
        if isinstance(i, bool) or not isinstance(i, int) or not 0 <= i < len(arr):
            raise self.error(f"{what}: an index into {name} (0..{len(arr) - 1})", repr(i))
        x = arr[i]
        if not isinstance(x, dict):
            raise self.error(f"{name}[{i}]: a JSON object", f"a JSON {type(x).__name__}")
        return x

    def get(self, obj: dict, key: str, kind: str, where: str, default: Any = _MISSING,
            *, below: int | None = None) -> Any:
        """``obj[key]`` checked to be of ``kind``: ``"index"`` (an int >= 0, ``< below``
        when given), ``"count"`` (an int >= 1), ``"number"``, ``"string"``,
        ``"object"``, ``"array"`` or ``"bool"``; ``default`` when absent (else an error).
        """
        if key not in obj:
            if default is _MISSING:
                raise self.error(f"{where}.{key}", "none")
            return default
        x = obj[key]
        ok = _KINDS[kind](x) and (kind != "index" or below is None or x < below)
        if not ok:
            want = {"index": "an index >= 0" + (f" below {below}" if below is not None else ""),
                    "count": "an integer >= 1", "number": "a number", "string": "a string",
                    "object": "a JSON object", "array": "a JSON array",
                    "bool": "true or false"}[kind]
            raise self.error(f"{where}.{key}: {want}", repr(x)[:80])
        return x

    def numbers(self, obj: dict, key: str, n: int, where: str, default) -> list[float]:
        """``obj[key]``: a list of ``n`` finite numbers (``default`` when absent)."""
        if key not in obj:
            return list(default)
        x = obj[key]
        if (not isinstance(x, list) or len(x) != n
                or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in x)):
            raise self.error(f"{where}.{key}: {n} numbers", repr(x)[:80])
        return [float(v) for v in x]

    # ------------------------------------------------------------------ budget
    @property
    def budget(self) -> int:
        """Bytes of arrays this file may still have decoded (see the module docs)."""
        return BUDGET_BASE + BUDGET_FACTOR * (self.size + self._opened) - self._used

    def reserve(self, nbytes: int, what: str, *, keep: bool = True) -> None:
        """Count ``nbytes`` of arrays about to be made against the budget; ``keep=False``
        for arrays that live only while one call works (checked, not counted)."""
        nbytes = int(nbytes)
        if nbytes > self.budget:
            limit = BUDGET_BASE + BUDGET_FACTOR * (self.size + self._opened)
            raise self.error(
                f"at most {limit} bytes of arrays decoded from a file of "
                f"{self.size + self._opened} bytes ({BUDGET_BASE // 2**20} MiB + "
                f"{BUDGET_FACTOR} times its size)",
                f"{what} needing {nbytes} bytes more (a hostile or damaged file?)")
        if keep:
            self._used += nbytes

    # ------------------------------------------------------------------ buffers
    def buffer(self, k: int) -> memoryview:
        """Buffer ``k``'s bytes (exactly its ``byteLength``), opened on first use."""
        if k in self._buffers:
            return self._buffers[k]
        b = self.item("buffers", k, f"buffer {k}")
        where = f"buffers[{k}]"
        length = self.get(b, "byteLength", "count", where)
        uri = self.get(b, "uri", "string", where, None)
        if uri is None:
            if self._bin is None or k != 0:
                raise self.error(f"{where}: a uri, or the GLB's BIN chunk (buffer 0 of a .glb)",
                                 "neither")
            data = self._bin
            if len(data) < length:
                raise self.error(f"{where}: the GLB BIN chunk of at least {length} bytes",
                                 f"{len(data)} bytes")
        elif uri.startswith("data:"):
            data = self._data_uri(uri, length, where)
        else:
            data = self._external(uri, length, where)
        data = memoryview(data)[:length]
        self._buffers[k] = data
        if uri is not None:
            self._opened += length
        return data

    def _data_uri(self, uri: str, length: int, where: str) -> bytes:
        head, sep, body = uri.partition(",")
        if not sep:
            raise self.error(f"{where}: a data: URI 'data:[type][;base64],DATA'",
                             repr(uri[:40]))
        if head.endswith(";base64"):
            # 4 characters of base64 hold 3 bytes: size the data before decoding any
            body = body.strip()
            have = len(body) // 4 * 3 - (len(body) - len(body.rstrip("=")))
            if have < length:
                raise self.error(f"{where}: a data: URI of {length} bytes (its byteLength)",
                                 f"one of {max(have, 0)} bytes")
            need = -(-length // 3) * 4
            try:
                data = base64.b64decode(body[:need], validate=True)[:length]
            except (binascii.Error, ValueError):
                raise self.error(f"{where}: base64 data", "invalid characters") from None
            if len(data) < length:
                raise self.error(f"{where}: a data: URI of {length} bytes (its byteLength)",
                                 f"one of {len(data)} bytes")
            return data
        if len(body) < length:      # percent-encoded: at least one character per byte
            raise self.error(f"{where}: a data: URI of {length} bytes (its byteLength)",
                             f"one of {len(body)} characters")
        data = unquote(body, encoding="latin-1").encode("latin-1")
        if len(data) < length:
            raise self.error(f"{where}: a data: URI of {length} bytes (its byteLength)",
                             f"one of {len(data)} bytes")
        return data

    def resolve(self, uri: str, where: str) -> Path:
        """The file a relative ``uri`` names, confined to the glTF file's own folder:
        no scheme, no absolute path, no ``..`` or symbolic link leading out."""
        if _SCHEME.match(uri) or uri.startswith(("/", "\\")) or "\\" in uri or "\0" in uri:
            raise self.error(f"{where}: a data: URI or a relative path beside the glTF file",
                             repr(uri[:80]))
        rel = unquote(uri)
        if "\0" in rel or rel.startswith("/") or _SCHEME.match(rel):
            raise self.error(f"{where}: a relative path beside the glTF file", repr(uri[:80]))
        folder = os.path.realpath(self.path.parent)
        target = os.path.realpath(os.path.join(folder, rel))
        if os.path.commonpath([folder, target]) != folder or target == folder:
            raise self.error(f"{where}: a file inside the glTF file's folder {folder!r}",
                             f"{uri[:80]!r}, which leads out of it")
        return Path(target)

    def _external(self, uri: str, length: int, where: str) -> bytes:
        p = self.resolve(uri, where)
        name = repr(unquote(uri)[:80])
        try:
            if not p.is_file():
                raise self.error(f"{where}: the file {name} beside the glTF file",
                                 "no such file")
            have = p.stat().st_size
            if have < length:
                raise self.error(f"{where}: {name} of at least {length} bytes "
                                 "(its byteLength)", f"{have} bytes")
            note_input(p)           # an output of this run may not be written over it
            with open(p, "rb") as fh:
                data = fh.read(length)
        except OSError as exc:      # a name too long, a file that cannot be read
            raise self.error(f"{where}: a readable file {name} beside the glTF file",
                             exc.strerror or type(exc).__name__) from None
        if len(data) < length:
            raise self.error(f"{where}: {name} of {length} bytes", f"{len(data)}")
        return data
