"""glTF 2.0 in: stbs.io.read_gltf on files written by hand. Our lbs skinning of the
imported rig equals the glTF skinning formula, evaluated by an independent reader of the
file's bytes (gltf_files.Reference), at every key and between keys: LINEAR slerps,
STEP, CUBICSPLINE pieces split by other channels' keys, translations of child joints,
a non-joint node between two joints, several meshes and skins over one skeleton."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
from gltf_files import (
    UBYTE,
    USHORT,
    Builder,
    Reference,
    local_matrices,
    node_globals,
    quat_xyzw,
    write,
)

import stbs
from stbs.io import FormatError, read_gltf, read_rig

NODES = [
    {"name": "Armature", "scale": [0.5, 0.5, 0.5], "rotation": quat_xyzw([1, 0, 0], 30),
     "children": [1, 5]},
    {"name": "hips", "translation": [0, 1, 0], "children": [2, 3, 4]},
    {"name": "spine", "translation": [0, 1, 0], "children": [6]},
    {"name": "leg_l", "translation": [0.3, -0.5, 0]},
    {"name": "leg_r", "translation": [-0.3, -0.5, 0]},
    {"name": "prop", "translation": [2, 0, 0]},                 # a second joint tree
    {"name": "chest", "translation": [0, 1, 0], "rotation": quat_xyzw([0, 0, 1], 20),
     "children": [8, 11, 10]},
    {"name": "body", "mesh": 0, "skin": 0, "translation": [5, 5, 5]},   # ignored
    {"name": "arm_l", "translation": [0.5, 0.1, 0]},
    {"name": "neck", "translation": [0, 0.3, 0.1], "scale": [2, 2, 2]},  # a scaled joint
    {"name": "arm_r", "translation": [-0.5, 0.1, 0]},
    {"name": "socket", "translation": [0, 0.3, 0], "rotation": quat_xyzw([1, 1, 0], 25),
     "children": [9]},                                              # not a joint
]
JOINTS = [1, 2, 3, 4, 5, 6, 8, 9, 10]
NAMES = [n["name"] for n in NODES]


def _bind_globals():
    """Bind pose: the node transforms but with the chest unturned (so the rest pose must
    come from the inverse bind matrices, not from the nodes)."""
    nodes = json.loads(json.dumps(NODES))
    nodes[6].pop("rotation")
    return node_globals(nodes, local_matrices(nodes))


def _anim(name, b, channels):
    """channels: {(node name, path): (times, values, mode)}."""
    samplers, chans = [], []
    for (node, path), (times, values, mode) in channels.items():
        samplers.append({"input": b.add(np.array(times, float)),
                         "output": b.add(np.array(values, float)), "interpolation": mode})
        chans.append({"sampler": len(samplers) - 1,
                      "target": {"node": NAMES.index(node), "path": path}})
    return {"name": name, "samplers": samplers, "channels": chans}


def _cubic(values, rng, scale=0.5):
    """(in-tangent, value, out-tangent) triples with random tangents."""
    out = []
    for v in values:
        v = np.asarray(v, float)
        out += [scale * rng.standard_normal(v.size), v, scale * rng.standard_normal(v.size)]
    return out


ANIMS = {
    # LINEAR, keys from 0.5; the non-joint Armature turns too (folded into the roots:
    # exact at the keys only); a constant scale
    "wave": lambda rng: {
        ("hips", "translation"): ([0.5, 1, 1.5], [[0, 1, 0], [0.3, 1.2, 0], [0.1, 0.9, 0.4]],
                                  "LINEAR"),
        ("spine", "rotation"): ([0.5, 1, 1.5], [quat_xyzw([0, 0, 1], a) for a in (0, 40, -30)],
                                "LINEAR"),
        ("chest", "rotation"): ([0.5, 1, 1.5], [quat_xyzw([0, 1, 1], a) for a in (20, 90, 170)],
                                "LINEAR"),
        ("neck", "scale"): ([0.5, 1, 1.5], [[2, 2, 2]] * 3, "LINEAR"),
        ("prop", "translation"): ([0.5, 1, 1.5], [[2, 0, 0], [2, 1, 0], [1, 1, 1]], "LINEAR"),
        ("Armature", "rotation"): ([0.5, 1, 1.5], [quat_xyzw([1, 0, 0], a) for a in (30, 45, 10)],
                                   "LINEAR")},
    # CUBICSPLINE channels on different key times: each splits the others' pieces
    "cubic": lambda rng: {
        ("spine", "rotation"): ([0, 1, 2], _cubic([quat_xyzw([0, 0, 1], a) for a in (0, 50, -20)],
                                                  rng), "CUBICSPLINE"),
        ("hips", "translation"): ([0, 1, 2], _cubic([[0, 1, 0], [1, 1, 0], [0, 2, 0]], rng),
                                  "CUBICSPLINE"),
        ("leg_l", "rotation"): ([0.25, 0.7, 1.6],
                                _cubic([quat_xyzw([1, 0, 0.3], a) for a in (0, -70, 40)], rng),
                                "CUBICSPLINE"),
        ("neck", "translation"): ([0.1, 1.3], _cubic([[0, 0.3, 0.1], [0.2, 0.4, 0]], rng),
                                  "CUBICSPLINE")},
    # STEP beside LINEAR channels keyed elsewhere; a child joint's translation
    "step": lambda rng: {
        ("leg_r", "rotation"): ([0, 0.3], [quat_xyzw([1, 0, 0], a) for a in (0, 80)], "STEP"),
        ("arm_l", "translation"): ([0, 0.2, 0.45], [[0.5, 0.1, 0], [0.7, 0.3, 0], [0.4, 0, 0.2]],
                                   "STEP"),
        ("chest", "rotation"): ([0.1, 0.35], [quat_xyzw([0, 1, 0], a) for a in (0, 120)],
                                "LINEAR"),
        ("neck", "rotation"): ([0, 0.25, 0.5], [quat_xyzw([0, 1, 0.2], a) for a in (0, 200, 10)],
                               "LINEAR")},
}


def _scene(tmp_path, *, glb=True, name="scene", extra_anims=(), edit=None):
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
    anims = [_anim(nm, b, make(np.random.default_rng(k))) for k, (nm, make) in
             enumerate(ANIMS.items())]
    for a in extra_anims:
        anims.append(a(b))
    doc = {"scene": 0, "scenes": [{"nodes": [0, 7]}], "nodes": json.loads(json.dumps(NODES)),
           "meshes": [{"name": "body", "primitives": prims}],
           "skins": [{"joints": JOINTS, "inverseBindMatrices": ibm, "name": "rig"}],
           "animations": anims}
    if edit is not None:
        edit(doc, b, IBM)
    path = write(tmp_path / f"{name}.{'glb' if glb else 'gltf'}", doc, b, glb=glb)
    return path, {"V": V, "F0": F0, "IBM": IBM, "P": P}


def _times(ref, a):
    T = ref.animation_times(a)
    return np.concatenate([T, (T[1:] + T[:-1]) / 2, (3 * T[1:] + T[:-1]) / 4,
                           [T[0] - 0.1, T[-1] + 0.2]])


def _err(rig, clip, ref, a, times):
    dfm = stbs.Deformer(rig.V, rig.skeleton, rig.W, method="lbs")
    size = np.linalg.norm(np.ptp(ref.V, axis=0))
    return max(np.abs(dfm(clip.pose(float(t))) - ref.skin_at(a, float(t))).max()
               for t in times) / size


@pytest.mark.parametrize("glb", [True, False])
def test_clips_skin_as_the_file_says_at_and_between_keys(tmp_path, glb):
    path, ctx = _scene(tmp_path, glb=glb)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        rig, clips = read_gltf(path)
    assert list(clips) == ["wave", "cubic", "step"]
    np.testing.assert_array_equal(rig.V, ctx["V"].astype(np.float32).astype(float))
    ref = Reference(path)
    for a, name in enumerate(clips):
        clip = clips[name]
        T = ref.animation_times(a)
        np.testing.assert_allclose(clip.times, T, atol=1e-7)
        # at the keys: every animation, the non-joint Armature's turn included
        assert _err(rig, clip, ref, a, T) <= 1e-5, name
        if name != "wave":           # between keys: exact where no non-joint node moves
            assert _err(rig, clip, ref, a, _times(ref, a)) <= 1e-5, name
    assert clips["cubic"].rotation_interpolation[rig.skeleton.names.index("leg_l")] == "cubic"
    assert clips["step"].offset_interpolation[rig.skeleton.names.index("arm_l")] == "step"
    # the wave between its keys: the Armature's turn folded into the roots, linearly
    assert _err(rig, clips["wave"], ref, 0, _times(ref, 0)) < 0.05


def test_a_cubic_piece_split_by_other_keys_is_the_same_curve(tmp_path):
    # the cubic leg turn keyed at 0.25, 0.7, 1.6 is re-keyed at 0, 0.1, 1, 1.3, 2 too:
    # its keys there are Hermite values off the unit sphere, the curve unchanged
    path, _ = _scene(tmp_path)
    rig, clips = read_gltf(path)
    clip = clips["cubic"]
    i = rig.skeleton.names.index("leg_l")
    norms = np.linalg.norm(clip.quaternions[:, i], axis=-1)
    assert np.abs(norms - 1).max() > 1e-3
    ref = Reference(path)
    fine = np.linspace(-0.1, 2.1, 89)
    assert _err(rig, clip, ref, 1, fine) <= 1e-5


def test_the_rig_structure(tmp_path):
    path, ctx = _scene(tmp_path)
    rig, _ = read_gltf(path)
    sk = rig.skeleton
    assert sk.names == [NAMES[j] for j in JOINTS]
    # one bone per joint, starting at the bind positions of the inverse bind matrices
    # (not the node rest pose, whose chest is turned by 20 degrees)
    np.testing.assert_array_equal(sk.BE[:, 0], np.arange(len(JOINTS)))
    np.testing.assert_allclose(sk.C[:9], ctx["P"], atol=1e-6)
    # parents: the nearest joint above, across the non-joint socket (neck -> chest)
    j = {n: i for i, n in enumerate(sk.names)}
    want = {"hips": None, "spine": "hips", "leg_l": "hips", "leg_r": "hips", "prop": None,
            "chest": "spine", "arm_l": "chest", "neck": "chest", "arm_r": "chest"}
    assert {n: (sk.names[p] if p >= 0 else None) for n, p in zip(sk.names, sk.parents,
                                                                  strict=True)} == want
    # the chest continues to the neck (connected); the arms hang off it where they are
    assert sk.BE[j["chest"], 1] == j["neck"] and sk.connected[j["neck"]]
    assert not sk.connected[j["arm_l"]] and not sk.connected[j["arm_r"]]
    # primitives concatenated: the strip's triangles come after the indexed ones
    n0 = 40
    np.testing.assert_array_equal(rig.F[:len(ctx["F0"])], ctx["F0"])
    strip = rig.F[len(ctx["F0"]):]
    assert strip.min() == n0 and len(strip) == len(rig.V) - n0 - 2
    np.testing.assert_array_equal(strip[1], [n0 + 1, n0 + 3, n0 + 2])   # winding alternates
    np.testing.assert_allclose(rig.W.sum(axis=1), 1)
    g = rig.meta["gltf"]
    assert g["joints"] == JOINTS and g["skins"] == [0]
    assert [(p["node"], p["mesh"], p["primitive"], p["start"], p["count"])
            for p in g["primitives"]] == [(7, 0, 0, 0, 40), (7, 0, 1, 40, len(rig.V) - 40)]


def test_turning_a_branching_joint_by_hand(tmp_path):
    # the chest (three children, one across the socket) turned 40 degrees in its own
    # frame: FK with the equivalent local rotation, in the bind-aligned frame
    path, _ = _scene(tmp_path)
    rig, _ = read_gltf(path)
    ref = Reference(path)
    B = ref.bind_world()
    sk = rig.skeleton
    for node in (1, 6):                     # hips and chest
        axis = np.array([1.0, 2, 3]) / np.sqrt(14)
        D = stbs.transforms.axis_angle_to_matrix(axis, np.radians(40))
        Rb = B[node][:3, :3] / np.cbrt(np.linalg.det(B[node][:3, :3]))
        R = np.tile(np.eye(3), (sk.n_bones, 1, 1))
        R[JOINTS.index(node)] = Rb @ D @ Rb.T
        U = stbs.deform(rig.V, sk, stbs.forward_kinematics(sk, rotations=R), rig.W,
                        method="lbs")
        want = ref.skin_bind(turn=(node, D))
        assert np.abs(U - want).max() <= 1e-5 * np.linalg.norm(np.ptp(want, axis=0))
        assert np.abs(U - rig.V).max() > 0.05


def test_an_animated_scale_is_dropped_with_a_warning_naming_the_joint(tmp_path):
    def squash(b):
        return _anim("squash", b, {("spine", "scale"): ([0, 1], [[1, 1, 1], [1, 2, 1]],
                                                        "LINEAR")})

    path, _ = _scene(tmp_path, extra_anims=[squash])
    rig, clips = read_gltf(path)
    with pytest.warns(UserWarning, match="changes the scale of joint 'spine'.*dropped"):
        clip = clips["squash"]
    # its children still move as in the file: the chest's start follows the scale
    ref = Reference(path)
    a = list(clips).index("squash")
    U = clip.pose(1.0).origins[rig.skeleton.names.index("chest")]
    G = node_globals(ref.nodes, ref.locals_at(a, 1.0))
    np.testing.assert_allclose(U, G[6][:3, 3], atol=1e-9)


def test_meshes_sharing_a_skin_and_a_second_skin_over_the_same_joints(tmp_path):
    # three skinned nodes: the body twice (once through a second skin whose binds move
    # the mesh: each of its vertices is placed where the file's rest pose puts it)
    X = np.eye(4)
    X[:3, :3] = stbs.transforms.axis_angle_to_matrix(np.array([0, 1.0, 0]), 0.7)
    X[:3, 3] = [0.5, -0.2, 0.1]

    def more(doc, b, IBM):
        doc["nodes"] += [{"name": "body2", "mesh": 0, "skin": 0},
                         {"name": "body3", "mesh": 0, "skin": 1}]
        doc["scenes"][0]["nodes"] += [12, 13]
        doc["skins"].append({"joints": JOINTS, "inverseBindMatrices": b.add(
            (IBM @ X).transpose(0, 2, 1).reshape(len(JOINTS), 16), mat4=True)})

    path, ctx = _scene(tmp_path, edit=more)
    rig, clips = read_gltf(path)
    n = len(ctx["V"])
    assert rig.V.shape == (3 * n, 3) and rig.skeleton.n_bones == len(JOINTS)
    assert [p["node"] for p in rig.meta["gltf"]["primitives"]] == [7, 7, 12, 12, 13, 13]
    assert rig.meta["gltf"]["skins"] == [0, 1]
    ref = Reference(path)
    for a in (1, 2):
        assert _err(rig, clips[list(clips)[a]], ref, a, _times(ref, a)) <= 1e-5
    # mesh= reads one mesh alone; skin= the skeleton of a skin, every mesh bound to it
    assert len(read_gltf(path, mesh="body2")[0].V) == n
    assert len(read_gltf(path, mesh="body3")[0].V) == n
    assert len(read_gltf(path, skin=1)[0].V) == 3 * n


def test_two_skeletons_read_the_first_with_a_warning(tmp_path):
    def second(doc, b, IBM):
        doc["nodes"] += [{"name": "other_root", "translation": [9, 0, 0], "children": [13]},
                         {"name": "other_tip", "translation": [0, 1, 0]},
                         {"name": "other", "mesh": 1, "skin": 1}]
        doc["scenes"][0]["nodes"] += [12, 14]
        V = np.array([[9, 0, 0], [9.1, 1, 0], [8.9, 0.5, 0.1]], float)
        doc["meshes"].append({"name": "other", "primitives": [{"attributes": {
            "POSITION": b.add(V), "JOINTS_0": b.add(np.array([[0, 1, 0, 0]] * 3), UBYTE),
            "WEIGHTS_0": b.add(np.array([[0.5, 0.5, 0, 0]] * 3))}}]})
        doc["skins"].append({"joints": [12, 13], "name": "other_skin"})

    path, ctx = _scene(tmp_path, edit=second)
    with pytest.warns(UserWarning, match="2 skeletons; reading the one of node 7"):
        rig, _ = read_gltf(path)
    assert rig.skeleton.n_bones == len(JOINTS)
    other, _ = read_gltf(path, skin="other_skin")
    assert other.skeleton.names == ["other_root", "other_tip"] and len(other.V) == 3
    assert read_gltf(path, mesh="other")[0].skeleton.names == ["other_root", "other_tip"]
    with pytest.raises(ValueError, match="no skinned mesh matches mesh='x'"):
        read_gltf(path, mesh="x")


def test_unnamed_and_shared_joint_names(tmp_path):
    def names(doc, b, IBM):
        doc["nodes"][2].pop("name")                     # spine: unnamed
        doc["nodes"][3]["name"] = doc["nodes"][4]["name"] = "leg"

    path, _ = _scene(tmp_path, edit=names)
    sk = read_gltf(path)[0].skeleton
    assert sk.names[:4] == ["hips", "node2", "node3", "node4"]


def test_animations_are_decoded_only_when_asked(tmp_path):
    def broken(doc, b, IBM):
        doc["animations"][1]["samplers"][0]["output"] = 10_000       # out of range

    path, _ = _scene(tmp_path, edit=broken)
    rig = read_rig(path)                           # never looks at the animations
    rig2, clips = read_gltf(path)
    assert list(clips) == ["wave", "cubic", "step"] and len(clips) == 3
    assert clips["wave"].times.size == 3
    with pytest.raises(FormatError, match="an index into accessors"):
        clips["cubic"]
    assert rig.V.shape == rig2.V.shape


def test_the_shared_files(shared_data):
    for name, n, b in (("RiggedSimple.glb", 160, 2), ("SimpleSkin.gltf", 10, 2)):
        rig, clips = read_gltf(shared_data / "gltf" / name)
        assert rig.V.shape == (n, 3) and rig.skeleton.n_bones == b and len(clips) == 1


def test_simple_skin_against_its_own_numbers(shared_data):
    # SimpleSkin (Khronos): joint 1 turns about z by the key's quaternion; the file's
    # output at key 2 is (0, 0, 0.707, 0.707): a quarter turn.
    rig, clips = read_gltf(shared_data / "gltf" / "SimpleSkin.gltf")
    clip = clips["animation_0"]
    doc = json.loads((shared_data / "gltf" / "SimpleSkin.gltf").read_text())
    assert len(clip.times) == doc["accessors"][5]["count"]
    R = clip.keys[2][1].rotations[1]
    np.testing.assert_allclose(R, [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-3)


@pytest.mark.parametrize("damage, match", [
    (lambda p: p.write_bytes(p.read_bytes()[:200]), "GLB"),
    (lambda p: p.write_bytes(b"not a gltf at all"), "glTF"),
])
def test_broken_files(tmp_path, damage, match):
    path, _ = _scene(tmp_path)
    damage(path)
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
    (lambda d: d["accessors"][0].update(count=10_000), r"inside its buffer view"),
    (lambda d: d["meshes"][0]["primitives"][0]["attributes"].update(POSITION=999),
     r"an index into accessors"),
    (lambda d: d["meshes"][0].update(primitives=[dict(d["meshes"][0]["primitives"][0],
                                                      mode=1)]), "points and lines only"),
    (lambda d: d["skins"][0].update(joints=[1, 2, 99]), "joint node indices"),
    (lambda d: d["skins"][0].update(joints=[1, 2, 2]), "distinct joint nodes"),
    (lambda d: (d["nodes"][1].update(children=[2]), d["nodes"][3].update(children=[4]),
                d["nodes"][4].update(children=[3])), "a cycle through nodes"),
    (lambda d: d["nodes"][3].update(children=[6]), "node 6 a child of nodes 2 and 3"),
    (lambda d: d["asset"].update(version="1.0"), "asset.version"),
])
@pytest.mark.filterwarnings("ignore:.*points or lines")
def test_bad_content_is_one_clear_error(tmp_path, fn, match):
    with pytest.raises((FormatError, ValueError), match=match) as info:
        read_gltf(_edit(tmp_path, fn))
    assert "\n" not in str(info.value)


def test_a_missing_file(tmp_path):
    with pytest.raises(FileNotFoundError):
        read_gltf(tmp_path / "none.glb")


# ------------------------------------------------------------------ meshes hung on joints
# A box, 8 corners, 12 triangles facing out.
BOX_V = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
BOX_F = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                  [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])


def _volume(V, F):
    """Signed volume of a closed surface (> 0 when its triangles face out)."""
    return float(np.einsum("fi,fi->f", V[F[:, 0]], np.cross(V[F[:, 1]], V[F[:, 2]])).sum()
                 / 6)


def hang_parts(doc, b, IBM):
    """Meshes without a skin: a helmet on the neck through a non-joint mount (turned,
    scaled unevenly and mirrored), the same box as a glove right under arm_l, a box on
    the joint leg_l itself; a lamp under the Armature node (above every joint) and a
    table at the scene's root are props, not the character."""
    nodes = doc["nodes"]
    box = {"attributes": {"POSITION": b.add(0.1 * BOX_V)}, "indices": b.add(BOX_F.ravel(),
                                                                           USHORT)}
    leg = {"attributes": {"POSITION": b.add(0.1 * BOX_V + [0, -0.3, 0])},
           "indices": b.add(BOX_F.ravel(), USHORT)}
    doc["meshes"] += [{"name": "box", "primitives": [box]},
                      {"name": "leg", "primitives": [leg]}]
    nodes[9]["children"] = [12]                                        # neck
    nodes[3]["mesh"] = 2                                               # leg_l
    nodes[8]["children"] = [16]                                        # arm_l
    nodes[0]["children"] = nodes[0]["children"] + [14]                 # Armature
    nodes += [{"name": "mount", "translation": [0, 0.2, 0.05],
               "rotation": quat_xyzw([0, 1, 1], 35), "children": [13]},
              {"name": "helmet", "mesh": 1, "translation": [0.05, 0.1, 0],
               "scale": [-1, 1.5, 0.8]},
              {"name": "lamp", "mesh": 1, "translation": [3, 0, 0]},
              {"name": "table", "mesh": 1, "translation": [0, -2, 0]},
              {"name": "glove", "mesh": 1, "translation": [0.3, 0, 0],
               "rotation": quat_xyzw([1, 0, 0], 60)}]
    doc["scenes"][0]["nodes"] += [15]


def _parts(rig):
    """{node: (rows, triangles)} of the rig's rigid parts."""
    out = {}
    for p in rig.meta["gltf"]["rigid"]:
        rows = np.arange(p["start"], p["start"] + p["count"])
        out[p["node"]] = (rows, rig.F[np.isin(rig.F, rows).all(axis=1)])
    return out


def test_meshes_hung_on_joints_are_part_of_the_rig(tmp_path):
    path, ctx = _scene(tmp_path, edit=hang_parts)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        rig, clips = read_gltf(path)
    n = len(ctx["V"])
    g = rig.meta["gltf"]
    # after the skinned body, in node order: leg_l on itself, the helmet on the neck
    # (the nearest joint above, across the mount), the glove on arm_l; no lamp, no table
    assert [(p["node"], p["mesh"], p["primitive"], p["joint"], p["start"], p["count"])
            for p in g["rigid"]] == [(3, 2, 0, 3, n, 8), (13, 1, 0, 9, n + 8, 8),
                                     (16, 1, 0, 8, n + 16, 8)]
    assert len(rig.V) == n + 24 and rig.F.max() == n + 23
    np.testing.assert_array_equal(rig.V[:n], ctx["V"].astype(np.float32).astype(float))
    sk = rig.skeleton
    for p in g["rigid"]:
        rows = slice(p["start"], p["start"] + p["count"])
        assert np.all(rig.W[rows, sk.names.index(NAMES[p["joint"]])] == 1)
    # placed as the file's bind pose draws them (the chest's bind is not its rest: the
    # helmet and glove sit where the turned-back chest carries them)
    ref = Reference(path)
    assert [(k, m, p, j) for k, m, p, _, j in ref.rigid] == [(3, 2, 0, 3), (13, 1, 0, 9),
                                                            (16, 1, 0, 8)]
    np.testing.assert_allclose(rig.V, ref.skin_bind(), atol=1e-6)
    # facing out, the mirrored helmet too (its triangles reversed, as viewers draw them)
    for node, (_, F) in _parts(rig).items():
        assert len(F) == 12 and _volume(rig.V, F) > 0, NAMES[node] if node < 12 else node
    assert (_parts(rig)[13][1][0] == [n + 8, n + 8 + 3, n + 8 + 1]).all()
    # they move exactly as the file draws them: at every key (the Armature's turn
    # too), and between keys where no non-joint node moves
    for a, name in enumerate(clips):
        T = ref.animation_times(a)
        assert _err(rig, clips[name], ref, a, T) <= 1e-5, name
        if name != "wave":
            assert _err(rig, clips[name], ref, a, _times(ref, a)) <= 1e-5, name
        moved = max(np.abs(ref.skin_at(a, float(t))[n:] - rig.V[n:]).max() for t in T)
        assert moved > 0.05, name
    # turning the chest by hand carries the helmet and the glove
    B = ref.bind_world()
    D = stbs.transforms.axis_angle_to_matrix(np.array([1.0, 2, 3]) / np.sqrt(14),
                                             np.radians(40))
    R = np.tile(np.eye(3), (sk.n_bones, 1, 1))
    Rb = B[6][:3, :3] / np.cbrt(np.linalg.det(B[6][:3, :3]))
    R[JOINTS.index(6)] = Rb @ D @ Rb.T
    U = stbs.deform(rig.V, sk, stbs.forward_kinematics(sk, rotations=R), rig.W, method="lbs")
    np.testing.assert_allclose(U, ref.skin_bind(turn=(6, D)), atol=1e-6)
    # rigid=False, or one mesh alone: the skinned body only
    for kw in ({"rigid": False}, {"mesh": "body"}):
        alone, _ = read_gltf(path, **kw)
        assert len(alone.V) == n and alone.meta["gltf"]["rigid"] == []
    assert len(Reference(path, rigid=False).V) == n
    with pytest.raises(TypeError, match="rigid must be True or False"):
        read_gltf(path, rigid="no")


def test_an_animation_moving_a_rigid_parts_mount_is_warned_about(tmp_path):
    def nod(b):
        return {"name": "nod", "samplers": [
            {"input": b.add(np.array([0.0, 1.0])),
             "output": b.add(np.array([quat_xyzw([0, 1, 1], 35), quat_xyzw([1, 0, 0], 50)]))}],
            "channels": [{"sampler": 0, "target": {"node": 12, "path": "rotation"}}]}

    path, _ = _scene(tmp_path, edit=hang_parts, extra_anims=[nod])
    rig, clips = read_gltf(path)
    clips["step"]                                       # no warning: the mount holds
    with pytest.warns(UserWarning, match=r"'nod'\) moves node 'mount' \(carrying 'helmet' "
                                         r"on joint 'neck'\); a rigid part moves with its "
                                         "joint only"):
        clips["nod"]
