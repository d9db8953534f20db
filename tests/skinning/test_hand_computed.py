"""One bone, a few vertices, stretch and twist worked out by hand."""

import numpy as np
import pytest

import stbs

SQ = np.sqrt(0.5)


@pytest.fixture
def one_bone():
    # bone from (0,0,0) to (1,0,0); rest axis u = x
    return stbs.Skeleton([[0.0, 0, 0], [1, 0, 0]], [[0, 1]])


def pose(sk, *, stretch=1.0, twist=(0.0, 0.0), R=None, origin=(0.0, 0, 0)):
    return stbs.Pose(sk, rotations=[np.eye(3) if R is None else R], origins=[origin],
                     stretch=[stretch], twist=[twist])


def run(sk, P, V, E, method):
    return stbs.deform(np.asarray(V, float), sk, P, np.ones((len(V), 1)), np.asarray(E, float),
                       method=method)


def test_stretch_beyond_end(one_bone):
    # p = (2, 1, 0), e = 1, sigma = 2: s = (1, 0, 0)
    P = pose(one_bone, stretch=2.0)
    V, E = [[2.0, 1, 0]], [[1.0]]
    for m in ("stbs-lbs", "stbs-dqs"):
        # eq. 5: a' + (e s + p - a) = (3, 1, 0): translated by s, not scaled
        np.testing.assert_allclose(run(one_bone, P, V, E, m), [[3.0, 1, 0]], atol=1e-14)
    # LBS: a' + S (p - a), S = diag(2, 1, 1) -> (4, 1, 0): the "explosion"
    np.testing.assert_allclose(run(one_bone, P, V, E, "lbs"), [[4.0, 1, 0]], atol=1e-14)
    # DQS blends the same stretch in rest space, then the (identity) rigid part
    np.testing.assert_allclose(run(one_bone, P, V, E, "dqs"), [[4.0, 1, 0]], atol=1e-14)


def test_stretch_midway_uses_endpoint_weight(one_bone):
    # p = (0.5, 0, 1) with e = 0.5 and sigma = 3: s = (2, 0, 0), p' = p + 0.5 s
    P = pose(one_bone, stretch=3.0)
    for m in ("stbs-lbs", "stbs-dqs"):
        np.testing.assert_allclose(run(one_bone, P, [[0.5, 0, 1]], [[0.5]], m), [[1.5, 0, 1]],
                                   atol=1e-14)


def test_twist_grows_along_bone(one_bone):
    # theta_b = 90 deg; p = (0.5, 1, 0) with e = 0.5 turns by 45 deg about x
    P = pose(one_bone, twist=(0.0, np.pi / 2))
    for m in ("stbs-lbs", "stbs-dqs"):
        np.testing.assert_allclose(run(one_bone, P, [[0.5, 1, 0]], [[0.5]], m),
                                   [[0.5, SQ, SQ]], atol=1e-14)
        # e = 1 at the far end: the full 90 deg, (1, 0, 1) -> (1, -1, 0)
        np.testing.assert_allclose(run(one_bone, P, [[1.0, 0, 1]], [[1.0]], m),
                                   [[1.0, -1, 0]], atol=1e-14)
    # LBS and DQS have no twist term: the vertex does not move
    for m in ("lbs", "dqs"):
        np.testing.assert_allclose(run(one_bone, P, [[0.5, 1, 0]], [[0.5]], m), [[0.5, 1, 0]],
                                   atol=1e-14)


def test_start_twist_and_rotation_and_translation(one_bone):
    # theta_a = 180, theta_b = 0: at e = 0 the section turns by 180 deg.
    # Then R = 90 deg about z, a' = (5, 0, 0): x -> y.
    Rz = np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]])
    P = pose(one_bone, twist=(np.pi, 0.0), R=Rz, origin=(5.0, 0, 0), stretch=2.0)
    # p = (0, 1, 0), e = 0: twist -> (0, -1, 0); R -> (1, 0, 0); + a' -> (6, 0, 0)
    for m in ("stbs-lbs", "stbs-dqs"):
        np.testing.assert_allclose(run(one_bone, P, [[0.0, 1, 0]], [[0.0]], m), [[6.0, 0, 0]],
                                   atol=1e-14)
        # p = (1, 0, 1), e = 1: no twist; stretch s = (1,0,0): (2, 0, 1) -> R -> (0, 2, 1) + a'
        np.testing.assert_allclose(run(one_bone, P, [[1.0, 0, 1]], [[1.0]], m), [[5.0, 2, 1]],
                                   atol=1e-14)


def test_two_bones_half_half_twist_opposite_dqs_vs_lbs():
    # Two collinear bones, the second turned 180 deg about x. A vertex at the joint with
    # weights 1/2, 1/2: LBS averages the matrices and collapses it onto the axis;
    # DQS turns it by 90 deg and keeps its distance.
    sk = stbs.Skeleton([[0.0, 0, 0], [1, 0, 0], [2, 0, 0]], [[0, 1], [1, 2]])
    Rx = np.diag([1.0, -1, -1])
    P = stbs.Pose(sk, rotations=[np.eye(3), Rx], origins=[[0.0, 0, 0], [1, 0, 0]])
    V = np.array([[1.0, 1, 0]])
    W = np.array([[0.5, 0.5]])
    np.testing.assert_allclose(stbs.deform(V, sk, P, W, method="lbs"), [[1.0, 0, 0]], atol=1e-14)
    U = stbs.deform(V, sk, P, W, method="dqs")
    assert abs(np.linalg.norm(U[0, 1:]) - 1.0) < 1e-14 and abs(U[0, 0] - 1.0) < 1e-14


def test_2d_stretch_and_rotation():
    sk = stbs.Skeleton([[0.0, 0], [2, 0]], [[0, 1]])
    P = stbs.Pose(sk, rotations=[np.pi / 2], origins=[[1.0, 1]], stretch=[1.5])
    # p = (3, 1), e = 1: s = (1, 0); e s + p - a = (4, 1); rotate 90 deg -> (-1, 4); + a'
    for m in ("stbs-lbs", "stbs-dqs"):
        U = stbs.deform([[3.0, 1]], sk, P, [[1.0]], [[1.0]], method=m)
        np.testing.assert_allclose(U, [[0.0, 5]], atol=1e-14)
    # LBS: S (p - a) = (4.5, 1) -> (-1, 4.5) + a' = (0, 5.5)
    np.testing.assert_allclose(stbs.deform([[3.0, 1]], sk, P, [[1.0]], method="lbs"),
                               [[0.0, 5.5]], atol=1e-14)
