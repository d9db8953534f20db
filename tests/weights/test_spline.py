"""Spline filters on endpoint weights (paper Fig. 10)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

import stbs
from stbs.weights.spline import SplineFilter, spline_filter

X = np.linspace(0.0, 1.0, 1001)


@pytest.mark.parametrize("points", [None, [], [(0.3, 0.3), (0.8, 0.8)], [(0, 0), (1, 1)]])
def test_identity_filters(points):
    f = SplineFilter(points)
    assert f.is_identity
    np.testing.assert_array_equal(f(X), X)


def test_passes_through_its_points_and_keeps_the_ends():
    f = SplineFilter([(0.5, 0.9), (0.25, 0.6)])        # any order
    np.testing.assert_allclose(f(np.array([0.0, 0.25, 0.5, 1.0])), [0, 0.6, 0.9, 1], atol=1e-15)
    np.testing.assert_array_equal(f.points, [[0, 0], [0.25, 0.6], [0.5, 0.9], [1, 1]])
    assert repr(f) == "SplineFilter([[0.25, 0.6], [0.5, 0.9]])"


def test_random_monotone_points_give_monotone_bounded_curves():
    rng = np.random.default_rng(11)
    for _ in range(20):
        k = rng.integers(1, 6)
        x = np.sort(rng.uniform(0.01, 0.99, k))
        y = np.sort(rng.uniform(0, 1, k))
        y[rng.random(k) < 0.3] = y[0]                   # flat stretches too
        y = np.maximum.accumulate(y)
        fx = SplineFilter(np.stack([x, y], 1))(X)
        assert fx[0] == 0 and fx[-1] == 1
        assert np.all(np.diff(fx) >= -1e-15)
        assert fx.min() >= 0 and fx.max() <= 1


def test_fig10_moves_the_twist_into_the_abdomen():
    """Spine bone from hips (e = 0) to neck (e = 1), twisted at the neck: the filtered
    weights change fast over the abdomen (low e) and slowly over the chest (high e)."""
    f = SplineFilter([(0.25, 0.6), (0.5, 0.9)])
    low, high = X < 0.5, X > 0.5
    slope = np.gradient(f(X), X)
    assert slope[low].mean() > 3 * slope[high].mean()
    theta = np.pi                                        # twist at b
    chest = np.linspace(0.6, 1.0, 50)
    spread = np.ptp(theta * f(chest))                    # twist variation across the chest
    assert spread < 0.25 * np.ptp(theta * chest)


@pytest.mark.parametrize("points, match", [
    ([(0.5, 1.2)], r"in \[0, 1\]\^2"),
    ([(0.3, 0.5), (0.3, 0.6)], "distinct x"),
    ([(0.3, 0.6), (0.6, 0.4)], "monotone"),
    ([(0.0, 0.2)], r"f\(0\) must be 0"),
    ([(1.0, 0.5)], r"f\(1\) must be 1"),
    ([(0.5, np.nan)], "finite"),
    ([0.5, 0.5], "2-D array"),
])
def test_bad_points_are_rejected(points, match):
    with pytest.raises(ValueError, match=match):
        SplineFilter(points)


def test_out_of_range_weights_are_rejected():
    with pytest.raises(ValueError, match=r"E must lie in \[0, 1\]"):
        SplineFilter([(0.5, 0.7)])(np.array([0.2, 1.5]))


def test_per_bone_filters_dense_and_sparse():
    rng = np.random.default_rng(2)
    E = rng.random((50, 3))
    f = SplineFilter([(0.5, 0.8)])
    out = spline_filter(E, f, bones=[1])
    np.testing.assert_array_equal(out[:, [0, 2]], E[:, [0, 2]])
    np.testing.assert_allclose(out[:, 1], f(E[:, 1]))
    assert out is not E
    per = spline_filter(E, {0: [(0.5, 0.2)], 2: f})
    np.testing.assert_allclose(per[:, 0], SplineFilter([(0.5, 0.2)])(E[:, 0]))
    np.testing.assert_array_equal(per[:, 1], E[:, 1])
    Es = sp.csr_array(np.where(E > 0.5, E, 0.0))
    outs = spline_filter(Es, f)
    assert sp.issparse(outs) and outs.nnz == Es.nnz
    np.testing.assert_allclose(outs.toarray(), f(Es.toarray()))


def test_bones_by_name_need_the_skeleton():
    sk = stbs.Skeleton([[0.0, 0], [1, 0], [2, 0]], [[0, 1], [1, 2]], names=["spine", "neck"])
    E = np.full((4, 2), 0.5)
    out = spline_filter(E, [(0.5, 0.9)], bones=["neck"], sk=sk)
    np.testing.assert_allclose(out, [[0.5, 0.9]] * 4)
    with pytest.raises(ValueError, match="pass sk= to name bones"):
        spline_filter(E, [(0.5, 0.9)], bones=["neck"])
    with pytest.raises(ValueError, match="bones must be None when filters is a mapping"):
        spline_filter(E, {0: []}, bones=[0])
    with pytest.raises(ValueError, match=r"E must have shape \(4, 3\)"):
        spline_filter(E, [], sk=stbs.Skeleton([[0.0, 0], [1, 0], [2, 0], [3, 0]],
                                              [[0, 1], [1, 2], [2, 3]]))
