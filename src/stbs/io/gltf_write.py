"""glTF 2.0 out: :func:`write_gltf` writes a rig as a standard skin every viewer plays.

What is written
---------------
- The mesh (POSITION, NORMAL, triangles) and a skin with one joint node per bone: the
  node sits at the bone's start, parented to its parent bone's node (roots under a node
  ``"stbs"``), with inverse bind matrices that translate by ``-a_i``; ``JOINTS_0`` and
  ``WEIGHTS_0`` hold each vertex's four heaviest bones, the weights quantised to
  normalised 16-bit integers that sum to exactly 65535 (largest-remainder rounding).
- The endpoint weights as the custom attribute ``_ENDPOINT_WEIGHTS_0`` (float VEC4,
  aligned with ``JOINTS_0``) and the skeleton (``C``, ``BE``, names) in
  ``skin.extras["stbs"]``, so :func:`stbs.io.read_gltf` reads the rig back whole;
  other tools ignore both.
- ``clip=``: an animation of the joint nodes' rotations and translations, sampled at the
  clip's rate. glTF skins rigid joints with linear blending only, so this carries each
  bone's rotation and posed start (classic LBS: ``lbs`` with stretch 1 and no twist);
  stretch and twist are not in it (``bake=`` carries them).
- ``bake=METHOD``: what that method computes, stretch and twist included, as one morph
  target per sampled frame (the displacement from the rest mesh) and a ``weights``
  animation that shows frame k alone at its time; the joints stay at rest, so any glTF
  viewer plays the STBS animation as computed.
"""

from __future__ import annotations

import base64
import json
import os
import struct
from typing import Any

import numpy as np

from .. import transforms as tf
from ..clip import Clip
from ..geometry import boundary_faces, vertex_normals
from ..pose import local_transforms
from ..rig.model import Rig
from ..skinning import METHODS, Deformer, top_k
from ._atomic import atomic_open
from ._parse import suffix
from .gltf import GLTF_EXTENSIONS

__all__ = ["write_gltf", "quantize_weights", "glb_bytes"]

_FLOAT, _USHORT, _UINT, _UBYTE = 5126, 5123, 5125, 5121
_ARRAY, _ELEMENTS = 34962, 34963


def glb_bytes(doc: dict, blob: bytes) -> bytes:
    """A GLB file: the 12-byte header, the JSON chunk (space-padded) and the BIN chunk
    (zero-padded), each to 4 bytes as the specification asks."""
    js = json.dumps(doc, separators=(",", ":")).encode()
    js += b" " * (-len(js) % 4)
    bin_ = blob + b"\0" * (-len(blob) % 4)
    return (struct.pack("<4sII", b"glTF", 2, 12 + 8 + len(js) + 8 + len(bin_))
            + struct.pack("<I4s", len(js), b"JSON") + js
            + struct.pack("<I4s", len(bin_), b"BIN\0") + bin_)


def quantize_weights(w: np.ndarray, total: int = 65535) -> np.ndarray:
    """Rows of non-negative weights (n, k) as integers summing to exactly ``total``.

    Largest-remainder rounding: each row is scaled to ``total``, floored, and the units
    left over go to the entries with the largest fractional parts, so no entry is off by
    a unit or more from its exact value.

    Examples
    --------
    >>> quantize_weights(np.array([[1, 1, 1, 0.0]]), total=255).tolist()
    [[85, 85, 85, 0]]
    >>> quantize_weights(np.array([[0.5, 0.25, 0.25, 0.0]]), total=3).sum()
    np.int64(3)
    """
    w = np.asarray(w, dtype=np.float64)
    s = w.sum(axis=1, keepdims=True)
    x = np.where(s > 0, w / np.where(s > 0, s, 1) * total, 0.0)
    q = np.floor(x).astype(np.int64)
    left = total - q.sum(axis=1)
    frac = x - q
    order = np.argsort(-frac, axis=1, kind="stable")
    rank = np.empty_like(order)
    np.put_along_axis(rank, order, np.arange(w.shape[1])[None, :].repeat(len(w), 0), axis=1)
    q += (rank < left[:, None]) & (s > 0)
    return q


class _Blob:
    def __init__(self):
        self.data = bytearray()
        self.views: list[dict] = []
        self.accessors: list[dict] = []

    def add(self, a: np.ndarray, ctype: int, gl_type: str, *, target: int | None = None,
            normalized: bool = False, minmax: bool = False) -> int:
        dt = {_FLOAT: "<f4", _USHORT: "<u2", _UINT: "<u4", _UBYTE: "u1"}[ctype]
        a = np.ascontiguousarray(a, dtype=dt)
        while len(self.data) % 4:
            self.data.append(0)
        view = {"buffer": 0, "byteOffset": len(self.data), "byteLength": a.nbytes}
        if target is not None:
            view["target"] = target
        self.data.extend(a.tobytes())
        self.views.append(view)
        rows = a.reshape(len(a), -1) if a.ndim > 1 else a.reshape(-1, 1)
        acc: dict[str, Any] = {"bufferView": len(self.views) - 1, "componentType": ctype,
                               "count": int(len(rows) if gl_type != "MAT4" else len(a)),
                               "type": gl_type}
        if normalized:
            acc["normalized"] = True
        if minmax:
            acc["min"] = rows.min(axis=0).astype(float).tolist()
            acc["max"] = rows.max(axis=0).astype(float).tolist()
        self.accessors.append(acc)
        return len(self.accessors) - 1


def _quat_xyzw(R: np.ndarray) -> np.ndarray:
    q = tf.matrix_to_quat(R)          # (w, x, y, z), w >= 0
    return q[..., [1, 2, 3, 0]]


def _check_clip(clip, rig: Rig):
    if clip is None:
        return None
    if not isinstance(clip, Clip):
        raise TypeError(f"clip must be a stbs.Clip, got {type(clip).__name__}")
    if clip.skeleton != rig.skeleton:
        raise ValueError(f"clip must be of the rig's skeleton, got {clip.skeleton!r} for "
                         f"{rig.skeleton!r}")
    return clip


def write_gltf(path: str | os.PathLike, rig: Rig, clip: Clip | None = None,
               bake: str | None = None, *, frames=None) -> None:
    """Write a 3D rig as glTF 2.0 (``.glb``, or ``.gltf`` with its buffer embedded).

    Parameters
    ----------
    path : str or os.PathLike
        Destination ending in ``.glb`` or ``.gltf``; written atomically.
    rig : Rig
        3D, with triangles (or tetrahedra, whose boundary is written).
    clip : Clip, optional
        An animation of the rig's skeleton: written as joint rotations and
        translations (see the module docs), sampled at ``clip.fps``.
    bake : {"lbs", "dqs", "stbs-lbs", "stbs-dqs"}, optional
        With ``clip``: also bake that method's deformation at each sampled frame as
        morph targets played by a ``weights`` animation (then the joints stay at rest).
    frames : sequence of (n, 3) float, keyword-only, optional
        With ``bake``: the deformed positions at each of ``clip.sample_times()``,
        already computed (by a :class:`stbs.Deformer` of that method); default: computed
        here.

    Raises
    ------
    ValueError
        A 2D rig, no triangles, a clip of another skeleton, ``bake`` without a clip or
        naming no method, a path of another extension.
    """
    suffix(path, GLTF_EXTENSIONS, "write_gltf")
    if not isinstance(rig, Rig):
        raise TypeError(f"rig must be a stbs.Rig, got {type(rig).__name__}")
    if rig.dim != 3:
        raise ValueError(f"glTF holds 3D rigs; got a {rig.dim}D rig")
    clip = _check_clip(clip, rig)
    if bake is not None and bake not in METHODS:
        raise ValueError(f"bake must be one of {', '.join(METHODS)}, got {bake!r}")
    if bake is not None and clip is None:
        raise ValueError("bake needs a clip: the animation to bake")
    F = rig.F if rig.F is not None else (boundary_faces(rig.T, rig.V)
                                         if rig.T is not None else None)
    if F is None or len(F) == 0:
        raise ValueError("write_gltf needs triangles (rig.F) or tetrahedra (rig.T)")
    sk = rig.skeleton
    V = np.asarray(rig.V, dtype=np.float64)
    b = sk.n_bones
    layout = top_k(rig.W, rig.E, max_influences=4, pad=(4,))
    idx, w = layout.idx.T, layout.w.T                 # (n, 4) each
    e = layout.e.T if rig.E is not None else None
    q = quantize_weights(w)
    idx = np.where(q > 0, idx, 0)          # unused slots name joint 0, as the spec asks
    blob = _Blob()
    attrs = {"POSITION": blob.add(V, _FLOAT, "VEC3", target=_ARRAY, minmax=True),
             "NORMAL": blob.add(vertex_normals(V, F), _FLOAT, "VEC3", target=_ARRAY),
             "JOINTS_0": blob.add(idx, _UBYTE if b <= 256 else _USHORT, "VEC4", target=_ARRAY),
             "WEIGHTS_0": blob.add(q, _USHORT, "VEC4", target=_ARRAY, normalized=True)}
    if e is not None:
        attrs["_ENDPOINT_WEIGHTS_0"] = blob.add(np.where(q > 0, e, 0.0), _FLOAT, "VEC4",
                                                target=_ARRAY)
    prim: dict[str, Any] = {"attributes": attrs, "mode": 4,
                            "indices": blob.add(np.asarray(F).ravel(), _UINT, "SCALAR",
                                                target=_ELEMENTS)}
    mesh: dict[str, Any] = {"name": "mesh", "primitives": [prim]}

    # joint nodes: bone i's node at a_i, under its parent bone's node
    A = sk.A
    nodes: list[dict[str, Any]] = [{"name": "stbs", "children": []},
                                   {"name": "mesh", "mesh": 0, "skin": 0}]
    first = len(nodes)
    for i in range(b):
        p = sk.parents[i]
        t = A[i] - (A[p] if p >= 0 else 0.0)
        nodes.append({"name": sk.names[i], "translation": t.tolist()})
    for i in range(b):
        p = sk.parents[i]
        parent = nodes[first + p] if p >= 0 else nodes[0]
        parent.setdefault("children", []).append(first + i)
    IBM = np.tile(np.eye(4), (b, 1, 1))
    IBM[:, :3, 3] = -A
    skin = {"name": "stbs", "joints": list(range(first, first + b)), "skeleton": 0,
            "inverseBindMatrices": blob.add(IBM.transpose(0, 2, 1).reshape(b, 16), _FLOAT,
                                            "MAT4"),
            "extras": {"stbs": {"version": 1, "C": sk.C.tolist(), "BE": sk.BE.tolist(),
                                "names": list(sk.names)}}}
    animations = []
    if clip is not None:
        times = clip.sample_times()
        poses = [clip.pose(float(t)) for t in times]
        t_acc = blob.add(times - times[0], _FLOAT, "SCALAR", minmax=True)
        samplers, channels = [], []
        if bake is None:
            R = np.array([p.rotations for p in poses])          # (k, b, 3, 3) world
            O = np.array([p.origins for p in poses])            # (k, b, 3)
            local_R, local_t = local_transforms(sk, R, O)
            quat = _quat_xyzw(local_R)
            # keep consecutive keys on the same hemisphere so viewers slerp the short way
            for k in range(1, len(times)):
                flip = (quat[k] * quat[k - 1]).sum(axis=1) < 0
                quat[k, flip] *= -1
            for i in range(b):
                for path_, vals, typ in (("rotation", quat[:, i], "VEC4"),
                                         ("translation", local_t[:, i], "VEC3")):
                    samplers.append({"input": t_acc, "interpolation": "LINEAR",
                                     "output": blob.add(vals, _FLOAT, typ)})
                    channels.append({"sampler": len(samplers) - 1,
                                     "target": {"node": first + i, "path": path_}})
            animations.append({"name": "clip", "samplers": samplers, "channels": channels})
        else:
            if frames is None:
                dfm = Deformer(V, sk, rig.W, rig.E, method=bake)
                frames = (dfm(p) for p in poses)
            elif len(frames) != len(poses):
                raise ValueError(f"frames must hold one mesh per sampled time ({len(poses)}), "
                                 f"got {len(frames)}")
            targets = []
            for U in frames:
                U = np.asarray(U, dtype=np.float64)
                if U.shape != V.shape:
                    raise ValueError(f"frames: each must have shape {V.shape}, got {U.shape}")
                targets.append({"POSITION": blob.add(U - V, _FLOAT, "VEC3", target=_ARRAY,
                                                     minmax=True)})
            prim["targets"] = targets
            k = len(poses)
            mesh["weights"] = [0.0] * k
            mesh["extras"] = {"targetNames": [f"frame_{j}" for j in range(k)]}
            onehot = np.eye(k, dtype=np.float32).reshape(-1)
            samplers.append({"input": t_acc, "interpolation": "LINEAR",
                             "output": blob.add(onehot, _FLOAT, "SCALAR")})
            channels.append({"sampler": 0, "target": {"node": 1, "path": "weights"}})
            animations.append({"name": f"baked {bake}", "samplers": samplers,
                               "channels": channels})
    doc: dict[str, Any] = {
        "asset": {"version": "2.0", "generator": "stbs"},
        "scene": 0, "scenes": [{"nodes": [0, 1]}],
        "nodes": nodes, "meshes": [mesh], "skins": [skin],
        "accessors": blob.accessors, "bufferViews": blob.views,
    }
    if animations:
        doc["animations"] = animations
    data = bytes(blob.data)
    glb = os.fspath(path).lower().endswith(".glb")
    if glb:
        doc["buffers"] = [{"byteLength": len(data)}]
        with atomic_open(path, "wb") as f:
            f.write(glb_bytes(doc, data))
    else:
        doc["buffers"] = [{"byteLength": len(data), "uri": "data:application/octet-stream;"
                           "base64," + base64.b64encode(data).decode()}]
        with atomic_open(path, "w", encoding="utf-8") as f:
            json.dump(doc, f)
