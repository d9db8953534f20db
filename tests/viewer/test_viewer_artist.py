"""The viewer page's pose mode for artists in a real browser (headless Chromium,
Playwright): clicking a bone selects it (highlighted, the bone list follows), the
keyboard shortcuts and their help overlay, X-mirror posing, the one History (pose and
key edits undone and redone bit for bit), the layout at 1024x600 (panels never over
the character), orbiting with Alt in paint mode, and the page's error without its
token. Rigs and the page helper: test_viewer_page.py."""

from __future__ import annotations

import io
import json

import numpy as np
import pytest
from test_viewer_page import (  # noqa: F401  (fixture)
    READY_S,
    Page,
    _endpoints,
    _gauss_weights,
    browser,
    tube_rig,
)
from viewer_client import grid_mesh

import stbs

SELECTED = (255, 160, 64)       # the selected bone's colour (main.js)


def _shot(p):
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(p.page.screenshot())).convert("RGB"), dtype=np.int16)


def figure_rig(seed=5) -> stbs.Rig:
    """A 2D figure, symmetric about x = 0: a spine and two two-bone arms named .L/.R."""
    rng = np.random.default_rng(seed)
    xs, ys = np.linspace(-2.3, 2.3, 47), np.linspace(-1.2, 1.5, 28)
    V, F = grid_mesh(xs, ys)
    C = np.array([[0, -1], [0, 1], [1, 1], [2, 1], [-1, 1], [-2, 1]], dtype=float)
    BE = np.array([[0, 1], [1, 2], [2, 3], [1, 4], [4, 5]])
    names = ["spine", "arm.L", "hand.L", "arm.R", "hand.R"]
    sk = stbs.Skeleton(C, BE, names)
    return stbs.Rig(V=V, F=np.array(F), skeleton=sk, W=_gauss_weights(V, sk, 0.4),
                    E=_endpoints(V, sk, rng))


@pytest.fixture(scope="module")
def tube(browser):  # noqa: F811
    p = Page(browser, tube_rig())
    yield p
    p.close()


@pytest.fixture(scope="module")
def figure(browser):  # noqa: F811
    p = Page(browser, figure_rig())
    yield p
    p.close()


def _bone_mid(p, rig, i):
    J = np.array(p.js("stbsViewer.jointScreenPositions()"))
    a, b = rig.skeleton.BE[i]
    return 0.5 * (J[a] + J[b])


def _slide(p, sel, value):
    p.page.eval_on_selector(sel, """(e, v) => { e.value = v; e.dispatchEvent(new Event('input'));
        e.dispatchEvent(new Event('change')); }""", value)


def _state(p):
    """Everything an edit may change: the pose (object and posed joints), the keys, the
    clip, the weights (W and E as the bytes of their Float32Arrays)."""
    weights = p.js("""stbsViewer.weights().then(o => [o.W, o.E].map(a =>
        Array.from(new Uint8Array(a.buffer, a.byteOffset, a.byteLength))))""")
    return {"pose": p.js("stbsViewer.getPose()"), "joints": p.js("stbsViewer.posedJoints()"),
            "keys": p.js("stbsViewer.keys()"), "clip": p.js("stbsViewer.clipState()"),
            "weights": weights}


# --------------------------------------------------------------------------- selection
def test_a_click_on_a_bone_selects_it_highlighted_and_the_list_follows(figure):
    p, rig = figure, figure.rig
    p.js("stbsViewer.setPose({})")
    for i in (3, 1):                          # arm.R, then arm.L
        x, y = _bone_mid(p, rig, i)
        p.page.mouse.click(x, y)
        assert p.js("stbsViewer.store()")["selection"] == {"bone": i}
        assert p.page.eval_on_selector("#bone", "e => e.value") == str(i)
        img = _shot(p)
        patch = img[int(y) - 2:int(y) + 3, int(x) - 2:int(x) + 3].reshape(-1, 3)
        near = np.abs(patch - np.array(SELECTED)).max(axis=1)
        assert near.min() <= 40, f"bone {i} is not drawn in the selection colour at its middle"
    # drawn wider than a plain bone: the colour spans several pixels across the bone
    column = np.abs(img[int(y) - 6:int(y) + 7, int(x)] - np.array(SELECTED)).max(axis=1)
    assert int((column <= 40).sum()) >= 3
    # a ring round its start joint (arm.L starts at joint 1 and points along +x): the
    # selection colour 11 pixels from the joint in directions away from the bone
    jx, jy = p.js("stbsViewer.jointScreenPositions()")[1]
    hits = 0
    for deg in range(40, 330, 10):
        t = np.radians(deg)
        ring = img[int(round(jy - 11 * np.sin(t))) - 1:int(round(jy - 11 * np.sin(t))) + 2,
                   int(round(jx + 11 * np.cos(t))) - 1:int(round(jx + 11 * np.cos(t))) + 2]
        hits += int(np.abs(ring.reshape(-1, 3) - np.array(SELECTED)).max(axis=1).min() <= 40)
    assert hits >= 20, f"the joint ring shows at {hits} of 29 directions"
    # a click on empty space, or a drag of the camera from there, keeps the selection
    rect = p.js("stbsViewer.camera()")
    ex, ey = rect["left"] + 5, rect["top"] + rect["height"] - 5
    p.page.mouse.click(ex, ey)
    assert p.js("stbsViewer.store()")["selection"] == {"bone": 1}
    p.page.mouse.move(ex, ey)
    p.page.mouse.down()
    p.page.mouse.move(ex + 40, ey - 30, steps=5)
    p.page.mouse.up()
    assert p.js("stbsViewer.store()")["selection"] == {"bone": 1}
    # the bone list selects too; the gizmo, when on, follows the selection
    p.page.select_option("#bone", "2")
    assert p.js("stbsViewer.store()")["selection"] == {"bone": 2}
    p.js("stbsViewer.setGizmo(2)")
    x, y = _bone_mid(p, rig, 4)
    p.page.mouse.click(x, y)
    assert p.js("stbsViewer.gizmo()")["bone"] == 4
    p.js("stbsViewer.setGizmo(null)")


# --------------------------------------------------------------------------- shortcuts
def test_shortcuts_and_their_help_overlay_do_nothing_while_typing(figure):
    p = figure
    kb = p.page.keyboard
    p.page.mouse.click(*_bone_mid(p, p.rig, 0))     # focus on the page, not a field
    kb.press("?")
    help_ = p.page.locator("#help")
    assert help_.is_visible()
    listed = help_.inner_text()
    for s in p.js("stbsViewer.shortcuts()"):
        assert s["label"] in listed
    for label in ("undo", "redo", "play or pause", "frame the view", "switch between posing",
                  "mirror"):
        assert label in listed
    kb.press("Escape")
    assert not help_.is_visible()
    assert p.js("stbsViewer.store()")["mirror"] is False
    kb.press("x")
    assert p.js("stbsViewer.store()")["mirror"] is True
    assert p.page.is_checked("#mirror")
    kb.press("x")
    assert p.js("stbsViewer.store()")["mirror"] is False
    kb.press("Tab")
    assert p.js("stbsViewer.store()")["mode"] == "paint"
    assert p.js("stbsViewer.paint()")["mode"] == "bone"      # the brush is on
    kb.press("Tab")
    assert p.js("stbsViewer.store()")["mode"] == "pose"
    assert p.js("stbsViewer.paint()")["mode"] == "off"
    # typing in a field: the keys are text there
    p.page.click("#pose-name")
    kb.type("x?")
    assert p.page.input_value("#pose-name") == "x?"
    assert p.js("stbsViewer.store()")["mirror"] is False
    assert not p.page.locator("#help").is_visible()
    p.page.fill("#pose-name", "")
    # F frames: a camera moved away comes back to the framing
    p.page.mouse.click(*_bone_mid(p, p.rig, 0))
    framed = p.js("stbsViewer.frame()")["projection"]
    p.page.mouse.move(320, 240)
    p.page.mouse.wheel(0, 600)
    p.js("new Promise(r => setTimeout(r, 100))")
    assert p.js("stbsViewer.camera()")["projection"] != framed
    kb.press("f")
    assert np.allclose(p.js("stbsViewer.camera()")["projection"], framed)
    # Ctrl-Z and Ctrl-Shift-Z: one History for the page
    p.js("stbsViewer.setPose({})")
    before = p.js("stbsViewer.getPose()")
    p.js("stbsViewer.turnBone('arm.L', null, 25)")
    after = p.js("stbsViewer.getPose()")
    kb.press("Control+z")
    p.js("stbsViewer.idle()")
    assert p.js("stbsViewer.getPose()") == before
    kb.press("Control+Shift+z")
    p.js("stbsViewer.idle()")
    assert p.js("stbsViewer.getPose()") == after
    # Space plays and pauses the clip
    p.js("stbsViewer.clearKeys()")
    p.js("stbsViewer.addKey(0)")
    p.js("stbsViewer.turnBone('spine', null, 20)")
    p.js("stbsViewer.addKey(1)")
    kb.press(" ")
    p.page.wait_for_function("() => stbsViewer.clipState().playing", timeout=10000)
    kb.press(" ")
    p.page.wait_for_function("() => !stbsViewer.clipState().playing", timeout=10000)
    p.js("stbsViewer.clearKeys()")
    kb.press(" ")                      # no keys: Space does nothing (no error either)
    assert not p.js("stbsViewer.clipState().playing")
    assert p.page.locator("#status.error").count() == 0


# --------------------------------------------------------------------------- mirror
def test_x_mirror_posing_turns_the_mirror_bone_the_other_way(figure):
    p = figure
    p.js("stbsViewer.setPose({})")
    p.js("stbsViewer.setMirror(true)")
    try:
        p.js("stbsViewer.turnBone('arm.L', null, 30)")
        pose = p.js("stbsViewer.getPose()")
        assert pose["rotate"]["arm.L"]["angle"] == pytest.approx(30, abs=1e-9)
        assert pose["rotate"]["arm.R"]["angle"] == pytest.approx(-30, abs=1e-9)
        assert "spine" not in pose.get("rotate", {})
        # the posed joints are mirror images across x = 0
        J = np.array(p.js("stbsViewer.posedJoints()"))
        assert np.allclose(J[[4, 5]] * [-1, 1], J[[2, 3]], atol=1e-9)
        # a slider: the mirror bone gets the same stretch
        p.js("stbsViewer.selectBone('hand.R')")
        _slide(p, "#stretch", "1.5")
        p.js("stbsViewer.idle()")
        pose = p.js("stbsViewer.getPose()")
        assert pose["stretch"] == {"hand.L": 1.5, "hand.R": 1.5}
        # one undo step each, the mirrored edit with it
        p.js("stbsViewer.undo()")
        assert "stretch" not in p.js("stbsViewer.getPose()")
        p.js("stbsViewer.undo()")
        assert p.js("stbsViewer.getPose()").get("rotate") is None
    finally:
        p.js("stbsViewer.setMirror(false)")
    p.js("stbsViewer.turnBone('arm.L', null, 30)")
    assert "arm.R" not in p.js("stbsViewer.getPose()")["rotate"]


# --------------------------------------------------------------------------- one History
def test_undoing_every_pose_key_and_paint_edit_restores_the_state_bit_for_bit(tube):
    p = tube
    p.js("stbsViewer.setPose({})")
    p.js("stbsViewer.clearKeys()")
    while p.js("stbsViewer.canUndo()"):       # a History that starts here
        p.js("stbsViewer.undo()")
    p.js("stbsViewer.setPose({rotate: {'3': {axis: [0, 1, 0], angle: 20}}})")
    start = _state(p)
    names = []
    # pose edits: the gizmo's turn, a joint drag, the sliders, reset, a pose file
    p.js("stbsViewer.turnBone(5, [0, 0, 1], 40)")
    J = p.js("stbsViewer.jointScreenPositions()")
    x, y = J[12]
    p.page.mouse.move(x, y)
    p.page.mouse.down()
    for k in range(1, 6):
        p.page.mouse.move(x + 6 * k, y - 5 * k)
    p.page.mouse.up()
    p.js("stbsViewer.idle()")
    p.js("stbsViewer.selectBone(7)")
    _slide(p, "#twist", "90")
    p.js("stbsViewer.idle()")
    # a paint stroke along the tube's middle
    p.js("stbsViewer.frame()")
    p.js("o => stbsViewer.setPaint(o)", {"mode": "bone", "bone": 10, "op": "add",
                                         "radius": 0.6, "strength": 0.4})
    J = p.js("stbsViewer.jointScreenPositions()")
    m = p.page.mouse
    m.move(*J[9])
    m.down()
    for q in (J[10], J[11]):
        m.move(*q, steps=4)
    m.up()
    p.js("stbsViewer.setPaint({mode: 'off'})")
    assert p.js("stbsViewer.history()")["undo"][-1] != "slider", "the stroke is no step"
    # key edits: add, fps, interpolation, delete, a clip set whole, clear
    p.js("stbsViewer.addKey(0)")
    p.js("stbsViewer.turnBone(9, [1, 0, 0], -30)")
    p.js("stbsViewer.addKey(1.5)")
    p.js("stbsViewer.setFps(12)")
    p.js("stbsViewer.setInterpolation('step')")
    p.js("stbsViewer.addKey(3)")
    p.js("stbsViewer.deleteKey(1.5)")
    p.js("stbsViewer.loadPoseText(JSON.stringify({stretch: {'2': 1.7}}))")
    clip = p.js("stbsViewer.getClip()")
    p.js("c => stbsViewer.setClip(c)", {"fps": 24, "interpolation": "linear",
                                          "keys": [{"time": 0, "pose": {}},
                                                   {"time": 2, "pose": clip["keys"][0]["pose"]}]})
    p.js("stbsViewer.seek(1)")
    edited = _state(p)
    names = p.js("stbsViewer.history()")["undo"]
    assert len(names) >= 10, names
    assert edited["pose"] != start["pose"] and edited["keys"] != start["keys"]
    assert edited["weights"] != start["weights"]
    n = 0
    while p.js("stbsViewer.canUndo()"):
        p.js("stbsViewer.undo()")
        n += 1
    p.js("stbsViewer.idle()")
    back = _state(p)
    assert n == len(names)
    assert back["pose"] == start["pose"]
    assert back["joints"] == start["joints"]          # exactly: the same pose arrays
    assert back["keys"] == start["keys"] and back["clip"] == start["clip"]
    assert back["weights"] == start["weights"]
    while p.js("stbsViewer.canRedo()"):
        p.js("stbsViewer.redo()")
    p.js("stbsViewer.idle()")
    again = _state(p)
    # a seek is not an edit: the redone state is the clip set whole, at its first key
    p.js("stbsViewer.seek(1)")
    again = _state(p)
    assert again == edited
    assert json.dumps(p.js("stbsViewer.history()")["redo"]) == "[]"


# --------------------------------------------------------------------------- the layout
def _rect(p, sel):
    return p.page.eval_on_selector(sel, """e => { const r = e.getBoundingClientRect();
        return [r.left, r.top, r.right, r.bottom]; }""")


def _overlap(a, b):
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


def test_at_1024x600_the_panels_never_cover_the_framed_character(browser):  # noqa: F811
    p = Page(browser, tube_rig())
    try:
        p.page.set_viewport_size({"width": 1024, "height": 600})
        p.page.eval_on_selector("#weights-panel", "e => { e.open = true; }")
        for collapsed in (False, True):
            if collapsed:
                for sel in ("#panel", "#timeline-panel"):
                    p.page.click(f"{sel} > summary")
            p.js("new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))")
            cam = p.js("stbsViewer.frame()")
            U = p.positions()
            view = np.array(cam["view"]).reshape(4, 4).T
            proj = np.array(cam["projection"]).reshape(4, 4).T
            X = np.hstack([U, np.ones((len(U), 1))]) @ (proj @ view).T
            ndc = X[:, :2] / X[:, 3:]
            sx = cam["left"] + 0.5 * (ndc[:, 0] + 1) * cam["width"]
            sy = cam["top"] + 0.5 * (1 - ndc[:, 1]) * cam["height"]
            box = [sx.min(), sy.min(), sx.max(), sy.max()]
            assert box[0] >= 0 and box[1] >= 0 and box[2] <= 1024 and box[3] <= 600
            view = [cam["left"], cam["top"], cam["left"] + cam["width"], cam["top"] + cam["height"]]
            for sel in ("#hud", "#panel", "#weights-panel", "#timeline-panel"):
                r = _rect(p, sel)
                assert not _overlap(box, r), f"{sel} {r} covers the character {box}"
                # the view the framing fills is the area the panels leave
                assert not _overlap(view, r), f"{sel} {r} covers the view {view}"
            print(f"1024x600, panels {'collapsed' if collapsed else 'open'}: view "
                  f"{cam['width']:.0f}x{cam['height']:.0f} at ({cam['left']:.0f}, "
                  f"{cam['top']:.0f}), mesh box {[round(v) for v in box]}")
            if not collapsed:
                open_width = cam["width"]
        # collapsed panels leave the canvas more room, and the framing uses it
        assert cam["width"] > open_width
        assert p.page.eval_on_selector("#panel", "e => e.getBoundingClientRect().height") < 40
        assert not p.errors, p.errors
    finally:
        p.close()


def test_alt_drag_orbits_and_the_wheel_zooms_while_painting(browser):  # noqa: F811
    p = Page(browser, tube_rig())
    try:
        p.js("stbsViewer.frame()")
        p.js("stbsViewer.setPaint({mode: 'bone', bone: 3, op: 'add', strength: 1})")
        W0 = p.js("stbsViewer.weights().then(w => Array.from(w.W))")
        cam0 = p.js("stbsViewer.camera()")
        cx, cy = cam0["left"] + cam0["width"] / 2, cam0["top"] + cam0["height"] / 2
        p.page.keyboard.down("Alt")
        p.page.mouse.move(cx, cy)
        p.page.mouse.down()
        p.page.mouse.move(cx + 60, cy + 20, steps=6)
        p.page.mouse.up()
        p.page.keyboard.up("Alt")
        cam1 = p.js("stbsViewer.camera()")
        assert cam1["view"] != cam0["view"], "Alt+drag did not orbit"
        assert p.js("stbsViewer.weights().then(w => Array.from(w.W))") == W0, "Alt+drag painted"
        p.page.mouse.move(cx, cy)
        p.page.mouse.wheel(0, -400)
        p.js("new Promise(r => setTimeout(r, 100))")
        assert p.js("stbsViewer.camera()")["view"] != cam1["view"], "the wheel did not zoom"
        p.js("stbsViewer.setPaint({mode: 'off'})")
    finally:
        p.close()


# --------------------------------------------------------------------------- errors
def test_without_the_token_the_error_is_shown_in_full_on_top(browser):  # noqa: F811
    p = Page(browser, tube_rig())
    try:
        context = browser.new_context(viewport={"width": 640, "height": 480})
        page = context.new_page()
        url = p.srv.url.split("?")[0]
        page.goto(url)
        page.wait_for_function("() => document.querySelector('#status.error') !== null",
                               timeout=READY_S * 1000)
        info = page.eval_on_selector("#status", """e => { const r = e.getBoundingClientRect();
            const top = document.elementFromPoint(r.left + r.width / 2, r.top + r.height / 2);
            return {text: e.textContent, visible: r.width > 0 && r.height > 0,
                    inside: r.left >= 0 && r.top >= 0 && r.right <= innerWidth &&
                            r.bottom <= innerHeight,
                    whole: e.scrollWidth <= e.clientWidth && e.scrollHeight <= e.clientHeight,
                    onTop: top === e || e.contains(top),
                    color: getComputedStyle(e).color,
                    bg: getComputedStyle(e).backgroundColor}; }""")
        assert info["visible"] and info["inside"] and info["whole"] and info["onTop"], info
        assert "token" in info["text"].lower(), info["text"]
        assert info["color"] != info["bg"]
        page.click("#status")               # a click closes the banner
        assert page.locator("#status.error").count() == 0
        context.close()
    finally:
        p.close()
