"""Weight paint's tools in a real browser (headless Chromium, Playwright): locked bones,
X-mirror painting, the bone-weight heat map, the brush's [ and ] keys, and strokes on the
page's one History beside pose edits. Helpers: test_viewer_paint.py."""

from __future__ import annotations

import numpy as np
import pytest
from test_viewer_page import Page, browser, tube_rig  # noqa: F401
from test_viewer_paint import _diag, _screen, _shot, _stroke, _weights

import stbs
from stbs.weights import projection


def mirror_rig(rings=41, seg=24) -> stbs.Rig:
    """A tube along x from -5 to 5, exactly symmetric about x = 0, with two bones from
    the centre outwards: "arm.R" to x = -5 and "arm.L" to x = 5; W a smooth step in x."""
    x = np.linspace(-5, 5, rings)
    t = 2 * np.pi * np.arange(seg) / seg
    V = np.column_stack([np.repeat(x, seg), np.tile(0.5 * np.cos(t), rings),
                         np.tile(0.5 * np.sin(t), rings)])
    i = np.arange(rings - 1)[:, None] * seg
    j = np.arange(seg)[None, :]
    p, q = (i + j).ravel(), (i + (j + 1) % seg).ravel()
    F = np.concatenate([np.stack([p, q, q + seg], 1), np.stack([p, q + seg, p + seg], 1)])
    sk = stbs.Skeleton(np.array([[0.0, 0, 0], [-5, 0, 0], [5, 0, 0]]), np.array([[0, 1], [0, 2]]),
                       names=["arm.R", "arm.L"], P=np.array([-1, -1]))
    left = 1 / (1 + np.exp(-2 * V[:, 0]))
    W = np.column_stack([1 - left, left])
    return stbs.Rig(V=V, F=F, skeleton=sk, W=W, E=projection(V, sk))


@pytest.fixture(scope="module")
def tube(browser):  # noqa: F811
    p = Page(browser, tube_rig())
    yield p
    p.close()


@pytest.fixture(scope="module")
def arms(browser):  # noqa: F811
    p = Page(browser, mirror_rig())
    yield p
    p.close()


def _ring_point(p, x0):
    """The page point of the posed tube's ring nearest x = x0 (its vertices' centre)."""
    V = np.asarray(p.rig.V, dtype=np.float64)
    cam = p.js("stbsViewer.camera()")
    U = p.positions()
    xs = np.unique(np.round(V[:, 0], 6))
    x = xs[np.argmin(np.abs(xs - x0))]
    return tuple(float(c) for c in _screen(cam, U[np.abs(V[:, 0] - x) < 1e-6]).mean(axis=0))


def test_a_locked_bone_keeps_its_weights_while_others_are_painted(tube):
    p = tube
    p.js("stbsViewer.setPose({})")
    p.js("stbsViewer.frame()")
    W0, E0 = _weights(p)
    # lock bone 9 with the panel's checkbox, then paint bone 10 over both
    p.js("document.getElementById('weights-panel').open = true")
    p.js("stbsViewer.setPaint({bone: 9})")
    p.page.check("#paint-lock")
    assert p.js("stbsViewer.paint()")["locked"] == [9]
    assert "locked: b9" in p.page.inner_text("#paint-locked")
    p.js("o => stbsViewer.setPaint(o)", {"mode": "bone", "bone": 10, "op": "add", "radius": 0.8,
                                         "strength": 0.6, "falloff": "linear"})
    assert not p.page.is_checked("#paint-lock")           # the box shows the selected bone's
    st = _stroke(p, [_ring_point(p, 4.9), _ring_point(p, 5.2)])
    W1, E1 = _weights(p)
    assert st["vertices"] > 20
    changed = np.flatnonzero((W1 != W0).any(axis=1))
    had9 = changed[W0[changed, 9] > 0.05]
    assert had9.size > 5                                   # the brush was over bone 9's weight
    assert np.array_equal(W1[:, 9], W0[:, 9])              # bit for bit
    assert np.all(W1[changed, 10] >= W0[changed, 10])
    assert np.abs(W1.astype(np.float64).sum(axis=1) - 1).max() < 2e-6
    assert np.array_equal(E1, E0)
    # painting the locked bone itself changes nothing
    p.js("stbsViewer.setPaint({bone: 9})")
    assert p.page.is_checked("#paint-lock")
    _stroke(p, [_ring_point(p, 4.8)])
    assert np.array_equal(_weights(p)[0], W1)
    # unlocked, the same stroke paints it
    p.page.uncheck("#paint-lock")
    assert p.js("stbsViewer.paint()")["locked"] == []
    _stroke(p, [_ring_point(p, 4.8)])
    W2, _ = _weights(p)
    assert np.any(W2[:, 9] != W1[:, 9])
    while p.js("stbsViewer.canPaintUndo()"):
        p.js("stbsViewer.paintUndo()")
    assert np.array_equal(_weights(p)[0], W0)
    p.js("stbsViewer.setPaint({mode: 'off'})")
    p.js("document.getElementById('weights-panel').open = false")
    assert p.errors == []


def test_x_mirror_paints_the_mirror_bone_on_the_mirror_side_in_one_step(arms):
    p = arms
    p.js("stbsViewer.frame()")
    W0, E0 = _weights(p)
    V = np.asarray(p.rig.V, dtype=np.float64)
    p.js("o => stbsViewer.setPaint(o)", {"mode": "bone", "bone": "arm.L", "op": "subtract",
                                         "radius": 0.9, "strength": 0.4, "falloff": "smooth",
                                         "mirror": True})
    assert p.js("stbsViewer.store()")["mirror"] is True
    assert p.page.is_checked("#paint-mirror")
    st = _stroke(p, [_ring_point(p, 2.5), _ring_point(p, 3.0)])
    assert st["mirror"] is True
    W1, _ = _weights(p)
    dL = W1[:, 1].astype(np.float64) - W0[:, 1]
    dR = W1[:, 0].astype(np.float64) - W0[:, 0]
    right = V[:, 0] > 0.5
    assert dL[right].min() < -0.1                     # arm.L lowered on the left (x > 0) ...
    # ... and arm.R lowered by as much at each vertex's mirror (x -> -x)
    mirror = np.array([np.flatnonzero(np.all(np.abs(V - [-v[0], v[1], v[2]]) < 1e-9, axis=1))[0]
                       for v in V])
    hit = np.flatnonzero(right & (dL < -1e-4))
    assert hit.size > 20
    assert np.abs(dR[mirror[hit]] - dL[hit]).max() < 1e-5
    assert np.abs(W1.astype(np.float64).sum(axis=1) - 1).max() < 2e-6
    # one stroke, one undo step, bit for bit
    assert p.js("stbsViewer.paintUndo()") is True
    W2, E2 = _weights(p)
    assert np.array_equal(W2, W0) and np.array_equal(E2, E0)
    # mirror off: only the painted side
    p.js("stbsViewer.setPaint({mirror: false})")
    _stroke(p, [_ring_point(p, 2.5)])
    W3, _ = _weights(p)
    assert np.array_equal(W3[V[:, 0] < -0.5], W0[V[:, 0] < -0.5])
    p.js("stbsViewer.paintUndo()")
    p.js("stbsViewer.setPaint({mode: 'off'})")
    assert p.errors == []


def test_the_weight_heat_map_follows_the_selected_bone(arms):
    p = arms
    p.js("stbsViewer.setPose({})")
    p.js("stbsViewer.frame()")
    p.js("stbsViewer.setPaint({bone: 'arm.L'})")
    assert p.js("stbsViewer.setColorMode('weight')") == "weight"
    V = np.asarray(p.rig.V, dtype=np.float64)
    cam = p.js("stbsViewer.camera()")
    front = V[:, 2] > 0.45                    # the tube's side facing the camera (z up front)
    left = _screen(cam, V[front & (np.abs(V[:, 0] - 4.0) < 0.2)]).mean(axis=0)
    right = _screen(cam, V[front & (np.abs(V[:, 0] + 4.0) < 0.2)]).mean(axis=0)

    def colour(img, xy):
        x, y = (int(round(c)) for c in xy)
        return img[y - 1:y + 2, x - 1:x + 2].reshape(-1, 3).mean(axis=0)

    img = _shot(p)
    # arm.L's weight is ~1 at x = 4 (red: r high, b low) and ~0 at x = -4 (blue)
    r1, g1, b1 = colour(img, left)
    r0, g0, b0 = colour(img, right)
    assert r1 > b1 + 60 and b0 > r0 + 60, (colour(img, left), colour(img, right))
    # selecting the other bone swaps them ("select" follows the store)
    p.js("stbsViewer.setPaint({bone: 'arm.R'})")
    img = _shot(p)
    assert colour(img, left)[2] > colour(img, left)[0] + 60
    assert colour(img, right)[0] > colour(img, right)[2] + 60
    p.js("stbsViewer.setColorMode('shaded')")
    assert p.errors == []


def test_brackets_resize_the_brush_and_are_listed_in_the_help(arms):
    p = arms
    r0 = p.js("stbsViewer.paint()")["radius"]
    p.page.locator("#view").hover()
    p.page.keyboard.press("]")
    assert abs(p.js("stbsViewer.paint()")["radius"] - 1.25 * r0) < 1e-9 * r0
    p.page.keyboard.press("[")
    p.page.keyboard.press("[")
    assert abs(p.js("stbsViewer.paint()")["radius"] - r0 / 1.25) < 1e-9 * r0
    keys = {s["key"]: s["label"] for s in p.js("stbsViewer.shortcuts()")}
    assert keys["["] == "brush smaller" and keys["]"] == "brush larger"
    p.page.keyboard.press("?")
    assert "brush larger" in p.page.inner_text("#help")
    p.page.keyboard.press("Escape")
    p.js("r => stbsViewer.setPaint({radius: r})", r0)
    assert p.errors == []


def test_strokes_and_pose_edits_share_one_history(arms):
    p = arms
    diag = _diag(p.rig)
    W0, _ = _weights(p)
    p.js("stbsViewer.setPose({rotate: {'arm.L': {axis: [0, 0, 1], angle: 30}}})")
    p.js("stbsViewer.turnBone('arm.L', [0, 0, 1], 10)")
    p.js("stbsViewer.idle()")
    pose1 = p.js("stbsViewer.getPose()")
    p.js("stbsViewer.setPaint({mode: 'bone', bone: 'arm.L', mirror: false})")
    _stroke(p, [_ring_point(p, 2.0)])
    W1, _ = _weights(p)
    assert not np.array_equal(W1, W0)
    assert p.js("stbsViewer.history()")["undo"][-1] == "paint bone weights"
    # Ctrl-Z: the stroke first, then the pose edit; Ctrl-Shift-Z: back again
    p.page.keyboard.press("Control+z")
    assert np.array_equal(_weights(p)[0], W0)
    assert p.js("stbsViewer.idle().then(() => stbsViewer.getPose())") == pose1
    U1 = p.positions()
    p.page.keyboard.press("Control+z")
    p.js("stbsViewer.idle()")
    assert p.js("stbsViewer.getPose()") != pose1
    assert np.abs(p.positions() - U1).max() > 1e-3 * diag
    p.page.keyboard.press("Control+Shift+z")
    p.page.keyboard.press("Control+Shift+z")
    p.js("stbsViewer.idle()")
    assert np.array_equal(_weights(p)[0], W1)
    p.js("stbsViewer.paintUndo()")
    p.js("stbsViewer.setPaint({mode: 'off'})")
    assert p.errors == []
