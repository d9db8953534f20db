"""stbs.retarget: motion (stbs.Motion) onto a rig's skeleton, twist spread along bones."""

from __future__ import annotations

import numpy as np
import pytest

import stbs
from stbs import transforms as tf
from stbs.retargeting import _normalise, retarget


def _rx(deg):
    return tf.axis_angle_to_matrix(np.broadcast_to([1.0, 0, 0], (np.size(deg), 3)),
                                   np.radians(np.atleast_1d(deg)))


def _arm_motion(roll_deg, wrist_x=None):
    """shoulder -> elbow -> wrist -> hand end along x (3, 3, 1 long); the wrist joint
    rolls about x by ``roll_deg`` per frame (capture stores a forearm's roll there)."""
    f = len(roll_deg)
    R = np.tile(np.eye(3), (f, 4, 1, 1))
    R[:, 2] = _rx(roll_deg)
    offsets = [[0, 0, 0], [3, 0, 0], [3, 0, 0], [1, 0, 0]]
    T = None
    if wrist_x is not None:
        T = np.broadcast_to(np.array(offsets, float), (f, 4, 3)).copy()
        T[:, 2, 0] = wrist_x
    return stbs.Motion(["shoulder", "elbow", "wrist", "wrist_end"], [-1, 0, 1, 2], offsets,
                       rotations=R, translations=T, frame_time=0.04,
                       end_site=[False, False, False, True])


def test_the_motion_skeleton_rule():
    m = _arm_motion([0.0])
    sk, drive, end = m.skeleton()
    assert sk.names == ["shoulder", "elbow", "wrist"]
    np.testing.assert_array_equal(sk.C, [[0, 0, 0], [3, 0, 0], [6, 0, 0], [7, 0, 0]])
    assert drive.tolist() == [0, 1, 2] and end.tolist() == [1, 2, 3]
    # a zero offset merges joints; a joint turning two bones names the second P>K
    R = np.tile(np.eye(3), (1, 4, 1, 1))
    m2 = stbs.Motion(["hips", "zero", "l", "r"], [-1, 0, 1, 1],
                     [[0, 0, 0], [0, 0, 0], [1, 0, 0], [-1, 0, 0]], rotations=R, frame_time=1)
    sk2, drive2, _ = m2.skeleton()
    assert sk2.names == ["zero", "zero>r"] and sk2.n_joints == 3
    assert drive2.tolist() == [1, 1]


@pytest.fixture(scope="module")
def rolling():
    roll = np.linspace(0, 720, 25)           # two full turns, 30 degrees per frame
    m = _arm_motion(roll)
    sk = m.skeleton()[0]
    return m, sk, roll


def test_spread_moves_the_wrist_roll_onto_the_forearm_unwrapped(rolling):
    m, sk, roll = rolling
    spread = retarget(m, sk, twist="spread")
    joint = retarget(m, sk, twist="joint")
    assert len(spread.keys) == 25 and spread.fps == pytest.approx(25)
    np.testing.assert_allclose(spread.times, m.times)
    fore = sk.bone_index("elbow")
    th = np.array([p.twist[fore] for _, p in spread.keys])
    np.testing.assert_allclose(th[:, 0], 0, atol=1e-12)
    np.testing.assert_allclose(th[:, 1], np.radians(roll), atol=1e-9)     # 0 .. 4 pi
    assert np.abs(np.diff(th[:, 1])).max() < np.pi                          # never a full-turn jump
    for (_, ps), (_, pj), a in zip(spread.keys, joint.keys, roll, strict=True):
        assert not pj.twist.any()
        # same bone rotations and joints either way; the hand turned by the roll
        np.testing.assert_allclose(ps.rotations, pj.rotations, atol=1e-12)
        np.testing.assert_allclose(ps.joints(), pj.joints(), atol=1e-12)
        np.testing.assert_allclose(ps.rotations[sk.bone_index("wrist")], _rx(a)[0], atol=1e-12)


def test_the_spread_roll_grows_along_the_forearm(rolling):
    m, sk, roll = rolling
    k = 3                                      # 90 degrees of roll
    assert roll[k] == pytest.approx(90)
    # a tube around the forearm, all on the forearm bone, e by projection
    t = np.linspace(0.1, 0.9, 9)
    phi = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    T, P = np.meshgrid(t, phi, indexing="ij")
    V = np.column_stack([3 + 3 * T.ravel(), 0.5 * np.cos(P.ravel()), 0.5 * np.sin(P.ravel())])
    W = np.zeros((len(V), 3))
    W[:, sk.bone_index("elbow")] = 1
    E = stbs.weights.projection(V, sk)
    for twist, expect in (("spread", 90 * T.ravel()), ("joint", 0 * T.ravel())):
        pose = retarget(m, sk, twist=twist).keys[k][1]
        U = stbs.deform(V, sk, pose, W, E, method="stbs-lbs")
        turned = np.degrees(np.arctan2(U[:, 2], U[:, 1]) - np.arctan2(V[:, 2], V[:, 1]))
        turned = (turned + 180) % 360 - 180
        np.testing.assert_allclose(turned, expect, atol=1e-6)


def test_stretch_match_follows_the_source_bone_length():
    wx = np.linspace(3, 6, 5)                 # the forearm grows to twice its length
    m = _arm_motion(np.zeros(5), wrist_x=wx)
    sk = m.skeleton()[0]
    keep = retarget(m, sk)
    match = retarget(m, sk, stretch="match")
    fore = sk.bone_index("elbow")
    assert all((p.stretch == 1).all() for _, p in keep.keys)
    got = np.array([p.stretch[fore] for _, p in match.keys])
    # the total rest length is 7 in both, so the scale is 1 and sigma = length / 3
    np.testing.assert_allclose(got, wx / 3, atol=1e-12)
    np.testing.assert_allclose(match.keys[-1][1].ends[fore], [9, 0, 0], atol=1e-12)


def test_names_match_across_conventions():
    assert _normalise("mixamorig:LeftForeArm") == ("l", "forearm")
    assert _normalise("RightUpLeg") == ("r", "upleg")
    assert _normalise("forearm_L") == ("l", "forearm")
    assert _normalise("Hips") == ("", "hips")
    roll = np.array([0.0, 90.0])
    m = _arm_motion(roll)
    C = [[0, 0, 0], [3, 0, 0], [6, 0, 0], [7, 0, 0]]
    sk = stbs.Skeleton(C, [[0, 1], [1, 2], [2, 3]], names=["Shoulder", "ForeArm", "Hand"])
    c = retarget(m, sk)          # shoulder = shoulder, forearm ~ elbow, hand ~ wrist
    np.testing.assert_allclose(c.keys[1][1].twist[1], [0, np.pi / 2], atol=1e-12)


def test_mapping_and_errors(tmp_path):
    m = _arm_motion(np.array([0.0, 90.0]))
    C = [[0, 0, 0], [3, 0, 0], [6, 0, 0], [7, 0, 0]]
    sk = stbs.Skeleton(C, [[0, 1], [1, 2], [2, 3]], names=["a", "b", "c"])
    with pytest.raises(ValueError, match=r"no bone of the rig matches .* \(give a mapping\)"):
        retarget(m, sk)
    mapping = {"a": "shoulder", "b": "elbow", "2": "wrist"}
    c = retarget(m, sk, mapping=mapping)
    np.testing.assert_allclose(c.keys[1][1].twist[1], [0, np.pi / 2], atol=1e-12)
    p = tmp_path / "map.json"
    p.write_text('{"a": "shoulder", "b": "elbow", "c": "wrist"}')
    c2 = retarget(m, sk, mapping=p)
    np.testing.assert_array_equal(c2.keys[1][1].twist, c.keys[1][1].twist)
    # by name, a bone without a joint is named in a warning and follows its parent
    sk4 = stbs.Skeleton(C + [[8, 0, 0]], [[0, 1], [1, 2], [2, 3], [3, 4]],
                        names=["shoulder", "elbow", "wrist", "finger"])
    with pytest.warns(UserWarning, match="1 rig bones match no joint .*: finger"):
        c4 = retarget(m, sk4)
    np.testing.assert_allclose(c4.keys[1][1].rotations[3], c4.keys[1][1].rotations[2])
    # "c" follows its parent when unmapped: no roll reaches the forearm then
    c3 = retarget(m, sk, mapping={"a": "shoulder", "b": "elbow", "c": None})
    assert not c3.keys[1][1].twist.any()
    with pytest.raises(ValueError, match="the motion has no joint 'LeftWrist' .*its joints are"):
        retarget(m, sk, mapping={"c": "LeftWrist"})
    with pytest.raises(ValueError, match="the rig has no bone 'z'; its bones are a, b, c"):
        retarget(m, sk, mapping={"z": "wrist"})
    with pytest.raises(ValueError, match="twist must be one of 'spread', 'joint'"):
        retarget(m, sk, mapping=mapping, twist="rigid")
    with pytest.raises(ValueError, match="stretch must be one of"):
        retarget(m, sk, mapping=mapping, stretch="x")
    with pytest.raises(ValueError, match="3D rig"):
        retarget(m, stbs.Skeleton([[0, 0], [1, 0]], [[0, 1]]))
    with pytest.raises(TypeError, match="motion must be a stbs.Motion"):
        retarget("m", sk)


def test_the_cmu_clip_drives_its_own_skeleton(shared_data):
    m = stbs.read_bvh(shared_data / "bvh11-cmu" / "131_03.bvh")
    part = stbs.Motion(m.names, m.parents, m.offsets, rotations=m.rotations[::20],
                       translations=m.translations[::20], frame_time=20 * m.frame_time,
                       end_site=m.end_site)
    sk, drive, end = part.skeleton()
    clip = retarget(part, sk)
    P = part.positions()
    th = np.array([p.twist for _, p in clip.keys])
    assert np.isfinite(th).all() and np.abs(th).max() > 0.1
    for k, (_, pose) in enumerate(clip.keys):
        assert np.isfinite(pose.rotations).all()
        np.testing.assert_allclose(pose.ends, P[k, end], atol=1e-9)
        np.testing.assert_allclose(pose.origins, P[k, drive], atol=1e-9)
