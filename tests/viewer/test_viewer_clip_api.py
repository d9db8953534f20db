"""The viewer server's clip routes over plain HTTP: sample, pose at a time, save, export."""

from __future__ import annotations

import base64
import io
import json
import re

import numpy as np
import pytest
from viewer_client import bar_rig, post_json, request

import stbs
from stbs.viewer import ViewerServer, clips

KEYS = [
    {"time": 0.0, "pose": {}},
    {"time": 1.0, "pose": {"rotate": {"upper": {"axis": [0, 0, 1], "angle": 90}},
                           "stretch": {"lower": 2.0}}},
    {"time": 1.5, "pose": {"twist": {"lower": [0, 720]}}},
]
CLIP = {"fps": 4, "interpolation": "linear", "keys": KEYS}


@pytest.fixture(scope="module")
def srv(tmp_path_factory):
    folder = tmp_path_factory.mktemp("poses")
    with ViewerServer(bar_rig(), pose_folder=folder, name="bar") as s:
        yield s


@pytest.fixture(scope="module")
def nosave():
    with ViewerServer(bar_rig()) as s:
        yield s


def _pose(frame, sk):
    return stbs.Pose(sk, rotations=frame["rotations"], origins=frame["origins"],
                     stretch=frame["stretch"], twist=frame["twist"])


def test_sample_gives_the_clip_on_its_fps_grid(srv):
    r = post_json(srv, "/api/clip/sample", CLIP)
    assert r.status == 200, r.body
    out = r.json()
    assert out["fps"] == 4 and out["duration"] == 1.5 and out["keys"] == [0.0, 1.0, 1.5]
    assert out["times"] == [0.0, 0.25, 0.5, 0.75, 1.0, 1.25, 1.5]
    assert len(out["frames"]) == 7
    sk = srv.rig.skeleton
    # by hand: halfway to the second key the upper bone is turned 45 degrees about z,
    # the lower one stretched 1.5; at 1.25 the lower bone's end twist is 360 degrees
    half = _pose(out["frames"][2], sk)
    assert np.allclose(half.rotations[0] @ [1, 0, 0], [np.sqrt(0.5), np.sqrt(0.5), 0])
    assert half.stretch.tolist() == pytest.approx([1.0, 1.5])
    assert np.degrees(_pose(out["frames"][5], sk).twist[1, 1]) == pytest.approx(360.0)
    clip = stbs.io.read_clip(CLIP, sk)
    for t, frame in zip(out["times"], out["frames"], strict=True):
        ref = clip.pose(t)
        got = _pose(frame, sk)
        for a, b in ((got.rotations, ref.rotations), (got.origins, ref.origins),
                     (got.stretch, ref.stretch), (got.twist, ref.twist)):
            assert np.abs(a - b).max() < 1e-12


def test_sample_at_explicit_times(srv):
    r = post_json(srv, "/api/clip/sample", dict(CLIP, times=[0.3, -1, 9]))
    assert r.status == 200, r.body
    out = r.json()
    assert out["times"] == [0.3, -1.0, 9.0]
    sk = srv.rig.skeleton
    f = [_pose(x, sk) for x in out["frames"]]
    assert f[0].stretch[1] == pytest.approx(1.3)
    assert f[1].is_rest()                                   # clamped before the first key
    assert np.degrees(f[2].twist[1, 1]) == pytest.approx(720.0)    # after the last


def test_clip_pose_becomes_the_current_pose(srv):
    r = post_json(srv, "/api/clip/pose", {"clip": CLIP, "time": 0.5})
    assert r.status == 200, r.body
    out = r.json()
    assert out["time"] == 0.5 and set(out) == {"pose", "time"}
    # halfway between rest and a bent, stretched pose: the pose object (the
    # forward-kinematics form, which holds every pose) reads back to the pose itself
    ref = stbs.io.read_clip(CLIP, srv.rig.skeleton).pose(0.5)
    bones = request(srv, "GET", "/api/pose/bones", token=True).json()
    assert np.abs(np.array(bones["rotations"]) - ref.rotations).max() < 1e-12
    assert np.abs(np.array(bones["origins"]) - ref.origins).max() < 1e-12
    assert request(srv, "GET", "/api/pose", token=True).json() == out["pose"]
    back = stbs.io.read_pose(out["pose"], srv.rig.skeleton)
    assert np.abs(back.origins - ref.origins).max() < 1e-12
    assert np.abs(back.rotations - ref.rotations).max() < 1e-12
    out = post_json(srv, "/api/clip/pose", {"clip": CLIP, "time": 1.0}).json()
    back = stbs.io.read_pose(out["pose"], srv.rig.skeleton)
    assert back.stretch.tolist() == pytest.approx([1.0, 2.0])


def _frames(r, sk):
    """The rows of GET /api/clip/ID/frames as (R, O, sigma, theta)."""
    rows = r.array()
    k, b, d = rows.shape[0], rows.shape[1], sk.dim
    assert r.headers["x-stbs-dtype"] == "float64" and rows.shape[2] == d * d + d + 3
    return (rows[..., :d * d].reshape(k, b, d, d), rows[..., d * d:d * d + d],
            rows[..., d * d + d], rows[..., d * d + d + 1:])


def test_a_held_clip_answers_frames_poses_and_keys_by_id(srv):
    sk = srv.rig.skeleton
    r = post_json(srv, "/api/clip", CLIP)
    assert r.status == 200, r.body
    out = r.json()
    cid = out["id"]
    assert re.fullmatch(r"[0-9a-f]{16}", cid)
    assert {k: out[k] for k in ("fps", "interpolation", "start", "end", "duration", "keys")} \
        == {"fps": 4, "interpolation": "linear", "start": 0.0, "end": 1.5, "duration": 1.5,
            "keys": [0.0, 1.0, 1.5]}
    assert request(srv, "GET", f"/api/clip/{cid}", token=True).json() == out
    clip = stbs.io.read_clip(CLIP, sk)
    times = [0.3, -1, 1.0, 1.2345678901234567, 9]
    r = request(srv, "GET", f"/api/clip/{cid}/frames?t={','.join(map(repr, times))}",
                token=True)
    assert r.status == 200, r.body
    R, O, sigma, theta = _frames(r, sk)
    for k, t in enumerate(times):       # the clip's own poses, to rounding
        ref = clip.pose(t)
        for a, b in ((R[k], ref.rotations), (O[k], ref.origins), (sigma[k], ref.stretch),
                     (theta[k], ref.twist)):
            assert np.abs(a - b).max() < 1e-12
    out = post_json(srv, f"/api/clip/{cid}/pose", {"time": 0.5}).json()
    assert out["time"] == 0.5
    assert np.abs(srv.pose.origins - clip.pose(0.5).origins).max() < 1e-12
    assert request(srv, "GET", "/api/pose", token=True).json() == out["pose"]
    keys = request(srv, "GET", f"/api/clip/{cid}/keys", token=True).json()["clip"]
    back = stbs.io.read_clip(keys, sk)
    assert back.times.tolist() == [0.0, 1.0, 1.5] and back.fps == 4
    assert np.abs(back.pose(0.7).origins - clip.pose(0.7).origins).max() < 1e-12
    # saved by id (at another fps) without sending the clip
    r = post_json(srv, "/api/save-clip", {"id": cid, "fps": 12, "name": "held.json"})
    assert r.status == 200, r.body
    saved = stbs.io.read_clip(srv.pose_folder / "held.json", sk)
    assert saved.fps == 12 and saved.times.tolist() == [0.0, 1.0, 1.5]


def test_the_server_keeps_the_clips_used_last(srv):
    first = post_json(srv, "/api/clip", CLIP).json()["id"]
    ids = [post_json(srv, "/api/clip", CLIP).json()["id"] for _ in range(clips.MAX_CLIPS)]
    r = request(srv, "GET", f"/api/clip/{first}/frames?t=0", token=True)
    assert r.status == 404 and "POST /api/clip it again" in r.json()["error"]
    assert request(srv, "GET", f"/api/clip/{ids[0]}/frames?t=0", token=True).status == 200


@pytest.mark.parametrize("query, match", [
    ("", "expected t=T0,T1,... once"),
    ("?t=", "expected t=T0,T1,... once"),
    ("?t=0&t=1", "expected t=T0,T1,... once"),
    ("?t=0,x", r"t\[1\]: expected a number of seconds"),
    ("?t=0,nan", r"t\[1\]: expected a finite number"),
    ("?t=0&fps=3", "unexpected parameter 'fps'"),
    ("?t=" + ",".join(["0"] * 2001), "at most 2000 a request"),
])
def test_bad_frame_queries_get_one_clear_line(srv, query, match):
    cid = post_json(srv, "/api/clip", CLIP).json()["id"]
    r = request(srv, "GET", f"/api/clip/{cid}/frames{query}", token=True)
    assert r.status == (413 if "at most" in match else 400), r.body
    assert re.search(match, r.json()["error"]), r.json()["error"]


def test_save_clip_writes_a_clip_file(srv):
    r = post_json(srv, "/api/save-clip", {"clip": CLIP, "name": "walk.json"})
    assert r.status == 200, r.body
    out = r.json()
    assert out["name"] == "walk.json" and out["keys"] == 3
    path = srv.pose_folder / "walk.json"
    assert out["path"] == str(path)
    back = stbs.io.read_clip(path, srv.rig.skeleton)
    assert back.times.tolist() == [0.0, 1.0, 1.5] and back.fps == 4
    ref = stbs.io.read_clip(CLIP, srv.rig.skeleton)
    for (_, a), (_, b) in zip(ref.keys, back.keys, strict=True):
        assert np.abs(a.rotations - b.rotations).max() < 1e-12
        assert np.abs(a.twist - b.twist).max() < 1e-12
    # no overwrite without asking; with it, replaced
    r = post_json(srv, "/api/save-clip", {"clip": dict(CLIP, fps=8), "name": "walk.json"})
    assert r.status == 409 and "overwrite" in r.json()["error"]
    r = post_json(srv, "/api/save-clip", {"clip": dict(CLIP, fps=8), "name": "walk.json",
                                          "overwrite": True})
    assert r.status == 200 and stbs.io.read_clip(path, srv.rig.skeleton).fps == 8
    # default names count up
    names = [post_json(srv, "/api/save-clip", {"clip": CLIP}).json()["name"] for _ in range(2)]
    assert names == ["bar-clip-001.json", "bar-clip-002.json"]
    assert not [p for p in srv.pose_folder.iterdir() if p.name.startswith(".")]


@pytest.mark.parametrize("path, body, status, match", [
    ("/api/clip/sample", [1], 400, "clip: expected a JSON object"),
    ("/api/clip/sample", {"keys": []}, 400, 'clip: "keys": expected a non-empty list'),
    ("/api/clip/sample", {"keys": [{"time": 0, "pose": {"stretch": {"lower": 0}}}]}, 400,
     r'clip: keys\[0\]\.pose: "stretch" bone \'lower\': stretch must be > 0'),
    ("/api/clip/sample", dict(CLIP, times=[]), 400, '"times": expected a list of 1 to 2000'),
    ("/api/clip/sample", dict(CLIP, times=[0, "x"]), 400, r'"times"\[1\]: expected a finite'),
    ("/api/clip/sample", dict(CLIP, fps=1000, keys=KEYS + [{"time": 3, "pose": {}}]), 413,
     "3 s at 1000 fps is 3001 frames; the limit is 2000"),
    ("/api/clip/pose", {"clip": CLIP}, 400, 'request body: missing "time"'),
    ("/api/clip/pose", {"clip": CLIP, "time": True}, 400, '"time": expected a finite number'),
    ("/api/save-clip", {"clip": CLIP, "name": "../x.json"}, 400,
     '"name": expected a bare file name ending in .json'),
    ("/api/save-clip", {"clip": CLIP, "name": "x.json", "overwrite": 1}, 400,
     '"overwrite": expected true or false'),
    ("/api/save-clip", {"clip": CLIP, "as": "x"}, 400, "unexpected key 'as'"),
    ("/api/save-clip", {"name": "x.json"}, 400, 'expected "clip" .* or "id"'),
    ("/api/save-clip", {"id": "zz"}, 400, '"id": expected a clip id'),
    ("/api/save-clip", {"id": "0123456789abcdef"}, 404, "no clip '0123456789abcdef'"),
    ("/api/save-clip", {"clip": CLIP, "fps": 3}, 400, '"fps" goes with "id"'),
    ("/api/clip", [1], 400, "clip: expected a JSON object"),
    ("/api/clip/0123456789abcdef/pose", {"time": 0}, 404, "no clip"),
    ("/api/export", {"frames": ["AAAA"], "fps": 10}, 400,
     r'"frames"\[0\]: expected a PNG image, found 3 bytes'),
    ("/api/export", {"frames": [], "fps": 10}, 400, '"frames": expected a list of 1 to 600'),
    ("/api/export", {"frames": ["!!"], "fps": 10}, 400, r'"frames"\[0\]: not valid base64'),
    ("/api/export", {"frames": ["data:image/jpeg;base64,AAAA"], "fps": 10}, 400,
     "expected a data:image/png;base64 URL"),
    ("/api/export", {"frames": ["AAAA"], "fps": 0}, 400,
     r'"fps": expected a number in \[0.01, 100\]'),
    ("/api/export", {"frames": ["AAAA"], "fps": 10, "format": "mp4"}, 400,
     '"format": expected "gif"'),
])
def test_bad_requests_get_one_clear_line(srv, path, body, status, match):
    r = post_json(srv, path, body)
    assert r.status == status, r.body
    err = r.json()["error"]
    assert "\n" not in err
    assert re.search(match, err), err


def _png(color, size=(24, 16)):
    from PIL import Image

    buf = io.BytesIO()
    Image.new("RGB", size, color).save(buf, format="PNG")
    return base64.b64encode(buf.getvalue()).decode()


def test_export_writes_an_animated_gif(srv):
    from PIL import Image

    colors = [(255, 0, 0), (0, 255, 0), (0, 0, 255), (255, 255, 0)]
    frames = [_png(c) for c in colors]
    frames[1] = "data:image/png;base64," + frames[1]            # canvas.toDataURL() form
    r = post_json(srv, "/api/export", {"frames": frames, "fps": 10, "name": "spin.gif"})
    assert r.status == 200, r.body
    out = r.json()
    path = srv.pose_folder / "spin.gif"
    assert out == {"path": str(path), "name": "spin.gif", "frames": 4, "width": 24, "height": 16,
                   "fps": 10.0}
    with Image.open(path) as im:
        assert im.format == "GIF" and im.n_frames == 4 and im.size == (24, 16)
        seen = []
        for k in range(4):
            im.seek(k)
            seen.append(im.convert("RGB").getpixel((5, 5)))
            assert im.info["duration"] == 100
        assert im.info.get("loop") == 0
    assert seen == colors
    r = post_json(srv, "/api/export", {"frames": frames, "fps": 10, "name": "spin.gif"})
    assert r.status == 409
    r = post_json(srv, "/api/export", {"frames": [_png((0, 0, 0)), _png((0, 0, 0), (8, 8))],
                                       "fps": 10})
    assert r.status == 400 and "must have the size of frame 0 (24 x 16)" in r.json()["error"]


def test_export_without_pillow_says_what_to_install(srv, monkeypatch):
    import stbs._optional as opt

    real = opt.available
    monkeypatch.setattr(opt, "available", lambda m: False if m == "PIL" else real(m))
    r = post_json(srv, "/api/export", {"frames": [_png((1, 2, 3))], "fps": 10})
    assert r.status == 501
    assert r.json()["error"].startswith("exporting a GIF needs pillow, which is not installed")


def test_saving_is_refused_without_a_folder(nosave):
    for path, body in (("/api/save-clip", {"clip": CLIP}),
                       ("/api/export", {"frames": [_png((1, 2, 3))], "fps": 10})):
        r = post_json(nosave, path, body)
        assert r.status == 409 and "--save-as" in r.json()["error"]
    # sampling needs no folder
    assert post_json(nosave, "/api/clip/sample", CLIP).status == 200


def test_the_clip_routes_need_the_token_and_post(srv):
    body = json.dumps(CLIP)
    for path in ("/api/clip/sample", "/api/clip/pose", "/api/save-clip", "/api/export"):
        assert request(srv, "POST", path, body=body).status == 403
        assert request(srv, "POST", path, body=body, token="0" * 32).status == 403
        assert request(srv, "POST", path, body=body, token=True,
                       host="evil.example:80").status == 403
        r = request(srv, "GET", path, token=True)
        assert r.status == 405 and r.headers["allow"] == "POST"
    cid = post_json(srv, "/api/clip", CLIP).json()["id"]
    for path, allow in ((f"/api/clip/{cid}", "GET"), (f"/api/clip/{cid}/keys", "GET"),
                        (f"/api/clip/{cid}/frames?t=0", "GET"), (f"/api/clip/{cid}/pose", "POST")):
        for method in ("GET", "POST"):
            assert request(srv, method, path, body=body).status == 403
        other = "POST" if allow == "GET" else "GET"
        r = request(srv, other, path, token=True, body=body if other == "POST" else None)
        assert r.status == 405 and r.headers["allow"] == allow
    assert request(srv, "GET", f"/api/clip/{cid}x", token=True).status == 404


def test_seek_makes_the_clips_pose_current_and_answers_its_binary_bones(srv):
    sk = srv.rig.skeleton
    cid = post_json(srv, "/api/clip", CLIP).json()["id"]
    clip = stbs.io.read_clip(CLIP, sk)
    for t in (0.0, 0.5, 1.25, 7.0):
        r = post_json(srv, f"/api/clip/{cid}/seek", {"time": t})
        assert r.status == 200, r.body
        assert r.headers["content-type"] == "application/octet-stream"
        assert float(r.headers["x-stbs-time"]) == t
        rows = r.array()
        assert rows.shape == (sk.n_bones, 15)
        ref = clip.pose(t)
        R, O = rows[:, :9].reshape(-1, 3, 3), rows[:, 9:12]
        sigma, theta = rows[:, 12], rows[:, 13:15]
        for a, b in ((R, ref.rotations), (O, ref.origins), (sigma, ref.stretch),
                     (theta, ref.twist)):
            assert np.abs(a - b).max() < 1e-12
        assert np.abs(srv.pose.origins - ref.origins).max() < 1e-12
        # the pose file object of the current pose follows, made when asked for
        back = stbs.io.read_pose(request(srv, "GET", "/api/pose", token=True).json(), sk)
        assert np.abs(back.origins - ref.origins).max() < 1e-9
    # asked for JSON: the pose object and the bones in one answer
    r = request(srv, "POST", f"/api/clip/{cid}/seek", body=json.dumps({"time": 0.75}),
                token=True, headers={"Content-Type": "application/json",
                                     "Accept": "application/json"})
    assert r.status == 200 and r.headers["content-type"].startswith("application/json")
    got, ref = r.json(), clip.pose(0.75)
    assert got["time"] == 0.75
    assert np.abs(np.array(got["bones"]["origins"]) - ref.origins).max() < 1e-12
    assert np.abs(np.array(got["bones"]["rotations"]) - ref.rotations).max() < 1e-12
    assert np.abs(stbs.io.read_pose(got["pose"], sk).origins - ref.origins).max() < 1e-9
    before = srv.pose
    for body, status, words in (({"time": "x"}, 400, "finite number of seconds"),
                                ({}, 400, 'missing "time"'),
                                ({"time": 0, "at": 1}, 400, "unexpected key 'at'")):
        r = post_json(srv, f"/api/clip/{cid}/seek", body)
        assert r.status == status and words in r.json()["error"], r.body
    assert post_json(srv, "/api/clip/0123456789abcdef/seek", {"time": 0}).status == 404
    r = request(srv, "GET", f"/api/clip/{cid}/seek", token=True)
    assert r.status == 405 and r.headers["allow"] == "POST"
    assert srv.pose is before
