"""Round trips and identities of the batched rotation / quaternion / dual-quaternion helpers."""

import numpy as np
import pytest

from stbs import transforms as tf


@pytest.fixture
def rng():
    return np.random.default_rng(0)


def test_quat_matrix_round_trip(rng):
    q = tf.quat_normalize(rng.normal(size=(500, 4)))
    q *= np.sign(q[:, :1])
    R = tf.quat_to_matrix(q)
    np.testing.assert_allclose(np.einsum("nij,nkj->nik", R, R), np.broadcast_to(np.eye(3), R.shape),
                               atol=1e-14)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-14)
    np.testing.assert_allclose(tf.matrix_to_quat(R), q, atol=1e-14)


def test_matrix_to_quat_near_half_turn():
    # Shepperd's method stays accurate where w ~ 0
    for axis in np.eye(3):
        R = tf.axis_angle_to_matrix(axis, np.pi - 1e-9)
        q = tf.matrix_to_quat(R)
        np.testing.assert_allclose(tf.quat_to_matrix(q), R, atol=1e-14)


def test_axis_angle_round_trip(rng):
    axis = rng.normal(size=(100, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    angle = rng.uniform(0, np.pi, 100)
    a2, g2 = tf.quat_to_axis_angle(tf.axis_angle_to_quat(axis, angle))
    np.testing.assert_allclose(g2, angle, atol=1e-12)
    np.testing.assert_allclose(a2, axis, atol=1e-9)
    # a hand case: 90 deg about z takes x to y
    np.testing.assert_allclose(tf.axis_angle_to_matrix([0, 0, 2.0], np.pi / 2) @ [1, 0, 0],
                               [0, 1, 0], atol=1e-15)


def test_quat_mul_matches_matrix_product(rng):
    p, q = tf.quat_normalize(rng.normal(size=(2, 50, 4)))
    np.testing.assert_allclose(tf.quat_to_matrix(tf.quat_mul(p, q)),
                               tf.quat_to_matrix(p) @ tf.quat_to_matrix(q), atol=1e-14)
    x = rng.normal(size=(50, 3))
    np.testing.assert_allclose(tf.rotate(p, x), np.einsum("nij,nj->ni", tf.quat_to_matrix(p), x),
                               atol=1e-14)


def test_rotation_between_is_minimal(rng):
    u, v = rng.normal(size=(2, 200, 3))
    R = tf.rotation_between(u, v)
    got = np.einsum("nij,nj->ni", R, u / np.linalg.norm(u, axis=1, keepdims=True))
    np.testing.assert_allclose(got, v / np.linalg.norm(v, axis=1, keepdims=True), atol=1e-13)
    # minimal: the rotation angle equals the angle between u and v
    _, ang = tf.quat_to_axis_angle(tf.matrix_to_quat(R))
    cos = np.sum(u * v, 1) / np.linalg.norm(u, axis=1) / np.linalg.norm(v, axis=1)
    np.testing.assert_allclose(ang, np.arccos(np.clip(cos, -1, 1)), atol=1e-7)
    # antiparallel and parallel vectors
    for a in np.eye(3):
        np.testing.assert_allclose(tf.rotation_between(a, -a) @ a, -a, atol=1e-15)
        np.testing.assert_allclose(tf.rotation_between(a, 3 * a), np.eye(3), atol=1e-15)
    # 2D
    R2 = tf.rotation_between([1.0, 0], [0, 2.0])
    np.testing.assert_allclose(R2, [[0, -1], [1, 0]], atol=1e-15)
    with pytest.raises(ValueError, match="non-zero"):
        tf.rotation_between([0.0, 0, 0], [1.0, 0, 0])


def test_slerp(rng):
    q0, q1 = tf.quat_normalize(rng.normal(size=(2, 20, 4)))
    np.testing.assert_allclose(np.abs(np.sum(tf.quat_slerp(q0, q1, 0.0) * q0, -1)), 1, atol=1e-12)
    np.testing.assert_allclose(np.abs(np.sum(tf.quat_slerp(q0, q1, 1.0) * q1, -1)), 1, atol=1e-12)
    # the half-way rotation is the half angle of the relative rotation
    half = tf.quat_slerp(q0, q1, 0.5)
    _, full = tf.quat_to_axis_angle(tf.quat_mul(q1, tf.quat_conj(q0)))
    _, part = tf.quat_to_axis_angle(tf.quat_mul(half, tf.quat_conj(q0)))
    np.testing.assert_allclose(part, full / 2, atol=1e-12)
    # 2D matrices take the short way round
    R = tf.matrix_slerp(tf.rotation_2d(np.radians(170)), tf.rotation_2d(np.radians(-170)), 0.5)
    np.testing.assert_allclose(tf.angle_2d(R), np.pi, atol=1e-12)


def test_dual_quaternion_round_trip_and_product(rng):
    q = tf.quat_normalize(rng.normal(size=(30, 4)))
    t = rng.normal(size=(30, 3))
    qr, qd = tf.dq_from_rt(q, t)
    q2, t2 = tf.dq_to_rt(qr, qd)
    np.testing.assert_allclose(t2, t, atol=1e-13)
    np.testing.assert_allclose(np.abs(np.sum(q2 * q, -1)), 1, atol=1e-14)
    x = rng.normal(size=(30, 3))
    np.testing.assert_allclose(tf.dq_apply(qr, qd, x), tf.rotate(q, x) + t, atol=1e-13)
    # product = composition (apply b first)
    p = tf.quat_normalize(rng.normal(size=(30, 4)))
    s = rng.normal(size=(30, 3))
    b = tf.dq_from_rt(p, s)
    ab = tf.dq_mul((qr, qd), b)
    np.testing.assert_allclose(tf.dq_apply(*ab, x), tf.dq_apply(qr, qd, tf.dq_apply(*b, x)),
                               atol=1e-12)
    # -q is the same rigid map
    np.testing.assert_allclose(tf.dq_apply(-qr, -qd, x), tf.dq_apply(qr, qd, x), atol=1e-13)


def test_dq_blend_pivot_makes_it_sign_independent(rng):
    q = tf.quat_normalize(rng.normal(size=(3, 4)))
    t = rng.normal(size=(3, 3))
    qr, qd = tf.dq_from_rt(q, t)
    w = np.array([0.5, 0.3, 0.2])
    a = tf.dq_blend(w, qr, qd)
    flip = np.array([1.0, -1, -1])[:, None]
    b = tf.dq_blend(w, qr * flip, qd * flip)
    x = rng.normal(size=(5, 3))
    np.testing.assert_allclose(tf.dq_apply(*a, x), tf.dq_apply(*b, x), atol=1e-13)
