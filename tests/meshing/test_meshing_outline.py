"""outline_from_image, boundary_loops, read_polygons."""

from __future__ import annotations

import math

import numpy as np
import pytest
from meshing_checks import ENGINES_2D, check_covers_outline, check_trimesh

import stbs
from stbs.io import FormatError, read_polygons
from stbs.meshing import boundary_loops, outline_from_image, triangulate_2d
from stbs.meshing._geometry import point_segment_distance, signed_area


def _disc(r=40.0, size=128, centre=(63.3, 64.6), aa=False):
    yy, xx = np.mgrid[:size, :size]
    d = np.hypot(xx - centre[0], yy - centre[1])
    return np.clip(r + 0.5 - d, 0.0, 1.0) if aa else d < r


# ----------------------------------------------------------------------------- images


def test_disc_is_one_polygon_with_the_disc_area():
    polys = outline_from_image(_disc())
    assert len(polys) == 1
    P = polys[0]
    assert P.shape[1] == 2 and P.dtype == np.float64
    assert signed_area(P) > 0  # outer boundary counter-clockwise
    assert signed_area(P) == pytest.approx(math.pi * 40 ** 2, rel=0.01)


def test_antialiased_disc_is_traced_to_sub_pixel_accuracy():
    P, = outline_from_image(_disc(aa=True), tolerance=0)
    # Pixel (r, c) is at (x, y) = (c, H - 1 - r): the centre is (63.3, 127 - 64.6).
    centre = np.array([63.3, 127 - 64.6])
    radius = np.linalg.norm(P - centre, axis=1)
    assert np.abs(radius - 40.0).max() < 0.1
    assert signed_area(P) == pytest.approx(math.pi * 40 ** 2, rel=0.002)


def test_ring_is_outer_plus_hole():
    yy, xx = np.mgrid[:128, :128]
    d = np.hypot(xx - 64, yy - 64)
    ring = (d < 50) & (d > 20)
    polys = outline_from_image(ring)
    assert len(polys) == 2
    outer, hole = polys
    assert signed_area(outer) == pytest.approx(math.pi * 50 ** 2, rel=0.01)
    assert signed_area(hole) == pytest.approx(-math.pi * 20 ** 2, rel=0.02)  # clockwise


def test_island_in_a_hole_is_counter_clockwise_again():
    img = np.zeros((60, 60), bool)
    img[5:55, 5:55] = True
    img[15:45, 15:45] = False
    img[25:35, 25:35] = True
    polys = outline_from_image(img)
    assert [np.sign(signed_area(P)) for P in polys] == [1, -1, 1]


@pytest.mark.parametrize("kind", ["bool", "uint8", "float", "rgba", "rgb_inverted"])
def test_image_kinds(kind):
    mask = _disc(r=20, size=64, centre=(31.5, 31.5))
    if kind == "bool":
        img, kw = mask, {}
    elif kind == "uint8":
        img, kw = (mask * 255).astype(np.uint8), {}
    elif kind == "float":
        img, kw = mask * 0.8, dict(threshold=0.4)
    elif kind == "rgba":
        img = np.zeros((64, 64, 4))
        img[..., :3] = 0.3  # colour is ignored: alpha is traced
        img[..., 3] = mask
        kw = {}
    else:  # a dark shape on white, traced from the luma
        img = np.ones((64, 64, 3)) - mask[..., None]
        kw = dict(invert=True, alpha=False)
    P, = outline_from_image(img, **kw)
    assert signed_area(P) == pytest.approx(math.pi * 20 ** 2, rel=0.02)


def test_simplification_stays_within_tolerance():
    img = _disc(aa=True)
    raw, = outline_from_image(img, tolerance=0)
    for tol in (0.25, 1.0):
        P, = outline_from_image(img, tolerance=tol)
        assert P.shape[0] < raw.shape[0]
        A, B = P, np.roll(P, -1, axis=0)
        d = point_segment_distance(raw[:, None], A[None], B[None]).min(axis=1)
        assert d.max() <= tol + 1e-9
        # Douglas-Peucker keeps a subset of the contour points, in order.
        assert np.isin(P.view([("", P.dtype)] * 2), raw.view([("", raw.dtype)] * 2)).all()


def test_diagonal_pixels_give_separate_simple_loops():
    img = np.zeros((8, 8), bool)
    img[2:4, 2:4] = True
    img[4:6, 4:6] = True  # touches the first square at one corner (a saddle)
    polys = outline_from_image(img, min_area=0)
    assert len(polys) == 2
    sk = stbs.Skeleton([[2.5, 4.5], [2.6, 4.6]], [[0, 1]])
    triangulate_2d(polys, sk, engine="builtin")  # valid, non-touching outlines


def test_specks_are_dropped_and_empty_images_give_nothing():
    img = np.zeros((40, 40), bool)
    img[5:30, 5:30] = True
    img[35, 35] = True
    assert len(outline_from_image(img)) == 1
    assert len(outline_from_image(img, min_area=0)) == 2
    assert outline_from_image(np.zeros((10, 10))) == []


@pytest.mark.parametrize("engine", ENGINES_2D)
def test_image_to_mesh(engine):
    yy, xx = np.mgrid[:100, :100]
    d = np.hypot(xx - 50, yy - 50)
    ring = (d < 45) & (d > 15)
    polys = outline_from_image(ring, tolerance=1.0)
    # A bone in the ring's band, from left to top (y is up: row 50 - k is y = 49 + k).
    sk = stbs.Skeleton([[20, 49], [50 - 21, 49 + 21], [50, 49 + 30]], [[0, 1], [1, 2]])
    m = triangulate_2d(polys, sk, max_area=20.0, engine=engine)
    check_trimesh(m, sk, min_angle_deg=30, max_area=20.0)
    check_covers_outline(m, polys)


@pytest.mark.parametrize("image, kwargs, match", [
    (np.zeros((4, 4, 2)), {}, r"image must have shape \(H, W\), \(H, W, 3\) or \(H, W, 4\)"),
    (np.zeros(4), {}, "image must have shape"),
    (np.array([["a"]]), {}, "image must be a bool, integer or float array"),
    (np.full((4, 4), np.nan), {}, "image must be finite"),
    (np.zeros((4, 4)), dict(threshold=-0.5), "threshold must lie above the background"),
    (np.zeros((4, 4)), dict(threshold=1.5, invert=True), "below the background value 1"),
    (np.zeros((4, 4)), dict(tolerance=-1), "tolerance must be >= 0"),
    (np.zeros((4, 4)), dict(min_area=-1), "min_area must be >= 0"),
])
def test_bad_images(image, kwargs, match):
    with pytest.raises(ValueError, match=match):
        outline_from_image(image, **kwargs)


# ----------------------------------------------------------------------------- mesh loops


def test_boundary_loops_of_an_annulus():
    k = 12
    a = np.linspace(0, 2 * np.pi, k, endpoint=False)
    V = np.vstack([np.c_[np.cos(a), np.sin(a)] * 2, np.c_[np.cos(a), np.sin(a)]])
    i, j = np.arange(k), (np.arange(k) + 1) % k
    F = np.vstack([np.c_[i, j, j + k], np.c_[i, j + k, i + k]])
    loops = boundary_loops(F)
    assert [len(L) for L in loops] == [k, k]
    assert {frozenset(L.tolist()) for L in loops} == {frozenset(range(k)),
                                                     frozenset(range(k, 2 * k))}
    # The outer loop follows the (counter-clockwise) triangles; the hole runs clockwise.
    signs = sorted(np.sign(signed_area(V[L])) for L in loops)
    assert signs == [-1, 1]


def test_boundary_loops_errors():
    with pytest.raises(ValueError, match=r"edge \(0, 1\) is shared by 3 triangles"):
        boundary_loops([[0, 1, 2], [1, 0, 3], [0, 1, 4]])
    with pytest.raises(ValueError, match="pinched"):
        boundary_loops([[0, 1, 2], [2, 3, 4]])
    with pytest.raises(ValueError, match="at least one triangle"):
        boundary_loops(np.zeros((0, 3), int))


# ----------------------------------------------------------------------------- .poly files

POLY = """# a square with a square hole
8 2 0 1
1 0 0 1
2 10 0 1
3 10 10 1
4 0 10 1
5 4 4 2
6 6 4 2
7 6 6 2
8 4 6 2
8 1
1 1 2 1
2 2 3 1
3 3 4 1
4 4 1 1
5 5 6 2
6 6 7 2
7 7 8 2
8 8 5 2
1
1 5 5
"""


def test_read_polygons(tmp_path):
    p = tmp_path / "box.poly"
    p.write_text(POLY)
    polys = read_polygons(p)
    assert len(polys) == 2
    assert sorted(abs(signed_area(P)) for P in polys) == [4.0, 100.0]
    sk = stbs.Skeleton([[1, 1], [1, 9], [9, 9]], [[0, 1], [1, 2]])
    m = triangulate_2d(polys, sk, engine="builtin")
    check_covers_outline(m, polys)


@pytest.mark.parametrize("text, match", [
    ("0 2 0 0\n", "separate .node file"),
    ("3 3 0 0\n", "dimension 2"),
    ("3 2 0 0\n1 0 0\n2 1 0\n", "vertex line 3 of 3"),
    ("3 2 0 0\n1 0 0\n2 1 0\n3 0 1\n2 0\n1 1 2\n2 2 3\n", "two segments at every vertex"),
    ("3 2 0 0\n1 0 0\n2 1 0\n3 0 x\n", "found '3 0 x'"),
])
def test_read_polygons_errors(tmp_path, text, match):
    p = tmp_path / "bad.poly"
    p.write_text(text)
    with pytest.raises(FormatError, match=match):
        read_polygons(p)
    with pytest.raises(ValueError, match="supported extensions are .poly"):
        read_polygons(tmp_path / "x.svg")
