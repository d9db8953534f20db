"""stbs view with a motion: the server hands the page a clip (GET /api/clip) and the page
opens its timeline with it; --motion retargets a BVH capture onto the rig."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest
from test_viewer_cli import View
from test_viewer_page import Page, browser  # noqa: F401  (fixture)
from viewer_client import bar_rig, request

import stbs
from stbs.cli import main
from stbs.viewer import ViewerServer

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bake"))
from bake_fixtures import arm_bvh, arm_rig  # noqa: E402


def _clip(rig, n=3):
    sk = rig.skeleton
    keys = [(0.0, stbs.Pose.rest(sk))]
    for k in range(1, n):
        R = stbs.transforms.axis_angle_to_matrix(np.tile([0, 0, 1.0], (sk.n_bones, 1)),
                                                 np.full(sk.n_bones, 0.4 * k))
        keys.append((0.5 * k, stbs.forward_kinematics(sk, rotations=R, stretch=[1 + 0.2 * k] *
                                                       sk.n_bones)))
    return stbs.Clip(keys, fps=10)


def test_the_server_serves_its_clip():
    rig = bar_rig()
    clip = _clip(rig)
    with ViewerServer(rig, clip=clip) as srv:
        info = request(srv, "GET", "/api/rig", token=True).json()
        assert info["clip"] is True
        r = request(srv, "GET", "/api/clip", token=True)
        assert r.status == 200
        out = r.json()
        assert out["keys"] == clip.times.tolist() and out["fps"] == 10
        assert (out["start"], out["end"]) == (0.0, 1.0)
        # the keys' poses on request (a clip file object), the clip itself held as it is
        r = request(srv, "GET", f"/api/clip/{out['id']}/keys", token=True)
        back = stbs.io.read_clip(r.json()["clip"], rig.skeleton)
        assert back.times.tolist() == clip.times.tolist()
        np.testing.assert_allclose(back.pose(0.7).origins, clip.pose(0.7).origins, atol=1e-9)
        assert srv.clips.get(out["id"]) is clip
        assert request(srv, "GET", "/api/clip").status == 403          # the token
    with ViewerServer(rig) as srv:
        assert request(srv, "GET", "/api/rig", token=True).json()["clip"] is False
        r = request(srv, "GET", "/api/clip", token=True)
        assert r.status == 404 and "--motion" in r.json()["error"]
    other = stbs.Clip([(0.0, stbs.Pose.rest(stbs.Skeleton([[0, 0, 0], [0, 1, 0]], [[0, 1]])))])
    with pytest.raises(ValueError, match="clip must be a stbs.Clip of the rig's skeleton"):
        ViewerServer(rig, clip=other)


def test_the_page_opens_its_timeline_with_the_clip(browser):  # noqa: F811
    rig = bar_rig()
    clip = _clip(rig)
    p = Page(browser, rig, clip=clip)
    try:
        keys = p.js("stbsViewer.keys()")
        assert [k["time"] for k in keys] == [0.0, 0.5, 1.0]
        p.js("t => stbsViewer.seek(t)", 0.75)
        want = stbs.deform(rig.V, rig.skeleton, clip.pose(0.75), rig.W, rig.E,
                           method="stbs-dqs", max_influences=4)
        got = p.positions()
        diag = float(np.linalg.norm(np.ptp(rig.V, axis=0)))
        assert np.abs(got - np.pad(want, ((0, 0), (0, 3 - want.shape[1])))).max() < 1e-4 * diag
        assert p.errors == []
    finally:
        p.close()


def test_view_motion_retargets_a_capture(tmp_path, capsys):
    rig = arm_rig()
    stbs.save_rig(tmp_path / "arm.npz", rig)
    bvh = arm_bvh(tmp_path / "wave.bvh", frames=20)
    with View(tmp_path / "arm.npz", "--motion", bvh, cwd=tmp_path) as v:
        status, body = v.get("/api/clip")
        out = json.loads(body)
        assert status == 200 and len(out["keys"]) == 20 and out["fps"] == pytest.approx(25)
        # the wrist's roll, spread along the forearm: the elbow bone's end twist
        status, body = v.get(f"/api/clip/{out['id']}/keys")
        back = stbs.io.read_clip(json.loads(body)["clip"], rig.skeleton)
        assert back.keys[-1][1].twist[1, 1] == pytest.approx(np.radians(6 * 19), abs=1e-6)
        code, _, _ = v.stop()
    assert code == 0
    # --mapping: the rig's wrist driven by no joint of the capture: no roll to spread
    (tmp_path / "map.json").write_text(json.dumps({"shoulder": "shoulder", "elbow": "elbow",
                                                   "wrist": None}))
    with View(tmp_path / "arm.npz", "--motion", bvh, "--mapping", tmp_path / "map.json",
              cwd=tmp_path) as v:
        out = json.loads(v.get("/api/clip")[1])
        back = stbs.io.read_clip(json.loads(v.get(f"/api/clip/{out['id']}/keys")[1])["clip"],
                                 rig.skeleton)
        assert len(back) == 20 and np.abs(back.keys[-1][1].twist).max() < 1e-9
        v.stop()
    for args, words in (((tmp_path / "none.bvh",), "file not found"),
                        ((bvh, "--mapping", tmp_path / "none.json"), "file not found"),
                        ((tmp_path / "map.json", "--mapping", tmp_path / "map.json"),
                         "--mapping applies to --motion CAPTURE.bvh")):
        assert main(["view", str(tmp_path / "arm.npz"), "--motion", *map(str, args),
                     "--no-browser"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("stbs view: error: ") and words in err[0]


def test_a_gltf_rig_opens_with_its_own_animation(shared_data, tmp_path):
    with View(shared_data / "gltf" / "SimpleSkin.gltf", cwd=tmp_path) as v:
        status, body = v.get("/api/clip")
        assert status == 200 and len(json.loads(body)["keys"]) == 12
        v.stop()
    # RiggedSimple's animation moves a joint off its parent bone's end: the pose files'
    # forward-kinematics form holds that too, so it goes on the timeline as it is
    with View(shared_data / "gltf" / "RiggedSimple.glb", cwd=tmp_path) as v:
        status, body = v.get("/api/clip")
        assert status == 200 and len(json.loads(body)["keys"]) > 1
        code, _, err = v.stop()
    assert code == 0 and "cannot go on the timeline" not in err
