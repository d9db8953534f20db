"""The valid files the fuzz suite mutates, made from the shared data with the library.

- glTF characters: ``SimpleSkin.gltf`` (buffers in a data URI), ``RiggedSimple.glb``
  and ``CesiumMan.glb`` (small GLBs), ``RiggedFigure.glb`` (a humanoid, the rig that
  BVH captures are retargeted onto); and as stbs writes glTF: SimpleSkin written back
  with endpoint weights and its bone table, and exported afresh with a keyed clip;
- BVH captures cut to their first frames (cheap cases): CMU ``131_01`` and two walks;
- a pose and a clip of SimpleSkin's skeleton written by :func:`stbs.io.write_pose` and
  :func:`stbs.io.write_clip` (both pose forms), and a pose by bone index that fits any
  rig;
- a manifest of two jobs (a clip and a capture) for ``stbs animate --manifest``.
"""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path

import numpy as np

GLTF = {"SimpleSkin.gltf": "gltf/SimpleSkin.gltf", "RiggedSimple.glb": "gltf/RiggedSimple.glb",
        "CesiumMan.glb": "characters/gltf/CesiumMan.glb",
        "RiggedFigure.glb": "characters/gltf/RiggedFigure.glb"}
BVH = {"cmu.bvh": "bvh11-cmu/131_01.bvh",
       "walk.bvh": "characters/bvh/dataset-1_walk_normal_002.bvh",
       "walk60.bvh": "characters/bvh/games105_walk60.bvh"}
#: A pose by bone index: it fits every rig with a bone.
ANY_POSE = {"rotate": {"0": {"axis": [0, 0, 1], "angle": 30}}, "stretch": {"0": 1.25},
            "twist": {"0": [0, 45]}}


def cut_bvh(text: str, frames: int) -> str:
    """A BVH capture cut to its first ``frames`` frames."""
    lines = text.splitlines()
    m = next(k for k, s in enumerate(lines) if s.strip().upper().startswith("MOTION"))
    rest = lines[m + 1:]
    head = rest[:2]
    body = [s for s in rest[2:] if s.strip()][:frames]
    return "\n".join(lines[:m + 1] + [f"Frames: {frames}", head[1]] + body) + "\n"


def build(data: Path) -> dict[str, bytes]:
    """name -> bytes of every seed (see the module docs)."""
    import stbs
    from stbs import io

    out = {name: (data / rel).read_bytes() for name, rel in GLTF.items()}
    for name, rel in BVH.items():
        out[name] = cut_bvh((data / rel).read_text(), 5).encode()
    rig = io.read_rig(data / GLTF["SimpleSkin.gltf"])
    sk = rig.skeleton
    turn = np.array([[np.cos(0.6), -np.sin(0.6), 0], [np.sin(0.6), np.cos(0.6), 0], [0, 0, 1]])
    pose = stbs.forward_kinematics(sk, rotations=np.stack([turn] * sk.n_bones),
                                   stretch=np.full(sk.n_bones, 1.2),
                                   twist=np.radians(np.arange(len(sk.C)) * 15.0))
    clip = stbs.Clip([(0.0, stbs.Pose.rest(sk)), (0.1, pose), (0.2, stbs.Pose.rest(sk))],
                     fps=30)
    with tempfile.TemporaryDirectory() as tmp:
        for name, write in (("pose.json", lambda p: io.write_pose(p, pose)),
                            ("pose-joints.json", lambda p: io.write_pose(p, pose,
                                                                         form="joints")),
                            ("clip.json", lambda p: io.write_clip(p, clip))):
            p = os.path.join(tmp, name)
            write(p)
            out[name] = Path(p).read_bytes()
    # glTF files as stbs writes them: a character written back with its endpoint weights
    # and bone table, and a rig exported afresh with a keyed clip
    from stbs.weights.endpoint import projection

    with tempfile.TemporaryDirectory() as tmp:
        for name, make in (
                ("SimpleSkin-stbs.gltf", lambda p: io.write_rig(
                    p, rig.replace(E=projection(rig.V, sk)),
                    source=data / GLTF["SimpleSkin.gltf"])),
                ("exported.glb", lambda p: io.write_gltf(p, rig, clip))):
            p = os.path.join(tmp, name)
            make(p)
            out[name] = Path(p).read_bytes()
    out["any-pose.json"] = json.dumps(ANY_POSE).encode()
    # a rig whose vertices each have six bones (the skinning kernels' other form, which
    # the worker's warm-up compiles), and a clip of its skeleton
    wide = io.read_rig(data / GLTF["CesiumMan.glb"])
    W = np.asarray(wide.W) + 0.01 * (np.arange(wide.skeleton.n_bones) < 6)
    wide = wide.replace(W=W / W.sum(axis=1, keepdims=True), E=None, meta={})
    wide = wide.replace(E=projection(wide.V, wide.skeleton))
    turn = stbs.forward_kinematics(wide.skeleton, stretch=np.full(wide.skeleton.n_bones, 1.1))
    with tempfile.TemporaryDirectory() as tmp:
        for name, write in (("wide.npz", lambda p: io.save_rig(p, wide)),
                            ("wide-clip.json", lambda p: io.write_clip(p, stbs.Clip(
                                [(0.0, stbs.Pose.rest(wide.skeleton)), (0.1, turn)])))):
            p = os.path.join(tmp, name)
            write(p)
            out[name] = Path(p).read_bytes()
    out["manifest.json"] = json.dumps(manifest()).encode()
    return out


def manifest(folder: str = "") -> list[dict]:
    """The seed manifest; its paths relative to the manifest, in ``folder``."""
    return [{"rig": folder + "SimpleSkin.gltf", "motion": folder + "clip.json",
             "output": "clip.npz", "method": "lbs"},
            {"rig": folder + "RiggedFigure.glb", "motion": folder + "walk.bvh",
             "output": "walk.npz", "method": "stbs-dqs", "frames": "0:3"}]


def warmups() -> list[tuple[list[str], dict[str, bytes]]]:
    """Runs that load what the cases need (numba's kernels, lazy imports) into the
    worker once: (argv, files of its folder)."""
    runs = [
        ["weights", "{seeds}/SimpleSkin.gltf", "--endpoint", "projection", "-o", "o.gltf"],
        ["weights", "{seeds}/CesiumMan.glb", "--endpoint", "projection", "-o", "o.glb"],
        ["export", "{seeds}/RiggedSimple.glb", "-o", "o.glb"],
        ["animate", "{seeds}/SimpleSkin.gltf", "--motion", "{seeds}/SimpleSkin.gltf", "-o",
         "o.npz"],
        ["animate", "{seeds}/SimpleSkin.gltf", "--motion", "{seeds}/clip.json", "-o",
         "o.glb"],
        ["animate", "{seeds}/RiggedFigure.glb", "--motion", "{seeds}/walk.bvh", "-o",
         "o.npz"],
        ["animate", "{seeds}/RiggedFigure.glb", "--motion", "{seeds}/cmu.bvh", "-o",
         "o.json"],
    ]
    for method in ("lbs", "dqs", "stbs-lbs", "stbs-dqs"):     # each kernel, each form
        runs += [["deform", "{seeds}/SimpleSkin.gltf", "--pose", "{seeds}/pose.json",
                  "--method", method, "-o", "o.npz"],
                 ["deform", "{seeds}/wide.npz", "--pose", "{seeds}/any-pose.json",
                  "--method", method, "-o", "o.npz"],
                 ["animate", "{seeds}/SimpleSkin.gltf", "--motion", "{seeds}/clip.json",
                  "--method", method, "-o", "o.npz"],
                 ["animate", "{seeds}/wide.npz", "--motion", "{seeds}/wide-clip.json",
                  "--method", method, "-o", "o.npz"]]
    out = [(argv, {}) for argv in runs]
    out.append((["animate", "--manifest", "manifest.json"],
                {"manifest.json": json.dumps(manifest("{seeds}/")).encode()}))
    return out
