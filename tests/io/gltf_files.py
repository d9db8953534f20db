"""Small glTF 2.0 files written by hand for the reader's tests, and the glTF skinning
formula evaluated directly from what was written (independent of stbs.io.gltf)."""

from __future__ import annotations

import base64
import json
import struct
from dataclasses import dataclass, field

import numpy as np

FLOAT, UBYTE, USHORT, UINT = 5126, 5121, 5123, 5125
_NP = {FLOAT: "<f4", UBYTE: "u1", USHORT: "<u2", UINT: "<u4"}
_TYPE = {1: "SCALAR", 2: "VEC2", 3: "VEC3", 4: "VEC4", 16: "MAT4"}


def quat_xyzw(axis, deg):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    h = np.radians(deg) / 2
    return [*(np.sin(h) * axis), np.cos(h)]


def trs_matrix(t=(0, 0, 0), r=(0, 0, 0, 1), s=(1, 1, 1)):
    """4x4 of a node's TRS; the quaternion (x, y, z, w) normalised first, as viewers do
    (files round their quaternions: Khronos' SimpleSkin stores 0.707 for sqrt(1/2))."""
    r = np.asarray(r, float) / np.linalg.norm(r)
    x, y, z, w = r
    R = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                  [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                  [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    M = np.eye(4)
    M[:3, :3] = R * np.asarray(s, float)
    M[:3, 3] = t
    return M


@dataclass
class Builder:
    """Accumulates buffers views and accessors into one binary buffer."""

    data: bytearray = field(default_factory=bytearray)
    views: list = field(default_factory=list)
    accessors: list = field(default_factory=list)

    def add(self, a, ctype=FLOAT, *, normalized=False, mat4=False, stride=None) -> int:
        a = np.asarray(a)
        flat = a.reshape(len(a), -1) if a.ndim > 1 else a.reshape(-1, 1)
        nc = 16 if mat4 else flat.shape[1]
        raw = flat.astype(_NP[ctype]).tobytes()
        item = np.dtype(_NP[ctype]).itemsize * flat.shape[1]
        if stride and stride > item:            # interleave padding to exercise byteStride
            rows = [raw[k * item:(k + 1) * item] + b"\0" * (stride - item)
                    for k in range(len(flat))]
            raw = b"".join(rows)
        while len(self.data) % 4:
            self.data.append(0)
        view = {"buffer": 0, "byteOffset": len(self.data), "byteLength": len(raw)}
        if stride:
            view["byteStride"] = stride
        self.data.extend(raw)
        self.views.append(view)
        acc = {"bufferView": len(self.views) - 1, "componentType": ctype,
               "count": len(flat), "type": _TYPE[nc]}
        if normalized:
            acc["normalized"] = True
        if ctype == FLOAT and nc <= 4:
            acc["min"] = flat.min(axis=0).astype(float).tolist()
            acc["max"] = flat.max(axis=0).astype(float).tolist()
        self.accessors.append(acc)
        return len(self.accessors) - 1


def write(path, doc: dict, builder: Builder, *, glb: bool):
    doc = dict(doc)
    doc["asset"] = {"version": "2.0", "generator": "stbs tests"}
    doc["accessors"] = builder.accessors
    doc["bufferViews"] = builder.views
    blob = bytes(builder.data)
    if glb:
        doc["buffers"] = [{"byteLength": len(blob)}]
        js = json.dumps(doc).encode()
        js += b" " * (-len(js) % 4)
        bin_ = blob + b"\0" * (-len(blob) % 4)
        total = 12 + 8 + len(js) + 8 + len(bin_)
        out = struct.pack("<4sII", b"glTF", 2, total)
        out += struct.pack("<I4s", len(js), b"JSON") + js
        out += struct.pack("<I4s", len(bin_), b"BIN\0") + bin_
        path.write_bytes(out)
    else:
        uri = "data:application/octet-stream;base64," + base64.b64encode(blob).decode()
        doc["buffers"] = [{"byteLength": len(blob), "uri": uri}]
        path.write_text(json.dumps(doc))
    return path


def node_globals(nodes: list[dict], local: dict[int, np.ndarray]) -> dict[int, np.ndarray]:
    """World matrices of all nodes from their local matrices (node index -> 4x4)."""
    parent = {c: k for k, n in enumerate(nodes) for c in n.get("children", [])}
    G: dict[int, np.ndarray] = {}

    def g(k):
        if k not in G:
            G[k] = (g(parent[k]) @ local[k]) if k in parent else local[k]
        return G[k]

    for k in range(len(nodes)):
        g(k)
    return G


def local_matrices(nodes: list[dict], overrides: dict | None = None) -> dict[int, np.ndarray]:
    """Local matrices: each node's TRS (or matrix), with ``overrides[node][path] = value``."""
    out = {}
    for k, n in enumerate(nodes):
        if "matrix" in n:
            out[k] = np.array(n["matrix"], float).reshape(4, 4).T
            continue
        trs = {"translation": n.get("translation", [0, 0, 0]),
               "rotation": n.get("rotation", [0, 0, 0, 1]), "scale": n.get("scale", [1, 1, 1])}
        trs.update((overrides or {}).get(k, {}))
        out[k] = trs_matrix(trs["translation"], trs["rotation"], trs["scale"])
    return out


def skin_formula(V, joints_w: list[tuple[np.ndarray, np.ndarray]], G, skin_joints, IBM):
    """The glTF skinning formula: sum over the weight sets of w * (G_j IBM_j) v, with the
    weights of each vertex divided by their sum."""
    V = np.asarray(V, float)
    Vh = np.hstack([V, np.ones((len(V), 1))])
    out = np.zeros_like(V)
    tot = sum(w.sum(axis=1) for _, w in joints_w)
    for J, w in joints_w:
        for c in range(4):
            M = np.array([G[skin_joints[j]] @ IBM[j] for j in J[:, c]])
            out += (w[:, c] / tot)[:, None] * np.einsum("nij,nj->ni", M, Vh)[:, :3]
    return out


# ---------------------------------------------------------------- an independent reader
# A second, small glTF reader for the tests: it parses the file's bytes itself (GLB
# chunks, data: URIs, .bin files beside it), samples animations as the specification's
# appendix says, and skins with the specification's formula. It shares no code with
# stbs.io.gltf, so the two can only agree by both being right.

_COMP = {5120: ("i1", 127.0), 5121: ("u1", 255.0), 5122: ("<i2", 32767.0),
         5123: ("<u2", 65535.0), 5125: ("<u4", None), 5126: ("<f4", None)}
_NCOMP = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}


def load_raw(path):
    """(JSON document, [buffer bytes]) of a .glb or .gltf file."""
    from pathlib import Path
    from urllib.parse import unquote

    path = Path(path)
    data = path.read_bytes()
    blob = None
    if data[:4] == b"glTF":
        n = struct.unpack_from("<I", data, 12)[0]
        doc = json.loads(data[20:20 + n])
        if 20 + n + 8 <= len(data):
            m = struct.unpack_from("<I", data, 20 + n)[0]
            blob = data[28 + n:28 + n + m]
    else:
        doc = json.loads(data)
    bufs = []
    for b in doc.get("buffers", []):
        uri = b.get("uri")
        if uri is None:
            bufs.append(blob)
        elif uri.startswith("data:"):
            bufs.append(base64.b64decode(uri.split(",", 1)[1]))
        else:
            bufs.append((path.parent / unquote(uri)).read_bytes())
    return doc, bufs


_CACHE: dict = {}


def raw_accessor(doc, bufs, i):
    """Accessor i as float64 (count, components), normalised integers scaled."""
    key = (id(doc), i)
    if key not in _CACHE or _CACHE[key][0] is not doc:
        _CACHE[key] = (doc, _raw_accessor(doc, bufs, i))
    return _CACHE[key][1]


def _raw_accessor(doc, bufs, i):
    a = doc["accessors"][i]
    dt, norm = _COMP[a["componentType"]]
    nc = _NCOMP[a["type"]]
    item = np.dtype(dt).itemsize * nc
    x = np.zeros((a["count"], nc))
    if "bufferView" in a:
        bv = doc["bufferViews"][a["bufferView"]]
        stride = bv.get("byteStride", item)
        start = bv.get("byteOffset", 0) + a.get("byteOffset", 0)
        buf = bufs[bv["buffer"]]
        x = np.array([np.frombuffer(buf, dtype=dt, count=nc, offset=start + k * stride)
                      for k in range(a["count"])], dtype=float).reshape(a["count"], nc)
    if "sparse" in a:
        s = a["sparse"]
        ind, val = s["indices"], s["values"]
        bi = doc["bufferViews"][ind["bufferView"]]
        idx = np.frombuffer(bufs[bi["buffer"]], dtype=_COMP[ind["componentType"]][0],
                            count=s["count"],
                            offset=bi.get("byteOffset", 0) + ind.get("byteOffset", 0))
        bv = doc["bufferViews"][val["bufferView"]]
        v = np.frombuffer(bufs[bv["buffer"]], dtype=dt, count=s["count"] * nc,
                          offset=bv.get("byteOffset", 0) + val.get("byteOffset", 0))
        x[idx.astype(int)] = v.reshape(-1, nc)
    if a.get("normalized") and norm:
        x = np.maximum(x / norm, -1.0)
    return x


def _slerp(a, b, s):
    """The specification's slerp (shortest path) of (x, y, z, w) quaternions."""
    d = float(np.dot(a, b))
    if d < 0:
        b, d = -b, -d
    if d > 0.9999995:
        q = (1 - s) * a + s * b
    else:
        th = np.arccos(min(d, 1.0))
        q = (np.sin((1 - s) * th) * a + np.sin(s * th) * b) / np.sin(th)
    return q / np.linalg.norm(q)


class Reference:
    """A glTF character as the specification draws it (see the comment above).

    ``skin_at(a, t)``: every skinned primitive's vertices, concatenated in node and
    primitive order, skinned by animation ``a`` at time ``t``, then (``rigid=True``)
    every primitive of the meshes without a skin on a joint node or below one, in node
    and primitive order, drawn by their node's world matrix at ``t``;
    ``skin_bind(turn=None)``: the same in the bind pose (every joint at its inverse bind
    matrix, the nodes below it at their rest transforms), with ``turn = (joint node,
    3x3 rotation)`` applied in that node's frame.
    """

    def __init__(self, path, *, rigid=True):
        self.doc, self.bufs = load_raw(path)
        d = self.doc
        self.nodes = d["nodes"]
        self.parent = {c: k for k, n in enumerate(self.nodes) for c in n.get("children", [])}
        self.skinned = [k for k, n in enumerate(self.nodes) if "mesh" in n and "skin" in n]
        joints = {j for sk in d.get("skins", []) for j in sk["joints"]}
        self.rigid = []           # (node, mesh, primitive, V, nearest joint at or above)
        for k, n in enumerate(self.nodes):
            if not rigid or "mesh" not in n or "skin" in n:
                continue
            up = k
            while up is not None and up not in joints:
                up = self.parent.get(up)
            if up is None:
                continue              # a prop: under no joint
            for p, prim in enumerate(d["meshes"][n["mesh"]]["primitives"]):
                if prim.get("mode", 4) in (4, 5, 6):
                    self.rigid.append((k, n["mesh"], p,
                                       raw_accessor(d, self.bufs, prim["attributes"]["POSITION"]),
                                       up))
        self.prims = []           # (node, mesh, primitive, V, [(J, W)], skin)
        for k in self.skinned:
            n = self.nodes[k]
            for p, prim in enumerate(d["meshes"][n["mesh"]]["primitives"]):
                if prim.get("mode", 4) not in (4, 5, 6):
                    continue
                at = prim["attributes"]
                V = raw_accessor(d, self.bufs, at["POSITION"])
                sets, c = [], 0
                while f"JOINTS_{c}" in at:
                    sets.append((raw_accessor(d, self.bufs, at[f"JOINTS_{c}"]).astype(int),
                                 raw_accessor(d, self.bufs, at[f"WEIGHTS_{c}"])))
                    c += 1
                self.prims.append((k, n["mesh"], p, V, sets, n["skin"]))
        self.ibm = []
        for s in d["skins"]:
            if "inverseBindMatrices" in s:
                m = raw_accessor(d, self.bufs, s["inverseBindMatrices"])
                self.ibm.append(m.reshape(-1, 4, 4).transpose(0, 2, 1))
            else:
                self.ibm.append(np.tile(np.eye(4), (len(s["joints"]), 1, 1)))

    @property
    def V(self):
        """The vertices as the file holds them (skinned, then rigid), untransformed."""
        return np.vstack([p[3] for p in self.prims + self.rigid])

    def animation_times(self, a):
        """Every key time of animation a's translation, rotation and scale channels."""
        anim = self.doc["animations"][a]
        ts = set()
        for ch in anim["channels"]:
            if ch["target"].get("path") in ("translation", "rotation", "scale"):
                s = anim["samplers"][ch["sampler"]]
                ts.update(raw_accessor(self.doc, self.bufs, s["input"])[:, 0].tolist())
        return np.array(sorted(ts))

    def _sample(self, anim, ch, t):
        s = anim["samplers"][ch["sampler"]]
        T = raw_accessor(self.doc, self.bufs, s["input"])[:, 0]
        out = raw_accessor(self.doc, self.bufs, s["output"])
        mode = s.get("interpolation", "LINEAR")
        rot = ch["target"]["path"] == "rotation"
        if mode == "CUBICSPLINE":
            a_, v, b_ = out[0::3], out[1::3], out[2::3]
        else:
            v = out
        if t <= T[0]:
            return v[0] / (np.linalg.norm(v[0]) if rot else 1)
        if t >= T[-1]:
            return v[-1] / (np.linalg.norm(v[-1]) if rot else 1)
        k = int(np.searchsorted(T, t, side="right")) - 1
        td = T[k + 1] - T[k]
        u = (t - T[k]) / td
        if mode == "STEP":
            x = v[k]
        elif mode == "LINEAR":
            if rot:
                return _slerp(v[k] / np.linalg.norm(v[k]), v[k + 1] / np.linalg.norm(v[k + 1]),
                              u)
            x = (1 - u) * v[k] + u * v[k + 1]
        else:
            x = ((2 * u**3 - 3 * u**2 + 1) * v[k] + td * (u**3 - 2 * u**2 + u) * b_[k]
                 + (-2 * u**3 + 3 * u**2) * v[k + 1] + td * (u**3 - u**2) * a_[k + 1])
        return x / np.linalg.norm(x) if rot else x

    def locals_at(self, a, t):
        over = {}
        if a is not None:
            anim = self.doc["animations"][a]
            for ch in anim["channels"]:
                tg = ch["target"]
                if tg.get("path") in ("translation", "rotation", "scale") and "node" in tg:
                    over.setdefault(tg["node"], {})[tg["path"]] = self._sample(anim, ch, t)
        return local_matrices(self.nodes, over)

    def _skin(self, G):
        out = []
        for _, _, _, V, sets, s in self.prims:
            joints = self.doc["skins"][s]["joints"]
            M = np.array([G[j] @ self.ibm[s][i] for i, j in enumerate(joints)])
            Vh = np.hstack([V, np.ones((len(V), 1))])
            tot = sum(w.sum(axis=1) for _, w in sets)
            acc = np.zeros((len(V), 4))
            for J, w in sets:
                for c in range(4):
                    acc += (w[:, c] / tot)[:, None] * np.einsum("nij,nj->ni", M[J[:, c]], Vh)
            out.append(acc[:, :3])
        for k, _, _, V, _ in self.rigid:          # drawn by the node's world matrix
            out.append(V @ G[k][:3, :3].T + G[k][:3, 3])
        return np.vstack(out)

    def skin_at(self, a, t):
        return self._skin(node_globals(self.nodes, self.locals_at(a, t)))

    def bind_world(self):
        """Joint node -> world bind matrix (the first skin naming it)."""
        B = {}
        for s, skin in enumerate(self.doc["skins"]):
            for i, j in enumerate(skin["joints"]):
                B.setdefault(j, np.linalg.inv(self.ibm[s][i]))
        return B

    def skin_bind(self, turn=None):
        B = self.bind_world()
        rest = local_matrices(self.nodes)
        G: dict[int, np.ndarray] = {}

        def g(k):                    # the bind pose: every joint at its bind matrix
            if k not in G:
                up = g(self.parent[k]) if k in self.parent else np.eye(4)
                G[k] = B[k] if k in B else up @ rest[k]
            return G[k]

        for k in range(len(self.nodes)):
            g(k)
        local = {k: (np.linalg.inv(G[self.parent[k]]) @ G[k] if k in self.parent else G[k])
                 for k in G}
        if turn is not None:
            T = np.eye(4)
            T[:3, :3] = turn[1]
            local[turn[0]] = local[turn[0]] @ T
        return self._skin(node_globals(self.nodes, local))
