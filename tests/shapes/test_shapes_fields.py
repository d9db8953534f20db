"""stbs.shapes distance fields and blended primitives."""

import numpy as np
import pytest

from stbs.shapes import (
    Primitive,
    blend,
    bounds,
    box_sdf,
    capsule_sdf,
    ellipsoid,
    ellipsoid_sdf,
    mirror,
    round_cone,
    rounded_box,
    smooth_union,
    sphere_sdf,
)


# ---------------------------------------------------------------- distance fields
def test_capsule_sdf_is_the_round_cone_distance():
    rng = np.random.default_rng(1)
    a, b, ra, rb = np.array([0.1, -0.2, 0.3]), np.array([1.4, 0.5, -0.2]), 0.5, 0.2
    X = rng.uniform(-1.5, 2.5, size=(4000, 3))
    d = capsule_sdf(X, a, b, (ra, rb))
    # The shape is the union of balls along the segment with linear radius.
    t = np.linspace(0.0, 1.0, 2001)
    centres = a + t[:, None] * (b - a)
    radii = ra + t * (rb - ra)
    ball = np.linalg.norm(X[:, None] - centres[None], axis=2) - radii[None]
    union = ball.min(axis=1)
    assert np.array_equal(d < 0, union < 0) or np.mean((d < 0) != (union < 0)) < 1e-3
    out = union > 1e-3
    assert np.allclose(d[out], union[out], atol=1e-4)  # exact distance outside
    # Constant radius: distance to the segment minus r; and 2D works too.
    d2 = capsule_sdf(X[:, :2], a[:2], b[:2], 0.3)
    s = np.clip((X[:, :2] - a[:2]) @ (b - a)[:2] / np.sum((b - a)[:2] ** 2), 0, 1)
    seg = np.linalg.norm(X[:, :2] - (a[:2] + s[:, None] * (b - a)[:2]), axis=1)
    assert np.allclose(d2, seg - 0.3, atol=1e-12)
    with pytest.raises(ValueError, match=r"r must satisfy \|r_a - r_b\| < \|b - a\|"):
        capsule_sdf(X, [0, 0, 0], [0.1, 0, 0], (0.5, 0.1))


def test_smooth_union_and_simple_fields():
    rng = np.random.default_rng(2)
    d1, d2 = rng.normal(size=500), rng.normal(size=500)
    assert np.array_equal(smooth_union(d1, d2, 0.0), np.minimum(d1, d2))
    s = smooth_union(d1, d2, 0.4)
    assert np.all(s <= np.minimum(d1, d2) + 1e-15)
    assert np.all(s >= np.minimum(d1, d2) - 0.4 / 4 - 1e-15)  # the fillet is at most k / 4
    far = np.abs(d1 - d2) >= 0.4
    assert np.allclose(s[far], np.minimum(d1, d2)[far])
    with pytest.raises(ValueError, match="k must be >= 0, got -1"):
        smooth_union(d1, d2, -1.0)
    X = rng.uniform(-2, 2, size=(1000, 3))
    assert np.allclose(sphere_sdf(X, [0, 0, 0], 1.0), np.linalg.norm(X, axis=1) - 1)
    # An ellipsoid with equal radii is a sphere; the box's zero set is where expected.
    assert np.allclose(ellipsoid_sdf(X, [0, 0, 0], [1, 1, 1]), np.linalg.norm(X, axis=1) - 1)
    assert np.array_equal(box_sdf(X, [0, 0, 0], [1, 0.5, 0.25]) < 0,
                          np.all(np.abs(X) < [1, 0.5, 0.25], axis=1))
    e = ellipsoid_sdf(X, [0.2, 0, 0], [1.0, 0.5, 0.7])
    inside = np.sum(((X - [0.2, 0, 0]) / [1.0, 0.5, 0.7]) ** 2, axis=1) < 1
    assert np.array_equal(e < 0, inside)




def test_primitives_blend_and_mirror():
    cone = round_cone((0.0, 0.0), (1.0, 0.0), 0.3, 0.2)
    egg = ellipsoid((1.2, 0.1), (0.3, 0.2), k=0.1)
    box = rounded_box((-0.5, 0.0), (0.2, 0.1), 0.05)
    assert isinstance(cone, Primitive) and cone.args[3] == 0.2 and egg.k == 0.1
    X = np.random.default_rng(3).uniform(-1.5, 2.0, size=(500, 2))
    assert np.array_equal(cone.sdf(X), capsule_sdf(X, [0, 0], [1, 0], (0.3, 0.2)))
    assert np.array_equal(egg.sdf(X), ellipsoid_sdf(X, (1.2, 0.1), (0.3, 0.2)))
    assert np.array_equal(box.sdf(X), box_sdf(X, (-0.5, 0.0), (0.2, 0.1), 0.05))
    assert round_cone((0, 0), (1, 0), 0.3).args[3] == 0.3  # rb defaults to ra
    # blend: the first part alone, then smooth unions in order with each part's k, at
    # least min_k.
    f = blend([cone, egg, box])
    expect = smooth_union(smooth_union(cone.sdf(X), egg.sdf(X), 0.1), box.sdf(X), 0.0)
    assert np.array_equal(f(X), expect)
    g = blend([cone, egg, box], 0.2)
    expect = smooth_union(smooth_union(cone.sdf(X), egg.sdf(X), 0.2), box.sdf(X), 0.2)
    assert np.array_equal(g(X), expect)
    # Bounds hold the shape: the field is positive outside them.
    lo, hi = bounds([cone, egg, box])
    np.testing.assert_allclose(lo, [-0.75, -0.3])
    np.testing.assert_allclose(hi, [1.5, 0.3])
    out = np.any((X < lo) | (X > hi), axis=1)
    assert np.all(f(X[out]) > 0)
    # Mirroring in x = 0 reflects the field.
    m = blend(mirror([cone, egg, box]))
    assert np.allclose(m(X * [-1, 1]), f(X), atol=1e-12)
    assert [p.k for p in mirror([cone, egg, box])] == [0.0, 0.1, 0.0]
    with pytest.raises(ValueError, match="parts must be a non-empty sequence of Primitive"):
        blend([])
