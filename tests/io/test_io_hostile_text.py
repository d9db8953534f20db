"""Hostile text files: BVH captures, clip and pose JSON, retargeting mappings.

Each one is refused with one ValueError (a FormatError for a BVH) of one line naming the
file, what was expected and what was found, after work linear in the file at most and
without a large allocation; never a RecursionError, OverflowError, MemoryError, KeyError,
IndexError or a NumPy warning. The command line prints that line and exits 2, writing
nothing."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

import stbs
from stbs.cli import main
from stbs.io import FormatError, read_bvh, read_clip, read_pose
from stbs.io.bvh import MAX_FRAMES, MAX_JOINT_FRAMES, MAX_JOINTS
from stbs.io.clip import MAX_KEY_BONES, MAX_KEYS
from stbs.retargeting import joint_map
from work_count import Lines

DEEP = "[" * 100_000 + "]" * 100_000


def _refusal_budget(path) -> int:
    """Lines of stbs code a refusal may run: work linear in the file at most (reading it
    once), never a pass per joint, key or frame over the others. The cases here take
    under 2000 lines, BVH hierarchies of thousands of joints up to 7 a byte."""
    return 10_000 + 20 * path.stat().st_size


def _refused(call, path, match, *, kind=ValueError, peak_mb=64):
    """``call(path)`` raises one ``kind`` matching ``match`` that names ``path``, within
    :func:`_refusal_budget` lines of stbs code and ``peak_mb`` MiB of allocations; its
    message."""
    tracemalloc.start()
    try:
        with Lines(_refusal_budget(path)), pytest.raises(kind, match=match) as info:
            call(path)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < peak_mb * 2**20, f"{peak / 2**20:.0f} MiB allocated"
    msg = str(info.value)
    assert "\n" not in msg and str(path) in msg and len(msg) < 1000, msg
    return msg


# ------------------------------------------------------------------ BVH
def _bvh(frames="1", frame_time="0.1", values="0 0 0", channels="CHANNELS 3 Zrotation "
         "Xrotation Yrotation", offset="0 0 0", extra=""):
    return (f"HIERARCHY\nROOT r\n{{\n  OFFSET {offset}\n  {channels}\n{extra}  End Site\n  {{\n"
            f"    OFFSET 0 1 0\n  }}\n}}\nMOTION\nFrames: {frames}\nFrame Time: {frame_time}\n"
            f"{values}\n")


def _chain(n, *, frames=1):
    s = "HIERARCHY\nROOT r\n{\nOFFSET 0 0 0\nCHANNELS 3 Zrotation Xrotation Yrotation\n"
    s += "".join(f"JOINT j{i}\n{{\nOFFSET 0 1 0\nCHANNELS 1 Zrotation\n" for i in range(n))
    s += "}\n" * (n + 1) + f"MOTION\nFrames: {frames}\nFrame Time: 0.1\n"
    return s + ("0 0 0" + " 5" * n + "\n") * frames


def _still(n):
    """A BVH of two joints and no channel, declaring ``n`` frames and giving no line."""
    return ("HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0 0\n  CHANNELS 0\n  JOINT Spine\n  {\n"
            f"    OFFSET 0 1 0\n    CHANNELS 0\n  }}\n}}\nMOTION\nFrames: {n}\n"
            "Frame Time: 0.0333333\n")

BVH_CASES = [
    # a million (a billion) frames of no channels: once 187 s and 2.3 GB (a 67 GiB array)
    (_still(1_000_000), r"line 14: expected 1000000 frame lines .*found none"),
    (_still(1_000_000) + "\n" * 10,
     r"expected 1000000 frame lines .*found 10"),
    (_still(10**9), rf"line 13: expected at most {MAX_FRAMES} frames .*"
                                  r"found 'Frames: 1000000000'"),
    (_still("1" + "0" * 400), r"line 13: expected 'Frames: N' with N a whole"),
    (_bvh(frames="1_0"), r"expected 'Frames: N'"),
    (_bvh(frames="+1"), r"expected 'Frames: N'"),
    (_bvh(frames="\u0661"), r"expected 'Frames: N'"),
    # frames × joints beyond the limit: refused before the values are even counted
    (_chain(30, frames=1).replace("Frames: 1", f"Frames: {MAX_JOINT_FRAMES // 31 + 1}"),
     rf"expected at most {MAX_JOINT_FRAMES} frames × joints .*found \d+ frames × 31 joints"),
    # Frame Time: a finite number of seconds within bounds
    (_bvh(frame_time="nan"), r"line 13: expected 'Frame Time: SECONDS' with a number from "
                             r"1e-06 to 3600, found 'Frame Time: nan'"),
    (_bvh(frame_time="inf"), r"'Frame Time: SECONDS'"),
    (_bvh(frame_time="1e308"), r"'Frame Time: SECONDS'"),
    (_bvh(frame_time="-0.1"), r"'Frame Time: SECONDS'"),
    (_bvh(frame_time="1e-9"), r"'Frame Time: SECONDS'"),
    (_bvh(frame_time="7200"), r"'Frame Time: SECONDS'"),
    (_bvh(frame_time="1_0"), r"'Frame Time: SECONDS'"),
    # values: finite, bounded, with their line
    (_bvh(values="0 inf 0"), r"line 14: expected a number in the MOTION block \(finite, of "
                             r"magnitude at most 1e\+06\), found 'inf'"),
    (_bvh(values="0 0 1e308"), r"line 14: .*found '1e308'"),
    (_bvh(frames=2, values="0 0 0\n0 -NaN 0"), r"line 15: .*found '-NaN'"),
    (_bvh(values="0 0x10 0"), r"line 14: .*found '0x10'"),
    (_bvh(offset="0 nan 0"), r"line 4: expected an OFFSET value of 'r', found 'nan' "
                             r"\(not finite\)"),
    (_bvh(offset="0 1e300 0"), r"line 4: expected an OFFSET value of 'r' of magnitude at most"),
    (_bvh(offset="0 1 true"), r"line 4: expected an OFFSET value of 'r', found 'true'"),
    # channel counts and lists
    (_bvh(channels="CHANNELS 99999999999999999999999 Xrotation"), r"0 to 6 channels"),
    (_bvh(channels="CHANNELS -1"), r"0 to 6 channels"),
    (_bvh(channels="CHANNELS 3.0 Xrotation Yrotation Zrotation"), r"0 to 6 channels"),
    (_bvh(channels="CHANNELS 3 Xrotation"), r"3 channel names for 'r'|a channel name"),
    # a second OFFSET or CHANNELS line: refused, not merged or overwritten
    (_bvh(extra="  OFFSET 1 2 3\n"), r"line 6: expected one OFFSET line in 'r', found a second"),
    (_bvh(extra="  CHANNELS 1 Xposition\n"), r"line 6: expected one CHANNELS line in 'r'"),
    # names: bounded, unique
    (_bvh().replace("ROOT r", "ROOT " + "x" * 300), r"a joint name of at most 256 characters"),
    (_bvh(extra="  JOINT r_end\n  {\n OFFSET 0 0 0\n  }\n"), r"a joint name not used before"),
    # no content, garbage, a cut hierarchy
    ("", r"line 1: expected 'HIERARCHY' first, found an empty file"),
    (" \n\t\n", r"expected 'HIERARCHY' first, found an empty file"),
    ("\x00\xff\xfe garbage", r"line 1: expected 'HIERARCHY' first"),
    ("HIERARCHY\nROOT a\n{\nOFFSET 0 0 0\n" + "".join(f"JOINT b{k}\n{{\nOFFSET 0 1 0\n"
                                                     for k in range(2000)),
     r"line 6004: expected 'OFFSET', 'CHANNELS', .*found end of file"),
    (_bvh().replace("Frame Time: 0.1\n", ""), r"line 13: expected a line 'Frame Time: \.\.\.', "
                                               r"found '0 0 0'"),
]


@pytest.mark.parametrize("text, match", BVH_CASES)
def test_a_hostile_bvh_is_one_format_error(tmp_path, text, match):
    path = tmp_path / "hostile.bvh"
    path.write_bytes(text.encode("utf-8"))
    _refused(read_bvh, path, match, kind=FormatError)


def test_too_many_joints(tmp_path):
    path = tmp_path / "many.bvh"
    path.write_text("HIERARCHY\n" + "".join(f"ROOT a{k}\n{{\nOFFSET 0 0 0\n}}\n"
                                           for k in range(MAX_JOINTS + 1)))
    _refused(read_bvh, path, rf"expected at most {MAX_JOINTS} joints \(end sites included\), "
                             rf"found joint {MAX_JOINTS + 1}, 'a{MAX_JOINTS}'", kind=FormatError)


def test_a_hierarchy_thousands_deep_reads_without_recursion(tmp_path):
    # once a RecursionError at about 1000 deep; the motion's kinematics and skeleton
    # are loops over the joints too
    path = tmp_path / "deep.bvh"
    path.write_text(_chain(3000, frames=2))
    m = read_bvh(path)
    assert m.n_joints == 3001 and m.parents[-1] == 2999
    P = m.positions()
    assert np.isfinite(P).all()
    # every joint turns 5 degrees about z: the chain curls, each link of length 1
    np.testing.assert_allclose(np.linalg.norm(np.diff(P[0], axis=0), axis=1), 1.0)
    sk, drive, end = m.skeleton()
    assert sk.n_bones == 3000 and drive.tolist() == list(range(3000))


def test_many_roots_make_a_skeleton_in_linear_work(tmp_path):
    # Motion.skeleton grouped a root's bones by scanning every bone per root (quadratic):
    # four times the roots cost about four times the lines of stbs code, not sixteen
    def wide(n):
        path = tmp_path / f"wide{n}.bvh"
        path.write_text("HIERARCHY\n" + "".join(
            f"ROOT a{k}\n{{\nOFFSET 0 0 0\nCHANNELS 1 Zrotation\nJOINT b{k}\n{{\n"
            f"OFFSET 0 1 0\n}}\n}}\n" for k in range(n))
            + "MOTION\nFrames: 1\nFrame Time: 0.1\n" + " 0" * n)
        return read_bvh(path)

    n = 4000
    small, m = wide(n // 4), wide(n)
    small.skeleton()                                    # first calls fill caches
    with Lines() as w:
        small.skeleton()
    with Lines(5 * w.count):                            # stopped there if it runs over
        sk, _, _ = m.skeleton()
    assert sk.n_bones == n and (sk.parents == -1).all()


def test_frame_lines_of_no_channels_and_the_limits_keywords(tmp_path):
    path = tmp_path / "still.bvh"
    path.write_text(_still(3) + "\n\n\n")
    m = read_bvh(path)
    assert m.n_frames == 3 and m.channels.shape == (3, 0)
    with pytest.raises(FormatError, match=r"expected at most 2 frames \(read_bvh's max_frames\)"):
        read_bvh(path, max_frames=2)
    with pytest.raises(FormatError, match=r"expected at most 5 frames × joints"):
        read_bvh(path, max_joint_frames=5)
    assert read_bvh(path, max_frames=3, max_joint_frames=6).n_frames == 3
    for bad in (0, -1, 2.5, True, "3"):
        with pytest.raises(ValueError, match="max_frames must be a whole number >= 1"):
            read_bvh(path, max_frames=bad)


def test_wrapped_and_one_line_motion_blocks_read_alike(tmp_path):
    # the MOTION block is read in pieces: a block on one line, or wrapped anywhere,
    # gives the same values
    n = 40_000
    rows = np.arange(3 * n, dtype=float).reshape(n, 3) % 360
    lines = "\n".join(" ".join(f"{v:g}" for v in r) for r in rows)
    one = " ".join(f"{v:g}" for v in rows.ravel())
    for name, body in (("lines", lines), ("one", one), ("wrapped", one.replace(" ", "\n"))):
        path = tmp_path / f"{name}.bvh"
        path.write_text(_bvh(frames=n, values=body))
        np.testing.assert_array_equal(read_bvh(path).channels, rows, err_msg=name)
    bad = one.split(" ")
    bad[-7] = "x"
    path = tmp_path / "bad.bvh"
    path.write_text(_bvh(frames=n, values=" ".join(bad)))
    _refused(read_bvh, path, r"line 14: expected a number in the MOTION block .*found 'x'",
             kind=FormatError)


# ------------------------------------------------------------------ clip and pose files
def _arm():
    return stbs.Skeleton([[0, 0, 0], [1, 0, 0], [2, 0, 0]], [[0, 1], [1, 2]],
                         names=["upper", "fore"])


def _key(pose="{}", time="0"):
    return f'{{"time": {time}, "pose": {pose}}}'


def _clip(*keys, head='"fps": 30'):
    return f'{{{head}, "keys": [{", ".join(keys or (_key(),))}]}}'


CLIP_CASES = [
    # nesting 100 000 deep: once a RecursionError
    (DEEP, r"expected clip JSON nested at most 64 deep, found nesting 100000 deep"),
    (_clip(_key(pose=DEEP)), r"nested at most 64 deep"),
    # 401 digits, 1.7e308: once an OverflowError
    (_clip(_key(time="1" + "0" * 400)), r"integers of at most 20 digits, found one of 401"),
    (_clip(_key(time="1.7e308"), _key(time="-1.7e308")),
     r'keys\[0\]\."time": expected a finite number \(seconds\) of magnitude at most 1e\+06, '
     r"found 1.7e\+308"),
    (_clip(_key(time="1e999")), r"finite numbers?, found '1e999'|finite number"),
    (_clip(_key(time="NaN")), r"finite numbers, found NaN"),
    (_clip(_key(time="true")), r'keys\[0\]\."time": expected a finite number.*found true'),
    (_clip(_key(time='"0"')), r'keys\[0\]\."time": .*found "0"'),
    (_clip(_key(time="null")), r'keys\[0\]\."time": .*found null'),
    # fps: finite, > 0, at most 1000
    (_clip(head='"fps": 0'), r'"fps": expected a finite number > 0 and <= 1000'),
    (_clip(head='"fps": 1e9'), r'"fps": expected .* found 1000000000.0'),
    (_clip(head='"fps": 1' + "0" * 19), r'"fps": expected .*found 10000000000000000000\b'),
    (_clip(head='"fps": true'), r'"fps": expected .*found true'),
    (_clip(head='"fps": [30]'), r'"fps": expected .*found \[30\]'),
    # structure
    ("", r"line 1, column 1: not valid clip JSON"),
    ("\xff\xfe", r"expected UTF-8 clip JSON text"),
    ("[]", r"expected a JSON object"),
    ('{"keys": {}}', r'"keys": expected a non-empty list'),
    ('{"keys": [' + ", ".join(["0"] * 100_001) + "]}",
     r'"keys": expected at most 100000 keys, found 100001'),
    ('{"keys": [true]}', r"keys\[0\]: expected an object"),
    (_clip(head='"fps": 30, "fps": 60'), r'expected each key once in a JSON object, found "fps" '
                                         r"twice"),
    (_clip(_key(pose='{"stretch": {"upper": 2, "upper": 3}}')), r'found "upper" twice'),
    (_clip(head='"interpolation": "' + "x" * 100_000 + '"'), r'"interpolation": expected one'),
    (_clip(head='"' + "k" * 100_000 + '": 1'), r"key 'kkkk.*\.\.\.': unknown key"),
    # poses: bones that exist, numbers within bounds
    (_clip(_key(pose='{"stretch": {"nope": 2}}')), r"keys\[0\]\.pose: \"stretch\": bone 'nope' "
                                                  r"does not exist; bones are 0\.\.1"),
    (_clip(_key(pose='{"stretch": {"99999999999999999999999": 2}}')), r"does not exist"),
    (_clip(_key(pose='{"stretch": {"-1": 2}}')), r"bone '-1' does not exist"),
    (_clip(_key(pose='{"stretch": {"\u0661": 2}}')), r"does not exist"),
    (_clip(_key(pose='{"stretch": {"' + "b" * 10_000 + '": 2}}')), r"bone 'bbb.*\.\.\.' does"),
    (_clip(_key(pose='{"stretch": {"upper": 1e300}}')),
     r"\"stretch\" bone 'upper': expected a number of magnitude at most 1e\+06"),
    (_clip(_key(pose='{"stretch": {"upper": 1e-300}}')),
     r"expected a stretch from 1e-06 to 1e\+06 .*found 1e-300"),
    (_clip(_key(pose='{"stretch": {"upper": "2"}}')), r"expected a number, found \"2\""),
    (_clip(_key(pose='{"twist": {"fore": [0, 1e300]}}')), r"\[1\]: expected a number of "
                                                          r"magnitude at most"),
    (_clip(_key(pose='{"translate": [0, -1e300, 0]}')), r'"translate"\[1\]: expected a number'),
    (_clip(_key(pose='{"rotate": {"upper": {"axis": [0, 0, 1], "angle": 1e300}}}')),
     r'"angle": expected a number of magnitude at most'),
    (_clip(_key(pose='{"joints": [[0, 0, 0], [1e300, 0, 0], [0, 0, 0]]}')),
     r'"joints"\[1\]\[0\]: expected a number of magnitude'),
    (_clip(_key(pose='{"joints": [[0, 0, 0], [0, 0, 0], [1, 0, 0]]}')),
     r'"joints": .*zero posed length'),
    (_clip(_key(pose='{"joints": [[0, 0, 0], [1e-9, 0, 0], [1, 0, 0]]}')),
     r'"joints": bone 0 \(\'upper\'\): expected a posed length from 1e-06 to 1e\+06 times'),
]


@pytest.mark.parametrize("text, match", CLIP_CASES)
def test_a_hostile_clip_file_is_one_value_error(tmp_path, text, match):
    path = tmp_path / "hostile.json"
    path.write_bytes(text.encode("utf-8", "surrogateescape") if text != "\xff\xfe"
                     else b"\xff\xfe")
    _refused(lambda p: read_clip(p, _arm()), path, match)


@pytest.mark.parametrize("text, match", [
    (DEEP, r"expected pose JSON nested at most 64 deep"),
    ('{"stretch": {"upper": 1' + "0" * 400 + "}}", r"integers of at most 20 digits"),
    ('{"stretch": {"upper": 2}, "stretch": {}}', r'found "stretch" twice'),
    ('{"rotate": {"upper": {"axis": [0, 0, 1], "angle": 90, "angle": 0}}}', r'"angle" twice'),
    ('{"rotate": {"0": {"axis": [0, 0, 1], "angle": 1}, "upper": {"axis": [1, 0, 0], '
     '"angle": 1}}}', r"bone 0 \('upper'\) is given twice \(also as '0'\)"),
    ('{"rotate": {"upper": {"axis": [0, 0, 1e300], "angle": 1}}}', r"magnitude at most"),
    ('{"rotate": {"upper": {"axis": [0, 0, true], "angle": 1}}}', r"expected a number"),
    ('{"degrees": 1}', r'"degrees": expected true or false, found 1'),
    ('{"joints": [[0, 0, 0], [0, 0, 0, 0], [1, 0, 0]]}', r'"joints"\[1\]: expected a 3D'),
    ('{"joints": "' + "j" * 100_000 + '"}', r'"joints": expected 3 posed joint positions'),
    ("null", r"expected a JSON object"),
])
def test_a_hostile_pose_file_is_one_value_error(tmp_path, text, match):
    path = tmp_path / "hostile.json"
    path.write_text(text)
    _refused(lambda p: read_pose(p, _arm()), path, match)


def test_a_parsed_pose_or_clip_of_python_values(tmp_path):
    # what the viewer hands over: Python ints of any length, NaN floats, any key types,
    # containers nested deeper than json.dumps can render
    sk = _arm()
    deep: list = []
    for _ in range(10_000):
        deep = [deep]
    for obj, match in [
        ({"stretch": {"upper": 10**400}}, r"magnitude at most 1e\+06, found <an integer of "),
        ({"stretch": {"upper": float("nan")}}, r"expected a finite number, found NaN"),
        ({"stretch": {("a",): 1}}, r"bone \[\"a\"\] does not exist"),
        ({1: 2, "x": 3}, r"key 1: unknown key"),
        ({"stretch": deep}, r'"stretch": expected an object \{bone: value\}, found \[\[\['),
        ({"stretch": {5: 1}}, r"bone 5 does not exist"),
    ]:
        with pytest.raises(ValueError, match=match) as info:
            read_pose(obj, sk)
        assert len(str(info.value)) < 300
    for obj, match in [
        ({"keys": [{"time": 10**400, "pose": {}}]}, r'"time": expected a finite number'),
        ({"keys": [{"time": 0, "pose": {}}], "fps": float("inf")}, r'"fps": expected'),
        ({"keys": deep}, r'keys\[0\]: expected an object'),
        ({"keys": [{"time": 0, "pose": {}, 3: 4}]}, r"unexpected key 3"),
    ]:
        with pytest.raises(ValueError, match=match):
            read_clip(obj, sk)


def test_a_clip_at_the_key_limits(tmp_path):
    # 100 000 keys read with no pose made for each key (once a minute): about 120 lines
    # of stbs code a key, where a pose of its own costs 500 more; keys × bones beyond the
    # limit are refused before any pose is read
    def long(n):
        path = tmp_path / f"long{n}.json"
        path.write_text(_clip(*(_key(time=f"{k / 30!r}",
                                     pose='{"rotate": {"fore": {"axis": [0, 0, 1], "angle": '
                                          f'{k % 360}}}}}}}') for k in range(n))))
        return path

    read_clip(long(2), _arm())                          # first calls fill caches
    with Lines(200 * 2000):                             # stopped there if it runs over
        read_clip(long(2000), _arm())
    path = long(MAX_KEYS)
    clip = read_clip(path, _arm())
    assert len(clip) == MAX_KEYS and clip.end == pytest.approx((MAX_KEYS - 1) / 30)
    np.testing.assert_allclose(clip.pose(1.0).rotations[1] @ [1, 0, 0],
                               [np.cos(np.radians(30)), np.sin(np.radians(30)), 0], atol=1e-12)
    wide = stbs.Skeleton(np.arange(102)[:, None] * [1.0, 0, 0], np.c_[:101, 1:102])
    n = MAX_KEY_BONES // 101 + 1
    path.write_text('{"keys": [' + ", ".join(["0"] * n) + "]}")
    _refused(lambda p: read_clip(p, wide), path, rf'"keys": expected at most {MAX_KEY_BONES} '
                                                 rf"keys × bones, found {n} keys × 101 bones")


def test_legitimate_extremes_still_read(tmp_path):
    sk = _arm()
    path = tmp_path / "ok.json"
    path.write_text(_clip(
        _key(time="-1e6", pose='{"twist": {"fore": [0, 7200]}}'),
        _key(time="1e6", pose='{"rotate": {"upper": {"axis": [1e-200, 0, 0], "angle": 180}},'
                              ' "stretch": {"fore": 1e6}}'),
        # the joints form with a bone turned right round (antipodal directions)
        _key(time="3", pose='{"joints": [[0, 0, 0], [-1, 0, 0], [0, 0, 0]]}'),
        head='"fps": 1000, "interpolation": "step"'))
    clip = read_clip(path, sk)
    assert clip.times.tolist() == [-1e6, 3.0, 1e6] and clip.fps == 1000.0
    assert np.degrees(clip.keys[0][1].twist[1, 1]) == pytest.approx(7200)
    np.testing.assert_allclose(clip.keys[2][1].rotations[0], np.diag([1.0, -1, -1]),
                               atol=1e-12)
    np.testing.assert_allclose(clip.keys[1][1].rotations[0] @ [1, 0, 0], [-1, 0, 0],
                               atol=1e-12)
    assert np.isfinite(clip.arrays(np.linspace(-2e6, 2e6, 9))[1]).all()


# ------------------------------------------------------------------ mapping files
@pytest.fixture(scope="module")
def capture(tmp_path_factory):
    path = tmp_path_factory.mktemp("capture") / "walk.bvh"
    path.write_text(_chain(3, frames=2).replace("ROOT r", "ROOT Hips"))
    return read_bvh(path)


@pytest.mark.parametrize("text, match", [
    (DEEP, r"expected mapping JSON \{rig bone: capture joint\} nested at most 64 deep"),
    ('{"upper": ' + DEEP + "}", r"nested at most 64 deep, found nesting 100001 deep"),
    ('{"upper": 1' + "0" * 400 + "}", r"mapping JSON \{rig bone: capture joint\} with "
                                      r"integers of at most 20 digits, found one of 401"),
    ('{"upper": 5}', r"the motion has no joint 5 \(for bone 'upper'\)"),
    ('{"upper": NaN}', r"with finite numbers, found NaN"),
    ('{"upper": "Hips", "upper": "j0"}', r"expected each key once in a JSON object, found "
                                         r'"upper" twice'),
    ('{"0": "Hips", "upper": "j0"}', r"bone 0 \('upper'\) is given twice \(as '0' and 'upper'\)"),
    ('{"99999999999999999999999999": "Hips"}', r"the rig has no bone '9999.*'; its bones are "
                                              r"upper, fore"),
    ('{"-1": "Hips"}', r"the rig has no bone '-1'"),
    ('{"' + "n" * 100_000 + '": "Hips"}', r"the rig has no bone 'nnnn.*\.\.\.'"),
    ('{"upper": "' + "j" * 100_000 + '"}', r"no joint 'jjjj.*\.\.\.' \(for bone 'upper'\)"),
    ('{"upper": "j2_end"}', r"no joint 'j2_end'"),
    ('{"upper": ["Hips"]}', r"no joint a list"),
    ('{"upper": {"a": "Hips"}}', r"no joint an object"),
    ("[1, 2]", r"expected a JSON object \{rig bone: capture joint\}, got a JSON list"),
    ('{"upper": null}', r"mapping: expected a capture joint for some bone, found none \(every "
                        r"bone null or left out\); the rig's bones are upper, fore; the joints "
                        r"of '.*walk.bvh' are Hips, j0, j1, j2"),
    ("{}", r"expected a capture joint for some bone, found none"),
    ("", r"line 1, column 1: not valid mapping JSON"),
])
def test_a_hostile_mapping_file_is_one_value_error(tmp_path, capture, text, match):
    path = tmp_path / "map.json"
    path.write_text(text)
    _refused(lambda p: joint_map(capture, _arm(), mapping=p), path, match)


def test_a_mapping_file_reads(tmp_path, capture):
    path = tmp_path / "map.json"
    path.write_text('{"upper": "Hips", "1": null}')
    assert joint_map(capture, _arm(), mapping=path) == {"upper": "Hips", "fore": None}


# ------------------------------------------------------------------ the command line
@pytest.mark.parametrize("name, text, mapping", [
    ("million.bvh", _still(1_000_000), None),
    ("deep.json", DEEP, None),
    ("far.json", _clip(_key(time="1.7e308"), _key(time="-1.7e308")), None),
    ("digits.json", _clip(_key(time="1" + "0" * 400)), None),
    ("walk.bvh", _chain(2).replace("ROOT r", "ROOT Hips"), DEEP),
])
def test_the_command_line_says_one_line_and_writes_nothing(shared_data, tmp_path, capsys, name,
                                                            text, mapping):
    rig = shared_data / "gltf" / "SimpleSkin.gltf"
    motion = tmp_path / name
    motion.write_text(text)
    out = tmp_path / "out.npz"
    argv = ["animate", str(rig), "--motion", str(motion), "-o", str(out)]
    if mapping is not None:
        (tmp_path / "map.json").write_text(mapping)
        argv += ["--mapping", str(tmp_path / "map.json")]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("stbs animate: error: "), err
    assert (mapping is None and str(motion) in err[0]) or "map.json" in err[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        [name] + (["map.json"] if mapping is not None else []))
