"""FBX skins in: :func:`read_fbx` -> (:class:`stbs.Rig`, clips).

FBX (binary and ASCII, versions 6 and 7) is parsed and evaluated by ufbx, through
its author's Python binding (the ``fbx`` extra, ``pip install 'stbs-skinning[fbx]'``).
That binding (0.0.5) miscounts references to the scene's objects, which crashes the
interpreter when a scene is freed or garbage-collected; so the file is read in a child
process that hands back plain arrays and exits without freeing anything, as
:mod:`stbs.meshing.tetrahedra` does with TetGen. It costs about a third of a second.

How an FBX character becomes a rig
----------------------------------
- The *skeleton* is picked by ``skin=`` (a skin deformer) or ``mesh=``; by default the
  only one. Every mesh with a skin deformer whose clusters name bones of that skeleton
  is read (Mixamo's body and joints meshes, say): ``V`` and ``F`` are their vertices
  and faces concatenated in the file's order, and ``rig.meta["fbx"]["meshes"]`` says
  which vertex range (``start``, ``stop``) came from which mesh. Polygons become
  triangle fans ``(v0, v_k, v_k+1)``, exact for convex faces; points and lines are
  dropped. Only a mesh's first skin deformer counts, as in ufbx's own evaluation.
- *Rigid parts*: a mesh without a skin deformer whose node is a joint or lies below one
  (a robot's limbs parented to its bones) moves with its nearest joint ``j``: ufbx
  draws it at ``G_j(t) G_j^-1 X`` (``X`` its geometry-to-world at rest, ``G_j`` the
  joint's world transform, at rest and at ``t``). Its vertices follow the skinned
  meshes' in ``V`` (mesh order, each instance of the mesh under a joint once), placed
  at ``B_j G_j^-1 X`` (``B_j`` the joint's bind matrix), so the joint's skinning matrix
  ``G_j(t) B_j^-1`` moves them exactly as ufbx does; their rows of ``W`` are 1 on bone
  ``j``, and a mirroring ``X`` reverses their triangles' winding, as renderers do.
  ``rig.meta["fbx"]["rigid"]`` records each one (mesh name, node, joint, ``start``,
  ``stop``). A stack that moves a node between a part and its joint is warned about
  (the part then follows its joint only). Meshes under no joint (props, scenery) are
  not read; ``rigid=False`` leaves the rigid parts out, and so does ``mesh=``.
- The *joints* are the bones the clusters name (LimbNode, Null or any other node),
  plus the nodes on the parent chains between two of them, in the file's node order.
  Bone ``i`` of the rig is joint ``i`` (see :mod:`stbs.rig.joints`), named after its
  node (a repeated name gets ``#2``, ``#3``, ...). Nodes above the topmost joint (the
  armature) and leaf nodes no cluster names (Blender's ``_end`` bones) are not joints.
- ``W`` has one column per joint: each cluster's weights, each row divided by its sum
  (ufbx does the same when it skins). A vertex without weight is an error.
- *Coordinates* are the file's, in world space, as ufbx gives them: no change of axes
  or units (``rig.meta["fbx"]`` records the file's ``unit_meters`` and axes).
  ``V`` is each mesh in the world bind pose: its geometry mapped by the bind matrix of
  the mesh that its clusters agree on (``TransformLink @ geometry_to_bone``, the one
  carrying the most weight); a joint's bind matrix is its cluster's ``TransformLink``
  (the bind pose, or the node's rest transform, for a chain node no cluster names).
  Where a cluster binds the mesh elsewhere than the others do, that joint's bind is
  taken so that the rig skins exactly as the file does, with a warning.
- Each animation stack becomes a :class:`stbs.Clip`, sampled at the file's frame rate
  over the stack's time span (and at its end): FBX curves are Bezier curves of Euler
  angles, which the clip's key-to-key interpolation cannot follow, so the clip keys
  the scene as ufbx evaluates it at every frame. At a key, bone ``i``'s pose is the
  rigid part of its joint's skinning matrix ``G(t) B^-1``, so skinning the clip with
  ``lbs`` reproduces ufbx's linear skinning of the file at the keys; a joint whose
  matrix scales loses the scale, with a warning (:func:`clip_from_joint_matrices`).

Not read: blend shapes (morph targets), materials and UVs, dual-quaternion blending
(the weights are read; ``rig.meta["fbx"]`` names the file's skinning method).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._optional import OptionalDependencyError, require
from ..clip import MAX_SAMPLES, Clip
from ..rig.joints import clip_from_joint_matrices, rig_from_joints
from ..rig.model import Rig
from ._parse import input_path, suffix
from ._stack import MeshStack
from .errors import FormatError

__all__ = ["read_fbx", "FBX_EXTENSIONS"]

FBX_EXTENSIONS = (".fbx",)

_WHAT = "an FBX file (binary or ASCII)"

# The child: loads the file with ufbx, writes plain arrays (and one JSON string) to an
# .npz, and leaves with os._exit so that nothing of ufbx is ever freed. The binding
# hands out a cached element object without a new reference (each second fetch of
# the same node, cluster or mesh takes one away), so every element fetched here gets
# one back (`own`); the garbage collector is off because the binding's scene object
# breaks when it collects it. Evaluated scenes (one per frame) are freed explicitly,
# each right after its matrices are read, which is safe with the references set right.
_WORKER = r'''
import gc, json, os, sys
try:        # the address-space cap (argv[6]), set first: numpy and ufbx map ~1 GiB more
    import resource
    _cap = int(sys.argv[6]) + 2**30
    _soft, _hard = resource.getrlimit(resource.RLIMIT_AS)
    resource.setrlimit(resource.RLIMIT_AS, (
        _cap if _hard == resource.RLIM_INFINITY else min(_cap, _hard), _hard))
except (ImportError, ValueError, OSError):
    pass
gc.disable()
import ctypes
import numpy as np


def done(code, text=None):
    if text is not None:
        sys.stdout.write(text + "\n")
    sys.stdout.flush()
    os._exit(code)


try:
    import ufbx
    ufbx.evaluate_scene, ufbx.SkinCluster.geometry_to_bone
except (ImportError, AttributeError) as exc:
    done(4, json.dumps({"error": "import", "message": f"{type(exc).__name__}: {exc}"}))

incref = ctypes.pythonapi.Py_IncRef
incref.argtypes = [ctypes.py_object]
incref.restype = None
memo = {}


def own(e):
    if e is not None:
        incref(e)
    return e


def items(seq):
    return [own(seq[i]) for i in range(len(seq))]


def get(obj, name):
    """An element-valued attribute: the binding fetches it once per object."""
    key = (id(obj), name)
    if key not in memo:
        memo[key] = (obj, own(getattr(obj, name)))
    return memo[key][1]


def mat(m):
    out = np.eye(4)
    out[:3, :] = np.array(m, dtype=float).T
    return out


src, dst, want_anims = sys.argv[1], sys.argv[2], sys.argv[3] == "1"
MAX_FRAMES, MAX_BYTES = int(sys.argv[4]), int(sys.argv[5])
try:
    scene = ufbx.load_file(src, file_format=ufbx.FileFormat.FBX, ignore_embedded=True,
                           ignore_missing_external_files=True)
except ufbx.UfbxError as exc:
    done(3, json.dumps({"error": type(exc).__name__, "message": str(exc)}))

md, st = scene.metadata, scene.settings
nodes = items(scene.nodes)
index = {id(n): k for k, n in enumerate(nodes)}
# parents below the scene's root node: -1 for the root and its children
parent = [index[id(get(n, "parent"))] if get(n, "parent") is not None
          and not get(n, "parent").is_root else -1 for n in nodes]
out = {"node_world": np.array([mat(n.node_to_world) for n in nodes]).reshape(-1, 4, 4)}
meta = {
    "version": int(md.version), "ascii": bool(md.ascii), "creator": str(md.creator),
    "fps": float(st.frames_per_second), "unit_meters": float(st.unit_meters),
    "axes": [int(st.axes.right), int(st.axes.up), int(st.axes.front)],
    "nodes": [{"name": n.name, "parent": p, "attrib": int(n.attrib_type)}
              for n, p in zip(nodes, parent)],
    "meshes": [], "skins": [], "stacks": [], "pose": [],
}
skins = items(scene.skin_deformers)
skin_index = {id(s): k for k, s in enumerate(skins)}
meta["skins"] = [s.name for s in skins]
c = 0
for m, mesh in enumerate(items(scene.meshes)):
    inst = items(mesh.instances)
    mine = items(mesh.skin_deformers)
    rec = {"name": mesh.name, "nodes": [index[id(n)] for n in inst],
           "skins": [skin_index[id(s)] for s in mine], "clusters": [], "method": None}
    out[f"mesh{m}_V"] = np.array(mesh.vertices, dtype=float).reshape(-1, 3)
    out[f"mesh{m}_I"] = np.array(mesh.vertex_indices, dtype=np.int64).reshape(-1)
    out[f"mesh{m}_faces"] = np.array(mesh.faces, dtype=np.int64).reshape(-1, 2)
    out[f"mesh{m}_g2w"] = np.array([mat(n.geometry_to_world) for n in inst]).reshape(-1, 4, 4)
    if mine:
        rec["method"] = int(mine[0].skinning_method)
        for cl in items(mine[0].clusters):
            bone = get(cl, "bone_node")
            rec["clusters"].append({"name": cl.name,
                                    "bone": index[id(bone)] if bone is not None else -1})
            out[f"cl{c}_v"] = np.array(cl.vertices, dtype=np.int64).reshape(-1)
            out[f"cl{c}_w"] = np.array(cl.weights, dtype=float).reshape(-1)
            out[f"cl{c}_g2b"] = mat(cl.geometry_to_bone)
            out[f"cl{c}_link"] = mat(cl.bind_to_world)
            c += 1
    meta["meshes"].append(rec)
seen = set()
for pose in items(scene.poses):
    if not pose.is_bind_pose:
        continue
    bps = [pose.bone_poses[i] for i in range(len(pose.bone_poses))]
    for bp in bps:
        node = get(bp, "bone_node")
        if node is not None and id(node) not in seen:
            seen.add(id(node))
            meta["pose"].append(index[id(node)])
            out.setdefault("pose_world", []).append(mat(bp.bone_to_world))
if "pose_world" in out:
    out["pose_world"] = np.array(out["pose_world"])

def ancestors(k):
    out = []
    k = parent[k]
    while k >= 0:
        out.append(k)
        k = parent[k]
    return out


# The nodes a skeleton can use: every cluster's bone and its ancestors.
need = set()
for rec in meta["meshes"]:
    for cl in rec["clusters"]:
        k = cl["bone"]
        while k >= 0 and k not in need:
            need.add(k)
            k = parent[k]
# and the nodes of meshes without a skin below them (parts hung on a bone)
for rec in meta["meshes"]:
    if not rec["skins"]:
        for k in rec["nodes"]:
            if any(a in need for a in ancestors(k)):
                need.add(k)
need = sorted(need)
meta["evaluated"] = need
fps = meta["fps"] if np.isfinite(meta["fps"]) and meta["fps"] > 0 else 30.0
for s, stack in enumerate(items(scene.anim_stacks)):
    t0, t1 = float(stack.time_begin), float(stack.time_end)
    span = (t1 - t0) * fps
    n = max(int(np.floor(span + 1e-6)), 0) if np.isfinite(span) and span < MAX_FRAMES else 0
    times = t0 + np.arange(n + 1) / fps
    if t1 - times[-1] > 1e-6 / fps:
        times = np.append(times, t1)
    meta["stacks"].append({"name": stack.name, "begin": t0, "end": t1})
    if not want_anims or not need:
        continue
    if not (np.isfinite(t0) and np.isfinite(span)) or span + 2 > MAX_FRAMES \
            or (span + 2) * len(need) * 128 > MAX_BYTES:
        done(3, json.dumps({"error": "limit", "message":
                            f"animation stack {stack.name!r} from {t0:g} s to {t1:g} s at "
                            f"{fps:g} fps over {len(need)} nodes: more than {MAX_FRAMES} "
                            f"frames or {MAX_BYTES >> 20} MiB of node matrices"}))
    anim = stack.anim
    G = np.empty((len(times), len(need), 4, 4))
    for k, t in enumerate(times):
        ev = scene.evaluate(anim, float(t))
        enodes = ev.nodes
        got = [own(enodes[i]) for i in need]
        G[k] = [mat(e.node_to_world) for e in got]
        ev.free()
        del got, enodes, ev
    out[f"stack{s}_times"] = times
    out[f"stack{s}_G"] = G
out["meta"] = np.array(json.dumps(meta))
with open(dst, "wb") as f:
    np.savez(f, **out)
done(0)
'''


#: The reading process may use this many bytes of memory plus MEMORY_FACTOR times the
#: file's size, and this many seconds plus one per MiB of file.
MEMORY_BASE = 2 * 2**30
MEMORY_FACTOR = 64
TIMEOUT_BASE = 120.0


def _run_child(p: Path, anims: bool) -> tuple[dict, dict[str, np.ndarray]]:
    """The raw scene: the child's JSON record and arrays (see ``_WORKER``)."""
    require("ufbx", f"reading the FBX file {str(p)!r}")
    head = p.read_bytes()[:32] if p.stat().st_size else b""
    if not head:
        raise FormatError(p, _WHAT, "an empty file")
    with tempfile.TemporaryDirectory(prefix="stbs-fbx-") as tmp:
        dst = os.path.join(tmp, "scene.npz")
        size = p.stat().st_size
        memory = MEMORY_BASE + MEMORY_FACTOR * size
        try:
            proc = subprocess.run([sys.executable, "-c", _WORKER, str(p.resolve()), dst,
                                   "1" if anims else "0", str(MAX_SAMPLES), str(memory // 2),
                                   str(memory)],
                                  cwd=tmp, capture_output=True, text=True, errors="replace",
                                  check=False, timeout=TIMEOUT_BASE + size / 2**20)
        except subprocess.TimeoutExpired:
            raise FormatError(p, _WHAT, f"a file the FBX reader did not finish in "
                                        f"{TIMEOUT_BASE + size / 2**20:.0f} s (a hostile or "
                                        "damaged file?)") from None
        said = None
        for line in reversed(proc.stdout.splitlines()):
            if line.startswith('{"error"'):
                said = json.loads(line)
                break
        if said is not None and said["error"] == "import":
            raise OptionalDependencyError(
                f"reading the FBX file {str(p)!r} needs ufbx (the binding by ufbx's author, "
                f"PyPI 'ufbx'), which did not load ({said['message']}): pip install "
                "'stbs-skinning[fbx]'")
        if said is not None:
            msg = said["message"].strip().splitlines()[0] if said["message"].strip() else ""
            if said["error"] == "limit":
                found = f"an animation too long to sample ({msg})"
            elif "not an fbx" in msg.lower():
                found = f"another kind of file (it starts {head[:16]!r})"
            elif head.startswith(b"Kaydara FBX Binary"):
                found = f"a binary FBX file that is truncated or damaged (ufbx: {msg})"
            else:
                found = f"a file ufbx cannot read as FBX ({said['error']}: {msg})"
            raise FormatError(p, _WHAT, found)
        if proc.returncode != 0 or not os.path.exists(dst):
            how = (f"exit status {proc.returncode}" if proc.returncode >= 0
                   else f"killed by signal {-proc.returncode}")
            tail = [x.strip() for x in proc.stderr.splitlines() if x.strip()][-1:]
            raise FormatError(p, _WHAT, f"a file on which the FBX reader failed ({how}"
                              + (f": {tail[0]}" if tail else "") + ")")
        with np.load(dst, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
    return json.loads(str(arrays.pop("meta"))), arrays


# ---------------------------------------------------------------------------- picking
def _skeletons(meta: dict) -> list[list[int]]:
    """Skinned meshes grouped by skeleton: meshes whose bones hang under one top node."""
    nodes = meta["nodes"]

    def top(k: int) -> int:
        while nodes[k]["parent"] >= 0:
            k = nodes[k]["parent"]
        return k

    groups: list[tuple[set[int], list[int]]] = []
    for m, rec in enumerate(meta["meshes"]):
        tops = {top(cl["bone"]) for cl in rec["clusters"] if cl["bone"] >= 0}
        if not tops:
            continue
        hit = [g for g in groups if g[0] & tops]
        merged = (set(tops), [m])
        for g in hit:
            merged[0].update(g[0])
            merged[1].extend(g[1])
            groups.remove(g)
        groups.append(merged)
    return sorted((sorted(g[1]) for g in groups), key=lambda g: g[0])


def _pick_mesh(p: Path, meta: dict, mesh, skinned: list[int], names: list[str]) -> int:
    """The skinned mesh ``mesh`` names (its index among the skinned meshes, or its or
    its node's name)."""
    recs = meta["meshes"]
    if isinstance(mesh, (int, np.integer)) and not isinstance(mesh, bool):
        if not 0 <= mesh < len(skinned):
            raise ValueError(f"mesh={mesh}: {p} has {len(skinned)} skinned meshes "
                             f"(0..{len(skinned) - 1}): {', '.join(map(repr, names))}")
        return skinned[int(mesh)]
    if isinstance(mesh, str):
        node_names = {m: [meta["nodes"][k]["name"] for k in recs[m]["nodes"]]
                      for m in skinned}
        hits = [m for m in skinned if recs[m]["name"] == mesh or mesh in node_names[m]]
        if not hits:
            raise ValueError(f"mesh={mesh!r}: {p} has no skinned mesh of that name; it "
                             f"has {', '.join(map(repr, names))}")
        return hits[0]
    raise TypeError(f"mesh must be an int or a str, got {type(mesh).__name__}")


def _pick_skin(p: Path, meta: dict, skin) -> int:
    """The index of the skin deformer ``skin`` names (its index or name)."""
    if isinstance(skin, (int, np.integer)) and not isinstance(skin, bool):
        if not 0 <= skin < len(meta["skins"]):
            raise ValueError(f"skin={skin}: {p} has {len(meta['skins'])} skin deformers")
        return int(skin)
    if isinstance(skin, str):
        if skin not in meta["skins"]:
            raise ValueError(f"skin={skin!r}: {p} has no skin deformer of that name; it "
                             f"has {', '.join(map(repr, meta['skins']))}")
        return meta["skins"].index(skin)
    raise TypeError(f"skin must be an int or a str, got {type(skin).__name__}")


def _pick(p: Path, meta: dict, skin, mesh) -> list[int]:
    """The meshes to read: those of the skeleton ``skin``/``mesh`` picks (see read_fbx)."""
    recs = meta["meshes"]
    groups = _skeletons(meta)
    if not groups:
        found = (f"{len(recs)} mesh(es), none with a skin deformer whose clusters name "
                 "bones" if recs else "no meshes")
        raise FormatError(p, "a skinned mesh (a mesh with a Skin deformer and clusters)",
                          found)
    skinned = sorted(m for g in groups for m in g)
    names = [recs[m]["name"] for m in skinned]
    chosen = None if mesh is None else _pick_mesh(p, meta, mesh, skinned, names)
    if skin is not None:
        k = _pick_skin(p, meta, skin)
        users = [m for m in skinned if recs[m]["skins"][:1] == [k]]
        if not users:
            raise ValueError(f"skin={skin!r}: that skin deformer deforms no mesh of {p}")
        if chosen is not None and chosen not in users:
            raise ValueError(f"mesh={mesh!r} is not deformed by skin={skin!r}")
        if chosen is None:
            return next(g for g in groups if users[0] in g)
    if chosen is not None:
        return [chosen]
    if len(groups) > 1:
        warnings.warn(f"{p}: {len(groups)} skeletons (" + "; ".join(
            ", ".join(recs[m]["name"] for m in g) for g in groups) + "); reading the first "
            "(pick another with skin= or mesh=)", UserWarning, stacklevel=3)
    return groups[0]


# --------------------------------------------------------------------------- building
def _fans(p: Path, name: str, idx: np.ndarray, faces: np.ndarray, n: int) -> np.ndarray:
    """Triangle fans ``(v0, v_k, v_k+1)`` of the polygons ``faces`` ((f, 2): first corner,
    corner count) over the corner list ``idx``, in face order; points and lines dropped."""
    keep = faces[:, 1] >= 3
    start, count = faces[keep, 0], faces[keep, 1]
    if start.size == 0:
        raise FormatError(p, f"mesh {name!r}: polygons", "points and lines only")
    per = count - 2
    first = np.repeat(start, per)
    k = np.arange(int(per.sum())) - np.repeat(np.cumsum(per) - per, per) + 1
    corner = np.stack([first, first + k, first + k + 1], axis=1)
    if start.min() < 0 or corner.max() >= idx.size:
        raise FormatError(p, f"mesh {name!r}: faces inside its {idx.size} corners",
                          "faces past its end")
    F = idx[corner]
    if F.min() < 0 or F.max() >= n:
        raise FormatError(p, f"mesh {name!r}: vertex indices in 0..{n - 1}",
                          f"{int(F.min())}..{int(F.max())}")
    return F


def _agree(A: np.ndarray, B: np.ndarray, tol: float) -> bool:
    return float(np.abs(A - B).max()) <= tol


def _unique(names: list[str]) -> list[str]:
    """The names, a repeated one as ``name#2``, ``name#3``, ..."""
    taken: set[str] = set()
    out = []
    for s in names:
        t, k = s, 1
        while t in taken:
            k += 1
            t = f"{s}#{k}"
        taken.add(t)
        out.append(t)
    return out


_METHODS = {0: "linear", 1: "rigid", 2: "dual quaternion", 3: "blended dual quaternion"}
_AXES = ("+x", "-x", "+y", "-y", "+z", "-z")


def _hung(meta: dict, col: dict[int, int]) -> list[tuple[int, int, int, int]]:
    """(mesh, instance, node, joint node) of every instance of a mesh without a skin
    deformer whose node is a joint or lies below one (``joint``: the nearest), in mesh
    and instance order."""
    nodes = meta["nodes"]
    out = []
    for m, rec in enumerate(meta["meshes"]):
        if rec["skins"]:
            continue
        for i, node in enumerate(rec["nodes"]):
            k = node
            while k >= 0 and k not in col:
                k = nodes[k]["parent"]
            if k >= 0:
                out.append((m, i, node, k))
    return out


def _joints(meta: dict, picked: list[int]
            ) -> tuple[list[int], dict[int, int], np.ndarray, list[str]]:
    """The joint nodes (the picked meshes' clusters' bones and the chain nodes between
    them, in node order), node -> joint, each joint's parent joint and name."""
    nodes = meta["nodes"]
    recs = meta["meshes"]
    bones = sorted({cl["bone"] for m in picked for cl in recs[m]["clusters"]
                    if cl["bone"] >= 0})
    joint_set = set(bones)
    for b in bones:
        chain, k = [], nodes[b]["parent"]
        while k >= 0 and k not in joint_set:
            chain.append(k)
            k = nodes[k]["parent"]
        if k >= 0:
            joint_set.update(chain)
    joints = sorted(joint_set)
    col = {node: i for i, node in enumerate(joints)}
    parent = np.full(len(joints), -1, dtype=np.int64)
    for i, node in enumerate(joints):
        k = nodes[node]["parent"]
        while k >= 0 and k not in col:
            k = nodes[k]["parent"]
        parent[i] = col.get(k, -1)
    names = _unique([nodes[k]["name"] or f"node{k}" for k in joints])
    return joints, col, parent, names


def _cluster_weights(p: Path, arr: dict, rec: dict, first: int, col: dict[int, int], n: int
                     ) -> tuple[np.ndarray, list, list[float]]:
    """A skinned mesh's (n, joints) weights from its clusters (``first``: the index of
    its first cluster's arrays), checked to weigh every vertex; each cluster's (joint,
    TransformLink, geometry-to-bone) and the weight it carries."""
    W = np.zeros((n, len(col)))
    links, mass = [], []
    for k, cl in enumerate(rec["clusters"]):
        if cl["bone"] < 0:
            continue
        j = first + k
        v, w = arr[f"cl{j}_v"], arr[f"cl{j}_w"]
        if v.size and (v.min() < 0 or v.max() >= n):
            raise FormatError(p, f"cluster {cl['name']!r}: vertex indices in 0..{n - 1}",
                              f"{int(v.min())}..{int(v.max())}")
        if v.size and not np.isfinite(w).all():
            raise FormatError(p, f"cluster {cl['name']!r}: finite weights", "NaN or inf")
        np.add.at(W[:, col[cl["bone"]]], v, w)
        links.append((col[cl["bone"]], arr[f"cl{j}_link"], arr[f"cl{j}_g2b"]))
        mass.append(float(np.abs(w).sum()))
    tot = W.sum(axis=1)
    if np.any(tot <= 0):
        k = int(np.flatnonzero(tot <= 0)[0])
        raise FormatError(p, f"mesh {rec['name']!r}: skin weights on every vertex",
                          f"{int((tot <= 0).sum())} of its {n} vertices without weight "
                          f"(vertex {k} first)")
    return W, links, mass


def _mesh_bind(links: list, mass: list[float]) -> tuple[np.ndarray, float]:
    """The mesh's bind matrix: TransformLink @ geometry_to_bone of each cluster; the one
    that clusters carrying the most weight agree on; and the tolerance of agreeing."""
    Xs = [L @ g for _, L, g in links]
    # files store these in single precision: agreement to 1e-5 of their largest entry
    scale = max(max(float(np.abs(M).max()) for M in Xs),
                max(float(np.abs(L).max()) for _, L, _ in links))
    tol = 1e-5 * max(scale, 1.0)
    score = [sum(w for X2, w in zip(Xs, mass, strict=True) if _agree(X, X2, tol))
             for X in Xs]
    return Xs[int(np.argmax(score))], tol


@dataclass
class _Binds:
    """The joints' bind matrices as the meshes give them: joint -> bind, the mesh that
    gave it, and the joints whose clusters bind a mesh elsewhere than the others do."""

    p: Path
    names: list[str]
    bind: dict = field(default_factory=dict)
    bound_by: dict = field(default_factory=dict)
    moved: list = field(default_factory=list)

    def take(self, mesh: str, X: np.ndarray, links: list, tol: float) -> None:
        """The binds of the joints of ``mesh``, bound at ``X``; a joint bound otherwise
        by an earlier mesh keeps that one, with a warning."""
        for i, L, g in links:
            B = X @ np.linalg.inv(g)          # exact: B^-1 X = geometry_to_bone
            if not _agree(B, L, tol):
                self.moved.append(self.names[i])
            if i not in self.bind:
                self.bind[i] = B
                self.bound_by[i] = mesh
            elif not _agree(self.bind[i], B, tol):
                # stacklevel: as _build's 3, two calls deeper (_skinned_meshes, this)
                warnings.warn(f"{self.p}: joint {self.names[i]!r} is bound differently by "
                              f"the meshes {self.bound_by[i]!r} and {mesh!r}; the rig "
                              f"follows {self.bound_by[i]!r}, so {mesh!r} skins near, not "
                              "exactly as, the file", UserWarning, stacklevel=5)


def _skinned_meshes(p: Path, meta: dict, arr: dict, picked: list[int], col: dict[int, int],
                    binds: _Binds, geo: MeshStack) -> list[dict]:
    """Stack the picked meshes, placed at their bind, into ``geo`` (their binds into
    ``binds``); where each came from."""
    nodes = meta["nodes"]
    recs = meta["meshes"]
    # cluster records with their arrays, per mesh
    base, c = [], 0
    for rec in recs:
        base.append(c)
        c += len(rec["clusters"])
    ranges = []
    for m in picked:
        rec = recs[m]
        V0 = arr[f"mesh{m}_V"]
        n = len(V0)
        F = _fans(p, rec["name"], arr[f"mesh{m}_I"], arr[f"mesh{m}_faces"], n)
        W, links, mass = _cluster_weights(p, arr, rec, base[m], col, n)
        X, tol = _mesh_bind(links, mass)
        binds.take(rec["name"], X, links, tol)
        start = geo.add(V0 @ X[:3, :3].T + X[:3, 3], F, W)
        ranges.append({"name": rec["name"], "node": nodes[rec["nodes"][0]]["name"]
                       if rec["nodes"] else None, "start": start, "stop": start + n,
                       "skinning": _METHODS.get(rec["method"], str(rec["method"]))})
    return ranges


def _rest_binds(meta: dict, arr: dict, joints: list[int], bind: dict) -> np.ndarray:
    """(b, 4, 4) binds: the meshes' where they give one, else (a chain node) the bind
    pose, else the node's rest."""
    pose = {k: arr["pose_world"][i] for i, k in enumerate(meta["pose"])}
    for i, node in enumerate(joints):
        if i not in bind:
            bind[i] = pose.get(node, arr["node_world"][node])
    return np.array([bind[i] for i in range(len(joints))])


def _rigid_parts(p: Path, meta: dict, arr: dict, B: np.ndarray, col: dict[int, int],
                 names: list[str], geo: MeshStack) -> tuple[list[dict], list[tuple[int, int]]]:
    """Stack the meshes hung on a joint without a skin into ``geo``, each weighted 1 on
    its joint; where each came from, and (node, joint) of each.

    Such a mesh is drawn at ``G_j(t) G_j^-1 X`` (``X``: the mesh node's
    geometry-to-world at rest, ``G_j`` the joint's world at rest), so placed at
    ``B_j G_j^-1 X`` it moves exactly with the joint's skinning matrix
    ``G_j(t) B_j^-1``."""
    nodes = meta["nodes"]
    recs = meta["meshes"]
    parts, hung = [], []
    for m, i, node, joint in _hung(meta, col):
        rec = recs[m]
        V0 = arr[f"mesh{m}_V"]
        n = len(V0)
        F = _fans(p, rec["name"], arr[f"mesh{m}_I"], arr[f"mesh{m}_faces"], n)
        X = B[col[joint]] @ np.linalg.inv(arr["node_world"][joint]) @ arr[f"mesh{m}_g2w"][i]
        if np.linalg.det(X[:3, :3]) < 0:    # mirrored: drawn with the winding reversed
            F = F[:, [0, 2, 1]]
        W = np.zeros((n, len(col)))
        W[:, col[joint]] = 1.0
        start = geo.add(V0 @ X[:3, :3].T + X[:3, 3], F, W)
        parts.append({"name": rec["name"], "node": nodes[node]["name"],
                      "joint": names[col[joint]], "start": start, "stop": start + n})
        hung.append((node, col[joint]))
    return parts, hung


def _file_info(p: Path, meta: dict, ranges: list[dict], parts: list[dict],
               names: list[str]) -> dict:
    """``rig.meta["fbx"]``: the file, where each mesh came from, the joints' names and
    what the file says of itself."""
    return {"file": p.name, "meshes": ranges, "rigid": parts, "joints": names,
            "version": meta["version"], "ascii": meta["ascii"], "creator": meta["creator"],
            "unit_meters": meta["unit_meters"],
            "fps": meta["fps"] if np.isfinite(meta["fps"]) else None,
            "axes": dict(zip(("right", "up", "front"),
                             (_AXES[a] if 0 <= a < 6 else "?" for a in meta["axes"]),
                             strict=True)),
            "stacks": [s["name"] for s in meta["stacks"]]}


def _warn_parts_apart(p: Path, meta: dict, arr: dict, s: int, name: str, G: np.ndarray,
                      joints: list[int], names: list[str], hung: list[tuple[int, int]],
                      where: dict[int, int]) -> None:
    """Warn, once per stack, about the rigid parts whose own node (or one between it
    and its joint) moves: they follow their joint only."""
    nodes = meta["nodes"]
    apart = []
    for node, i in hung:
        want = G[:, i] @ (np.linalg.inv(arr["node_world"][joints[i]])
                          @ arr["node_world"][node])
        got = arr[f"stack{s}_G"][:, where[node]]
        if np.abs(got - want).max() > 1e-5 * max(1.0, float(np.abs(want).max())):
            apart.append(f"{nodes[node]['name']!r} (on {names[i]!r})")
    if apart:
        # stacklevel: as _build's 3, two calls deeper (_clips, this)
        warnings.warn(f"{p}: animation stack {name!r} moves the rigid parts "
                      f"{', '.join(dict.fromkeys(apart))} apart from their joints; the "
                      "rig moves them with their joints only", UserWarning, stacklevel=5)


def _clips(p: Path, meta: dict, arr: dict, rig: Rig, joints: list[int], names: list[str],
           B: np.ndarray, hung: list[tuple[int, int]]) -> dict[str, Clip]:
    """One clip per animation stack, named after it (``stack_<s>`` unnamed, a ``#``
    added to a name taken)."""
    clips: dict[str, Clip] = {}
    where = {node: k for k, node in enumerate(meta["evaluated"])}
    Binv = np.linalg.inv(B)
    fps = meta["fps"] if np.isfinite(meta["fps"]) and meta["fps"] > 0 else None
    for s, st in enumerate(meta["stacks"]):
        times = arr[f"stack{s}_times"]
        G = arr[f"stack{s}_G"][:, [where[node] for node in joints]]
        M = G @ Binv[None]
        name = st["name"] or f"stack_{s}"
        while name in clips:
            name += "#"
        clips[name] = clip_from_joint_matrices(
            rig.skeleton, times, M, fps=fps,
            source=f"{p.name}: animation stack {name!r}")
        _warn_parts_apart(p, meta, arr, s, name, G, joints, names, hung, where)
    return clips


def _build(p: Path, meta: dict, arr: dict, skin, mesh, anims: bool, rigid: bool = True
           ) -> tuple[Rig, dict[str, Clip]]:
    """The rig and clips of the scene the child read (``meta``, ``arr``)."""
    picked = _pick(p, meta, skin, mesh)
    joints, col, parent, names = _joints(meta, picked)
    geo = MeshStack()
    binds = _Binds(p, names)
    ranges = _skinned_meshes(p, meta, arr, picked, col, binds, geo)
    if binds.moved:
        warnings.warn(f"{p}: the clusters of {', '.join(map(repr, sorted(set(binds.moved))))} "
                      "bind the mesh elsewhere than the others do; their joints' bind "
                      "matrices are taken so that the rig skins as the file does",
                      UserWarning, stacklevel=3)
    B = _rest_binds(meta, arr, joints, binds.bind)
    parts, hung = (_rigid_parts(p, meta, arr, B, col, names, geo) if rigid and mesh is None
                   else ([], []))
    info = _file_info(p, meta, ranges, parts, names)
    rig = rig_from_joints(np.vstack(geo.Vs), np.vstack(geo.Fs), np.vstack(geo.Ws), B, parent,
                          names, meta={"fbx": info})
    if not anims:
        return rig, {}
    return rig, _clips(p, meta, arr, rig, joints, names, B, hung)


def _read(path, *, skin=None, mesh=None, rigid: bool = True, anims: bool = True
          ) -> tuple[Rig, dict[str, Clip]]:
    """:func:`read_fbx`; ``anims=False`` leaves the stacks out (for :func:`read_rig`)."""
    if not isinstance(rigid, (bool, np.bool_)):
        raise TypeError(f"rigid must be True or False, got {rigid!r}")
    p = input_path(path, "FBX")
    suffix(p, FBX_EXTENSIONS, "read_fbx")
    meta, arr = _run_child(p, anims)
    try:
        return _build(p, meta, arr, skin, mesh, anims, bool(rigid))
    except FormatError:
        raise
    except ValueError as exc:
        if str(p) in str(exc):
            raise                       # already names the file (e.g. a skin= it lacks)
        raise FormatError(p, "an FBX scene of finite transforms that make a skeleton",
                          str(exc)) from None


def read_fbx(path: str | os.PathLike, *, skin: int | str | None = None,
             mesh: int | str | None = None, rigid: bool = True
             ) -> tuple[Rig, dict[str, Clip]]:
    """Read a skinned character and its animation stacks from an FBX file.

    Binary and ASCII FBX, through ufbx (the ``fbx`` extra). The file is never modified.
    See the module docs for how joints, bind matrices and clips are made.

    Parameters
    ----------
    path : str or os.PathLike
        A ``.fbx`` file.
    skin : int or str, optional
        A skin deformer (index in the file's order, or name): its skeleton is read,
        with every mesh bound to it.
    mesh : int or str, optional
        One skinned mesh (index among the skinned meshes, or the name of the mesh or
        of its node): only that mesh is read, without the rigid parts. Default
        (neither): every mesh bound to the file's skeleton; with several skeletons, the
        first (with a warning).
    rigid : bool, default True
        Read the meshes without a skin attached to the skeleton's bones too (see the
        module docs), each moving with its nearest joint; False: the skinned meshes
        only.

    Returns
    -------
    rig : Rig
        3D; ``V`` (n, 3) and ``F`` (f, 3) of the meshes in the world bind pose, in the
        file's coordinates and units (the skinned meshes, then the rigid parts); one
        bone per joint, named as its node; ``W`` (n, j) (a rigid part's rows: 1 on its
        joint's bone); ``E`` None. ``rig.meta["fbx"]`` holds the file name, each skinned
        mesh's vertex range (``meshes``: name, node, start, stop, skinning method), each
        rigid part's (``rigid``: name, node, joint, start, stop), the joint names, the
        file's FBX version, creator, ``unit_meters``, axes and frame rate.
    clips : dict of str to Clip
        One per animation stack, by name, in file order; keyed at every frame of the
        file's frame rate over the stack's time span.

    Raises
    ------
    FileNotFoundError
        No such file.
    FormatError
        Not an FBX file, a truncated one, no skinned mesh, a vertex without weight;
        the message names the file and what was wrong.
    OptionalDependencyError
        ufbx is not installed.
    """
    return _read(path, skin=skin, mesh=mesh, rigid=rigid)
