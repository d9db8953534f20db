"""stbs.viewer.ViewerServer: the page, the token, the Host rule, confined paths, the rig
API (arrays, pose, saves) and body limits, over real HTTP on 127.0.0.1 only."""

from __future__ import annotations

import json
import os
import re
import socket

import numpy as np
import pytest
import scipy.sparse as sp
from viewer_client import bar_rig, post_json, raw, request

import stbs
from stbs.io import load_rig, read_pose
from stbs.viewer import STATIC_DIR, RigPayload, ViewerServer, static_path

SECRET = "TOP SECRET: outside the static folder"


@pytest.fixture
def rig():
    return bar_rig()


@pytest.fixture
def srv(rig, tmp_path):
    poses = tmp_path / "poses"
    poses.mkdir()
    with ViewerServer(rig, rig_target=tmp_path / "saved.npz", pose_folder=poses,
                      name="bar") as s:
        yield s


@pytest.fixture
def jail(tmp_path):
    """A static folder with a page, a symlink inside it, and symlinks pointing out."""
    (tmp_path / "secret.txt").write_text(SECRET)
    (tmp_path / "outside").mkdir()
    (tmp_path / "outside" / "secret.txt").write_text(SECRET)
    d = tmp_path / "static"
    (d / "assets").mkdir(parents=True)
    (d / "index.html").write_text("<!doctype html><title>test page</title>")
    (d / "assets" / "app.js").write_text("console.log('app');")
    (d / ".hidden.js").write_text(SECRET)
    os.symlink(tmp_path / "secret.txt", d / "link.txt")
    os.symlink(tmp_path / "outside", d / "out")
    os.symlink(d / "assets" / "app.js", d / "alias.js")      # inside: allowed
    return d


# ---------------------------------------------------------------- binding and token
def test_binds_loopback_with_a_fresh_token_each_time(rig):
    with ViewerServer(rig) as a, ViewerServer(rig) as b:
        assert a.server_address[0] == "127.0.0.1" and b.server_address[0] == "127.0.0.1"
        assert a.port != b.port and a.token != b.token
        for s in (a, b):
            assert re.fullmatch(r"[0-9a-f]{32,}", s.token)
            assert re.fullmatch(rf"http://127\.0\.0\.1:{s.port}/\?token={s.token}", s.url)
            assert s._httpd.socket.getsockname()[0] == "127.0.0.1"


def test_a_given_port_is_used(rig):
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    with ViewerServer(rig, port=port) as s:
        assert s.port == port and request(s, "GET", "/").status == 200


def test_page_and_assets_need_no_token(srv):
    for path in ("/", f"/?token={srv.token}", "/static/index.html"):
        r = request(srv, "GET", path)
        assert r.status == 200 and r.headers["content-type"].startswith("text/html")
        page = r.body.decode()
        assert 'src="/static/viewer.js"' in page and "/api/rig" in page
        assert "frame-ancestors 'none'" in r.headers["content-security-policy"]
        assert r.headers["referrer-policy"] == "no-referrer"
    assert (STATIC_DIR / "index.html").is_file()


@pytest.mark.parametrize("path", ["/api/rig", "/api/rig/V.bin", "/api/pose", "/api/nothing",
                                  "/favicon.ico", "/index.html"])
def test_everything_else_needs_the_token(srv, path):
    r = request(srv, "GET", path)
    assert r.status == 403 and "token" in r.json()["error"]
    assert request(srv, "GET", path, token="0" * 32).status == 403
    assert request(srv, "GET", path, token=srv.token[:-1]).status == 403
    assert request(srv, "GET", f"{path}?token={srv.token.upper()}").status == 403
    with_token = request(srv, "GET", path, token=True).status
    assert with_token == request(srv, "GET", f"{path}?token={srv.token}").status
    assert with_token == (404 if path in ("/api/nothing", "/favicon.ico", "/index.html")
                          else 200)


def test_token_by_query_and_by_header(srv):
    assert request(srv, "GET", f"/api/rig?token={srv.token}").status == 200
    assert request(srv, "GET", f"/api/rig?x=1&token={srv.token}").status == 200
    assert request(srv, "GET", "/api/rig", token=True).status == 200
    # two tokens in the query, or a right query with a wrong header: refused
    assert request(srv, "GET", f"/api/rig?token={srv.token}&token={srv.token}").status == 403
    assert request(srv, "GET", f"/api/rig?token={srv.token}", token="f" * 32).status == 403
    assert request(srv, "POST", "/api/pose", body="{}").status == 403


@pytest.mark.parametrize("host", ["evil.example:{port}", "127.0.0.1:{other}",
                                  "localhost:{other}", "127.0.0.1", "localhost", "",
                                  "127.0.0.1:{port}.evil.example", "[::1]:{port}",
                                  "127.0.0.2:{port}", "evil.example"])
def test_a_foreign_host_is_refused(srv, host):
    host = host.format(port=srv.port, other=srv.port + 1 if srv.port < 65535 else 1)
    for path in ("/", "/static/index.html", f"/api/rig?token={srv.token}"):
        r = request(srv, "GET", path, host=host)
        assert r.status == 403 and "Host" in r.json()["error"]
        assert b"not built" not in r.body and b"vertices" not in r.body


def test_localhost_is_this_host_too(srv):
    assert request(srv, "GET", "/", host=f"localhost:{srv.port}").status == 200
    assert request(srv, "GET", "/api/rig", token=True, host=f"LocalHost:{srv.port}").status == 200


def test_two_host_headers_are_refused(srv):
    head = (f"GET /api/rig?token={srv.token} HTTP/1.1\r\nHost: 127.0.0.1:{srv.port}\r\n"
            f"Host: evil.example\r\nConnection: close\r\n\r\n").encode()
    assert raw(srv, head).startswith(b"HTTP/1.1 403")


def test_a_foreign_origin_is_refused(srv):
    r = request(srv, "GET", "/api/rig", token=True, headers={"Origin": "http://evil.example"})
    assert r.status == 403 and "Origin" in r.json()["error"]
    assert request(srv, "GET", "/api/rig", token=True, headers={"Origin": "null"}).status == 403
    ok = {"Origin": f"http://127.0.0.1:{srv.port}"}
    assert request(srv, "GET", "/api/rig", token=True, headers=ok).status == 200


# ---------------------------------------------------------------- confined paths
TRAVERSALS = ["/static/../server.py", "/static/%2e%2e/server.py", "/static/%2E%2E/server.py",
              "/static/..%2fserver.py", "/static/..%2Fserver.py", "/static/%252e%252e/server.py",
              "/static/..\\server.py", "/static/.%2e/server.py", "/static/%2e./server.py",
              "/static/..%5cserver.py", "/static//etc/passwd", "/static/%2fetc%2fpasswd",
              "/static/./index.html", "/static/", "/static/index.html/", "/static/a/../server.py",
              "/static/..", "/static/index.html%00.js", "/static/~/server.py",
              "/static/%c0%ae%c0%ae/server.py", "/static/../../../../etc/passwd"]


@pytest.mark.parametrize("path", TRAVERSALS)
def test_the_package_static_folder_is_confined(srv, path):
    r = request(srv, "GET", path)
    assert r.status in (403, 404)
    assert b"ViewerServer" not in r.body and b"root:" not in r.body
    r = request(srv, "GET", path, token=True)     # the token opens no more files
    assert r.status in (403, 404) and b"ViewerServer" not in r.body


@pytest.mark.parametrize("path", [*TRAVERSALS, "/static/link.txt", "/static/out/secret.txt",
                                  "/static/.hidden.js", "/static/../secret.txt",
                                  "/static/%2e%2e/secret.txt", "/static/..%2fsecret.txt",
                                  "/static/%252e%252e/secret.txt", "/static/..\\secret.txt",
                                  "/static/assets/../../secret.txt", "/static/out"])
def test_symlinks_out_and_traversals_never_show_outside_content(rig, jail, path):
    with ViewerServer(rig, static_dir=jail) as s:
        for token in (False, True):
            r = request(s, "GET", path, token=token)
            assert r.status in (403, 404), path
            assert SECRET.encode() not in r.body


def test_files_inside_the_static_folder_are_served(rig, jail):
    with ViewerServer(rig, static_dir=jail) as s:
        r = request(s, "GET", "/")
        assert r.status == 200 and b"test page" in r.body
        r = request(s, "GET", "/static/assets/app.js")
        assert r.status == 200 and r.body == b"console.log('app');"
        assert r.headers["content-type"].startswith("text/javascript")
        assert r.headers["x-content-type-options"] == "nosniff"
        assert request(s, "GET", "/static/alias.js").body == r.body     # a symlink inside
        assert request(s, "GET", "/static/assets/missing.js").status == 404


def test_static_path_refuses_what_is_not_a_plain_file(jail):
    assert static_path(jail, "assets/app.js") == (jail / "assets" / "app.js").resolve()
    for rel in ("../secret.txt", "link.txt", "out/secret.txt", "assets", "", "assets/",
                ".hidden.js", "assets//app.js", "assets\\app.js", "%2e%2e/secret.txt",
                "assets/./app.js", "index.html\x00", "/etc/passwd"):
        assert static_path(jail, rel) is None, rel


def test_a_nul_byte_in_the_path_is_not_found(srv):
    reply = raw(srv, f"GET /static/index.html\x00 HTTP/1.1\r\nHost: 127.0.0.1:{srv.port}\r\n"
                     "Connection: close\r\n\r\n".encode())
    assert reply.split(b"\r\n", 1)[0].split(b" ")[1] in (b"400", b"404")
    assert b"not built" not in reply


# ---------------------------------------------------------------- methods
@pytest.mark.parametrize("method", ["PUT", "DELETE", "PATCH", "HEAD", "OPTIONS", "TRACE",
                                    "FROB"])
def test_methods_other_than_get_and_post_are_405(srv, method):
    for path in ("/", "/api/pose", "/api/nothing"):
        r = request(srv, method, path, token=True)
        assert r.status == 405 and r.headers["allow"] == "GET, POST"


def test_each_route_takes_its_methods(srv):
    assert request(srv, "POST", "/", body="x").status == 405
    assert request(srv, "POST", "/static/index.html", body="x").status == 405
    assert request(srv, "GET", "/api/save-pose", token=True).status == 405
    assert request(srv, "GET", "/api/save-rig", token=True).status == 405
    r = request(srv, "POST", "/api/rig", body="{}", token=True)
    assert r.status == 405 and r.headers["allow"] == "GET"
    assert request(srv, "GET", "/api/rig/", token=True).status == 404
    assert request(srv, "GET", "/api/rig/V.bin/", token=True).status == 404
    assert request(srv, "GET", "/api/rig/nope.bin", token=True).status == 404
    assert request(srv, "GET", "/api/rig/T.bin", token=True).status == 404    # no tets


# ---------------------------------------------------------------- the rig
def test_rig_summary(srv, rig):
    info = request(srv, "GET", "/api/rig", token=True).json()
    sk = rig.skeleton
    assert info["vertices"] == len(rig.V) and info["bones"] == sk.n_bones == 2
    assert info["dim"] == 3 and info["names"] == ["upper", "lower"]
    assert info["methods"] == list(stbs.METHODS) and info["parents"] == [-1, 0]
    assert info["has_E"] is True and info["faces"] == len(rig.F) and info["tets"] == 0
    assert info["name"] == "bar" and info["save"] == {"rig": True, "pose": True}
    assert set(info["arrays"]) == {"V", "F", "C", "BE", "P", "I4", "W4", "E4", "W", "E"}


def arrays(s) -> dict:
    info = request(s, "GET", "/api/rig", token=True).json()
    out = {}
    for name, spec in info["arrays"].items():
        r = request(s, "GET", spec["url"], token=True)
        assert r.status == 200 and r.headers["content-type"] == "application/octet-stream"
        a = r.array()
        assert [a.dtype.name, list(a.shape)] == [spec["dtype"], spec["shape"]]
        assert len(r.body) == a.nbytes
        out[name] = a
    return out


def scatter(I4, W4, b):
    n = len(I4)
    M = np.zeros((n, b))
    np.add.at(M, (np.repeat(np.arange(n), 4), I4.ravel().astype(int)), W4.ravel())
    return M


def test_binary_arrays_round_trip(srv, rig):
    a = arrays(srv)
    np.testing.assert_array_equal(a["V"], rig.V.astype(np.float32))
    np.testing.assert_array_equal(a["F"], rig.F)
    np.testing.assert_array_equal(a["C"], rig.C.astype(np.float32))
    np.testing.assert_array_equal(a["BE"], rig.BE)
    np.testing.assert_array_equal(a["P"], rig.skeleton.parents)
    np.testing.assert_array_equal(a["W"], np.asarray(rig.W, dtype=np.float32))
    np.testing.assert_array_equal(a["E"], np.asarray(rig.E, dtype=np.float32))
    assert a["I4"].dtype == np.uint16 and a["W4"].dtype == a["E4"].dtype == np.float32
    np.testing.assert_allclose(a["W4"].sum(axis=1), 1.0, atol=1e-6)
    # at most 2 bones per vertex: the top 4 are all of W, and E at the same pairs
    np.testing.assert_allclose(scatter(a["I4"], a["W4"], 2), rig.W, atol=1e-7)
    rows = np.repeat(np.arange(len(rig.V))[:, None], 4, axis=1)
    E_at = np.asarray(rig.E)[rows, a["I4"].astype(int)]
    np.testing.assert_allclose(np.where(a["W4"] > 0, a["E4"], 0), np.where(a["W4"] > 0, E_at, 0),
                               atol=1e-7)
    # heaviest first
    assert (np.diff(a["W4"], axis=1) <= 0).all()


def test_top4_of_more_bones_keeps_the_heaviest_renormalised():
    rng = np.random.default_rng(7)
    n, b = 40, 7
    C = np.c_[np.arange(b + 1), np.zeros(b + 1), np.zeros(b + 1)].astype(float)
    BE = np.c_[np.arange(b), np.arange(1, b + 1)]
    V = rng.uniform(0, b, (n, 3))
    W = rng.uniform(0, 1, (n, b)) ** 3
    W /= W.sum(axis=1, keepdims=True)
    E = rng.uniform(0, 1, (n, b))
    for Wx in (W, sp.csr_array(W)):
        rig = stbs.Rig(V=V, C=C, BE=BE, W=Wx, E=E)
        with ViewerServer(rig) as s:
            a = arrays(s)
        order = np.argsort(-W, axis=1, kind="stable")[:, :4]
        top = np.take_along_axis(W, order, axis=1)
        np.testing.assert_array_equal(a["I4"], order)
        np.testing.assert_allclose(a["W4"], top / top.sum(axis=1, keepdims=True), atol=1e-7)
        np.testing.assert_allclose(a["W4"].sum(axis=1), 1.0, atol=1e-6)
        np.testing.assert_allclose(a["E4"], np.take_along_axis(E, order, axis=1), atol=1e-7)
        assert "F" not in a and "T" not in a


def test_a_rig_without_E_serves_projection_endpoint_weights():
    rig = bar_rig(with_E=False)
    with ViewerServer(rig) as s:
        assert request(s, "GET", "/api/rig", token=True).json()["has_E"] is False
        E = request(s, "GET", "/api/rig/E.bin", token=True).array()
    want = stbs.endpoint_weights(rig.V, rig.skeleton, method="projection")
    np.testing.assert_allclose(E, want, atol=1e-7)


def test_a_tetrahedral_rig_serves_its_boundary_as_faces():
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1.0]])
    T = np.array([[0, 1, 2, 3], [1, 2, 3, 4]])
    rig = stbs.Rig(V=V, T=T, C=[[0, 0, 0], [1, 1, 1]], BE=[[0, 1]], W=np.ones((5, 1)))
    with ViewerServer(rig) as s:
        info = request(s, "GET", "/api/rig", token=True).json()
        a = arrays(s)
    assert info["tets"] == 2 and info["faces"] == 6 and info["faces_from"] == "tets"
    np.testing.assert_array_equal(a["T"], T)
    np.testing.assert_array_equal(a["F"], stbs.geometry.boundary_faces(T, V))
    np.testing.assert_array_equal(a["W4"], np.tile([1, 0, 0, 0], (5, 1)))


def test_a_2d_rig_with_extras():
    rig = stbs.Rig(V=[[0, 0.1], [1, 0.1], [1, -0.1]], F=[[0, 2, 1]], C=[[0, 0], [1, 0]],
                   BE=[[0, 1]], W=np.ones((3, 1)))
    uv = np.array([[0, 0], [1, 0], [1, 1]], dtype=np.float32)
    tex = np.arange(2 * 2 * 4, dtype=np.uint8).reshape(2, 2, 4)
    with ViewerServer(rig, extras={"UV": uv, "texture": tex}) as s:
        a = arrays(s)
    assert a["V"].shape == (3, 2) and a["C"].shape == (2, 2)
    np.testing.assert_array_equal(a["UV"], uv)
    np.testing.assert_array_equal(a["texture"], tex)


@pytest.mark.parametrize("extras", [{"V": np.zeros(3, np.float32)}, {"a/b": np.zeros(3)},
                                    {"X": np.zeros(3)}, {"X": np.zeros(3, np.int64)}])
def test_bad_extras_are_refused(rig, extras):
    with pytest.raises(ValueError, match="extras"):
        RigPayload(rig, extras=extras)


def test_weights_no_skinning_takes_are_refused(rig):
    W = np.asarray(rig.W).copy()
    W[3] = 0
    with pytest.raises(ValueError, match="row 3 sums to 0"):
        ViewerServer(rig.replace(W=W))
    W[3] = [1.5, -0.5]
    with pytest.raises(ValueError, match="W must be >= 0"):
        ViewerServer(rig.replace(W=W))
    with pytest.raises(ValueError, match=r"E must lie in \[0, 1\]"):
        ViewerServer(rig.replace(E=np.asarray(rig.E) + 1))


@pytest.mark.parametrize("kw", [dict(port=-1), dict(port=65536), dict(port=True),
                                dict(port="80"), dict(max_body=-1),
                                dict(rig_target="out.txt"), dict(rig_target="/nonexistent/x.npz"),
                                dict(pose_folder="/nonexistent-folder")])
def test_bad_options_are_value_errors(rig, kw):
    with pytest.raises(ValueError):
        ViewerServer(rig, **kw)


def test_a_taken_port_is_an_os_error(rig):
    with ViewerServer(rig) as s, pytest.raises(OSError):
        ViewerServer(rig, port=s.port)


# ---------------------------------------------------------------- the pose
def test_pose_get_and_post(srv, rig):
    assert request(srv, "GET", "/api/pose", token=True).json() == {"degrees": True}
    pose = {"rotate": {"1": {"axis": [0, 0, 1], "angle": 60}}, "stretch": {"upper": 1.5},
            "twist": {"upper": [0, 90]}}
    r = post_json(srv, "/api/pose", pose)
    assert r.status == 200
    back = r.json()["pose"]
    assert back == request(srv, "GET", "/api/pose", token=True).json()
    want = read_pose(pose, rig.skeleton)
    got = read_pose(back, rig.skeleton)
    np.testing.assert_allclose(got.rotations, want.rotations, atol=1e-12)
    np.testing.assert_allclose(got.stretch, want.stretch)
    np.testing.assert_allclose(got.twist, want.twist, atol=1e-12)
    assert srv.pose is not None and np.allclose(srv.pose.stretch, [1.5, 1])
    joints = {"joints": rig.C.tolist()}
    assert post_json(srv, "/api/pose", joints).status == 200


@pytest.mark.parametrize("body, words", [
    ({"stretch": {"9": 1.5}}, "does not exist"),
    ({"stretch": {"upper": -1}}, "stretch must be > 0"),
    ({"rotate": {"upper": {"axis": [0, 0, 0], "angle": 1}}}, "non-zero axis"),
    ({"frobnicate": 1}, "unknown key"),
    ({"joints": [[0, 0, 0]]}, "expected 3 posed joint positions"),
    ([1, 2], "expected a JSON object"),
    ("{not json", "not valid JSON"),
    (b"\xff\xfe{}", "UTF-8"),
    ('{"stretch": {"upper": NaN}}', "finite"),
    ("[" * 100000 + "]" * 100000, "JSON"),
])
def test_a_bad_pose_is_400_with_one_line(srv, body, words):
    before = request(srv, "GET", "/api/pose", token=True).json()
    data = body if isinstance(body, (str, bytes)) else json.dumps(body)
    r = request(srv, "POST", "/api/pose", body=data, token=True)
    assert r.status == 400
    msg = r.json()["error"]
    assert words in msg and "\n" not in msg
    assert request(srv, "GET", "/api/pose", token=True).json() == before


# ---------------------------------------------------------------- saving poses
def listing(folder):
    return sorted(p.name for p in folder.iterdir())


def test_save_pose_writes_atomically_into_its_folder(srv, rig, tmp_path):
    folder = tmp_path / "poses"
    pose = {"stretch": {"lower": 2.0}}
    r = post_json(srv, "/api/save-pose", pose)
    assert r.status == 200 and r.json()["name"] == "bar-pose-001.json"
    assert post_json(srv, "/api/save-pose", {"pose": {}}).json()["name"] == "bar-pose-002.json"
    r = post_json(srv, "/api/save-pose", {"pose": pose, "name": "wave.json"})
    assert r.status == 200 and r.json()["path"] == str(folder / "wave.json")
    assert listing(folder) == ["bar-pose-001.json", "bar-pose-002.json", "wave.json"]
    back = read_pose(folder / "wave.json", rig.skeleton)
    np.testing.assert_allclose(back.stretch, [1, 2])
    # an existing file is replaced only when asked
    r = post_json(srv, "/api/save-pose", {"pose": {}, "name": "wave.json"})
    assert r.status == 409 and "overwrite" in r.json()["error"]
    r = post_json(srv, "/api/save-pose", {"pose": {}, "name": "wave.json", "overwrite": True})
    assert r.status == 200
    np.testing.assert_allclose(read_pose(folder / "wave.json", rig.skeleton).stretch, [1, 1])
    assert listing(folder) == ["bar-pose-001.json", "bar-pose-002.json", "wave.json"]  # no temp


@pytest.mark.parametrize("name", ["../escape.json", "ABSOLUTE", "sub/escape.json",
                                  "..\\escape.json", ".escape.json", "escape.txt", "escape",
                                  "escape.json/", "escape.json\x00", "%2e%2e%2fescape.json",
                                  "..", "", " escape.json", "x" * 200 + ".json", 7, None, True])
def test_save_pose_refuses_names_that_leave_its_folder(srv, tmp_path, name):
    (tmp_path / "poses" / "sub").mkdir()
    if name == "ABSOLUTE":
        name = str(tmp_path / "escape.json")
    before = sorted(str(p) for p in tmp_path.rglob("*"))
    body = {"pose": {}, "name": name}
    if name is None:
        body = {"pose": {}, "name": "ok.json", "folder": "/tmp"}
    r = post_json(srv, "/api/save-pose", body)
    assert r.status == 400 and "\n" not in r.json()["error"]
    assert sorted(str(p) for p in tmp_path.rglob("*")) == before


def test_save_pose_does_not_write_through_a_symlink(srv, tmp_path):
    outside = tmp_path / "outside.json"
    outside.write_text("{}")
    os.symlink(outside, tmp_path / "poses" / "link.json")
    for overwrite in (False, True):
        r = post_json(srv, "/api/save-pose", {"pose": {"stretch": {"0": 3}}, "name": "link.json",
                                              "overwrite": overwrite})
        assert r.status == 403
    assert outside.read_text() == "{}" and os.path.islink(tmp_path / "poses" / "link.json")


def test_save_pose_bad_pose_and_no_folder(srv, rig):
    r = post_json(srv, "/api/save-pose", {"pose": {"stretch": {"9": 1}}, "name": "x.json"})
    assert r.status == 400 and "does not exist" in r.json()["error"]
    assert post_json(srv, "/api/save-pose", {"pose": {}, "nam": "x.json"}).status == 400
    with ViewerServer(rig) as s:
        r = post_json(s, "/api/save-pose", {})
        assert r.status == 409 and "--save-as" in r.json()["error"]
        r = post_json(s, "/api/save-rig", {})
        assert r.status == 409 and "--save-as" in r.json()["error"]


# ---------------------------------------------------------------- saving the rig
def same_rig(a, b):
    np.testing.assert_array_equal(a.V, b.V)
    np.testing.assert_array_equal(a.F, b.F)
    np.testing.assert_array_equal(np.asarray(a.W), np.asarray(b.W))
    np.testing.assert_array_equal(np.asarray(a.E), np.asarray(b.E))
    assert a.skeleton == b.skeleton


def test_save_rig_as_it_is(srv, rig, tmp_path):
    r = request(srv, "POST", "/api/save-rig", token=True)
    assert r.status == 200 and r.json()["path"] == str(tmp_path / "saved.npz")
    same_rig(load_rig(tmp_path / "saved.npz"), rig)
    assert not [p for p in tmp_path.iterdir() if ".tmp" in p.name]


def test_save_rig_with_new_weights_as_json_and_binary(srv, rig, tmp_path):
    W = np.asarray(rig.W)[:, ::-1].copy()
    E = 1 - np.asarray(rig.E)
    r = post_json(srv, "/api/save-rig", {"W": W.tolist(), "E": E.tolist()})
    assert r.status == 200
    saved = load_rig(tmp_path / "saved.npz")
    np.testing.assert_array_equal(saved.W, W)
    np.testing.assert_array_equal(saved.E, E)
    # what the page downloads now is the new rig
    got = request(srv, "GET", "/api/rig/W.bin", token=True).array()
    np.testing.assert_array_equal(got, W.astype(np.float32))
    W2 = np.asarray(rig.W).astype(np.float32)
    raw_W = {"Content-Type": "application/octet-stream", "X-Stbs-Arrays": "W",
             "X-Stbs-Dtype": "float32"}
    before = (tmp_path / "saved.npz").read_bytes()
    # the file exists now: replaced only when the request says so
    r = request(srv, "POST", "/api/save-rig", body=W2.astype("<f4").tobytes(), token=True,
                headers=raw_W)
    assert r.status == 409 and "X-Stbs-Overwrite: true" in r.json()["error"]
    r = post_json(srv, "/api/save-rig", {"W": W2.tolist()})
    assert r.status == 409 and '"overwrite": true' in r.json()["error"]
    assert (tmp_path / "saved.npz").read_bytes() == before
    np.testing.assert_array_equal(request(srv, "GET", "/api/rig/W.bin", token=True).array(),
                                  W.astype(np.float32))     # a refused save changes nothing
    r = request(srv, "POST", "/api/save-rig", body=W2.astype("<f4").tobytes(), token=True,
                headers={**raw_W, "X-Stbs-Overwrite": "yes"})
    assert r.status == 400 and "X-Stbs-Overwrite" in r.json()["error"]
    r = request(srv, "POST", "/api/save-rig", body=W2.astype("<f4").tobytes(), token=True,
                headers={**raw_W, "X-Stbs-Overwrite": "true"})
    assert r.status == 200, r.body
    saved = load_rig(tmp_path / "saved.npz")
    np.testing.assert_array_equal(saved.W, W2.astype(np.float64))
    np.testing.assert_array_equal(saved.E, E)          # E kept from the last save
    both = np.stack([np.asarray(rig.W), np.asarray(rig.E)]).astype("<f8").tobytes()
    r = request(srv, "POST", "/api/save-rig", body=both, token=True,
                headers={"Content-Type": "application/octet-stream", "X-Stbs-Arrays": "W,E",
                         "X-Stbs-Dtype": "float64", "X-Stbs-Overwrite": "true"})
    assert r.status == 200
    same_rig(load_rig(tmp_path / "saved.npz"), rig)
    assert post_json(srv, "/api/save-rig", {"overwrite": True}).status == 200
    assert post_json(srv, "/api/save-rig", {"overwrite": 1}).status == 400


def test_save_rig_refuses_bad_weights(srv, rig, tmp_path):
    n, b = np.asarray(rig.W).shape
    W = np.asarray(rig.W)
    bad = [({"W": W[:-1].tolist()}, "shape"), ({"W": (W * 2).tolist()}, "sum to 1"),
           ({"W": (-W).tolist()}, "[0, inf)"), ({"E": (W + 1).tolist()}, "[0, 1]"),
           ({"W": [["a"] * b] * n}, "numbers"), ({"X": 1}, "expected a JSON object"),
           ([1], "expected a JSON object")]
    for body, words in bad:
        r = post_json(srv, "/api/save-rig", body)
        assert r.status == 400 and words in r.json()["error"], (body, r.body)
    octet = {"Content-Type": "application/octet-stream"}
    for headers, data in [({}, b"\0" * 12), ({"X-Stbs-Arrays": "Q"}, b""),
                          ({"X-Stbs-Arrays": "W,W"}, b""), ({"X-Stbs-Dtype": "int8"}, b"")]:
        r = request(srv, "POST", "/api/save-rig", body=data, token=True,
                    headers={**octet, **headers})
        assert r.status == 400
    assert not (tmp_path / "saved.npz").exists()
    assert request(srv, "GET", "/api/rig/W.bin", token=True).array().shape == (n, b)


# ---------------------------------------------------------------- bodies
def test_body_limits(rig):
    with ViewerServer(rig, max_body=1000) as s:
        r = request(s, "POST", "/api/pose", body=b" " * 1001 + b"{}", token=True)
        assert r.status == 413
        assert request(s, "POST", "/api/pose", body=b" " * 900 + b"{}", token=True).status == 200
        chunked = (f"POST /api/pose HTTP/1.1\r\nHost: 127.0.0.1:{s.port}\r\n"
                   f"X-Stbs-Token: {s.token}\r\nTransfer-Encoding: chunked\r\n\r\n"
                   "2\r\n{}\r\n0\r\n\r\n").encode()
        assert raw(s, chunked).startswith(b"HTTP/1.1 411")
        bad_length = (f"POST /api/pose HTTP/1.1\r\nHost: 127.0.0.1:{s.port}\r\n"
                      f"X-Stbs-Token: {s.token}\r\nContent-Length: -5\r\n\r\n{{}}").encode()
        assert raw(s, bad_length).startswith(b"HTTP/1.1 400")
        short = (f"POST /api/pose HTTP/1.1\r\nHost: 127.0.0.1:{s.port}\r\n"
                 f"X-Stbs-Token: {s.token}\r\nContent-Length: 50\r\n\r\n{{}}").encode()
        assert raw(s, short).startswith(b"HTTP/1.1 400")
    assert ViewerServer.__init__.__kwdefaults__["max_body"] == 64 * 1024 * 1024


def test_keep_alive_survives_a_refused_body(srv):
    import http.client

    c = http.client.HTTPConnection("127.0.0.1", srv.port, timeout=10)
    try:
        c.request("POST", "/api/pose", body=b'{"x": 1}')            # no token: 403
        r = c.getresponse()
        r.read()
        assert r.status == 403
        if r.will_close:
            c.close()
        c.request("GET", "/api/pose", headers={"X-Stbs-Token": srv.token})
        r = c.getresponse()
        assert r.status == 200 and json.loads(r.read()) == {"degrees": True}
    finally:
        c.close()


# ---------------------------------------------------------------- stopping
def test_shutdown_stops_and_releases_the_port(rig):
    s = ViewerServer(rig).start()
    port = s.port
    assert request(s, "GET", "/").status == 200
    s.shutdown()
    s.shutdown()                                   # twice is fine
    with pytest.raises(OSError):
        socket.create_connection(("127.0.0.1", port), timeout=2).close()
    ViewerServer(rig).shutdown()                   # never started: returns at once
