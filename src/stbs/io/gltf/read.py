"""glTF 2.0 characters in: :func:`read_gltf` -> (:class:`stbs.Rig`, clips).

How a glTF character becomes a rig
----------------------------------
- **Which meshes.** Every node with a mesh and a skin whose joints belong to one
  skeleton (skins sharing joints, or one's joints below another's, are one skeleton):
  several meshes sharing a skin, and several skins over one joint hierarchy, are read
  together. ``skin=`` picks another skeleton when a file holds several (the first is
  read by default, with a warning listing the rest); ``mesh=`` reads one mesh alone.
- ``V`` is the POSITION data of those meshes' primitives, concatenated in node and
  primitive order (with the mesh's default morph weights applied, if any), ``F`` their
  triangles (strips and fans become triangles; points and lines are skipped with a
  warning). The mesh node's own transform is ignored, as the specification says for
  skinned meshes. ``rig.meta["gltf"]["primitives"]`` records where each primitive's
  vertices came from, so writing the rig back adds endpoint weights to each of them.
- **Rigid parts.** A node with a mesh and no skin that is a joint of the skeleton or
  lies below one (a robot's limbs hung on its bones) moves with its nearest such joint
  ``j``: the file draws it at ``G_j L``, ``L`` the rest transforms of the nodes from
  below ``j`` down to it. Its primitives follow the skinned ones in ``V`` (node order),
  placed at ``B_j L`` (``B_j`` the joint's bind, the inverse of its inverse bind
  matrix, as the skinned meshes are), so the joint's skin matrix ``G_j IBM_j`` moves
  them exactly as the file does; their rows of ``W`` are 1 on bone ``j``; a mirroring
  transform reverses their triangles' winding, as viewers do when drawing them.
  ``rig.meta["gltf"]["rigid"]`` records each one (node, mesh, primitive, joint,
  ``start``, ``count``). An animation that moves a node of ``L`` is warned about when
  its clip is decoded (the part then follows its joint only). Meshes under no joint
  (props, scenery) are not read; ``rigid=False`` leaves the rigid parts out, and so
  does ``mesh=``.
- **Bones.** One bone per joint node of those skins (their union, in the order the
  skins list them), named after the node (``node<k>`` for an unnamed one or a name
  shared by several joints), starting at the joint's *bind* position (from the inverse
  bind matrices, not from the node transforms); its parent bone is the nearest joint
  above it. Where each bone ends is :func:`stbs.rig.rig_from_joints`'s: at the child
  that continues it, a leaf's tail kept inside the mesh. A file written by stbs
  brings its own bone table back (:mod:`stbs.io.gltf.bones`).
- ``W`` has one column per bone, from every ``JOINTS_n``/``WEIGHTS_n`` set, each row
  divided by its sum (the renormalisation engines apply to quantised weights); ``E``
  from ``_ENDPOINT_WEIGHTS_n`` (as stbs writes them), else None; a rigid part, which
  the write-back leaves as it was, gets eq. 8's projection onto its bone. When several
  skins bind the same joint differently, a vertex is moved to where the first skin's
  bind puts it (its rest pose in the file), so one bind serves all.
- **Clips.** One per animation, decoded only when asked for (the mapping returned is
  lazy): see :mod:`stbs.io.gltf.animation` for how ``clip.pose(t)`` equals the file's
  node hierarchy at any time.
"""

from __future__ import annotations

import contextlib
import os
import warnings
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field

import numpy as np

from ...clip import Clip
from ...rig.joints import rig_from_joints
from ...rig.model import Rig
from .._parse import suffix
from .._stack import MeshStack
from .accessors import (
    FLOAT_ONLY,
    JOINT_INDICES,
    QUANTIZED,
    UNIT,
    VERTEX_INDICES,
    read_accessor,
)
from .animation import Joints, animation_names, decode_clip
from .bones import read_bone_table
from .container import GltfFile
from .scene import Scene

__all__ = ["read_gltf", "GLTF_EXTENSIONS", "GltfAnimations", "primitive_weights"]

GLTF_EXTENSIONS = (".gltf", ".glb")
#: Vertex and joint positions (after the file's transforms) may be this large at most.
MAX_COORDINATE = 1e12
# Extensions without which the geometry cannot be read.
_UNSUPPORTED = ("KHR_draco_mesh_compression", "EXT_meshopt_compression")


@contextlib.contextmanager
def _numeric(f: GltfFile, what: str) -> Iterator[None]:
    """Linear algebra that fails on what a file holds (an SVD that does not converge,
    a singular matrix) as a FormatError naming the file, not NumPy's bare message."""
    try:
        yield
    except np.linalg.LinAlgError as exc:
        raise f.error(f"{what}: transforms that linear algebra can work with",
                      f"{' '.join(str(exc).split())} (values too large or degenerate)") from None


class GltfAnimations(Mapping):
    """The animations of a glTF file as clips, by name, decoded on first access.

    A :class:`collections.abc.Mapping` of ``str`` to :class:`stbs.Clip`; iterating or
    ``len`` reads only the names. A decoded clip is kept.
    """

    def __init__(self, f: GltfFile, scene: Scene, joints: Joints):
        self._f, self._scene, self._joints = f, scene, joints
        self._names = animation_names(f)
        self._clips: dict[str, Clip] = {}

    def __getitem__(self, name: str) -> Clip:
        if name not in self._clips:
            try:
                a = self._names.index(name)
            except ValueError:
                raise KeyError(name) from None
            with _numeric(self._f, f"animation {a} ({name!r})"):
                self._clips[name] = decode_clip(self._f, self._scene, self._joints, a, name)
        return self._clips[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._names)

    def __len__(self) -> int:
        return len(self._names)

    def __repr__(self) -> str:
        return f"GltfAnimations({self._f.path.name!r}: {', '.join(map(repr, self._names))})"


# ---------------------------------------------------------------------- which meshes
def _label(scene: Scene, k: int, mesh: int, skin: int) -> str:
    return f"node {k} ({scene.names[k]!r}: mesh {mesh}, skin {skin})"


def _skeletons(scene: Scene, skins: list[int]) -> dict[int, int]:
    """Skin -> the first skin of its skeleton: skins sharing joints, or with joints
    below another's, are one skeleton."""
    joints = {s: scene.skin_joints(s) for s in skins}
    at: dict[int, list[int]] = {}
    for s in skins:
        for j in joints[s]:
            at.setdefault(j, []).append(s)
    # cover[k]: the skins with a joint at node k or above it (one pass down the tree)
    cover: list[frozenset] = [frozenset()] * scene.n
    for k in scene.order:
        p = int(scene.parent[k])
        base = cover[p] if p >= 0 else frozenset()
        cover[k] = base | frozenset(at[k]) if k in at else base
    root = {s: s for s in skins}

    def find(s):
        while root[s] != s:
            s = root[s]
        return s

    # a skin with a joint at or above another's joint is of the same skeleton
    for s in skins:
        for j in joints[s]:
            for x in cover[j]:
                a, b = find(x), find(s)
                if a != b:
                    root[max(a, b)] = min(a, b)
    return {s: find(s) for s in skins}


def _select(f: GltfFile, scene: Scene, skin, mesh) -> list[tuple[int, int, int]]:
    """The (node, mesh, skin) triples to read (see the module docs)."""
    if not f.items("skins"):
        raise f.error("a skin (a skinned mesh with joints)", "no skins")
    skinned = scene.skinned_nodes()
    if not skinned:
        raise f.error("a node with both a mesh and a skin", "none")
    meshes, skins = f.items("meshes"), f.items("skins")

    def named(x, i):
        return x[i].get("name") if isinstance(x[i], dict) else None

    group = _skeletons(scene, sorted({c[2] for c in skinned}))
    cands = skinned
    if mesh is not None:           # that mesh alone
        cands = [c for c in cands if mesh in (c[0], scene.names[c[0]], c[1], named(meshes, c[1]))]
    if skin is not None:           # the skeleton of that skin, every mesh bound to it
        picked = {group[c[2]] for c in skinned if skin in (c[2], named(skins, c[2]))}
        cands = [c for c in cands if group[c[2]] in picked]
    if not cands:
        raise ValueError(f"{str(f.path)!r}: no skinned mesh matches mesh={mesh!r}, "
                         f"skin={skin!r}; there are "
                         f"{'; '.join(_label(scene, *c) for c in skinned)}")
    first = group[cands[0][2]]
    chosen = [c for c in cands if group[c[2]] == first]
    others = [c for c in cands if group[c[2]] != first]
    if others:
        warnings.warn(f"{str(f.path)!r} has skinned meshes on {len({group[c[2]] for c in cands})}"
                      f" skeletons; reading the one of {_label(scene, *chosen[0])} (pick "
                      f"another with skin= or mesh=; the others: "
                      f"{'; '.join(_label(scene, *c) for c in others[:6])})",
                      UserWarning, stacklevel=4)
    return chosen


# ---------------------------------------------------------------------- geometry
def _positions(f: GltfFile) -> frozenset:
    """What POSITION (and a morph target's offsets) may hold: floats, and with the
    extension KHR_mesh_quantization the byte and short types too."""
    used = (f.get(f.doc, "extensionsUsed", "array", "glTF", [])
            + f.get(f.doc, "extensionsRequired", "array", "glTF", []))
    return QUANTIZED if "KHR_mesh_quantization" in used else FLOAT_ONLY


def _triangles(f: GltfFile, prim: dict, what: str, n: int) -> np.ndarray | None:
    mode = f.get(prim, "mode", "index", what, 4)
    i = f.get(prim, "indices", "index", what, None)
    idx = (np.arange(n) if i is None else
           read_accessor(f, i, f"{what} indices", floats=False, types=("SCALAR",),
                         components=VERTEX_INDICES)[:, 0])
    if idx.size and (idx.min() < 0 or idx.max() >= n):
        raise f.error(f"{what} indices below its {n} vertices", str(int(idx.max())))
    if mode == 4:
        if idx.size % 3:
            raise f.error(f"{what}: a multiple of 3 indices (triangles)", str(idx.size))
        return idx.reshape(-1, 3).astype(np.int64)
    if mode == 5:       # strip: alternate the winding
        m = np.arange(max(idx.size - 2, 0))
        return np.column_stack([idx[m], idx[m + 1 + m % 2], idx[m + 2 - m % 2]])
    if mode == 6:       # fan
        m = np.arange(1, max(idx.size - 1, 1))
        return np.column_stack([np.full(m.size, idx[0]), idx[m], idx[m + 1]])
    return None


def _morphed(f: GltfFile, prim: dict, node: dict, mesh: dict, V: np.ndarray, what: str):
    """POSITION with the default morph weights (the node's, else the mesh's) applied."""
    targets = f.get(prim, "targets", "array", what, [])
    src = node if "weights" in node else mesh
    if not targets or "weights" not in src:
        return V
    w = f.numbers(src, "weights", len(targets), f"{what}'s default morph", ())
    if not any(w):
        return V
    V = V.copy()
    with np.errstate(over="ignore", invalid="ignore"):
        for t, (tgt, wt) in enumerate(zip(targets, w, strict=True)):
            if wt and isinstance(tgt, dict) and "POSITION" in tgt:
                d = read_accessor(f, tgt["POSITION"], f"{what} target {t} POSITION",
                                  types=("VEC3",), components=_positions(f))
                if d.shape != V.shape:
                    raise f.error(f"{what} target {t}: {len(V)} POSITION offsets",
                                  str(len(d)))
                V += wt * d
    if not np.isfinite(V).all():
        raise f.error(f"{what}: morph target offsets times their default weights that "
                      "are finite", "an overflow (weights or offsets too large)")
    return V


def _weight_sets(f: GltfFile, at: dict, n: int, nj: int, what: str):
    """[(J, W, E or None)] of every JOINTS_n/WEIGHTS_n set of a primitive."""
    sets = []
    while True:
        k = len(sets)
        ja, wa = at.get(f"JOINTS_{k}"), at.get(f"WEIGHTS_{k}")
        if ja is None and wa is None:
            break
        if ja is None or wa is None:
            raise f.error(f"{what}: JOINTS_{k} and WEIGHTS_{k} together", "only one of them")
        J = read_accessor(f, ja, f"{what} JOINTS_{k}", floats=False, types=("VEC4",),
                          components=JOINT_INDICES)
        W = read_accessor(f, wa, f"{what} WEIGHTS_{k}", types=("VEC4",), components=UNIT)
        if len(J) != n or len(W) != n:
            raise f.error(f"{what}: JOINTS_{k}/WEIGHTS_{k} of {n} vertices",
                          f"{len(J)} and {len(W)}")
        if (W < 0).any():
            raise f.error(f"{what} WEIGHTS_{k}: weights >= 0", f"{W.min():.6g}")
        used = W > 0
        if used.any() and J[used].max() >= nj:
            raise f.error(f"{what} JOINTS_{k}: joints of its skin, in 0..{nj - 1}",
                          str(int(J[used].max())))
        E = None
        ea = at.get(f"_ENDPOINT_WEIGHTS_{k}")
        if ea is not None:
            E = read_accessor(f, ea, f"{what} _ENDPOINT_WEIGHTS_{k}", types=("VEC4",),
                              components=UNIT)
            if len(E) != n or E.min(initial=0) < 0 or E.max(initial=0) > 1:
                raise f.error(f"{what} _ENDPOINT_WEIGHTS_{k}: {n} values in [0, 1]",
                              f"{len(E)}, in [{E.min():.3g}, {E.max():.3g}]")
        sets.append((J, W, E))
    if not sets:
        raise f.error(f"{what}: JOINTS_0 and WEIGHTS_0 (a skinned primitive)", "none")
    return sets


def primitive_weights(f: GltfFile, at: dict, n: int, to_bone: np.ndarray, b: int,
                      what: str) -> tuple[np.ndarray, np.ndarray | None]:
    """(n, b) weights and endpoint weights (or None) of a skinned primitive's vertices
    over the rig's bones; ``to_bone`` maps its skin's joints to bones. Rows as in the
    file (not normalised); every vertex has some weight."""
    sets = _weight_sets(f, at, n, len(to_bone), what)
    f.reserve(n * b * 8 * (2 + (sets[0][2] is not None)),
              f"{what}: weights of {n} vertices over {b} joints")
    W = np.zeros((n, b))
    E = np.zeros((n, b)) if sets[0][2] is not None else None
    rows = np.repeat(np.arange(n), 4)
    for J, Wk, Ek in sets:
        use = (Wk > 0).ravel()
        cols = to_bone[np.where(Wk > 0, J, 0)].ravel()
        np.add.at(W, (rows[use], cols[use]), Wk.ravel()[use])
        if E is not None and Ek is not None:
            E[rows[use], cols[use]] = Ek.ravel()[use]
        elif (E is None) != (Ek is None):
            raise f.error(f"{what}: _ENDPOINT_WEIGHTS_n beside every JOINTS_n or none",
                          "beside some")
    tot = W.sum(axis=1)
    if (tot <= 0).any():
        v = int(np.flatnonzero(tot <= 0)[0])
        raise f.error(f"{what}: every vertex with a positive weight",
                      f"{int((tot <= 0).sum())} vertices with none (e.g. vertex {v})")
    return W, E


def _names(scene: Scene, nodes: list[int]) -> list[str]:
    raw = [scene.names[k] for k in nodes]
    count: dict[str | None, int] = {}
    for r in raw:
        count[r] = count.get(r, 0) + 1
    out = [r if r and count[r] == 1 else f"node{k}" for r, k in zip(raw, nodes, strict=True)]
    seen: set[str] = set()
    for i, nm in enumerate(out):
        while nm in seen:            # a node really called "node7" next to an unnamed 7
            nm = f"{nm}_"
        seen.add(nm)
        out[i] = nm
    return out


def _primitives(f: GltfFile, node: int, m: int):
    """(index, label, attributes, V, F) of each triangle primitive of mesh ``m`` drawn by
    ``node``: POSITION with the default morph weights applied, and the triangles; points
    and lines are skipped with a warning."""
    mobj = f.item("meshes", m, f"node {node} mesh")
    nobj = f.items("nodes")[node]
    for k, prim in enumerate(f.get(mobj, "primitives", "array", f"meshes[{m}]")):
        what = f"mesh {m} primitive {k}"
        if not isinstance(prim, dict):
            raise f.error(f"{what}: a JSON object", repr(prim)[:40])
        at = f.get(prim, "attributes", "object", what)
        if "POSITION" not in at:
            raise f.error(f"{what}: a POSITION attribute", "none")
        V = read_accessor(f, at["POSITION"], f"{what} POSITION", types=("VEC3",),
                          components=_positions(f))
        F = _triangles(f, prim, what, len(V))
        if F is None:
            # stacklevel: this generator, _read_skinned or _read_rigid, _read, read_gltf,
            # its caller
            warnings.warn(f"{str(f.path)!r}: {what} is points or lines (mode "
                          f"{prim.get('mode')}); skipped", UserWarning, stacklevel=5)
            continue
        yield k, what, at, _morphed(f, prim, nobj, f.items("meshes")[m], V, what), F


def _placed(V: np.ndarray, F: np.ndarray, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Vertices mapped by the 4x4 ``X``, and the triangles' winding kept facing out: a
    mirroring ``X`` (negative determinant) reverses it, as viewers do when drawing."""
    V = V @ X[:3, :3].T + X[:3, 3]
    if np.linalg.det(X[:3, :3]) < 0:
        F = F[:, [0, 2, 1]]
    return V, F


def _check_extensions(f: GltfFile) -> None:
    """Refuse a file that requires a mesh compression extension stbs cannot decode."""
    req = f.get(f.doc, "extensionsRequired", "array", "glTF", [])
    bad = [e for e in req if e in _UNSUPPORTED]
    if bad:
        raise f.error("geometry stbs can decode (no mesh compression extension required)",
                      f"extensionsRequired {bad[0]!r}")


def _joint_nodes(scene: Scene, skins: list[int]
                 ) -> tuple[list[int], np.ndarray, dict[int, int]]:
    """The joint nodes of ``skins`` (their union, in the order the skins list them), the
    inverse bind matrix of each (from the first skin listing it), and node -> bone."""
    nodes: list[int] = []
    ibm: list[np.ndarray] = []
    col: dict[int, int] = {}
    for s in skins:
        M = scene.inverse_binds(s)
        for j, node in enumerate(scene.skin_joints(s)):
            if node not in col:
                col[node] = len(nodes)
                nodes.append(node)
                ibm.append(M[j])
    return nodes, np.array(ibm), col


def _binds(f: GltfFile, IBM: np.ndarray) -> np.ndarray:
    """The binds ``B_j = IBM_j^-1`` of the joints."""
    try:
        bind = np.linalg.inv(IBM)
    except np.linalg.LinAlgError:
        raise f.error("invertible inverse bind matrices", "a singular one") from None
    if not np.isfinite(bind).all():
        raise f.error("invertible inverse bind matrices", "a singular one")
    return bind


def _joint_parents(scene: Scene, nodes: list[int], col: dict[int, int]) -> np.ndarray:
    """The parent bone of each bone: the nearest joint above its node (-1: none)."""
    parent = np.full(len(nodes), -1, dtype=np.int64)
    up = scene.nearest_above(col)
    for i, node in enumerate(nodes):
        if up[node] >= 0:
            parent[i] = col[int(up[node])]
    return parent


@dataclass
class _Geometry(MeshStack):
    """The primitives read so far, in the order they are stacked into the rig's ``V``,
    ``F`` (indices into the stack) and ``W``; ``Es`` the endpoint weights (or None) of
    the skinned ones; ``prims`` and ``parts`` where each skinned primitive and each
    rigid part came from."""

    Es: list = field(default_factory=list)
    prims: list = field(default_factory=list)
    parts: list = field(default_factory=list)


def _rebound(V: np.ndarray, W: np.ndarray, to_bone: np.ndarray, X: np.ndarray) -> np.ndarray:
    """The file's rest pose of each vertex under the first skin's binds: ``V`` moved by
    its weights' blend of ``X_j = B_j IBM_s,j`` (its own skin's bind to the first's)."""
    tot = W.sum(axis=1)
    w = (W / tot[:, None])[:, to_bone]
    Xv = np.einsum("nj,jab->nab", w, X)
    return np.einsum("nab,nb->na", Xv[:, :3, :3], V) + Xv[:, :3, 3]


def _read_skinned(f: GltfFile, scene: Scene, chosen: list[tuple[int, int, int]],
                  col: dict[int, int], bind: np.ndarray, geo: _Geometry) -> None:
    """Stack the triangle primitives of the skinned meshes ``chosen`` into ``geo``, with
    their weights over the bones."""
    b = len(col)
    for node, m, s in chosen:
        to_bone = np.array([col[j] for j in scene.skin_joints(s)])
        # where this skin's bind differs from the first's: X_j = B_j IBM_s,j
        X = bind[to_bone] @ scene.inverse_binds(s)
        moved = not np.allclose(X, np.eye(4), atol=1e-9 * max(1.0, np.abs(X).max()))
        for k, what, at, V, F in _primitives(f, node, m):
            n = len(V)
            W, E = primitive_weights(f, at, n, to_bone, b, what)
            if moved:
                V = _rebound(V, W, to_bone, X)
            start = geo.add(V, F, W)
            geo.Es.append(E)
            geo.prims.append({"node": int(node), "mesh": int(m), "primitive": k,
                              "skin": int(s), "start": start, "count": n})


def _endpoint_rows(f: GltfFile, Es: list) -> np.ndarray | None:
    """The skinned primitives' endpoint weights stacked, or None where none has them."""
    if not any(e is not None for e in Es):
        return None
    if any(e is None for e in Es):
        raise f.error("_ENDPOINT_WEIGHTS_0 on every primitive or on none", "on some only")
    return np.vstack(Es)


def _read_rigid(f: GltfFile, scene: Scene, col: dict[int, int], bind: np.ndarray,
                endpoints: bool, geo: _Geometry) -> dict[int, tuple[int, int]]:
    """Stack the meshes hung rigidly on a joint into ``geo``, each weighted 1 on its
    joint's bone; the nodes they hang from below their joints -> (mesh node, bone).

    Such a mesh is drawn at ``N_node = G_j L`` (``L``: the nodes from below joint ``j``
    down to the mesh node), so placing it at ``B_j L`` (``B_j = IBM_j^-1``, the bind the
    skinned meshes use) makes the skin matrix ``G_j IBM_j`` draw it at ``G_j L`` at any
    time, exactly."""
    b = len(col)
    carried: dict[int, tuple[int, int]] = {}
    for node, m, joint, L in scene.attached(set(col)):
        X = bind[col[joint]] @ L
        x = node                 # the nodes from the mesh's up to (not) its joint's
        while x != joint and x not in carried:
            carried[x] = (node, col[joint])
            x = int(scene.parent[x])
        for k, what, _, V, F in _primitives(f, node, m):
            n = len(V)
            V, F = _placed(V, F, X)
            f.reserve(n * b * 8 * (2 + endpoints),
                      f"{what}: weights of {n} vertices over {b} joints")
            W = np.zeros((n, b))
            W[:, col[joint]] = 1.0
            start = geo.add(V, F, W)
            geo.parts.append({"node": int(node), "mesh": int(m), "primitive": k,
                              "joint": int(joint), "start": start, "count": n})
    return carried


def _in_drawn_space(f: GltfFile, scene: Scene, nodes: list[int], IBM: np.ndarray,
                    bind: np.ndarray, parent: np.ndarray, V: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``V``, ``IBM`` and the binds moved into the space the file draws its rest pose
    in, where the skin matrices at rest are all one similarity (else unchanged)."""
    # Skin matrices G_j IBM_j that all scale by one factor c at rest (inverse binds
    # made in a mesh's own units, under an "armature" node scaled by c) cannot pose
    # rigid bones: the rig is then moved by Y, the root's skin matrix at rest (a
    # similarity of scale c), into the space the file draws it in; the file's skin is
    # unchanged: G_j IBM_j v = (G_j IBM_j Y^-1)(Y v).
    with np.errstate(over="ignore", invalid="ignore"):
        M0 = scene.finite_world(nodes) @ IBM
    if not np.isfinite(M0).all():
        raise f.error("skin matrices at rest (joint transforms times inverse bind matrices) "
                      "that are finite", "an overflow (transforms too large)")
    sv = np.linalg.svd(M0[:, :3, :3], compute_uv=False)
    # (a joint scaled to nothing at rest, which a file may hold, scales by no one factor)
    c = float(np.exp(np.log(sv).mean())) if sv.min() > 0 else 0.0
    uniform = c > 0 and np.abs(sv / max(c, 1e-300) - 1).max() <= 1e-4
    # The same holds when every joint's skin matrix at rest is one and the same rigid
    # motion (a bind made in Z-up space under a node turning it Y-up): the rig is put
    # where the file draws its rest pose, so a rest pose is upright as the file shows it.
    Y = M0[int(np.flatnonzero(parent < 0)[0])]
    rel = np.abs(M0 - Y).max() / max(float(np.abs(Y[:3, 3]).max()), 1.0)
    same = rel <= 1e-5 and uniform
    if (abs(c - 1) > 1e-4 and uniform) or (same and np.abs(Y - np.eye(4)).max() > 1e-6):
        V = V @ Y[:3, :3].T + Y[:3, 3]
        IBM = IBM @ np.linalg.inv(Y)
        bind = Y @ bind
    return V, IBM, bind


def _check_magnitude(f: GltfFile, V: np.ndarray, bind: np.ndarray) -> None:
    """Refuse vertex or joint positions beyond :data:`MAX_COORDINATE`."""
    # far beyond any real model (a planet in millimetres), and small enough that the
    # skeleton's geometry (squared distances, cross products) cannot overflow
    big = max(float(np.abs(V).max(initial=0)), float(np.abs(bind[:, :3, 3]).max()))
    if not big <= MAX_COORDINATE:
        raise f.error(f"vertex and joint positions of magnitude at most {MAX_COORDINATE:g}",
                      f"{big:g} (transforms too large)")


def _make_rig(f: GltfFile, scene: Scene, skins: list[int], nodes: list[int],
              bind: np.ndarray, parent: np.ndarray, V: np.ndarray, F: np.ndarray,
              W: np.ndarray, meta: dict) -> Rig:
    """The rig: the file's own bone table where stbs wrote one, else bones from the
    joints' bind positions (:func:`stbs.rig.rig_from_joints`)."""
    names = _names(scene, nodes)
    A = bind[:, :3, 3]
    size = float(np.linalg.norm(np.ptp(np.vstack([V, A]), axis=0))) or 1.0
    sk = read_bone_table(f, skins, nodes, A, parent, size)
    try:
        if sk is None:
            return rig_from_joints(V, F, W, bind, parent, names, meta=meta)
        return Rig(V=V, F=F, W=W / W.sum(axis=1, keepdims=True), skeleton=sk, meta=meta)
    except ValueError as exc:
        raise f.error("joints whose bind positions make a skeleton", str(exc)) from None


def _with_rigid_endpoints(E: np.ndarray, W: np.ndarray, rig: Rig) -> np.ndarray:
    """``E`` of the skinned rows, with the rigid parts' rows after them: eq. 8's
    projection onto their bone (a rigid part keeps no endpoint weights in the file; it
    is written back as it was)."""
    # stbs.weights imported only here: it is heavy, and reading a rig needs it only in
    # this case
    from ...weights.endpoint import projection

    rows = np.arange(len(E), len(rig.V))
    E = np.vstack([E, np.zeros((len(rows), W.shape[1]))])
    cols = np.argmax(W[rows], axis=1)
    E[rows, cols] = projection(rig.V[rows], rig.skeleton)[np.arange(len(rows)), cols]
    return E


def _read(f: GltfFile, skin, mesh, rigid: bool = True) -> tuple[Rig, Scene, Joints]:
    """The rig of the skeleton ``skin``/``mesh`` pick (see the module docs), the file's
    scene, and the joints its clips are decoded for."""
    _check_extensions(f)
    scene = Scene(f)
    chosen = _select(f, scene, skin, mesh)
    skins = list(dict.fromkeys(s for _, _, s in chosen))
    nodes, IBM, col = _joint_nodes(scene, skins)
    bind = _binds(f, IBM)
    parent = _joint_parents(scene, nodes, col)
    geo = _Geometry()
    _read_skinned(f, scene, chosen, col, bind, geo)
    E = _endpoint_rows(f, geo.Es)
    carried = (_read_rigid(f, scene, col, bind, E is not None, geo)
               if rigid and mesh is None else {})
    if not geo.Vs:
        raise f.error("a skinned mesh with triangles", "points and lines only")
    V, F, W = np.vstack(geo.Vs), np.vstack(geo.Fs), np.vstack(geo.Ws)
    V, IBM, bind = _in_drawn_space(f, scene, nodes, IBM, bind, parent, V)
    _check_magnitude(f, V, bind)
    meta = {"gltf": {"file": f.path.name, "skins": [int(s) for s in skins],
                     "joints": [int(j) for j in nodes], "primitives": geo.prims,
                     "rigid": geo.parts, "select": {"skin": skin, "mesh": mesh,
                                                    "rigid": rigid}}}
    rig = _make_rig(f, scene, skins, nodes, bind, parent, V, F, W, meta)
    if E is not None:
        rig = rig.replace(E=_with_rigid_endpoints(E, W, rig) if geo.parts else E)
    return rig, scene, Joints(nodes=nodes, ibm=IBM, skeleton=rig.skeleton, carried=carried)


def read_gltf(path: str | os.PathLike, *, skin: int | str | None = None,
              mesh: int | str | None = None, rigid: bool = True
              ) -> tuple[Rig, Mapping[str, Clip]]:
    """Read a skinned character and its animations from a glTF 2.0 file.

    Parameters
    ----------
    path : str or os.PathLike
        ``.gltf`` (buffers in files beside it or in ``data:`` URIs) or ``.glb``.
    skin : int or str, optional
        Read the skeleton of this skin (index or name), with every skinned mesh bound to
        it. Default: the first skinned mesh's skeleton (with a warning listing the
        others when the file holds several).
    mesh : int or str, optional
        Read this skinned mesh alone (node index or name, or mesh index or name), without
        the rigid parts.
    rigid : bool, default True
        Read the meshes hung rigidly on the skeleton's joints too (nodes with a mesh and
        no skin below a joint: a robot's limbs, a helmet on a head), each moving with
        its nearest joint; False reads the skinned meshes only.

    Returns
    -------
    rig : Rig
        3D; ``V``, ``F``, the skeleton (one bone per joint, see the module docs), ``W``
        (a rigid part's rows: 1 on its joint's bone); ``E`` from ``_ENDPOINT_WEIGHTS_n``
        where the file has them (a rigid part's: eq. 8's projection), else None.
        ``rig.meta["gltf"]`` records the file, the skins, the joint node of each bone and
        where each primitive's vertices came from (``primitives``: the skinned ones,
        then ``rigid``: the rigid parts, each with its ``joint`` node).
    clips : Mapping of str to Clip
        One per animation, by name (``"animation_K"`` when unnamed), in file order,
        decoded on first access (:class:`GltfAnimations`).

    Raises
    ------
    FileNotFoundError
        No such file.
    FormatError
        A file that is not glTF 2.0, damaged or hostile (see
        :mod:`stbs.io.gltf.container`), no skinned mesh, a skin whose joints are not a
        tree, an accessor out of range, weights that leave a vertex with none; the
        message names the file, what was expected and what was found.
    ValueError
        ``skin=`` or ``mesh=`` matching no skinned mesh (the message lists them).
    """
    if not isinstance(rigid, (bool, np.bool_)):
        raise TypeError(f"rigid must be True or False, got {rigid!r}")
    suffix(path, GLTF_EXTENSIONS, "read_gltf")
    f = GltfFile(path)
    with _numeric(f, "the skeleton and meshes"):
        rig, scene, joints = _read(f, skin, mesh, bool(rigid))
    return rig, GltfAnimations(f, scene, joints)
