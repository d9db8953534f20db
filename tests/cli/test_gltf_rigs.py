"""A glTF character is a rig everywhere a rig is accepted: stbs weights adds endpoint
weights and keeps the file's skeleton, bone weights and animations; stbs deform and
stbs view open it directly."""

from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path

import numpy as np
import pytest

import stbs
from stbs.cli import main
from stbs.io import read_gltf, read_rig

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "io"))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "viewer"))
from test_io_gltf_write import validate  # noqa: E402
from test_viewer_cli import View  # noqa: E402


def _sha(p):
    return hashlib.sha256(Path(p).read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def character(shared_data, tmp_path_factory):
    src = shared_data / "gltf" / "RiggedSimple.glb"
    before = _sha(src)
    out = tmp_path_factory.mktemp("gltf") / "rs-stbs.glb"
    assert main(["weights", str(src), "--endpoint", "bbw", "-o", str(out)]) == 0
    assert _sha(src) == before                       # the input is only read
    return src, out


def test_weights_adds_endpoint_weights_and_keeps_the_rest(character):
    src, out = character
    a, clips_a = read_gltf(src)
    b, clips_b = read_gltf(out)
    assert a.E is None and b.E is not None
    np.testing.assert_array_equal(b.V, a.V)
    np.testing.assert_array_equal(b.F, a.F)
    np.testing.assert_array_equal(b.W, a.W)
    np.testing.assert_array_equal(b.C, a.C)
    np.testing.assert_array_equal(b.BE, a.BE)
    assert b.skeleton.names == a.skeleton.names
    # the animation is the file's own, untouched
    assert list(clips_b) == list(clips_a)
    for (ta, pa), (tb, pb) in zip(clips_a["animation_0"].keys, clips_b["animation_0"].keys,
                                  strict=True):
        assert ta == tb
        np.testing.assert_array_equal(pa.rotations, pb.rotations)
    # endpoint weights: in [0, 1], 0 at a bone's start, growing toward its end
    sk = b.skeleton
    E = np.asarray(b.E)
    assert E.min() >= 0 and E.max() <= 1
    t = np.einsum("nd,d->n", b.V - sk.A[0], sk.axes[0]) / sk.lengths[0]
    w0 = np.asarray(b.W)[:, 0] > 0.5
    near, far = w0 & (t < 0.2), w0 & (t > 0.8)
    assert near.any() and far.any()
    assert E[near, 0].mean() < 0.3 < 0.7 < E[far, 0].mean()
    # the nodes, joint orientations and materials are the file's (a copy plus E)
    doc_a = _glb_json(src)
    doc_b = _glb_json(out)
    assert doc_b["nodes"] == doc_a["nodes"]
    assert doc_b["animations"] == doc_a["animations"]
    assert doc_b.get("materials") == doc_a.get("materials")
    assert "_ENDPOINT_WEIGHTS_0" in doc_b["meshes"][0]["primitives"][0]["attributes"]
    assert [r["errors"] for r in validate(out)] == [0]


def _glb_json(p):
    data = Path(p).read_bytes()
    n = int.from_bytes(data[12:16], "little")
    return json.loads(data[20:20 + n])


def test_deform_opens_a_gltf_rig(character, tmp_path, capsys):
    _, out = character
    pose = tmp_path / "p.json"
    pose.write_text('{"rotate": {"1": {"axis": [1, 0, 0], "angle": 60}}, '
                    '"twist": {"1": [0, 120]}}')
    obj = tmp_path / "p.npz"
    assert main(["deform", str(out), "--pose", str(pose), "-o", str(obj)]) == 0
    rig = read_rig(out)
    want = stbs.deform(rig.V, rig.skeleton, stbs.read_pose(pose, rig.skeleton), rig.W, rig.E,
                       method="stbs-dqs")
    np.testing.assert_allclose(np.load(obj)["U"], want)


def test_weights_to_npz_and_errors(character, tmp_path, capsys):
    src, _ = character
    npz = tmp_path / "rs.npz"
    assert main(["weights", str(src), "--endpoint", "projection", "-o", str(npz)]) == 0
    rig = stbs.load_rig(npz)
    np.testing.assert_allclose(rig.E, stbs.weights.projection(rig.V, rig.skeleton))
    capsys.readouterr()
    assert main(["weights", str(src), "-o", str(tmp_path / "x.obj")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "expected a rig file (.npz .gltf .glb)" in err[0]


def test_view_opens_a_gltf_rig(character, tmp_path):
    _, out = character
    with View(out, cwd=tmp_path) as v:
        status, body = v.get("/api/rig")
        info = json.loads(body)
        assert status == 200 and info["vertices"] == 160 and info["has_E"] is True
        assert info["names"] == ["Bone", "Bone.001"]
        code, _, _ = v.stop()
    assert code == 0


def test_skin_and_mesh_pick_what_a_command_reads(shared_data, tmp_path, capsys):
    # Xbot: two meshes on one skin; --mesh reads one alone, --skin the whole skeleton
    xbot = shared_data / "characters" / "gltf" / "threejs_Xbot.glb"
    pose = tmp_path / "p.json"
    pose.write_text('{"rotate": {"mixamorig:Spine": {"axis": [1, 0, 0], "angle": 30}}}')
    sizes = {}
    for flags in ([], ["--mesh", "Beta_Joints"], ["--mesh", "68"], ["--skin", "Armature"]):
        out = tmp_path / "u.npz"
        assert main(["deform", str(xbot), "--pose", str(pose), "--method", "lbs", "-o",
                     str(out), *flags]) == 0, capsys.readouterr().err
        sizes[" ".join(flags)] = len(np.load(out)["U"])
    assert sizes[""] == sizes["--skin Armature"] == 28374
    assert sizes["--mesh Beta_Joints"] + sizes["--mesh 68"] == 28374
    capsys.readouterr()
    # a choice that matches nothing, and the options on a .npz rig: one line, status 2
    npz = tmp_path / "rs.npz"
    stbs.save_rig(npz, read_rig(shared_data / "gltf" / "RiggedSimple.glb"))
    for argv in (["export", str(xbot), "--mesh", "nothing", "-o", str(tmp_path / "x.glb")],
                 ["export", str(npz), "--skin", "0", "-o", str(tmp_path / "x.glb")]):
        assert main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("stbs export: error:"), err
    assert not (tmp_path / "x.glb").exists()
