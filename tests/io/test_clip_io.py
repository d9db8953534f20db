"""Clip files: stbs.io.read_clip / write_clip / clip_to_dict."""

from __future__ import annotations

import json

import numpy as np
import pytest

import stbs
from stbs.io import clip_to_dict, read_clip, write_clip


def _arm():
    return stbs.Skeleton([[0, 0, 0], [1, 0, 0], [2, 0, 0]], [[0, 1], [1, 2]],
                         names=["upper", "fore"])


CLIP = {"fps": 12, "interpolation": "linear", "keys": [
    {"time": 0.0, "pose": {}},
    {"time": 2.0, "pose": {"rotate": {"upper": {"axis": [0, 0, 1], "angle": 90}},
                           "stretch": {"1": 2.0}, "twist": {"fore": [0, 720]}}},
    {"time": 1.0, "pose": {"joints": [[0, 0, 0], [0, 1, 0], [0, 2, 0]], "twist": {"0": [0, 30]}}},
]}


def test_reads_both_pose_forms_and_sorts_the_keys():
    sk = _arm()
    clip = read_clip(CLIP, sk)
    assert clip.fps == 12.0 and clip.interpolation == "linear"
    assert clip.times.tolist() == [0.0, 1.0, 2.0]
    assert clip.keys[0][1].is_rest()
    # keys[2]: the joints form; the upper bone points along +y, 30 degrees of twist at its end
    p1 = clip.keys[1][1]
    assert np.allclose(p1.rotations[0] @ [1, 0, 0], [0, 1, 0])
    assert np.degrees(p1.twist[0, 1]) == pytest.approx(30.0)
    # keys[1]: forward kinematics; the fore's end twist 720 degrees, stretch 2
    p2 = clip.keys[2][1]
    assert np.degrees(p2.twist[1, 1]) == pytest.approx(720.0)
    assert p2.stretch.tolist() == [1.0, 2.0]
    # between the last two keys: twist 720 -> halfway 360 + (half of 0 from the joints key)
    assert np.degrees(clip.pose(1.5).twist[1, 1]) == pytest.approx(360.0)
    assert clip.pose(1.5).stretch[1] == pytest.approx(1.5)


def test_defaults_fps_30_and_linear():
    clip = read_clip({"keys": [{"time": 0, "pose": {}}]}, _arm())
    assert clip.fps == 30.0 and clip.interpolation == "linear"


def test_write_then_read_gives_the_clip_back(tmp_path):
    sk = _arm()
    clip = read_clip(dict(CLIP, interpolation="step"), sk)
    path = tmp_path / "walk.json"
    write_clip(path, clip)
    back = read_clip(path, sk)
    assert back.fps == clip.fps and back.interpolation == "step"
    assert back.times.tolist() == clip.times.tolist()
    for (_, a), (_, b) in zip(clip.keys, back.keys, strict=True):
        for x, y in ((a.rotations, b.rotations), (a.origins, b.origins),
                     (a.stretch, b.stretch), (a.twist, b.twist)):
            assert np.abs(x - y).max() < 1e-12
    # written again: the same file (the JSON is stable under a round trip)
    again = tmp_path / "again.json"
    write_clip(again, back)
    assert _close(json.loads(again.read_text()), json.loads(path.read_text()))
    # no temporary file left beside it
    assert sorted(p.name for p in tmp_path.iterdir()) == ["again.json", "walk.json"]


def _close(a, b, tol=1e-9):
    if isinstance(a, dict):
        return set(a) == set(b) and all(_close(a[k], b[k], tol) for k in a)
    if isinstance(a, list):
        return len(a) == len(b) and all(_close(x, y, tol) for x, y in zip(a, b, strict=True))
    if isinstance(a, float) or isinstance(b, float):
        return abs(a - b) <= tol
    return a == b


def test_clip_to_dict_in_radians_and_joints_form():
    sk = _arm()
    clip = stbs.Clip([(0.0, stbs.Pose.rest(sk)),
                      (1.0, stbs.Pose.from_joints(sk, [[0, 0, 0], [0, 1, 0], [0, 3, 0]]))])
    obj = clip_to_dict(clip, form="joints", degrees=False)
    assert obj["fps"] == 30.0 and obj["interpolation"] == "linear"
    assert [k["time"] for k in obj["keys"]] == [0.0, 1.0]
    assert np.allclose(obj["keys"][1]["pose"]["joints"], [[0, 0, 0], [0, 1, 0], [0, 3, 0]],
                       atol=1e-12, rtol=0)
    assert obj["keys"][1]["pose"]["degrees"] is False
    # a pose the joints form cannot describe (a roll about the bone) names its key
    rolled = stbs.Pose.from_local(sk, rotations=stbs.transforms.axis_angle_to_matrix(
        np.array(sk.axes), np.full(sk.n_bones, 0.5)))
    with pytest.raises(ValueError, match=r"clip keys\[1\] \(time 2\)"):
        clip_to_dict(stbs.Clip([(0.0, clip.pose(0.5)), (2.0, rolled)]), form="joints")


def test_a_failed_write_leaves_the_old_file(tmp_path):
    sk = _arm()
    path = tmp_path / "c.json"
    path.write_text("old")
    rolled = stbs.Pose.from_local(sk, rotations=stbs.transforms.axis_angle_to_matrix(
        np.array(sk.axes), np.full(sk.n_bones, 0.5)))
    with pytest.raises(ValueError):
        write_clip(path, stbs.Clip([(0.0, rolled)]), form="joints")
    assert path.read_text() == "old"


@pytest.mark.parametrize("obj, match", [
    ({"keys": [{"time": 0, "pose": {}}], "loop": True}, r"clip: key 'loop': unknown key"),
    ({"fps": 0, "keys": [{"time": 0, "pose": {}}]}, r'clip: "fps": expected a finite number > 0'),
    ({"fps": "30", "keys": []}, r'clip: "fps": expected a finite number .*, found "30"'),
    ({"interpolation": "cubic", "keys": [{"time": 0, "pose": {}}]},
     r'clip: "interpolation": expected one of "linear", "step", found "cubic"'),
    ({"fps": 30}, r'clip: missing "keys"'),
    ({"keys": []}, r'clip: "keys": expected a non-empty list'),
    ({"keys": [{"time": 0, "pose": {}}, 5]}, r"clip: keys\[1\]: expected an object"),
    ({"keys": [{"time": 0, "pose": {}, "ease": 1}]}, r"clip: keys\[0\]: unexpected key 'ease'"),
    ({"keys": [{"pose": {}}]}, r'clip: keys\[0\]: missing "time"'),
    ({"keys": [{"time": 1}]}, r'clip: keys\[0\]: missing "pose"'),
    ({"keys": [{"time": None, "pose": {}}]}, r'clip: keys\[0\]."time": expected a finite number'),
    ({"keys": [{"time": 1, "pose": {}}, {"time": 1.0, "pose": {}}]},
     r"clip: keys\[1\]: time 1 is also the time of keys\[0\]"),
    ({"keys": [{"time": 0, "pose": {}}, {"time": 1, "pose": {"stretch": {"fore": -1}}}]},
     r'clip: keys\[1\].pose: "stretch" bone \'fore\': stretch must be > 0'),
    ({"keys": [{"time": 0, "pose": {"rotate": {"hand": {"angle": 3}}}}]},
     r'clip: keys\[0\].pose: "rotate": .*hand'),
    ({"keys": [{"time": 0, "pose": [1, 2]}]}, r"clip: keys\[0\].pose: expected a JSON object"),
])
def test_bad_clips_name_the_key_and_the_problem(obj, match):
    with pytest.raises(ValueError, match=match):
        read_clip(obj, _arm())


def test_file_errors_name_the_file(tmp_path):
    sk = _arm()
    with pytest.raises(FileNotFoundError):
        read_clip(tmp_path / "missing.json", sk)
    bad = tmp_path / "bad.json"
    bad.write_text('{"keys": [')
    with pytest.raises(ValueError, match=r"bad\.json, line 1, column 11: not valid clip JSON"):
        read_clip(bad, sk)
    broken = tmp_path / "broken.json"
    broken.write_text(json.dumps({"keys": [{"time": 0, "pose": {"twist": {"upper": [0]}}}]}))
    with pytest.raises(ValueError, match=r"broken\.json: keys\[0\]\.pose: \"twist\" bone "
                                         r"'upper': expected \[start, end\]"):
        read_clip(broken, sk)
    listed = tmp_path / "list.json"
    listed.write_text("[]")
    with pytest.raises(ValueError, match=r"list\.json: expected a JSON object"):
        read_clip(listed, sk)
    with pytest.raises(TypeError, match="path or a dict"):
        read_clip(42, sk)
