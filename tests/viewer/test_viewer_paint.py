"""Weights on the viewer page in a real browser (headless Chromium, Playwright): colour
modes, painting bone and endpoint weights with the mouse, undo and redo of strokes,
saving the painted rig, recomputing one bone's endpoint weights on the server, and
the endpoint filter curve (the same curve as stbs.weights.SplineFilter).
Rigs and the page helper: test_viewer_page.py."""

from __future__ import annotations

import base64
import contextlib
import io

import numpy as np
import pytest
from test_viewer_page import READY_S, Page, browser, plate_rig, tube_rig  # noqa: F401

import stbs
from stbs.weights import SplineFilter

POS_TOL = 1e-4          # of the bounding-box diagonal


def SavingPage(browser, rig, target):  # noqa: N802, F811
    """Page, with the server saving the rig to ``target``."""
    return Page(browser, rig, rig_target=target)


@pytest.fixture(scope="module")
def plate(browser, tmp_path_factory):  # noqa: F811
    p = SavingPage(browser, plate_rig(), tmp_path_factory.mktemp("paint") / "rig.npz")
    yield p
    p.close()


@pytest.fixture(scope="module")
def tube(browser):  # noqa: F811
    p = Page(browser, tube_rig())
    yield p
    p.close()


# --------------------------------------------------------------------------- helpers
B64 = """a => { const u = new Uint8Array(a.buffer, a.byteOffset, a.byteLength); let s = "";
  for (let i = 0; i < u.length; i += 32768) {
    s += String.fromCharCode.apply(null, u.subarray(i, i + 32768));
  }
  return btoa(s); }"""


def _weights(p):
    """The page's W and E, bit for bit (base64 of the Float32Arrays' bytes)."""
    n, b = p.info["vertices"], p.info["bones"]
    got = p.js(f"stbsViewer.weights().then(o => {{ const f = {B64}; return [f(o.W), f(o.E)]; }})")
    return tuple(np.frombuffer(base64.b64decode(g), dtype="<f4").reshape(n, b) for g in got)


def _shot(p):
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(p.page.screenshot())).convert("RGB"), dtype=np.int16)


def _matrices(cam):
    view = np.array(cam["view"]).reshape(4, 4).T           # three.js: column-major
    proj = np.array(cam["projection"]).reshape(4, 4).T
    return proj @ view


def _screen(cam, P):
    """World points (m, 3) -> page pixels (m, 2)."""
    X = np.hstack([P, np.ones((len(P), 1))]) @ _matrices(cam).T
    ndc = X[:, :2] / X[:, 3:]
    return np.column_stack([cam["left"] + 0.5 * (ndc[:, 0] + 1) * cam["width"],
                            cam["top"] + 0.5 * (1 - ndc[:, 1]) * cam["height"]])


def _raycast(cam, U, F, x, y):
    """The nearest hit of the pixel's ray with the triangles (U, F): (face, u, v) or None."""
    inv = np.linalg.inv(_matrices(cam))
    nx = 2 * (x - cam["left"]) / cam["width"] - 1
    ny = 1 - 2 * (y - cam["top"]) / cam["height"]
    a, b = inv @ [nx, ny, -1, 1], inv @ [nx, ny, 1, 1]
    o, d = a[:3] / a[3], b[:3] / b[3]
    d = d - o
    P0, e1, e2 = U[F[:, 0]], U[F[:, 1]] - U[F[:, 0]], U[F[:, 2]] - U[F[:, 0]]
    pv = np.cross(d, e2)
    det = np.einsum("ij,ij->i", e1, pv)
    ok = np.abs(det) > 1e-20
    s = o - P0
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.einsum("ij,ij->i", s, pv) / det
        q = np.cross(s, e1)
        v = (q @ d) / det
        t = np.einsum("ij,ij->i", e2, q) / det
    hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
    if not hit.any():
        return None
    f = int(np.flatnonzero(hit)[np.argmin(t[hit])])
    return f, u[f], v[f]


def _stroke(p, pts):
    m = p.page.mouse
    m.move(*pts[0])
    m.down()
    for b in pts[1:]:
        m.move(*b, steps=4)
    m.up()
    return p.js("stbsViewer.lastStroke()")


def _deform(p, pose_obj, W, E, method):
    """The library's positions with the page's weights W, E (float32).

    The page's layout of a vertex whose W is as loaded is the server's, made from the
    rig's float64 W (near-ties among the four heaviest bones can fall either way in
    float32): those rows take the rig's own W.
    """
    rig = p.rig
    W0 = np.asarray(rig.W.toarray() if hasattr(rig.W, "toarray") else rig.W, dtype=np.float64)
    same = (W == W0.astype(np.float32)).all(axis=1)
    W = np.where(same[:, None], W0, W.astype(np.float64))
    W /= W.sum(axis=1, keepdims=True)
    pose = stbs.io.read_pose(pose_obj, rig.skeleton)
    return stbs.deform(np.asarray(rig.V, float), rig.skeleton, pose, W, E.astype(np.float64),
                       method=method, max_influences=4)


def _diag(rig):
    V = np.asarray(rig.V)
    return float(np.linalg.norm(V.max(0) - V.min(0)))


def _check_region(before, after, col, dabs, radius, V):
    """Only column ``col`` of the vertices within ``radius`` (rest space) of a dab changed."""
    changed = np.flatnonzero((after != before).any(axis=1))
    assert changed.size > 0
    D = np.array([d["rest"] for d in dabs])[:, :V.shape[1]]
    dist = np.linalg.norm(V[changed, None, :] - D[None], axis=2).min(axis=1)
    assert dist.max() < radius * (1 + 1e-6), dist.max()
    return changed


@contextlib.contextmanager
def _spy(srv):
    """The request bodies of the endpoint recomputes (POST /api/jobs/endpoint) while in
    the block."""
    import stbs.viewer.jobs as jobs

    calls, real = [], jobs.read_endpoint_request

    def spy(obj, rig, *, nested):
        calls.append(obj)
        return real(obj, rig, nested=nested)

    jobs.read_endpoint_request = spy
    try:
        yield calls
    finally:
        jobs.read_endpoint_request = real


def _no_errors(p):
    """No errors but the browser's own line for the 400 a test asked for."""
    assert all("status of 400" in e for e in p.errors), p.errors


# --------------------------------------------------------------------------- colour modes
def test_colour_modes_change_the_picture_and_endpoint_is_grey_where_w_is_0(plate):
    p = plate
    assert p.js("stbsViewer.colorMode()") == "shaded"
    p.js("stbsViewer.setPose({})")
    bone = 3
    p.js("b => stbsViewer.setPaint({bone: b})", bone)
    shots = {}
    for mode in ("shaded", "bones", "endpoint"):
        assert p.js("m => stbsViewer.setColorMode(m)", mode) == mode
        assert p.js("stbsViewer.colorMode()") == mode
        assert p.js("document.getElementById('color-mode').value") == mode
        p.page.screenshot(path=f"build/screens/paint-colour-{mode}.png")
        shots[mode] = _shot(p)
    for a, b in (("shaded", "bones"), ("bones", "endpoint"), ("shaded", "endpoint")):
        diff = np.abs(shots[a] - shots[b]).max(axis=2) > 24
        assert diff.mean() > 0.05, (a, b, diff.mean())
    # endpoint mode: grey where the bone's weight is 0 (with all the vertex's neighbours),
    # coloured where it is large (the 2D plate is drawn unlit: the colours as they are)
    W, E = _weights(p)
    V = np.asarray(p.rig.V)
    F = np.asarray(p.rig.F)
    zero = np.ones(len(V), bool)
    for k in range(3):
        for m in range(3):
            zero[F[:, k]] &= W[F[:, m], bone] == 0
    lo, hi = V.min(axis=0), V.max(axis=0)
    inner = ((V > lo) & (V < hi)).all(axis=1)      # the plate's rim blends with the background
    zero &= inner
    heavy = (W[:, bone] > 0.5 * W[:, bone].max()) & inner
    cam = p.js("stbsViewer.camera()")
    J = np.array(p.js("stbsViewer.jointScreenPositions()"))
    BE = np.asarray(p.rig.skeleton.BE)

    def off_skeleton(x, y):       # farther than 5 px from every drawn bone, and off the
        a, b = J[BE[:, 0]], J[BE[:, 1]]     # selected bone's ring (11 px round its start)
        t = np.clip(np.einsum("ij,ij->i", [x, y] - a, b - a) / np.sum((b - a) ** 2, 1), 0, 1)
        if np.linalg.norm(J[BE[bone, 0]] - [x, y]) < 14:
            return False
        return np.linalg.norm(a + t[:, None] * (b - a) - [x, y], axis=1).min() > 5

    img = shots["endpoint"]
    on_canvas = "([x, y]) => document.elementFromPoint(x, y) === document.getElementById('view')"
    checked = {"zero": 0, "heavy": 0}
    for kind, mask in (("zero", zero), ("heavy", heavy)):
        idx = np.flatnonzero(mask)
        for i in idx[np.linspace(0, len(idx) - 1, 40).astype(int)]:
            x, y = _screen(cam, np.r_[V[i], 0][None])[0]
            if not (off_skeleton(x, y) and p.js(on_canvas, [float(x), float(y)])):
                continue
            r, g, b = img[int(round(y)), int(round(x))]
            if kind == "zero":
                assert abs(r - 128) <= 3 and abs(g - 128) <= 3 and abs(b - 128) <= 3, (i, r, g, b)
            else:
                assert max(r, g, b) - min(r, g, b) > 60, (i, r, g, b)
            checked[kind] += 1
    assert checked["zero"] >= 10 and checked["heavy"] >= 5, checked
    with pytest.raises(Exception, match="colour mode: expected one of shaded, bones, endpoint"):
        p.js("stbsViewer.setColorMode('weights')")
    # side by side, both views show the colours
    p.js("stbsViewer.setCompare('lbs')")
    try:
        pair = {}
        for mode in ("shaded", "endpoint"):
            p.js("m => stbsViewer.setColorMode(m)", mode)
            pair[mode] = _shot(p)
        diff = np.abs(pair["shaded"] - pair["endpoint"]).max(axis=2) > 24
        half = diff.shape[1] // 2
        assert diff[:, :half].mean() > 0.05 and diff[:, half:].mean() > 0.05
    finally:
        p.js("stbsViewer.setCompare(null)")
    # the menus do the same
    p.page.select_option("#color-mode", "bones")
    assert p.js("stbsViewer.colorMode()") == "bones"
    p.js("document.getElementById('weights-panel').open = true")
    for sel, value, key in (("#paint-mode", "endpoint", "mode"), ("#paint-op", "smooth", "op"),
                            ("#paint-falloff", "linear", "falloff")):
        p.page.select_option(sel, value)
        assert p.js("stbsViewer.paint()")[key] == value
    p.page.fill("#paint-strength", "0.7")
    assert p.js("stbsViewer.paint()")["strength"] == 0.7
    p.page.select_option("#bone", "5")
    assert p.js("stbsViewer.paint()")["bone"] == 5
    p.js("stbsViewer.setPaint({mode: 'off', op: 'add', falloff: 'smooth', strength: 0.25})")
    p.js("document.getElementById('weights-panel').open = false")
    p.js("stbsViewer.setColorMode('shaded')")
    assert p.errors == []


# --------------------------------------------------------------------------- painting
def test_a_stroke_on_the_posed_tube_paints_w_inside_the_brush_only(tube):
    p = tube
    rig = p.rig
    pose_obj = {"rotate": {"8": {"axis": [0, 0, 1], "angle": 35},
                           "12": {"axis": [0, 1, 0], "angle": -30}}, "stretch": {"10": 1.3}}
    p.js("o => stbsViewer.setPose(o)", pose_obj)
    p.js("stbsViewer.setMethod('stbs-lbs')")
    p.js("stbsViewer.frame()")
    W0, E0 = _weights(p)
    U0 = p.positions()
    cam = p.js("stbsViewer.camera()")
    V = np.asarray(rig.V, dtype=np.float64)
    F = np.asarray(rig.F)
    radius, bone = 0.6, 10
    p.js("o => stbsViewer.setPaint(o)", {"mode": "bone", "bone": bone, "op": "add",
                                         "radius": radius, "strength": 0.3, "falloff": "linear"})
    # a stroke along the posed tube over bone 10 (x 5 to 5.5 at rest): through the
    # screen centres of its posed rings of vertices
    pts = [tuple(_screen(cam, U0[np.abs(V[:, 0] - x0) < 0.1]).mean(axis=0))
           for x0 in (4.9, 5.25, 5.6)]
    first = _raycast(cam, U0, F, *pts[0])
    assert first is not None, "the stroke must start on the mesh"
    st = _stroke(p, [(float(x), float(y)) for x, y in pts])
    assert st["mode"] == "bone" and st["bone"] == bone and len(st["dabs"]) >= 3
    # the first dab lands where the cursor is on the posed surface (an independent raycast)
    f, u, v = first
    tri = F[f]
    want_posed = (1 - u - v) * U0[tri[0]] + u * U0[tri[1]] + v * U0[tri[2]]
    want_rest = (1 - u - v) * V[tri[0]] + u * V[tri[1]] + v * V[tri[2]]
    assert np.abs(np.array(st["dabs"][0]["posed"]) - want_posed).max() < 1e-4 * _diag(rig)
    assert np.abs(np.array(st["dabs"][0]["rest"]) - want_rest).max() < 1e-4 * _diag(rig)
    for d in st["dabs"]:
        assert np.abs(_screen(cam, np.array([d["posed"]])) - [d["x"], d["y"]]).max() < 0.5
    W1, E1 = _weights(p)
    changed = _check_region(W0, W1, bone, st["dabs"], radius, V)
    assert np.all(W1[changed, bone] > W0[changed, bone])          # "add" raised it
    assert np.abs(W1.astype(np.float64).sum(axis=1) - 1).max() < 2e-6
    assert W1.min() >= 0 and np.array_equal(E1, E0)
    assert st["vertices"] == len(changed)
    # the deformation follows: the shader's positions equal the library's with these weights
    U1 = p.positions()
    diag = _diag(rig)
    assert np.abs(U1 - U0).max() > 1e-3 * diag
    ref = _deform(p, pose_obj, W1, E1, "stbs-lbs")
    assert np.abs(U1 - ref).max() < POS_TOL * diag
    # undo and redo restore W and E exactly, and the drawing with them
    assert p.js("stbsViewer.canPaintUndo()")
    assert p.js("stbsViewer.paintUndo()") is True
    W2, E2 = _weights(p)
    assert np.array_equal(W2, W0) and np.array_equal(E2, E0)
    assert np.abs(p.positions() - U0).max() < 1e-6 * diag
    assert p.js("stbsViewer.paintRedo()") is True
    W3, E3 = _weights(p)
    assert np.array_equal(W3, W1) and np.array_equal(E3, E1)
    assert np.abs(p.positions() - U1).max() < 1e-6 * diag
    # Ctrl-Z / Ctrl-Shift-Z go to painting while it is on, not to the pose's undo
    pose_before = p.js("stbsViewer.getPose()")
    p.page.keyboard.press("Control+z")
    assert np.array_equal(_weights(p)[0], W0)
    p.page.keyboard.press("Control+Shift+z")
    assert np.array_equal(_weights(p)[0], W1)
    assert p.js("stbsViewer.idle().then(() => stbsViewer.getPose())") == pose_before
    # recomputing endpoint weights now sends the painted W (the server's is the rig's)
    with _spy(p.srv) as calls:
        p.js("b => stbsViewer.recomputeEndpoint(b, 'projection')", bone)
    assert np.array_equal(np.array(calls[0]["W"], dtype=np.float32), W1)
    for _ in range(2):
        assert p.js("stbsViewer.paintUndo()") is True
    assert np.array_equal(_weights(p)[0], W0) and np.array_equal(_weights(p)[1], E0)
    p.js("stbsViewer.setPaint({mode: 'off'})")
    assert p.errors == []


def test_endpoint_painting_and_smoothing_keep_e_in_0_1_and_w_unchanged(tube):
    p = tube
    p.js("stbsViewer.setPose({})")
    p.js("stbsViewer.frame()")
    W0, E0 = _weights(p)
    V = np.asarray(p.rig.V, dtype=np.float64)
    cam = p.js("stbsViewer.camera()")
    pts = [tuple(float(c) for c in _screen(cam, V[np.abs(V[:, 0] - x0) < 0.1]).mean(axis=0))
           for x0 in (2.4, 2.8)]
    radius, bone = 0.5, 5
    p.page.mouse.move(*pts[0])
    p.js("stbsViewer.setColorMode('endpoint')")
    p.js("b => stbsViewer.setPaint({bone: b})", bone)
    plain = _shot(p)
    p.js("o => stbsViewer.setPaint(o)", {"mode": "endpoint", "bone": bone, "op": "subtract",
                                         "radius": radius, "strength": 1.0,
                                         "falloff": "constant"})
    # the brush's ring follows the pointer over the mesh, only near it
    p.page.mouse.move(pts[0][0] + 1, pts[0][1])
    p.js("new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))")
    p.page.screenshot(path="build/screens/paint-tube-endpoint-brush.png")
    ring = np.argwhere(np.abs(_shot(p) - plain).max(axis=2) > 40)
    assert len(ring) > 20
    r_px = np.abs(_screen(cam, np.array([V[np.abs(V[:, 0] - 2.4) < 0.1].mean(axis=0)]))
                  - _screen(cam, np.array([V[np.abs(V[:, 0] - 2.4 - radius) < 0.1].mean(axis=0)])))
    assert np.abs(ring[:, ::-1] - pts[0]).max() < 1.5 * np.linalg.norm(r_px) + 4
    st = _stroke(p, pts)
    W1, E1 = _weights(p)
    changed = _check_region(E0, E1, bone, st["dabs"], radius, V)
    assert np.array_equal(W1, W0)
    assert np.all(E1[changed, bone] == 0)              # constant falloff, full strength
    assert np.array_equal(np.delete(E1, bone, axis=1), np.delete(E0, bone, axis=1))
    # smoothing: towards the neighbours' mean, staying in [0, 1]
    p.js("stbsViewer.setPaint({op: 'smooth', strength: 0.5, falloff: 'smooth'})")
    st = _stroke(p, pts)
    W2, E2 = _weights(p)
    changed = _check_region(E1, E2, bone, st["dabs"], radius, V)
    assert E2.min() >= 0 and E2.max() <= 1 and np.array_equal(W2, W0)
    assert np.all(E2[changed, bone] >= E1[changed, bone])      # the hole fills from its rim
    assert p.js("stbsViewer.paintUndo()") is True
    assert np.array_equal(_weights(p)[1], E1)
    p.js("document.getElementById('weights-panel').open = true")     # the buttons
    p.page.click("#paint-undo")
    assert np.array_equal(_weights(p)[1], E0)
    assert p.js("document.getElementById('paint-undo').disabled") is True
    p.page.click("#paint-redo")
    assert np.array_equal(_weights(p)[1], E1)
    p.page.click("#paint-undo")
    p.js("document.getElementById('weights-panel').open = false")
    assert np.array_equal(_weights(p)[1], E0)
    assert p.js("stbsViewer.paintUndo()") is False            # nothing more to undo
    p.js("stbsViewer.setPaint({mode: 'off'})")
    p.js("stbsViewer.setColorMode('shaded')")
    with pytest.raises(Exception, match="brush op: expected one of add, subtract, smooth"):
        p.js("stbsViewer.setPaint({op: 'blur'})")
    with pytest.raises(Exception, match="bone: expected an index 0..19 or a bone name"):
        p.js("stbsViewer.setPaint({bone: 'b99'})")
    assert p.errors == []


def test_taking_weight_from_a_bone_that_had_it_all_gives_it_to_the_parent(tube):
    p = tube
    p.js("stbsViewer.setPose({})")
    p.js("stbsViewer.frame()")
    W0, E0 = _weights(p)
    V = np.asarray(p.rig.V, dtype=np.float64)
    F = np.asarray(p.rig.F)
    cam = p.js("stbsViewer.camera()")
    at = [tuple(float(c) for c in _screen(cam, V[np.abs(V[:, 0] - 5.25) < 0.1]).mean(axis=0))]
    bone, parent = 10, int(p.rig.skeleton.parents[10])
    assert parent == 9
    # one dab: bone 10 takes all the weight within 0.6 (the others scaled to 0)
    p.js("o => stbsViewer.setPaint(o)", {"mode": "bone", "bone": bone, "op": "add",
                                         "radius": 0.6, "strength": 1.0, "falloff": "constant"})
    big = _stroke(p, at)["dabs"][0]["rest"]
    W1, _ = _weights(p)
    inside = np.linalg.norm(V - big, axis=1) < 0.6
    assert np.all(W1[inside, bone] == 1) and np.all(np.delete(W1[inside], bone, axis=1) == 0)
    # then half of it away within 0.3: where no neighbour has another bone, the parent gets it
    p.js("stbsViewer.setPaint({op: 'subtract', radius: 0.3, strength: 0.5})")
    small = _stroke(p, at)["dabs"][0]["rest"]
    W2, _ = _weights(p)
    core = np.linalg.norm(V - small, axis=1) < 0.3
    nb = np.zeros(len(V), bool)        # vertices with a neighbour outside the first dab
    for a in range(3):
        for b in range(3):
            nb[F[:, a]] |= ~inside[F[:, b]]
    sel = core & ~nb
    assert sel.sum() >= 8
    assert np.all(W2[sel, bone] == 0.5) and np.all(W2[sel, parent] == 0.5)
    assert np.abs(W2.astype(np.float64).sum(axis=1) - 1).max() < 2e-6
    for _ in range(2):
        assert p.js("stbsViewer.paintUndo()") is True
    assert np.array_equal(_weights(p)[0], W0)
    p.js("stbsViewer.setPaint({mode: 'off'})")
    assert p.errors == []


def test_painting_on_the_plate_saves_and_a_fresh_page_shows_it(plate, browser):  # noqa: F811
    p = plate
    p.js("stbsViewer.setPose({})")
    p.js("stbsViewer.frame()")
    W0, E0 = _weights(p)
    V = np.asarray(p.rig.V, dtype=np.float64)
    cam = p.js("stbsViewer.camera()")
    c = _screen(cam, np.array([[1.5, -1.0, 0.0]]))[0]
    p.js("o => stbsViewer.setPaint(o)", {"mode": "bone", "bone": "2", "op": "subtract",
                                         "radius": 0.6, "strength": 0.5, "falloff": "smooth"})
    st = _stroke(p, [(float(c[0]), float(c[1])), (float(c[0] + 30), float(c[1] - 10))])
    W1, E1 = _weights(p)
    changed = _check_region(W0, W1, 2, st["dabs"], 0.6, V)
    assert np.all(W1[changed, 2] < W0[changed, 2])
    assert np.abs(W1.astype(np.float64).sum(axis=1) - 1).max() < 2e-6
    p.js("stbsViewer.setPaint({mode: 'off'})")
    reply = p.js("stbsViewer.saveRig()")
    assert reply["path"] == str(p.srv.rig_target) and reply["has_E"] is True
    saved = stbs.load_rig(p.srv.rig_target)
    Ws = saved.W.toarray() if hasattr(saved.W, "toarray") else np.asarray(saved.W)
    Es = saved.E.toarray() if hasattr(saved.E, "toarray") else np.asarray(saved.E)
    assert np.array_equal(Ws, W1.astype(np.float64)) and np.array_equal(Es, E1.astype(np.float64))
    # the file exists now: saving again is refused (409) unless asked to overwrite; the
    # button asks first
    with pytest.raises(Exception, match="409|exists"):
        p.js("stbsViewer.saveRig()")
    p.js("document.getElementById('weights-panel').open = true")
    asked = []
    p.page.once("dialog", lambda d: (asked.append(d.message), d.dismiss()))
    p.page.click("#save-rig")
    p.page.wait_for_function("() => document.getElementById('status').textContent === 'not saved'")
    p.page.once("dialog", lambda d: (asked.append(d.message), d.accept()))
    p.page.click("#save-rig")
    p.page.wait_for_function(
        "() => document.getElementById('status').textContent.startsWith('saved ')")
    assert len(asked) == 2 and "Write over it?" in asked[0]
    p.js("document.getElementById('weights-panel').open = false")
    fresh = Page.__new__(Page)               # a second page on the same server
    fresh.rig, fresh.srv, fresh.page_options = p.rig, p.srv, {}
    fresh.open(browser)
    try:
        W2, E2 = _weights(fresh)
        assert np.array_equal(W2, W1) and np.array_equal(E2, E1)
        assert fresh.errors == []
    finally:
        fresh.page.close()
    # no errors but the browser's own lines for the three 409s asked for
    assert len(p.errors) == 3 and all("status of 409" in e for e in p.errors), p.errors
    p.errors.clear()


# --------------------------------------------------------------------------- endpoint weights
def test_recompute_one_bones_endpoint_weights_by_projection(plate):
    p = plate
    W0, E0 = _weights(p)
    bone = 7
    with _spy(p.srv) as calls:       # W as the server has it (saved above): not sent
        col = p.js("b => stbsViewer.recomputeEndpoint(b, 'projection').then(a => Array.from(a))",
                   bone)
    assert calls == [{"bone": bone, "method": "projection", "options": {}}]
    ref = stbs.weights.projection(np.asarray(p.rig.V), p.rig.skeleton)
    ref = np.asarray(ref.toarray() if hasattr(ref, "toarray") else ref)[:, bone]
    assert np.abs(np.array(col) - ref).max() < 1e-6
    W1, E1 = _weights(p)
    assert np.abs(E1[:, bone] - ref).max() < 1e-6
    assert np.abs(E0[:, bone] - ref).max() > 1e-2          # the rig's E was not projection
    assert np.array_equal(np.delete(E1, bone, axis=1), np.delete(E0, bone, axis=1))
    assert np.array_equal(W1, W0)
    assert p.js("stbsViewer.paintUndo()") is True
    assert np.array_equal(_weights(p)[1], E0)
    # the same from the box: the endpoint menu and recompute, for the selected bone
    p.js("document.getElementById('weights-panel').open = true")
    # the menu lists the methods the server says this rig can compute
    methods = p.js("Array.from(document.querySelectorAll('#endpoint-method option'), o => o.value)")
    from stbs.viewer.jobs import endpoint_methods

    assert methods == list(endpoint_methods(p.rig)) and "projection" in methods
    p.js("b => stbsViewer.setPaint({bone: b})", bone)
    p.page.select_option("#endpoint-method", "projection")
    assert p.page.is_hidden("#endpoint-progress") and p.page.is_hidden("#endpoint-cancel")
    p.page.click("#endpoint-recompute")
    done = f"{p.rig.skeleton.names[bone]}: endpoint weights by projection"
    p.page.wait_for_function("t => document.getElementById('status').textContent === t", arg=done)
    assert p.page.is_hidden("#endpoint-progress")
    assert np.abs(_weights(p)[1][:, bone] - ref).max() < 1e-6
    p.js("document.getElementById('weights-panel').open = false")
    assert p.js("stbsViewer.paintUndo()") is True
    assert np.array_equal(_weights(p)[1], E0)
    bad_method = 'endpoint method: expected one of .*projection.*, got "nearest"'
    with pytest.raises(Exception, match=bad_method):
        p.js("stbsViewer.recomputeEndpoint(0, 'nearest')")
    with pytest.raises(Exception, match="alpha applies to method='idw' only"):   # the server's 400
        p.js("stbsViewer.recomputeEndpoint(0, 'projection', {alpha: 3})")
    _no_errors(p)


# --------------------------------------------------------------------------- the curve
CURVES = [[[0.25, 0.6], [0.5, 0.9]], [[0.5, 0.5]], [[0.1, 0.0], [0.3, 0.0], [0.7, 1.0]],
          [[0.05, 0.4], [0.2, 0.45], [0.6, 0.55], [0.95, 0.99]], [[0.8, 0.2]]]


def test_the_endpoint_curve_is_splinefilter_live_and_applies_undoably(plate):
    p = plate
    bone = 4
    xs = np.linspace(0, 1, 301).tolist() + [0.25, 0.5, 1e-9, 1 - 1e-9]
    for pts in CURVES:
        back = p.js("([b, pts]) => stbsViewer.setSpline(b, pts)", [bone, pts])
        assert back[0] == [0, 0] and back[-1] == [1, 1] and back[1:-1] == pts
        got = np.array(p.js("([b, xs]) => stbsViewer.splineValues(b, xs)", [bone, xs]))
        assert np.abs(got - SplineFilter(pts)(np.array(xs))).max() < 1e-6, pts
    # live: the shader skins with f(E) for that bone, E itself unchanged
    pts = CURVES[0]
    p.js("([b, pts]) => stbsViewer.setSpline(b, pts)", [bone, pts])
    pose_obj = {"rotate": {"4": {"angle": 40}, "5": {"angle": -30}}, "stretch": {"4": 1.8}}
    p.js("o => stbsViewer.setPose(o)", pose_obj)
    W0, E0 = _weights(p)
    Ef = E0.astype(np.float64)
    Ef[:, bone] = SplineFilter(pts)(Ef[:, bone])
    U = p.positions()[:, :2]
    diag = _diag(p.rig)
    assert np.abs(U - _deform(p, pose_obj, W0, Ef, "stbs-dqs")).max() < POS_TOL * diag
    assert np.abs(U - _deform(p, pose_obj, W0, E0, "stbs-dqs")).max() > 10 * POS_TOL * diag
    # apply bakes f into E (one undo step); the curve is then the identity
    assert p.js("b => stbsViewer.applySpline(b)", bone) is True
    W1, E1 = _weights(p)
    assert np.abs(E1[:, bone] - Ef[:, bone]).max() < 1e-6
    assert np.array_equal(np.delete(E1, bone, axis=1), np.delete(E0, bone, axis=1))
    assert p.js("b => stbsViewer.spline(b)", bone) == [[0, 0], [1, 1]]
    assert np.abs(p.positions()[:, :2] - U).max() < 1e-6 * diag
    assert p.js("stbsViewer.paintUndo()") is True
    assert np.array_equal(_weights(p)[1], E0)
    assert p.js("stbsViewer.paintRedo()") is True
    assert np.array_equal(_weights(p)[1], E1)
    assert p.js("stbsViewer.paintUndo()") is True
    with pytest.raises(Exception, match="monotone"):
        p.js("stbsViewer.setSpline(0, [[0.2, 0.6], [0.4, 0.3]])")
    with pytest.raises(Exception, match=r"must lie in \[0, 1\]\^2"):
        p.js("stbsViewer.setSpline(0, [[1.2, 0.6]])")
    p.js("stbsViewer.setPose({})")
    _no_errors(p)


def test_the_curve_editor_adds_moves_and_removes_points_with_the_mouse(plate):
    p = plate
    p.js("document.getElementById('weights-panel').open = true")
    p.js("stbsViewer.setPaint({bone: 6})")
    box = p.page.locator("#spline").bounding_box()
    pad = 10
    def at(x, y):
        return (box["x"] + pad + x * (box["width"] - 2 * pad),
                box["y"] + box["height"] - pad - y * (box["height"] - 2 * pad))
    m = p.page.mouse
    m.click(*at(0.3, 0.7))
    pts = p.js("stbsViewer.spline(6)")
    assert len(pts) == 3 and np.allclose(pts[1], [0.3, 0.7], atol=0.02)
    m.move(*at(0.3, 0.7))
    m.down()
    m.move(*at(0.5, 0.8), steps=4)
    m.up()
    pts = p.js("stbsViewer.spline(6)")
    assert len(pts) == 3 and np.allclose(pts[1], [0.5, 0.8], atol=0.02)
    p.page.screenshot(path="build/screens/paint-curve-editor.png")
    m.dblclick(*at(0.5, 0.8))
    assert p.js("stbsViewer.spline(6)") == [[0, 0], [1, 1]]
    # apply bakes the curve drawn
    m.click(*at(0.4, 0.8))
    pts = p.js("stbsViewer.spline(6)")
    _, E0 = _weights(p)
    p.page.click("#spline-apply")
    _, E1 = _weights(p)
    assert np.abs(E1[:, 6] - SplineFilter(pts[1:-1])(E0[:, 6].astype(np.float64))).max() < 1e-6
    assert np.abs(E1[:, 6] - E0[:, 6]).max() > 0.05
    assert p.js("stbsViewer.spline(6)") == [[0, 0], [1, 1]]
    assert p.js("stbsViewer.paintUndo()") is True
    m.click(*at(0.4, 0.8))
    p.page.click("#spline-reset")
    assert p.js("stbsViewer.spline(6)") == [[0, 0], [1, 1]]
    p.js("document.getElementById('weights-panel').open = false")
    _no_errors(p)
