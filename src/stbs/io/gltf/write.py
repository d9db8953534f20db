"""glTF 2.0 out: :func:`write_gltf` writes a rig as a standard skin every viewer plays.

What is written
---------------
- The mesh (POSITION, NORMAL, triangles) and a skin with one joint node per bone: the
  node sits at the bone's start, its parent node is its parent bone's (an offset
  child hangs where it is; roots under a node ``"stbs"``), with inverse bind matrices
  that translate by ``-a_i``; ``JOINTS_0`` and ``WEIGHTS_0`` hold each vertex's four
  heaviest bones, the weights quantised to normalised 16-bit integers that sum to
  exactly 65535 (largest-remainder rounding).
- The endpoint weights as the custom attribute ``_ENDPOINT_WEIGHTS_0`` (float VEC4,
  aligned with ``JOINTS_0``) and the skeleton in the bone table
  (``skin.extras["stbs"]``, :mod:`stbs.io.gltf.bones`), so :func:`stbs.io.read_gltf`
  reads the rig back whole; other tools ignore both.
- ``clip=``: an animation of the joint nodes. glTF skins rigid joints with linear
  blending only, so it carries each bone's rotation and posed start (classic LBS:
  ``lbs`` with stretch 1 and no twist). A clip without stretch and twist is written
  key for key, each bone's rotation and offset channel with its own interpolation
  (LINEAR, STEP or CUBICSPLINE), so the file plays exactly as ``clip.pose(t)`` at any
  time; a clip with stretch or twist is sampled at ``clip.fps`` (``bake=`` carries
  those).
- ``bake=METHOD, frames=``: positions that method computed (stretch and twist included),
  one morph target per frame (the displacement from the rest mesh) and a ``weights``
  animation that shows frame k alone at its time; the joints stay at rest, so any glTF
  viewer plays the STBS animation as computed. This module only writes the frames:
  :func:`stbs.bake.export` skins a clip and writes it so.
"""

from __future__ import annotations

import base64
import json
import os
from typing import Any

import numpy as np

from ... import transforms as tf
from ...clip import Clip
from ...geometry import boundary_faces, vertex_normals
from ...methods import SKINNING_METHODS
from ...pose import local_transforms
from ...rig.model import Rig
from ...skinning.layout import four_heaviest
from .._atomic import atomic_open
from .._frames import skinned_frames
from .._parse import suffix
from .accessors import (
    ARRAY_BUFFER,
    ELEMENT_ARRAY_BUFFER,
    FLOAT,
    UBYTE,
    UINT,
    USHORT,
    AccessorWriter,
)
from .bones import TABLE_KEY, bone_table
from .container import glb_bytes
from .read import GLTF_EXTENSIONS

__all__ = ["write_gltf", "quantize_weights", "save_gltf_document"]

_GLTF_MODE = {"linear": "LINEAR", "step": "STEP", "cubic": "CUBICSPLINE"}


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


def skin_attributes(blob: AccessorWriter, W, E, n_joints: int) -> dict[str, int]:
    """``JOINTS_0``, ``WEIGHTS_0`` (and ``_ENDPOINT_WEIGHTS_0`` with ``E``) accessors of
    each vertex's four heaviest columns of ``W`` (n, n_joints)."""
    idx, w, e = four_heaviest(W, E)                    # (n, 4) each
    q = quantize_weights(w)
    idx = np.where(q > 0, idx, 0)          # unused slots name joint 0, as the spec asks
    out = {"JOINTS_0": blob.add(idx, UBYTE if n_joints <= 256 else USHORT, "VEC4",
                                target=ARRAY_BUFFER),
           "WEIGHTS_0": blob.add(q, USHORT, "VEC4", target=ARRAY_BUFFER, normalized=True)}
    if E is not None:
        out["_ENDPOINT_WEIGHTS_0"] = blob.add(np.where(q > 0, e, 0.0), FLOAT, "VEC4",
                                              target=ARRAY_BUFFER)
    return out


def save_gltf_document(path: str | os.PathLike, doc: dict, data: bytes) -> None:
    """Write ``doc`` with ``data`` as its one buffer: a GLB (``.glb``) or JSON with the
    buffer in a ``data:`` URI (``.gltf``), atomically."""
    if os.fspath(path).lower().endswith(".glb"):
        doc["buffers"] = [{"byteLength": len(data)}]
        with atomic_open(path, "wb") as f:
            f.write(glb_bytes(doc, data))
    else:
        doc["buffers"] = [{"byteLength": len(data), "uri": "data:application/octet-stream;"
                           "base64," + base64.b64encode(data).decode()}]
        with atomic_open(path, "w", encoding="utf-8") as f:
            json.dump(doc, f, allow_nan=False)


def _check_clip(clip, rig: Rig):
    if clip is None:
        return None
    if not isinstance(clip, Clip):
        raise TypeError(f"clip must be a stbs.Clip, got {type(clip).__name__}")
    if clip.skeleton != rig.skeleton:
        raise ValueError(f"clip must be of the rig's skeleton, got {clip.skeleton!r} for "
                         f"{rig.skeleton!r}")
    return clip


def _xyzw(q: np.ndarray) -> np.ndarray:
    return q[..., [1, 2, 3, 0]]


def _keyed(blob: AccessorWriter, clip: Clip, first: int) -> dict:
    """The clip key for key: each bone's node rotation ``L_i`` and translation
    ``a_i - a_p + D_i`` with the bone's own channel interpolation (no stretch, no twist:
    the node hierarchy is then exactly the clip's forward kinematics)."""
    sk = clip.skeleton
    A = sk.A
    rest = A - np.where(sk.parents[:, None] >= 0, A[np.maximum(sk.parents, 0)], 0.0)
    T = clip.times
    t0 = T - min(T[0], 0.0)            # glTF times are >= 0
    single = T.size == 1
    t_acc = blob.add(t0, FLOAT, "SCALAR", minmax=True)
    samplers, channels = [], []
    rmodes, dmodes = clip.rotation_interpolation, clip.offset_interpolation
    for i in range(sk.n_bones):
        for path, mode, vals, tan in (
                ("rotation", rmodes[i], _xyzw(clip.quaternions[:, i]),
                 clip.rotation_tangents),
                ("translation", dmodes[i], rest[i] + clip.offsets[:, i], clip.offset_tangents)):
            if single:
                mode = "linear"
            if mode == "cubic":
                tin, tout = (x[:, i] for x in tan)
                if path == "rotation":
                    tin, tout = _xyzw(tin), _xyzw(tout)
                vals = np.stack([tin, vals, tout], axis=1).reshape(-1, vals.shape[-1])
            samplers.append({"input": t_acc, "interpolation": _GLTF_MODE[mode],
                             "output": blob.add(vals, FLOAT, "VEC4" if path == "rotation"
                                                else "VEC3")})
            channels.append({"sampler": len(samplers) - 1,
                             "target": {"node": first + i, "path": path}})
    return {"name": "clip", "samplers": samplers, "channels": channels}


def _sampled(blob: AccessorWriter, clip: Clip, first: int) -> dict:
    """The clip sampled at its fps: each bone's world rotation and posed start as node
    rotations and translations in its parent bone's frame, LINEAR."""
    sk = clip.skeleton
    times = clip.sample_times()
    R, O, _, _ = clip.arrays(times)
    t_acc = blob.add(times - times[0], FLOAT, "SCALAR", minmax=True)
    local_R, local_t = local_transforms(sk, R, O)
    quat = _xyzw(tf.matrix_to_quat(local_R))
    # keep consecutive keys on the same hemisphere so viewers slerp the short way
    for k in range(1, len(times)):
        flip = (quat[k] * quat[k - 1]).sum(axis=1) < 0
        quat[k, flip] *= -1
    samplers, channels = [], []
    for i in range(sk.n_bones):
        for path_, vals, typ in (("rotation", quat[:, i], "VEC4"),
                                 ("translation", local_t[:, i], "VEC3")):
            samplers.append({"input": t_acc, "interpolation": "LINEAR",
                             "output": blob.add(vals, FLOAT, typ)})
            channels.append({"sampler": len(samplers) - 1,
                             "target": {"node": first + i, "path": path_}})
    return {"name": "clip", "samplers": samplers, "channels": channels}


def write_gltf(path: str | os.PathLike, rig: Rig, clip: Clip | None = None,
               bake: str | None = None, *, frames=None, times=None) -> None:
    """Write a 3D rig as glTF 2.0 (``.glb``, or ``.gltf`` with its buffer embedded).

    Parameters
    ----------
    path : str or os.PathLike
        Destination ending in ``.glb`` or ``.gltf``; written atomically.
    rig : Rig
        3D, with triangles (or tetrahedra, whose boundary is written).
    clip : Clip, optional
        An animation of the rig's skeleton: written as joint rotations and
        translations (see the module docs); with ``frames``, the default of ``times``.
    bake : {"lbs", "dqs", "stbs-lbs", "stbs-dqs"}, optional
        The method that computed ``frames``, or that skins ``clip`` at ``times`` when
        ``frames`` is not given: they are written as morph targets played by a
        ``weights`` animation (then the joints stay at rest). :func:`stbs.bake.export`
        is the pipeline that bakes (with its limits and progress) and calls this.
    frames : sequence of (n, 3) float, keyword-only
        With ``bake``: the deformed positions, one mesh per time.
    times : (k,) float, keyword-only, optional
        The frames' times in seconds (default ``clip.sample_times()``).

    Raises
    ------
    ValueError
        A 2D rig, no triangles, a clip of another skeleton, ``bake`` naming no method,
        ``bake`` with neither frames nor clip, frames of another shape or count, a path
        of another extension.
    """
    suffix(path, GLTF_EXTENSIONS, "write_gltf")
    if not isinstance(rig, Rig):
        raise TypeError(f"rig must be a stbs.Rig, got {type(rig).__name__}")
    if rig.dim != 3:
        raise ValueError(f"glTF holds 3D rigs; got a {rig.dim}D rig")
    clip = _check_clip(clip, rig)
    baked = _check_frames(rig, clip, bake, frames, times) if bake is not None or \
        frames is not None else None
    F = rig.F if rig.F is not None else (boundary_faces(rig.T, rig.V)
                                         if rig.T is not None else None)
    if F is None or len(F) == 0:
        raise ValueError("write_gltf needs triangles (rig.F) or tetrahedra (rig.T)")
    V = np.asarray(rig.V, dtype=np.float64)
    blob = AccessorWriter()
    attrs = {"POSITION": blob.add(V, FLOAT, "VEC3", target=ARRAY_BUFFER, minmax=True),
             "NORMAL": blob.add(vertex_normals(V, F), FLOAT, "VEC3", target=ARRAY_BUFFER)}
    attrs.update(skin_attributes(blob, rig.W, rig.E, rig.skeleton.n_bones))
    prim: dict[str, Any] = {"attributes": attrs, "mode": 4,
                            "indices": blob.add(np.asarray(F).ravel(), UINT, "SCALAR",
                                                target=ELEMENT_ARRAY_BUFFER)}
    mesh: dict[str, Any] = {"name": "mesh", "primitives": [prim]}
    nodes, skin = _joint_nodes(blob, rig.skeleton)
    first = len(nodes) - rig.skeleton.n_bones
    animations = []
    if baked is not None:
        animations.append(_morph_frames(blob, mesh, V, *baked, method=bake))
    elif clip is not None:
        rigid = bool(np.all(clip.stretch == 1) and not np.any(clip.twist))
        animations.append(_keyed(blob, clip, first) if rigid else _sampled(blob, clip, first))
    doc: dict[str, Any] = {
        "asset": {"version": "2.0", "generator": "stbs"},
        "scene": 0, "scenes": [{"nodes": [0, 1]}],
        "nodes": nodes, "meshes": [mesh], "skins": [skin],
        "accessors": blob.accessors, "bufferViews": blob.views,
    }
    if animations:
        doc["animations"] = animations
    save_gltf_document(path, doc, blob.blob())


def _check_frames(rig: Rig, clip: Clip | None, bake, frames, times):
    """``(times, frames)`` checked: ``bake`` names a method, one (n, 3) mesh per time."""
    if bake not in SKINNING_METHODS:
        what = "frames need bake=: the method that computed them" if bake is None else \
            f"bake must be one of {', '.join(SKINNING_METHODS)}, got {bake!r}"
        raise ValueError(what)
    if times is None:
        if clip is None:
            raise ValueError("bake needs a clip or times=: when the frames are")
        times = clip.sample_times()
    times = np.asarray(times, dtype=np.float64).reshape(-1)
    if times.size == 0 or not np.all(np.isfinite(times)) or np.any(np.diff(times) <= 0):
        raise ValueError(f"times must be finite and increasing, one per frame, got {times!r}")
    if frames is None:
        if clip is None:
            raise ValueError(f"bake={bake!r} without frames= needs a clip: the animation "
                             f"to bake")
        frames = skinned_frames(rig, clip, times, bake)
    if len(frames) != times.size:
        raise ValueError(f"frames must hold one mesh per time ({times.size}), "
                         f"got {len(frames)}")
    return times, frames


def _joint_nodes(blob: AccessorWriter, sk) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """The scene's nodes (root ``"stbs"``, the mesh, then bone i's joint node at ``a_i``
    under its parent bone's node) and the skin over the joint nodes."""
    A, b = sk.A, sk.n_bones
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
    joints = list(range(first, first + b))
    skin = {"name": "stbs", "joints": joints, "skeleton": 0,
            "inverseBindMatrices": blob.add(IBM.transpose(0, 2, 1).reshape(b, 16), FLOAT,
                                            "MAT4"),
            "extras": {TABLE_KEY: bone_table(sk, joints)}}
    return nodes, skin


def _morph_frames(blob: AccessorWriter, mesh: dict, V: np.ndarray, times: np.ndarray,
                  frames, *, method: str) -> dict:
    """Frame k as morph target k (its displacement from ``V``) and the animation that
    shows it alone at ``times[k]``."""
    t_acc = blob.add(times - times[0], FLOAT, "SCALAR", minmax=True)
    targets = []
    for U in frames:
        U = np.asarray(U, dtype=np.float64)
        if U.shape != V.shape:
            raise ValueError(f"frames: each must have shape {V.shape}, got {U.shape}")
        targets.append({"POSITION": blob.add(U - V, FLOAT, "VEC3", target=ARRAY_BUFFER,
                                             minmax=True)})
    mesh["primitives"][0]["targets"] = targets
    k = len(targets)
    mesh["weights"] = [0.0] * k
    mesh["extras"] = {"targetNames": [f"frame_{j}" for j in range(k)]}
    onehot = np.eye(k, dtype=np.float32).reshape(-1)
    return {"name": f"baked {method}",
            "samplers": [{"input": t_acc, "interpolation": "LINEAR",
                          "output": blob.add(onehot, FLOAT, "SCALAR")}],
            "channels": [{"sampler": 0, "target": {"node": 1, "path": "weights"}}]}
