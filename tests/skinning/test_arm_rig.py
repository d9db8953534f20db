"""Real data: the libigl arm rig (arm.obj, arm.tgf, arm-weights.dmat), bent and twisted."""

import numpy as np
import pytest

import stbs
from stbs import io
from stbs import transforms as tf


@pytest.fixture(scope="module")
def arm(shared_data):
    d = shared_data / "libigl-tutorial-data"
    V = io.read_mesh(d / "arm.obj").V
    sk = io.read_skeleton(d / "arm.tgf")
    W = io.read_dmat(d / "arm-weights.dmat")
    return V, sk, W


def radius(X, center, axis):
    r = X - center
    r -= np.outer(r @ axis, axis)
    return np.linalg.norm(r, axis=1)


def test_arm_loads(arm):
    V, sk, W = arm
    assert V.shape == (8311, 3) and sk.n_bones == 4 and W.shape == (8311, 4)
    np.testing.assert_array_equal(sk.parents, [-1, 0, 1, 2])


@pytest.fixture(scope="module")
def bent_and_twisted(arm):
    V, sk, W = arm
    # bend 60 deg at the elbow (start of bone 2), twist 180 deg at the wrist (joint 3)
    axis = np.cross(sk.axes[1], [0, 0, 1.0])
    L = np.tile(np.eye(3), (4, 1, 1))
    L[2] = tf.axis_angle_to_matrix(axis, np.radians(60))
    pose = stbs.forward_kinematics(sk, rotations=L, twist=[0, 0, 0, np.pi, 0])
    E = stbs.endpoint_weights(V, sk)
    return pose, E, {m: stbs.deform(V, sk, pose, W, E, method=m) for m in stbs.METHODS}


def test_lbs_collapses_wrist_dqs_and_stbs_dqs_do_not(arm, bent_and_twisted):
    V, sk, W = arm
    pose, _, U = bent_and_twisted
    wrist, u = sk.C[3], sk.axes[2]
    slab = np.abs((V - wrist) @ u + 0.03) < 0.015  # a forearm cross-section by the wrist
    assert slab.sum() > 50
    r0 = radius(V[slab], wrist, u).mean()
    ratio = {m: radius(U[m][slab], pose.origins[3], pose.rotations[2] @ u).mean() / r0
             for m in stbs.METHODS}
    assert ratio["lbs"] < 0.5  # candy wrapper
    assert ratio["dqs"] > 0.95 and ratio["stbs-dqs"] > 0.95
    assert ratio["stbs-lbs"] > 0.9  # the twist spread along the forearm avoids the collapse


def test_stbs_spreads_the_twist_along_the_forearm(arm, bent_and_twisted):
    V, sk, W = arm
    pose, E, U = bent_and_twisted
    # mid-forearm vertices dominated by the forearm bone
    mid = (W.argmax(axis=1) == 2) & (np.abs(E[:, 2] - 0.5) < 0.1)
    assert mid.sum() > 20
    a, u = sk.C[2], sk.axes[2]
    Rf = pose.rotations[2]

    def turn(X):
        # angle of each vertex about the forearm axis, after undoing the bend
        local = (X - pose.origins[2]) @ Rf  # back to rest orientation
        r_rest = V[mid] - a - np.outer((V[mid] - a) @ u, u)
        r_now = local - np.outer(local @ u, u)
        cos = np.sum(r_rest * r_now, 1)
        sin = np.cross(r_rest, r_now) @ u
        return np.degrees(np.arctan2(sin, cos))

    assert abs(np.median(turn(U["stbs-dqs"][mid])) - 90) < 20  # e ~ 0.5 of 180 deg
    assert abs(np.median(turn(U["dqs"][mid]))) < 20  # DQS keeps the twist at the wrist
