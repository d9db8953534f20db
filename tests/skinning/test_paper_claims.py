"""The paper's Fig. 2 and Fig. 3 as assertions on numbers (built-in shapes)."""

import numpy as np
import pytest

import stbs


def cigar(n_len=61, n_around=24):
    """An ellipsoid along x from -1.5 to 1.5 with a bone from -1 to 1 (paper Fig. 2)."""
    x = np.linspace(-1.5, 1.5, n_len)
    r = 0.4 * np.sqrt(np.clip(1 - (x / 1.5) ** 2, 0, None))
    t = np.linspace(0, 2 * np.pi, n_around, endpoint=False)
    V = np.stack([np.repeat(x, n_around), np.outer(r, np.cos(t)).ravel(),
                  np.outer(r, np.sin(t)).ravel()], axis=1)
    sk = stbs.Skeleton([[-1.0, 0, 0], [1, 0, 0]], [[0, 1]])
    return V, sk


def box(n=41):
    """A box [0, 2] x [-0.25, 0.25]^2 (its volume grid) and a bone along x (paper Fig. 3)."""
    g = np.linspace(-0.25, 0.25, 5)
    x = np.linspace(0.0, 2.0, n)
    X, Y, Z = np.meshgrid(x, g, g, indexing="ij")
    V = np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=1)
    sk = stbs.Skeleton([[0.0, 0, 0], [2, 0, 0]], [[0, 1]])
    return V, sk


@pytest.mark.parametrize("method", ["stbs-lbs", "stbs-dqs"])
def test_fig2_cigar_stretch_keeps_tip_rigid(method):
    V, sk = cigar()
    W = np.ones((len(V), 1))
    E = stbs.endpoint_weights(V, sk, method="projection")
    P = stbs.Pose(sk, rotations=[np.eye(3)], origins=[[-1.0, 0, 0]], stretch=[2.0])
    s = np.array([2.0, 0, 0])  # (sigma - 1)(b - a)
    beyond = V[:, 0] > 1.0
    behind = V[:, 0] < -1.0
    U = stbs.deform(V, sk, P, W, E, method=method)
    # the part beyond the end translates by s: same shape, same size
    np.testing.assert_allclose(U[beyond] - V[beyond], np.broadcast_to(s, U[beyond].shape),
                               atol=1e-12)
    # the part behind the start does not move at all
    np.testing.assert_allclose(U[behind], V[behind], atol=1e-12)
    tip_len_rest = V[beyond, 0].max() - 1.0
    tip_len = U[beyond, 0].max() - 3.0  # the bone's posed end is at x = 3
    assert abs(tip_len / tip_len_rest - 1.0) < 1e-12
    # LBS scales the whole cigar about a by sigma along the bone: the tip doubles
    L = stbs.deform(V, sk, P, W, method="lbs")
    lbs_tip = L[beyond, 0].max() - 3.0  # the bone's posed end is at x = 3
    assert abs(lbs_tip / tip_len_rest - 2.0) < 1e-12
    # and the part behind the start is pushed out by sigma as well
    assert abs((-1.0 - L[behind, 0].min()) / (-1.0 - V[behind, 0].min()) - 2.0) < 1e-12


def section_angles(V, U):
    """Signed turn angle (about x) of each vertex off the axis, unwrapped along x."""
    a0 = np.arctan2(V[:, 2], V[:, 1])
    a1 = np.arctan2(U[:, 2], U[:, 1])
    return np.mod(a1 - a0 + np.pi, 2 * np.pi) - np.pi


@pytest.mark.parametrize("method", ["stbs-lbs", "stbs-dqs"])
@pytest.mark.parametrize("degrees", [315.0, 720.0 + 45.0])
def test_fig3_box_twist_spreads_along_bone(method, degrees):
    V, sk = box()
    W = np.ones((len(V), 1))
    E = stbs.endpoint_weights(V, sk, method="projection")
    theta = np.radians(degrees)
    P = stbs.Pose(sk, rotations=[np.eye(3)], origins=[[0.0, 0, 0]], twist=[[0.0, theta]])
    U = stbs.deform(V, sk, P, W, E, method=method)
    off = np.linalg.norm(V[:, 1:], axis=1) > 1e-9
    # each cross-section x is turned rigidly by e * theta, e = x / 2
    want = np.mod(E[off, 0] * theta + np.pi, 2 * np.pi) - np.pi
    got = section_angles(V[off], U[off])
    diff = np.mod(got - want + np.pi, 2 * np.pi) - np.pi
    assert np.abs(diff).max() < 1e-12
    # distances to the axis and positions along it are kept (a twist, not a collapse)
    np.testing.assert_allclose(np.linalg.norm(U[:, 1:], axis=1),
                               np.linalg.norm(V[:, 1:], axis=1), atol=1e-12)
    np.testing.assert_allclose(U[:, 0], V[:, 0], atol=1e-12)


def test_fig3_lbs_dqs_can_only_turn_the_whole_box():
    # With one bone, the only way LBS/DQS can twist is to rotate the bone: every
    # cross-section turns by the same angle.
    V, sk = box()
    W = np.ones((len(V), 1))
    R = stbs.transforms.axis_angle_to_matrix([1.0, 0, 0], np.radians(315))
    P = stbs.Pose(sk, rotations=[R], origins=[[0.0, 0, 0]])
    off = np.linalg.norm(V[:, 1:], axis=1) > 1e-9
    for method in ("lbs", "dqs"):
        ang = section_angles(V[off], stbs.deform(V, sk, P, W, method=method)[off])
        assert np.ptp(np.mod(ang, 2 * np.pi)) < 1e-12


@pytest.mark.parametrize("method", ["stbs-lbs", "stbs-dqs"])
def test_stretched_and_twisted_result_is_continuous(method):
    # Lipschitz check of the deformation map: nearby points stay nearby, also across
    # the bone's ends where projection endpoint weights are only C0.
    _, sk = box()
    rng = np.random.default_rng(0)
    p = rng.uniform([-0.5, -0.3, -0.3], [2.5, 0.3, 0.3], (4000, 3))
    p[:200, 0] = rng.choice([0.0, 2.0], 200)  # right on the ends
    dp = rng.normal(size=p.shape)
    dp *= 1e-7 / np.linalg.norm(dp, axis=1, keepdims=True)
    V = np.vstack([p, p + dp])
    W = np.ones((len(V), 1))
    E = stbs.endpoint_weights(V, sk, method="projection")
    P = stbs.Pose(sk, rotations=[np.eye(3)], origins=[[0.0, 0, 0]], stretch=[1.7],
                  twist=[[0.3, np.radians(315)]])
    U = stbs.deform(V, sk, P, W, E, method=method)
    ratio = np.linalg.norm(U[4000:] - U[:4000], axis=1) / 1e-7
    # sigma 1.7 plus a 315 deg twist over length 2 at radius <= 0.43: |grad| < 1.7 + 1.2
    assert ratio.max() < 3.5
