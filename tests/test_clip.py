"""stbs.Clip: keyed poses, interpolated between keys and held outside them."""

from __future__ import annotations

import numpy as np
import pytest

import stbs


def _bone_2d():
    return stbs.Skeleton([[0.0, 0.0], [1.0, 0.0]], [[0, 1]], names=["arm"])


def _chain_3d():
    return stbs.Skeleton([[0, 0, 0], [1, 0, 0], [2, 0, 0]], [[0, 1], [1, 2]],
                         names=["upper", "fore"])


def _angle(R):
    return float(np.degrees(np.arctan2(R[1, 0], R[0, 0])))


def _twisted(sk, end_deg):
    b = sk.n_bones
    th = np.zeros((b, 2))
    th[-1, 1] = np.radians(end_deg)
    return stbs.Pose(sk, rotations=np.tile(np.eye(3), (b, 1, 1)), origins=sk.A, twist=th)


def test_a_bone_turned_and_stretched_by_hand():
    sk = _bone_2d()
    key0 = stbs.Pose.rest(sk)
    key1 = stbs.forward_kinematics(sk, rotations=[np.pi / 2], stretch=[2.0])
    clip = stbs.Clip([(1.0, key0), (3.0, key1)])
    mid = clip.pose(2.0)
    assert _angle(mid.rotations[0]) == pytest.approx(45.0, abs=1e-12)
    assert mid.stretch[0] == pytest.approx(1.5, abs=1e-15)
    quarter = clip.pose(1.5)
    assert _angle(quarter.rotations[0]) == pytest.approx(22.5, abs=1e-12)
    assert quarter.stretch[0] == pytest.approx(1.25, abs=1e-15)
    # the posed end: rotated 45 degrees and 1.5 long
    assert np.allclose(mid.ends[0], 1.5 * np.array([np.sqrt(0.5), np.sqrt(0.5)]))


def test_twists_past_360_are_kept():
    sk = _chain_3d()
    clip = stbs.Clip([(0.0, stbs.Pose.rest(sk)), (2.0, _twisted(sk, 720.0))])
    assert np.degrees(clip.pose(1.0).twist[1, 1]) == pytest.approx(360.0, abs=1e-9)
    assert np.degrees(clip.pose(0.5).twist[1, 1]) == pytest.approx(180.0, abs=1e-9)
    assert np.degrees(clip.pose(1.5).twist[1, 1]) == pytest.approx(540.0, abs=1e-9)


def test_three_keys_pick_the_right_pair_and_keys_are_exact():
    sk = _bone_2d()
    poses = [stbs.forward_kinematics(sk, rotations=[np.radians(a)], stretch=[s])
             for a, s in ((0, 1.0), (60, 2.0), (30, 0.5))]
    # given out of order: sorted by time
    clip = stbs.Clip([(2.0, poses[2]), (0.0, poses[0]), (1.0, poses[1])])
    assert clip.times.tolist() == [0.0, 1.0, 2.0]
    assert [p for _, p in clip.keys] == poses
    assert clip.pose(1.0) is poses[1]
    assert _angle(clip.pose(1.5).rotations[0]) == pytest.approx(45.0, abs=1e-12)
    assert clip.pose(1.5).stretch[0] == pytest.approx(1.25)
    assert _angle(clip.pose(0.25).rotations[0]) == pytest.approx(15.0, abs=1e-12)
    assert clip.start == 0.0 and clip.end == 2.0 and clip.duration == 2.0
    assert len(clip) == 3 and clip.skeleton == sk


def test_clamped_before_the_first_and_after_the_last_key():
    sk = _bone_2d()
    a = stbs.forward_kinematics(sk, rotations=[0.3])
    b = stbs.forward_kinematics(sk, rotations=[1.2], stretch=[1.7])
    clip = stbs.Clip([(0.5, a), (1.5, b)])
    assert clip.pose(-10.0) is a and clip.pose(0.5) is a
    assert clip.pose(1.5) is b and clip.pose(99.0) is b


def test_step_interpolation_holds_each_key():
    sk = _bone_2d()
    a = stbs.forward_kinematics(sk, stretch=[1.0])
    b = stbs.forward_kinematics(sk, stretch=[2.0])
    c = stbs.forward_kinematics(sk, stretch=[3.0])
    clip = stbs.Clip([(0.0, a), (1.0, b), (2.0, c)], interpolation="step")
    assert [clip.pose(t).stretch[0] for t in (0.0, 0.99, 1.0, 1.5, 2.0, 3.0)] == \
        [1.0, 1.0, 2.0, 2.0, 3.0, 3.0]


def test_sample_includes_the_end_on_the_grid_only():
    sk = _bone_2d()
    a = stbs.Pose.rest(sk)
    b = stbs.forward_kinematics(sk, stretch=[2.0])
    clip = stbs.Clip([(0.5, a), (1.5, b)], fps=4)
    assert clip.sample_times().tolist() == [0.5, 0.75, 1.0, 1.25, 1.5]
    assert [p.stretch[0] for p in clip.sample()] == pytest.approx([1, 1.25, 1.5, 1.75, 2])
    # 1 s at 3 fps: 0, 1/3, 2/3, 1 (k / 3 is not exact in floating point; still on the grid)
    assert len(clip.sample_times(3)) == 4
    # 1 s at 2.5 fps: 0, 0.4, 0.8; 1.2 is past the end
    assert clip.sample_times(2.5) == pytest.approx([0.5, 0.9, 1.3])
    assert len(clip.sample(2.5)) == 3
    one = stbs.Clip([(2.0, b)])
    assert one.duration == 0.0 and one.sample_times().tolist() == [2.0]


@pytest.mark.parametrize("keys, fps, interp, err, match", [
    ([], 30, "linear", ValueError, "at least one"),
    ("abc", 30, "linear", TypeError, "list of"),
    ([(0.0,)], 30, "linear", TypeError, r"keys\[0\] must be a \(time, Pose\) pair"),
    ([(float("nan"), "P")], 30, "linear", ValueError, r"keys\[0\] time must be finite"),
    ([(0.0, "not a pose")], 30, "linear", TypeError, r"keys\[0\] pose must be a stbs.Pose"),
    ([("0", "P")], 30, "linear", TypeError, r"keys\[0\] time must be a real number"),
    ([(0.0, "P"), (0.0, "P")], 30, "linear", ValueError, "same time 0"),
    ([(0.0, "P")], 0, "linear", ValueError, "fps must be > 0, got 0"),
    ([(0.0, "P")], float("inf"), "linear", ValueError, "fps must be finite"),
    ([(0.0, "P")], 30, "cubic", ValueError, "interpolation must be one of linear, step, got "
                                            "'cubic'"),
])
def test_bad_input_is_named(keys, fps, interp, err, match):
    pose = stbs.Pose.rest(_bone_2d())
    keys = [tuple(pose if x == "P" else x for x in k) if isinstance(k, tuple) else k
            for k in keys] if isinstance(keys, list) else keys
    with pytest.raises(err, match=match):
        stbs.Clip(keys, fps=fps, interpolation=interp)


def test_keys_of_different_skeletons_are_refused_equal_ones_accepted():
    a = stbs.Pose.rest(_bone_2d())
    same = stbs.Pose.rest(_bone_2d())          # an equal skeleton, another object
    assert len(stbs.Clip([(0, a), (1, same)])) == 2
    other = stbs.Pose.rest(stbs.Skeleton([[0.0, 0.0], [2.0, 0.0]], [[0, 1]], names=["arm"]))
    with pytest.raises(ValueError, match=r"keys\[1\] pose is of another skeleton"):
        stbs.Clip([(0, a), (1, other)])


def test_pose_and_sample_check_their_arguments():
    clip = stbs.Clip([(0.0, stbs.Pose.rest(_bone_2d()))])
    with pytest.raises(ValueError, match="t must be finite"):
        clip.pose(float("nan"))
    with pytest.raises(ValueError, match="fps must be > 0"):
        clip.sample(-1)
    long = stbs.Clip([(0.0, stbs.Pose.rest(_bone_2d())), (1e6, stbs.Pose.rest(_bone_2d()))])
    with pytest.raises(ValueError, match="at most 100000"):
        long.sample_times()


# ---------------------------------------------------------------- the local frame
def _curl_chain():
    C = [[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]]
    return stbs.Skeleton(C, [[0, 1], [1, 2], [2, 3]], names=["a", "b", "c"])


def _rz(deg):
    a = np.radians(deg)
    return np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])


def test_a_curling_chain_never_tears_or_shrinks_between_keys():
    sk = _curl_chain()
    curled = stbs.forward_kinematics(sk, rotations=[_rz(90)] * 3)
    clip = stbs.Clip([(0.0, stbs.Pose.rest(sk)), (1.0, curled)])
    for t in np.linspace(0, 1, 21):
        pose = clip.pose(float(t))
        # connected: every child starts at its parent's posed end (gap < 1e-9)
        gap = np.linalg.norm(pose.origins[1:] - pose.ends[:-1], axis=1)
        assert gap.max() < 1e-9
        # bones keep their length, and the chain is forward kinematics of the slerped
        # local rotations (90 degrees per joint at t = 1)
        np.testing.assert_allclose(np.linalg.norm(pose.ends - pose.origins, axis=1), 1.0,
                                   atol=1e-12)
        want = stbs.forward_kinematics(sk, rotations=[_rz(90 * t)] * 3)
        np.testing.assert_allclose(pose.rotations, want.rotations, atol=1e-12)
        np.testing.assert_allclose(pose.origins, want.origins, atol=1e-12)
    # half-way the tip is where three 45-degree turns put it, not a third of the way
    tip = clip.pose(0.5).ends[2]
    a = np.radians([45, 90, 135])
    np.testing.assert_allclose(tip[:2], [np.cos(a).sum(), np.sin(a).sum()], atol=1e-12)


def test_offset_children_are_carried_between_keys():
    # hips with two legs hanging off its start and a spine: turning the hips turns all
    C = [[0, 0, 0], [0, 1, 0], [0.2, 0, 0], [0.2, -1, 0], [-0.2, 0, 0], [-0.2, -1, 0]]
    sk = stbs.Skeleton(C, [[0, 1], [2, 3], [4, 5]], names=["hips", "l", "r"], P=[-1, 0, 0])
    turned = stbs.forward_kinematics(sk, rotations=[_rz(90), np.eye(3), np.eye(3)])
    np.testing.assert_allclose(turned.origins[1], [0, 0.2, 0], atol=1e-12)
    clip = stbs.Clip([(0.0, stbs.Pose.rest(sk)), (2.0, turned)])
    mid = clip.pose(1.0)
    R = _rz(45)
    np.testing.assert_allclose(mid.origins[1:], (np.array(C)[[2, 4]]) @ R.T, atol=1e-12)
    np.testing.assert_allclose(mid.rotations[1:], [R, R], atol=1e-12)


def test_poses_for_many_times_equal_one_at_a_time():
    rng = np.random.default_rng(3)
    sk = _curl_chain()
    keys = []
    for k in range(4):
        q = rng.normal(size=(3, 4))
        R = stbs.transforms.quat_to_matrix(q / np.linalg.norm(q, axis=1, keepdims=True))
        keys.append((float(k), stbs.forward_kinematics(
            sk, rotations=R, stretch=rng.uniform(0.5, 2, 3), twist=rng.normal(size=4))))
    clip = stbs.Clip(keys)
    ts = np.linspace(-0.5, 3.5, 17)
    R, O, sig, th = clip.arrays(ts)
    for k, t in enumerate(ts):
        p = clip.pose(float(t))
        np.testing.assert_allclose(R[k], p.rotations, atol=1e-12)
        np.testing.assert_allclose(O[k], p.origins, atol=1e-12)
        np.testing.assert_allclose(sig[k], p.stretch, atol=1e-15)
        np.testing.assert_allclose(th[k], p.twist, atol=1e-15)
    # a key comes back as given
    for (_t, pose), Rk, Ok in zip(keys, *clip.arrays([t for t, _ in keys])[:2], strict=True):
        np.testing.assert_allclose(Rk, pose.rotations, atol=1e-12)
        np.testing.assert_allclose(Ok, pose.origins, atol=1e-12)


def test_from_local_step_and_cubic_channels():
    sk = _curl_chain()
    times = np.array([0.0, 1.0, 2.0])
    ang = np.radians([0.0, 60.0, 90.0])
    q = np.zeros((3, 3, 4))
    q[..., 0] = 1
    q[:, 0, 0], q[:, 0, 3] = np.cos(ang / 2), np.sin(ang / 2)
    q[:, 1] = q[:, 0]
    q[:, 2] = q[:, 0]
    zero = np.zeros_like(q)
    clip = stbs.Clip.from_local(sk, times, rotations=q,
                                rotation_interpolation=["linear", "step", "cubic"],
                                rotation_tangents=(zero, zero))
    L = clip.local([0.5, 1.5])[0]
    a = lambda R: np.degrees(np.arctan2(R[1, 0], R[0, 0]))   # noqa: E731
    assert a(L[0, 0]) == pytest.approx(30.0, abs=1e-9)       # slerp
    assert a(L[0, 1]) == pytest.approx(0.0, abs=1e-9)        # step: held
    assert a(L[1, 1]) == pytest.approx(60.0, abs=1e-9)
    # cubic Hermite with zero slopes: the quaternion half way between, normalised
    h = 0.5 * (q[0, 2] + q[1, 2])
    h /= np.linalg.norm(h)
    assert a(L[0, 2]) == pytest.approx(np.degrees(2 * np.arctan2(h[3], h[0])), abs=1e-9)
    assert clip.pose(1.0).rotations.shape == (3, 3, 3)
    with pytest.raises(ValueError, match="rotation_tangents"):
        stbs.Clip.from_local(sk, times, rotations=q, rotation_interpolation="cubic")
    with pytest.raises(ValueError, match="increase"):
        stbs.Clip.from_local(sk, [0.0, 0.0, 1.0], rotations=q)


def test_key_times_are_bounded_and_extreme_keys_never_overflow():
    # times at ±1.7e308 once made sample_times and local() overflow; a time is now within
    # ±MAX_TIME, checked before any conversion (a 401-digit integer included)
    sk = _bone_2d()
    rest = stbs.Pose.rest(sk)
    for t, match in [(1.7e308, r"keys\[0\] time must lie within ±1e\+06, got 1.7e\+308"),
                     (-2e6, r"within ±1e\+06"),
                     (10**400, r"keys\[0\] time must be finite, got an integer of about 401")]:
        with pytest.raises(ValueError, match=match):
            stbs.Clip([(t, rest)])
    with pytest.raises(ValueError, match=r"times must lie within ±1e\+06 s, got -1.7e\+308"):
        stbs.Clip.from_local(sk, [-1.7e308, 0.0])
    edge = stbs.Clip([(-stbs.clip.MAX_TIME, rest), (stbs.clip.MAX_TIME, rest)])
    assert edge.duration == 2e6
    # keys a denormal apart: far outside that piece the ratio overflows, quietly clipped
    # (a RuntimeWarning is an error in this test suite)
    tiny = stbs.Clip.from_local(sk, [0.0, 5e-324], rotations=[[[1, 0, 0, 0]], [[0, 0, 0, 1]]])
    R = tiny.arrays(np.array([-1e6, 1.0, 1e6]))[0]
    np.testing.assert_allclose(R[1:, 0], [[[-1, 0], [0, -1]]] * 2, atol=1e-12)
