"""Poses: the three constructors of DESIGN §2, composition and interpolation."""

import numpy as np
import pytest

import stbs
from rigs import random_pose, random_rig, random_rotations
from stbs import transforms as tf


@pytest.fixture
def arm():
    # shoulder -> elbow -> wrist -> fingertip along x
    C = [[0.0, 0, 0], [1, 0, 0], [2, 0, 0], [2.5, 0, 0]]
    return stbs.Skeleton(C, [[0, 1], [1, 2], [2, 3]], names=["upper", "fore", "hand"])


def test_rest_pose(arm):
    P = stbs.Pose.rest(arm)
    assert P.is_rest()
    np.testing.assert_allclose(P.ends, arm.B)
    np.testing.assert_allclose(P.joints(), arm.C)


def test_fk_children_start_at_stretched_parent_end(arm):
    Rz = tf.axis_angle_to_matrix([0, 0, 1.0], np.pi / 2)
    P = stbs.forward_kinematics(arm, rotations=[Rz, np.eye(3), np.eye(3)], stretch=[2, 1, 1],
                                translation=[0, 0, 1])
    # upper arm turned to +y and doubled: elbow at (0, 2, 1); everything below follows
    np.testing.assert_allclose(P.origins, [[0, 0, 1], [0, 2, 1], [0, 3, 1]], atol=1e-15)
    np.testing.assert_allclose(P.ends[2], [0, 3.5, 1], atol=1e-15)
    for i in (1, 2):
        np.testing.assert_allclose(P.origins[i], P.ends[i - 1], atol=1e-15)


def test_fk_wrist_twist_spreads_along_forearm_and_turns_hand(arm):
    # paper Fig. 5: 180 deg at the wrist (joint 2)
    P = stbs.forward_kinematics(arm, twist=[0, 0, np.pi, 0])
    np.testing.assert_allclose(P.twist, [[0, 0], [0, np.pi], [0, 0]])
    # the hand inherits R_fore K_fore(1): a half turn about x
    np.testing.assert_allclose(P.rotations[2], np.diag([1.0, -1, -1]), atol=1e-15)
    np.testing.assert_allclose(P.rotations[1], np.eye(3))
    # skinning: a point on the hand turns by 180, one mid-forearm by 90
    V = np.array([[2.25, 0.1, 0], [1.5, 0.1, 0]])
    W = np.array([[0, 0, 1.0], [0, 1.0, 0]])
    E = stbs.endpoint_weights(V, arm)
    U = stbs.deform(V, arm, P, W, E, method="stbs-dqs")
    np.testing.assert_allclose(U, [[2.25, -0.1, 0], [1.5, 0, 0.1]], atol=1e-14)


def test_fk_root_twist_turns_root_bone_rigidly(arm):
    P = stbs.forward_kinematics(arm, twist=[np.pi / 2, 0, 0, 0])
    np.testing.assert_allclose(P.twist[0], [np.pi / 2, np.pi / 2])
    np.testing.assert_allclose(P.twist[1:], 0)


def test_fk_local_rotations_compose_down_the_chain(arm):
    Rz = tf.axis_angle_to_matrix([0, 0, 1.0], np.pi / 2)
    P = stbs.forward_kinematics(arm, rotations=[Rz, Rz, np.eye(3)])
    np.testing.assert_allclose(P.rotations[1], Rz @ Rz, atol=1e-15)
    np.testing.assert_allclose(P.ends[1], [-1, 1, 0], atol=1e-15)


def test_from_joints_round_trip():
    rng, sk, *_ = random_rig(21, 3)
    P = stbs.forward_kinematics(sk, rotations=random_rotations(rng, sk.n_bones, 3),
                                stretch=rng.uniform(0.5, 2, sk.n_bones))
    Q = stbs.Pose.from_joints(sk, P.joints())
    np.testing.assert_allclose(Q.origins, P.origins, atol=1e-12)
    np.testing.assert_allclose(Q.ends, P.ends, atol=1e-12)
    np.testing.assert_allclose(Q.stretch, P.stretch, atol=1e-12)
    # from_joints picks the smallest rotation: its angle never exceeds FK's
    _, a_fk = tf.quat_to_axis_angle(tf.matrix_to_quat(P.rotations))
    _, a_min = tf.quat_to_axis_angle(tf.matrix_to_quat(Q.rotations))
    assert np.all(a_min <= a_fk + 1e-12)


def test_from_joints_2d_and_errors():
    sk = stbs.Skeleton([[0.0, 0], [1, 0]], [[0, 1]])
    P = stbs.Pose.from_joints(sk, [[1.0, 1], [1, 3]])
    np.testing.assert_allclose(P.rotations[0], [[0, -1], [1, 0]], atol=1e-15)
    assert P.stretch[0] == pytest.approx(2.0)
    with pytest.raises(ValueError, match="zero posed length"):
        stbs.Pose.from_joints(sk, [[1.0, 1], [1, 1]])
    with pytest.raises(ValueError, match=r"C_posed must have shape \(2, 2\)"):
        stbs.Pose.from_joints(sk, [[1.0, 1, 0], [1, 1, 0]])
    with pytest.raises(ValueError, match="twist must be 0 in 2D"):
        stbs.Pose.from_joints(sk, [[0.0, 0], [1, 0]], twist=[[0, 1.0]])


def test_compose_and_interpolate():
    rng, sk, V, W, E = random_rig(22, 3)
    A, B = random_pose(rng, sk), random_pose(rng, sk)
    rest = stbs.Pose.rest(sk)
    for P in (A.compose(rest), rest.compose(A)):
        np.testing.assert_allclose(P.rotations, A.rotations, atol=1e-14)
        np.testing.assert_allclose(P.origins, A.origins, atol=1e-14)
        np.testing.assert_allclose(P.stretch, A.stretch)
    # composition of the rigid parts is composition of maps (no stretch or twist)
    A0 = stbs.Pose(sk, rotations=A.rotations, origins=A.origins)
    B0 = stbs.Pose(sk, rotations=B.rotations, origins=B.origins)
    U_ab = stbs.deform(V, sk, A0.compose(B0), W, method="lbs")
    W1 = np.eye(sk.n_bones)[np.argmax(W, axis=1)]  # rigid per bone: maps compose exactly
    U_a = stbs.deform(V, sk, A0, W1, method="lbs")
    i = np.argmax(W, axis=1)
    Rb, ob, a = B0.rotations[i], B0.origins[i], sk.A[i]
    np.testing.assert_allclose(stbs.deform(V, sk, A0.compose(B0), W1, method="lbs"),
                               ob + np.einsum("nij,nj->ni", Rb, U_a - a), atol=1e-12)
    assert U_ab.shape == V.shape
    # interpolation: end points, and linear stretch/twist (twists past 360 kept)
    np.testing.assert_allclose(A.interpolate(B, 0).rotations, A.rotations, atol=1e-12)
    np.testing.assert_allclose(A.interpolate(B, 1).rotations, B.rotations, atol=1e-12)
    M = A.interpolate(B, 0.25)
    np.testing.assert_allclose(M.stretch, 0.75 * A.stretch + 0.25 * B.stretch)
    np.testing.assert_allclose(M.twist, 0.75 * A.twist + 0.25 * B.twist)
    # rotations are slerped in the local (parent) frame, not the world frame
    qa, qb, qm = (tf.matrix_to_quat(P.local()[0]) for P in (A, B, M))
    np.testing.assert_allclose(np.abs(np.sum(qm * tf.quat_slerp(qa, qb, 0.25), -1)), 1,
                               atol=1e-12)
    # an equal skeleton (another object, as a rig or a file gives) is accepted ...
    equal = stbs.Skeleton(sk.C.copy(), sk.BE.copy())
    np.testing.assert_allclose(A.interpolate(stbs.Pose.rest(equal), 0.0).rotations,
                               A.rotations, atol=1e-12)
    # ... a different one is not
    moved = stbs.Skeleton(sk.C + 1.0, sk.BE)
    with pytest.raises(ValueError, match="equal skeleton"):
        A.interpolate(stbs.Pose.rest(moved), 0.5)
    with pytest.raises(ValueError, match="equal skeleton"):
        A.compose(stbs.Pose.rest(moved))


@pytest.mark.parametrize("kwargs, match", [
    (dict(rotations=np.zeros((2, 3, 3))), r"rotations\[0\] must be a rotation"),
    (dict(rotations=np.tile(np.diag([1.0, 1, -1]), (2, 1, 1))), "det"),
    (dict(rotations=np.eye(3)), r"rotations must have shape \(2, 3, 3\)"),
    (dict(origins=np.zeros((2, 2))), r"origins must have shape \(2, 3\)"),
    (dict(origins=np.full((2, 3), np.inf)), "origins must be finite"),
    (dict(stretch=[1.0, 0.0]), "stretch must be > 0, got 0 for bone 1"),
    (dict(stretch=[1.0, np.nan]), "stretch must be finite"),
    (dict(twist=np.zeros(2)), r"twist must have shape \(2, 2\)"),
])
def test_invalid_poses(kwargs, match):
    sk = stbs.Skeleton([[0.0, 0, 0], [1, 0, 0], [2, 0, 0]], [[0, 1], [1, 2]])
    args = dict(rotations=np.tile(np.eye(3), (2, 1, 1)), origins=sk.A)
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        stbs.Pose(sk, **args)


def test_fk_errors():
    sk2 = stbs.Skeleton([[0.0, 0], [1, 0]], [[0, 1]])
    with pytest.raises(ValueError, match="twist must be 0 in 2D"):
        stbs.forward_kinematics(sk2, twist=[0, 1.0])
    with pytest.raises(ValueError, match=r"stretch must be > 0"):
        stbs.forward_kinematics(sk2, stretch=[-1.0])
    with pytest.raises(TypeError, match="stbs.Skeleton"):
        stbs.forward_kinematics("arm")
    P = stbs.forward_kinematics(sk2, rotations=[np.pi / 2])
    np.testing.assert_allclose(P.ends, [[0, 1]], atol=1e-15)
