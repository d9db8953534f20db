"""``POST /api/endpoint-weights``: one bone's endpoint weights recomputed on the server
by a method of ``stbs.weights.endpoint_weights``, for the page's editor."""

from __future__ import annotations

import json

import numpy as np
import pytest
from viewer_client import bar_rig, post_json, request

import stbs
from stbs.viewer import ViewerServer


@pytest.fixture(scope="module")
def srv():
    with ViewerServer(bar_rig()) as s:
        yield s


def _dense(E):
    return np.asarray(E.toarray() if hasattr(E, "toarray") else E, dtype=np.float64)


def test_projection_column_as_json_and_binary(srv):
    rig = srv.rig
    ref = _dense(stbs.weights.projection(rig.V, rig.skeleton))
    for bone, i in ((0, 0), ("lower", 1), ("1", 1)):
        r = post_json(srv, "/api/endpoint-weights", {"bone": bone, "method": "projection"})
        assert r.status == 200, r.body
        got = r.json()
        assert got["bone"] == i and got["method"] == "projection"
        assert np.allclose(got["E"], ref[:, i], atol=1e-12, rtol=0)
    assert ref[:, 1].min() == 0 and ref[:, 1].max() == 1     # a column that says something
    r = request(srv, "POST", "/api/endpoint-weights", token=True,
                body=json.dumps({"bone": 1, "method": "projection"}),
                headers={"Content-Type": "application/json", "Accept": "application/octet-stream"})
    assert r.status == 200 and r.headers["x-stbs-bone"] == "1"
    assert r.headers["x-stbs-shape"] == str(len(rig.V))
    assert np.array_equal(r.array(), ref[:, 1].astype(np.float32))


def test_the_pages_bone_weights_and_options_are_used(srv):
    rig = srv.rig
    V, sk = rig.V, rig.skeleton
    W = np.asarray(rig.W, dtype=np.float64).copy()
    W[:, 1] = np.where(V[:, 0] < np.median(V[:, 0]) + 0.5, 0.0, W[:, 1])   # bone 1 shrinks
    W[:, 0] = 1 - W[:, 1]
    r = post_json(srv, "/api/endpoint-weights", {"bone": 1, "method": "heat", "W": W.tolist()})
    assert r.status == 200, r.body
    ref = _dense(stbs.weights.endpoint_weights(V, sk, method="heat", W=W, F=rig.F))[:, 1]
    base = _dense(stbs.weights.endpoint_weights(V, sk, method="heat", W=rig.W, F=rig.F))[:, 1]
    assert np.abs(ref - base).max() > 1e-3      # the sent W matters for this method
    assert np.allclose(r.json()["E"], ref, atol=1e-12)
    r = post_json(srv, "/api/endpoint-weights", {"bone": 0, "method": "idw", "alpha": 4})
    ref = _dense(stbs.weights.idw(V, sk, alpha=4))[:, 0]
    assert r.status == 200 and np.allclose(r.json()["E"], ref, atol=1e-12)


@pytest.mark.parametrize("body, needle", [
    ({"bone": 0, "method": "bbw"}, "BBW needs a volume"),     # a surface-only 3D rig
    ({"bone": 0, "method": "smooth"}, '"method": expected one of projection'),
    ({"bone": 5, "method": "idw"}, '"bone": bone 5 does not exist'),
    ({"bone": True, "method": "idw"}, '"bone": expected a bone index'),
    ({"method": "idw"}, '"bone": expected a bone index'),
    ({"bone": 0, "method": "idw", "tol": 1}, "tol applies to"),
    ({"bone": 0, "method": "idw", "colour": 1}, "unexpected key 'colour'"),
    ({"bone": 0, "method": "heat", "W": [[1, 0]]}, "W must have shape (74, 2)"),
    ([0, "idw"], "expected a JSON object"),
])
def test_bad_requests_are_one_line_400s(srv, body, needle):
    r = post_json(srv, "/api/endpoint-weights", body)
    assert r.status == 400, r.body
    msg = r.json()["error"]
    assert needle in msg and "\n" not in msg


def test_get_is_405_and_the_token_is_needed(srv):
    assert request(srv, "GET", "/api/endpoint-weights", token=True).status == 405
    r = request(srv, "POST", "/api/endpoint-weights", body='{"bone": 0, "method": "idw"}',
                headers={"Content-Type": "application/json"})
    assert r.status == 403


# ---------------------------------------------------------------- as jobs
def _wait(srv, jid, states=("done", "failed", "cancelled"), timeout=60.0):
    import time

    end = time.monotonic() + timeout
    while time.monotonic() < end:
        st = request(srv, "GET", f"/api/jobs/{jid}", token=True).json()
        if st["state"] in states:
            return st
        time.sleep(0.02)
    raise AssertionError(f"job {jid} still {st}")


def _grid_rig() -> stbs.Rig:
    """A 2D strip of 9 x 3 vertices, two bones along its middle line, W blended by x."""
    x, y = np.meshgrid(np.arange(9.0), np.arange(3.0), indexing="ij")
    V = np.c_[x.ravel(), y.ravel()]
    q = np.array([3 * i + j for i in range(8) for j in range(2)])
    F = np.r_[np.c_[q, q + 3, q + 4], np.c_[q, q + 4, q + 1]]
    sk = stbs.Skeleton([[0.0, 1.0], [4.0, 1.0], [8.0, 1.0]], [[0, 1], [1, 2]])
    w = np.clip((V[:, 0] - 2) / 4, 0, 1)
    return stbs.Rig(V=V, F=F, skeleton=sk, W=np.c_[1 - w, w])


def test_an_endpoint_job_runs_reports_progress_and_answers_its_column():
    rig = _grid_rig()
    with ViewerServer(rig) as srv:
        info = request(srv, "GET", "/api/rig", token=True).json()
        assert set(info["endpoint_methods"]) == {"projection", "idw", "bbw", "bbw-joints"}
        assert info["methods"] == ["lbs", "dqs", "stbs-lbs", "stbs-dqs"]
        r = post_json(srv, "/api/jobs/endpoint", {"bone": 1, "method": "bbw",
                                                  "options": {"tol": 1e-9}})
        assert r.status == 200, r.body
        jid = r.json()["job"]
        st = _wait(srv, jid)
        assert st["state"] == "done" and st["bone"] == 1 and st["method"] == "bbw"
        assert st["done"] == st["total"] and st["total"] >= 1     # steps of the solve
        ref = _dense(stbs.weights.endpoint_weights(rig.V, rig.skeleton, method="bbw",
                                                   W=rig.W, F=rig.F, tol=1e-9))[:, 1]
        assert ref.min() == 0 and ref.max() == 1
        got = request(srv, "GET", f"/api/jobs/{jid}/result", token=True).json()
        assert got["bone"] == 1 and np.allclose(got["E"], ref, atol=1e-12)
        r = request(srv, "GET", f"/api/jobs/{jid}/result", token=True,
                    headers={"Accept": "application/octet-stream"})
        assert r.headers["x-stbs-bone"] == "1"
        assert np.array_equal(r.array(), ref.astype(np.float32))


def test_the_methods_a_rig_cannot_compute_are_not_listed_and_refused(srv):
    info = request(srv, "GET", "/api/rig", token=True).json()
    assert set(info["endpoint_methods"]) == {"projection", "idw", "heat"}  # a surface
    r = post_json(srv, "/api/jobs/endpoint", {"bone": 0, "method": "bbw"})
    assert r.status == 400
    msg = r.json()["error"]
    assert "'bbw' cannot work on this rig" in msg
    assert all(m in msg.split("takes ")[1] for m in ("projection", "idw", "heat"))
    for body, words in (({"bone": 0, "method": "idw", "alpha": 2}, "unexpected key 'alpha'"),
                        ({"bone": 0, "method": "idw", "options": {"colour": 1}},
                         "key 'colour'"),
                        ({"bone": 0, "method": "idw", "options": 3}, '"options": expected'),
                        ({"bone": 9, "method": "idw"}, '"bone"')):
        r = post_json(srv, "/api/jobs/endpoint", body)
        assert r.status == 400 and words in r.json()["error"], r.body
    # an option the method refuses fails the job, with the library's one line
    jid = post_json(srv, "/api/jobs/endpoint", {"bone": 0, "method": "idw",
                                                "options": {"tol": 1}}).json()["job"]
    st = _wait(srv, jid)
    assert st["state"] == "failed" and "tol applies to" in st["error"]
    r = request(srv, "GET", f"/api/jobs/{jid}/result", token=True)
    assert r.status == 409 and "failed" in r.json()["error"]


def test_one_job_at_a_time_and_a_cancel_stops_it_at_its_next_step(srv, monkeypatch):
    import threading

    from stbs.viewer import jobs

    steps, release = [], threading.Event()

    def slow(rig, W, bone, method, options, progress=None):
        for k in range(10_000):     # until cancelled: progress raises then
            steps.append(k)
            progress("solving", k, 10_000)
            release.wait(0.01)
        return np.zeros(len(rig.V))

    monkeypatch.setattr(jobs, "endpoint_column", slow)
    jid = post_json(srv, "/api/jobs/endpoint", {"bone": 0, "method": "idw"}).json()["job"]
    r = post_json(srv, "/api/jobs/endpoint", {"bone": 1, "method": "idw"})
    assert r.status == 409 and f"job {jid}" in r.json()["error"]
    r = request(srv, "GET", f"/api/jobs/{jid}/result", token=True)
    assert r.status == 409 and "running" in r.json()["error"]
    st = request(srv, "GET", f"/api/jobs/{jid}", token=True).json()
    assert st["state"] == "running" and st["total"] in (0, 1, 10_000)
    r = post_json(srv, f"/api/jobs/{jid}/cancel", {})
    assert r.status == 200 and r.json()["state"] in ("running", "cancelled")
    st = _wait(srv, jid)
    assert st["state"] == "cancelled" and len(steps) < 10_000
    monkeypatch.undo()
    jid2 = post_json(srv, "/api/jobs/endpoint", {"bone": 1, "method": "projection"}).json()
    assert _wait(srv, jid2["job"])["state"] == "done"
    assert post_json(srv, f"/api/jobs/{jid}/cancel", {}).json()["state"] == "cancelled"


def test_jobs_are_bounded_and_their_routes_are_in_the_table(srv):
    from stbs.viewer.jobs import MAX_JOBS

    ids = []
    for _ in range(MAX_JOBS + 1):
        ids.append(post_json(srv, "/api/jobs/endpoint",
                             {"bone": 0, "method": "projection"}).json()["job"])
        _wait(srv, ids[-1])
    r = request(srv, "GET", f"/api/jobs/{ids[0]}", token=True)
    assert r.status == 404 and f"keeps the {MAX_JOBS} jobs" in r.json()["error"]
    assert request(srv, "GET", f"/api/jobs/{ids[-1]}", token=True).status == 200
    r = request(srv, "GET", f"/api/jobs/{ids[-1]}/cancel", token=True)
    assert r.status == 405 and r.headers["allow"] == "POST"
    r = request(srv, "GET", "/api/jobs/endpoint", token=True)
    assert r.status == 405 and r.headers["allow"] == "POST"
    assert request(srv, "GET", "/api/jobs/0123", token=True).status == 404
    assert request(srv, "GET", f"/api/jobs/{ids[-1]}").status == 403
