"""glTF 2.0 skins in: :func:`read_gltf` -> (:class:`stbs.Rig`, clips).

The container (JSON, GLB chunks) is parsed by pygltflib (the ``gltf`` extra); buffers,
accessors, node hierarchies, skins and animation samplers are evaluated here, because no
Python library evaluates skins.

How a glTF skin becomes a rig
-----------------------------
- ``V`` is the mesh's POSITION data in the file's vertex order, its primitives
  concatenated in order (``F`` likewise, offset); triangle strips and fans become
  triangles. The mesh node's own transform is ignored, as the specification says for
  skinned meshes.
- Each joint of the skin gives one bone, named after the joint's node, starting at the
  joint's *bind* position (from the inverse bind matrices, not from the node
  transforms). It ends at one of the joint's children in the skin: the only one, or
  with several the one that continues the direction from the joint's parent best (for a
  root joint: the first, in the file's order); children at the joint's own position are
  passed over. A leaf joint's bone ends half its parent bone's length further along the
  parent's direction (a root leaf: along its bind frame's +y, a tenth of the mesh's
  size). The other children start bones of their own.
- ``W`` has one column per joint, from every ``JOINTS_n``/``WEIGHTS_n`` set (unsigned
  byte or short joints; float, or normalised byte or short weights), each row divided
  by its sum (the renormalisation engines apply to quantised weights).
- Each animation becomes a :class:`stbs.Clip` with a key at every keyframe time of its
  channels (keys that start after 0 included), LINEAR, STEP and CUBICSPLINE samplers
  evaluated as the specification says. At a key, bone ``i``'s pose is the rigid part of
  the joint's skinning matrix ``M = G(t) IBM`` (its rotation and the image of the bone's
  start), so skinning the clip with ``lbs`` reproduces the file's skinning; a joint
  whose matrix scales (an animated or non-uniform scale) cannot be a bone of a rig, so
  its scale is dropped, with a warning giving how far from rigid it was.
- A file written by :func:`stbs.io.write_gltf` comes back whole: its skeleton from
  ``skin.extras["stbs"]`` (the bone tails glTF has no place for) and its endpoint
  weights from the attribute ``_ENDPOINT_WEIGHTS_0``.
"""

from __future__ import annotations

import base64
import os
import warnings
from pathlib import Path
from urllib.parse import unquote

import numpy as np

from .. import transforms as tf
from .._optional import require
from ..clip import Clip
from ..pose import Pose
from ..rig.model import Rig
from ..skeleton import Skeleton
from ._parse import input_path, suffix
from .errors import FormatError

__all__ = ["read_gltf", "GLTF_EXTENSIONS"]

GLTF_EXTENSIONS = (".gltf", ".glb")

_DTYPES = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32,
           5126: np.float32}
_NCOMP = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
_NORM = {np.int8: 127.0, np.uint8: 255.0, np.int16: 32767.0, np.uint16: 65535.0}


class _File:
    """A loaded glTF: the pygltflib object, its buffers as bytes, accessor reads."""

    def __init__(self, path: Path):
        pygltflib = require("pygltflib", f"reading the glTF file {str(path)!r}")
        self.path = path
        try:
            g = pygltflib.GLTF2().load(str(path))
        except Exception as exc:       # pygltflib raises many kinds on broken input
            raise FormatError(path, "a glTF 2.0 file (JSON .gltf or binary .glb)",
                              f"an unreadable file ({type(exc).__name__}: {exc})") from None
        if g is None:
            raise FormatError(path, "a glTF 2.0 file (JSON .gltf or binary .glb)",
                              "an unreadable file")
        self.g = g
        self.buffers = [self._buffer(k, b) for k, b in enumerate(g.buffers or [])]

    def _buffer(self, k: int, b) -> bytes:
        uri = b.uri
        if uri is None:
            blob = self.g.binary_blob()
            if blob is None:
                raise FormatError(self.path, f"buffer {k}: the GLB binary chunk", "none")
            data = bytes(blob)
        elif uri.startswith("data:"):
            head, _, body = uri.partition(",")
            data = base64.b64decode(body) if head.endswith(";base64") else unquote(body).encode()
        else:
            if "://" in uri:
                raise FormatError(self.path, f"buffer {k}: a file beside the glTF or a data: URI",
                                  repr(uri[:60]))
            p = self.path.parent / unquote(uri)
            if not p.is_file():
                raise FormatError(self.path, f"buffer {k}: the file {unquote(uri)!r} beside it",
                                  "no such file")
            data = p.read_bytes()
        if b.byteLength is not None and len(data) < b.byteLength:
            raise FormatError(self.path, f"buffer {k} of {b.byteLength} bytes",
                              f"{len(data)} bytes (a truncated file?)")
        return data

    def accessor(self, i, what: str, *, floats: bool = True) -> np.ndarray:
        """Accessor ``i`` as (count, ncomp) float64 (normalised ints scaled) or ints."""
        accs = self.g.accessors or []
        if i is None or not 0 <= i < len(accs):
            raise FormatError(self.path, f"{what}: an accessor index in 0..{len(accs) - 1}",
                              repr(i))
        a = accs[i]
        dt = _DTYPES.get(a.componentType)
        nc = _NCOMP.get(a.type)
        if dt is None or nc is None:
            raise FormatError(self.path, f"{what} (accessor {i}): a known componentType and type",
                              f"{a.componentType}, {a.type!r}")
        count = int(a.count)
        item = np.dtype(dt).itemsize
        if a.bufferView is None:
            out = np.zeros((count, nc), dtype=dt)
        else:
            bvs = self.g.bufferViews or []
            if not 0 <= a.bufferView < len(bvs):
                raise FormatError(self.path, f"{what} (accessor {i}): a bufferView in "
                                             f"0..{len(bvs) - 1}", repr(a.bufferView))
            bv = bvs[a.bufferView]
            if not 0 <= bv.buffer < len(self.buffers):
                raise FormatError(self.path, f"bufferView {a.bufferView}: a buffer in "
                                             f"0..{len(self.buffers) - 1}", repr(bv.buffer))
            buf = self.buffers[bv.buffer]
            start = (bv.byteOffset or 0) + (a.byteOffset or 0)
            stride = bv.byteStride or nc * item
            need = start + (stride * (count - 1) + nc * item if count else 0)
            view_end = (bv.byteOffset or 0) + bv.byteLength
            if need > view_end or view_end > len(buf):
                raise FormatError(self.path, f"{what} (accessor {i}) inside its bufferView and "
                                             f"buffer ({min(view_end, len(buf))} bytes)",
                                  f"{count} elements reaching byte {need} (out of range)")
            out = np.ndarray((count, nc), dtype=np.dtype(dt).newbyteorder("<"), buffer=buf,
                             offset=start, strides=(stride, item)).astype(dt)
        if a.sparse is not None:
            s = a.sparse
            idx = self._raw(s.indices.bufferView, s.indices.byteOffset, s.indices.componentType,
                            1, s.count, f"{what} sparse indices")[:, 0]
            val = self._raw(s.values.bufferView, s.values.byteOffset, a.componentType, nc,
                            s.count, f"{what} sparse values")
            if idx.size and idx.max() >= count:
                raise FormatError(self.path, f"{what}: sparse indices below {count}",
                                  str(int(idx.max())))
            out = out.copy()
            out[idx] = val
        if not floats:
            return out.astype(np.int64)
        x = out.astype(np.float64)
        if a.normalized and dt in _NORM:
            x = np.maximum(x / _NORM[dt], -1.0)
        if not np.isfinite(x).all():
            raise FormatError(self.path, f"{what} (accessor {i}): finite values", "NaN or inf")
        return x

    def _raw(self, view, offset, ctype, nc, count, what) -> np.ndarray:
        dt = _DTYPES.get(ctype)
        bvs = self.g.bufferViews or []
        if dt is None or view is None or not 0 <= view < len(bvs):
            raise FormatError(self.path, f"{what}: a bufferView and componentType",
                              f"{view}, {ctype}")
        bv = bvs[view]
        buf = self.buffers[bv.buffer]
        start = (bv.byteOffset or 0) + (offset or 0)
        n = count * nc * np.dtype(dt).itemsize
        if start + n > min(len(buf), (bv.byteOffset or 0) + bv.byteLength):
            raise FormatError(self.path, f"{what} inside its bufferView", "out of range")
        return np.frombuffer(buf, dtype=np.dtype(dt).newbyteorder("<"), count=count * nc,
                             offset=start).reshape(count, nc).astype(dt)


# ---------------------------------------------------------------------- transforms
def _trs(t, r, s) -> np.ndarray:
    """4x4 of translation, rotation quaternion (x, y, z, w as glTF stores it), scale."""
    M = np.eye(4)
    q = np.array([r[3], r[0], r[1], r[2]], dtype=float)
    n = np.linalg.norm(q)
    M[:3, :3] = tf.quat_to_matrix(q / n if n > 0 else np.array([1.0, 0, 0, 0])) * np.asarray(s)
    M[:3, 3] = t
    return M


def _node_trs(n) -> tuple[np.ndarray, np.ndarray, np.ndarray] | np.ndarray:
    if n.matrix is not None:
        return np.array(n.matrix, dtype=float).reshape(4, 4).T      # column-major
    return (np.array(n.translation if n.translation is not None else [0, 0, 0], float),
            np.array(n.rotation if n.rotation is not None else [0, 0, 0, 1], float),
            np.array(n.scale if n.scale is not None else [1, 1, 1], float))


class _Sampler:
    def __init__(self, f: _File, anim: int, k: int, s, path: str):
        what = f"animation {anim} sampler {k}"
        self.t = f.accessor(s.input, f"{what} input")[:, 0]
        out = f.accessor(s.output, f"{what} output")
        self.mode = s.interpolation or "LINEAR"
        if self.mode not in ("LINEAR", "STEP", "CUBICSPLINE"):
            raise FormatError(f.path, f"{what}: interpolation LINEAR, STEP or CUBICSPLINE",
                              repr(self.mode))
        if self.t.size == 0 or np.any(np.diff(self.t) <= 0):
            raise FormatError(f.path, f"{what}: increasing key times", "none or not increasing")
        per = 3 if self.mode == "CUBICSPLINE" else 1
        if len(out) != per * len(self.t):
            raise FormatError(f.path, f"{what}: {per * len(self.t)} output values "
                                      f"({len(self.t)} keys)", f"{len(out)}")
        self.out = out.reshape(len(self.t), per, -1)
        self.rotation = path == "rotation"

    def __call__(self, t: float) -> np.ndarray:
        T, O = self.t, self.out
        v = 1 if self.mode == "CUBICSPLINE" else 0
        if t <= T[0]:
            return O[0, v].copy()
        if t >= T[-1]:
            return O[-1, v].copy()
        k = int(np.searchsorted(T, t, side="right")) - 1
        dt = T[k + 1] - T[k]
        s = (t - T[k]) / dt
        if self.mode == "STEP":
            return O[k, 0].copy()
        if self.mode == "LINEAR":
            if self.rotation:       # glTF stores x, y, z, w; slerp on the shortest arc
                q0, q1 = O[k, 0][[3, 0, 1, 2]], O[k + 1, 0][[3, 0, 1, 2]]
                q = tf.quat_slerp(q0, q1, s)
                return q[[1, 2, 3, 0]]
            return (1 - s) * O[k, 0] + s * O[k + 1, 0]
        s2, s3 = s * s, s * s * s
        p = ((2 * s3 - 3 * s2 + 1) * O[k, 1] + (s3 - 2 * s2 + s) * dt * O[k, 2]
             + (-2 * s3 + 3 * s2) * O[k + 1, 1] + (s3 - s2) * dt * O[k + 1, 0])
        return p / np.linalg.norm(p) if self.rotation else p


def _polar(M: np.ndarray) -> tuple[np.ndarray, float]:
    """Closest rotation to a 3x3 matrix, and how far it was from one (max |s - 1|)."""
    U, S, Vt = np.linalg.svd(M)
    D = np.eye(3)
    D[2, 2] = np.sign(np.linalg.det(U @ Vt)) or 1.0
    return U @ D @ Vt, float(np.abs(S - 1).max())


# ---------------------------------------------------------------------- the reader
def _pick(f: _File, skin, mesh) -> tuple[int, int]:
    """(mesh node, skin) to read: the options, else the only (or first) skinned mesh."""
    g = f.g
    nodes = g.nodes or []
    skinned = [k for k, n in enumerate(nodes) if n.mesh is not None and n.skin is not None]
    if not g.skins:
        raise FormatError(f.path, "a skin (a skinned mesh with joints)", "no skins")
    if not skinned:
        raise FormatError(f.path, "a node with both a mesh and a skin", "none")

    def label(k):
        n = nodes[k]
        return f"node {k} ({n.name!r}: mesh {n.mesh}, skin {n.skin})"

    cands = skinned
    if mesh is not None:
        cands = [k for k in cands if mesh in (k, nodes[k].name, nodes[k].mesh,
                                              (g.meshes[nodes[k].mesh].name or None))]
    if skin is not None:
        cands = [k for k in cands if skin in (nodes[k].skin, g.skins[nodes[k].skin].name)]
    if not cands:
        raise ValueError(f"{str(f.path)!r}: no skinned mesh matches mesh={mesh!r}, "
                         f"skin={skin!r}; there are {'; '.join(label(k) for k in skinned)}")
    if len(cands) > 1:
        warnings.warn(f"{str(f.path)!r} has {len(cands)} skinned meshes, reading the first "
                      f"(pick with mesh= or skin=): {'; '.join(label(k) for k in cands)}",
                      UserWarning, stacklevel=3)
    return cands[0], nodes[cands[0]].skin


def _triangles(f: _File, prim, k: int, offset: int, n: int) -> np.ndarray:
    mode = 4 if prim.mode is None else prim.mode
    idx = (np.arange(n) if prim.indices is None else
           f.accessor(prim.indices, f"primitive {k} indices", floats=False)[:, 0])
    if idx.size and (idx.min() < 0 or idx.max() >= n):
        raise FormatError(f.path, f"primitive {k} indices below its {n} vertices",
                          str(int(idx.max())))
    if mode == 4:
        if idx.size % 3:
            raise FormatError(f.path, f"primitive {k}: a multiple of 3 indices (triangles)",
                              str(idx.size))
        F = idx.reshape(-1, 3)
    elif mode == 5:       # strip: alternate the winding
        m = np.arange(max(idx.size - 2, 0))
        F = np.column_stack([idx[m], idx[m + 1 + m % 2], idx[m + 2 - m % 2]])
    elif mode == 6:       # fan
        m = np.arange(1, max(idx.size - 1, 1))
        F = np.column_stack([np.full(m.size, idx[0]), idx[m], idx[m + 1]])
    else:
        raise FormatError(f.path, f"primitive {k}: triangles (mode 4, 5 or 6)",
                          f"mode {mode} (points or lines)")
    return F.astype(np.int64) + offset


def read_gltf(path: str | os.PathLike, *, skin: int | str | None = None,
              mesh: int | str | None = None) -> tuple[Rig, dict[str, Clip]]:
    """Read a skinned mesh and its animations from a glTF 2.0 file (.gltf or .glb).

    Parameters
    ----------
    path : str or os.PathLike
        ``.gltf`` (buffers in files beside it or in data: URIs) or ``.glb``.
    skin, mesh : int or str, optional
        Which skinned mesh to read when the file has several: a skin (index or name),
        a mesh node (node index or name, or mesh index or name). Default: the only one;
        with several, the first (with a warning listing them).

    Returns
    -------
    rig : Rig
        3D; ``V``, ``F``, the skeleton (one bone per joint, see the module docs), ``W``;
        ``E`` from ``_ENDPOINT_WEIGHTS_0`` where the file has it (as
        :func:`stbs.io.write_gltf` writes), else None. ``rig.meta["gltf"]`` records
        the file, the mesh node, the skin and the joint nodes of the bones.
    clips : dict of str to Clip
        One per animation, by name (``"animation_K"`` when unnamed), in file order.

    Raises
    ------
    FileNotFoundError
        No such file.
    FormatError
        A file that is not glTF 2.0 (or a truncated GLB), no skinned mesh, an accessor
        or buffer out of range, a mesh of points or lines, weights that leave a vertex
        with none; the message names the file and what was wrong.
    """
    p = input_path(path, "glTF")
    suffix(p, GLTF_EXTENSIONS, "read_gltf")
    f = _File(p)
    g = f.g
    node_k, skin_k = _pick(f, skin, mesh)
    nodes = g.nodes
    sk_g = g.skins[skin_k]
    joints = list(sk_g.joints or [])
    if not joints:
        raise FormatError(p, f"skin {skin_k} with joints", "no joints")
    if any(not 0 <= j < len(nodes) for j in joints):
        raise FormatError(p, f"skin {skin_k}: joint node indices in 0..{len(nodes) - 1}",
                          str(joints))
    nj = len(joints)

    # ---- geometry and weights
    Vs, Fs, Ws, Es = [], [], [], []
    off = 0
    for k, prim in enumerate(g.meshes[nodes[node_k].mesh].primitives):
        at = prim.attributes
        if at.POSITION is None:
            raise FormatError(p, f"primitive {k}: a POSITION attribute", "none")
        V = f.accessor(at.POSITION, f"primitive {k} POSITION")
        if V.shape[1] != 3:
            raise FormatError(p, f"primitive {k} POSITION as VEC3", f"{V.shape[1]} components")
        n = len(V)
        W = np.zeros((n, nj))
        sets = 0
        while True:
            J_acc = getattr(at, f"JOINTS_{sets}", None)
            W_acc = getattr(at, f"WEIGHTS_{sets}", None)
            if J_acc is None and W_acc is None:
                break
            if J_acc is None or W_acc is None:
                raise FormatError(p, f"primitive {k}: JOINTS_{sets} and WEIGHTS_{sets} together",
                                  "only one of them")
            J = f.accessor(J_acc, f"primitive {k} JOINTS_{sets}", floats=False)
            Wk = f.accessor(W_acc, f"primitive {k} WEIGHTS_{sets}")
            if J.shape != (n, 4) or Wk.shape != (n, 4):
                raise FormatError(p, f"primitive {k}: JOINTS_{sets}/WEIGHTS_{sets} as {n} VEC4",
                                  f"{J.shape} and {Wk.shape}")
            used = Wk != 0
            if used.any() and (J[used].min() < 0 or J[used].max() >= nj):
                raise FormatError(p, f"primitive {k} JOINTS_{sets}: joints in 0..{nj - 1}",
                                  str(int(J[used].max())))
            if (Wk < 0).any():
                raise FormatError(p, f"primitive {k} WEIGHTS_{sets}: weights >= 0",
                                  f"{Wk.min():.6g}")
            np.add.at(W, (np.repeat(np.arange(n), 4)[used.ravel()], J[used]), Wk[used])
            if sets == 0:
                J0, W0 = J, Wk
            sets += 1
        if sets == 0:
            raise FormatError(p, f"primitive {k}: JOINTS_0 and WEIGHTS_0 (a skinned primitive)",
                              "none")
        E_acc = getattr(at, "_ENDPOINT_WEIGHTS_0", None)       # written by stbs
        if E_acc is not None:
            e = f.accessor(E_acc, f"primitive {k} _ENDPOINT_WEIGHTS_0")
            J, w0 = J0, W0
            if e.shape != (n, 4) or e.min(initial=0) < 0 or e.max(initial=0) > 1:
                raise FormatError(p, f"primitive {k} _ENDPOINT_WEIGHTS_0: {n} VEC4 in [0, 1]",
                                  f"{e.shape}, values in [{e.min():.3g}, {e.max():.3g}]")
            Ek = np.zeros((n, nj))
            use = w0 > 0
            Ek[np.repeat(np.arange(n), 4)[use.ravel()], J[use]] = e[use]
            Es.append(Ek)
        else:
            Es.append(None)
        Vs.append(V)
        Ws.append(W)
        Fs.append(_triangles(f, prim, k, off, n))
        off += n
    V = np.vstack(Vs)
    W = np.vstack(Ws)
    F = np.vstack(Fs)
    tot = W.sum(axis=1)
    if (tot <= 0).any():
        raise FormatError(p, "every vertex with a positive weight",
                          f"{int((tot <= 0).sum())} vertices with none (e.g. vertex "
                          f"{int(np.flatnonzero(tot <= 0)[0])})")
    W /= tot[:, None]
    E = None
    if any(x is not None for x in Es):
        if any(x is None for x in Es):
            raise FormatError(p, "_ENDPOINT_WEIGHTS_0 on every primitive or on none",
                              "on some only")
        E = np.vstack(Es)

    # ---- bind pose and bones
    if sk_g.inverseBindMatrices is None:
        IBM = np.tile(np.eye(4), (nj, 1, 1))
    else:
        m = f.accessor(sk_g.inverseBindMatrices, f"skin {skin_k} inverseBindMatrices")
        if m.shape != (nj, 16):
            raise FormatError(p, f"skin {skin_k}: {nj} MAT4 inverse bind matrices",
                              f"{m.shape[0]} of {m.shape[1]} values")
        IBM = m.reshape(nj, 4, 4).transpose(0, 2, 1)          # column-major
    try:
        B = np.linalg.inv(IBM)
    except np.linalg.LinAlgError:
        raise FormatError(p, f"skin {skin_k}: invertible inverse bind matrices",
                          "a singular one") from None
    P = B[:, :3, 3]
    parent_node = {c: k for k, n in enumerate(nodes) for c in (n.children or [])}
    in_skin = {node: i for i, node in enumerate(joints)}
    jparent = np.full(nj, -1)
    for i, node in enumerate(joints):
        a = parent_node.get(node)
        while a is not None and a not in in_skin:
            a = parent_node.get(a)
        if a is not None:
            jparent[i] = in_skin[a]
    size = float(np.linalg.norm(np.ptp(V, axis=0))) or 1.0
    tol = 1e-9 * size
    C = [P[i] for i in range(nj)]
    BE = []
    for i in range(nj):
        kids = [c for c in range(nj) if jparent[c] == i and np.linalg.norm(P[c] - P[i]) > tol]
        if kids:
            if jparent[i] >= 0 and np.linalg.norm(P[i] - P[jparent[i]]) > tol:
                d = P[i] - P[jparent[i]]
                kids.sort(key=lambda c: -float((P[c] - P[i]) @ d) / np.linalg.norm(P[c] - P[i]))
            BE.append([i, kids[0]])
            continue
        a = jparent[i]
        d = P[i] - P[a] if a >= 0 else np.zeros(3)
        if np.linalg.norm(d) <= tol:
            y = B[i, :3, 1]
            d = 0.1 * size * y / (np.linalg.norm(y) or 1.0)
        else:
            d = 0.5 * d
        C.append(P[i] + d)
        BE.append([i, len(C) - 1])
    table = (sk_g.extras or {}).get("stbs") if isinstance(sk_g.extras, dict) else None
    if table is not None:       # written by stbs: the skeleton as it was
        try:
            C2 = np.asarray(table["C"], dtype=float)
            BE2 = np.asarray(table["BE"], dtype=np.int64)
            ok = (C2.ndim == 2 and C2.shape[1] == 3 and BE2.shape == (nj, 2)
                  and np.allclose(C2[BE2[:, 0]], P, atol=1e-5 * size))
        except (KeyError, TypeError, ValueError, IndexError):
            ok = False
        if not ok:
            raise FormatError(p, f"skin {skin_k} extras.stbs: a bone table (C, BE, names) "
                                 f"whose bones start at the joints' bind positions",
                              "one that does not fit")
        C, BE = list(C2), BE2.tolist()
    names, seen = [], set()
    given = table.get("names") if table is not None else None
    for i, node in enumerate(joints):
        nm = str(given[i]) if given is not None and i < len(given) else (
            nodes[node].name or f"joint_{i}")
        while nm in seen:
            nm = f"{nm}_{i}"
        seen.add(nm)
        names.append(nm)
    try:
        sk = Skeleton(np.array(C), np.array(BE), names=names)
    except ValueError as exc:
        raise FormatError(p, "joints whose bind positions make a valid skeleton",
                          str(exc)) from None
    rig = Rig(V=V, F=F, skeleton=sk, W=W, E=E,
              meta={"gltf": {"file": p.name, "node": node_k, "skin": skin_k,
                             "joints": [int(j) for j in joints]}})

    # ---- animations
    rest = [_node_trs(n) for n in nodes]
    order = []                       # nodes, parents first
    stack = [k for k in range(len(nodes)) if k not in parent_node]
    while stack:
        k = stack.pop()
        order.append(k)
        stack.extend(nodes[k].children or [])
    clips: dict[str, Clip] = {}
    for a, anim in enumerate(g.animations or []):
        chans = []
        for c, ch in enumerate(anim.channels or []):
            tgt = ch.target
            if tgt is None or tgt.node is None or tgt.path not in ("translation", "rotation",
                                                                   "scale"):
                continue                 # morph weights, or a channel without a node
            if not 0 <= ch.sampler < len(anim.samplers):
                raise FormatError(p, f"animation {a} channel {c}: a sampler in "
                                     f"0..{len(anim.samplers) - 1}", str(ch.sampler))
            chans.append((tgt.node, tgt.path, _Sampler(f, a, ch.sampler,
                                                       anim.samplers[ch.sampler], tgt.path)))
        times = np.unique(np.concatenate([s.t for _, _, s in chans])) if chans else np.zeros(1)
        keys = []
        worst = 0.0
        for t in times:
            local = {}
            for k in range(len(nodes)):
                r = rest[k]
                local[k] = [r] if isinstance(r, np.ndarray) else [x.copy() for x in r]
            for node, path_, s in chans:
                trs = local[node]
                if len(trs) == 1:
                    continue             # a matrix node cannot be animated (spec)
                trs[("translation", "rotation", "scale").index(path_)] = s(float(t))
            G = {}
            for k in order:
                L = local[k][0] if len(local[k]) == 1 else _trs(*local[k])
                G[k] = G[parent_node[k]] @ L if k in parent_node else L
            R = np.empty((sk.n_bones, 3, 3))
            O = np.empty((sk.n_bones, 3))
            for i, node in enumerate(joints):
                M = G[node] @ IBM[i]
                R[i], dev = _polar(M[:3, :3])
                worst = max(worst, dev)
                O[i] = M[:3, :3] @ sk.A[i] + M[:3, 3]
            keys.append((float(t), Pose(sk, rotations=R, origins=O)))
        if worst > 1e-6:
            warnings.warn(f"{str(p)!r}: animation {a} scales joints (up to {worst:.3g} off "
                          f"rigid); bones of a rig are rigid, so the scale is dropped",
                          UserWarning, stacklevel=2)
        name = anim.name or f"animation_{a}"
        while name in clips:
            name = f"{name}_{a}"
        clips[name] = Clip(keys, fps=30)
    return rig, clips
