"""``stbs bench --viewer``: the viewer's frame time in headless Chromium beside three.js's
SkinnedMesh (``three-lbs``). The JSON is DESIGN §7's, the peer page really skins (its
positions are stbs's LBS for a rotation-only pose, and its picture is the viewer's),
and a missing Playwright or Chromium is one line and exit status 2.

Needs ``playwright`` and Chromium at ``/usr/bin/chromium`` (or ``$STBS_CHROMIUM``) like
the viewer's browser tests. Nothing here asserts a speed.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

import stbs
import stbs._optional
from stbs.bench import viewer as bv
from stbs.cli import main
from stbs.viewer import STATIC_DIR, ViewerServer

pytest.importorskip("playwright.sync_api", reason="playwright is not installed "
                    "(pip install playwright; the test extra has it)")

METHODS = ("lbs", "dqs", "stbs-lbs", "stbs-dqs")
BACKGROUND = np.array([0x20, 0x23, 0x2A])


def run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def browser_path():
    path = bv.default_browser()
    if not Path(path).is_file():
        pytest.skip(f"no Chromium at {path} (apt-get install chromium; make test does)")
    for bundle in ("viewer.js", "three-lbs.js"):
        if not (STATIC_DIR / bundle).is_file():
            pytest.skip(f"the bundle {bundle} is not built (make "
                        f"src/stbs/viewer/static/{bundle})")
    return path


@pytest.fixture(scope="module")
def bench(browser_path):
    with bv.ViewerBench(browser_path, canvas=(640, 400), timeout_s=120) as b:
        yield b


# --------------------------------------------------------------------------- the rig
def test_the_tube_rig_has_exactly_n_vertices_and_four_weights_each():
    for n in (32, 2000, 2017):
        rig = bv.tube_rig(n)
        assert rig.V.shape == (n, 3) and rig.skeleton.n_bones == 20
        assert rig.F.min() >= 0 and rig.F.max() == n - 1
        W, E = rig.W.tocsr(), rig.E.tocsr()
        assert np.all(np.diff(W.indptr) == 4) and np.allclose(W.sum(axis=1), 1)
        assert W.data.min() > 0 and 0 <= E.data.min() and E.data.max() <= 1
    rig = bv.tube_rig(4000)
    # bone i spans x in [i/2, (i+1)/2]: a vertex inside it weighs most on it, and its
    # endpoint weight there is its place along the bone
    x = rig.V[:, 0]
    inside = (x > 0.05) & (x < 9.95) & (np.abs(x * 2 - np.round(x * 2)) > 0.1)
    home = np.floor(x * 2).astype(int)
    Wd, Ed = rig.W.toarray(), rig.E.toarray()
    assert np.all(Wd[inside].argmax(axis=1) == home[inside])
    rows = np.nonzero(inside)[0]
    assert np.allclose(Ed[rows, home[rows]], x[rows] * 2 - home[rows])
    with pytest.raises(ValueError, match="n: expected a vertex count >= 32, got 5"):
        bv.tube_rig(5)


def test_the_bench_pose_stretches_and_twists_and_its_rotation_only_form_does_not():
    sk = bv.tube_rig(100).skeleton
    full = stbs.io.read_pose(bv.bench_pose(), sk)
    rot = stbs.io.read_pose(bv.bench_pose(stretch=False, twist=False), sk)
    assert np.all(np.abs(full.stretch - 1) > 1e-3) and np.abs(full.twist).max() > 0.1
    assert np.all(rot.stretch == 1) and np.all(rot.twist == 0)
    assert np.allclose(full.rotations[0], rot.rotations[0])


def test_the_table_gives_fps_and_the_ratio_to_three_lbs():
    rows = [{"vertices": 1000, "method": "stbs-dqs", "ms_per_frame": 3.0},
            {"vertices": 1000, "method": "three-lbs", "ms_per_frame": 2.0}]
    text = bv.format_table(rows, {"renderer": "R", "canvas": [640, 400],
                                  "frames": {"1000": 7}})
    line = next(ln for ln in text.splitlines() if ln.strip().startswith("1,000  stbs-dqs"))
    assert line.split() == ["1,000", "stbs-dqs", "3.00", "333.3", "1.50", "7"]
    assert "canvas 640x400" in text and "1.50x three-lbs" in text
    rows = [{"vertices": 100_000, "method": m, "ms_per_frame": t}
            for m, t in (("stbs-dqs", 16.0), ("three-lbs", 10.0))]
    meta = {"canvas": [640, 400], "latency": {"100000": {
        "dab_ms": 12.5, "dabs": 40, "dab_vertices": 9000, "seek_ms": 30.25, "seeks": 40}}}
    text = bv.format_table(rows, meta)
    assert "1.60x three-lbs's frame time\n" in text + "\n"
    tail = text.split("latency: a paint dab", 1)[1]
    line = next(ln for ln in tail.splitlines() if ln.strip().startswith("100,000  "))
    assert line.split() == ["100,000", "12.50", "40", "9,000", "30.25", "40"]
    assert "target" not in text


def test_the_seek_clip_has_1000_keys_that_read_as_a_clip():
    clip = bv.seek_clip()
    assert len(clip["keys"]) == bv.SEEK_KEYS == 1000
    sk = bv.tube_rig(100).skeleton
    c = stbs.io.read_clip(clip, sk)
    a, b = c.pose(0.0), c.pose(10.0)
    assert np.abs(a.rotations - b.rotations).max() > 0.05


# --------------------------------------------------------------------------- command line
def test_the_command_writes_design_json_for_every_method_and_size(capsys, tmp_path,
                                                                  browser_path):
    out = tmp_path / "viewer.json"
    code, text, err = run(capsys, "bench", "--viewer", "--sizes", "2k", "--frames", "3",
                          "--browser", browser_path, "--json", str(out))
    assert code == 0, err
    doc = json.loads(out.read_text())
    assert set(doc) == {"viewer", "latency"}
    assert [(r["vertices"], r["method"]) for r in doc["viewer"]] == \
        [(2000, m) for m in METHODS + ("three-lbs",)]
    for r in doc["viewer"]:
        assert set(r) == {"vertices", "method", "ms_per_frame"}
        assert isinstance(r["ms_per_frame"], float)
        assert math.isfinite(r["ms_per_frame"]) and r["ms_per_frame"] > 0
    # the latencies: a stroke's dabs and the seeks, timed in the page, each size
    assert [r["vertices"] for r in doc["latency"]] == [2000]
    for r in doc["latency"]:
        assert set(r) == {"vertices", "dab_ms", "dabs", "dab_vertices", "seek_ms", "seeks"}
        assert r["dabs"] >= 10 and r["seeks"] == bv.SEEKS
        assert 0 < r["dab_ms"] < 1000 and 0 < r["seek_ms"] < 10_000
        assert 50 < r["dab_vertices"] < r["vertices"]       # the brush covers a part
    assert "WebGL renderer:" in text and "canvas 1280x720" in text
    assert "latency: a paint dab" in text
    assert sum(ln.split()[1:2] == ["three-lbs"] for ln in text.splitlines()) == 1
    assert not list(tmp_path.glob("*.tmp*"))           # written by rename


def test_missing_chromium_or_playwright_is_one_line_and_exit_2(capsys, tmp_path, monkeypatch):
    code, out, err = run(capsys, "bench", "--viewer", "--browser", str(tmp_path / "chromium"))
    assert code == 2 and out == "" and err.count("\n") == 1
    assert err.startswith("stbs bench: error:") and str(tmp_path / "chromium") in err
    assert "Chromium" in err
    real = stbs._optional.available
    monkeypatch.setattr(stbs._optional, "available",
                        lambda m: m != "playwright" and real(m))
    code, out, err = run(capsys, "bench", "--viewer")
    assert code == 2 and out == "" and err.count("\n") == 1
    assert "playwright" in err and "stbs-skinning[bench]" in err


def test_unbuilt_or_broken_pages_are_one_line_and_exit_2(capsys, tmp_path, monkeypatch,
                                                         browser_path):
    import stbs.viewer.server

    (tmp_path / "index.html").write_text('<!doctype html><script type="module" '
                                         'src="/static/viewer.js"></script>')
    monkeypatch.setattr(stbs.viewer, "STATIC_DIR", tmp_path)
    monkeypatch.setattr(stbs.viewer.server, "STATIC_DIR", tmp_path)
    code, out, err = run(capsys, "bench", "--viewer", "--sizes", "1k", "--frames", "1")
    assert code == 2 and out == "" and err.count("\n") == 1
    assert "viewer.js, three-lbs.js are not built" in err and str(tmp_path) in err
    # built, but the page cannot start (as without WebGL2): its error, in one line
    (tmp_path / "viewer.js").write_text(
        'window.stbsViewer = { ready: Promise.reject(new Error("WebGL2 is required")) };')
    (tmp_path / "three-lbs.js").write_text("")
    code, out, err = run(capsys, "bench", "--viewer", "--sizes", "1k", "--frames", "1",
                         "--browser", browser_path)
    # after the progress lines, the error in one line
    errors = [ln for ln in err.splitlines() if "error:" in ln]
    assert code == 2 and out == "" and errors == [err.splitlines()[-1]], err
    assert errors[0].startswith("stbs bench: error: http://127.0.0.1:")
    assert "the page did not start in Chromium" in err and "WebGL2 is required" in err


def test_bad_options_are_one_line_and_exit_2(capsys):
    code, out, err = run(capsys, "bench", "--viewer", "--methods", "lbs,three-dqs")
    assert code == 2 and err.count("\n") == 1 and "three-dqs" in err and out == ""
    code, out, err = run(capsys, "bench", "--viewer", "--weights")
    assert code == 2 and err.count("\n") == 1 and out == ""
    assert "--weights" in err and "--viewer" in err and "give one of them" in err


# --------------------------------------------------------------------------- the peer
def _six_bone_rig(seed=4):
    """The bench's tube, but six bone weights a vertex (so the top-4 cut matters)."""
    tube = bv.tube_rig(2000)
    n, b = len(tube.V), tube.skeleton.n_bones
    rng = np.random.default_rng(seed)
    home = np.clip(np.floor(tube.V[:, 0] * 2), 0, b - 1).astype(int)
    idx = np.clip(home - 2, 0, b - 6)[:, None] + np.arange(6)[None]     # 6 bones near it
    w = rng.uniform(0.05, 1.0, (n, 6))
    np.put_along_axis(w, (home - idx[:, 0])[:, None], 2.0, axis=1)   # its own bone most
    w /= w.sum(axis=1, keepdims=True)
    W = sp.csr_array((w.ravel(), idx.ravel(), np.arange(0, 6 * n + 1, 6)), shape=(n, b))
    return stbs.Rig(V=tube.V, F=tube.F, skeleton=tube.skeleton, W=W)


def _mask(png: bytes) -> np.ndarray:
    import io

    from PIL import Image

    img = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=np.int16)
    return np.abs(img - BACKGROUND).max(axis=2) > 12


def _iou(a, b):
    return (a & b).sum() / max((a | b).sum(), 1)


def test_the_three_lbs_peer_is_stbs_lbs_for_a_rotation_only_pose(bench):
    rig = _six_bone_rig()
    V = np.asarray(rig.V)
    diag = float(np.linalg.norm(V.max(0) - V.min(0)))
    with ViewerServer(rig) as srv:
        page = bench.open(srv.url, "stbsViewer")
        page.evaluate("p => stbsViewer.setPose(p)", bv.bench_pose(stretch=False, twist=False))
        page.evaluate("stbsViewer.setMethod('lbs')")
        bv.canvas_only(page, (640, 400))    # the canvas alone, filling the page as the peer's
        cam = page.evaluate("stbsViewer.camera()")
        ours = _mask(page.screenshot())
        page.close()
        pose = srv.pose
        peer = bench.open(f"http://127.0.0.1:{srv.port}/static/three-lbs.html"
                          f"?token={srv.token}", "stbsThreeLbs")
        try:
            U = np.array(peer.evaluate("stbsThreeLbs.skinnedPositions().then(Array.from)"),
                         dtype=np.float64).reshape(-1, 3)
            peer.evaluate("c => stbsThreeLbs.setCamera(c)", cam)
            theirs = _mask(peer.screenshot())
            srv.set_pose({})
            peer.evaluate("stbsThreeLbs.fetchPose()")
            peer.evaluate("c => stbsThreeLbs.setCamera(c)", cam)
            rest = _mask(peer.screenshot())
        finally:
            peer.close()
    ref = stbs.deform(V, rig.skeleton, pose, rig.W, method="lbs", max_influences=4)
    assert np.abs(ref - V).max() > 0.1 * diag                   # a real pose
    assert np.abs(U - ref).max() < 1e-4 * diag
    # the same top-4 cut: without it (all six weights) the positions differ
    six = stbs.deform(V, rig.skeleton, pose, rig.W, method="lbs")
    assert np.abs(six - ref).max() > 2e-3 * diag
    # three's shader draws that posed mesh where the viewer draws its lbs
    assert ours.mean() > 0.01
    print("IoU viewer/peer", _iou(ours, theirs), "rest/peer", _iou(rest, theirs))
    assert _iou(ours, theirs) > 0.9, _iou(ours, theirs)
    assert _iou(rest, theirs) < 0.6, _iou(rest, theirs)
    assert bench.errors == []
