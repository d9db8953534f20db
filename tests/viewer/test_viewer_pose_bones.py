"""GET /api/pose/bones: the current pose's per-bone arrays, for the page's shader."""

from __future__ import annotations

import numpy as np
from viewer_client import bar_rig, post_json, request

import stbs
from stbs.viewer import ViewerServer


def test_pose_bones_are_the_current_pose_read_by_the_library():
    rig = bar_rig()
    sk = rig.skeleton
    with ViewerServer(rig) as srv:
        r = request(srv, "GET", "/api/pose/bones", token=True)
        assert r.status == 200 and r.headers["content-type"] == "application/json"
        rest = stbs.Pose.rest(sk)
        got = r.json()
        assert set(got) == {"rotations", "origins", "stretch", "twist"}
        for key in got:
            assert np.allclose(got[key], getattr(rest, key), atol=0)
        pose = {"rotate": {"lower": {"axis": [0, 0, 1], "angle": 50}}, "stretch": {"0": 1.4},
                "twist": {"lower": [0, 800]}, "translate": [0.1, 0, 0]}
        assert post_json(srv, "/api/pose", pose).status == 200
        want = stbs.io.read_pose(pose, sk)
        got = request(srv, "GET", "/api/pose/bones", token=True).json()
        assert np.array(got["rotations"]).shape == (2, 3, 3)
        assert np.array(got["twist"]).shape == (2, 2)
        for key in got:
            assert np.array_equal(np.array(got[key]), getattr(want, key))
        assert abs(got["twist"][1][1] - np.deg2rad(800)) < 1e-12
        # a refused pose leaves it as it was
        assert post_json(srv, "/api/pose", {"stretch": {"0": -1}}).status == 400
        assert request(srv, "GET", "/api/pose/bones", token=True).json() == got


def test_pose_bones_needs_the_token_and_is_get_only():
    with ViewerServer(bar_rig()) as srv:
        assert request(srv, "GET", "/api/pose/bones").status == 403
        assert request(srv, "GET", "/api/pose/bones", token="0" * 32).status == 403
        r = request(srv, "POST", "/api/pose/bones", body="{}", token=True)
        assert r.status == 405 and r.headers["allow"] == "GET"
