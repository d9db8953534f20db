"""The page's timeline in a real browser: keys, seek, playback, saving and GIF export.

One page load on a small 3D bar (two bones, 74 vertices); three keys. ``seek(t)``
between keys must draw exactly ``stbs.Clip.pose(t)`` (the shader's output equals
``stbs.deform`` on that pose) and make it the server's current pose.
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest
from test_viewer_page import READY_S, browser  # noqa: F401  (the module's browser fixture)
from viewer_client import bar_rig

import stbs
from stbs.viewer import ViewerServer

POS_TOL = 1e-4      # of the bounding-box diagonal
SCREENS = Path(__file__).resolve().parents[2] / "build" / "screens"
FPS = 8
KEYS = [
    (0.0, {}),
    (0.5, {"rotate": {"upper": {"axis": [0, 0, 1], "angle": 60}}, "stretch": {"lower": 1.5},
           "twist": {"lower": [0, 200]}}),
    (1.25, {"rotate": {"upper": {"axis": [0, 1, 1], "angle": -40},
                       "lower": {"axis": [0, 0, 1], "angle": 70}},
            "stretch": {"upper": 0.8}, "twist": {"lower": [0, -400]}}),
]


class TimelinePage:
    def __init__(self, chromium, folder):
        self.rig = bar_rig()
        self.srv = ViewerServer(self.rig, pose_folder=folder, name="bar").start()
        self.errors = []
        self.page = chromium.new_page(viewport={"width": 640, "height": 480})
        self.page.on("console", lambda m: m.type == "error" and self.errors.append(m.text))
        self.page.on("pageerror", lambda e: self.errors.append(str(e)))
        self.page.goto(self.srv.url)
        self.page.wait_for_function("window.stbsViewer !== undefined", timeout=READY_S * 1000)
        self.js("stbsViewer.ready")

    def js(self, expr, arg=None):
        return self.page.evaluate(expr, arg)

    def positions(self):
        return np.array(self.js("stbsViewer.skinnedPositions().then(a => Array.from(a))"),
                        dtype=np.float64).reshape(-1, 3)

    def close(self):
        self.page.close()
        self.srv.shutdown()


@pytest.fixture(scope="module")
def tl(browser, tmp_path_factory):  # noqa: F811
    p = TimelinePage(browser, tmp_path_factory.mktemp("clips"))
    for t, pose in KEYS:
        p.js("o => stbsViewer.setPose(o)", pose)
        p.js("t => stbsViewer.addKey(t)", t)
    p.js("f => stbsViewer.setFps(f)", FPS)
    yield p
    p.close()


def _clip(tl):
    return stbs.io.read_clip(tl.js("stbsViewer.getClip()"), tl.rig.skeleton)


def test_three_keys_from_the_current_pose(tl):
    keys = tl.js("stbsViewer.keys()")
    assert [k["time"] for k in keys] == [t for t, _ in KEYS]
    sk = tl.rig.skeleton
    for (_, pose), key in zip(KEYS, keys, strict=True):
        want, got = stbs.io.read_pose(pose, sk), stbs.io.read_pose(key["pose"], sk)
        assert np.abs(want.rotations - got.rotations).max() < 1e-9
        assert np.abs(want.twist - got.twist).max() < 1e-9
    clip = tl.js("stbsViewer.getClip()")
    assert clip["fps"] == FPS and clip["interpolation"] == "linear"
    assert tl.errors == []


@pytest.mark.parametrize("t", [0.3, 0.9, 1.1])     # between keys, off the 8 fps grid
def test_seek_shows_the_clips_pose_and_makes_it_current(tl, t):
    out = tl.js("t => stbsViewer.seek(t)", t)
    assert out["time"] == t
    rig, sk = tl.rig, tl.rig.skeleton
    pose = _clip(tl).pose(t)
    V = np.asarray(rig.V, dtype=np.float64)
    diag = float(np.linalg.norm(V.max(0) - V.min(0)))
    ref = stbs.deform(V, sk, pose, rig.W, rig.E, method="stbs-dqs", max_influences=4)
    moved = np.abs(ref - V).max() / diag
    assert moved > 0.05                         # a pose far from rest: the check means something
    err = np.abs(tl.positions() - ref).max() / diag
    assert err < POS_TOL, err
    assert np.abs(tl.srv.pose.rotations - pose.rotations).max() < 1e-12
    assert np.abs(tl.srv.pose.twist - pose.twist).max() < 1e-12
    assert tl.js("stbsViewer.clipState()")["time"] == t
    assert tl.errors == []


def _shot(tl, name):
    SCREENS.mkdir(parents=True, exist_ok=True)
    data = tl.page.locator("#view").screenshot(path=str(SCREENS / name))
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(data)).convert("RGB"), dtype=np.int16)


def test_play_moves_the_picture_and_pause_keeps_the_pose(tl):
    tl.js("stbsViewer.seek(0)")
    state = tl.js("stbsViewer.play()")
    assert state["playing"] is True
    # a screenshot here takes a variable 0.3 .. 1 s, so two of them can land on the same
    # frame of the looping 1.375 s clip: the picture must change within four of them
    a = _shot(tl, "timeline-play-a.png")
    for k in range(4):
        tl.page.wait_for_timeout(150)
        b = _shot(tl, f"timeline-play-{k}.png")
        if np.abs(a - b).max() > 60 and (np.abs(a - b).sum(axis=2) > 60).mean() > 0.002:
            break
    else:
        pytest.fail("the picture did not change while the clip played")
    t_mid = tl.js("stbsViewer.clipState()")["time"]
    state = tl.js("stbsViewer.pause()")
    assert state["playing"] is False
    assert state["time"] == t_mid or tl.js("stbsViewer.clipState()")["loop"]
    # what is shown after the pause is the server's current pose, on the fps grid
    assert abs(state["time"] * FPS - round(state["time"] * FPS)) < 1e-9
    pose = _clip(tl).pose(state["time"])
    assert np.abs(tl.srv.pose.origins - pose.origins).max() < 1e-12
    assert tl.errors == []


def test_save_clip_writes_what_read_clip_loads(tl):
    out = tl.js("stbsViewer.saveClip('walk.json')")
    path = tl.srv.pose_folder / "walk.json"
    assert out["path"] == str(path) and out["keys"] == 3
    back = stbs.io.read_clip(path, tl.rig.skeleton)
    ref = _clip(tl)
    assert back.times.tolist() == [t for t, _ in KEYS] and back.fps == FPS
    for (_, a), (_, b) in zip(ref.keys, back.keys, strict=True):
        assert np.abs(a.rotations - b.rotations).max() < 1e-12
        assert np.abs(a.origins - b.origins).max() < 1e-12
        assert np.abs(a.stretch - b.stretch).max() < 1e-12
        assert np.abs(a.twist - b.twist).max() < 1e-12


def test_export_writes_a_gif_of_every_sampled_frame(tl):
    from PIL import Image

    before = tl.js("stbsViewer.camera()")
    out = tl.js("stbsViewer.exportClip({name: 'walk.gif', format: 'gif', width: 160})")
    assert tl.js("stbsViewer.camera()") == before        # the user's view is given back
    n = len(_clip(tl).sample_times())
    assert n == 11                              # 0 .. 1.25 s at 8 fps
    path = tl.srv.pose_folder / "walk.gif"
    assert out["path"] == str(path) and out["frames"] == n and out["width"] == 160
    frames = []
    with Image.open(path) as im:
        # the canvas's aspect (the area the panels leave), 160 pixels wide
        height = round(before["height"] * 160 / before["width"])
        assert im.format == "GIF" and im.n_frames == n and im.size[0] == 160
        assert abs(im.size[1] - height) <= 1, (im.size, height)
        for k in range(n):
            im.seek(k)
            frames.append(np.asarray(im.convert("RGB"), dtype=np.int16))
    Image.fromarray(frames[n // 2].astype(np.uint8)).save(SCREENS / "timeline-export-mid.png")
    diffs = [np.abs(frames[k + 1] - frames[k]).max() for k in range(n - 1)]
    assert min(diffs) > 0, diffs                # every frame differs from the one before
    assert np.abs(frames[0] - frames[n // 2]).max() > 60
    # the whole clip is framed: the mesh never touches the picture's border, which stays
    # the page's background colour (0x20232a), and all frames together span a good part
    # of the picture (the bounding sphere of the clip fits the view)
    bg = np.array([0x20, 0x23, 0x2A])
    for f in frames:
        border = np.concatenate([f[0], f[-1], f[:, 0], f[:, -1]])
        assert np.abs(border - bg).max() <= 12
    ys, xs = np.nonzero(np.any([np.abs(f - bg).max(axis=2) > 30 for f in frames], axis=0))
    span = max((xs.max() - xs.min()) / 160, (ys.max() - ys.min()) / im.size[1])
    assert span > 0.5, span
    assert tl.errors == []


def test_bad_calls_reject_with_a_clear_message(tl):
    msg = tl.js("""async () => { try { await stbsViewer.setClip({keys: [{time: 0,
                   pose: {stretch: {lower: -1}}}]}); return null; } catch (e) {
                   return e.message; } }""")
    assert msg is not None and "keys[0].pose" in msg and "stretch must be > 0" in msg
    # the clip is unchanged by the refused one
    assert len(tl.js("stbsViewer.keys()")) == 3
    msg = tl.js("""async () => { try { await stbsViewer.seek('soon'); return null; }
                   catch (e) { return e.message; } }""")
    assert msg == 't must be a finite number of seconds, got "soon"'
    # the refused setClip shows as the browser's own note of a 400 answer, nothing else
    assert all("status of 400" in e for e in tl.errors), tl.errors
    tl.errors.clear()


def test_the_bar_loads_keys_interpolates_by_steps_adds_and_deletes(tl):
    path = tl.srv.pose_folder / "walk.json"          # saved by the test above
    tl.js("stbsViewer.clearKeys()")
    assert tl.js("stbsViewer.keys()") == []
    tl.page.set_input_files("#tl-load", str(path))
    tl.page.wait_for_function("() => stbsViewer.keys().length === 3", timeout=10_000)
    assert [k["time"] for k in tl.js("stbsViewer.keys()")] == [t for t, _ in KEYS]
    tl.page.select_option("#tl-interp", "step")
    assert tl.js("stbsViewer.getClip()")["interpolation"] == "step"
    tl.js("stbsViewer.seek(0.9)")
    held = stbs.io.read_pose(KEYS[1][1], tl.rig.skeleton)          # step: key 0.5 held
    assert np.abs(tl.srv.pose.rotations - held.rotations).max() < 1e-9
    assert np.abs(tl.srv.pose.stretch - held.stretch).max() < 1e-12
    assert tl.page.locator("#tl-count").text_content() == "3 keys"
    tl.page.click("#tl-add")                         # keys the current pose at 0.9 s
    tl.page.wait_for_function("() => stbsViewer.keys().length === 4", timeout=10_000)
    assert [k["time"] for k in tl.js("stbsViewer.keys()")] == [0.0, 0.5, 0.9, 1.25]
    assert tl.page.locator(".tl-mark").count() == 4
    tl.page.click("#tl-delete")                      # the key nearest 0.9 s
    assert [k["time"] for k in tl.js("stbsViewer.keys()")] == [0.0, 0.5, 1.25]
    assert tl.errors == []
