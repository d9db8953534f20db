"""The demo's pictures tell their figure's story: what each panel draws, measured."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("matplotlib")

from matplotlib import colormaps  # noqa: E402

from stbs.demo import paper  # noqa: E402
from stbs.demo.render import MASK_COLOR, Panel, PlotPanel, draw_panels  # noqa: E402
from stbs.geometry import triangle_areas  # noqa: E402


@pytest.fixture(scope="module")
def fig6():
    return paper.fig6_character(quick=True)


@pytest.fixture(scope="module")
def fig10():
    return paper.fig10_torso(quick=True)


def test_fig6_endpoint_weights_are_grey_where_the_bone_has_no_weight(fig6):
    W, E, names = fig6.W, fig6.E, fig6.sk.names
    panels = fig6.pictures["fig6_character.png"]["panels"][1:]
    assert len(panels) == 6
    reds = colormaps["Reds"]
    for p in panels:
        i = names.index(p.title.removeprefix("e: "))
        c = p.vertex_colors()
        region = W[:, i] >= paper.FIG6_SUPPORT
        assert np.array_equal(p.mask, region)
        # Grey wherever the bone's weight is 0 or negligible, ...
        assert np.all(c[W[:, i] == 0] == MASK_COLOR)
        assert np.all(c[~region] == MASK_COLOR)
        # ... the endpoint weights' colour map inside the bone's region ...
        np.testing.assert_allclose(c[region], reds(np.clip(E[region, i], 0, 1))[:, :3])
        # ... which is the bone's own part of the body: most of the surface is grey.
        assert 0.03 < region.mean() < 0.4, p.title
    assert fig6.numbers["heat"]["region"] < 0.4


def test_fig6_panel_pixels_are_grey_outside_and_red_inside(fig6):
    p = fig6.pictures["fig6_character.png"]["panels"][4]   # the forearm: a small region
    img = draw_panels([p], camera=fig6.pictures["fig6_character.png"]["camera"])
    rgb = img[..., :3].astype(int)
    grey = (np.ptp(rgb, axis=2) < 8) & (rgb.mean(axis=2) < 215) & (rgb.mean(axis=2) > 60)
    red = (rgb[..., 0] - rgb[..., 2] > 60)
    drawn = rgb.mean(axis=2) < 245
    assert grey.sum() > 3 * red.sum() > 0, (grey.sum(), red.sum())
    assert grey.sum() > 0.5 * drawn.sum()


def test_fig10_panels_differ_in_the_chest(fig10):
    V, U = fig10.V, fig10.U
    lo, hi = 0.85, 1.35   # the chest below the twisted joint (torso.extra["chest"])
    chest = (V[:, 1] > lo) & (V[:, 1] < hi)
    moved = np.linalg.norm(U["identity"][chest] - U["spline"][chest], axis=1)
    assert moved.mean() > 0.05 and moved.max() > 0.12
    n = fig10.numbers
    # With the filter the chest's lower end is already turned nearly as far as its top
    # (it turns as one piece); without, the chest itself is wrung.
    assert n["spline"]["turn"] > n["identity"]["turn"] + 15
    assert n["spline"]["chest"] < 0.5 * n["identity"]["chest"]
    kw = fig10.pictures["fig10_torso.png"]
    meshes = [p for p in kw["panels"] if isinstance(p, Panel)]
    plots = [p for p in kw["panels"] if isinstance(p, PlotPanel)]
    assert len(meshes) == 2 and len(plots) == 2
    # Stripes drawn at rest (the same colours on both), so the twist shows as their turn.
    assert np.array_equal(meshes[0].colors, meshes[1].colors)
    dark = meshes[0].colors[:, :3].sum(axis=1) < 2.0
    assert 0.15 < dark.mean() < 0.6
    a = draw_panels([meshes[0]], camera=kw["camera"]).astype(int)
    b = draw_panels([meshes[1]], camera=kw["camera"]).astype(int)
    top = slice(0, a.shape[0] // 2)   # the chest is in the upper half of the picture
    assert np.abs(a[top] - b[top]).mean() > 1.5


def test_fig12_no_triangle_collapses_in_any_pose():
    fig = paper.fig12_picture()  # full size: the quick mesh hid the folded crease (0.21)
    a0 = triangle_areas(fig.V, fig.F)
    for label, U in fig.U.items():
        ratio = triangle_areas(U, fig.F) / a0
        assert ratio.min() > 0.2, (label, ratio.min())
    assert fig.numbers["stbs-dqs"]["area"] > 0.2
    assert set(fig.U) == {"rest", "wave", "lean", "stretch"}
