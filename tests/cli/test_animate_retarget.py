"""stbs animate CHARACTER --motion CAPTURE.bvh [--mapping MAP.json] -o CLIP.json: the
capture retargeted onto the character, written as a clip (not baked); mapping errors
are one line and exit status 2."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

import stbs
from stbs.cli import main

BVH = "dataset-1_walk_normal_002.bvh"          # Bandai Namco: 31 frames


@pytest.fixture(scope="module")
def inputs(shared_data):
    char = shared_data / "characters" / "gltf" / "CesiumMan.glb"
    bvh = shared_data / "characters" / "bvh" / BVH
    return char, bvh, stbs.io.read_rig(char), stbs.read_bvh(bvh)


def _error(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    return err[0]


def test_the_clip_file_is_the_retargeted_capture(inputs, tmp_path, capsys):
    char, bvh, rig, motion = inputs
    out = tmp_path / "walk.json"
    assert main(["animate", str(char), "--motion", str(bvh), "-o", str(out)]) == 0
    assert f"wrote {out}: a clip of 31 keys" in capsys.readouterr().out
    back = stbs.io.read_clip(out, rig.skeleton)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        want = stbs.retarget(motion, rig)
    np.testing.assert_allclose(back.times, want.times)
    assert back.fps == pytest.approx(want.fps)
    Rb, Ob, sb, tb = back.arrays(back.times)
    Rw, Ow, sw, tw = want.arrays(want.times)
    np.testing.assert_allclose(Rb, Rw, atol=1e-9)
    np.testing.assert_allclose(Ob, Ow, atol=1e-9)
    np.testing.assert_allclose(tb, tw, atol=1e-9)
    # the capture walks: the character travels
    assert np.linalg.norm(Ob[-1, 0] - Ob[0, 0]) > 0.3


def test_frames_and_a_mapping_file(inputs, tmp_path, capsys):
    char, bvh, rig, motion = inputs
    names = {"pelvis": "node2", "l_thigh": "node7", "l_shin": "node8"}
    mp = tmp_path / "map.json"
    mp.write_text(json.dumps({names["pelvis"]: "Hips", names["l_thigh"]: "UpperLeg_L",
                              names["l_shin"]: "LowerLeg_L"}))
    out = tmp_path / "left-leg.json"
    assert main(["animate", str(char), "--motion", str(bvh), "--mapping", str(mp),
                 "--frames", "0:30:3", "-o", str(out)]) == 0
    back = stbs.io.read_clip(out, rig.skeleton)
    assert len(back) == 10
    R, _, _, _ = back.arrays(back.times)
    sk = rig.skeleton
    moved = np.abs(R - R[:1]).max(axis=(0, 2, 3)) > 1e-6
    # the mapped leg moves; the other leg follows the pelvis alone
    assert moved[sk.names.index("node8")]
    other = sk.names.index("node4")
    np.testing.assert_allclose(R[:, other], R[:, sk.names.index("node2")], atol=1e-12)
    want = stbs.retarget(motion, rig, mapping=mp)
    np.testing.assert_allclose(R, want.arrays(back.times)[0], atol=1e-9)


@pytest.mark.parametrize("content, expect", [
    ('{"nope": "Hips"}', "mapping: the rig has no bone 'nope'; its bones are node2, "),
    ('{"node2": "Pelvis"}', "mapping: the motion has no joint 'Pelvis' (for bone 'node2'); "
                            "its joints are joint_Root, Hips, "),
    ("[1, 2]", "expected a JSON object {rig bone: capture joint}, got a JSON list"),
    ("{not json", "not valid mapping JSON"),
])
def test_a_bad_mapping_is_one_line_and_status_2(inputs, tmp_path, capsys, content, expect):
    char, bvh, _, _ = inputs
    mp = tmp_path / "map.json"
    mp.write_text(content)
    out = tmp_path / "x.json"
    assert main(["animate", str(char), "--motion", str(bvh), "--mapping", str(mp),
                 "-o", str(out)]) == 2
    line = _error(capsys)
    assert line.startswith("stbs animate: error: ") and expect in line
    assert not out.exists()


def test_mapping_errors_before_any_work(inputs, tmp_path, capsys):
    char, bvh, rig, _ = inputs
    assert main(["animate", str(char), "--motion", str(bvh), "--mapping",
                 str(tmp_path / "none.json"), "-o", str(tmp_path / "x.json")]) == 2
    assert "mapping file not found" in _error(capsys)
    clip = tmp_path / "c.json"
    stbs.io.write_clip(clip, stbs.Clip([(0.0, stbs.Pose.rest(rig.skeleton))]))
    (tmp_path / "m.json").write_text("{}")
    assert main(["animate", str(char), "--motion", str(clip), "--mapping",
                 str(tmp_path / "m.json"), "-o", str(tmp_path / "x.json")]) == 2
    assert "--mapping applies to a .bvh motion" in _error(capsys)


def test_a_capture_that_maps_to_nothing(inputs, tmp_path, capsys):
    _, bvh, _, _ = inputs
    sk = stbs.Skeleton([[0, 0, 0], [0, 1, 0], [0, 2, 0]], [[0, 1], [1, 2]],
                       names=["Bone", "Bone.001"])
    V, F = stbs.shapes.box(2, 6, 2, size=(0.4, 2.0, 0.4))[:2]
    V = np.asarray(V) + [0, 1.0, 0]
    rig = stbs.build_rig(V, sk, F=F, bone="heat", endpoint="projection")
    stbs.save_rig(tmp_path / "stick.npz", rig)
    assert main(["animate", str(tmp_path / "stick.npz"), "--motion", str(bvh), "-o",
                 str(tmp_path / "x.json")]) == 2
    line = _error(capsys)
    assert line.startswith(f"stbs animate: error: no joint of '{bvh}' maps to a bone of the "
                           f"rig; the rig's bones are Bone, Bone.001; ")
