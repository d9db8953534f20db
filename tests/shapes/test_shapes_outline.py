"""stbs.shapes 2D outlines: outline_of_field and resample_loop."""

import numpy as np
import pytest

from stbs.geometry import signed_area
from stbs.shapes import capsule_sdf, outline_of_field, resample_loop, sphere_sdf


def test_resample_loop_spaces_points_evenly_along_the_perimeter():
    square = np.array([[0, 0], [2, 0], [2, 2], [0, 2]], float)
    P = resample_loop(square, 0.5)
    assert P.shape == (16, 2) and np.array_equal(P[0], square[0])
    step = np.linalg.norm(np.diff(np.vstack([P, P[:1]]), axis=0), axis=1)
    np.testing.assert_allclose(step, 0.5)
    assert resample_loop(square, 10.0).shape == (8, 2)  # at least 8 points
    with pytest.raises(ValueError, match="spacing must be > 0, got 0.0"):
        resample_loop(square, 0)
    with pytest.raises(ValueError, match=r"P must have shape \(k, 2\) with k >= 3"):
        resample_loop(square[:2], 0.5)


def test_outline_of_a_disc_and_a_ring_lies_on_the_zero_set():
    loops = outline_of_field(lambda X: sphere_sdf(X, [0.3, -0.2], 1.0), [-0.7, -1.2],
                             [1.3, 0.8], 0.05)
    assert len(loops) == 1
    L = loops[0]
    np.testing.assert_allclose(np.linalg.norm(L - [0.3, -0.2], axis=1), 1.0, atol=1e-6)
    assert signed_area(L) > 0  # counter-clockwise
    step = np.linalg.norm(np.diff(np.vstack([L, L[:1]]), axis=0), axis=1)
    assert 0.04 < step.min() and step.max() < 0.06
    # A ring: an outer loop counter-clockwise, the hole clockwise, larger first.
    def ring(X):
        r = np.linalg.norm(X, axis=1)
        return np.maximum(r - 1.0, 0.5 - r)
    outer, hole = outline_of_field(ring, [-1, -1], [1, 1], 0.05)
    assert signed_area(outer) > 0 > signed_area(hole)
    np.testing.assert_allclose(np.linalg.norm(hole, axis=1), 0.5, atol=1e-5)


def test_outline_bad_arguments():
    def sdf(X):
        return capsule_sdf(X, [0, 0], [1, 0], 0.3)

    with pytest.raises(ValueError, match="sdf must be callable, got int"):
        outline_of_field(3, [0, 0], [1, 1], 0.1)
    with pytest.raises(ValueError, match="hi must be greater than lo"):
        outline_of_field(sdf, [1, 1], [0, 0], 0.1)
    with pytest.raises(ValueError, match="spacing must be > 0"):
        outline_of_field(sdf, [0, 0], [1, 1], -0.1)
