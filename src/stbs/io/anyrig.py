"""A rig from or to any rig file: the native ``.npz``, a glTF character, or (to read) an
FBX character.

The paper's promise is that STBS needs "only an extra scalar weight function per
bone ... without changing the existing skeleton rig or bone weights". So a glTF
character is a rig wherever a rig is read, and :func:`write_rig` of a rig read from a
glTF file *adds* its endpoint weights to a copy of that file, keeping everything else
of it (nodes, joint orientations, animations, materials) as it was.
"""

from __future__ import annotations

import base64
import json
import os
import struct
from pathlib import Path
from typing import Any

import numpy as np

from ..rig.model import Rig
from ._atomic import atomic_open
from ._parse import input_path, suffix
from .errors import FormatError
from .fbx import FBX_EXTENSIONS
from .fbx import _read as _read_fbx
from .gltf import GLTF_EXTENSIONS, _File, read_gltf
from .gltf_write import glb_bytes, write_gltf
from .rig import load_rig, save_rig

__all__ = ["read_rig", "write_rig", "RIG_EXTENSIONS"]

RIG_EXTENSIONS = (".npz", *GLTF_EXTENSIONS, *FBX_EXTENSIONS)


def read_rig(path: str | os.PathLike, **gltf_options: Any) -> Rig:
    """The rig in a ``.npz`` rig file, a glTF 2.0 file (``.gltf``/``.glb``) or an FBX file.

    ``gltf_options`` (``skin=``, ``mesh=``) pick the skinned mesh of a glTF file or the
    skeleton of an FBX file (see :func:`stbs.io.read_gltf`, :func:`stbs.io.read_fbx`);
    their animations are not read here.
    """
    ext = suffix(path, RIG_EXTENSIONS, "read_rig")
    if ext == ".npz":
        if gltf_options:
            raise TypeError(f"{', '.join(gltf_options)}: options for glTF files, not .npz")
        return load_rig(path)
    if ext in FBX_EXTENSIONS:
        return _read_fbx(path, anims=False, **gltf_options)[0]
    return read_gltf(path, **gltf_options)[0]


def write_rig(path: str | os.PathLike, rig: Rig, *, source: str | os.PathLike | None = None
              ) -> None:
    """Write a rig to ``.npz`` or glTF (``.glb``/``.gltf``), atomically.

    Parameters
    ----------
    path : str or os.PathLike
        The destination; its extension picks the format.
    rig : Rig
    source : str or os.PathLike, optional
        The glTF file ``rig`` was read from. Writing glTF then copies that file and adds
        the rig's endpoint weights (``_ENDPOINT_WEIGHTS_0`` on every primitive of the
        skinned mesh, aligned with ``JOINTS_0``) and its bone table
        (``skin.extras["stbs"]``); nothing else of the file changes. Without it, glTF
        is written afresh by :func:`stbs.io.write_gltf`.
    """
    ext = suffix(path, RIG_EXTENSIONS, "write_rig")
    if ext in FBX_EXTENSIONS:
        raise ValueError(f"write_rig: cannot write FBX ({os.fspath(path)!r}); stbs reads FBX "
                         "characters only: write .npz, .glb or .gltf")
    if ext == ".npz":
        save_rig(path, rig)
    elif source is not None and str(source).lower().endswith(GLTF_EXTENSIONS):
        _add_endpoint_weights(Path(os.fspath(source)), Path(os.fspath(path)), rig)
    else:
        write_gltf(path, rig)


def _raw_json(p: Path) -> tuple[dict, bytes | None]:
    """The JSON object of a glTF file and, for a GLB, its BIN chunk."""
    data = p.read_bytes()
    if p.suffix.lower() == ".gltf":
        return json.loads(data.decode("utf-8")), None
    if len(data) < 20 or data[:4] != b"glTF":
        raise FormatError(p, "a GLB file ('glTF' magic)", "another kind of file")
    n = struct.unpack_from("<I", data, 12)[0]
    doc = json.loads(data[20:20 + n].decode("utf-8"))
    at = 20 + n
    blob = None
    if at + 8 <= len(data):
        m, kind = struct.unpack_from("<I4s", data, at)
        if kind == b"BIN\0":
            blob = data[at + 8:at + 8 + m]
    return doc, blob


def _add_endpoint_weights(src: Path, dst: Path, rig: Rig) -> None:
    src = input_path(src, "glTF")
    info = (rig.meta or {}).get("gltf")
    if not isinstance(info, dict) or "node" not in info or "skin" not in info:
        raise ValueError("rig.meta['gltf'] is missing: the rig was not read from a glTF "
                         "file (write it without source=)")
    if rig.E is None:
        raise ValueError("the rig has no endpoint weights (E) to add")
    f = _File(src)
    doc, blob = _raw_json(src)
    node = doc["nodes"][info["node"]]
    if node.get("skin") != info["skin"] or node.get("mesh") is None:
        raise ValueError(f"{str(src)!r} is not the file the rig was read from (node "
                         f"{info['node']} has no skinned mesh)")
    E = rig.E.toarray() if hasattr(rig.E, "toarray") else np.asarray(rig.E, dtype=float)
    buffers = [bytes(b) for b in f.buffers]
    if blob is not None and buffers and doc["buffers"][0].get("uri") is None:
        buffers[0] = bytes(blob)
    extra = bytearray(buffers[0]) if buffers else bytearray()
    off = 0
    prims = doc["meshes"][node["mesh"]]["primitives"]
    for k, prim in enumerate(prims):
        at = prim["attributes"]
        n = f.g.accessors[at["POSITION"]].count
        J = f.accessor(at["JOINTS_0"], f"primitive {k} JOINTS_0", floats=False)
        W0 = f.accessor(at["WEIGHTS_0"], f"primitive {k} WEIGHTS_0")
        rows = np.arange(off, off + n)
        if rows[-1] >= len(E):
            raise ValueError(f"the rig has {len(E)} vertices, fewer than the file's mesh")
        E4 = np.where(W0 > 0, E[rows[:, None], np.clip(J, 0, E.shape[1] - 1)], 0.0)
        while len(extra) % 4:
            extra.append(0)
        raw = np.ascontiguousarray(np.clip(E4, 0, 1), dtype="<f4").tobytes()
        doc.setdefault("bufferViews", []).append(
            {"buffer": 0, "byteOffset": len(extra), "byteLength": len(raw), "target": 34962})
        extra.extend(raw)
        doc.setdefault("accessors", []).append(
            {"bufferView": len(doc["bufferViews"]) - 1, "componentType": 5126, "count": n,
             "type": "VEC4"})
        at["_ENDPOINT_WEIGHTS_0"] = len(doc["accessors"]) - 1
        off += n
    if off != len(E):
        raise ValueError(f"the rig has {len(E)} vertices, the file's mesh {off}")
    sk = rig.skeleton
    skin = doc["skins"][info["skin"]]
    skin.setdefault("extras", {})
    if not isinstance(skin["extras"], dict):
        skin["extras"] = {"value": skin["extras"]}
    skin["extras"]["stbs"] = {"version": 1, "C": sk.C.tolist(), "BE": sk.BE.tolist(),
                              "names": list(sk.names)}
    if not buffers:
        doc["buffers"] = [{"byteLength": 0}]
        buffers = [b""]
    buffers[0] = bytes(extra)
    glb = dst.suffix.lower() == ".glb"
    for k, b in enumerate(doc["buffers"]):
        b["byteLength"] = len(buffers[k])
        if glb and k == 0:
            b.pop("uri", None)
        else:
            b["uri"] = "data:application/octet-stream;base64," + base64.b64encode(
                buffers[k]).decode()
    if glb:
        with atomic_open(dst, "wb") as out:
            out.write(glb_bytes(doc, buffers[0]))
    else:
        with atomic_open(dst, "w", encoding="utf-8") as out:
            json.dump(doc, out)
