"""/api/pose/bones: the current pose's per-bone arrays (JSON, or binary rows of float64),
and the page's world transforms in, the forward-kinematics pose out."""

from __future__ import annotations

import json

import numpy as np
import pytest
from viewer_client import bar_rig, post_json, request

import stbs
from rigs import random_pose, random_rig
from stbs.viewer import ViewerServer

OCTET = {"Accept": "application/octet-stream"}


def _rows(pose: stbs.Pose) -> np.ndarray:
    """The documented binary layout, written out here: per bone R row-major, a', sigma,
    theta_a, theta_b."""
    b, d = pose.skeleton.n_bones, pose.skeleton.dim
    out = []
    for i in range(b):
        out.append([*pose.rotations[i].ravel(), *pose.origins[i], pose.stretch[i],
                    *pose.twist[i]])
    return np.array(out).reshape(b, d * d + d + 3)


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


@pytest.mark.parametrize("d", [2, 3])
def test_pose_bones_as_binary_rows(d):
    rng, sk, V, W, E = random_rig(7, d, n=30)
    pose = random_pose(rng, sk)
    with ViewerServer(stbs.Rig(V=V, skeleton=sk, W=W, E=E)) as srv:
        srv.state.set_pose(pose)
        r = request(srv, "GET", "/api/pose/bones", token=True, headers=OCTET)
        assert r.status == 200 and r.headers["content-type"] == "application/octet-stream"
        assert r.headers["x-stbs-dtype"] == "float64"
        assert r.headers["x-stbs-byte-order"] == "little"
        m = d * d + d + 3
        assert r.headers["x-stbs-shape"] == f"{sk.n_bones},{m}"
        assert len(r.body) == sk.n_bones * m * 8
        A = np.frombuffer(r.body, dtype="<f8").reshape(sk.n_bones, m)
        assert np.array_equal(A, _rows(pose))


def _world(pose: stbs.Pose, embed: bool) -> dict:
    """The page's world form: 3x3 rows and 3-vectors (a 2D rig embedded with z = 0)."""
    R, A = pose.rotations, pose.origins
    if embed and pose.skeleton.dim == 2:
        b = len(R)
        R3 = np.tile(np.eye(3), (b, 1, 1))
        R3[:, :2, :2] = R
        R, A = R3, np.c_[A, np.zeros(b)]
    return {"R": R.tolist(), "A": A.tolist(), "S": pose.stretch.tolist(),
            "T": pose.twist.tolist()}


def _offset_rig() -> stbs.Rig:
    """A chain with an offset child hanging halfway along its first bone (t_c = 0.5)."""
    C = np.array([[0, 0, 0], [2, 0, 0], [3, 0, 0], [1, 0.5, 0], [1, 1.5, 0]], dtype=float)
    BE = np.array([[0, 1], [1, 2], [3, 4]])
    sk = stbs.Skeleton(C, BE, P=[-1, 0, 0])
    assert not sk.connected[2] and abs(sk.hang[2] - 0.5) < 1e-12
    V = np.random.default_rng(0).normal(size=(20, 3))
    W = np.full((20, 3), 1 / 3)
    return stbs.Rig(V=V, skeleton=sk, W=W)


@pytest.mark.parametrize("case", ["3d", "2d", "2d-embedded", "offset"])
def test_world_transforms_in_give_the_same_pose_out(case):
    if case == "offset":
        rig = _offset_rig()
        rng = np.random.default_rng(5)
    else:
        rng, sk, V, W, E = random_rig(11, 3 if case == "3d" else 2, n=30)
        rig = stbs.Rig(V=V, skeleton=sk, W=W, E=E)
    sk = rig.skeleton
    pose = random_pose(rng, sk)          # world arrays that forward kinematics must hold
    with ViewerServer(rig) as srv:
        r = post_json(srv, "/api/pose/bones", _world(pose, embed=case != "2d"))
        assert r.status == 200, r.body
        got = r.json()
        scale = max(1.0, float(np.abs(pose.origins).max()))
        for key in ("rotations", "origins", "stretch", "twist"):
            assert np.abs(np.array(got["bones"][key]) - getattr(pose, key)).max() < \
                1e-12 * scale, key
        # the pose object is the forward-kinematics form the library writes and reads back
        assert got["pose"] == stbs.io.pose_to_dict(srv.pose)
        back = stbs.io.read_pose(got["pose"], sk)
        for key in ("rotations", "origins", "stretch", "twist"):
            assert np.abs(getattr(back, key) - getattr(pose, key)).max() < 1e-9 * scale, key
            assert np.abs(getattr(srv.pose, key) - getattr(pose, key)).max() < 1e-12 * scale
        assert request(srv, "GET", "/api/pose", token=True).json() == got["pose"]


def test_the_arrays_form_is_taken_too_and_twist_may_be_left_out():
    rig = bar_rig()
    pose = stbs.io.read_pose({"rotate": {"upper": {"axis": [0, 1, 0], "angle": 30}},
                              "stretch": {"lower": 1.5}}, rig.skeleton)
    with ViewerServer(rig) as srv:
        body = {"rotations": pose.rotations.tolist(), "origins": pose.origins.tolist(),
                "stretch": pose.stretch.tolist()}
        r = post_json(srv, "/api/pose/bones", body)
        assert r.status == 200, r.body
        assert np.abs(srv.pose.origins - pose.origins).max() < 1e-12
        assert np.abs(srv.pose.rotations - pose.rotations).max() < 1e-12


@pytest.mark.parametrize("change, words", [
    (lambda w: w.pop("R"), 'missing "R"'),
    (lambda w: w.update(X=1), "unexpected key 'X'"),
    (lambda w: w.update(R=w["R"][:1]), '"R": expected shape (2, 3, 3)'),
    (lambda w: w.update(A="x"), '"A": expected numbers of shape'),
    (lambda w: w.update(S=[1, -1]), "stretch must be > 0"),
    (lambda w: w.update(R=[[[2, 0, 0], [0, 1, 0], [0, 0, 1]]] * 2), "must be a rotation"),
    (lambda w: w.update(T=[[0, 1]]), '"T": expected shape (2, 2)'),
    (lambda w: w.update(S=[1, 1e400]), "request body"),
])
def test_bad_world_poses_are_one_line_400s_and_change_nothing(change, words):
    rig = bar_rig()
    pose = stbs.io.read_pose({"stretch": {"0": 1.2}}, rig.skeleton)
    with ViewerServer(rig) as srv:
        world = _world(pose, embed=True)
        change(world)
        before = srv.pose
        r = request(srv, "POST", "/api/pose/bones", token=True,
                    body=json.dumps(world).replace("Infinity", "1e400"),
                    headers={"Content-Type": "application/json"})
        assert r.status == 400, r.body
        msg = r.json()["error"]
        assert words in msg and "\n" not in msg, msg
        assert srv.pose is before


def test_a_2d_rig_refuses_a_turn_out_of_its_plane():
    rng, sk, V, W, E = random_rig(3, 2, n=20)
    with ViewerServer(stbs.Rig(V=V, skeleton=sk, W=W)) as srv:
        world = _world(stbs.Pose.rest(sk), embed=True)
        world["R"][0] = [[1, 0, 0], [0, 0, -1], [0, 1, 0]]
        r = post_json(srv, "/api/pose/bones", world)
        assert r.status == 400 and "turns about z only" in r.json()["error"]
        world = _world(stbs.Pose.rest(sk), embed=True)
        world["A"][0][2] = 0.5
        r = post_json(srv, "/api/pose/bones", world)
        assert r.status == 400 and "z = 0" in r.json()["error"]


def test_pose_bones_needs_the_token():
    with ViewerServer(bar_rig()) as srv:
        assert request(srv, "GET", "/api/pose/bones").status == 403
        assert request(srv, "GET", "/api/pose/bones", token="0" * 32).status == 403
        assert request(srv, "POST", "/api/pose/bones", body="{}").status == 403
