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
    ({"bone": 0, "method": "bbw"}, "tetrahedra T"),           # a surface-only 3D rig
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
