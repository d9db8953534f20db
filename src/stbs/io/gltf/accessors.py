"""glTF accessors both ways: one table of component types, one reader, one writer.

:func:`read_accessor` turns an accessor of a :class:`GltfFile` into a NumPy array,
checking every declared size against the bytes really there before making it
(``count``, ``byteOffset``, ``byteStride`` against the buffer view, the view against
its buffer; sparse indices in range) and counting it against the file's budget.
:class:`AccessorWriter` packs arrays into one binary buffer with their buffer views
and accessors, as :func:`stbs.io.write_gltf` and the write-back of a character need.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .container import GltfFile, pad4

__all__ = ["COMPONENTS", "TYPES", "NAMES", "read_accessor", "AccessorWriter", "describe",
           "FLOAT_ONLY", "UNIT", "SIGNED_UNIT", "QUANTIZED", "JOINT_INDICES",
           "VERTEX_INDICES", "FLOAT", "UBYTE", "USHORT", "UINT", "ARRAY_BUFFER",
           "ELEMENT_ARRAY_BUFFER"]

BYTE, UBYTE, SHORT, USHORT, UINT, FLOAT = 5120, 5121, 5122, 5123, 5125, 5126
ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963

#: componentType -> (little-endian NumPy dtype, divisor of a normalised value)
COMPONENTS = {
    BYTE: (np.dtype("i1"), 127.0),
    UBYTE: (np.dtype("u1"), 255.0),
    SHORT: (np.dtype("<i2"), 32767.0),
    USHORT: (np.dtype("<u2"), 65535.0),
    UINT: (np.dtype("<u4"), None),
    FLOAT: (np.dtype("<f4"), None),
}
#: accessor type -> number of components
TYPES = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
#: componentType -> its name in the specification, for messages
NAMES = {BYTE: "byte", UBYTE: "unsigned byte", SHORT: "short", USHORT: "unsigned short",
         UINT: "unsigned int", FLOAT: "float"}

# What an accessor may hold, by its use: (componentType, normalized) pairs, as the
# glTF 2.0 specification lists them (3.7.2.1 meshes, 3.7.3 skins, 3.11 animations) and
# KHR_mesh_quantization widens them for positions.
#: POSITION, morph target offsets, inverse bind matrices, key times, translations
FLOAT_ONLY = frozenset({(FLOAT, False)})
#: WEIGHTS_n (and stbs's _ENDPOINT_WEIGHTS_n)
UNIT = FLOAT_ONLY | {(UBYTE, True), (USHORT, True)}
#: rotation keys
SIGNED_UNIT = UNIT | {(BYTE, True), (SHORT, True)}
#: POSITION and morph target offsets of a file using KHR_mesh_quantization
QUANTIZED = FLOAT_ONLY | {(c, n) for c in (BYTE, UBYTE, SHORT, USHORT) for n in (False, True)}
#: JOINTS_n
JOINT_INDICES = frozenset({(UBYTE, False), (USHORT, False)})
#: a primitive's indices
VERTEX_INDICES = JOINT_INDICES | {(UINT, False)}


def describe(allowed) -> str:
    """``allowed`` (pairs as above) in words: ``float, normalized unsigned byte``."""
    return ", ".join(("normalized " if n else "") + NAMES[c]
                     for c, n in sorted(allowed, key=lambda x: (x[0] != FLOAT, x[0], x[1])))


def _view(f: GltfFile, v: int, what: str) -> tuple[memoryview, int, int, int | None]:
    """(buffer, start, length, byteStride) of buffer view ``v``, checked to fit."""
    bv = f.item("bufferViews", v, what)
    where = f"bufferViews[{v}]"
    k = f.get(bv, "buffer", "index", where)
    length = f.get(bv, "byteLength", "count", where)
    start = f.get(bv, "byteOffset", "index", where, 0)
    stride = f.get(bv, "byteStride", "index", where, None)
    if stride is not None and not 4 <= stride <= 252:
        raise f.error(f"{where}.byteStride in 4..252", str(stride))
    declared = f.get(f.item("buffers", k, where), "byteLength", "count", f"buffers[{k}]")
    if start + length > declared:
        raise f.error(f"{where} inside buffer {k} ({declared} bytes)",
                      f"bytes {start}..{start + length}")
    return f.buffer(k), start, length, stride


def _raw(f: GltfFile, view: int, offset: int, dt: np.dtype, nc: int, count: int,
         what: str) -> np.ndarray:
    buf, start, length, stride = _view(f, view, what)
    item = dt.itemsize * nc
    stride = stride or item
    if stride < item:
        raise f.error(f"{what}: a byteStride of at least its element's {item} bytes",
                      str(stride))
    need = offset + stride * (count - 1) + item
    if need > length:
        raise f.error(f"{what} inside its buffer view ({length} bytes)",
                      f"{count} elements reaching byte {need}")
    f.reserve(count * nc * 8, what)
    return np.ndarray((count, nc), dtype=dt, buffer=buf, offset=start + offset,
                      strides=(stride, dt.itemsize)).copy()


def read_accessor(f: GltfFile, i: Any, what: str, *, floats: bool = True,
                  types: tuple[str, ...] | None = None,
                  components: frozenset | None = None) -> np.ndarray:
    """Accessor ``i`` of ``f`` as a (count, components) array.

    Parameters
    ----------
    f : GltfFile
    i : int
        The accessor's index (checked).
    what : str
        What the accessor is for, named in errors (``"primitive 3 POSITION"``).
    floats : bool
        True: float64, normalised integers scaled to [0, 1] or [-1, 1], checked finite.
        False: int64 (indices, joints), the raw values.
    types : tuple of str, optional
        Accessor types allowed (``("VEC3",)``).
    components : frozenset of (int, bool), optional
        The (componentType, normalized) pairs allowed (:data:`FLOAT_ONLY`,
        :data:`UNIT`, :data:`JOINT_INDICES`...).

    Returns
    -------
    (count, components) float64 or int64
        Decoded once per file and kind; later calls return the same (read-only) array.
    """
    # what the accessor is checked against its use every time (one accessor may be
    # named for two uses); decoded once
    a = f.item("accessors", i, what)
    where = f"accessors[{i}] ({what})"
    ctype = f.get(a, "componentType", "index", where)
    typ = f.get(a, "type", "string", where)
    if ctype not in COMPONENTS or typ not in TYPES:
        raise f.error(f"{where}: a componentType in {sorted(COMPONENTS)} and a type in "
                      f"{', '.join(TYPES)}", f"{ctype}, {typ!r}")
    if types is not None and typ not in types:
        raise f.error(f"{where}: of type {' or '.join(types)}", typ)
    if typ in ("MAT2", "MAT3") and COMPONENTS[ctype][0].itemsize < 4:
        raise f.error(f"{where}: a matrix of 4-byte components", "a column-padded matrix")
    normalized = f.get(a, "normalized", "bool", where, False)
    if normalized and ctype in (FLOAT, UINT):
        raise f.error(f"{where}: normalized only on byte and short components",
                      f"normalized {NAMES[ctype]}")
    if components is not None and (ctype, normalized) not in components:
        raise f.error(f"{where}: components of {describe(components)}",
                      ("normalized " if normalized else "") + NAMES[ctype])
    key = (i, floats)
    if key in f.cache:
        return f.cache[key]
    dt, norm = COMPONENTS[ctype]
    nc = TYPES[typ]
    count = f.get(a, "count", "count", where)
    view = f.get(a, "bufferView", "index", where, None)
    if view is None:
        f.reserve(count * nc * 8, where)
        out = np.zeros((count, nc), dtype=dt)
    else:
        out = _raw(f, view, f.get(a, "byteOffset", "index", where, 0), dt, nc, count, where)
    sparse = f.get(a, "sparse", "object", where, None)
    if sparse is not None:
        sw = f"{where}.sparse"
        m = f.get(sparse, "count", "count", sw)
        if m > count:
            raise f.error(f"{sw}.count at most the accessor's {count}", str(m))
        ind = f.get(sparse, "indices", "object", sw)
        ictype = f.get(ind, "componentType", "index", sw + ".indices")
        if ictype not in (UBYTE, USHORT, UINT):
            raise f.error(f"{sw}.indices: unsigned byte, short or int", str(ictype))
        idx = _raw(f, f.get(ind, "bufferView", "index", sw + ".indices"),
                   f.get(ind, "byteOffset", "index", sw + ".indices", 0),
                   COMPONENTS[ictype][0], 1, m, sw + ".indices")[:, 0].astype(np.int64)
        val = f.get(sparse, "values", "object", sw)
        vals = _raw(f, f.get(val, "bufferView", "index", sw + ".values"),
                    f.get(val, "byteOffset", "index", sw + ".values", 0), dt, nc, m,
                    sw + ".values")
        if idx.size and (idx.max() >= count or np.any(np.diff(idx) <= 0)):
            raise f.error(f"{sw}.indices increasing and below {count}",
                          f"indices up to {int(idx.max())}")
        out[idx] = vals
    if not floats:
        x = out.astype(np.int64)
    else:
        x = out.astype(np.float64)
        if normalized and norm is not None:
            x = np.maximum(x / norm, -1.0)
        if not np.isfinite(x).all():
            raise f.error(f"{where}: finite values", "NaN or infinity")
    x.setflags(write=False)
    f.cache[key] = x
    return x


class AccessorWriter:
    """Arrays packed into one binary buffer, with their buffer views and accessors.

    Parameters
    ----------
    data : bytes, optional
        Bytes the buffer starts with (a copy of a file's buffer being extended).
    """

    def __init__(self, data: bytes = b""):
        self.data = bytearray(data)
        self.views: list[dict] = []
        self.accessors: list[dict] = []
        self.view_base = 0
        self.accessor_base = 0

    def raw(self, blob: bytes, *, target: int | None = None, align: int = 4) -> int:
        """Append ``blob`` as a buffer view of its own; returns the view's index."""
        self.data.extend(b"\0" * (-len(self.data) % align))
        view = {"buffer": 0, "byteOffset": len(self.data), "byteLength": len(blob)}
        if target is not None:
            view["target"] = target
        self.data.extend(blob)
        self.views.append(view)
        return self.view_base + len(self.views) - 1

    def add(self, a: np.ndarray, ctype: int, gl_type: str, *, target: int | None = None,
            normalized: bool = False, minmax: bool = False) -> int:
        """Append array ``a`` (one element per row; MAT4 as (count, 16) column-major) as
        an accessor of ``ctype`` and ``gl_type``; returns the accessor's index."""
        dt = COMPONENTS[ctype][0]
        nc = TYPES[gl_type]
        a = np.ascontiguousarray(np.asarray(a).reshape(-1, nc), dtype=dt)
        view = self.raw(a.tobytes(), target=target)
        acc: dict[str, Any] = {"bufferView": view, "componentType": ctype,
                               "count": int(len(a)), "type": gl_type}
        if normalized:
            acc["normalized"] = True
        if minmax:
            acc["min"] = a.min(axis=0).astype(float).tolist()
            acc["max"] = a.max(axis=0).astype(float).tolist()
        self.accessors.append(acc)
        return self.accessor_base + len(self.accessors) - 1

    def blob(self) -> bytes:
        """The buffer's bytes, padded to 4."""
        return pad4(self.data)
