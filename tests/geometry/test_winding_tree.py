"""stbs.geometry.WindingTree: hierarchical (fast) generalised winding numbers against
the exact sum, on closed, open, overlapping and real surfaces."""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from stbs.geometry import WindingTree, winding_numbers

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from surfaces import box, join, tube  # noqa: E402


def test_a_closed_box_by_hand():
    V, F = box([0, 0, 0], [1, 1, 1])
    w = WindingTree(V, F)([[0.5, 0.5, 0.5], [0.9, 0.1, 0.5], [2, 0, 0], [0.5, 0.5, 9.0]])
    # far clusters are summed as dipoles (second order): within 1 % here
    np.testing.assert_allclose(w, [1, 1, 0, 0], atol=0.01)
    np.testing.assert_allclose(WindingTree(V, F[:, ::-1])([[0.5, 0.5, 0.5]]), [-1], atol=0.01)
    # beta large enough that nothing is far: the exact sum
    np.testing.assert_allclose(WindingTree(V, F, beta=1e6)([[0.5, 0.5, 0.5], [2, 0, 0]]),
                               winding_numbers([[0.5, 0.5, 0.5], [2, 0, 0]], V, F), atol=1e-12)
    assert WindingTree(V, F)(np.zeros((0, 3))).shape == (0,)
    assert WindingTree(V, F[:0])([[0.5, 0.5, 0.5]]).tolist() == [0.0]


def test_agrees_with_the_exact_sum_on_a_soup():
    # an open tube through two overlapping boxes: fractions near the tube's ends, 2 where
    # the boxes overlap
    V, F = join(tube(48, 41), box([1, -1, -1], [2, 1, 1], 6),
                box([1.5, -0.5, -2], [3, 0.5, 0.5], 6))
    rng = np.random.default_rng(7)
    lo, hi = V.min(axis=0) - 0.5, V.max(axis=0) + 0.5
    Q = lo + rng.random((3000, 3)) * (hi - lo)
    exact = winding_numbers(Q, V, F)
    fast = WindingTree(V, F)(Q)
    assert np.abs(fast - exact).max() < 0.05
    assert np.abs(WindingTree(V, F, beta=4.0)(Q) - exact).max() < 0.01   # beta buys accuracy
    # the soup has all three kinds of points: outside, fractional, inside twice
    assert exact.max() > 1.9 and np.any((exact > 0.2) & (exact < 0.8)) and exact.min() < 0.05


def test_on_a_real_character(shared_data):
    from stbs.io import read_rig

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")        # what the reader says about the file
        rig = read_rig(shared_data / "characters" / "gltf" / "CesiumMan.glb")
    V, F = rig.V, rig.F
    rng = np.random.default_rng(1)
    Q = V.min(axis=0) + rng.random((2000, 3)) * np.ptp(V, axis=0)
    Q = np.vstack([Q, rig.skeleton.C])
    fast, exact = WindingTree(V, F)(Q), winding_numbers(Q, V, F)
    assert np.abs(fast - exact).max() < 0.05
    # inside or out: the same answer, except within a hair of the 1/2 level
    differ = (fast > 0.5) != (exact > 0.5)
    assert np.all(np.abs(exact[differ] - 0.5) < 0.05)


@pytest.mark.parametrize("args, kw, match", [
    ((np.zeros((3, 2)), np.zeros((1, 3), int)), {}, r"V must have shape \(n, 3\)"),
    ((np.zeros((3, 3)), np.zeros((1, 4), int)), {}, r"F must have shape \(f, 3\)"),
    ((np.zeros((3, 3)), np.array([[0, 1, 5]])), {}, "F must hold vertex indices"),
    ((np.zeros((3, 3)), np.array([[0, 1, 2]])), {"beta": 0.0}, "beta must be a positive"),
])
def test_bad_arguments(args, kw, match):
    with pytest.raises(ValueError, match=match):
        WindingTree(*args, **kw)
