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
