"""Writing a glTF character back (stbs.io.write_rig with source=): a copy of the file
with endpoint weights on every primitive the rig came from and the bone table; the rest
as it was; the Khronos validator finds no more than in the source (nothing in a clean
one); bone weights recomputed elsewhere replace the file's JOINTS_0/WEIGHTS_0."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
from gltf_files import Reference, load_raw
from test_io_gltf_write import validate

import stbs
from stbs.io import read_gltf, write_rig

FILES = ["gltf/SimpleSkin.gltf", "gltf/RiggedSimple.glb",
         "characters/gltf/CesiumMan.glb", "characters/gltf/RiggedFigure.glb",
         "characters/gltf/Fox.glb", "characters/gltf/Fox_separate/Fox.gltf",
         "characters/gltf/RobotExpressive.glb", "characters/gltf/threejs_Xbot.glb",
         "characters/gltf/BrainStem.glb"]


def _read(path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return read_gltf(path)


@pytest.mark.parametrize("name", FILES)
def test_a_character_written_back(shared_data, tmp_path, name):
    src = shared_data / name
    rig, clips = _read(src)
    E = stbs.weights.projection(rig.V, rig.skeleton)
    out = tmp_path / ("back.gltf" if name.endswith(".gltf") else "back.glb")
    write_rig(out, rig.replace(E=E), source=src)
    back, clips_b = _read(out)
    np.testing.assert_array_equal(back.V, rig.V)
    np.testing.assert_array_equal(back.F, rig.F)
    np.testing.assert_array_equal(back.W, rig.W)
    np.testing.assert_array_equal(back.C, rig.C)
    np.testing.assert_array_equal(back.skeleton.parents, rig.skeleton.parents)
    assert back.skeleton.names == rig.skeleton.names
    on = np.asarray(rig.W) > 0
    np.testing.assert_allclose(np.asarray(back.E)[on], E[on], atol=1e-7)
    # the animations are the file's own
    assert list(clips_b) == list(clips)
    first = next(iter(clips))
    np.testing.assert_array_equal(clips_b[first].times, clips[first].times)
    np.testing.assert_allclose(clips_b[first].quaternions, clips[first].quaternions)
    # every primitive the rig came from carries its endpoint weights; the nodes and
    # animations are the source's
    doc_a, _ = load_raw(src)
    doc_b, _ = load_raw(out)
    for p in rig.meta["gltf"]["primitives"]:
        assert "_ENDPOINT_WEIGHTS_0" in \
            doc_b["meshes"][p["mesh"]]["primitives"][p["primitive"]]["attributes"]
    assert doc_b["nodes"] == doc_a["nodes"]
    assert doc_b.get("animations") == doc_a.get("animations")
    assert doc_b.get("materials") == doc_a.get("materials")
    assert len(doc_b["buffers"]) == 1
    a, b = validate(src, out)
    assert b["errors"] <= a["errors"] and b["warnings"] <= a["warnings"], (a, b)
    if (a["errors"], a["warnings"]) == (0, 0):
        assert (b["errors"], b["warnings"]) == (0, 0), b


def test_new_bone_weights_replace_the_files(shared_data, tmp_path):
    # bone weights recomputed (here: each vertex to its two nearest bone starts) go into
    # JOINTS_0/WEIGHTS_0 of each primitive, over that primitive's skin
    src = shared_data / "characters/gltf/Fox.glb"
    rig, _ = _read(src)
    sk = rig.skeleton
    d = np.linalg.norm(rig.V[:, None] - sk.A[None], axis=2)
    near = np.argsort(d, axis=1)[:, :2]
    W = np.zeros((len(rig.V), sk.n_bones))
    np.put_along_axis(W, near, [0.75, 0.25], axis=1)
    E = stbs.weights.projection(rig.V, sk)
    out = tmp_path / "fox.glb"
    write_rig(out, rig.replace(W=W, E=E), source=src)
    back, _ = _read(out)
    np.testing.assert_allclose(back.W, W, atol=1 / 65535)
    on = W > 0
    np.testing.assert_allclose(np.asarray(back.E)[on], E[on], atol=1e-7)
    a, b = validate(src, out)
    assert (b["errors"], b["warnings"]) == (0, 0), b


def test_an_external_texture_is_embedded(shared_data, tmp_path):
    src = shared_data / "characters/gltf/Fox_separate/Fox.gltf"
    rig, _ = _read(src)
    out = tmp_path / "elsewhere" / "fox.gltf"
    out.parent.mkdir()
    write_rig(out, rig.replace(E=stbs.weights.projection(rig.V, rig.skeleton)), source=src)
    doc = json.loads(out.read_text())
    assert all("uri" not in img and img["mimeType"] == "image/png" for img in doc["images"])
    assert doc["buffers"][0]["uri"].startswith("data:")
    assert validate(out)[0]["errors"] == 0


def test_a_rig_from_elsewhere_is_refused(shared_data, tmp_path):
    rig, _ = _read(shared_data / "characters/gltf/Fox.glb")
    rig = rig.replace(E=stbs.weights.projection(rig.V, rig.skeleton))
    with pytest.raises(ValueError, match="not the file the rig was read from"):
        write_rig(tmp_path / "x.glb", rig, source=shared_data / "characters/gltf/CesiumMan.glb")
    with pytest.raises(ValueError, match="no endpoint weights"):
        write_rig(tmp_path / "x.glb", rig.replace(E=None), source=shared_data /
                  "characters/gltf/Fox.glb")
    assert not list(tmp_path.iterdir())



def _clean_rigid_file(path):
    """A small file the validator finds clean: a box skinned to hips -> spine, a box hung
    on the spine through a turned mount node (mirrored), a table at the scene's root
    (a prop), and an animation turning the spine."""
    from gltf_files import UBYTE, USHORT, Builder, local_matrices, node_globals, quat_xyzw, write
    from test_io_gltf import BOX_F, BOX_V

    nodes = [{"name": "hips", "translation": [0, 1, 0], "children": [1]},
             {"name": "spine", "translation": [0, 1, 0], "rotation": quat_xyzw([0, 0, 1], 10),
              "children": [2]},
             {"name": "mount", "translation": [0, 0.5, 0.1],
              "rotation": quat_xyzw([1, 1, 0], 30), "children": [3]},
             {"name": "helmet", "mesh": 1, "scale": [-1, 1.5, 0.8]},
             {"name": "body", "mesh": 0, "skin": 0},
             {"name": "table", "mesh": 1, "translation": [3, 0, 0]}]
    G = node_globals(nodes, local_matrices(nodes))
    b = Builder()
    V = 0.2 * BOX_V * [1, 5, 1] + [0, 2, 0]
    J = np.zeros((8, 4), int)
    J[:, 1] = 1
    Wt = np.where(V[:, 1:2] > 2, [[0.2, 0.8, 0, 0]], [[0.8, 0.2, 0, 0]]).astype(np.float32)
    body = {"attributes": {"POSITION": b.add(V), "JOINTS_0": b.add(J, UBYTE),
                           "WEIGHTS_0": b.add(Wt)}, "indices": b.add(BOX_F.ravel(), USHORT)}
    box = {"attributes": {"POSITION": b.add(0.1 * BOX_V)},
           "indices": b.add(BOX_F.ravel(), USHORT)}
    ibm = np.array([np.linalg.inv(G[j]) for j in (0, 1)]).transpose(0, 2, 1).reshape(2, 16)
    turn = {"input": b.add(np.array([0.0, 1.0])),
            "output": b.add(np.array([quat_xyzw([0, 0, 1], 10), quat_xyzw([1, 0, 1], 70)])),
            "interpolation": "LINEAR"}
    doc = {"scene": 0, "scenes": [{"nodes": [0, 4, 5]}], "nodes": nodes,
           "meshes": [{"name": "body", "primitives": [body]},
                      {"name": "box", "primitives": [box]}],
           "skins": [{"joints": [0, 1], "inverseBindMatrices": b.add(ibm, mat4=True)}],
           "animations": [{"name": "turn", "samplers": [turn], "channels": [
               {"sampler": 0, "target": {"node": 1, "path": "rotation"}}]}]}
    return write(path, doc, b, glb=True)


def test_rigid_parts_are_written_back_as_they_were(tmp_path):
    # meshes hung on joints stay unskinned, drawn by their nodes, so the copy draws as
    # the source in any viewer; their endpoint weights are not written (read back: the
    # projection onto their bone), the skinned body's are
    src = _clean_rigid_file(tmp_path / "robot.glb")
    rig, clips = read_gltf(src)
    n = 8
    assert len(rig.V) == n + 8 and [p["node"] for p in rig.meta["gltf"]["rigid"]] == [3]
    ref = Reference(src)
    dfm = stbs.Deformer(rig.V, rig.skeleton, rig.W, method="lbs")
    for t in (0.0, 0.3, 1.0):
        assert np.abs(dfm(clips["turn"].pose(t)) - ref.skin_at(0, t)).max() <= 1e-6
    E = np.random.default_rng(3).uniform(0, 1, (len(rig.V), rig.skeleton.n_bones))
    out = tmp_path / "back.glb"
    write_rig(out, rig.replace(E=E), source=src)
    doc_a, _ = load_raw(src)
    doc_b, _ = load_raw(out)
    assert doc_b["nodes"] == doc_a["nodes"] and doc_b["skins"][0]["joints"] == \
        doc_a["skins"][0]["joints"]
    assert doc_b["meshes"][1] == doc_a["meshes"][1]             # the box
    assert all("_ENDPOINT_WEIGHTS_0" in p["attributes"] for p in doc_b["meshes"][0]
               ["primitives"])
    a, b = validate(src, out)
    assert (a["errors"], a["warnings"]) == (0, 0) and (b["errors"], b["warnings"]) == (0, 0), b
    back, _ = read_gltf(out)
    np.testing.assert_array_equal(back.V, rig.V)
    np.testing.assert_array_equal(back.F, rig.F)
    np.testing.assert_array_equal(back.W, rig.W)
    assert back.meta["gltf"]["rigid"] == rig.meta["gltf"]["rigid"]
    on = np.asarray(rig.W[:n]) > 0
    np.testing.assert_allclose(np.asarray(back.E)[:n][on], E[:n][on], atol=1e-7)
    rows = np.arange(n, len(rig.V))
    cols = np.argmax(rig.W[rows], axis=1)
    want = stbs.weights.projection(rig.V, rig.skeleton)[rows, cols]
    np.testing.assert_allclose(np.asarray(back.E)[rows, cols], want, atol=1e-12)
    assert np.abs(want - E[rows, cols]).max() > 0.1               # E there was dropped
    # new bone weights on a rigid part are not written: a warning names it
    W = np.array(rig.W, dtype=float)
    W[n:n + 8] = 1.0 / W.shape[1]
    with pytest.warns(UserWarning, match="rigid parts 'helmet' have new bone weights"):
        write_rig(tmp_path / "repainted.glb", rig.replace(W=W, E=E), source=src)
    assert validate(tmp_path / "repainted.glb")[0]["errors"] == 0
