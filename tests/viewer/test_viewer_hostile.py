"""The viewer's server under hostile requests: the work a request may ask for is bounded
before it is done, the body's framing is unambiguous, bursts of connections are held,
every bad body on every POST route is a one-line 400 (never a 500, nothing on stderr),
and no save writes over a file the viewer reads."""

from __future__ import annotations

import base64
import errno
import io
import json
import os
import select
import socket
import struct
import threading
import time
import weakref
import zlib
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
from viewer_client import TIMEOUT, bar_rig, post_json, raw, request

import stbs
from stbs._inputs import inputs, note_input, tracking
from stbs.viewer import ViewerServer, clips
from stbs.viewer import handler as handler_module
from work_count import Lines

KEYS = [
    {"time": 0.0, "pose": {}},
    {"time": 1.0, "pose": {"rotate": {"upper": {"axis": [0, 0, 1], "angle": 90}},
                           "stretch": {"lower": 2.0}}},
]
CLIP = {"fps": 4, "interpolation": "linear", "keys": KEYS}


@pytest.fixture
def srv(tmp_path):
    folder = tmp_path / "poses"
    folder.mkdir()
    with ViewerServer(bar_rig(), rig_target=tmp_path / "saved.npz", pose_folder=folder,
                      name="bar") as s:
        yield s


def error(r) -> str:
    """The one-line message of a refusal."""
    assert r.headers["content-type"] == "application/json", r.body
    body = r.json()
    assert body["status"] == r.status and isinstance(body["error"], str), body
    assert "\n" not in body["error"] and body["error"]
    return body["error"]


def status_line(reply: bytes) -> bytes:
    return reply.split(b"\r\n", 1)[0]


def chain_rig(b: int) -> stbs.Rig:
    """A planar chain of ``b`` bones, a triangle on each, each vertex on its bone only."""
    C = np.c_[np.arange(b + 1.0), np.zeros(b + 1)]
    BE = np.c_[np.arange(b), np.arange(1, b + 1)]
    V = np.concatenate([[[i + 0.2, 0.0], [i + 0.8, 0.1], [i + 0.8, -0.1]] for i in range(b)])
    F = np.arange(3 * b).reshape(b, 3)[:, [0, 2, 1]]
    W = np.repeat(np.eye(b), 3, axis=0)
    return stbs.Rig(V=V, F=F, C=C, BE=BE, W=W)


# ---------------------------------------------------------------- export pixels
PNG = b"\x89PNG\r\n\x1a\n"


def header_only_png(w: int, h: int) -> str:
    """A PNG signature and an IHDR chunk claiming w x h pixels, and nothing more."""
    ihdr = struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)
    chunk = struct.pack(">I", 13) + b"IHDR" + ihdr + struct.pack(">I", zlib.crc32(b"IHDR" + ihdr))
    return base64.b64encode(PNG + chunk).decode()


def png(color, size=(24, 16)) -> str:
    from PIL import Image

    buf = io.BytesIO()
    Image.new("RGB", size, color).save(buf, format="PNG")
    return base64.b64encode(buf.getvalue()).decode()


def test_export_pixels_are_bounded_from_the_png_headers_before_any_decoding(srv, monkeypatch):
    from PIL import Image

    opened = []
    real_open = Image.open
    monkeypatch.setattr(Image, "open", lambda *a, **k: opened.append(1) or real_open(*a, **k))
    big = header_only_png(2048, 2048)
    assert clips.MAX_EXPORT_TOTAL_PIXELS == 2**28 and clips.MAX_EXPORT_PIXELS == 2048 * 2048
    r = post_json(srv, "/api/export", {"frames": [big] * 600, "fps": 30})
    assert r.status == 413
    assert ('"frames": 600 frames of 2048 x 2048 = 2516582400 pixels; the limit is 268435456 '
            "pixels an export (at most 64 frames of this size)") == error(r)
    r = post_json(srv, "/api/export", {"frames": [big] * 65, "fps": 30})
    assert r.status == 413 and "65 frames of 2048 x 2048" in error(r)
    r = post_json(srv, "/api/export", {"frames": [header_only_png(4096, 4096)], "fps": 30})
    assert r.status == 413
    assert error(r) == ('"frames"[0]: 4096 x 4096 = 16777216 pixels; the limit is 4194304 '
                        "pixels a frame")
    r = post_json(srv, "/api/export", {"frames": [header_only_png(8, 8)] * 601, "fps": 30})
    assert r.status == 413 and "601 frames; the limit is 600" in error(r)
    r = post_json(srv, "/api/export", {"frames": [png((1, 2, 3)), header_only_png(8, 8)],
                                       "fps": 30})
    assert r.status == 400 and "must have the size of frame 0 (24 x 16)" in error(r)
    assert opened == []                                 # all of it from the headers
    assert list(srv.pose_folder.iterdir()) == []


def test_export_decodes_one_frame_at_a_time(srv, monkeypatch):
    from PIL import Image

    made: list[weakref.ref] = []            # the frames decoded, while they live
    most = [0]
    real_convert = Image.Image.convert

    def convert(self, mode=None, *a, **k):
        out = real_convert(self, mode, *a, **k)
        if mode == "RGB":
            made.append(weakref.ref(out))
            most[0] = max(most[0], sum(m() is not None for m in made))
        return out

    monkeypatch.setattr(Image.Image, "convert", convert)
    colors = [(20 * k, 255 - 20 * k, 7 * k) for k in range(12)]
    r = post_json(srv, "/api/export", {"frames": [png(c) for c in colors], "fps": 12})
    assert r.status == 200, r.body
    assert r.json()["frames"] == 12
    assert most[0] <= 3, most[0]                        # not 12 decoded frames at once


def test_a_broken_frame_after_the_first_leaves_no_file(srv):
    broken = base64.b64decode(png((0, 0, 0)))
    broken = broken[:40] + b"\0" * (len(broken) - 52) + broken[-12:]   # IHDR kept
    frames = [png((1, 2, 3)), png((4, 5, 6)), base64.b64encode(broken).decode()]
    r = post_json(srv, "/api/export", {"frames": frames, "fps": 10, "name": "x.gif"})
    assert r.status == 400 and error(r).startswith('"frames"[2]: not a readable PNG image')
    assert list(srv.pose_folder.iterdir()) == []


# ---------------------------------------------------------------- clip keys and samples
def test_clip_keys_are_bounded_before_the_clip_is_read(srv, monkeypatch):
    read = []
    real = clips.read_clip
    monkeypatch.setattr(clips, "read_clip", lambda *a: read.append(1) or real(*a))
    assert clips.MAX_KEYS == 10_000

    def refused(path, k):
        """The lines of stbs code the server ran to refuse ``k`` keys on ``path``."""
        many = {"fps": 30, "keys": [{"time": j / 30, "pose": {}} for j in range(k)]}
        body = {"/api/clip/pose": {"clip": many, "time": 0},
                "/api/save-clip": {"clip": many, "name": "many.json"}}.get(path, many)
        with Lines() as work:
            r = post_json(srv, path, body)
        assert r.status == 413, (path, r.body)
        assert error(r) == f'clip: "keys": {k} keys; the limit is 10000 keys a request'
        return work.count

    # refused before any work per key: the same lines for 10 001 keys as for 40 004
    # (give or take the end of the request's thread, which may run after the answer)
    for path in ("/api/clip", "/api/clip/sample", "/api/clip/pose", "/api/save-clip"):
        refused(path, 10_001)                               # first calls fill caches
        small, large = refused(path, 10_001), refused(path, 40_004)
        assert large < small + 1000, (path, small, large)
    assert read == []
    assert list(srv.pose_folder.iterdir()) == []


def test_clip_keys_times_bones_are_bounded(monkeypatch):
    assert clips.MAX_KEY_BONES == 100_000
    rig = chain_rig(40)
    keys = [{"time": k / 30, "pose": {}} for k in range(2501)]      # 2501 x 40 > 100000
    with ViewerServer(rig) as s:
        r = post_json(s, "/api/clip", {"fps": 30, "keys": keys})
        assert r.status == 413
        assert error(r) == ('clip: "keys": 2501 keys x 40 bones = 100040 bone poses; the limit '
                            "is 100000 a request (at most 2500 keys for this rig)")
    monkeypatch.setattr(clips, "MAX_KEY_BONES", 20, raising=False)
    with ViewerServer(bar_rig()) as s:                  # 11 keys x 2 bones
        r = post_json(s, "/api/clip", {"fps": 30, "keys": keys[:11]})
        assert r.status == 413 and "22 bone poses; the limit is 20" in error(r)
        assert post_json(s, "/api/clip", {"fps": 30, "keys": keys[:10]}).status == 200


def test_sampled_frames_times_bones_are_bounded(monkeypatch):
    assert clips.MAX_SAMPLES == 100_000 and clips.MAX_FRAME_SAMPLES == 500_000
    clip = {"fps": 499.75, "keys": [{"time": 0, "pose": {}}, {"time": 4, "pose": {}}]}
    with ViewerServer(chain_rig(60)) as s:
        r = post_json(s, "/api/clip/sample", clip)      # 2000 frames x 60 bones
        assert r.status == 413
        assert error(r) == ("clip: 2000 frames x 60 bones = 120000 samples; the limit is 100000 "
                            "a request (at most 1666 frames for this rig)")
        r = post_json(s, "/api/clip/sample", dict(clip, times=[0.5] * 1667))
        assert r.status == 413 and "1667 frames x 60 bones" in error(r)
        r = post_json(s, "/api/clip/sample", dict(clip, times=[0.5] * 1666))
        assert r.status == 200 and len(r.json()["frames"]) == 1666
    monkeypatch.setattr(clips, "MAX_SAMPLES", 10, raising=False)
    monkeypatch.setattr(clips, "MAX_FRAME_SAMPLES", 10, raising=False)
    with ViewerServer(bar_rig()) as s:
        r = post_json(s, "/api/clip/sample", dict(CLIP, times=[0, 0.1, 0.2, 0.3, 0.4, 0.5]))
        assert r.status == 413 and "6 frames x 2 bones = 12 samples" in error(r)
        cid = post_json(s, "/api/clip", CLIP).json()["id"]
        r = request(s, "GET", f"/api/clip/{cid}/frames?t=0,1,2,3,4,5", token=True)
        assert r.status == 413 and error(r).startswith("t: 6 frames x 2 bones = 12 samples")
        r = request(s, "GET", f"/api/clip/{cid}/frames?t=0,1,2,3,4", token=True)
        assert r.status == 200 and r.array().shape == (5, 2, 15)


# ---------------------------------------------------------------- connections
def _connect_all(port: int, n: int, wait: float) -> list[socket.socket]:
    """Start n connections at once; those the listen queue took within ``wait`` s."""
    socks, done = [], []
    for _ in range(n):
        s = socket.socket()
        s.setblocking(False)
        assert s.connect_ex(("127.0.0.1", port)) in (0, errno.EINPROGRESS)
        socks.append(s)
    pending = list(socks)
    deadline = time.monotonic() + wait
    while pending and time.monotonic() < deadline:
        _, ready, _ = select.select([], pending, [], 0.05)
        for s in ready:
            pending.remove(s)
            if s.getsockopt(socket.SOL_SOCKET, socket.SO_ERROR) == 0:
                done.append(s)
    for s in pending:
        s.close()
    return done


def test_the_listen_queue_holds_200_connections_until_they_are_answered():
    s = ViewerServer(bar_rig())                         # listening, not yet accepting
    try:
        socks = _connect_all(s.port, 200, wait=2.0)
        try:
            assert len(socks) == 200
            s.start()
            req = (f"GET /api/pose HTTP/1.1\r\nHost: 127.0.0.1:{s.port}\r\n"
                   f"X-Stbs-Token: {s.token}\r\nConnection: close\r\n\r\n").encode()
            for c in socks:
                c.setblocking(True)
                c.settimeout(TIMEOUT)
                c.sendall(req)
            answers = [c.recv(65536) for c in socks]
        finally:
            for c in socks:
                c.close()
    finally:
        s.shutdown()
    assert [status_line(a) for a in answers] == [b"HTTP/1.1 200 OK"] * 200


def test_200_concurrent_requests_all_succeed(srv):
    n = 200
    barrier = threading.Barrier(n)

    def one(_):
        barrier.wait()
        return request(srv, "GET", "/api/pose", token=True).status

    with ThreadPoolExecutor(n) as pool:
        statuses = list(pool.map(one, range(n)))
    assert statuses == [200] * n


def test_handler_threads_are_bounded(monkeypatch):
    monkeypatch.setattr(handler_module.Handler, "timeout", 2)

    def handlers() -> int:
        return sum("process_request" in t.name for t in threading.enumerate())

    with ViewerServer(bar_rig()) as s:
        idle = _connect_all(s.port, handler_module.MAX_HANDLERS + 60, wait=3.0)
        try:
            time.sleep(0.5)
            assert handlers() <= handler_module.MAX_HANDLERS
        finally:
            for c in idle:
                c.close()
        assert request(s, "GET", "/api/pose", token=True).status == 200


def test_a_handler_slot_is_released_once_whoever_ends_first():
    # a Ctrl-C while the handler's thread starts: the serving thread gives the slot back
    # unless the handler's thread claimed it, which then gives it back itself; a second
    # release would raise (BoundedSemaphore) and replace the KeyboardInterrupt
    for thread_first in (True, False):
        sem = threading.BoundedSemaphore(1)
        sem.acquire()
        slot = handler_module._Slot(sem)
        if thread_first:
            slot.claim()
            slot.release_if_unclaimed()         # the serving thread: not its to release
            assert not sem.acquire(blocking=False)
            slot.release()                      # the handler's thread, when it ends
        else:
            slot.release_if_unclaimed()
            slot.claim()                        # a thread that started late
            slot.release()
        assert sem.acquire(blocking=False)      # released exactly once
        sem.release()


# ---------------------------------------------------------------- framing
def head(s, lines: list[str], body: bytes = b"", method: str = "POST",
         path: str = "/api/pose") -> bytes:
    text = (f"{method} {path} HTTP/1.1\r\nHost: 127.0.0.1:{s.port}\r\n"
            f"X-Stbs-Token: {s.token}\r\n" + "".join(f"{h}\r\n" for h in lines) + "\r\n")
    return text.encode() + body


@pytest.mark.parametrize("lines, words", [
    (["Content-Length: 2", "Content-Length: 5"], "Content-Length: expected one header, got 2"),
    (["Content-Length: 2", "Content-Length: 2"], "Content-Length: expected one header, got 2"),
    (["Content-Length: 2", "Transfer-Encoding: chunked"], "got both"),
    (["Transfer-Encoding: chunked", "Content-Length: 2"], "got both"),
    (["Content-Length: " + "9" * 5000], "at most 20 digits"),
    (["Content-Length: 99999999999999999999"], "the limit is 67108864 bytes"),
    (["Content-Length: 0x10"], "expected a number of bytes"),
    (["Content-Length: +2"], "expected a number of bytes"),
])
def test_the_body_length_must_be_unambiguous(srv, capfd, lines, words):
    reply = raw(srv, head(srv, [*lines, "Connection: keep-alive"], b"{}"))
    assert status_line(reply) in (b"HTTP/1.1 400 Bad Request",
                                  b"HTTP/1.1 413 Request Entity Too Large")
    assert words.encode() in reply
    assert reply.count(b"HTTP/1.1 ") == 1                # and the connection was closed
    assert capfd.readouterr().err == ""


@pytest.mark.parametrize("data, status", [
    (b"GET /" + b"a" * 70000 + b" HTTP/1.1\r\n\r\n", 414),
    (b"GET / HTTP/1.1\r\nX-Long: " + b"a" * 70000 + b"\r\n\r\n", 431),
    (b"GET / HTTP/1.1\r\n" + b"".join(b"X-%d: 1\r\n" % i for i in range(120)) + b"\r\n", 431),
    (b"GET / HTTP/1.x\r\n\r\n", 400),         # no version to answer in: a bare body
])
def test_requests_http_server_refuses_itself_are_json_too(srv, capfd, data, status):
    reply = raw(srv, data)
    if status != 400:
        assert status_line(reply).startswith(f"HTTP/1.1 {status} ".encode())
        head_, _, reply = reply.partition(b"\r\n\r\n")
        assert b"Content-Type: application/json" in head_ and b"Connection: close" in head_
    assert json.loads(reply)["status"] == status and json.loads(reply)["error"]
    assert capfd.readouterr().err == ""


def test_an_unread_body_is_never_read_as_the_next_request(srv):
    hidden = (f"POST /api/pose HTTP/1.1\r\nHost: 127.0.0.1:{srv.port}\r\nX-Stbs-Token: "
              f"{srv.token}\r\nContent-Length: 31\r\n\r\n{{\"stretch\": {{\"upper\": 3.0}}}}")
    reply = raw(srv, head(srv, [f"Content-Length: {len(hidden)}"], hidden.encode(),
                          method="GET"))
    assert reply.count(b"HTTP/1.1 ") == 1 and status_line(reply) == b"HTTP/1.1 200 OK"
    assert request(srv, "GET", "/api/pose", token=True).json() == {"degrees": True}


def test_a_body_cut_short_is_a_400_without_a_traceback(srv, capfd, monkeypatch):
    monkeypatch.setattr(handler_module.Handler, "timeout", 0.5)
    with socket.create_connection(("127.0.0.1", srv.port), timeout=TIMEOUT) as c:
        c.sendall(head(srv, ["Content-Length: 50"], b'{"st'))        # then silence
        reply = b""
        while chunk := c.recv(65536):
            reply += chunk
    assert status_line(reply) == b"HTTP/1.1 400 Bad Request"
    assert b"request body: expected 50 bytes, got 4 before the connection was idle" in reply
    # closed mid-body, reset mid-body, silent mid-headers: no answer needed, no noise
    assert status_line(raw(srv, head(srv, ["Content-Length: 50"], b"{}"))) == \
        b"HTTP/1.1 400 Bad Request"
    with socket.create_connection(("127.0.0.1", srv.port), timeout=TIMEOUT) as c:
        c.sendall(head(srv, ["Content-Length: 50"], b"{}"))
        c.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
    with socket.create_connection(("127.0.0.1", srv.port), timeout=TIMEOUT) as c:
        c.sendall(b"GET /api/pose HTTP/1.1\r\nHost: 127.0.0.1")
        assert c.recv(65536) == b""                     # dropped after the timeout
    time.sleep(0.3)
    assert request(srv, "GET", "/api/pose", token=True).status == 200
    assert capfd.readouterr().err == ""


# ---------------------------------------------------------------- JSON bodies
@pytest.mark.parametrize("body, words", [
    ('{"stretch": {"upper": 1e999}}', "finite number, found '1e999'"),
    ('{"stretch": {"upper": NaN}}', "finite numbers"),
    ('{"stretch": {"upper": -Infinity}}', "finite numbers"),
    ('{"stretch": {"upper": 1234567890123456789012345}}', "at most 20 digits, found one of 25"),
    ('{"a": ' * 65 + "1" + "}" * 65, "nested at most 64 deep, found nesting 65 deep"),
    ("[" * 200000 + "]" * 200000, "nested at most 64 deep"),
    (b'{"stretch": {"upper": 1.5}}\xff', "expected UTF-8 JSON text"),
    ('{"stretch": ', "line 1, column 13: not valid JSON"),
    ("", "not valid JSON"),
])
def test_json_bodies_are_read_by_the_safe_loader(srv, capfd, body, words):
    data = body if isinstance(body, bytes) else body.encode()
    r = request(srv, "POST", "/api/pose", body=data, token=True)
    assert r.status == 400
    msg = error(r)
    assert msg.startswith("request body") and words in msg, msg
    assert capfd.readouterr().err == ""


# ---------------------------------------------------------------- every POST route
def _routes(s) -> dict:
    """A valid body for every POST route (the clip route: a clip the server holds)."""
    rig = s.rig
    W = np.asarray(rig.W, dtype=float)
    cid = post_json(s, "/api/clip", CLIP).json()["id"]
    return {
        "/api/pose": {"rotate": {"upper": {"axis": [0, 0, 1], "angle": 30}},
                      "stretch": {"lower": 1.5}, "twist": {"upper": [0, 45]}},
        "/api/save-pose": {"pose": {"stretch": {"upper": 2}}, "name": "p.json",
                           "overwrite": True},
        "/api/save-rig": {"W": W.tolist(), "E": np.asarray(rig.E).tolist(), "overwrite": True},
        "/api/endpoint-weights": {"bone": 0, "method": "idw", "W": W.tolist(), "alpha": 2,
                                  "normalize": "bone", "threshold": 0.1},
        "/api/clip": CLIP,
        "/api/clip/sample": dict(CLIP, times=[0, 0.5]),
        "/api/clip/pose": {"clip": CLIP, "time": 0.5},
        f"/api/clip/{cid}/pose": {"time": 0.5},
        f"/api/clip/{cid}/seek": {"time": 0.5},
        "/api/pose/bones": {"R": np.tile(np.eye(3), (2, 1, 1)).tolist(),
                            "A": rig.skeleton.A.tolist(), "S": [1.0, 1.5], "T": [[0, 0], [0, 1]]},
        "/api/jobs/endpoint": {"bone": 0, "method": "idw", "W": W.tolist(),
                               "options": {"alpha": 2, "normalize": "bone", "threshold": 0.1}},
        "/api/save-clip": {"clip": CLIP, "name": "c.json", "overwrite": True},
        "/api/export": {"frames": [png((9, 9, 9), (8, 8))], "fps": 10, "name": "e.gif",
                        "overwrite": True, "loop": True, "format": "gif"},
    }


#: Values that go where they do not belong.
HOSTILE = [None, True, 0, -1, 9223372036854775808, 99999999999999999999, 1e308, -1e308,
           5e-324, "", "x", "1.5", [], [[]], [1, [2, [3]]], {}, {"a": {"b": 1}}, "A" * 5000,
           [0.5] * 500]


def _paths(obj, depth=3, prefix=()):
    """Paths into a JSON body: each key of an object, the first and last item of a list."""
    if depth == 0:
        return
    items = (obj.items() if isinstance(obj, dict) else
             [(0, obj[0]), (len(obj) - 1, obj[-1])] if isinstance(obj, list) and obj else [])
    for k, v in dict(items).items():
        yield (*prefix, k)
        yield from _paths(v, depth - 1, (*prefix, k))


def _replaced(obj, path, value):
    obj = json.loads(json.dumps(obj))
    if not path:
        return value
    at = obj
    for k in path[:-1]:
        at = at[k]
    if value is _DELETE:
        del at[path[-1]]
    else:
        at[path[-1]] = value
    return obj


_DELETE = object()


def _finish(s, jid: str) -> None:
    """Wait (bounded) until job ``jid`` has ended."""
    for _ in range(2000):
        if request(s, "GET", f"/api/jobs/{jid}", token=True).json()["state"] != "running":
            return
        time.sleep(0.005)
    raise AssertionError(f"job {jid} still running")


def test_every_post_route_answers_bad_bodies_with_one_line_never_a_500(srv, capfd):
    routes = _routes(srv)
    seen = {}
    for path, good in routes.items():
        r = post_json(srv, path, good)
        assert r.status == 200, (path, r.body)
        cases = [((), v) for v in HOSTILE]
        for p in _paths(good):
            if p[-1] == "W" or (len(p) > 1 and p[-2] in ("W", "E")):
                cases += [(p, v) for v in HOSTILE[:12]]     # weights: the cheap ones
            else:
                cases += [(p, v) for v in [*HOSTILE, _DELETE]]
        cases.append(((), dict(good, unexpected=1)) if isinstance(good, dict) else ((), 1))
        for p, v in cases:
            body = _replaced(good, p, v)
            r = post_json(srv, path, body)
            assert r.status in (200, 400, 404, 409, 413), (path, p, v, r.status, r.body[:300])
            if r.status != 200:
                seen[r.status] = seen.get(r.status, 0) + 1
                error(r)
            elif path == "/api/jobs/endpoint":
                _finish(srv, r.json()["job"])    # its worker's errors are said before we look
        assert capfd.readouterr().err == "", path
    assert seen.get(400, 0) > 500 and 500 not in seen


@pytest.mark.parametrize("path, body, status, words", [
    ("/api/endpoint-weights", {"bone": 0, "method": "idw", "W": [[1, 0], [0.5]]}, 400,
     '"W": expected 74 rows of 2 numbers (vertices x bones), got row 1 of length 1'),
    ("/api/endpoint-weights", {"bone": 0, "method": "idw", "W": [["0.5", "0.5"]] * 74}, 400,
     '"W": expected 74 rows of 2 numbers (vertices x bones), got "0.5" at [0][0]'),
    ("/api/endpoint-weights", {"bone": 0, "method": "idw", "W": [[0.5, None]] * 74}, 400,
     "got null at [0][1]"),
    ("/api/endpoint-weights", {"bone": 0, "method": "idw", "W": {"a": 1}}, 400,
     "got an object"),
    ("/api/endpoint-weights", {"bone": 0, "method": "idw", "W": [[0.5, 0.5]] * 73}, 400,
     "W must have shape (74, 2) (vertices, bones), got (73, 2)"),
    ("/api/endpoint-weights", {"bone": 0, "method": "idw", "alpha": 1e308}, 400,
     "method 'idw' with alpha=1e+308 gives endpoint weights that are not finite"),
    ("/api/endpoint-weights", {"bone": 99999999999999999999, "method": "idw"}, 400, '"bone"'),
    ("/api/save-rig", {"W": [[1, 0]] * 73 + [[1]]}, 400, "got row 73 of length 1"),
    ("/api/save-rig", {"E": [[True, False]] * 74}, 400, "got true at [0][0]"),
    ("/api/save-rig", {"W": "[[1, 0]]"}, 400, '"W": expected 74 rows of 2 numbers'),
    ("/api/save-pose", {"pose": {}, "name": "p.json", "overwrite": "yes"}, 400,
     '"overwrite": expected true or false'),
    ("/api/clip/sample", dict(CLIP, times=[0, "1"]), 400, '"times"[1]: expected a finite'),
    ("/api/clip/sample", dict(CLIP, times=[0] * 2001), 413,
     '"times": 2001 times; the limit is 2000'),
    ("/api/clip/sample", {"fps": 1000, "keys": [{"time": 0, "pose": {}},
                                                 {"time": 3, "pose": {}}]}, 413,
     "clip: 3 s at 1000 fps is 3001 frames; the limit is 2000 a request"),
    ("/api/clip", {"fps": 30, "keys": [{"time": -1e308, "pose": {}},
                                       {"time": 1e308, "pose": {}}]}, 400,
     'keys[0]."time": expected a finite number'),
    ("/api/export", {"frames": [header_only_png(8, 8)], "fps": 5e-324}, 400,
     '"fps": expected a number in [0.01, 100] (a GIF frame lasts 10 ms to 100 s), found '
     "5e-324"),
    ("/api/export", {"frames": [header_only_png(0, 5)], "fps": 1}, 400, "0 x 5 pixels"),
    ("/api/export", {"frames": [base64.b64encode(PNG + b"\0" * 30).decode()], "fps": 1}, 400,
     "its first chunk is not the 13-byte IHDR header"),
])
def test_bad_bodies_name_the_field_the_expectation_and_what_arrived(srv, capfd, path, body,
                                                                   status, words):
    r = post_json(srv, path, body)
    assert r.status == status, r.body
    if words is not None:
        assert words in error(r), error(r)
    assert capfd.readouterr().err == ""


# ---------------------------------------------------------------- outputs over inputs
@pytest.fixture
def motion(tmp_path):
    """A viewer started from Python with a clip file of its pose folder as its motion."""
    folder = tmp_path / "poses"
    folder.mkdir()
    path = folder / "walk.json"
    rig = bar_rig()
    stbs.io.write_clip(path, stbs.io.read_clip(CLIP, rig.skeleton))
    clip = stbs.io.read_clip(path, rig.skeleton)
    with ViewerServer(rig, pose_folder=folder, clip=clip, inputs=[path], name="bar") as s:
        yield s, path


def test_no_save_writes_over_the_motion_the_viewer_was_started_with(motion):
    s, path = motion
    before = path.read_bytes()
    os.link(path, path.with_name("alias.json"))
    cid = request(s, "GET", "/api/clip", token=True).json()["id"]
    other = dict(CLIP, fps=9)
    for route, body in (("/api/save-clip", {"id": cid, "name": "walk.json", "overwrite": True}),
                        ("/api/save-clip", {"clip": other, "name": "walk.json",
                                            "overwrite": True}),
                        ("/api/save-clip", {"clip": other, "name": "walk.json"}),
                        ("/api/save-clip", {"clip": other, "name": "alias.json",
                                            "overwrite": True}),
                        ("/api/save-pose", {"pose": {}, "name": "walk.json", "overwrite": True}),
                        ("/api/save-pose", {"pose": {}, "name": "alias.json", "overwrite": True})):
        r = post_json(s, route, body)
        assert r.status == 409, (route, body, r.body)
        name = body["name"]
        assert error(r) == (f"{name!r} is a file this viewer reads (its rig, motion or "
                            'mapping): never written over, even with "overwrite": true; '
                            "choose another name")
    assert path.read_bytes() == before
    assert sorted(p.name for p in s.pose_folder.iterdir()) == ["alias.json", "walk.json"]
    assert post_json(s, "/api/save-clip", {"id": cid, "name": "walk2.json"}).status == 200
    assert inputs() == []                       # tracked for each save, not for the process


def test_the_inputs_are_refused_as_rig_target_and_for_exports(tmp_path):
    rig = bar_rig()
    src = tmp_path / "rig.npz"
    stbs.io.write_rig(src, rig)
    with pytest.raises(ValueError, match="rig_target .* is a file this viewer reads"):
        ViewerServer(rig, rig_target=src, inputs=[src])
    with pytest.raises(ValueError, match="rig_target"):
        ViewerServer(rig, rig_target=tmp_path / "." / "rig.npz", inputs=str(src))
    gif = tmp_path / "old.gif"
    gif.write_bytes(b"GIF89a")
    with ViewerServer(rig, pose_folder=tmp_path, inputs=[gif, src]) as s:
        r = post_json(s, "/api/export", {"frames": [png((1, 1, 1))], "fps": 10,
                                         "name": "old.gif", "overwrite": True})
        assert r.status == 409 and "is a file this viewer reads" in error(r)
    assert gif.read_bytes() == b"GIF89a"


def test_a_tracked_run_around_the_server_is_honoured_too(tmp_path):
    """As under ``stbs view``: the command tracks what it read, the server saves."""
    motion_path = tmp_path / "walk.json"
    motion_path.write_text(json.dumps(CLIP))
    with tracking():
        note_input(motion_path)
        with ViewerServer(bar_rig(), pose_folder=tmp_path) as s:
            r = post_json(s, "/api/save-clip", {"clip": CLIP, "name": "walk.json",
                                                "overwrite": True})
            assert r.status == 409 and "is a file this viewer reads" in error(r)
            r = post_json(s, "/api/save-pose", {"pose": {}, "name": "walk.json",
                                                "overwrite": True})
            assert r.status == 409
    assert json.loads(motion_path.read_text()) == CLIP
