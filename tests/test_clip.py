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
