"""BVH motion capture: stbs.io.read_bvh -> stbs.Motion, on hand-made quirk files and the
CMU clips."""

from __future__ import annotations

import numpy as np
import pytest

import stbs
from stbs.io import FormatError, read_bvh


def _write(tmp_path, text: str, name="m.bvh", newline="\n"):
    p = tmp_path / name
    p.write_bytes(text.replace("\n", newline).encode())
    return p


def _chain(channels: str, values: str, child_offset="1 0 0"):
    return f"""HIERARCHY
ROOT root
{{
  OFFSET 0 0 0
  CHANNELS {len(channels.split())} {channels}
  JOINT child
  {{
    OFFSET {child_offset}
    CHANNELS 0
    End Site
    {{
      OFFSET 0 2 0
    }}
  }}
}}
MOTION
Frames: 1
Frame Time: 0.1
{values}
"""


@pytest.mark.parametrize("channels, values, expected", [
    # Rz(90) maps x to y
    ("Zrotation Xrotation Yrotation", "90 0 0", [0, 1, 0]),
    # R = Rx(90) Rz(90): x -> y (Rz) -> z (Rx)
    ("Xrotation Zrotation", "90 90", [0, 0, 1]),
    # R = Rz(90) Rx(90): x -> x (Rx) -> y (Rz)
    ("Zrotation Xrotation", "90 90", [0, 1, 0]),
    # R = Ry(90): x -> -z
    ("Yrotation", "90", [0, 0, -1]),
])
def test_the_rotation_is_the_product_of_the_channels_in_their_order(tmp_path, channels,
                                                                    values, expected):
    m = read_bvh(_write(tmp_path, _chain(channels, values)))
    assert m.names == ["root", "child", "child_end"]
    np.testing.assert_allclose(m.positions()[0, 1], expected, atol=1e-12)


def test_positions_end_sites_roots_and_rest(tmp_path):
    text = """HIERARCHY
ROOT a
{
  OFFSET 1 2 3
  CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation
  JOINT b
  {
    OFFSET 0 0 0
    CHANNELS 4 Xposition Zrotation Yposition Xrotation
    End Site
    {
      OFFSET 0 1 0
    }
  }
}
ROOT c
{
  OFFSET 5 0 0
  CHANNELS 3 Xrotation Yrotation Zrotation
}
MOTION
Frames: 2
Frame Time: .25
0 0 0 0 0 0   0 0 0 0   0 0 0
10 20 30 90 0 0   2 0 3 0   0 0 180
"""
    m = read_bvh(_write(tmp_path, text))
    assert m.names == ["a", "b", "b_end", "c"]
    assert m.parents.tolist() == [-1, 0, 1, -1]
    assert m.end_site.tolist() == [False, False, True, False]
    assert m.n_frames == 2 and m.fps == 4.0
    np.testing.assert_array_equal(m.times, [0, 0.25])
    np.testing.assert_allclose(m.rest_positions(), [[1, 2, 3], [1, 2, 3], [1, 3, 3], [5, 0, 0]])
    # frame 0: a's position channels put it at the world origin, b on it
    np.testing.assert_allclose(m.positions(0)[0], [[0, 0, 0], [0, 0, 0], [0, 1, 0], [5, 0, 0]],
                               atol=1e-12)
    # frame 1: a at (10, 20, 30) turned Rz(90); b's local translation (2, 3, 0) (its
    # position channels in place of the offset) -> (-3, 2, 0); b's own rotation is the
    # identity, so its end site's (0, 1, 0) turns with a: Rz(90) (0, 1, 0) = (-1, 0, 0).
    P = m.positions(1)[0]
    np.testing.assert_allclose(P[0], [10, 20, 30], atol=1e-12)
    np.testing.assert_allclose(P[1], [7, 22, 30], atol=1e-12)
    np.testing.assert_allclose(P[2], [6, 22, 30], atol=1e-12)
    np.testing.assert_allclose(P[3], [5, 0, 0], atol=1e-12)
    assert m.channels.shape == (2, 13)
    assert m.channel_names[6:10] == ["b.Xposition", "b.Zrotation", "b.Yposition", "b.Xrotation"]


def test_line_ends_case_tabs_and_wrapped_frames(tmp_path):
    base = _chain("Xposition Yposition Zposition Zrotation Xrotation Yrotation",
                  "1 2 3 90 0 0")
    ref = read_bvh(_write(tmp_path, base, "ref.bvh"))
    mixed = base.replace("OFFSET 0 0 0\n", "OFFSET 0 0 0\r\n").replace("{\n", "{\r")
    weird = mixed.replace("  ", "\t").replace("HIERARCHY", "hierarchy").replace(
        "End Site", "end site").replace("1 2 3 90 0 0", "1 2 3\n90 0 0\n\n")
    for name, text, nl in [("crlf.bvh", base, "\r\n"), ("cr.bvh", base, "\r"),
                           ("mixed.bvh", mixed, "\n"), ("weird.bvh", weird, "\n")]:
        m = read_bvh(_write(tmp_path, text, name, nl))
        assert m.names == ref.names, name
        np.testing.assert_array_equal(m.positions(), ref.positions())


def _motion_block(n_frames, lines, n_ch=3):
    head = """HIERARCHY
ROOT r
{
  OFFSET 0 0 0
  CHANNELS 3 Zrotation Xrotation Yrotation
}
MOTION
"""
    return head + f"Frames: {n_frames}\nFrame Time: 0.1\n" + "\n".join(lines) + "\n"


@pytest.mark.parametrize("text, match", [
    ("", "expected 'HIERARCHY' first, found an empty file"),
    ("HIERARCHY\nJOINT x\n", "line 2: expected 'ROOT'"),
    ("HIERARCHY\nROOT r\n{\n  OFFSET 0 0\n}\n",
     r"line 5: expected an OFFSET value of 'r', found '\}'"),
    ("HIERARCHY\nROOT r\n{\n  OFFSET 0 0 0\n  CHANNELS 2 Xrotation Wrotation\n}\n",
     "line 5: expected a channel name"),
    ("HIERARCHY\nROOT r\n{\n  OFFSET 0 0 0\n  CHANNELS 7 Xrotation\n}\n", "0 to 6 channels"),
    ("HIERARCHY\nROOT r\n{\n  OFFSET 0 0 0\n  CHANNELS 2 Xrotation Xrotation\n}\n",
     "each channel of 'r' once"),
    ("HIERARCHY\nROOT r\n{\n  OFFSET 0 0 0\n  JOINT r\n  {\n  OFFSET 0 0 0\n  }\n}\n",
     "line 5: expected a joint name not used before, found 'r'"),
    ("HIERARCHY\nROOT r\n{\n  CHANNELS 0\n}\nMOTION\nFrames: 1\nFrame Time: 1\n\n",
     "expected an OFFSET line in 'r'"),
    ("HIERARCHY\nROOT r\n{\n  OFFSET 0 0 0\n", "line 4: expected 'OFFSET'.*found end of file"),
    ("HIERARCHY\nROOT r\n{\n  OFFSET 0 0 0\n}\n", "expected a 'MOTION' line"),
    ("HIERARCHY\nROOT r\n{\n  OFFSET 0 0 0\n  MOTION\n", "found 'MOTION'"),
    (_motion_block("x", ["0 0 0"]), "line 8: expected 'Frames: N'"),
    (_motion_block(0, []), "'Frames: N' with N a whole number >= 1"),
    (_motion_block(1, ["0 0 0"]).replace("Frame Time: 0.1", "Frame Time: 0"),
     "line 9: expected 'Frame Time: SECONDS' with a number from 1e-06 to 3600"),
    (_motion_block(1, ["0 0 0"]).replace("Frame Time: 0.1", "Frametime 1"), "'Frame Time: ...'"),
    # truncated: 3 frames announced, 2 given
    (_motion_block(3, ["0 0 0", "0 0 0"]),
     r"line 11: expected 3 frames of 3 values \(9 numbers; 'Frames: 3'\), found 6 numbers "
     r"\(a truncated MOTION block\)"),
    # a frame line one value short
    (_motion_block(2, ["0 0 0", "0 0"]),
     r"line 11: expected 2 frames of 3 values .*found 5 numbers \(a truncated MOTION block or "
     r"a frame line of 2 values\)"),
    (_motion_block(1, ["0 0 0 0"]), r"found 4 numbers \(a frame line of 4 values\)"),
    (_motion_block(1, ["0 x 0"]), r"line 10: expected a number in the MOTION block .*, found 'x'"),
    (_motion_block(1, ["0 nan 0"]), r"line 10: expected a number in the MOTION block \(finite"),
])
def test_malformed_files_name_the_line(tmp_path, text, match):
    with pytest.raises(FormatError, match=match):
        read_bvh(_write(tmp_path, text))


def test_missing_file(tmp_path):
    with pytest.raises(FileNotFoundError):
        read_bvh(tmp_path / "none.bvh")


def test_motion_checks_its_arguments():
    R = np.tile(np.eye(3), (1, 2, 1, 1))
    ok = dict(rotations=R, frame_time=0.1)
    stbs.Motion(["a", "b"], [-1, 0], np.zeros((2, 3)), **ok)
    with pytest.raises(ValueError, match="names must be unique, got 'a' twice"):
        stbs.Motion(["a", "a"], [-1, 0], np.zeros((2, 3)), **ok)
    with pytest.raises(ValueError, match=r"parents\[0\] must be -1 or a joint before 0, got 1"):
        stbs.Motion(["a", "b"], [1, -1], np.zeros((2, 3)), **ok)
    with pytest.raises(ValueError, match="proper rotations"):
        stbs.Motion(["a", "b"], [-1, 0], np.zeros((2, 3)), rotations=-R, frame_time=0.1)
    with pytest.raises(ValueError, match="frame_time must be a positive"):
        stbs.Motion(["a", "b"], [-1, 0], np.zeros((2, 3)), rotations=R, frame_time=0)
    m = stbs.Motion(["a", "b"], [-1, 0], [[0, 0, 0], [0, 1, 0]], **ok)
    with pytest.raises(ValueError, match=r"frames must lie in 0..0, got 3"):
        m.positions(3)
    with pytest.raises(ValueError, match="no joint named 'z'; the joints are a, b"):
        m.index("z")
    assert m.children(0) == [1] and m.index("b") == 1


@pytest.mark.parametrize("name, frames", [("131_01", 994), ("131_03", 1102)])
def test_the_cmu_clips(shared_data, name, frames):
    m = read_bvh(shared_data / "bvh11-cmu" / f"{name}.bvh")
    # MANIFEST: 31 joints, 7 end sites, 96 channels, 120 fps, the frame counts
    assert (~m.end_site).sum() == 31 and m.end_site.sum() == 7
    assert m.channels.shape == (frames, 96) and m.n_frames == frames
    assert m.frame_time == pytest.approx(0.0083333)
    zero = [n for k, n in enumerate(m.names) if m.parents[k] >= 0 and not m.offsets[k].any()]
    assert len(zero) == 10 and "LHipJoint" in zero
    # 12 arm and hand joints use Zrotation Xrotation Yrotation, the rest Z Y X
    zxy = {n.split(".")[0] for n, nxt in zip(m.channel_names, m.channel_names[1:], strict=False)
           if n.endswith("Zrotation") and nxt.endswith("Xrotation")
           and nxt.split(".")[0] == n.split(".")[0]}
    assert len(zxy) == 12 and "LeftElbow" in zxy
    # rotations only below the root: every bone keeps its length in every frame
    P = m.positions()
    child = m.parents >= 0
    lengths = np.linalg.norm(P[:, child] - P[:, m.parents[child]], axis=2)
    np.testing.assert_allclose(lengths, np.broadcast_to(
        np.linalg.norm(m.offsets[child], axis=1), lengths.shape), atol=1e-9)
    # the root follows its position channels
    np.testing.assert_allclose(P[:, 0], m.channels[:, :3])
    assert np.isfinite(P).all() and np.ptp(P[:, 0], axis=0).max() > 1
