"""The viewer page in a real browser: headless Chromium (SwiftShader WebGL2) via Playwright.

The page skins in its vertex shader; ``stbsViewer.skinnedPositions()`` and
``skinnedNormals()`` read that shader's output back by transform feedback. The
shader must equal the library: ``stbs.deform`` / ``stbs.Deformer`` on the same
top-4 weights (``max_influences=4``), for the four methods, on a 3D and a 2D rig
of 20 bones with stretch and (3D) twists past 720 degrees.

Needs ``playwright`` (the test extra) and Chromium at ``/usr/bin/chromium``
(``make test`` installs both; never ``playwright install``). Under CI a missing one
is a failure (tests/conftest.py turns skips into failures there).
"""

from __future__ import annotations

import io
import os
from pathlib import Path

import numpy as np
import pytest
from viewer_client import grid_mesh

import stbs
from stbs.viewer import STATIC_DIR, ViewerServer

sync_api = pytest.importorskip("playwright.sync_api", reason="playwright is not installed "
                               "(pip install playwright; the test extra has it)")

CHROMIUM = os.environ.get("STBS_CHROMIUM", "/usr/bin/chromium")
ARGS = ["--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--headless=new",
        "--disable-dev-shm-usage"]
READY_S = 60        # the page must be ready within this (it takes about 1 s here)
METHODS = ("lbs", "dqs", "stbs-lbs", "stbs-dqs")
POS_TOL = 1e-4      # of the bounding-box diagonal
NORMAL_TOL = 1e-3


# --------------------------------------------------------------------------- rigs
def _gauss_weights(V, sk, h, keep=6):
    """Smooth bone weights from the distance to each bone, ``keep`` bones per vertex."""
    A, B = sk.A, sk.B
    d = B - A
    t = np.clip(np.einsum("nbk,bk->nb", V[:, None, :] - A[None], d) / np.sum(d * d, 1), 0, 1)
    near = A[None] + t[..., None] * d[None]
    dist2 = np.sum((V[:, None, :] - near) ** 2, axis=2)
    W = np.exp(-dist2 / h ** 2) + 1e-12
    drop = np.argsort(-W, axis=1)[:, keep:]
    np.put_along_axis(W, drop, 0.0, axis=1)
    return W / W.sum(axis=1, keepdims=True)


def _endpoints(V, sk, rng):
    E = stbs.weights.projection(V, sk)
    E = np.asarray(E.toarray() if hasattr(E, "toarray") else E, dtype=np.float64)
    return np.clip(E + 0.05 * rng.standard_normal(E.shape), 0.0, 1.0)


def tube_rig(seed=7) -> stbs.Rig:
    """A 3D tube along x, 20 bones in a chain with jittered joints, 6 influences a vertex."""
    rng = np.random.default_rng(seed)
    rings, seg, r = 61, 16, 0.35
    x = np.linspace(-0.2, 10.2, rings)
    a = 2 * np.pi * np.arange(seg) / seg
    V = np.array([[xi, r * np.cos(t), r * np.sin(t)] for xi in x for t in a])
    F = []
    for i in range(rings - 1):
        for j in range(seg):
            p, q = i * seg + j, i * seg + (j + 1) % seg
            F += [[p, q, q + seg], [p, q + seg, p + seg]]
    C = np.column_stack([np.linspace(0, 10, 21), 0.04 * rng.standard_normal((21, 2))])
    BE = np.column_stack([np.arange(20), np.arange(1, 21)])
    sk = stbs.Skeleton(C, BE, names=[f"b{i}" for i in range(20)])
    return stbs.Rig(V=V, F=np.array(F), skeleton=sk, W=_gauss_weights(V, sk, 0.6),
                    E=_endpoints(V, sk, rng))


def plate_rig(seed=11) -> stbs.Rig:
    """A 2D plate, a 20-bone tree: a 10-bone spine and two 5-bone branches off joint 5."""
    rng = np.random.default_rng(seed)
    xs, ys = np.linspace(-0.3, 5.3, 57), np.linspace(-3.0, 3.0, 61)
    V, F = grid_mesh(xs, ys)
    spine = np.column_stack([np.linspace(0, 5, 11), np.zeros(11)])
    up = np.column_stack([np.full(5, 2.5), np.linspace(0.5, 2.5, 5)])
    down = np.column_stack([np.full(5, 2.5), -np.linspace(0.5, 2.5, 5)])
    C = np.vstack([spine, up, down]) + 0.02 * rng.standard_normal((21, 2))
    BE = [[i, i + 1] for i in range(10)]
    BE += [[5, 11]] + [[11 + k, 12 + k] for k in range(4)]
    BE += [[5, 16]] + [[16 + k, 17 + k] for k in range(4)]
    sk = stbs.Skeleton(C, np.array(BE))
    return stbs.Rig(V=V, F=np.array(F), skeleton=sk, W=_gauss_weights(V, sk, 0.35),
                    E=_endpoints(V, sk, rng))


def poses(rig: stbs.Rig, seed: int) -> list[dict]:
    """Two poses of the rig, one in each form: stretch, rotations past 180 degrees
    along the chain, and in 3D twists up to and past 720 degrees."""
    rng = np.random.default_rng(seed)
    sk = rig.skeleton
    b, d = sk.n_bones, sk.dim
    names = sk.names
    fk = {"rotate": {}, "stretch": {}, "degrees": True}
    for i in range(b):
        key = names[i] if names and i % 2 else str(i)
        angle = float(rng.uniform(15, 40) * rng.choice([-1, 1]))
        if d == 3:
            fk["rotate"][key] = {"axis": rng.standard_normal(3).tolist(), "angle": angle}
        else:
            fk["rotate"][key] = {"angle": angle}
        fk["stretch"][key] = float(rng.uniform(0.6, 1.7))
    if d == 3:
        fk["twist"] = {"0": [-200.0, 150.0]}
        fk["twist"].update({str(i): [0.0, float(rng.uniform(-400, 400))] for i in (3, 13)})
        fk["twist"]["8"] = [0.0, 760.0]
        fk["translate"] = [0.3, -0.2, 0.1]
    joints = sk.C + 0.25 * rng.standard_normal(sk.C.shape)
    jp = {"joints": joints.tolist()}
    if d == 3:
        jp["twist"] = {str(i): [float(rng.uniform(-720, 720)), float(rng.uniform(-800, 800))]
                       for i in range(b)}
        jp["twist"]["5"] = [0.0, 810.0]
    return [fk, jp]


def _area_normals(V, F):
    N = np.zeros_like(V)
    c = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    for k in range(3):
        np.add.at(N, F[:, k], c)
    return N / np.linalg.norm(N, axis=1, keepdims=True)


# --------------------------------------------------------------------------- fixtures
@pytest.fixture(scope="module")
def browser():
    if not Path(CHROMIUM).is_file():
        pytest.skip(f"no Chromium at {CHROMIUM} (apt-get install chromium; make test does)")
    if not (STATIC_DIR / "viewer.js").is_file():
        pytest.skip("the page's bundle is not built (npm ci --prefix viewer && npm run "
                    "--prefix viewer build; make test does)")
    with sync_api.sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=ARGS, headless=True)
        yield b
        b.close()


class Page:
    """The viewer page for one rig, served by a ViewerServer in a thread."""

    def __init__(self, browser, rig, extras=None, clip=None, *, page_options=None,
                 **server):
        """``server``: more ViewerServer options (rig_target, pose_folder, name, ...);
        ``page_options``: more options of the browser page (e.g. accept_downloads)."""
        self.rig = rig
        self.srv = ViewerServer(rig, extras=extras, clip=clip, **server).start()
        self.page_options = dict(page_options or {})
        self.open(browser)

    def open(self, browser):
        """Open (again) a browser page on the server and wait until the viewer is ready."""
        self.errors = []
        self.page = browser.new_page(viewport={"width": 640, "height": 480},
                                     **self.page_options)
        self.page.on("console", lambda m: m.type == "error" and self.errors.append(m.text))
        self.page.on("pageerror", lambda e: self.errors.append(str(e)))
        self.page.goto(self.srv.url)
        self.page.wait_for_function("window.stbsViewer !== undefined", timeout=READY_S * 1000)
        self.info = self.page.evaluate(
            """s => Promise.race([stbsViewer.ready, new Promise((_, no) => setTimeout(
                   () => no(new Error(`not ready after ${s} s`)), s * 1000))])""", READY_S)

    def js(self, expr, arg=None):
        return self.page.evaluate(expr, arg)

    def positions(self):
        return np.array(self.js("stbsViewer.skinnedPositions().then(a => Array.from(a))"),
                        dtype=np.float64).reshape(-1, 3)

    def normals(self):
        return np.array(self.js("stbsViewer.skinnedNormals().then(a => Array.from(a))"),
                        dtype=np.float64).reshape(-1, 3)

    def close(self):
        self.page.close()
        self.srv.shutdown()


@pytest.fixture(scope="module")
def tube(browser):
    p = Page(browser, tube_rig())
    yield p
    p.close()


@pytest.fixture(scope="module")
def plate(browser):
    p = Page(browser, plate_rig())
    yield p
    p.close()


# --------------------------------------------------------------------------- tests
def test_the_page_loads_compiles_and_reports_the_rig(tube, plate):
    for p, dim in ((tube, 3), (plate, 2)):
        assert p.info["vertices"] == len(p.rig.V)
        assert p.info["bones"] == 20
        assert p.info["dim"] == dim
        assert p.info["methods"] == list(METHODS)
        assert p.info["method"] == "stbs-dqs"
        assert p.info["shaders"] == {"mesh": True, "feedback": True}
        assert p.js("document.body.dataset.ready") == "true"
        assert p.js("stbsViewer.info()")["vertices"] == len(p.rig.V)
        assert p.errors == []


def test_rest_pose_reproduces_the_mesh(tube, plate):
    for p in (tube, plate):
        p.js("stbsViewer.setPose({})")
        V = np.asarray(p.rig.V, dtype=np.float64)
        V3 = np.hstack([V, np.zeros((len(V), 3 - V.shape[1]))])
        for m in METHODS:
            p.js("n => stbsViewer.setMethod(n)", m)
            assert np.abs(p.positions() - V3).max() < 1e-5
    N = tube.normals()
    assert np.abs(N - _area_normals(np.asarray(tube.rig.V), np.asarray(tube.rig.F))).max() < 1e-5
    assert tube.errors == [] and plate.errors == []


@pytest.mark.parametrize("which", ["tube", "plate"])
def test_the_shader_equals_the_library(which, request):
    p = request.getfixturevalue(which)
    rig, sk = p.rig, p.rig.skeleton
    V = np.asarray(rig.V, dtype=np.float64)
    d = V.shape[1]
    diag = float(np.linalg.norm(V.max(0) - V.min(0)))
    N0 = np.array(p.js("stbsViewer.restNormals().then(a => Array.from(a))")).reshape(-1, 3)
    worst = {}
    for k, obj in enumerate(poses(rig, seed=3 if d == 3 else 5)):
        back = p.js("o => stbsViewer.setPose(o)", obj)
        assert p.js("stbsViewer.getPose()") == back
        pose = stbs.io.read_pose(obj, sk)
        assert np.allclose(pose.rotations, p.srv.pose.rotations)
        if d == 3:
            assert np.abs(pose.twist).max() > np.deg2rad(750)
        for m in METHODS:
            assert p.js("n => stbsViewer.setMethod(n)", m) == m
            assert p.js("stbsViewer.info()")["method"] == m
            U = p.positions()
            ref = stbs.deform(V, sk, pose, rig.W, rig.E, method=m, max_influences=4)
            err = np.abs(U[:, :d] - ref).max() / diag
            worst[(k, m, "pos")] = err
            assert err < POS_TOL, (k, m, err)
            if d == 2:
                assert np.all(U[:, 2] == 0)
                continue
            dfm = stbs.Deformer(V, sk, rig.W, rig.E, method=m, max_influences=4,
                                normals=N0)
            ref_u, ref_n = dfm.deform_with_normals(pose)
            assert np.abs(ref_u - ref).max() < 1e-9 * diag
            N = p.normals()
            nerr = np.abs(N - ref_n).max()
            worst[(k, m, "normal")] = nerr
            assert nerr < NORMAL_TOL, (k, m, nerr)
    print(which, {f"{k}": f"{v:.2e}" for k, v in worst.items()})
    assert p.errors == []


def test_switching_methods_changes_the_picture(tube, plate, tmp_path):
    from PIL import Image

    for p, name in ((tube, "tube"), (plate, "plate")):
        p.js("o => stbsViewer.setPose(o)", poses(p.rig, seed=3)[0])
        shots = {}
        for m in ("lbs", "stbs-dqs"):
            p.js("n => stbsViewer.setMethod(n)", m)
            path = tmp_path / f"{name}-{m}.png"
            p.page.screenshot(path=str(path))
            shots[m] = np.asarray(Image.open(io.BytesIO(path.read_bytes())).convert("RGB"),
                                  dtype=np.int16)
        diff = np.abs(shots["lbs"] - shots["stbs-dqs"]).max(axis=2) > 24
        assert diff.mean() > 0.002, diff.mean()
        # lit and shaded (3D): the mesh shows many distinct tones, not a flat fill
        img = shots["stbs-dqs"]
        assert len(np.unique(img.reshape(-1, 3), axis=0)) > (200 if name == "tube" else 20)
    print("screenshots in", tmp_path)
    assert tube.errors == [] and plate.errors == []


def test_degrees_false_and_names_give_the_same_pose(tube):
    deg = {"rotate": {"b3": {"axis": [0, 1, 0], "angle": 90}}, "twist": {"b3": [0, 720]}}
    rad = {"rotate": {"3": {"axis": [0, 1, 0], "angle": np.pi / 2}},
           "twist": {"3": [0, 4 * np.pi]}, "degrees": False}
    tube.js("o => stbsViewer.setPose(o)", deg)
    U = tube.positions()
    tube.js("o => stbsViewer.setPose(o)", rad)
    assert np.abs(tube.positions() - U).max() < 1e-6
    assert tube.errors == []


def test_a_2d_picture_is_drawn_with_its_texture(browser, tmp_path):
    from PIL import Image

    rig = plate_rig()
    V = np.asarray(rig.V)
    UV = ((V - V.min(0)) / np.ptp(V, axis=0)).astype(np.float32)
    tex = np.zeros((64, 64, 4), dtype=np.uint8)
    tex[..., 3] = 255
    tex[:32, :, 0] = 255        # top half red (row 0 at the top)
    tex[32:, :, 2] = 255        # bottom half blue
    p = Page(browser, rig, extras={"UV": UV, "texture": tex})
    try:
        path = tmp_path / "picture.png"
        p.page.screenshot(path=str(path))
        img = np.asarray(Image.open(path).convert("RGB"), dtype=np.int16)
        red = (img[..., 0] > 200) & (img[..., 1] < 60) & (img[..., 2] < 60)
        blue = (img[..., 2] > 200) & (img[..., 0] < 60) & (img[..., 1] < 60)
        assert red.sum() > 5000 and blue.sum() > 5000
        rows = np.nonzero(red.any(axis=1))[0], np.nonzero(blue.any(axis=1))[0]
        assert rows[0].mean() < rows[1].mean()      # red above blue: the picture upright
        assert p.errors == []
    finally:
        p.close()


def test_time_frames_and_a_bad_pose(tube):
    ms = tube.js("stbsViewer.timeFrames(10)")
    assert isinstance(ms, (int, float)) and 0 < ms < 5000
    msg = tube.js("stbsViewer.setPose({'stretch': {'0': -1}}).then(() => 'ok', e => e.message)")
    assert "stretch" in msg
    with pytest.raises(sync_api.Error, match="method must be one of"):
        tube.js("stbsViewer.setMethod('nope')")
    # the bad pose was a console-free rejection; the page keeps working
    tube.errors.clear()
    tube.js("stbsViewer.setMethod('stbs-dqs')")
    assert tube.errors == []
