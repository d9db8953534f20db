"""glTF 2.0 in: stbs.io.read_gltf. Our lbs skinning of the imported rig at every keyframe
equals the glTF skinning formula evaluated directly from what the file holds."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
from gltf_files import (
    UBYTE,
    USHORT,
    Builder,
    local_matrices,
    node_globals,
    quat_xyzw,
    skin_formula,
    write,
)

import stbs
from stbs.io import FormatError, read_gltf

NODES = [
    {"name": "Armature", "scale": [0.5, 0.5, 0.5], "rotation": quat_xyzw([1, 0, 0], 30),
     "children": [1, 5]},
    {"name": "hips", "translation": [0, 1, 0], "children": [2, 3, 4]},
    {"name": "spine", "translation": [0, 1, 0], "children": [6]},
    {"name": "leg_l", "translation": [0.3, -0.5, 0]},
    {"name": "leg_r", "translation": [-0.3, -0.5, 0]},
    {"name": "prop", "translation": [2, 0, 0]},                 # a second hierarchy
    {"name": "chest", "translation": [0, 1, 0], "rotation": quat_xyzw([0, 0, 1], 20),
     "children": [8, 9, 10]},
    {"name": "body", "mesh": 0, "skin": 0, "translation": [5, 5, 5]},   # ignored
    {"name": "arm_l", "translation": [0.5, 0.1, 0]},
    {"name": "neck", "translation": [0, 0.6, 0], "scale": [2, 2, 2]},  # a scaled joint
    {"name": "arm_r", "translation": [-0.5, 0.1, 0]},
]
JOINTS = [1, 2, 3, 4, 5, 6, 8, 9, 10]


def _bind_globals():
    """Bind pose: the node transforms but with the chest unturned (so the rest pose must
    come from the inverse bind matrices, not from the nodes)."""
    nodes = json.loads(json.dumps(NODES))
    nodes[6].pop("rotation")
    return node_globals(nodes, local_matrices(nodes))


def _scene(tmp_path, *, glb=True, name="scene", extra_anims=()):
    rng = np.random.default_rng(7)
    Gb = _bind_globals()
    IBM = np.array([np.linalg.inv(Gb[j]) for j in JOINTS])
    P = np.array([Gb[j][:3, 3] for j in JOINTS])
    # vertices scattered around the bind joints, two primitives
    V = np.repeat(P, 7, axis=0) + 0.08 * rng.standard_normal((7 * len(P), 3))
    V0, V1 = V[:40], V[40:]
    n0, n1 = len(V0), len(V1)
    J0 = rng.integers(0, len(JOINTS), (n0, 4))
    W0 = rng.uniform(0.05, 1, (n0, 4))
    J1 = rng.integers(0, len(JOINTS), (n0, 4))
    W1 = rng.uniform(0, 0.5, (n0, 4))
    # quantised and unnormalised: 8-bit weights in set 0, 16-bit in set 1
    qW0 = np.round(W0 / W0.sum(1, keepdims=True) * 200).astype(np.uint8)
    qW1 = np.round(W1 / (W0.sum(1, keepdims=True) + W1.sum(1, keepdims=True)) * 30000
                   ).astype(np.uint16)
    Jp1 = rng.integers(0, len(JOINTS), (n1, 4))
    Wp1 = rng.uniform(0, 1, (n1, 4)).astype(np.float32)
    b = Builder()
    F0 = np.array([[i, i + 1, i + 2] for i in range(0, n0 - 2, 3)])
    prims = [
        {"attributes": {"POSITION": b.add(V0, stride=16), "JOINTS_0": b.add(J0, UBYTE),
                        "WEIGHTS_0": b.add(qW0, UBYTE, normalized=True),
                        "JOINTS_1": b.add(J1, USHORT),
                        "WEIGHTS_1": b.add(qW1, USHORT, normalized=True)},
         "indices": b.add(F0.ravel(), USHORT)},
        {"attributes": {"POSITION": b.add(V1), "JOINTS_0": b.add(Jp1, USHORT),
                        "WEIGHTS_0": b.add(Wp1)}, "mode": 5},    # a strip, no indices
    ]
    ibm = b.add(IBM.transpose(0, 2, 1).reshape(len(JOINTS), 16), mat4=True)
    anims = []
    # LINEAR, keys starting after 0; the non-joint Armature turns too; head scale constant
    t = b.add(np.array([0.5, 1.0, 1.5]))
    ch = {("hips", "translation"): [[0, 1, 0], [0.3, 1.2, 0], [0.1, 0.9, 0.4]],
          ("spine", "rotation"): [quat_xyzw([0, 0, 1], a) for a in (0, 40, -30)],
          ("chest", "rotation"): [quat_xyzw([0, 1, 1], a) for a in (20, 90, 170)],
          ("leg_l", "rotation"): [quat_xyzw([1, 0, 0], a) for a in (0, -60, 30)],
          ("neck", "scale"): [[2, 2, 2]] * 3,
          ("prop", "translation"): [[2, 0, 0], [2, 1, 0], [1, 1, 1]],
          ("Armature", "rotation"): [quat_xyzw([1, 0, 0], a) for a in (30, 45, 10)]}
    anims.append(_anim("wave", b, t, ch, "LINEAR"))
    # CUBICSPLINE with tangents
    t = b.add(np.array([0.0, 1.0, 2.0]))
    q = [quat_xyzw([0, 0, 1], a) for a in (0, 50, -20)]
    cub = {("spine", "rotation"): [x for v in q for x in ([0.1, 0, 0, 0], v, [0, 0.2, 0, 0])],
           ("hips", "translation"): [x for v in ([0, 1, 0], [1, 1, 0], [0, 2, 0])
                                     for x in ([1, 0, 0], v, [0, 1, 0])]}
    anims.append(_anim("cubic", b, t, cub, "CUBICSPLINE"))
    t = b.add(np.array([0.0, 0.3]))
    anims.append(_anim("step", b, t, {("leg_r", "rotation"): [quat_xyzw([1, 0, 0], a)
                                                               for a in (0, 80)]}, "STEP"))
    for a in extra_anims:
        anims.append(a(b))
    doc = {"scene": 0, "scenes": [{"nodes": [0, 7]}], "nodes": NODES,
           "meshes": [{"name": "body", "primitives": prims}],
           "skins": [{"joints": JOINTS, "inverseBindMatrices": ibm, "name": "rig"}],
           "animations": anims}
    path = write(tmp_path / f"{name}.{'glb' if glb else 'gltf'}", doc, b, glb=glb)
    sets = [(np.vstack([J0, Jp1]), np.vstack([qW0 / 255.0, Wp1])),
            (np.vstack([J1, np.zeros((n1, 4), int)]), np.vstack([qW1 / 65535.0,
                                                                  np.zeros((n1, 4))]))]
    return path, {"V": V, "F0": F0, "IBM": IBM, "P": P, "sets": sets, "doc": doc, "ch": ch,
                  "cub": cub}


def _anim(name, b, t, channels, mode):
    samplers, chans = [], []
    names = [n["name"] for n in NODES]
    for (node, path), values in channels.items():
        samplers.append({"input": t, "output": b.add(np.array(values, float)),
                         "interpolation": mode})
        chans.append({"sampler": len(samplers) - 1,
                      "target": {"node": names.index(node), "path": path}})
    return {"name": name, "samplers": samplers, "channels": chans}


def _reference(ctx, anim_name, k):
    """The glTF formula at key k of an animation: channel values read as written."""
    names = [n["name"] for n in NODES]
    chans = {"wave": ctx["ch"], "cubic": ctx["cub"]}.get(anim_name)
    over: dict = {}
    if anim_name == "step":
        chans = {("leg_r", "rotation"): [quat_xyzw([1, 0, 0], a) for a in (0, 80)]}
    for (node, path), values in chans.items():
        v = values[3 * k + 1] if anim_name == "cubic" else values[k]
        over.setdefault(names.index(node), {})[path] = v
    G = node_globals(NODES, local_matrices(NODES, over))
    return skin_formula(ctx["V"], ctx["sets"], G, JOINTS, ctx["IBM"])


@pytest.mark.parametrize("glb", [True, False])
def test_every_keyframe_skins_as_the_file_says(tmp_path, glb):
    path, ctx = _scene(tmp_path, glb=glb)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        rig, clips = read_gltf(path)
    assert list(clips) == ["wave", "cubic", "step"]
    np.testing.assert_array_equal(rig.V, ctx["V"].astype(np.float32).astype(float))
    diag = np.linalg.norm(np.ptp(rig.V, axis=0))
    for name, times in (("wave", [0.5, 1.0, 1.5]), ("cubic", [0, 1, 2]), ("step", [0, 0.3])):
        clip = clips[name]
        np.testing.assert_allclose(clip.times, times, atol=1e-7)
        for k, (_, pose) in enumerate(clip.keys):
            U = stbs.deform(rig.V, rig.skeleton, pose, rig.W, method="lbs")
            ref = _reference(ctx, name, k)
            assert np.abs(U - ref).max() <= 1e-5 * diag, (name, k, np.abs(U - ref).max())
        # before the first key (the wave starts at 0.5) the clip holds the first pose
        assert clip.pose(0.0).origins.tolist() == clip.keys[0][1].origins.tolist()


def test_the_rig_structure(tmp_path):
    path, ctx = _scene(tmp_path)
    rig, _ = read_gltf(path)
    sk = rig.skeleton
    assert sk.names == ["hips", "spine", "leg_l", "leg_r", "prop", "chest", "arm_l", "neck",
                        "arm_r"]
    # joints at the bind positions of the inverse bind matrices (not the node rest pose,
    # whose chest is turned by 20 degrees)
    np.testing.assert_allclose(sk.C[:9], ctx["P"], atol=1e-6)
    j = {n: i for i, n in enumerate(sk.names)}
    # hips (a root joint with three children): the first child, spine
    assert sk.BE[j["hips"], 1] == j["spine"]
    # chest: the child that continues spine -> chest best, the neck (listed second)
    assert sk.BE[j["chest"], 1] == j["neck"]
    # a leaf: half its parent bone further on
    spine_to_chest = ctx["P"][5] - ctx["P"][1]
    np.testing.assert_allclose(sk.C[sk.BE[j["arm_l"], 1]] - ctx["P"][6],
                               0.5 * (ctx["P"][6] - ctx["P"][5]), atol=1e-6)
    assert np.linalg.norm(spine_to_chest) > 0
    # primitives concatenated: the strip's triangles come after the indexed ones
    n0 = 40
    np.testing.assert_array_equal(rig.F[:len(ctx["F0"])], ctx["F0"])
    strip = rig.F[len(ctx["F0"]):]
    assert strip.min() == n0 and len(strip) == len(rig.V) - n0 - 2
    np.testing.assert_array_equal(strip[1], [n0 + 1, n0 + 3, n0 + 2])   # winding alternates
    np.testing.assert_allclose(rig.W.sum(axis=1), 1)
    assert rig.meta["gltf"]["joints"] == JOINTS and rig.meta["gltf"]["node"] == 7


def test_an_animated_non_uniform_scale_is_dropped_with_a_warning(tmp_path):
    def squash(b):
        t = b.add(np.array([0.0, 1.0]))
        return _anim("squash", b, t, {("spine", "scale"): [[1, 1, 1], [1, 2, 1]]}, "LINEAR")

    path, _ = _scene(tmp_path, extra_anims=[squash])
    with pytest.warns(UserWarning, match="animation 3 scales joints .* the scale is dropped"):
        _, clips = read_gltf(path)
    assert "squash" in clips


def test_the_shared_files(shared_data):
    for name, n, b in (("RiggedSimple.glb", 160, 2), ("SimpleSkin.gltf", 10, 2)):
        rig, clips = read_gltf(shared_data / "gltf" / name)
        assert rig.V.shape == (n, 3) and rig.skeleton.n_bones == b and len(clips) == 1
        clip = next(iter(clips.values()))
        diag = np.linalg.norm(np.ptp(rig.V, axis=0))
        moved = 0.0
        for _, pose in clip.keys:
            U = stbs.deform(rig.V, rig.skeleton, pose, rig.W, method="lbs")
            assert np.isfinite(U).all() and np.ptp(U, axis=0).max() < 10 * diag
            moved = max(moved, np.abs(U - rig.V).max())
        assert moved > 0.05 * diag


def test_simple_skin_against_its_own_numbers(shared_data):
    # SimpleSkin (Khronos): joint 1 turns about z by the key's quaternion; vertices
    # with weight on it turn about (0, 1, 0). At the key of 90 degrees... the file's
    # output at key 2 is (0, 0, 0.707, 0.707): a quarter turn.
    rig, clips = read_gltf(shared_data / "gltf" / "SimpleSkin.gltf")
    clip = clips["animation_0"]
    doc = json.loads((shared_data / "gltf" / "SimpleSkin.gltf").read_text())
    assert len(clip.keys) == doc["accessors"][5]["count"]
    R = clip.keys[2][1].rotations[1]
    np.testing.assert_allclose(R, [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-3)


@pytest.mark.parametrize("damage, match", [
    (lambda d, p: p.write_bytes(p.read_bytes()[:200]), "glTF"),
    (lambda d, p: p.write_bytes(b"not a gltf at all"), "glTF"),
])
def test_broken_files(tmp_path, damage, match):
    path, _ = _scene(tmp_path)
    damage(None, path)
    with pytest.raises(FormatError, match=match):
        read_gltf(path)


def _edit(tmp_path, fn):
    path, ctx = _scene(tmp_path, glb=False)
    doc = json.loads(path.read_text())
    fn(doc)
    path.write_text(json.dumps(doc))
    return path


@pytest.mark.parametrize("fn, match", [
    (lambda d: d.pop("skins"), "expected a skin"),
    (lambda d: d["nodes"][7].pop("skin"), "a node with both a mesh and a skin"),
    (lambda d: d["accessors"][0].update(count=10_000), r"out of range"),
    (lambda d: d["meshes"][0]["primitives"][0]["attributes"].update(POSITION=999),
     r"an accessor index in 0\.\."),
    (lambda d: d["meshes"][0]["primitives"][1].update(mode=1), "points or lines"),
    (lambda d: d["skins"][0].update(joints=[1, 2, 99]), "joint node indices"),
])
def test_bad_content_is_one_clear_error(tmp_path, fn, match):
    with pytest.raises((FormatError, ValueError), match=match):
        read_gltf(_edit(tmp_path, fn))


def test_several_skinned_meshes_are_listed(tmp_path):
    def two(d):
        d["nodes"].append({"name": "body2", "mesh": 0, "skin": 0})
        d["scenes"][0]["nodes"].append(len(d["nodes"]) - 1)

    path = _edit(tmp_path, two)
    with pytest.warns(UserWarning, match="2 skinned meshes, reading the first"):
        read_gltf(path)
    rig, _ = read_gltf(path, mesh="body2")
    assert rig.meta["gltf"]["node"] == 11
    with pytest.raises(ValueError, match="no skinned mesh matches mesh='x'"):
        read_gltf(path, mesh="x")


def test_a_missing_file(tmp_path):
    with pytest.raises(FileNotFoundError):
        read_gltf(tmp_path / "none.glb")


# ---------------------------------------------------------------- the shared files
def _raw_gltf(path):
    """(JSON, buffers) of a .glb or a .gltf with data: URIs, read without stbs."""
    import base64
    import struct

    data = path.read_bytes()
    if path.suffix == ".glb":
        n = struct.unpack_from("<I", data, 12)[0]
        doc = json.loads(data[20:20 + n])
        m = struct.unpack_from("<I", data, 20 + n)[0]
        return doc, [data[28 + n:28 + n + m]]
    doc = json.loads(data)
    return doc, [base64.b64decode(b["uri"].split(",", 1)[1]) for b in doc["buffers"]]


def _raw_accessor(doc, bufs, i):
    a = doc["accessors"][i]
    bv = doc["bufferViews"][a["bufferView"]]
    dt = {5126: "<f4", 5123: "<u2", 5121: "u1"}[a["componentType"]]
    nc = {"SCALAR": 1, "VEC3": 3, "VEC4": 4, "MAT4": 16}[a["type"]]
    item = np.dtype(dt).itemsize
    stride = bv.get("byteStride", nc * item)
    start = bv.get("byteOffset", 0) + a.get("byteOffset", 0)
    rows = [np.frombuffer(bufs[bv["buffer"]], dtype=dt, count=nc, offset=start + k * stride)
            for k in range(a["count"])]
    x = np.array(rows, dtype=float)
    if a.get("normalized"):
        x /= {"<u2": 65535.0, "u1": 255.0}[dt]
    return x


@pytest.mark.parametrize("name", ["RiggedSimple.glb", "SimpleSkin.gltf"])
def test_the_shared_files_skin_as_the_formula_says(shared_data, name):
    path = shared_data / "gltf" / name
    doc, bufs = _raw_gltf(path)
    nodes = doc["nodes"]
    node = next(k for k, n in enumerate(nodes) if "skin" in n)
    skin = doc["skins"][nodes[node]["skin"]]
    prim = doc["meshes"][nodes[node]["mesh"]]["primitives"][0]
    V = _raw_accessor(doc, bufs, prim["attributes"]["POSITION"])
    J = _raw_accessor(doc, bufs, prim["attributes"]["JOINTS_0"]).astype(int)
    Wt = _raw_accessor(doc, bufs, prim["attributes"]["WEIGHTS_0"])
    IBM = _raw_accessor(doc, bufs, skin["inverseBindMatrices"]).reshape(-1, 4, 4)
    IBM = IBM.transpose(0, 2, 1)
    anim = doc["animations"][0]
    rig, clips = read_gltf(path)
    clip = next(iter(clips.values()))
    diag = float(np.linalg.norm(np.ptp(V, axis=0)))
    for k, (t, pose) in enumerate(clip.keys):
        over: dict = {}
        for ch in anim["channels"]:
            s = anim["samplers"][ch["sampler"]]
            times = _raw_accessor(doc, bufs, s["input"])[:, 0]
            assert abs(times[k] - t) < 1e-6            # every channel keyed at the same times
            over.setdefault(ch["target"]["node"], {})[ch["target"]["path"]] = \
                _raw_accessor(doc, bufs, s["output"])[k]
        G = node_globals(nodes, local_matrices(nodes, over))
        ref = skin_formula(V, [(J, Wt)], G, skin["joints"], IBM)
        U = stbs.deform(rig.V, rig.skeleton, pose, rig.W, method="lbs")
        assert np.abs(U - ref).max() <= 1e-5 * diag, (k, np.abs(U - ref).max())
    assert len(clip.keys) == doc["accessors"][anim["samplers"][0]["input"]]["count"]
