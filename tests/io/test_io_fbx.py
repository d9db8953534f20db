"""FBX in: stbs.io.read_fbx. Our lbs skinning of the imported rig, posed by its clips at
their keys, equals ufbx's own evaluation of the file's skinning (run in a child process
apart from the reader: ufbx evaluates the scene at the time and skins the meshes); the
joints, meshes and bind pose are the file's; an ASCII FBX written here by hand is read and
bends as computed by hand; broken files give one FormatError."""

from __future__ import annotations

import functools
import hashlib
import json
import subprocess
import sys
import warnings

import numpy as np
import pytest

import stbs
from stbs.cli import main
from stbs.io import RIG_EXTENSIONS, FormatError, read_fbx, read_rig, write_rig

pytest.importorskip("ufbx")

FILES = ["assimp_animation_with_skeleton.fbx", "assimp_huesitos.fbx",
         "threejs_SambaDancing_mixamo.fbx"]
SLOW = {"threejs_SambaDancing_mixamo.fbx"}

# ufbx's evaluation of a file, independent of stbs: per skinned mesh its vertices in the
# world (the mesh node's geometry_to_world), its clusters' bone nodes with their bind
# matrices (TransformLink) and parents, and at each (stack, time) asked for the skinned
# vertices ufbx computes (evaluate_skinning); per instance of a mesh without a skin, its
# vertices moved by the evaluated node's geometry_to_world. Each object of the binding is
# fetched once and kept to the end (its wrappers lose a reference on every second fetch),
# the garbage collector is off and the child leaves without freeing the scene.
_ORACLE = r'''
import gc, json, os, sys
gc.disable()
import numpy as np
import ufbx

keep = []


def once(x):
    keep.append(x)
    return x


def mat(m):
    out = np.eye(4)
    out[:3, :] = np.array(m, dtype=float).T
    return out


src, dst, req = sys.argv[1], sys.argv[2], json.loads(sys.argv[3])
s = once(ufbx.load_file(src))
nodes = [once(s.nodes[i]) for i in range(len(s.nodes))]
ids = {n.element_id: k for k, n in enumerate(nodes)}
out, rec = {}, {"meshes": [], "nodes": [], "rigid": []}
for n in nodes:
    p = n.parent
    rec["nodes"].append({"name": n.name, "parent": ids[p.element_id] if p is not None else -1,
                         "world": mat(n.node_to_world).tolist()})
    once(p)
for m in range(len(s.meshes)):
    mesh = once(s.meshes[m])
    if len(mesh.skin_deformers) == 0:
        V = np.array(mesh.vertices, dtype=float).reshape(-1, 3)
        for i in range(len(mesh.instances)):
            inst = once(mesh.instances[i])
            X = mat(inst.geometry_to_world)
            rec["rigid"].append({"mesh": mesh.name, "node": inst.name, "n": len(V),
                                 "index": ids[inst.element_id]})
            out[f"V_node_{inst.name}"] = V
            out[f"rest_node_{inst.name}"] = V @ X[:3, :3].T + X[:3, 3]
        continue
    inst = once(mesh.instances[0])
    skin = once(mesh.skin_deformers[0])
    bones = []
    for c in range(len(skin.clusters)):
        cl = once(skin.clusters[c])
        b = cl.bone_node
        bones.append({"node": ids[b.element_id], "link": mat(cl.bind_to_world).tolist(),
                      "weights": len(cl.weights)})
    V = np.array(mesh.vertices, dtype=float).reshape(-1, 3)
    X = mat(inst.geometry_to_world)
    out[f"rest_{mesh.name}"] = V @ X[:3, :3].T + X[:3, 3]
    rec["meshes"].append({"name": mesh.name, "n": len(V), "bones": bones})
stacks = [once(s.anim_stacks[i]) for i in range(len(s.anim_stacks))]
rec["stacks"] = [[st.name, st.time_begin, st.time_end] for st in stacks]
anims = [once(st.anim) for st in stacks]
for r, (k, t) in enumerate(req):
    ev = once(s.evaluate(anims[k], float(t), evaluate_skinning=True))
    for m in range(len(ev.meshes)):
        mesh = once(ev.meshes[m])
        if len(mesh.skin_deformers) == 0:
            continue
        P = np.array(mesh.skinned_position.values, dtype=float).reshape(-1, 3)
        if mesh.skinned_is_local:
            X = mat(once(mesh.instances[0]).geometry_to_world)
            P = P @ X[:3, :3].T + X[:3, 3]
        out[f"{r}_{mesh.name}"] = P
    enodes = once(ev.nodes)
    for part in rec["rigid"]:
        X = mat(once(enodes[part["index"]]).geometry_to_world)
        out[f"{r}_node_{part['node']}"] = out[f"V_node_{part['node']}"] @ X[:3, :3].T \
            + X[:3, 3]
out["record"] = np.array(json.dumps(rec))
with open(dst, "wb") as f:
    np.savez(f, **out)
sys.stdout.flush()
os._exit(0)
'''


def ufbx_says(path, requests=(), tmp=None):
    """(record, arrays) of ufbx's own evaluation; ``requests``: (stack index, time)."""
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        dst = f"{d}/oracle.npz"
        proc = subprocess.run([sys.executable, "-c", _ORACLE, str(path), dst,
                               json.dumps([[int(k), float(t)] for k, t in requests])],
                              capture_output=True, text=True, check=False)
        assert proc.returncode == 0, proc.stderr[-2000:]
        with np.load(dst) as z:
            arrays = {k: z[k] for k in z.files}
    return json.loads(str(arrays.pop("record"))), arrays


@functools.cache
def _read(path):
    with warnings.catch_warnings():
        warnings.simplefilter("error")            # the shared files read without warning
        return read_fbx(path)


def _diag(V):
    return float(np.linalg.norm(np.ptp(V, axis=0)))


def _check_skinning(path, rig, clips, per_stack=4):
    """Every stack's clip, at ``per_stack`` of its keys, skins as ufbx skins the file;
    returns how far the meshes moved (relative to the size)."""
    diag = _diag(rig.V)
    req = []
    for k, clip in enumerate(clips.values()):
        T = clip.times
        req += [(k, float(T[i])) for i in np.unique(np.linspace(0, len(T) - 1, per_stack)
                                                    .round().astype(int))]
    _, ref = ufbx_says(path, req)
    moved = 0.0
    names = list(clips)
    for r, (k, t) in enumerate(req):
        pose = clips[names[k]].pose(t)
        U = stbs.deform(rig.V, rig.skeleton, pose, rig.W, method="lbs")
        for part in rig.meta["fbx"]["meshes"] + rig.meta["fbx"]["rigid"]:
            want = ref[f"{r}_node_{part['node']}" if "joint" in part else f"{r}_{part['name']}"]
            got = U[part["start"]:part["stop"]]
            err = float(np.abs(got - want).max())
            assert err <= 1e-5 * diag, (names[k], t, part["name"], err / diag)
            moved = max(moved, float(np.abs(want - rig.V[part["start"]:part["stop"]]).max()))
    return moved / diag


# --------------------------------------------------------------------------- shared files
@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if n in SLOW
                                  else n for n in FILES])
def test_the_shared_files_skin_as_ufbx_evaluates_them(shared_data, name):
    path = shared_data / "characters" / "fbx" / name
    rig, clips = _read(str(path))
    assert clips
    assert _check_skinning(path, rig, clips) > 0.05        # a real motion, not the rest


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if n in SLOW
                                  else n for n in FILES])
def test_the_shared_files_joints_meshes_and_bind_pose(shared_data, name):
    path = shared_data / "characters" / "fbx" / name
    before = hashlib.sha256(path.read_bytes()).hexdigest()
    rig, clips = _read(str(path))
    rec, arr = ufbx_says(path)
    nodes = rec["nodes"]
    sk = rig.skeleton
    # the joints: the nodes the clusters name, each once, named as the node
    bone_nodes = {b["node"] for m in rec["meshes"] for b in m["bones"]}
    assert sorted(sk.names) == sorted(nodes[k]["name"] for k in bone_nodes)
    assert sk.n_bones == len(bone_nodes)
    # a joint's parent is its nearest ancestor among the joints
    by_name = {nodes[k]["name"]: k for k in bone_nodes}
    for i, nm in enumerate(sk.names):
        k = nodes[by_name[nm]]["parent"]
        while k >= 0 and k not in bone_nodes:
            k = nodes[k]["parent"]
        want = nodes[k]["name"] if k >= 0 else None
        assert (sk.names[sk.P[i]] if sk.P[i] >= 0 else None) == want, nm
    # each bone starts at its joint's bind position (the cluster's TransformLink)
    for m in rec["meshes"]:
        for b in m["bones"]:
            i = sk.names.index(nodes[b["node"]]["name"])
            np.testing.assert_allclose(sk.A[i], np.array(b["link"])[:3, 3],
                                       atol=1e-5 * _diag(rig.V))
    # every skinned mesh, in file order, in the world bind pose
    parts = rig.meta["fbx"]["meshes"]
    assert [p["name"] for p in parts] == [m["name"] for m in rec["meshes"]]
    assert [p["stop"] - p["start"] for p in parts] == [m["n"] for m in rec["meshes"]]
    assert parts[0]["start"] == 0 and parts[-1]["stop"] == len(rig.V)
    for p in parts:
        np.testing.assert_allclose(rig.V[p["start"]:p["stop"]], arr[f"rest_{p['name']}"],
                                   atol=1e-5 * _diag(rig.V))
    np.testing.assert_allclose(rig.W.sum(axis=1), 1.0, atol=1e-12)
    assert rig.F.shape[1] == 3 and rig.F.min() >= 0 and rig.F.max() < len(rig.V)
    # one clip per stack, keyed at every frame over the stack's span
    assert list(clips) == [s[0] for s in rec["stacks"]]
    fps = rig.meta["fbx"]["fps"]
    for clip, (_, t0, t1) in zip(clips.values(), rec["stacks"], strict=True):
        assert clip.times[0] == pytest.approx(t0) and clip.times[-1] == pytest.approx(t1)
        assert np.all(np.diff(clip.times) <= 1 / fps + 1e-9)
        assert len(clip.times) == int(np.floor((t1 - t0) * fps + 1e-6)) + 1 + (
            not np.isclose((t1 - t0) * fps, round((t1 - t0) * fps)))
    assert hashlib.sha256(path.read_bytes()).hexdigest() == before


@pytest.mark.slow
def test_a_mixamo_character_is_its_two_meshes_on_one_skeleton(shared_data):
    path = shared_data / "characters" / "fbx" / "threejs_SambaDancing_mixamo.fbx"
    rig, clips = _read(str(path))
    parts = rig.meta["fbx"]["meshes"]
    assert len(parts) == 2
    # one mesh alone, by its name or index among the skinned meshes
    one, _ = read_fbx(path, mesh=parts[1]["name"])
    n1 = parts[1]["stop"] - parts[1]["start"]
    assert len(one.V) == n1
    np.testing.assert_allclose(one.V, rig.V[parts[1]["start"]:])
    assert len(read_fbx(path, mesh=0)[0].V) == parts[0]["stop"]
    # a skin deformer picks its skeleton: both meshes
    assert len(read_fbx(path, skin=1)[0].V) == len(rig.V)
    with pytest.raises(ValueError, match="no skinned mesh of that name.*Alpha_Surface"):
        read_fbx(path, mesh="Nope")
    # stbs animate bakes the file's own animation: the stack that moves ("Take 001" of a
    # Mixamo file holds the bind pose), sampled as the clip is
    moving = clips["mixamo.com"]
    assert np.ptp(clips["Take 001"].quaternions, axis=0).max() < 1e-9
    from stbs.bake import load_motion

    assert load_motion(path, rig) is not None
    assert load_motion(path, rig).times.tolist() == moving.times.tolist()


# --------------------------------------------------------------------------- ASCII by hand
SEC = 46186158000          # FBX time units in a second


def _arr(name, vals, fmt="{:.17g}", tabs=2):
    vals = list(vals)
    t = "\t" * tabs
    return f"{t}{name}: *{len(vals)} {{\n{t}\ta: " + ",".join(fmt.format(v) for v in vals) \
        + f"\n{t}}}\n"


def _mat(name, M, tabs=2):
    # FBX keeps a matrix by columns: its translation is entries 12, 13, 14
    return _arr(name, np.asarray(M, float).T.ravel(), tabs=tabs)


def _T(y):
    M = np.eye(4)
    M[1, 3] = y
    return M


# A box: 8 corners, 6 quads facing out.
BOX_V = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
BOX_Q = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]


def _box_geometry(uid, name):
    poly = [v for q in BOX_Q for v in (*q[:3], -q[3] - 1)]
    return (f"\tGeometry: {uid}, \"Geometry::{name}\", \"Mesh\" {{\n"
            + _arr("Vertices", (0.1 * BOX_V).ravel()) + _arr("PolygonVertexIndex", poly, "{:d}")
            + "\t\tGeometryVersion: 124\n\t}\n")


_P = 'P: "{}", "{}", "{}", "{}",{}\n'


def _fbx_header() -> list[str]:
    """The header and global settings: y up, z front, x right, metres, 30 fps."""
    o = ["; FBX 7.4.0 project file\n", "FBXHeaderExtension:  {\n\tFBXHeaderVersion: 1003\n"
         "\tFBXVersion: 7400\n\tCreator: \"stbs tests\"\n}\n",
         "GlobalSettings:  {\n\tVersion: 1000\n\tProperties70:  {\n"]
    for k, v in (("UpAxis", 1), ("UpAxisSign", 1), ("FrontAxis", 2), ("FrontAxisSign", 1),
                 ("CoordAxis", 0), ("CoordAxisSign", 1)):
        o.append("\t\t" + _P.format(k, "int", "Integer", "", v))
    o.append("\t\t" + _P.format("UnitScaleFactor", "double", "Number", "", 1))
    o.append("\t\t" + _P.format("TimeMode", "enum", "", "", 6) + "\t}\n}\n")   # 6: 30 fps
    return o


def _fbx_models(V, poly, parts: bool) -> list[str]:
    """The bar's geometry and model, the three joints' models and attributes, and with
    ``parts`` the Cap, its Socket and the Crate."""
    o = ["Objects:  {\n\tGeometry: 1000, \"Geometry::Bar\", \"Mesh\" {\n"
         + _arr("Vertices", V.ravel()) + _arr("PolygonVertexIndex", poly, "{:d}")
         + "\t\tGeometryVersion: 124\n\t}\n"
         "\tModel: 2000, \"Model::Bar\", \"Mesh\" {\n\t\tVersion: 232\n\t}\n"]
    for uid, name, kind, y in ((3000, "Bone1", "LimbNode", 0.0), (3500, "Mid", "Null", 0.5),
                               (4000, "Bone2", "Null", 0.5)):
        o.append(f"\tModel: {uid}, \"Model::{name}\", \"{kind}\" {{\n\t\tVersion: 232\n"
                 "\t\tProperties70:  {\n\t\t\t"
                 + _P.format("Lcl Translation", "Lcl Translation", "", "A", f"0,{y},0")
                 + "\t\t}\n\t}\n"
                 f"\tNodeAttribute: {uid + 1}, \"NodeAttribute::{name}\", \"{kind}\" {{\n"
                 + ("\t\tTypeFlags: \"Skeleton\"\n" if kind == "LimbNode" else "") + "\t}\n")
    if parts:
        o.append(_box_geometry(1100, "Cap") + _box_geometry(1200, "Crate"))
        for uid, name, kind, props in (
                (3600, "Socket", "Null", (("Lcl Translation", "0.1,0.3,0"),
                                          ("Lcl Rotation", "20,0,0"))),
                (2100, "Cap", "Mesh", (("Lcl Translation", "0.2,0.1,0"),
                                       ("Lcl Rotation", "0,30,45"),
                                       ("Lcl Scaling", "-1,1.5,0.8"))),
                (2200, "Crate", "Mesh", (("Lcl Translation", "3,0,0"),))):
            o.append(f"\tModel: {uid}, \"Model::{name}\", \"{kind}\" {{\n\t\tVersion: 232\n"
                     "\t\tProperties70:  {\n"
                     + "".join("\t\t\t" + _P.format(k, k, "", "A", v) for k, v in props)
                     + "\t\t}\n\t}\n")
        o.append("\tNodeAttribute: 3601, \"NodeAttribute::Socket\", \"Null\" {\n\t}\n")
    return o


def _fbx_skin(w1, shift: float) -> list[str]:
    """The skin deformer, Bone1's and Bone2's clusters (Bone2's bind moved ``shift``
    along x) and the bind pose."""
    o = ["\tDeformer: 5000, \"Deformer::Skin\", \"Skin\" {\n\t\tVersion: 101\n\t}\n"]
    for uid, name, w, y, dx in ((5001, "Bone1", w1, 0.0, 0.0),
                                (5002, "Bone2", 1 - w1, 1.0, shift)):
        idx = np.flatnonzero(w > 0)
        mesh_at = np.eye(4)
        mesh_at[0, 3] = dx
        # "Transform" as files keep it: the mesh's bind matrix in the bone's frame
        o.append(f"\tDeformer: {uid}, \"SubDeformer::{name}\", \"Cluster\" {{\n"
                 "\t\tVersion: 100\n" + _arr("Indexes", idx, "{:d}")
                 + _arr("Weights", w[idx]) + _mat("Transform", _T(-y) @ mesh_at)
                 + _mat("TransformLink", _T(y)) + "\t}\n")
    o.append("\tPose: 6000, \"Pose::BIND_POSES\", \"BindPose\" {\n\t\tType: \"BindPose\"\n"
             "\t\tVersion: 100\n\t\tNbPoseNodes: 4\n")
    for uid, y in ((2000, 0.0), (3000, 0.0), (3500, 0.5), (4000, 1.0)):
        o.append(f"\t\tPoseNode:  {{\n\t\t\tNode: {uid}\n" + _mat("Matrix", _T(y), 3)
                 + "\t\t}\n")
    o.append("\t}\n")
    return o


def _fbx_curve(uid: int, values) -> str:
    """An animation curve of two keys, at 0 and 1 s."""
    return (f"\t\t}}\n\t}}\n\tAnimationCurve: {uid}, \"AnimCurve::\", \"\" {{\n"
            "\t\tDefault: 0\n\t\tKeyVer: 4009\n" + _arr("KeyTime", [0, SEC], "{:d}")
            + _arr("KeyValueFloat", values) + _arr("KeyAttrFlags", [24836], "{:d}")
            + _arr("KeyAttrDataFloat", [0, 0, 0, 0], "{:d}")
            + _arr("KeyAttrRefCount", [2], "{:d}") + "\t}\n")


def _fbx_animation(nod: bool) -> list[str]:
    """Stack "Bend": Bone2 turned about z from 0 to 90 degrees (``nod``: the Socket
    about x from 20 to -40 too)."""
    o = ["\tAnimationStack: 7000, \"AnimStack::Bend\", \"\" {\n\t\tProperties70:  {\n"]
    for k, v in (("LocalStart", 0), ("LocalStop", SEC), ("ReferenceStart", 0),
                 ("ReferenceStop", SEC)):
        o.append("\t\t\t" + _P.format(k, "KTime", "Time", "", v))
    o.append("\t\t}\n\t}\n\tAnimationLayer: 7001, \"AnimLayer::BaseLayer\", \"\" {\n\t}\n"
             "\tAnimationCurveNode: 7002, \"AnimCurveNode::R\", \"\" {\n"
             "\t\tProperties70:  {\n")
    for k in "XYZ":
        o.append("\t\t\t" + _P.format(f"d|{k}", "Number", "", "A", 0))
    o.append(_fbx_curve(7003, [0, 90]))
    if nod:
        o.append("\tAnimationCurveNode: 7004, \"AnimCurveNode::R\", \"\" {\n"
                 "\t\tProperties70:  {\n")
        for k, v in (("X", 20), ("Y", 0), ("Z", 0)):
            o.append("\t\t\t" + _P.format(f"d|{k}", "Number", "", "A", v))
        o.append(_fbx_curve(7005, [20, -40]))
    return o


def _fbx_connections(*, skin: bool, anim: bool, parts: bool, nod: bool) -> list[str]:
    """The Connections section: the node tree, the skin's links and the animation's."""
    o = ["}\nConnections:  {\n"]
    con = [("OO", 2000, 0), ("OO", 1000, 2000), ("OO", 3000, 0), ("OO", 3001, 3000),
           ("OO", 3500, 3000), ("OO", 3501, 3500), ("OO", 4000, 3500), ("OO", 4001, 4000)]
    if parts:
        con += [("OO", 3600, 4000), ("OO", 3601, 3600), ("OO", 2100, 3600),
                ("OO", 1100, 2100), ("OO", 2200, 0), ("OO", 1200, 2200)]
    if skin:
        con += [("OO", 5000, 1000), ("OO", 5001, 5000), ("OO", 3000, 5001),
                ("OO", 5002, 5000), ("OO", 4000, 5002)]
    o += [f"\tC: \"{k}\",{a},{b}\n" for k, a, b in con]
    if anim:
        o += ["\tC: \"OO\",7001,7000\n", "\tC: \"OO\",7002,7001\n",
              "\tC: \"OP\",7002,4000, \"Lcl Rotation\"\n", "\tC: \"OP\",7003,7002, \"d|Z\"\n"]
        if nod:
            o += ["\tC: \"OO\",7004,7001\n", "\tC: \"OP\",7004,3600, \"Lcl Rotation\"\n",
                  "\tC: \"OP\",7005,7004, \"d|X\"\n"]
    o.append("}\n")
    return o


def ascii_fbx(*, skin=True, anim=True, shift=0.0, parts=False, nod=False):
    """An ASCII FBX 7.4 of a bar (y from 0 to 2, 20 vertices, 18 quads) on Bone1
    (LimbNode at the origin) -> Mid (a Null at y = 0.5, in no cluster) -> Bone2 (a Null
    at y = 1, a cluster of its own); stack "Bend" turns Bone2 about z from 0 to 90
    degrees over 1 s, at 30 fps. ``shift``: Bone2's cluster binds the mesh that far
    along x from where Bone1's does. ``parts``: two meshes without a skin, a box "Cap"
    hung on Bone2 through a turned Null "Socket" (the Cap's node turned, scaled unevenly
    and mirrored), and a box "Crate" at the scene's root (a prop); ``nod``: the stack
    turns the Socket too. Returns (text, rest vertices, Bone1's weights)."""
    ys = [0.0, 0.5, 1.0, 1.5, 2.0]
    ring = [(-0.2, -0.2), (0.2, -0.2), (0.2, 0.2), (-0.2, 0.2)]
    V = np.array([(x, y, z) for y in ys for x, z in ring])
    quads = [(4 * r + i, 4 * r + (i + 1) % 4, 4 * (r + 1) + (i + 1) % 4, 4 * (r + 1) + i)
             for r in range(len(ys) - 1) for i in range(4)]
    quads += [(3, 2, 1, 0), (16, 17, 18, 19)]
    poly = [v for q in quads for v in (*q[:3], -q[3] - 1)]    # FBX ends a polygon with ~v
    w1 = np.array([1.0] * 8 + [0.5] * 4 + [0.0] * 8)
    o = _fbx_header() + _fbx_models(V, poly, parts)
    if skin:
        o += _fbx_skin(w1, shift)
    if anim:
        o += _fbx_animation(nod)
    o += _fbx_connections(skin=skin, anim=anim, parts=parts, nod=nod)
    return "".join(o), V, w1


@pytest.fixture
def bar_fbx(tmp_path):
    text, V, w1 = ascii_fbx()
    path = tmp_path / "bar.fbx"
    path.write_text(text)
    return path, V, w1


def test_an_ascii_fbx_written_by_hand(bar_fbx):
    path, V0, w1 = bar_fbx
    rig, clips = read_fbx(path)
    sk = rig.skeleton
    assert rig.meta["fbx"]["ascii"] and rig.meta["fbx"]["meshes"] == [
        {"name": "Bar", "node": "Bar", "start": 0, "stop": 20, "skinning": "linear"}]
    # joints: the clusters' bones (a LimbNode and a Null) and the Null between them
    assert sorted(sk.names) == ["Bone1", "Bone2", "Mid"]
    b1, mid, b2 = (sk.names.index(n) for n in ("Bone1", "Mid", "Bone2"))
    assert sk.P[b1] == -1 and sk.P[mid] == b1 and sk.P[b2] == mid
    np.testing.assert_allclose(sk.A[[b1, mid, b2]], [[0, 0, 0], [0, 0.5, 0], [0, 1, 0]],
                               atol=1e-12)
    np.testing.assert_allclose(rig.V, V0, atol=1e-12)
    np.testing.assert_allclose(rig.W[:, b1], w1, atol=1e-12)
    np.testing.assert_allclose(rig.W[:, b2], 1 - w1, atol=1e-12)
    assert not rig.W[:, mid].any()
    assert len(rig.F) == 36 and len({tuple(sorted(f)) for f in rig.F}) == 36
    # the stack: keyed at every frame of 30 fps over its second
    clip = clips["Bend"]
    np.testing.assert_allclose(clip.times, np.arange(31) / 30, atol=1e-12)
    # by hand: at 1 s Bone2 has turned 90 degrees about z at (0, 1, 0): the vertices it
    # alone moves go (x, y, z) -> (1 - y, 1 + x, z); those it shares half turn half stay
    U = stbs.deform(rig.V, sk, clip.pose(1.0), rig.W, method="lbs")
    c = np.array([0.0, 1.0, 0.0])
    turned = np.stack([c[0] - (V0[:, 1] - c[1]), c[1] + V0[:, 0], V0[:, 2]], axis=1)
    want = w1[:, None] * V0 + (1 - w1[:, None]) * turned
    np.testing.assert_allclose(U, want, atol=1e-9)
    # and as ufbx evaluates it, at the keys
    assert _check_skinning(path, rig, clips, per_stack=5) > 0.2


def test_a_cluster_that_binds_the_mesh_elsewhere_still_skins_as_the_file(tmp_path):
    path = tmp_path / "shifted.fbx"
    path.write_text(ascii_fbx(shift=0.3)[0])
    with pytest.warns(UserWarning, match=r"'Bone2' bind the mesh elsewhere"):
        rig, clips = read_fbx(path)
    assert _check_skinning(path, rig, clips, per_stack=5) > 0.2


def test_a_mesh_parented_to_a_bone_moves_with_it(tmp_path):
    # the Cap, without a skin, hangs on Bone2 through the Socket: it is read, weighted 1
    # to Bone2, placed where ufbx draws it at rest and moved as ufbx moves its node;
    # the Crate under no joint is a prop, not read
    path = tmp_path / "parts.fbx"
    path.write_text(ascii_fbx(parts=True)[0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        rig, clips = read_fbx(path)
    assert rig.meta["fbx"]["rigid"] == [{"name": "Cap", "node": "Cap", "joint": "Bone2",
                                         "start": 20, "stop": 28}]
    assert len(rig.V) == 28 and rig.meta["fbx"]["meshes"][0]["stop"] == 20
    sk = rig.skeleton
    assert np.all(rig.W[20:, sk.names.index("Bone2")] == 1)
    rec, arr = ufbx_says(path)
    assert [r["node"] for r in rec["rigid"]] == ["Cap", "Crate"]
    np.testing.assert_allclose(rig.V[20:], arr["rest_node_Cap"], atol=1e-9)
    # mirrored by its node, drawn with its winding reversed: its faces still face out
    F = rig.F[(rig.F >= 20).all(axis=1)]
    assert len(F) == 12
    vol = np.einsum("fi,fi->f", rig.V[F[:, 0]], np.cross(rig.V[F[:, 1]], rig.V[F[:, 2]]))
    assert vol.sum() > 0
    # at the keys, lbs of the whole rig is ufbx's skinning of the bar and ufbx's node
    # transform of the Cap (asserted to 1e-5 of the size, the Cap's rows included)
    assert _check_skinning(path, rig, clips, per_stack=7) > 0.2
    _, ref = ufbx_says(path, [(0, 0.5), (0, 1.0)])
    U = stbs.deform(rig.V, sk, clips["Bend"].pose(1.0), rig.W, method="lbs")
    assert np.abs(U[20:] - ref["1_node_Cap"]).max() <= 1e-9
    assert np.abs(ref["1_node_Cap"] - rig.V[20:]).max() > 0.3           # it moved
    # rigid=False (also through read_rig), or one mesh alone: the bar only
    for alone in (read_fbx(path, rigid=False)[0], read_rig(path, rigid=False),
                  read_fbx(path, mesh="Bar")[0]):
        assert len(alone.V) == 20 and alone.meta["fbx"]["rigid"] == []
    assert len(read_rig(path).V) == 28
    # Bone2's cluster binding the bar 0.3 along x from where Bone1's does: Bone2's bind
    # is not its rest, and the Cap is placed by that bind so that it still moves as ufbx
    # moves it
    path = tmp_path / "shifted.fbx"
    path.write_text(ascii_fbx(parts=True, shift=0.3)[0])
    with pytest.warns(UserWarning, match=r"'Bone2' bind the mesh elsewhere"):
        rig, clips = read_fbx(path)
    assert np.abs(rig.V[20:] - arr["rest_node_Cap"]).max() > 0.2
    assert _check_skinning(path, rig, clips, per_stack=7) > 0.2


def test_a_stack_moving_a_parts_own_node_is_warned_about(tmp_path):
    path = tmp_path / "nod.fbx"
    path.write_text(ascii_fbx(parts=True, nod=True)[0])
    with pytest.warns(UserWarning, match=r"stack 'Bend' moves the rigid parts 'Cap' \(on "
                                         r"'Bone2'\) apart from their joints"):
        read_fbx(path)


# --------------------------------------------------------------------------- reading rigs
def test_read_rig_takes_fbx_and_write_rig_does_not(bar_fbx, tmp_path):
    path, _, _ = bar_fbx
    assert ".fbx" in RIG_EXTENSIONS
    rig = read_rig(path)
    ref, _ = read_fbx(path)
    np.testing.assert_array_equal(rig.V, ref.V)
    np.testing.assert_array_equal(rig.W, ref.W)
    assert rig.skeleton == ref.skeleton
    with pytest.raises(ValueError, match="FBX"):
        write_rig(tmp_path / "out.fbx", rig)
    assert not (tmp_path / "out.fbx").exists()


def test_stbs_animate_bakes_an_fbx_files_own_animation(bar_fbx, tmp_path, capsys):
    path, _, _ = bar_fbx
    out = tmp_path / "bend.npz"
    assert main(["animate", str(path), "--motion", str(path), "--method", "lbs",
                 "--frames", "0:31:10", "-o", str(out)]) == 0
    with np.load(out) as z:
        U, times = z["U"], z["times"]
    np.testing.assert_allclose(times, [0, 1 / 3, 2 / 3, 1.0], atol=1e-9)
    _, ref = ufbx_says(path, [(0, t) for t in times])
    for k in range(len(times)):
        np.testing.assert_allclose(U[k], ref[f"{k}_Bar"], atol=1e-5)   # float32 frames


# --------------------------------------------------------------------------- bad files
def _no_skin(p):
    p.write_text(ascii_fbx(skin=False)[0])


def _truncated(p, shared_data):
    src = shared_data / "characters" / "fbx" / "assimp_huesitos.fbx"
    p.write_bytes(src.read_bytes()[:4000])


@pytest.mark.parametrize("make, found", [
    (lambda p, d: _no_skin(p), r"expected a skinned mesh .* found 1 mesh\(es\), none with"),
    (lambda p, d: _truncated(p, d),
     r"expected an FBX file .* found a binary FBX file that is truncated or damaged"),
    (lambda p, d: p.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"),
     r"expected an FBX file .* found another kind of file \(it starts b'v 0 0 0"),
    (lambda p, d: p.write_bytes(b""), r"expected an FBX file .* found an empty file"),
    (lambda p, d: p.write_bytes(bytes(range(256)) * 8),
     r"expected an FBX file .* found another kind of file"),
    (lambda p, d: p.write_text("; FBX 7.4.0 project file\nnot really\n"),
     r"expected an FBX file .* found a file ufbx cannot read as FBX"),
    (lambda p, d: p.write_text("; FBX 7.4.0 project file\nObjects:  {\n\tModel: 1, \"M\""),
     r"expected a skinned mesh .* found no meshes"),              # ASCII cut short
])
def test_broken_files_give_one_format_error_naming_the_file(tmp_path, shared_data, make,
                                                            found):
    p = tmp_path / "broken.fbx"
    make(p, shared_data)
    before = p.read_bytes()
    with pytest.raises(FormatError, match=found) as exc:
        read_fbx(p)
    msg = str(exc.value)
    assert msg.startswith(str(p) + ": expected") and "\n" not in msg
    assert p.read_bytes() == before


def test_the_command_line_says_one_line_and_exits_2(tmp_path, capsys):
    p = tmp_path / "broken.fbx"
    p.write_text("; FBX 7.4.0 project file\nnot really\n")
    code = main(["animate", str(p), "--motion", str(p), "-o", str(tmp_path / "x.npz")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and str(p) in err[0]
    assert not (tmp_path / "x.npz").exists()


def test_without_ufbx_the_error_names_the_extra(bar_fbx, monkeypatch):
    from stbs._optional import OptionalDependencyError

    monkeypatch.setitem(sys.modules, "ufbx", None)
    with pytest.raises(OptionalDependencyError, match=r"stbs-skinning\[fbx\]"):
        read_fbx(bar_fbx[0])


def _stack_ending_at(data: bytes, seconds: float) -> bytes:
    """A binary FBX whose animation stacks' LocalStop/ReferenceStop (KTime, 46186158000
    ticks a second) are moved to ``seconds``: each is a P70 record of three strings
    ('S', uint32 length, bytes) and an int64 ('L')."""
    import re
    import struct

    b = bytearray(data)
    for m in re.finditer(rb"LocalStop|ReferenceStop", b):
        i = m.end()
        for _ in range(3):
            assert b[i:i + 1] == b"S"
            i += 5 + struct.unpack_from("<I", b, i + 1)[0]
        assert b[i:i + 1] == b"L"
        struct.pack_into("<q", b, i + 1, int(seconds * 46186158000))
    return bytes(b)


def test_an_animation_claiming_days_is_refused_before_sampling(shared_data, tmp_path,
                                                               capsys):
    """A stack whose end is 11 days in would be sampled at 24 fps (24 million frames of
    every node's matrix): refused with one line; the rig itself still reads."""
    src = shared_data / "characters" / "fbx" / FILES[0]
    bad = tmp_path / "long.fbx"
    bad.write_bytes(_stack_ending_at(src.read_bytes(), 1e6))
    with pytest.raises(FormatError, match="an animation too long to sample"):
        read_fbx(bad)
    capsys.readouterr()
    assert main(["animate", str(bad), "--motion", str(bad), "-o",
                 str(tmp_path / "o.npz")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "more than 100000 frames" in err[0]
    assert not (tmp_path / "o.npz").exists()
    assert main(["export", str(bad), "-o", str(tmp_path / "rig.glb")]) == 0


@pytest.mark.filterwarnings("ignore:.*bind the mesh elsewhere")  # NaN binds agree with none
def test_non_finite_transforms_are_one_error_naming_the_file(shared_data, tmp_path):
    """A binary FBX whose GeometricTranslation (a P70 record: three strings, then 'D'
    doubles) is NaN: the error names the file, not an array deep in the library."""
    import re
    import struct

    b = bytearray((shared_data / "characters" / "fbx" / FILES[0]).read_bytes())
    hits = 0
    for m in re.finditer(rb"GeometricTranslation", b):
        i = m.end()
        for _ in range(3):
            i += 5 + struct.unpack_from("<I", b, i + 1)[0]
        while b[i:i + 1] == b"D":
            struct.pack_into("<d", b, i + 1, float("nan"))
            i, hits = i + 9, hits + 1
    assert hits
    bad = tmp_path / "nan.fbx"
    bad.write_bytes(bytes(b))
    with pytest.raises(FormatError, match=r"nan\.fbx: expected an FBX scene of finite "
                                          r"transforms .* must be finite, got nan at index "
                                          r"\(0, 0, 0\)"):
        read_fbx(bad)
