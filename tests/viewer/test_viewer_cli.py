"""``stbs view``: one URL line on stdout, a server that answers it, Ctrl-C exits 0 with one
line; bad inputs are one line on stderr and exit status 2. The server runs in a
subprocess (Ctrl-C is SIGINT), on 127.0.0.1 only, with bounded waits."""

from __future__ import annotations

import json
import re
import selectors
import signal
import socket
import subprocess
import sys

import numpy as np
import pytest
from viewer_client import bar_rig

import stbs
from stbs.cli import main
from stbs.io import load_rig, save_rig, write_mesh, write_tgf

URL = re.compile(r"^http://127\.0\.0\.1:(\d+)/\?token=([0-9a-f]{32,})$")
MAIN = "import sys; from stbs.cli import main; sys.exit(main())"
START_S = 120     # rigging an example or a mesh, and the imports, on two busy cores
STOP_S = 30


class View:
    """``stbs view ARGS --no-browser`` in a subprocess, stopped by SIGINT."""

    def __init__(self, *args, cwd):
        self.p = subprocess.Popen([sys.executable, "-c", MAIN, "view", "--no-browser",
                                   *map(str, args)], cwd=cwd, text=True,
                                  stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        with selectors.DefaultSelector() as sel:
            sel.register(self.p.stdout, selectors.EVENT_READ)
            ready = sel.select(timeout=START_S)
        if not ready:
            self.kill()
            pytest.fail(f"stbs view printed nothing in {START_S} s")
        self.line = self.p.stdout.readline()
        m = URL.match(self.line.rstrip("\n"))
        if m is None:
            out, err = self.kill()
            pytest.fail(f"not a URL line: {self.line!r}; stderr: {err!r}")
        self.port, self.token = int(m[1]), m[2]

    def get(self, path, *, method="GET", body=None, headers=None):
        import http.client

        c = http.client.HTTPConnection("127.0.0.1", self.port, timeout=10)
        try:
            c.request(method, path, body=body, headers={"X-Stbs-Token": self.token,
                                                        **(headers or {})})
            r = c.getresponse()
            return r.status, r.read()
        finally:
            c.close()

    def stop(self):
        """SIGINT (Ctrl-C); the exit status, the rest of stdout and stderr."""
        self.p.send_signal(signal.SIGINT)
        try:
            out, err = self.p.communicate(timeout=STOP_S)
        except subprocess.TimeoutExpired:
            self.kill()
            pytest.fail(f"stbs view did not stop in {STOP_S} s after SIGINT")
        return self.p.returncode, out, err

    def kill(self):
        self.p.kill()
        return self.p.communicate(timeout=STOP_S)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        if self.p.poll() is None:
            self.kill()


@pytest.fixture
def rig_file(tmp_path):
    rig = bar_rig()
    path = tmp_path / "bar.npz"
    save_rig(path, rig)
    return path


def test_view_rig_prints_one_url_serves_it_and_stops_on_ctrl_c(rig_file, tmp_path):
    before = rig_file.read_bytes()
    with View(rig_file, cwd=tmp_path) as v:
        status, body = v.get("/api/rig")
        info = json.loads(body)
        assert status == 200 and info["vertices"] == 74 and info["name"] == "bar"
        assert info["save"] == {"rig": True, "pose": True}
        status, body = v.get("/api/rig/W4.bin")
        W4 = np.frombuffer(body, dtype="<f4").reshape(74, 4)
        np.testing.assert_allclose(W4.sum(axis=1), 1, atol=1e-6)
        assert v.get("/api/rig", headers={"X-Stbs-Token": "0" * 32})[0] == 403
        # the rig is saved beside the input, never over it; poses into its folder
        status, body = v.get("/api/save-rig", method="POST")
        assert status == 200 and json.loads(body)["path"] == str(tmp_path / "bar-edited.npz")
        status, body = v.get("/api/save-pose", method="POST", body=b'{"stretch": {"0": 2}}')
        assert status == 200 and json.loads(body)["path"] == str(tmp_path / "bar-pose-001.json")
        code, out, err = v.stop()
    assert code == 0 and out == ""                       # the URL was the only line
    assert err == "stbs view: stopped\n"
    assert rig_file.read_bytes() == before
    np.testing.assert_array_equal(load_rig(tmp_path / "bar-edited.npz").W, bar_rig().W)
    with View(rig_file, cwd=tmp_path) as w:
        assert w.token != v.token                         # a new token each run
        w.stop()


def test_view_mesh_and_skeleton_rigs_first_and_saves_as_asked(tmp_path):
    rig = bar_rig()
    write_mesh(tmp_path / "bar.obj", rig.V, rig.F)
    write_tgf(tmp_path / "bar.tgf", rig.C, rig.BE)
    (tmp_path / "out").mkdir()
    with View(tmp_path / "bar.obj", tmp_path / "bar.tgf", "--bone", "heat", "--endpoint",
              "projection", "--save-as", tmp_path / "out" / "mine.npz", cwd=tmp_path) as v:
        info = json.loads(v.get("/api/rig")[1])
        assert info["vertices"] == 74 and info["bones"] == 2 and info["has_E"]
        # the rig it built is written before the URL; the page replaces it when it asks
        written = (tmp_path / "out" / "mine.npz").read_bytes()
        status, body = v.get("/api/save-rig", method="POST")
        assert status == 409 and "overwrite" in json.loads(body)["error"]
        assert (tmp_path / "out" / "mine.npz").read_bytes() == written
        status, body = v.get("/api/save-rig", method="POST", body=b'{"overwrite": true}')
        assert status == 200 and json.loads(body)["path"] == str(tmp_path / "out" / "mine.npz")
        status, body = v.get("/api/save-pose", method="POST", body=b"{}")
        assert json.loads(body)["path"] == str(tmp_path / "out" / "bar-pose-001.json")
        code, out, err = v.stop()
    assert code == 0 and out == ""
    # rigging progress on stderr (the pipeline's stages), then where the rig went
    assert "stbs rig: read mesh ..." in err and "stbs rig: bone heat ..." in err, err
    assert "bone heat: [###" in err and "3/3" in err, err
    assert f"stbs view: rig written to {tmp_path / 'out' / 'mine.npz'}" in err
    saved = load_rig(tmp_path / "out" / "mine.npz")
    assert saved.W.shape == (74, 2) and np.allclose(np.asarray(saved.W).sum(axis=1), 1)


def test_view_mesh_and_skeleton_never_replaces_a_rig_file_without_force(capsys, tmp_path):
    rig = bar_rig()
    write_mesh(tmp_path / "bar.obj", rig.V, rig.F)
    write_tgf(tmp_path / "bar.tgf", rig.C, rig.BE)
    (tmp_path / "bar.npz").write_bytes(b"mine")
    one_error(capsys, tmp_path / "bar.obj", tmp_path / "bar.tgf", "--bone", "heat",
              words=f"{str(tmp_path / 'bar.npz')!r} exists")
    code, out, err = run(capsys, tmp_path / "bar.obj", tmp_path / "bar.tgf")
    assert "--force" in err
    assert (tmp_path / "bar.npz").read_bytes() == b"mine"
    one_error(capsys, tmp_path / "bar.npz", "--force", words="--force applies to MESH SKELETON")
    with View(tmp_path / "bar.obj", tmp_path / "bar.tgf", "--bone", "heat", "--endpoint",
              "projection", "--force", cwd=tmp_path) as v:
        assert json.loads(v.get("/api/rig")[1])["vertices"] == 74
        code, out, _ = v.stop()
    assert code == 0 and load_rig(tmp_path / "bar.npz").W.shape == (74, 2)


def test_a_missing_page_bundle_is_one_line_saying_how_to_get_it(capsys, monkeypatch, rig_file,
                                                                tmp_path):
    import stbs.viewer.static

    empty = tmp_path / "static"
    empty.mkdir()
    monkeypatch.setattr(stbs.viewer.static, "STATIC_DIR", empty)
    one_error(capsys, rig_file, words="lacks the viewer's page")
    code, out, err = run(capsys, rig_file)
    assert "viewer.js" in err and "reinstall" in err and "make" in err
    monkeypatch.undo()
    assert stbs.viewer.static.page_missing() is None       # this checkout has its bundle


@pytest.mark.parametrize("args, name, b, extras", [
    ((), "arm", 3, set()),
    (("--example", "picture"), "picture", 10, {"UV", "texture"}),
])
def test_view_examples(tmp_path, args, name, b, extras):
    with View(*args, cwd=tmp_path) as v:
        info = json.loads(v.get("/api/rig")[1])
        assert info["name"] == name and info["bones"] == b and info["has_E"]
        assert extras <= set(info["arrays"])
        assert info["save"] == {"rig": False, "pose": False}      # no folder of its own
        assert v.get("/api/save-pose", method="POST", body=b"{}")[0] == 409
        if extras:
            uv = np.frombuffer(v.get("/api/rig/UV.bin")[1], "<f4").reshape(-1, 2)
            assert len(uv) == info["vertices"] and uv.min() >= 0 and uv.max() <= 1
        code, out, _ = v.stop()
    assert code == 0 and out == ""
    assert list(tmp_path.iterdir()) == []                           # nothing written


def _save_weights(v, W, E):
    body = np.concatenate([W.ravel(), E.ravel()]).astype("<f4").tobytes()
    return v.get("/api/save-rig", method="POST", body=body,
                 headers={"Content-Type": "application/octet-stream", "X-Stbs-Arrays": "W,E",
                          "X-Stbs-Dtype": "float32"})


def test_a_gltf_character_is_saved_as_gltf_with_its_painted_weights(shared_data, tmp_path):
    from stbs.io import read_rig

    glb = shared_data / "characters" / "gltf" / "CesiumMan.glb"
    before = glb.read_bytes()
    with View(glb, "--skin", "0", "--save-as", tmp_path / "painted.glb", cwd=tmp_path) as v:
        info = json.loads(v.get("/api/rig")[1])
        n, b = info["vertices"], info["bones"]
        assert info["save"] == {"rig": True, "pose": True}
        W = np.frombuffer(v.get("/api/rig/W.bin")[1], "<f4").reshape(n, b).copy()
        E = np.random.default_rng(3).uniform(0, 1, (n, b)).astype(np.float32)  # "painted"
        # a painted bone weight: the vertex's weights among its own bones, reversed
        k = int(np.argmax((W > 0).sum(axis=1)))
        on = np.flatnonzero(W[k])
        W[k, on] = W[k, on[::-1]]
        status, body = _save_weights(v, W, E)
        assert status == 200, body
        assert json.loads(body)["path"] == str(tmp_path / "painted.glb")
        v.stop()
    assert glb.read_bytes() == before
    back = read_rig(tmp_path / "painted.glb")
    Eb = back.E.toarray() if hasattr(back.E, "toarray") else np.asarray(back.E)
    Wb = back.W.toarray() if hasattr(back.W, "toarray") else np.asarray(back.W)
    assert len(on) > 1 and np.abs(Wb - W).max() < 1e-4          # quantised to 1/65535
    used = Wb > 0
    assert used.sum() >= n and np.abs(Eb[used] - E[used]).max() < 1e-6
    # without --save-as a glTF character is saved beside itself as CHAR-edited.glb
    (tmp_path / "c").mkdir()
    (tmp_path / "c" / "man.glb").write_bytes(before)
    with View(tmp_path / "c" / "man.glb", cwd=tmp_path) as v:
        status, body = v.get("/api/save-rig", method="POST")     # no endpoint weights yet
        assert status == 409 and "endpoint weights" in json.loads(body)["error"]
        status, body = _save_weights(v, W, E)
        assert status == 200 and json.loads(body)["path"] == str(tmp_path / "c" / "man-edited.glb")
        v.stop()


# ---------------------------------------------------------------- bad inputs
def run(capsys, *argv):
    code = main(["view", "--no-browser", *map(str, argv)])
    out, err = capsys.readouterr()
    return code, out, err


def one_error(capsys, *argv, words):
    code, out, err = run(capsys, *argv)
    assert code == 2 and out == "", (out, err)
    assert err.count("\n") == 1 and err.startswith("stbs view: error: "), err
    assert words in err, err


def test_bad_inputs_are_one_line_and_exit_2(capsys, rig_file, tmp_path):
    one_error(capsys, tmp_path / "missing.npz", words="not found")
    one_error(capsys, tmp_path / "mesh.obj", words="expected a rig (.npz, or a character .gltf")
    one_error(capsys, tmp_path / "missing.obj", tmp_path / "x.tgf", words="not found")
    one_error(capsys, rig_file, "--example", "arm", words="not both")
    one_error(capsys, rig_file, "--bone", "heat", words="--bone applies to MESH SKELETON")
    one_error(capsys, "--example", "arm", "--tol", "1e-3", words="--tol applies")
    one_error(capsys, rig_file, "--port", "70000", words="--port")
    one_error(capsys, rig_file, "--save-as", tmp_path / "x.txt",
              words="expected a rig file (.npz, .glb, .gltf)")
    one_error(capsys, rig_file, "--skin", "0", words="--skin applies to a character file")
    one_error(capsys, rig_file, "--mapping", tmp_path / "m.json",
              words="--mapping applies to --motion CAPTURE.bvh")
    one_error(capsys, rig_file, "--save-as", tmp_path / "no" / "x.npz", words="does not exist")
    one_error(capsys, "--example", "nope", words="invalid choice")
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip")
    one_error(capsys, bad, words="bad.npz")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.npz", "bar.npz"]


def test_a_taken_port_is_one_line(capsys, rig_file):
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen(1)
        port = s.getsockname()[1]
        one_error(capsys, rig_file, "--port", port, words=f"cannot listen on 127.0.0.1:{port}")


def test_bad_weights_in_a_rig_are_one_line(capsys, tmp_path):
    rig = bar_rig()
    W = np.asarray(rig.W).copy()
    W[5] = 0
    save_rig(tmp_path / "zero.npz", rig.replace(W=W))
    one_error(capsys, tmp_path / "zero.npz", words="row 5 sums to 0")


def test_help_and_the_command_list(capsys):
    code = main(["view", "--help"])
    out = capsys.readouterr().out
    assert code == 0 and "examples:" in out and "stbs view arm.npz" in out
    assert "skins it in a vertex shader with any of the four methods" in " ".join(out.split())
    assert main(["--help"]) == 0 and "view" in capsys.readouterr().out
    assert main([]) == 2 and "view" in capsys.readouterr().err


def test_building_the_parser_imports_neither_the_viewer_nor_numba():
    code = ("import sys; from stbs.cli import build_parser; build_parser(); "
            "print(sorted(m for m in ('stbs.viewer', 'numba', 'stbs.demo', 'http.server') "
            "if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120, check=True).stdout
    assert out.strip() == "[]"


def test_the_url_line_is_what_the_server_says(rig_file):
    from stbs.viewer import ViewerServer

    with ViewerServer(load_rig(rig_file)) as s:
        assert URL.match(s.url) and int(URL.match(s.url)[1]) == s.port
    assert stbs.viewer.HOST == "127.0.0.1"
