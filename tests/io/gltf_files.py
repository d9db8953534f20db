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
