"""Skeleton validation and derived topology."""

import numpy as np
import pytest

import stbs


def test_chain_topology():
    sk = stbs.Skeleton([[0.0, 0, 0], [1, 0, 0], [1, 2, 0], [1, 2, 2]], [[2, 3], [0, 1], [1, 2]],
                       names=["hand", "upper", "fore"])
    np.testing.assert_array_equal(sk.parents, [2, -1, 1])
    np.testing.assert_allclose(sk.lengths, [2, 1, 2])
    np.testing.assert_allclose(sk.axes, [[0, 0, 1], [1, 0, 0], [0, 1, 0]])
    assert sk.dim == 3 and sk.n_bones == 3 and sk.n_joints == 4
    np.testing.assert_array_equal(sk.roots, [1])
    assert list(sk.order) == [1, 2, 0]  # parents before children, though listed after
    assert sk.bone_index("fore") == 2 and sk.bone_index("0") == 0 and sk.bone_index(1) == 1


def test_forest_with_unshared_joints_and_branches():
    C = [[0.0, 0], [1, 0], [2, 1], [2, -1], [5, 5], [6, 5]]
    sk = stbs.Skeleton(C, [[0, 1], [1, 2], [1, 3], [4, 5]])
    assert sk.dim == 2
    np.testing.assert_array_equal(sk.parents, [-1, 0, 0, -1])
    np.testing.assert_array_equal(sk.roots, [0, 3])
    order = list(sk.order)
    assert order.index(0) < order.index(1) and order.index(0) < order.index(2)


@pytest.mark.parametrize("C, BE, match", [
    ([[0.0, 0, 0], [1, 0, 0]], [[0, 2]], r"bone 0 .* outside 0\.\.1"),
    ([[0.0, 0, 0], [1, 0, 0]], [[0, -1]], "outside"),
    ([[0.0, 0, 0], [1, 0, 0]], [[0, 1], [0, 1]], "bone 1 .* listed twice"),
    ([[0.0, 0, 0], [1, 0, 0]], [[0, 1], [1, 0]], "listed twice"),
    ([[0.0, 0, 0], [0, 0, 0], [1, 0, 0]], [[1, 2], [0, 1]], "bone 1 .* zero length"),
    ([[0.0, 0, 0], [1, 0, 0]], [[0, 0]], "same joint"),
    ([[0.0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]], [[0, 2], [1, 2], [2, 3]],
     "bone 2 .* 2 parents"),
    ([[0.0, 0, 0], [1, 0, 0], [1, 1, 0]], [[0, 1], [1, 2], [2, 0]], "cycle"),
    ([[0.0, 0, 0, 0], [1, 0, 0, 0]], [[0, 1]], r"C must have shape \(j, 2\) or \(j, 3\)"),
    ([[0.0, np.nan, 0], [1, 0, 0]], [[0, 1]], "C must be finite"),
    ([[0.0, 0, 0], [1, 0, 0]], [[0.5, 1]], "integer"),
    ([[0.0, 0, 0], [1, 0, 0]], [[0, 1, 2]], r"BE must have shape \(\?, 2\)"),
    ([[0.0, 0, 0], [1, 0, 0]], np.zeros((0, 2), int), "at least one bone"),
])
def test_invalid_skeletons(C, BE, match):
    with pytest.raises(ValueError, match=match):
        stbs.Skeleton(C, BE)


def test_names_validated_and_unknown_bone():
    C, BE = [[0.0, 0, 0], [1, 0, 0], [2, 0, 0]], [[0, 1], [1, 2]]
    with pytest.raises(ValueError, match="names must have 2"):
        stbs.Skeleton(C, BE, names=["a"])
    with pytest.raises(ValueError, match="unique"):
        stbs.Skeleton(C, BE, names=["a", "a"])
    sk = stbs.Skeleton(C, BE, names=["a", "b"])
    for bad in ("forearm", 5, "7", -1):
        with pytest.raises(ValueError, match="does not exist"):
            sk.bone_index(bad)


def test_arrays_are_read_only():
    sk = stbs.Skeleton([[0.0, 0], [1, 0]], [[0, 1]])
    with pytest.raises(ValueError):
        sk.C[0, 0] = 5


def test_offset_children_from_P():
    # hips -> spine (connected), two legs hanging off the hips' start (offset), an arm
    # hanging half way up the spine
    C = [[0, 0, 0], [0, 1, 0], [0, 2, 0], [0.2, 0, 0], [0.2, -1, 0], [-0.2, 0, 0],
         [-0.2, -1, 0], [0.3, 1.5, 0], [1.3, 1.5, 0]]
    BE = [[0, 1], [1, 2], [3, 4], [5, 6], [7, 8]]
    sk = stbs.Skeleton(C, BE, P=[-1, 0, 0, 0, 1])
    assert sk.parents.tolist() == [-1, 0, 0, 0, 1]
    assert sk.connected.tolist() == [False, True, False, False, False]
    np.testing.assert_allclose(sk.hang, [0, 1, 0, 0, 0.5])
    assert sk.depth.tolist() == [0, 1, 1, 1, 2] and sk.roots.tolist() == [0]
    assert [lv.tolist() for lv in sk.levels()] == [[0], [1, 2, 3], [4]]
    # P is part of equality
    assert sk != stbs.Skeleton(C, BE)


@pytest.mark.parametrize("P, match", [
    ([-1, 0, 5], r"P: bone 2 .* has parent 5, outside -1..2"),
    ([-1, 1, 0], r"P: bone 1 .* is its own parent"),
    ([2, 0, 1], r"P: bone 0 .* lies on a cycle"),
    ([-1, 0], r"P must have shape"),
])
def test_bad_P_is_named(P, match):
    C = [[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]]
    with pytest.raises(ValueError, match=match):
        stbs.Skeleton(C, [[0, 1], [1, 2], [2, 3]], P=P)


def test_two_bones_ending_at_a_joint_need_P():
    C = [[0, 0, 0], [2, 0, 0], [1, 1, 0], [1, 2, 0]]
    with pytest.raises(ValueError, match="give P"):
        stbs.Skeleton(C, [[0, 2], [1, 2], [2, 3]])
    sk = stbs.Skeleton(C, [[0, 2], [1, 2], [2, 3]], P=[-1, -1, 0])
    assert sk.connected.tolist() == [False, False, True]
