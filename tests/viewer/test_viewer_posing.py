"""The viewer page's posing tools in a real browser (headless Chromium, Playwright):
the IK drag (bone lengths kept), the rotation gizmo (forward kinematics), side by side
methods, pose files saved, downloaded and loaded from the page. Rigs and the page
helper: test_viewer_page.py."""

from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np
import pytest
from test_viewer_page import READY_S, Page, browser, plate_rig, tube_rig  # noqa: F401  (fixture)

import stbs

SCREENS = Path(__file__).resolve().parents[2] / "build" / "screens"


def PosingPage(browser, rig, pose_folder=None):  # noqa: N802, F811
    """Page with a pose folder, so that "save pose" writes there, and downloads on."""
    return Page(browser, rig, pose_folder=pose_folder, name="posing",
                page_options={"accept_downloads": True})


@pytest.fixture(scope="module")
def tube(browser, tmp_path_factory):  # noqa: F811
    p = PosingPage(browser, tube_rig(), pose_folder=tmp_path_factory.mktemp("poses"))
    yield p
    p.close()


@pytest.fixture(scope="module")
def plate(browser):  # noqa: F811
    p = PosingPage(browser, plate_rig())
    yield p
    p.close()


def _lengths(J, BE):
    J = np.asarray(J, dtype=np.float64)
    return np.linalg.norm(J[BE[:, 1]] - J[BE[:, 0]], axis=1)


def _mouse_path(p, points):
    m = p.page.mouse
    m.move(*points[0])
    m.down()
    for q in points[1:]:
        m.move(*q)
    m.up()
    p.js("stbsViewer.idle()")


def _drag(p, x, y, dx, dy, steps=6):
    _mouse_path(p, [(x + dx * k / steps, y + dy * k / steps) for k in range(steps + 1)])


def _canvas(p, name=None):
    """The canvas's pixels (no page overlays), RGB int16; saved under build/screens."""
    import base64

    from PIL import Image

    url = p.js("document.getElementById('view').toDataURL('image/png')")
    img = Image.open(io.BytesIO(base64.b64decode(url.split(",", 1)[1]))).convert("RGB")
    if name:
        SCREENS.mkdir(parents=True, exist_ok=True)
        Image.open(io.BytesIO(p.page.screenshot())).save(SCREENS / f"posing-{name}.png")
    return np.asarray(img, dtype=np.int16)


def _wait_status(p, part, seconds=20):
    """Poll the status line until it holds `part` (the page's CSP forbids eval'd predicates)."""
    for _ in range(int(seconds / 0.05)):
        text = p.js("document.getElementById('status').textContent")
        if part in text:
            return text
        p.page.wait_for_timeout(50)
    raise AssertionError(f"status line {text!r} never held {part!r}")


def _pose(p):
    return stbs.io.read_pose(p.js("stbsViewer.getPose()"), p.rig.skeleton)


# --------------------------------------------------------------------------- IK drag
def test_ik_drag_of_the_end_joint_keeps_bone_lengths_and_twists(tube):
    sk = tube.rig.skeleton
    assert tube.js("stbsViewer.dragMode()") == "stretch"          # the default
    tube.js("o => stbsViewer.setPose(o)", {"twist": {"4": [0, 90]}, "stretch": {"2": 1.3}})
    assert tube.js("stbsViewer.setDragMode('ik')") == "ik"
    assert tube.js("document.querySelector('#drag-mode').value") == "ik"
    before = tube.js("stbsViewer.getPose()")
    J0 = np.array(tube.js("stbsViewer.posedJoints()"))
    L0 = _lengths(J0, sk.BE)
    x, y = tube.js("stbsViewer.jointScreenPositions()")[20]
    dx, dy = -90, -70
    _drag(tube, x, y, dx, dy)
    J1 = np.array(tube.js("stbsViewer.posedJoints()"))
    # the end joint is under the cursor (within reach), the root joint stays
    sx, sy = tube.js("stbsViewer.jointScreenPositions()")[20]
    assert np.hypot(sx - (x + dx), sy - (y + dy)) < 1.5, (sx, sy, x + dx, y + dy)
    assert np.linalg.norm(J1[0] - J0[0]) < 1e-5
    assert np.abs(_lengths(J1, sk.BE) / L0 - 1).max() < 1e-4
    assert np.linalg.norm(J1 - J0, axis=1)[10:].min() > 1e-3       # the chain bent along
    after = tube.js("stbsViewer.getPose()")
    assert "joints" not in after and "rotate" in after              # the FK form
    pose = stbs.io.read_pose(after, sk)
    assert np.isclose(pose.twist[4, 1], np.pi / 2) and np.isclose(pose.stretch[2], 1.3)
    tube.js("stbsViewer.undo()")
    assert tube.js("stbsViewer.getPose()") == before
    tube.js("stbsViewer.setDragMode('stretch')")
    msg = tube.js("stbsViewer.setDragMode('bend').then(() => 'ok', e => e.message)")
    assert msg == 'drag mode must be one of stretch, ik, got "bend"'
    tube.js("stbsViewer.setPose({})")
    assert tube.errors == []


def test_ik_drag_in_a_branch_stops_at_the_branching_joint(plate):
    sk = plate.rig.skeleton
    plate.js("stbsViewer.setPose({})")
    plate.js("stbsViewer.setDragMode('ik')")
    J0 = np.array(plate.js("stbsViewer.posedJoints()"))
    x, y = plate.js("stbsViewer.jointScreenPositions()")[15]    # the upper branch's tip
    dx, dy = 60, 40
    _drag(plate, x, y, dx, dy)
    J1 = np.array(plate.js("stbsViewer.posedJoints()"))
    sx, sy = plate.js("stbsViewer.jointScreenPositions()")[15]
    assert np.hypot(sx - (x + dx), sy - (y + dy)) < 1.5
    assert np.abs(_lengths(J1, sk.BE) / _lengths(J0, sk.BE) - 1).max() < 1e-4
    moved = np.linalg.norm(J1 - J0, axis=1)
    branch = [11, 12, 13, 14, 15]                # joint 5 (three bones start there) stays
    assert np.delete(moved, branch).max() < 1e-5 and moved[branch].min() > 1e-4
    plate.js("stbsViewer.undo()")
    assert np.abs(np.array(plate.js("stbsViewer.posedJoints()")) - J0).max() < 1e-5
    # the root joint: the skeleton moves as a whole
    x, y = plate.js("stbsViewer.jointScreenPositions()")[0]
    _drag(plate, x, y, 30, -20)
    shift = np.array(plate.js("stbsViewer.posedJoints()")) - J0
    assert np.linalg.norm(shift[0]) > 1e-3 and np.abs(shift - shift[0]).max() < 1e-5
    assert "translate" in plate.js("stbsViewer.getPose()")
    plate.js("stbsViewer.undo()")
    plate.js("stbsViewer.setDragMode('stretch')")
    assert plate.errors == []


def test_a_stretch_drag_after_a_twist_keeps_the_roll_below_it(tube):
    sk = tube.rig.skeleton
    tube.js("o => stbsViewer.setPose(o)", {"twist": {"4": [0, 90]}})
    R0 = _pose(tube).rotations
    x, y = tube.js("stbsViewer.jointScreenPositions()")[14]
    _drag(tube, x, y, 40, -30)
    after = _pose(tube)
    moved = [13, 14]                             # the two bones at joint 14
    keep = [i for i in range(sk.n_bones) if i not in moved]
    # bones 5.. carry bone 4's twist as roll: a drag elsewhere must keep it
    assert np.abs(after.rotations[keep] - R0[keep]).max() < 1e-6
    assert np.abs(after.rotations[moved] - R0[moved]).max() > 1e-3
    tube.js("stbsViewer.setPose({})")


# --------------------------------------------------------------------------- the gizmo
def _ring(info, name):
    return next(r for r in info["rings"] if r["name"] == name)


def test_the_gizmo_turns_a_bone_and_its_children_in_2d(plate):
    sk = plate.rig.skeleton
    plate.js("stbsViewer.setPose({})")
    before = plate.js("stbsViewer.getPose()")
    J0 = np.array(plate.js("stbsViewer.posedJoints()"))
    info = plate.js("stbsViewer.setGizmo(7).then(() => stbsViewer.gizmo())")
    assert info["bone"] == 7 and [r["name"] for r in info["rings"]] == ["z"]
    assert plate.js("document.querySelector('#gizmo').checked") is True
    cx, cy = info["center"]
    assert np.allclose([cx, cy], plate.js("stbsViewer.jointScreenPositions()")[7], atol=1e-6)
    r = info["radius"]
    pts = np.array(_ring(info, "z")["points"])
    assert np.allclose(np.hypot(pts[:, 0] - cx, pts[:, 1] - cy), r, rtol=0.02)
    _canvas(plate, "gizmo-2d")
    turn = 50.0                                  # counter-clockwise on the screen
    path = [(cx + r * np.cos(t), cy - r * np.sin(t)) for t in np.radians(np.linspace(0, turn, 11))]
    _mouse_path(plate, path)
    J1 = np.array(plate.js("stbsViewer.posedJoints()"))
    d0, d1 = J0[8] - J0[7], J1[8] - J1[7]
    got = np.degrees(np.arctan2(d0[0] * d1[1] - d0[1] * d1[0], d0 @ d1))
    assert abs(got - turn) < 2.0, got
    assert np.abs(_lengths(J1, sk.BE) / _lengths(J0, sk.BE) - 1).max() < 1e-5
    moved = np.linalg.norm(J1 - J0, axis=1)
    assert moved[:8].max() < 1e-5 and moved[11:].max() < 1e-5 and moved[8:11].min() > 1e-3
    after = plate.js("stbsViewer.getPose()")
    name = sk.names[7]
    assert list(after["rotate"]) == [name] and "joints" not in after, after["rotate"]
    assert abs(after["rotate"][name]["angle"] - got) < 1e-3
    # the stretch slider then keeps the rotation; undo takes back one step at a time
    assert plate.js("document.querySelector('#bone').value") == "7"
    plate.js("""() => { const el = document.querySelector('#stretch'); el.value = '1.5';
                el.dispatchEvent(new Event('input', {bubbles: true}));
                el.dispatchEvent(new Event('change', {bubbles: true})); }""")
    plate.js("stbsViewer.idle()")
    slid = plate.js("stbsViewer.getPose()")
    assert slid["rotate"] == after["rotate"] and slid["stretch"] == {name: 1.5}
    plate.js("stbsViewer.undo()")
    assert plate.js("stbsViewer.getPose()") == after
    plate.js("stbsViewer.undo()")
    assert plate.js("stbsViewer.getPose()") == before
    plate.js("stbsViewer.setGizmo(null)")
    assert plate.js("stbsViewer.gizmo()") is None
    msg = plate.js("stbsViewer.setGizmo('elbow').then(() => 'ok', e => e.message)")
    assert msg == 'gizmo: expected a bone index 0..19 or name, got "elbow"'
    assert plate.js("stbsViewer.gizmo()") is None
    assert plate.errors == []


def _rodrigues(n, a):
    n = np.asarray(n, dtype=np.float64) / np.linalg.norm(n)
    K = np.array([[0, -n[2], n[1]], [n[2], 0, -n[0]], [-n[1], n[0], 0]])
    return np.eye(3) + np.sin(a) * K + (1 - np.cos(a)) * K @ K


def test_the_gizmo_view_ring_turns_a_3d_bone_keeping_stretch_and_twist(tube):
    sk = tube.rig.skeleton
    tube.js("o => stbsViewer.setPose(o)", {"twist": {"4": [0, 120]}, "stretch": {"9": 1.4}})
    tube.js("stbsViewer.frame()")
    before = tube.js("stbsViewer.getPose()")
    J0 = np.array(tube.js("stbsViewer.posedJoints()"))
    info = tube.js("stbsViewer.setGizmo('b8').then(() => stbsViewer.gizmo())")
    assert info["bone"] == 8 and {r["name"] for r in info["rings"]} == {"x", "y", "z", "view"}
    view = _ring(info, "view")
    cx, cy = info["center"]
    pts = np.array(view["points"])
    rv = float(np.mean(np.hypot(pts[:, 0] - cx, pts[:, 1] - cy)))
    _canvas(tube, "gizmo-3d")
    turn = 40.0
    ts = np.radians(np.linspace(90, 90 - turn, 9))
    path = [(cx + rv * np.cos(t), cy + rv * np.sin(t)) for t in ts]
    _mouse_path(tube, path)                      # counter-clockwise on the screen
    J1 = np.array(tube.js("stbsViewer.posedJoints()"))
    want = J0[8] + (J0[9:] - J0[8]) @ _rodrigues(view["axis"], np.radians(turn)).T
    err = np.linalg.norm(J1[9:] - want, axis=1) / np.linalg.norm(J0[9:] - J0[8], axis=1)
    assert err.max() < np.radians(2.5), err.max()        # about the dragged angle
    assert np.abs(J1[:9] - J0[:9]).max() < 1e-5
    assert np.abs(_lengths(J1, sk.BE) / _lengths(J0, sk.BE) - 1).max() < 1e-5
    after = tube.js("stbsViewer.getPose()")
    assert "b8" in after["rotate"] and "joints" not in after
    pose = stbs.io.read_pose(after, sk)
    assert np.isclose(pose.stretch[9], 1.4) and np.isclose(pose.twist[4, 1], np.radians(120))
    tube.js("stbsViewer.undo()")
    assert tube.js("stbsViewer.getPose()") == before
    tube.js("stbsViewer.setGizmo(null)")
    tube.js("stbsViewer.setPose({})")
    assert tube.errors == []


# --------------------------------------------------------------------------- side by side
def _differ(a, b):
    return float((np.abs(a - b).max(axis=2) > 24).mean())


def test_side_by_side_draws_two_methods_and_keeps_picking(plate):
    plate.js("o => stbsViewer.setPose(o)", {"rotate": {"0": {"angle": 40}, "4": {"angle": 80}},
                                             "stretch": {"3": 2.5, "8": 2.2}})
    plate.js("stbsViewer.setMethod('stbs-dqs')")
    U0 = plate.positions()
    one = _canvas(plate, "single")
    assert plate.js("stbsViewer.compare()") is None
    assert plate.js("stbsViewer.setCompare('lbs')") == "lbs"
    assert plate.js("stbsViewer.compare()") == "lbs"
    two = _canvas(plate, "compare-lbs")
    h, w = two.shape[:2]
    left, right = two[:, : w // 2], two[:, w // 2:]
    assert _differ(left, right) > 0.01, _differ(left, right)
    assert _differ(two, one) > 0.01
    assert not plate.js("document.querySelector('#compare-labels').hidden")
    # the API reads the primary (left) method
    assert np.abs(plate.positions() - U0).max() < 1e-6
    same = plate.js("stbsViewer.setCompare('stbs-dqs').then(() => 0)") == 0 and _canvas(plate)
    assert np.abs(same[:, : w // 2] - same[:, w // 2:]).max() <= 2
    # joints are found in the left view and dragged there; the right view drags too
    plate.js("stbsViewer.setCompare('lbs')")
    screen = np.array(plate.js("stbsViewer.jointScreenPositions()"))
    half = plate.js("stbsViewer.camera()")          # the left view, on the page
    assert screen[:, 0].max() < half["left"] + half["width"]
    J0 = np.array(plate.js("stbsViewer.posedJoints()"))
    x, y = screen[10]
    _drag(plate, x, y, 20, 15)
    sx, sy = plate.js("stbsViewer.jointScreenPositions()")[10]
    assert np.hypot(sx - (x + 20), sy - (y + 15)) < 1.5
    J1 = np.array(plate.js("stbsViewer.posedJoints()"))
    # the same joint in the right view (one there that the panels do not cover)
    free = plate.js("""h => stbsViewer.jointScreenPositions().then(s => s.map(([x, y]) =>
        document.elementFromPoint(x + h, y)?.id === 'view'))""", half["width"])
    k = max(j for j in range(len(free)) if free[j] and j != 10)
    x, y = plate.js("stbsViewer.jointScreenPositions()")[k]
    _drag(plate, x + half["width"], y, -15, 10)
    J2 = np.array(plate.js("stbsViewer.posedJoints()"))
    moved = np.linalg.norm(J2 - J1, axis=1)
    assert moved[k] > 1e-3 and np.delete(moved, k).max() < 1e-5
    assert np.linalg.norm(J1 - J0, axis=1)[10] > 1e-3
    msg = plate.js("stbsViewer.setCompare('phong').then(() => 'ok', e => e.message)")
    assert msg.startswith("compare: the second method must be one of lbs, dqs, stbs-lbs, "
                          "stbs-dqs or null, got \"phong\"")
    assert plate.js("stbsViewer.setCompare(null)") is None
    plate.js("o => stbsViewer.setPose(o)", {"rotate": {"0": {"angle": 40}, "4": {"angle": 80}},
                                             "stretch": {"3": 2.5, "8": 2.2}})
    assert _differ(_canvas(plate), one) < 0.002
    plate.js("stbsViewer.setPose({})")
    assert plate.errors == []


# --------------------------------------------------------------------------- pose files
def _same_pose(a, b):
    return all(np.allclose(getattr(a, k), getattr(b, k), atol=1e-9)
               for k in ("rotations", "origins", "stretch", "twist"))


def test_save_download_and_load_pose_files(tube):
    sk = tube.rig.skeleton
    folder = tube.srv.pose_folder
    obj = {"rotate": {"3": {"axis": [0, 1, 1], "angle": 35}}, "stretch": {"b6": 1.7},
           "twist": {"10": [0, 200]}}
    tube.js("o => stbsViewer.setPose(o)", obj)
    want = stbs.io.read_pose(obj, sk)
    # save: the name field, the button, a file read_pose loads to the same pose
    tube.page.fill("#pose-name", "bent")
    tube.page.click("#save-pose")
    _wait_status(tube, "saved")
    saved = Path(folder) / "bent.json"
    assert saved.is_file()
    assert _same_pose(stbs.io.read_pose(saved, sk), want)
    # download: the current pose as JSON
    with tube.page.expect_download() as dl:
        tube.page.click("#download-pose")
    assert dl.value.suggested_filename == "bent.json"
    assert _same_pose(stbs.io.read_pose(json.loads(Path(dl.value.path()).read_text()), sk), want)
    # load: a file input, the pose it holds, one undo step
    other = {"joints": (sk.C + [[0, 0.3 * np.sin(k), 0] for k in range(sk.n_joints)]).tolist()}

    def load(name, data):
        tube.js("document.getElementById('status').textContent = ''")
        tube.page.set_input_files("#load-pose", files=[
            {"name": name, "mimeType": "application/json", "buffer": data}])
        _wait_status(tube, "load")
        tube.js("stbsViewer.idle()")
        return tube.js("document.getElementById('status').textContent")

    assert load("wave.json", json.dumps(other).encode()) == "loaded the pose from wave.json"
    assert _same_pose(_pose(tube), stbs.io.read_pose(other, sk))
    assert np.allclose(tube.js("stbsViewer.posedJoints()"), other["joints"], atol=1e-6)
    # bad files: one line in the status line naming the file; the pose stays
    line = load("broken.json", b"{not json")
    assert line.startswith("load pose: broken.json: not valid JSON"), line
    assert tube.js("document.getElementById('status').classList.contains('error')")
    line = load("negative.json", json.dumps({"stretch": {"2": -1}}).encode())
    assert line.startswith("load pose: negative.json:") and "stretch must be > 0" in line, line
    assert _same_pose(_pose(tube), stbs.io.read_pose(other, sk))
    assert [e for e in tube.errors if "status of 400" not in e] == []   # the refused POST
    tube.errors.clear()
    tube.js("stbsViewer.undo()")
    assert _same_pose(_pose(tube), want)
    tube.js("stbsViewer.setPose({})")
    assert tube.errors == []


def test_save_pose_is_off_without_a_pose_folder(plate):
    assert plate.js("document.querySelector('#save-pose').disabled") is True
    msg = plate.js("stbsViewer.savePose('x.json').then(() => 'ok', e => e.message)")
    assert "saving poses is off" in msg
    assert "saving poses is off" in plate.js("document.getElementById('status').textContent")
    plate.errors.clear()          # the refused request is logged by the browser as a 409
