"""Mutations of the files stbs reads, as Hypothesis strategies.

A mutation is a tuple ``(op, *args)``: drawn by a strategy, shown as it is in a
failure report, applied by a function here to a seed file's content. Positions and
indices are drawn as plain integers and taken modulo what the file holds when the
mutation is applied, so every mutation fits every seed and shrinks well.

- :func:`byte_ops`: flips, insertions, deletions, truncation, duplicated ranges and
  interesting bytes, on any file;
- :func:`json_ops`: structure-aware edits of a JSON document (a value replaced by a
  huge, negative, non-finite, huge-integer, deeply nested or wrongly typed one; keys
  deleted; entries duplicated; indices moved out of range; lists grown);
- :func:`gltf_ops`: the glTF ones on top (buffer and image URIs leading to the canary
  file by absolute paths, ``../``, percent-encoding, ``file:`` and symbolic links;
  accessor data overwritten with NaN and huge values; strides, component types,
  counts; node cycles; empty skins, meshes and primitives; GLB headers and chunks);
- :func:`bvh_ops`: BVH-aware edits (frame counts and times, channel counts, deep and
  wide hierarchies, huge and malformed numbers, rows cut or grown).

The JSON serializer writes :class:`Raw` values as their text, so a document can hold
what JSON cannot (``NaN``, ``1e999``, a 5000-digit integer, nesting 10000 deep).
"""

from __future__ import annotations

import base64
import copy
import json
import struct
from dataclasses import dataclass, field

import numpy as np
from hypothesis import strategies as st


@dataclass(frozen=True)
class Raw:
    """A value written into JSON as this text, unquoted."""

    text: str

    def __repr__(self) -> str:
        t = self.text
        return f"Raw({t[:24] + '...' + t[-8:] if len(t) > 40 else t!r}, {len(t)} chars)"


def dumps(doc) -> str:
    """``doc`` as JSON text, each :class:`Raw` value as its text."""
    raws: list[str] = []

    def enc(x):
        if isinstance(x, Raw):
            raws.append(x.text)
            return f"\0RAW{len(raws) - 1}\0"
        if isinstance(x, dict):
            return {k: enc(v) for k, v in x.items()}
        if isinstance(x, list):
            return [enc(v) for v in x]
        if isinstance(x, float) and not np.isfinite(x):
            return enc(Raw("NaN" if x != x else ("Infinity" if x > 0 else "-Infinity")))
        return x

    text = json.dumps(enc(doc), separators=(",", ":"))
    for k, r in enumerate(raws):
        text = text.replace(f'"\\u0000RAW{k}\\u0000"', r)
    return text


# ----------------------------------------------------------------------------- values
HUGE_INTS = [2**31 - 1, 2**31, 2**32, 2**32 + 1, 2**53 + 1, 2**63, 2**64 + 7, 10**20,
             -(2**31), -1, 400_000_000]
SMALL_INTS = [0, 1, 2, 3, 4, 5, 7, 8, 12, 16, 252, 253, 255, 256, 65535, 65536]
FLOATS = [0.0, -0.0, 0.5, -1.5, 1e-320, 1e-45, 3.4e38, -3.4e38, 1e308, -1e308, 1e30]
RAWS = [Raw("NaN"), Raw("Infinity"), Raw("-Infinity"), Raw("1e999"), Raw("-1e999"),
        Raw("9" * 400), Raw("1" + "0" * 5000), Raw("-" + "7" * 30), Raw("1E400"),
        Raw("[" * 70 + "1" + "]" * 70), Raw("[" * 10000 + "]" * 10000),
        Raw('{"a":' * 3000 + "1" + "}" * 3000)]
STRINGS = ["", "x", "NaN", "-1", "1e999", "0x10", "../../secret", "\u0000", "é",
           "A" * 5000, "node1", "0", "99999", " ", "%2e%2e"]
OTHERS = [None, True, False, [], {}, [[]], [None], {"": None}, [0] * 20,
          list(range(1000)), [1e308] * 16, [Raw("NaN")] * 16]


def hostile_values() -> st.SearchStrategy:
    """A value of the wrong size, sign, finiteness, type or depth."""
    return st.one_of(st.sampled_from(HUGE_INTS + SMALL_INTS), st.sampled_from(FLOATS),
                     st.sampled_from(RAWS), st.sampled_from(STRINGS),
                     st.sampled_from(OTHERS), st.integers(-3, 70))


# ----------------------------------------------------------------------------- bytes
INTERESTING = [b"\x00", b"\xff", b"\x00\x00\x00\x00", b"\xff\xff\xff\x7f", b"\xff\xff\xff\xff",
               b"\x00\x00\xc0\x7f", b"\x00\x00\x80\x7f", b"\xff\xff\x7f\x7f", b"NaN", b"-",
               b"9" * 30, b'"', b"{", b"}", b"[", b"]", b",", b"\\u0000", b"\xc3\x28",
               b"\r\n", b"\t", b"1e999", b"\n}\n", b"glTF", b"JSON", b"BIN\x00"]


def byte_ops(max_ops: int = 3) -> st.SearchStrategy:
    """Byte-level mutations of any file."""
    pos = st.integers(0, 2**31)
    op = st.one_of(
        st.tuples(st.just("flip"), pos, st.integers(0, 7)),
        st.tuples(st.just("insert"), pos, st.sampled_from(INTERESTING)),
        st.tuples(st.just("insert"), pos, st.binary(min_size=1, max_size=8)),
        st.tuples(st.just("delete"), pos, st.integers(1, 64)),
        st.tuples(st.just("truncate"), pos),
        st.tuples(st.just("overwrite"), pos, st.sampled_from(INTERESTING)),
        st.tuples(st.just("dup"), pos, st.integers(1, 256)),
    )
    return st.lists(op, min_size=1, max_size=max_ops)


def apply_bytes(data: bytes, ops) -> bytes:
    b = bytearray(data)
    for op in ops:
        kind, p = op[0], op[1] % (len(b) + 1)
        if kind == "flip" and b:
            b[p % len(b)] ^= 1 << op[2]
        elif kind == "insert":
            b[p:p] = op[2]
        elif kind == "delete":
            del b[p:p + op[2]]
        elif kind == "truncate":
            del b[p:]
        elif kind == "overwrite":
            b[p:p + len(op[2])] = op[2]
        elif kind == "dup":
            b[p:p] = b[p:p + op[2]]
    return bytes(b)


# ----------------------------------------------------------------------------- JSON
def paths(doc) -> list[tuple]:
    """Every place in a JSON document (the root excluded), parents before children."""
    out: list[tuple] = []
    stack = [((), doc)]
    while stack:
        p, x = stack.pop()
        items = x.items() if isinstance(x, dict) else enumerate(x) if isinstance(x, list) \
            else ()
        for k, v in items:
            out.append((*p, k))
            if len(out) < 200_000:
                stack.append(((*p, k), v))
    out.sort(key=len)
    return out


def _get(doc, path):
    for k in path:
        doc = doc[k]
    return doc


def json_ops(max_ops: int = 3, values: st.SearchStrategy | None = None) -> st.SearchStrategy:
    """Structure-aware edits of any JSON document."""
    at = st.integers(0, 2**31)
    values = values if values is not None else hostile_values()
    op = st.one_of(
        st.tuples(st.just("replace"), at, values),
        st.tuples(st.just("delete"), at),
        st.tuples(st.just("duplicate"), at),
        st.tuples(st.just("copy"), at, at),
        st.tuples(st.just("shift"), at, st.sampled_from([-2, -1, 1, 2, 1000, 2**31])),
        st.tuples(st.just("grow"), at, st.sampled_from([2, 10, 1000, 20000])),
    )
    return st.lists(op, min_size=1, max_size=max_ops)


#: A document grown (or copied into itself) past this many places is not grown further:
#: the cases stay a few megabytes, cheap to make and to run.
MAX_PLACES = 30_000


def apply_json(doc, ops):
    """``doc`` (a parsed JSON document, copied) with ``ops`` applied."""
    doc = copy.deepcopy(doc)
    for op in ops:
        ps = paths(doc)
        if not ps:
            break
        p = ps[op[1] % len(ps)]
        parent, key = _get(doc, p[:-1]), p[-1]
        kind = op[0]
        if kind in ("grow", "copy") and len(ps) > MAX_PLACES:
            continue
        if kind == "replace":
            parent[key] = copy.deepcopy(op[2])
        elif kind == "delete":
            del parent[key]
        elif kind == "duplicate" and isinstance(parent, list):
            parent.insert(key, copy.deepcopy(parent[key]))
        elif kind == "duplicate" and isinstance(parent[key], list) and parent[key]:
            parent[key].append(copy.deepcopy(parent[key][-1]))
        elif kind == "copy":
            src = ps[op[2] % len(ps)]
            if src[:len(p)] != p:
                parent[key] = copy.deepcopy(_get(doc, src))
        elif kind == "shift":
            v = parent[key]
            if isinstance(v, (int, float)) and not isinstance(v, bool):
                parent[key] = v + op[2]
        elif kind == "grow":
            v = parent[key]
            if isinstance(v, list) and v:
                parent[key] = (v * (op[2] // len(v) + 1))[:max(op[2], len(v))]
            elif isinstance(v, str):
                parent[key] = ((v or "x") * op[2])[:100_000]
    return doc


# ----------------------------------------------------------------------------- glTF
#: URIs leading out of the case folder to the canary (``CANARY`` is replaced by the
#: canary's absolute path, ``SECRET`` by its name, ``UP`` by the ``../`` to its folder),
#: and other hostile ones.
URIS = ["CANARY", "UP/SECRET", "UP%2fSECRET", "%2e%2e/%2e%2e/SECRET", "%2E%2E%2F%2E%2E%2FSECRET",
        "file://CANARY", "file:CANARY", "FILE:///etc/passwd", "/etc/passwd", "/proc/self/environ",
        "link.bin", "linkdir/SECRET", "sub/../UP/SECRET", "..\\..\\SECRET", "C:\\x.bin",
        "http://127.0.0.1:9/x.bin", "data:application/octet-stream;base64,!!!!AAAA",
        "data:application/octet-stream;base64,AAAA AAAA\nAAAA", "data:,abc", "data:",
        "data:application/octet-stream;base64,AAA", "data:;base64,====", "",
        "missing.bin", ".", "./", "%00", "buf.bin%00.png", "\u00e9.bin"]

_SECTIONS = {
    "accessors": ["bufferView", "byteOffset", "componentType", "count", "type", "normalized",
                  "sparse", "min", "max"],
    "bufferViews": ["buffer", "byteOffset", "byteLength", "byteStride", "target"],
    "buffers": ["byteLength", "uri"],
    "nodes": ["children", "matrix", "translation", "rotation", "scale", "mesh", "skin",
              "weights", "name", "camera"],
    "skins": ["joints", "inverseBindMatrices", "skeleton", "extras", "name"],
    "meshes": ["primitives", "weights", "name"],
    "animations": ["samplers", "channels", "name"],
    "scenes": ["nodes"],
    "images": ["uri", "bufferView", "mimeType"],
}
_SPECIAL = {
    "componentType": [5120, 5121, 5122, 5123, 5124, 5125, 5126, 5130, 0, 1],
    "type": ["SCALAR", "VEC2", "VEC3", "VEC4", "MAT2", "MAT3", "MAT4", "MAT5", "vec3", ""],
    "byteStride": [0, 1, 2, 3, 4, 5, 6, 8, 11, 12, 13, 16, 20, 64, 252, 253, 256, 4096],
    "count": [1, 2, 3, 4, 400_000_000, 2**31, 2**32 + 1, 10**15, 0, -1],
    "matrix": [[Raw("NaN")] * 16, [1e308] * 16, [0.0] * 16, [3.4e38] * 16,
               [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0], [1.0] * 16, [1e-300] * 16,
               [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 1e308, 1e308, 1e308, 1]],
    "rotation": [[0, 0, 0, 0], [1e308, 1e308, 0, 0], [Raw("NaN")] * 4, [0, 0, 0, 1e-300],
                 [1e-320, 0, 0, 0]],
    "scale": [[0, 0, 0], [1e308, 1e308, 1e308], [-1, 1, 1], [1e-300] * 3, [0, 1, 1]],
    "translation": [[1e308, -1e308, 0], [3.4e38] * 3, [Raw("1e999"), 0, 0]],
    "joints": [[], [0], [0, 0], [0, 1, 0], list(range(300)), [-1], [2**31]],
    "primitives": [[], [{}], [{"attributes": {}}], [{"attributes": {"POSITION": 0}}]],
    "sparse": [{"count": 1, "indices": {"bufferView": 0, "componentType": 5125},
                "values": {"bufferView": 0}},
               {"count": 2**31, "indices": {"bufferView": 0, "componentType": 5121},
                "values": {"bufferView": 0}}],
    "mode": [0, 1, 2, 3, 4, 5, 6, 7, -1],
    "interpolation": ["LINEAR", "STEP", "CUBICSPLINE", "linear", ""],
    "path": ["translation", "rotation", "scale", "weights", "pointer", ""],
}
ATTRIBUTES = ["POSITION", "NORMAL", "JOINTS_0", "WEIGHTS_0", "JOINTS_1", "WEIGHTS_1",
              "_ENDPOINT_WEIGHTS_0", "TEXCOORD_0"]
#: 4-byte patterns written over accessor data: NaN, infinity, the largest float, a
#: denormal, -0, 0xffffffff, 0x80000000, 1.0
PATTERNS = [b"\x00\x00\xc0\x7f", b"\x00\x00\x80\x7f", b"\xff\xff\x7f\x7f", b"\x01\x00\x00\x00",
            b"\x00\x00\x00\x80", b"\xff\xff\xff\xff", b"\x00\x00\x00\x80"[::-1],
            b"\x00\x00\x80\x3f", b"\x00\x00\x00\x00"]


def _index_values() -> st.SearchStrategy:
    return st.one_of(st.integers(-2, 40), st.sampled_from(HUGE_INTS))


def gltf_ops(max_ops: int = 3) -> st.SearchStrategy:
    """glTF-aware mutations (see the module docs)."""
    i = st.integers(0, 2**16)
    section = st.sampled_from(sorted(_SECTIONS))
    value = st.one_of(hostile_values(), _index_values(),
                      st.sampled_from([v for vs in _SPECIAL.values() for v in vs]))
    op = st.one_of(
        st.tuples(st.just("set"), section, i, i, value),
        st.tuples(st.just("typed"), section, i, i, i),
        st.tuples(st.just("ext"), st.sampled_from(["KHR_mesh_quantization",
                                                   "KHR_draco_mesh_compression",
                                                   "EXT_meshopt_compression",
                                                   "KHR_materials_variants"]), st.booleans()),
        st.tuples(st.just("del"), section, i, i),
        st.tuples(st.just("prim"), i, i, st.sampled_from(["indices", "mode", "targets",
                                                          "attributes"]), value),
        st.tuples(st.just("attr"), i, i, st.sampled_from(ATTRIBUTES), _index_values()),
        st.tuples(st.just("sampler"), i, i, st.sampled_from(["input", "output",
                                                             "interpolation"]), value),
        st.tuples(st.just("target"), i, i, st.sampled_from(["node", "path"]), value),
        st.tuples(st.just("uri"), st.sampled_from(["buffer", "image", "unused"]), i,
                  st.sampled_from(URIS)),
        st.tuples(st.just("fill"), i, st.sampled_from(PATTERNS), st.booleans()),
        st.tuples(st.just("edge"), i, i),
        st.tuples(st.just("empty"), st.sampled_from(["skins", "meshes", "nodes", "joints",
                                                     "primitives", "accessors", "buffers",
                                                     "animations", "scenes"]), i),
        st.tuples(st.just("keys"), i, st.sampled_from([1, 2, 3, 1000, 20000])),
        st.tuples(st.just("morph"), i, i, st.sampled_from([0.5, 1.0, -2.0, 1e-300, 1e30,
                                                          1e308, 0.0])),
        st.tuples(st.just("rigid"), i, i),
        st.tuples(st.just("chain"), i, st.sampled_from([50, 500, 3000])),
        st.tuples(st.just("second-skin"), i, i, st.booleans()),
        st.tuples(st.just("external"), st.booleans()),
        st.tuples(st.just("glb"), st.sampled_from(["version0", "version1", "version3",
                                                   "length+", "length-", "json-type",
                                                   "bin-first", "two-bin", "bin-huge",
                                                   "no-bin", "extra-chunk", "pad"])),
    )
    return st.lists(st.one_of(op, op, op, json_ops(1).map(lambda x: ("json", x[0]))),
                    min_size=1, max_size=max_ops)


@dataclass
class Gltf:
    """A glTF file taken apart: its JSON, its binary buffer, and how it is stored."""

    doc: dict
    bin: bytearray
    glb: bool
    external: str | None = None                    # buffer 0 in this file beside it
    links: dict = field(default_factory=dict)      # name -> target path
    header: list = field(default_factory=list)     # GLB tweaks, applied when packing

    @classmethod
    def parse(cls, data: bytes) -> Gltf:
        if data[:4] == b"glTF":
            n = struct.unpack_from("<I", data, 12)[0]
            doc = json.loads(data[20:20 + n])
            m = struct.unpack_from("<I", data, 20 + n)[0] if len(data) > 28 + n else 0
            return cls(doc, bytearray(data[28 + n:28 + n + m]), True)
        doc = json.loads(data)
        uri = doc["buffers"][0]["uri"]
        doc["buffers"][0]["uri"] = "@bin"          # written back from .bin when packing
        return cls(doc, bytearray(base64.b64decode(uri.split(",", 1)[1])), False)

    def pack(self) -> tuple[bytes, dict[str, bytes]]:
        """The file's bytes, and the files beside it (name -> bytes)."""
        files = {self.external: bytes(self.bin)} if self.external else {}
        return self._pack(), files

    def _pack(self) -> bytes:
        doc = self.doc
        bufs = doc.get("buffers")
        if (isinstance(bufs, list) and bufs and isinstance(bufs[0], dict)
                and bufs[0].get("uri") == "@bin"):
            doc = dict(doc, buffers=[dict(bufs[0], uri="data:application/octet-stream;base64,"
                                          + base64.b64encode(bytes(self.bin)).decode()),
                                     *bufs[1:]])
        if not self.glb:
            return dumps(doc).encode("utf-8", "surrogatepass")
        js = dumps(doc).encode("utf-8", "surrogatepass")
        js += b" " * (-len(js) % 4)
        blob = bytes(self.bin) + b"\0" * (-len(self.bin) % 4)
        jc = struct.pack("<I4s", len(js), b"JSON") + js
        bc = struct.pack("<I4s", len(blob), b"BIN\0") + blob
        chunks = [jc, bc]
        version = 2
        delta = 0
        for h in self.header:
            if h.startswith("version"):
                version = int(h[7:])
            elif h == "length+":
                delta = 1000
            elif h == "length-":
                delta = -8
            elif h == "json-type":
                chunks[0] = struct.pack("<I4s", len(js), b"JSOX") + js
            elif h == "bin-first":
                chunks = chunks[::-1]
            elif h == "two-bin":
                chunks.append(bc)
            elif h == "bin-huge":
                chunks[-1] = struct.pack("<I4s", 2**32 - 4, b"BIN\0") + blob
            elif h == "no-bin":
                chunks = chunks[:1]
            elif h == "extra-chunk":
                chunks.insert(1, struct.pack("<I4s", 4, b"XTRA") + b"abcd")
            elif h == "pad":
                chunks[0] = struct.pack("<I4s", len(js) + 3, b"JSON") + js + b"\0\0\0"
        body = b"".join(chunks)
        return struct.pack("<4sII", b"glTF", version, 12 + len(body) + delta) + body


def _list(doc, name):
    x = doc.get(name)
    return x if isinstance(x, list) else None


def _pick(doc, name, i):
    x = _list(doc, name)
    if not x:
        return None
    return x[i % len(x)]


def _accessor_span(g: Gltf, a: dict):
    """(start, length) in the binary buffer of an accessor's buffer view, or None."""
    views = _list(g.doc, "bufferViews")
    v = a.get("bufferView") if isinstance(a, dict) else None
    if not views or not isinstance(v, int) or not 0 <= v < len(views):
        return None
    bv = views[v]
    if not isinstance(bv, dict) or bv.get("buffer", 0) != 0:
        return None
    start = bv.get("byteOffset", 0)
    n = bv.get("byteLength", 0)
    if not isinstance(start, int) or not isinstance(n, int) or start < 0 or n < 0:
        return None
    return start, min(n, max(len(g.bin) - start, 0))


def _uri(text: str, env: dict) -> str:
    return (text.replace("CANARY", env["canary"]).replace("SECRET", env["secret"])
            .replace("UP", env["up"]))


def _op_set(g: Gltf, op, env: dict) -> None:
    """("set", section, i, key, value): a value put under a key of an item."""
    x = _pick(g.doc, op[1], op[2])
    if isinstance(x, dict):
        keys = _SECTIONS[op[1]]
        x[keys[op[3] % len(keys)]] = copy.deepcopy(op[4])


def _op_typed(g: Gltf, op, env: dict) -> None:
    """("typed", section, i, key, k): a value made for that key."""
    x = _pick(g.doc, op[1], op[2])
    if isinstance(x, dict):
        keys = _SECTIONS[op[1]]
        key = keys[op[3] % len(keys)]
        vals = _SPECIAL.get(key) or [-1, 0, 1, 2, 3, 2**31, 2**32 + 1, 10**15]
        x[key] = copy.deepcopy(vals[op[4] % len(vals)])


def _op_ext(g: Gltf, op, env: dict) -> None:
    """("ext", name, required): an extension used (and required)."""
    d = g.doc
    for name in ("extensionsUsed", "extensionsRequired")[:1 + op[2]]:
        if not isinstance(d.get(name), list):
            d[name] = []
        d[name].append(op[1])


def _op_del(g: Gltf, op, env: dict) -> None:
    """("del", section, i, key): a key of an item deleted."""
    x = _pick(g.doc, op[1], op[2])
    keys = _SECTIONS[op[1]]
    if isinstance(x, dict):
        x.pop(keys[op[3] % len(keys)], None)


def _primitive(d: dict, m: int, k: int) -> dict | None:
    """Primitive ``k`` (modulo) of mesh ``m`` (modulo), if it is a JSON object."""
    mesh = _pick(d, "meshes", m)
    prims = mesh.get("primitives") if isinstance(mesh, dict) else None
    if isinstance(prims, list) and prims and isinstance(prims[k % len(prims)], dict):
        return prims[k % len(prims)]
    return None


def _op_prim(g: Gltf, op, env: dict) -> None:
    """("prim", mesh, primitive, key, value): a primitive's key set."""
    p = _primitive(g.doc, op[1], op[2])
    if p is not None:
        p[op[3]] = copy.deepcopy(op[4])


def _op_attr(g: Gltf, op, env: dict) -> None:
    """("attr", mesh, primitive, attribute, index): a primitive's attribute set."""
    p = _primitive(g.doc, op[1], op[2])
    if p is not None and isinstance(p.get("attributes"), dict):
        p["attributes"][op[3]] = op[4]


def _op_animation(g: Gltf, op, env: dict) -> None:
    """("sampler" | "target", animation, i, key, value): a key of an animation's sampler,
    or of a channel's target, set."""
    kind = op[0]
    a = _pick(g.doc, "animations", op[1])
    arr = a.get("samplers" if kind == "sampler" else "channels") \
        if isinstance(a, dict) else None
    if isinstance(arr, list) and arr and isinstance(arr[op[2] % len(arr)], dict):
        x = arr[op[2] % len(arr)]
        if kind == "target":
            x = x.setdefault("target", {}) if isinstance(x.get("target", {}), dict) \
                else x
        x[op[3]] = copy.deepcopy(op[4])


def _op_uri(g: Gltf, op, env: dict) -> None:
    """("uri", "buffer" | "image" | "unused", i, text): a URI (leading to the canary,
    through links too) on a buffer, a new image or a new buffer nothing uses."""
    d = g.doc
    uri = _uri(op[3], env)
    if uri == "link.bin":
        g.links["link.bin"] = env["canary"]
    elif uri.startswith("linkdir/"):
        g.links["linkdir"] = env["canary_dir"]
    if op[1] == "buffer":
        x = _pick(d, "buffers", op[2])
        if isinstance(x, dict):
            x["uri"] = uri
    elif op[1] == "image":
        imgs = d.setdefault("images", [])
        if isinstance(imgs, list):
            imgs.append({"uri": uri})
    else:                               # a buffer nothing uses
        bufs = d.setdefault("buffers", [])
        if isinstance(bufs, list):
            bufs.append({"uri": uri, "byteLength": 64})


def _op_fill(g: Gltf, op, env: dict) -> None:
    """("fill", accessor, pattern, all): an accessor's data (or one value of it)
    overwritten with a pattern."""
    a = _pick(g.doc, "accessors", op[1])
    span = _accessor_span(g, a)
    if span:
        start, n = span
        if op[3]:                                       # all of it
            g.bin[start:start + n] = (op[2] * (n // 4 + 1))[:n]
        elif n >= 4:                                    # one value
            k = (op[1] * 4) % max(n - 3, 1)
            g.bin[start + k:start + k + 4] = op[2]


def _op_edge(g: Gltf, op, env: dict) -> None:
    """("edge", a, b): node b made a child of node a (cycles, two parents)."""
    nodes = _list(g.doc, "nodes")
    if nodes:
        a, b = nodes[op[1] % len(nodes)], op[2] % len(nodes)
        if isinstance(a, dict):
            ch = a.setdefault("children", [])
            if isinstance(ch, list):
                ch.append(b)


def _op_empty(g: Gltf, op, env: dict) -> None:
    """("empty", what, i): a top-level list, a skin's joints or a mesh's primitives
    emptied."""
    d = g.doc
    what = op[1]
    if what == "joints":
        s = _pick(d, "skins", op[2])
        if isinstance(s, dict):
            s["joints"] = []
    elif what == "primitives":
        m = _pick(d, "meshes", op[2])
        if isinstance(m, dict):
            m["primitives"] = []
    else:
        d[what] = []


def _op_keys(g: Gltf, op, env: dict) -> None:
    """("keys", animation, n): see :func:`_more_keys`."""
    _more_keys(g, op[1], op[2])


def _op_morph(g: Gltf, op, env: dict) -> None:
    """("morph", mesh, accessor, weight): a morph target, on by default."""
    d = g.doc
    m = _pick(d, "meshes", op[1])
    a = _pick(d, "accessors", op[2])
    prims = m.get("primitives") if isinstance(m, dict) else None
    if isinstance(prims, list) and prims and isinstance(prims[0], dict) and a:
        attrs = prims[0].get("attributes")
        pos = attrs.get("POSITION") if isinstance(attrs, dict) else None
        target = pos if op[2] % 2 else op[2] % len(d["accessors"])
        prims[0].setdefault("targets", [])
        if isinstance(prims[0]["targets"], list):
            prims[0]["targets"].append({"POSITION": target})
            m["weights"] = [op[3]] * len(prims[0]["targets"])


def _op_chain(g: Gltf, op, env: dict) -> None:
    """("chain", joint, n): a chain of n joints below a joint of skin 0."""
    skin, nodes = _pick(g.doc, "skins", 0), _list(g.doc, "nodes")
    joints = skin.get("joints") if isinstance(skin, dict) else None
    if nodes and isinstance(joints, list) and joints:
        top = joints[op[1] % len(joints)]
        if isinstance(top, int) and 0 <= top < len(nodes) and \
                isinstance(nodes[top], dict):
            first = len(nodes)
            nodes += [{"name": f"chain{m}", "translation": [0, 0.01, 0],
                       "children": [first + m + 1]} for m in range(op[2])]
            del nodes[-1]["children"]
            ch = nodes[top].setdefault("children", [])
            if isinstance(ch, list):
                ch.append(first)
            joints += range(first, first + op[2])
            skin.pop("inverseBindMatrices", None)   # (binds: the identity)


def _op_rigid(g: Gltf, op, env: dict) -> None:
    """("rigid", node, mesh): a mesh hung on a node, without a skin."""
    nodes, meshes = _list(g.doc, "nodes"), _list(g.doc, "meshes")
    if nodes and meshes and isinstance(nodes[op[1] % len(nodes)], dict):
        nodes.append({"name": "part", "mesh": op[2] % len(meshes),
                      "translation": [0, 0.1, 0]})
        ch = nodes[op[1] % len(nodes)].setdefault("children", [])
        if isinstance(ch, list):
            ch.append(len(nodes) - 1)


def _op_second_skin(g: Gltf, op, env: dict) -> None:
    """("second-skin", skin, mesh node, no binds): a second skin over the joints, bound
    to a mesh node."""
    skins, nodes = _list(g.doc, "skins"), _list(g.doc, "nodes")
    if skins and nodes and isinstance(skins[op[1] % len(skins)], dict):
        sk = copy.deepcopy(skins[op[1] % len(skins)])
        if op[3]:
            sk.pop("inverseBindMatrices", None)
        skins.append(sk)
        with_mesh = [n for n in nodes if isinstance(n, dict) and "mesh" in n]
        if with_mesh:
            with_mesh[op[2] % len(with_mesh)]["skin"] = len(skins) - 1


def _op_external(g: Gltf, op, env: dict) -> None:
    """("external", spaced): buffer 0 in a file beside the glTF."""
    bufs = _list(g.doc, "buffers")
    if bufs and isinstance(bufs[0], dict):
        g.external = "my buf.bin" if op[1] else "buf.bin"
        bufs[0]["uri"] = "my%20buf.bin" if op[1] else "buf.bin"


def _op_glb(g: Gltf, op, env: dict) -> None:
    """("glb", tweak): a GLB header or chunk tweak, applied when packing."""
    g.header.append(op[1])


#: The glTF mutations but "json", by kind: each changes ``g`` in place.
_GLTF_OPS = {"set": _op_set, "typed": _op_typed, "ext": _op_ext, "del": _op_del,
             "prim": _op_prim, "attr": _op_attr, "sampler": _op_animation,
             "target": _op_animation, "uri": _op_uri, "fill": _op_fill, "edge": _op_edge,
             "empty": _op_empty, "keys": _op_keys, "morph": _op_morph, "chain": _op_chain,
             "rigid": _op_rigid, "second-skin": _op_second_skin, "external": _op_external,
             "glb": _op_glb}


def apply_gltf(g: Gltf, ops, env: dict) -> Gltf:
    """``g`` (copied) with the glTF mutations ``ops`` applied; ``env`` names the canary
    (``canary``: its absolute path, ``secret``: its name, ``up``: ``../`` from the
    case folder to its folder)."""
    g = Gltf(copy.deepcopy(g.doc), bytearray(g.bin), g.glb, g.external, dict(g.links),
             list(g.header))
    for op in ops:
        if op[0] == "json":
            g.doc = apply_json(g.doc, [op[1]])
            if not isinstance(g.doc, dict):
                break
        elif op[0] in _GLTF_OPS:
            _GLTF_OPS[op[0]](g, op, env)
    return g


def _more_keys(g: Gltf, a: int, n: int) -> None:
    """Give animation ``a``'s first sampler ``n`` keys (times 0, 1/30, ...; rotations
    alternating about z), appended to the binary buffer."""
    anim = _pick(g.doc, "animations", a)
    views, accs = _list(g.doc, "bufferViews"), _list(g.doc, "accessors")
    if not isinstance(anim, dict) or views is None or accs is None:
        return
    samplers, chans = anim.get("samplers"), anim.get("channels")
    if not isinstance(samplers, list) or not samplers or not isinstance(chans, list):
        return
    t = (np.arange(n) / 30.0).astype("<f4")
    q = np.tile(np.array([0, 0, 0, 1], "<f4"), (n, 1))
    q[::2] = [0, 0, 1, 0]
    ids = []
    for arr, typ in ((t, "SCALAR"), (q, "VEC4")):
        while len(g.bin) % 4:
            g.bin.append(0)
        views.append({"buffer": 0, "byteOffset": len(g.bin), "byteLength": arr.nbytes})
        g.bin.extend(arr.tobytes())
        accs.append({"bufferView": len(views) - 1, "componentType": 5126, "count": n,
                     "type": typ})
        ids.append(len(accs) - 1)
    samplers[0] = {"input": ids[0], "output": ids[1], "interpolation": "LINEAR"}
    for c in chans:
        if isinstance(c, dict) and c.get("sampler") == 0 and isinstance(c.get("target"), dict):
            c["target"]["path"] = "rotation"
    bufs = _list(g.doc, "buffers")
    if bufs and isinstance(bufs[0], dict):
        bufs[0]["byteLength"] = len(g.bin)


# ----------------------------------------------------------------------------- BVH
BVH_NUMBERS = ["0", "-0", "1e308", "-1e308", "1e999", "nan", "NaN", "inf", "-inf", "1e-320",
               "0x10", "1,5", "--1", "+-1", "9" * 400, "1e", ".", "", "1.2.3", "½"]


def bvh_ops(max_ops: int = 3) -> st.SearchStrategy:
    """BVH-aware mutations (see the module docs)."""
    i = st.integers(0, 2**16)
    op = st.one_of(
        st.tuples(st.just("frames"), st.sampled_from(
            ["0", "-1", "1", "4", "6", "50", "1000000000", str(2**63), "abc", "1e3", "", "5.5",
             "99999999999999999999999"])),
        st.tuples(st.just("frametime"), st.sampled_from(
            ["0", "-0.01", "1e-300", "1e300", "nan", "inf", "", "1e999", "abc", "1e-9"])),
        st.tuples(st.just("channels"), i, st.sampled_from(["0", "1", "2", "7", "-1", "1000000000",
                                                           "x", "3 Xrotation", "6"])),
        st.tuples(st.just("channel-name"), i, st.sampled_from(
            ["Wrotation", "Xposition", "Xrotation", "", "Zscale", "xrotation"])),
        st.tuples(st.just("deep"), i, st.sampled_from([2, 50, 200, 1000, 5000])),
        st.tuples(st.just("wide"), i, st.sampled_from([2, 100, 3000])),
        st.tuples(st.just("number"), i, i, st.sampled_from(BVH_NUMBERS)),
        st.tuples(st.just("offset"), i, st.sampled_from(
            ["0 0 0", "1e308 1e308 1e308", "nan 0 0", "1 2", "1 2 3 4", "3.4e38 0 0"])),
        st.tuples(st.just("name"), i, st.sampled_from(["", "Hips", "LeftArm", "A" * 5000,
                                                       "a b", "é", "{"])),
        st.tuples(st.just("rows"), i, st.sampled_from(["cut", "dup", "extra", "short", "blank",
                                                       "zeros", "huge"])),
        st.tuples(st.just("line"), i, st.sampled_from(["del", "dup", "{", "}", "End Site",
                                                       "ROOT x", "JOINT", "MOTION",
                                                       "HIERARCHY", ""])),
    )
    # edits that keep the file readable, so that the cases reach retargeting and baking
    keep = st.one_of(
        st.tuples(st.just("resize"), st.sampled_from([1, 2, 3, 60, 1000])),
        st.tuples(st.just("value"), i, i, st.sampled_from(
            ["0", "1e5", "-1e5", "1e6", "-1e6", "720", "-359.99", "1e-300", "90", "180"])),
        st.tuples(st.just("offset"), i, st.sampled_from(
            ["0 0 0", "1e5 0 0", "1e-9 0 0", "0 -50 0", "1e6 1e6 1e6"])),
        st.tuples(st.just("order"), i, st.permutations([0, 1, 2])),
        st.tuples(st.just("drop"), i),
        st.tuples(st.just("position"), i),
        st.tuples(st.just("name"), i, st.sampled_from(
            ["Hips", "LeftUpLeg", "RightArm", "Head", "Spine", "mixamorig:Hips", "pelvis",
             "LeftHand", "Neck", "RightFoot", "root"])),
    )
    return st.lists(st.one_of(keep, keep, op), min_size=1, max_size=max_ops)


def _channels(lines: list[str]) -> list[tuple[int, int]]:
    """(line, first motion column) of each CHANNELS line, in file order."""
    out, col = [], 0
    for k, s in enumerate(lines):
        parts = s.split()
        if parts and parts[0].upper() == "CHANNELS":
            out.append((k, col))
            col += int(parts[1]) if len(parts) > 1 and parts[1].isdigit() else 0
    return out


def _where(lines: list[str], prefix: str) -> list[int]:
    """The lines whose first word starts with ``prefix``."""
    return [k for k, s in enumerate(lines) if s.strip().split(" ")[0].startswith(prefix)]


def _bvh_resize(lines, op, motion, rows, chans) -> None:
    """("resize", n): the motion rows repeated or cut to n, and the frame count said."""
    if not rows:
        return
    body = [lines[r] for r in rows]
    body = (body * (op[1] // len(body) + 1))[:op[1]]
    lines[motion + 3:] = body
    for k in _where(lines, "Frames:"):
        lines[k] = f"Frames: {op[1]}"


def _bvh_value(lines, op, motion, rows, chans) -> None:
    """("value", row, column, text): one motion value replaced."""
    if not rows:
        return
    k = rows[op[1] % len(rows)]
    parts = lines[k].split()
    if parts:
        parts[op[2] % len(parts)] = op[3]
        lines[k] = " ".join(parts)


def _bvh_order(lines, op, motion, rows, chans) -> None:
    """("order", joint, permutation): a joint's rotation channels reordered."""
    if not chans:
        return
    k, _ = chans[op[1] % len(chans)]
    parts = lines[k].split()
    rot = [m for m, w in enumerate(parts) if w.lower().endswith("rotation")]
    if len(rot) == 3:
        names = [parts[m] for m in rot]
        for m, perm in zip(rot, op[2], strict=True):
            parts[m] = names[perm]
        lines[k] = " ".join(parts)


def _bvh_columns(lines, op, motion, rows, chans) -> None:
    """("drop", joint): a joint's channels and their columns removed; ("position",
    joint): position channels (columns of zeros) given to a joint without them."""
    if not chans:
        return
    kind = op[0]
    k, col = chans[op[1] % len(chans)]
    parts = lines[k].split()
    n = int(parts[1]) if len(parts) > 1 and parts[1].isdigit() else 0
    for r in rows:
        vals = lines[r].split()
        if kind == "drop":
            del vals[col:col + n]
        elif not any(w.lower().endswith("position") for w in parts):
            vals[col:col] = ["0", "0", "0"]
        lines[r] = " ".join(vals)
    if kind == "drop":
        lines[k] = "CHANNELS 0"
    elif not any(w.lower().endswith("position") for w in parts):
        lines[k] = f"CHANNELS {n + 3} Xposition Yposition Zposition " + \
            " ".join(parts[2:])


def _bvh_frames(lines, op, motion, rows, chans) -> None:
    """("frames", text): the frame count line said otherwise."""
    for k in _where(lines, "Frames:"):
        lines[k] = f"Frames: {op[1]}"


def _bvh_frametime(lines, op, motion, rows, chans) -> None:
    """("frametime", text): the frame time line said otherwise."""
    for k in [k for k, s in enumerate(lines) if s.strip().startswith("Frame Time")]:
        lines[k] = f"Frame Time: {op[1]}"


def _bvh_channels(lines, op, motion, rows, chans) -> None:
    """("channels", joint, count): a CHANNELS line's count replaced; ("channel-name",
    joint, name): one of its names."""
    ks = _where(lines, "CHANNELS")
    if ks:
        k = ks[op[1] % len(ks)]
        parts = lines[k].split()
        if op[0] == "channels":
            lines[k] = f"CHANNELS {op[2]} " + " ".join(parts[2:])
        elif len(parts) > 2:
            parts[2 + op[1] % (len(parts) - 2)] = op[2]
            lines[k] = " ".join(parts)


def _bvh_joints(lines, op, motion, rows, chans) -> None:
    """("deep", end site, n): a chain of n joints; ("wide", end site, n): n sibling
    joints; put before an End Site's block, in its parent, with their motion columns
    (zeros)."""
    ks = _where(lines, "End")
    if not ks:
        return
    k = ks[op[1] % len(ks)]
    n = op[2]
    if op[0] == "deep":
        block = []
        for m in range(n):
            block += [f"JOINT deep{m}", "{", "OFFSET 0 0.1 0",
                      "CHANNELS 3 Zrotation Xrotation Yrotation"]
        block += ["End Site", "{", "OFFSET 0 0.1 0", "}"] + ["}"] * n
        extra = 3 * n
    else:
        block = []
        for m in range(n):
            block += [f"JOINT wide{m}", "{", "OFFSET 0 0.1 0",
                      "CHANNELS 3 Zrotation Xrotation Yrotation", "End Site",
                      "{", "OFFSET 0 0.1 0", "}", "}"]
        extra = 3 * n
    lines[k:k] = block
    motion = (_where(lines, "MOTION") or [len(lines)])[0]
    for r in range(motion + 3, len(lines)):
        if lines[r].strip():
            lines[r] = lines[r] + " 0" * extra


def _bvh_number(lines, op, motion, rows, chans) -> None:
    """("number", line, word, text): a number anywhere in the file replaced."""
    rows = [k for k in range(len(lines)) if any(c.isdigit() for c in lines[k])]
    if rows:
        k = rows[op[1] % len(rows)]
        parts = lines[k].split()
        nums = [m for m, s in enumerate(parts) if any(c.isdigit() for c in s)]
        if nums:
            parts[nums[op[2] % len(nums)]] = op[3]
            lines[k] = " ".join(parts)


def _bvh_offset(lines, op, motion, rows, chans) -> None:
    """("offset", joint, text): an OFFSET line's values replaced."""
    ks = _where(lines, "OFFSET")
    if ks:
        lines[ks[op[1] % len(ks)]] = f"OFFSET {op[2]}"


def _bvh_name(lines, op, motion, rows, chans) -> None:
    """("name", joint, name): a joint renamed."""
    ks = _where(lines, "JOINT") + _where(lines, "ROOT")
    if ks:
        k = ks[op[1] % len(ks)]
        lines[k] = f"{lines[k].split()[0]} {op[2]}".rstrip()


_ROW_EDITS = {"extra": lambda s: s + " 1 2 3",
              "short": lambda s: " ".join(s.split()[:-1]),
              "blank": lambda s: "",
              "zeros": lambda s: " ".join("0" for _ in s.split()),
              "huge": lambda s: " ".join("1e308" for _ in s.split())}


def _bvh_rows(lines, op, motion, rows, chans) -> None:
    """("rows", row, how): a line after the motion header cut, doubled or edited."""
    rows = list(range(motion + 3, len(lines)))
    if not rows:
        return
    k = rows[op[1] % len(rows)]
    if op[2] == "cut":
        del lines[k]
    elif op[2] == "dup":
        lines.insert(k, lines[k])
    elif op[2] in _ROW_EDITS:
        lines[k] = _ROW_EDITS[op[2]](lines[k])


def _bvh_line(lines, op, motion, rows, chans) -> None:
    """("line", line, what): any line deleted or doubled, or a line inserted."""
    if not lines:
        return
    k = op[1] % len(lines)
    if op[2] == "del":
        del lines[k]
    elif op[2] == "dup":
        lines.insert(k, lines[k])
    else:
        lines.insert(k, op[2])


#: The BVH mutations by kind: each edits the file's lines in place, given where the
#: motion part starts, its rows and the CHANNELS lines as they were before it.
_BVH_OPS = {"resize": _bvh_resize, "value": _bvh_value, "order": _bvh_order,
            "drop": _bvh_columns, "position": _bvh_columns, "frames": _bvh_frames,
            "frametime": _bvh_frametime, "channels": _bvh_channels,
            "channel-name": _bvh_channels, "deep": _bvh_joints, "wide": _bvh_joints,
            "number": _bvh_number, "offset": _bvh_offset, "name": _bvh_name,
            "rows": _bvh_rows, "line": _bvh_line}


def apply_bvh(text: str, ops) -> str:
    """BVH text with ``ops`` applied (line-based; works on broken files too)."""
    lines = text.splitlines()
    for op in ops:
        motion = (_where(lines, "MOTION") or [len(lines)])[0]
        rows = [r for r in range(motion + 3, len(lines)) if lines[r].strip()]
        chans = _channels(lines)
        if op[0] in _BVH_OPS:
            _BVH_OPS[op[0]](lines, op, motion, rows, chans)
    return "\n".join(lines) + "\n"
