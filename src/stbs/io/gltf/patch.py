"""Writing a character back: a copy of its glTF file plus what stbs added.

The paper's promise is that STBS needs "only an extra scalar weight function per
bone ... without changing the existing skeleton rig or bone weights". So a rig read
from a glTF file is written back as a *copy* of that file -- nodes, joint orientations,
animations, materials and textures as they were -- with, on every skinned primitive the
rig's vertices came from (``rig.meta["gltf"]["primitives"]``):

- the endpoint weights as ``_ENDPOINT_WEIGHTS_n``, aligned with ``JOINTS_n``;
- when the rig's bone weights are no longer the file's (recomputed, painted), new
  ``JOINTS_0``/``WEIGHTS_0`` (each vertex's four heaviest joints of that primitive's
  skin, quantised to sum to 65535) in place of the file's sets;

and the bone table (:mod:`stbs.io.gltf.bones`) in each of the rig's skins.

A *rigid part* (a mesh without a skin hung on a joint, ``rig.meta["gltf"]["rigid"]``)
is left exactly as it was, and its endpoint weights are not written. Giving it
skinning attributes would mean giving its node a skin, and a skinned mesh ignores its
node's transform and its parents' (the validator warns about a skinned mesh that is
not a root node, and viewers differ in how they draw one), so the copy would no longer
draw as the source in every viewer. Read back, its endpoint weights are eq. 8's
projection onto its bone (see :func:`stbs.io.read_gltf`); new bone weights on it are
not written either (with a warning). The copy is
self-contained: the buffers the file uses become one (the GLB's BIN chunk, or a
``data:`` URI), and external PNG or JPEG images are embedded, so it can be written
anywhere.
"""

from __future__ import annotations

import copy
import os
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from ..._inputs import note_input
from ...rig.model import Rig
from .accessors import ARRAY_BUFFER, FLOAT, AccessorWriter, read_accessor
from .bones import TABLE_KEY, bone_table
from .container import GltfFile
from .read import primitive_weights
from .scene import Scene
from .write import save_gltf_document, skin_attributes

__all__ = ["write_back"]

# A rig's weights within this of the file's (rows normalised) are the file's.
_SAME_WEIGHTS = 1e-6
_MAGIC = ((b"\x89PNG\r\n\x1a\n", "image/png"), (b"\xff\xd8\xff", "image/jpeg"))


def _dense(X) -> np.ndarray:
    return X.toarray() if hasattr(X, "toarray") else np.asarray(X, dtype=float)


def _merge_buffers(f: GltfFile, doc: dict) -> AccessorWriter:
    """One buffer holding every buffer a buffer view uses (views moved into it), and
    the external PNG/JPEG images; unused buffers are dropped unopened."""
    blob = AccessorWriter()
    base: dict[int, int] = {}
    f.items("bufferViews")                         # checked: an array
    views = doc.get("bufferViews", [])
    for i, v in enumerate(views):
        where = f"bufferViews[{i}]"
        f.item("bufferViews", i, where)            # checked: an object
        k = f.get(v, "buffer", "index", where)
        offset = f.get(v, "byteOffset", "index", where, 0)
        if k not in base:
            blob.data.extend(b"\0" * (-len(blob.data) % 16))    # keeps every alignment
            base[k] = len(blob.data)
            blob.data.extend(f.buffer(k))
        v["buffer"] = 0
        v["byteOffset"] = base[k] + offset
    blob.view_base = len(views)
    f.items("images")
    for i, img in enumerate(doc.get("images", [])):
        uri = img.get("uri") if isinstance(img, dict) else None
        if not isinstance(uri, str) or uri.startswith("data:"):
            continue
        p = f.resolve(uri, f"images[{i}].uri")
        try:
            if not p.is_file():
                continue              # as broken as in the source; left as it was
            note_input(p)
            data = p.read_bytes()
        except OSError:
            continue                  # a name too long, unreadable: likewise
        mime = next((m for magic, m in _MAGIC if data.startswith(magic)), None)
        if mime is None:
            continue                  # KTX2, WebP: need their extension's rules; kept
        img.pop("uri")
        img["bufferView"] = blob.raw(data)
        img["mimeType"] = mime
    return blob


def _record(rig: Rig) -> dict:
    """The rig's record of the glTF file it was read from, checked usable."""
    info = (rig.meta or {}).get("gltf")
    if not isinstance(info, dict) or "primitives" not in info or "joints" not in info:
        raise ValueError("rig.meta['gltf'] is missing or from an older stbs: read the rig "
                         "from its glTF file again (or write it without source=)")
    if rig.E is None:
        raise ValueError("the rig has no endpoint weights (E) to add")
    return info


def _source(src: str | os.PathLike) -> GltfFile:
    """The source file, refused where it uses a compression stbs cannot write back."""
    f = GltfFile(src)
    if "EXT_meshopt_compression" in f.get(f.doc, "extensionsUsed", "array", "glTF", []):
        raise ValueError(f"{str(f.path)!r} uses EXT_meshopt_compression; write the rig "
                         "without source= (a fresh glTF file)")
    return f


def _recorded_joints(f: GltfFile, scene: Scene, info: dict, b: int) -> list[int]:
    """The joint node of each of the rig's ``b`` bones, checked against the file."""
    joints = [int(j) for j in info["joints"]]
    if len(joints) != b or any(not 0 <= j < scene.n for j in joints):
        raise ValueError(f"{str(f.path)!r} is not the file the rig was read from (the rig has "
                         f"{b} bones, its record names {len(joints)} joint nodes)")
    return joints


def _not_the_source(f: GltfFile, what: str, count, n: int) -> ValueError:
    return ValueError(f"{str(f.path)!r} is not the file the rig was read from ({what} "
                      f"has {count} vertices, the rig's record {n})")


def _skinned_primitive(f: GltfFile, doc: dict, scene: Scene, col: dict[int, int], e: dict,
                       n_rows: int) -> tuple[dict, np.ndarray]:
    """The attributes (in ``doc``) of the skinned primitive the record ``e`` names, and
    its skin's joints as the rig's bones; checked to be the one the rig was read from."""
    m, k, s = int(e["mesh"]), int(e["primitive"]), int(e["skin"])
    start, n = int(e["start"]), int(e["count"])
    what = f"mesh {m} primitive {k}"
    try:
        prim = doc["meshes"][m]["primitives"][k]
        at = prim["attributes"]
        count = f.items("accessors")[at["POSITION"]]["count"]
        to_bone = np.array([col[j] for j in scene.skin_joints(s)])
    except (KeyError, IndexError, TypeError):
        raise ValueError(f"{str(f.path)!r} is not the file the rig was read from ({what} "
                         "or its skin's joints differ)") from None
    if count != n or start + n > n_rows:
        raise _not_the_source(f, what, count, n)
    return at, to_bone


def _same_weights(Wf: np.ndarray, Wr: np.ndarray) -> bool:
    """Whether the rig's rows ``Wr`` are the file's ``Wf`` (both rows normalised)."""
    return np.abs(Wf / Wf.sum(1, keepdims=True)
                  - Wr / np.maximum(Wr.sum(1, keepdims=True), 1e-300)).max() <= _SAME_WEIGHTS


def _add_endpoints(f: GltfFile, at: dict, what: str, Er: np.ndarray, to_bone: np.ndarray,
                   blob: AccessorWriter) -> None:
    """An ``_ENDPOINT_WEIGHTS_c`` beside each ``JOINTS_c``/``WEIGHTS_c`` set the file
    keeps: the rig's endpoint weights ``Er`` of the primitive's vertices, on the
    set's joints."""
    n = len(Er)
    c = 0
    while f"JOINTS_{c}" in at:
        J = read_accessor(f, at[f"JOINTS_{c}"], f"{what} JOINTS_{c}", floats=False)
        Wk = read_accessor(f, at[f"WEIGHTS_{c}"], f"{what} WEIGHTS_{c}")
        e4 = np.where(Wk > 0, Er[np.arange(n)[:, None], to_bone[J]], 0.0)
        at[f"_ENDPOINT_WEIGHTS_{c}"] = blob.add(np.clip(e4, 0, 1), FLOAT, "VEC4",
                                                target=ARRAY_BUFFER)
        c += 1


def _reweight(at: dict, what: str, s: int, Wr: np.ndarray, Er: np.ndarray,
              to_bone: np.ndarray, b: int, blob: AccessorWriter) -> None:
    """Replace the primitive's weight sets with the rig's ``Wr`` and ``Er``, which must
    weigh only joints of its skin ``s``."""
    outside = np.delete(Wr, to_bone, axis=1).sum() if len(to_bone) < b else 0.0
    if outside > 1e-6 * Wr.sum():
        raise ValueError(f"{what}: the rig weighs joints its skin {s} does not have; "
                         "write the rig without source= (a fresh glTF file)")
    for name in [a for a in at if a.startswith(("JOINTS_", "WEIGHTS_"))]:
        del at[name]
    at.update(skin_attributes(blob, Wr[:, to_bone], Er[:, to_bone], len(to_bone)))


def _write_skinned(f: GltfFile, doc: dict, scene: Scene, info: dict, col: dict[int, int],
                   W: np.ndarray, E: np.ndarray, b: int, blob: AccessorWriter) -> int:
    """Give each skinned primitive of ``doc`` the rig's endpoint weights (beside the
    file's weights where the rig's are the same, else with the rig's weights); the
    vertices the record counts for them."""
    done: set[tuple[int, int]] = set()
    total = 0
    for e in info["primitives"]:
        m, k, s = int(e["mesh"]), int(e["primitive"]), int(e["skin"])
        start, n = int(e["start"]), int(e["count"])
        total += n
        if (m, k) in done:
            continue                   # a mesh drawn by two nodes: its attributes are shared
        done.add((m, k))
        what = f"mesh {m} primitive {k}"
        at, to_bone = _skinned_primitive(f, doc, scene, col, e, len(W))
        rows = slice(start, start + n)
        Wf, _ = primitive_weights(f, at, n, to_bone, b, what)
        same = _same_weights(Wf, W[rows])
        for name in [a for a in at if a.startswith("_ENDPOINT_WEIGHTS_")]:
            del at[name]
        if same:
            _add_endpoints(f, at, what, E[rows], to_bone, blob)
        else:
            _reweight(at, what, s, W[rows], E[rows], to_bone, b, blob)
    return total


def _repainted_parts(f: GltfFile, doc: dict, scene: Scene, info: dict, col: dict[int, int],
                     W: np.ndarray, b: int) -> tuple[int, list[str]]:
    """The vertices the record counts for the rigid parts (written as they were), and
    the names of the parts the rig weighs otherwise than 1 on their joint."""
    total = 0
    repainted = []
    for e in info.get("rigid", []):
        m, k, start, n = (int(e[x]) for x in ("mesh", "primitive", "start", "count"))
        total += n
        what = f"mesh {m} primitive {k}"
        try:
            count = f.items("accessors")[doc["meshes"][m]["primitives"][k]["attributes"][
                "POSITION"]]["count"]
            bone = col[int(e["joint"])]
        except (KeyError, IndexError, TypeError):
            raise ValueError(f"{str(f.path)!r} is not the file the rig was read from ({what} "
                             "or its joint differ)") from None
        if count != n or start + n > len(W):
            raise _not_the_source(f, what, count, n)
        Wr = W[start:start + n]
        one = np.zeros(b)
        one[bone] = 1.0
        if np.abs(Wr / np.maximum(Wr.sum(1, keepdims=True), 1e-300) - one).max() \
                > _SAME_WEIGHTS:
            repainted.append(scene.name(int(e["node"])))
    return total, repainted


def _store_bone_table(doc: dict, info: dict, table) -> None:
    """Keep the bone table in the extras of each skin the rig was read from."""
    for s in info.get("skins", []):
        skin = doc["skins"][int(s)]
        extras = skin.setdefault("extras", {})
        if not isinstance(extras, dict):
            skin["extras"] = extras = {"value": extras}
        extras[TABLE_KEY] = table


def write_back(src: str | os.PathLike, dst: str | os.PathLike, rig: Rig) -> None:
    """Write ``rig`` (read from the glTF file ``src``) to ``dst`` as a copy of ``src``
    with its endpoint weights and bone table (see the module docs).

    Raises
    ------
    ValueError
        ``rig`` was not read from a glTF file, has no endpoint weights, or does not fit
        ``src`` (other vertex counts or joints).
    FormatError
        ``src`` is damaged (as :func:`stbs.io.read_gltf` would say).
    """
    info = _record(rig)
    f = _source(src)
    scene = Scene(f)
    sk = rig.skeleton
    joints = _recorded_joints(f, scene, info, sk.n_bones)
    col = {j: i for i, j in enumerate(joints)}
    doc: dict[str, Any] = copy.deepcopy(f.doc)
    blob = _merge_buffers(f, doc)
    accessors = doc.setdefault("accessors", [])
    blob.accessor_base = len(accessors)
    W = _dense(rig.W)
    E = _dense(rig.E)
    total = _write_skinned(f, doc, scene, info, col, W, E, sk.n_bones, blob)
    rigid_total, repainted = _repainted_parts(f, doc, scene, info, col, W, sk.n_bones)
    total += rigid_total
    if repainted:
        warnings.warn(f"the rigid parts {', '.join(map(repr, dict.fromkeys(repainted)))} "
                      "have new bone weights in the rig; they are written as they were "
                      "(moved by their nodes), without them", UserWarning, stacklevel=3)
    if total != len(W):
        raise ValueError(f"the rig has {len(W)} vertices, the file's meshes {total}")
    _store_bone_table(doc, info, bone_table(sk, joints))
    doc["bufferViews"] = doc.get("bufferViews", []) + blob.views
    doc["accessors"] = accessors + blob.accessors
    save_gltf_document(Path(os.fspath(dst)), doc, blob.blob())
