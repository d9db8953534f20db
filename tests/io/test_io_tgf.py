"""read_tgf / write_tgf."""

import numpy as np
import pytest

from stbs.io import FormatError, read_tgf, write_tgf

# ---------------------------------------------------------------- hand-made files


def test_garbage_columns_ignored_and_one_based(tmp_path):
    p = tmp_path / "s.tgf"
    p.write_text("1 0 0 1 2.79e+199 nan junk\n2 1 0 1 4.4e+291\n3 1 2 1\n#\n1 2\n2 3\n#\n")
    C, BE = read_tgf(p)
    np.testing.assert_array_equal(C, [[0, 0, 1], [1, 0, 1], [1, 2, 1]])
    assert C.dtype == np.float64 and BE.dtype == np.int64
    np.testing.assert_array_equal(BE, [[0, 1], [1, 2]])


def test_bone_flags_select_bones(tmp_path):
    # Edge 2-3 is a cage edge (is_bone = 0): only flagged edges are bones.
    p = tmp_path / "f.tgf"
    p.write_text("1 0 0 0\n2 1 0 0\n3 1 1 0\n4 2 1 0\n#\n1 2 1 0 0\n2 3 0 0 1\n3 4 1 0 0\n")
    C, BE = read_tgf(p)
    assert C.shape == (4, 2)  # all z == 0 -> 2-D
    np.testing.assert_array_equal(BE, [[0, 1], [2, 3]])


def test_flags_all_zero_mean_all_edges(tmp_path):
    # No edge has is_bone == 1, so (as libigl's tutorials do) every edge is a bone.
    p = tmp_path / "z.tgf"
    p.write_text("1 0 0 1\n2 1 0 1\n3 2 0 1\n#\n1 2 0 0 0\n2 3\n")
    np.testing.assert_array_equal(read_tgf(p)[1], [[0, 1], [1, 2]])


def test_text_after_closing_hash_and_blank_lines_ignored(tmp_path):
    p = tmp_path / "t.tgf"
    p.write_text("1 0 0 0\r\n\r\n2 0 1 0\r\n#\r\n1 2\r\n\r\n#\r\nwhatever 1 2 3\r\n")
    C, BE = read_tgf(p)
    np.testing.assert_array_equal(C, [[0, 0], [0, 1]])
    np.testing.assert_array_equal(BE, [[0, 1]])


def test_joints_only_gives_no_bones(tmp_path):
    p = tmp_path / "p.tgf"
    p.write_text("1 0 0 1\n#\n")
    C, BE = read_tgf(p)
    assert C.shape == (1, 3) and BE.shape == (0, 2)


def test_dim_options(tmp_path):
    p = tmp_path / "p.tgf"
    p.write_text("1 0 0 0\n2 1 0 0\n#\n1 2\n")
    assert read_tgf(p, dim=3)[0].shape == (2, 3)
    assert read_tgf(p, dim=2)[0].shape == (2, 2)
    q = tmp_path / "q.tgf"
    q.write_text("1 0 0 0\n2 1 0 0.5\n#\n1 2\n")
    with pytest.raises(ValueError, match=r"dim=2 .*max \|z\| = 0.5"):
        read_tgf(q, dim=2)


@pytest.mark.parametrize("d", [2, 3])
def test_write_read_round_trip(tmp_path, d):
    rng = np.random.default_rng(3)
    C = rng.normal(size=(6, d))
    BE = np.array([[0, 1], [1, 2], [1, 3], [4, 5]])
    p = tmp_path / "r.tgf"
    write_tgf(p, C, BE)
    C2, BE2 = read_tgf(p)
    np.testing.assert_array_equal(C2, C)
    np.testing.assert_array_equal(BE2, BE)


def test_write_rejects_bad_input(tmp_path):
    with pytest.raises(ValueError, match=r"BE must hold joint indices in 0..1, got 2"):
        write_tgf(tmp_path / "a.tgf", np.zeros((2, 3)), [[0, 2]])
    with pytest.raises(ValueError, match=r"supported extensions are \.tgf"):
        write_tgf(tmp_path / "a.txt", np.zeros((2, 3)), [[0, 1]])
    assert list(tmp_path.iterdir()) == []


# ---------------------------------------------------------------- real shared files


def test_real_arm_tgf(shared_data):
    C, BE = read_tgf(shared_data / "libigl-tutorial-data/arm.tgf")
    assert C.shape == (5, 3) and BE.shape == (4, 2)
    # Columns 5+ hold garbage such as 2.79e+199; only x y z are read.
    np.testing.assert_array_equal(C[0], [-0.72962893, 0.011729617, -0.1327604])
    np.testing.assert_array_equal(C[4], [0.73572894, -0.17523362, 0.090210152])
    assert np.abs(C).max() < 1
    np.testing.assert_array_equal(BE, [[0, 1], [1, 2], [2, 3], [3, 4]])


def test_real_hand_tgf(shared_data):
    C, BE = read_tgf(shared_data / "libigl-tutorial-data/hand.tgf")
    assert C.shape == (21, 3) and BE.shape == (20, 2)
    assert BE.min() == 0 and BE.max() == 20


def test_real_cantilever_flags_2d(shared_data):
    C, BE = read_tgf(shared_data / "fast_support_reduction/cantilever_S.tgf")
    np.testing.assert_array_equal(C, [[-0.8, 0], [-0.4, 0], [0, 0], [0.4, 0], [0.8, 0]])
    np.testing.assert_array_equal(BE, [[0, 1], [1, 2], [2, 3], [3, 4]])


def test_real_knight_tgf(shared_data):
    C, BE = read_tgf(shared_data / "computer-graphics-kinematics/knight.tgf")
    assert C.shape == (19, 3) and BE.shape == (18, 2)


# ---------------------------------------------------------------- broken files


@pytest.mark.parametrize("text, match", [
    ("1 0 0 0\n2 1 zero 0\n#\n1 2\n", r"line 2: expected a number in a joint line"),
    ("1 0 0 0\n2 1 0\n#\n1 2\n", r"line 2: expected at least 4 numbers"),
    ("1 0 0 0\n2 1 0 0\n#\n1 2\n2 3\n", r"line 5: expected a joint index in 1..2 \(TGF is "
     r"1-based\), found 3"),
    ("1 0 0 0\n2 1 0 0\n#\n0 1\n", r"line 4: expected a joint index in 1..2"),
    ("1 0 0 0\n2 1 0 0\n#\n1\n", r"line 4: expected an edge line"),
    ("1 0 0 0\n2 1 0 0\n#\n1 b\n", r"line 4: expected integers in an edge line"),
    ("1 0 0 0\n2 1 0 0\n", r"line 2: expected a '#' line after the joint lines, found end"),
    ("#\n1 2\n", r"line 1: expected joint lines 'index x y z' before the first '#', found '#'"),
    ("", r"found an empty file"),
    ("\n  \n", r"found an empty file"),
])
def test_broken_tgf(tmp_path, text, match):
    p = tmp_path / "b.tgf"
    p.write_text(text)
    with pytest.raises(FormatError, match=match) as info:
        read_tgf(p)
    assert str(info.value).startswith(str(p))


def test_missing_file(tmp_path):
    with pytest.raises(FileNotFoundError, match="gone.tgf"):
        read_tgf(tmp_path / "gone.tgf")
