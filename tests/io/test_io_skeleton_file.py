"""read_skeleton: .tgf and .bf into a validated stbs.Skeleton."""

import warnings

import numpy as np
import pytest

import stbs
from stbs.io import FormatError, read_bf, read_skeleton


def test_tgf_to_skeleton(tmp_path):
    p = tmp_path / "s.tgf"
    p.write_text("1 0 0 0\n2 1 0 0\n3 1 1 0\n#\n1 2\n2 3\n")
    sk = read_skeleton(p)
    assert isinstance(sk, stbs.Skeleton) and sk.dim == 2 and sk.n_bones == 2
    np.testing.assert_array_equal(sk.parents, [-1, 0])
    assert read_skeleton(p, dim=3).dim == 3


def test_bf_to_skeleton_sorted_by_weight_column(tmp_path):
    p = tmp_path / "s.bf"
    p.write_text("-1 -1 0 0 0\n1 0 1 0 0\n0 1 0 1 0\n")
    sk = read_skeleton(p)
    np.testing.assert_array_equal(sk.BE, [[1, 2], [0, 1]])  # weight column 0 first


def test_invalid_skeleton_names_file_and_reason(tmp_path):
    p = tmp_path / "zero.tgf"
    p.write_text("1 0 0 1\n2 0 0 1\n#\n1 2\n")
    with pytest.raises(FormatError, match=r"zero.tgf: expected bones that form a valid "
                       r"skeleton, found .*zero length"):
        read_skeleton(p)
    q = tmp_path / "pts.tgf"
    q.write_text("1 0 0 1\n#\n")
    with pytest.raises(FormatError, match="at least one bone"):
        read_skeleton(q)


def test_unknown_extension_and_missing_file(tmp_path):
    p = tmp_path / "s.bvh"
    p.write_text("HIERARCHY\n")
    with pytest.raises(ValueError, match=r"supported extensions are \.tgf, \.bf"):
        read_skeleton(p)
    with pytest.raises(FileNotFoundError, match="none.tgf"):
        read_skeleton(tmp_path / "none.tgf")


def test_real_skeletons(shared_data):
    sk = read_skeleton(shared_data / "libigl-tutorial-data/arm.tgf")
    assert (sk.n_joints, sk.n_bones, sk.dim) == (5, 4, 3)
    sk = read_skeleton(shared_data / "fast_support_reduction/cantilever_S.tgf")
    assert (sk.n_joints, sk.n_bones, sk.dim) == (5, 4, 2)
    path = shared_data / "FAST/male/bone_roots.bf"
    sk = read_skeleton(path)
    bf = read_bf(path)
    assert sk.n_bones == 17
    np.testing.assert_array_equal(sk.BE, bf.BE[np.argsort(bf.weight_index)])
    sk = read_skeleton(shared_data / "computer-graphics-kinematics/robot-arm.bf", dim=3)
    assert sk.dim == 3


def test_real_point_handles_are_left_out_with_a_warning(shared_data):
    # FAST's Basset: 3 bones and 2 point handles (weight columns 0 and 1).
    with pytest.warns(UserWarning, match=r"2 point handle\(s\) .* left out"):
        sk = read_skeleton(shared_data / "FAST/Basset/bone_roots.bf")
    assert sk.n_bones == 3
    with warnings.catch_warnings():
        warnings.simplefilter("error")        # no handles: no warning
        read_skeleton(shared_data / "FAST/male/bone_roots.bf")


def test_real_point_handles_only_is_an_error(shared_data):
    with pytest.raises(FormatError, match="only 2 point handles"):
        read_skeleton(shared_data / "FAST/cactus_3d/bone_roots.bf")


def test_dim_error_is_not_reported_as_a_bad_skeleton(tmp_path):
    p = tmp_path / "z.tgf"
    p.write_text("1 0 0 0\n2 1 0 1\n#\n1 2\n")
    with pytest.raises(ValueError, match="dim=2 asks for planar joints") as info:
        read_skeleton(p, dim=2)
    assert not isinstance(info.value, FormatError)
