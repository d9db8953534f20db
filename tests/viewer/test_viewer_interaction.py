"""The viewer page's pose editing in a real browser (headless Chromium, Playwright):
framing the posed mesh, dragging a joint with the mouse, the per-bone twist and
stretch sliders, undo and redo. Rigs and the page helper: test_viewer_page.py."""

from __future__ import annotations

import io

import numpy as np
import pytest
from test_viewer_page import Page, browser, plate_rig, tube_rig  # noqa: F401  (fixture)

import stbs

W, H = 640, 480


def _ndc(cam, P):
    """Points (m, 3) -> normalised device coordinates (m, 3) and clip w, by the page's camera."""
    view = np.array(cam["view"]).reshape(4, 4).T           # three.js: column-major
    proj = np.array(cam["projection"]).reshape(4, 4).T
    X = np.hstack([P, np.ones((len(P), 1))]) @ (proj @ view).T
    return X[:, :3] / X[:, 3:], X[:, 3]


def _shot(p):
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(p.page.screenshot())).convert("RGB"), dtype=np.int16)


@pytest.fixture(scope="module")
def tube(browser):  # noqa: F811
    p = Page(browser, tube_rig())
    yield p
    p.close()


@pytest.fixture(scope="module")
def plate(browser):  # noqa: F811
    p = Page(browser, plate_rig())
    yield p
    p.close()


def _big_pose(dim):
    if dim == 3:
        return {"rotate": {"0": {"axis": [0, 0, 1], "angle": 60},
                           "5": {"axis": [0, 1, 0], "angle": 50},
                           "12": {"axis": [0, 0, 1], "angle": -80}},
                "stretch": {"3": 2.5, "9": 2.0, "15": 2.8}, "translate": [4, 3, -2]}
    return {"rotate": {"0": {"angle": 70}, "6": {"angle": -60}}, "stretch": {"2": 2.5, "8": 2.8},
            "translate": [3, -2]}


@pytest.mark.parametrize("which", ["tube", "plate"])
def test_the_view_frames_the_posed_mesh(which, request):
    p = request.getfixturevalue(which)
    p.js("o => stbsViewer.setPose(o)", _big_pose(p.info["dim"]))
    for cam in (p.js("stbsViewer.camera()"), p.js("stbsViewer.frame()")):
        ndc, w = _ndc(cam, p.positions())
        assert np.all(w > 0)
        assert np.abs(ndc[:, :2]).max() <= 1.0, np.abs(ndc[:, :2]).max(0)
        # framed, not lost in the distance: the mesh spans most of one axis
        assert np.ptp(ndc[:, :2], axis=0).max() > 0.8
    p.js("stbsViewer.setPose({})")
    assert p.errors == []


def _drag(p, joint, dx, dy):
    x, y = p.js("stbsViewer.jointScreenPositions()")[joint]
    m = p.page.mouse
    m.move(x, y)
    m.down()
    for k in range(1, 6):
        m.move(x + dx * k / 5, y + dy * k / 5)
    m.up()
    p.js("stbsViewer.idle()")
    return x, y


@pytest.mark.parametrize("which", ["plate", "tube"])
def test_dragging_a_joint_poses_it_and_undo_gives_the_pose_back(which, request):
    p = request.getfixturevalue(which)
    d = p.info["dim"]
    start = {"stretch": {"2": 1.3}} if d == 2 else {"twist": {"4": [0, 90]}, "stretch": {"2": 1.3}}
    p.js("o => stbsViewer.setPose(o)", start)
    before = p.js("stbsViewer.getPose()")
    J0 = np.array(p.js("stbsViewer.posedJoints()"))
    cam = p.js("stbsViewer.camera()")
    shot0 = _shot(p)
    joint, dx, dy = 14, 60, -45           # a joint inside the chain: two bones stretch
    x, y = _drag(p, joint, dx, dy)
    after = p.js("stbsViewer.getPose()")
    assert after != before
    J1 = np.array(p.js("stbsViewer.posedJoints()"))
    moved = np.linalg.norm(J1 - J0, axis=1)
    assert moved[joint] > 0 and np.delete(moved, joint).max() < 1e-5 * moved[joint]
    # on screen the joint follows the mouse; in world units it moved by the mouse delta
    sx, sy = p.js("stbsViewer.jointScreenPositions()")[joint]
    assert abs(sx - (x + dx)) < 1.5 and abs(sy - (y + dy)) < 1.5, (sx, sy, x + dx, y + dy)
    if d == 2:
        per_px = 2.0 / np.array(cam["projection"]).reshape(4, 4).T[1, 1] / cam["height"]
        assert np.allclose(J1[joint] - J0[joint], [dx * per_px, -dy * per_px], rtol=1e-3)
    else:                                 # twists carried over into the joints form
        pose = stbs.io.read_pose(after, p.rig.skeleton)
        assert np.isclose(pose.twist[4, 1], np.pi / 2)
    diff = np.abs(_shot(p) - shot0).max(axis=2) > 24
    assert diff.mean() > 0.001, diff.mean()
    assert p.js("stbsViewer.canUndo()")
    p.js("stbsViewer.undo()")
    assert p.js("stbsViewer.getPose()") == before
    assert np.abs(np.array(p.js("stbsViewer.posedJoints()")) - J0).max() < 1e-6
    p.js("stbsViewer.redo()")
    assert p.js("stbsViewer.getPose()") == after
    # the keyboard: Ctrl-Z and Ctrl-Shift-Z
    p.page.keyboard.press("Control+z")
    p.js("stbsViewer.idle()")
    assert p.js("stbsViewer.idle().then(() => stbsViewer.getPose())") == before
    p.page.keyboard.press("Control+Shift+z")
    p.js("stbsViewer.idle()")
    assert p.js("stbsViewer.idle().then(() => stbsViewer.getPose())") == after
    p.js("stbsViewer.setPose({})")
    assert p.errors == []


def test_a_drag_off_the_joints_orbits_and_keeps_the_pose(tube):
    tube.js("stbsViewer.setPose({})")
    before = tube.js("stbsViewer.getPose()")
    cam0 = tube.js("stbsViewer.camera()")
    m = tube.page.mouse
    x0, y0 = cam0["left"] + 20, cam0["top"] + cam0["height"] - 20     # a corner of the view
    m.move(x0, y0)
    m.down()
    m.move(x0 + 60, y0 - 40, steps=5)
    m.up()
    assert tube.js("stbsViewer.getPose()") == before
    assert tube.js("stbsViewer.camera()")["view"] != cam0["view"]
    tube.js("stbsViewer.frame()")
    assert tube.errors == []


def _slide(p, bone, twist=None, stretch=None):
    p.page.select_option("#bone", str(bone))
    for sel, val in (("#twist", twist), ("#stretch", stretch)):
        if val is not None:
            p.js("""([s, v]) => { const el = document.querySelector(s); el.value = String(v);
                    el.dispatchEvent(new Event('input', {bubbles: true}));
                    el.dispatchEvent(new Event('change', {bubbles: true})); }""", [sel, val])
    p.js("stbsViewer.idle()")


def test_twist_and_stretch_sliders_equal_the_library(tube):
    rig, sk = tube.rig, tube.rig.skeleton
    V = np.asarray(rig.V, dtype=np.float64)
    diag = float(np.linalg.norm(np.ptp(V, axis=0)))
    tube.js("stbsViewer.setPose({})")
    tube.js("stbsViewer.setMethod('stbs-dqs')")
    U0 = tube.positions()
    _slide(tube, 6, twist=540)
    _slide(tube, 12, stretch=2.2)
    U = tube.positions()
    assert np.abs(U - U0).max() > 0.1
    want = {"twist": {"b6": [0, 540]}, "stretch": {"b12": 2.2}}
    pose = stbs.read_pose(want, sk)
    ref = stbs.deform(V, sk, pose, rig.W, rig.E, method="stbs-dqs", max_influences=4)
    assert np.abs(U - ref).max() / diag < 1e-4
    assert tube.js("document.querySelector('#twist-value').textContent") == "0°"   # bone 12's
    tube.page.select_option("#bone", "6")
    assert tube.js("document.querySelector('#twist').value") == "540"
    # undo takes back the stretch, then the twist; reset gives the rest pose
    tube.js("stbsViewer.undo()")
    ref6 = stbs.deform(V, sk, stbs.read_pose({"twist": {"b6": [0, 540]}}, sk), rig.W, rig.E,
                       method="stbs-dqs", max_influences=4)
    assert np.abs(tube.positions() - ref6).max() / diag < 1e-4
    tube.page.click("#reset")
    tube.js("stbsViewer.idle()")
    assert np.abs(tube.positions() - U0).max() < 1e-5
    assert tube.js("document.querySelector('#twist').value") == "0"
    assert tube.errors == []


def test_a_2d_rig_has_no_twist_slider(plate):
    assert plate.js("document.querySelector('#twist-row').hidden") is True
    _slide(plate, 3, stretch=2.0)
    pose = stbs.read_pose({"stretch": {"3": 2.0}}, plate.rig.skeleton)
    assert np.allclose(plate.srv.pose.stretch, pose.stretch)
    plate.js("stbsViewer.setPose({})")
    assert plate.errors == []
