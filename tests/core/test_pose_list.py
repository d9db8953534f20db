"""``stbs.pose.pose_list``: the one check of a list of poses of a skeleton."""

from __future__ import annotations

import pytest

import stbs
from stbs.pose import pose_list


def test_pose_list_takes_any_sequence_of_poses_of_the_skeleton():
    sk = stbs.Skeleton([[0, 0, 0], [1, 0, 0]], [[0, 1]])
    poses = (stbs.Pose.rest(sk), stbs.forward_kinematics(sk, stretch=[2.0]))
    assert pose_list(poses, sk) == list(poses)
    assert pose_list(iter(poses), sk) == list(poses)


@pytest.mark.parametrize("bad, error, says", [
    ("rest", TypeError, "wrap a single Pose in a list"),
    ([], ValueError, "at least one stbs.Pose"),
    (["x"], TypeError, "poses[0] must be a stbs.Pose, got str"),
    ("other", ValueError, "poses[1] must be a pose of the skeleton"),
    (3, TypeError, "got int"),
])
def test_pose_list_names_what_is_wrong(bad, error, says):
    sk = stbs.Skeleton([[0, 0, 0], [1, 0, 0]], [[0, 1]])
    other = stbs.Skeleton([[0, 0, 0], [0, 1, 0]], [[0, 1]])
    if bad == "rest":
        bad = stbs.Pose.rest(sk)
    elif bad == "other":
        bad = [stbs.Pose.rest(sk), stbs.Pose.rest(other)]
    with pytest.raises(error) as exc:
        pose_list(bad, sk)
    assert says in str(exc.value)
