"""Bad input through the API: each a clear ValueError naming the input."""

import warnings

import numpy as np
import pytest
import scipy.sparse as sp

import stbs


@pytest.fixture
def rig():
    sk = stbs.Skeleton([[0.0, 0, 0], [1, 0, 0], [2, 0, 0]], [[0, 1], [1, 2]])
    V = np.array([[0.2, 0.1, 0], [1.5, 0, 0.1], [1.0, 0.2, 0.2]])
    W = np.array([[1.0, 0], [0, 1], [0.5, 0.5]])
    E = np.array([[0.2, 0], [0, 0.5], [1, 0]])
    return sk, V, W, E


@pytest.mark.parametrize("change, match", [
    (dict(V=np.zeros((3, 2))), r"V must have shape \(3, 3\) to match the 3D skeleton"),
    (dict(V=np.zeros((3, 4))), r"V must have shape \(n, 2\) or \(n, 3\)"),
    (dict(V=np.zeros(3)), "V must be a 2-D array"),
    (dict(V=[[0, 0, np.nan]] * 3), "V must be finite"),
    (dict(V="abc"), "V must be a numeric array"),
    (dict(W=np.ones((3, 3)) / 3), r"W must have shape \(3, 2\)"),
    (dict(W=[[1.0, 0], [np.inf, 0], [0, 1]]), "W must be finite"),
    (dict(W=[[1.2, -0.2], [0, 1], [0.5, 0.5]]),
     r"W must be >= 0, got -0.2 at \(vertex, bone\) = \(0, 1\)"),
    (dict(W=[[0.0, 0], [0, 1], [0.5, 0.5]]), "row 0 sums to 0"),
    (dict(E=[[1.5, 0], [0, 1], [0, 0]]), r"E must lie in \[0, 1\], got 1.5"),
    (dict(E=[[-0.5, 0], [0, 1], [0, 0]]), r"E must lie in \[0, 1\], got -0.5"),
    (dict(E=np.zeros((3, 1))), r"E must have shape \(3, 2\)"),
    (dict(method="lbs2"), "method must be one of 'lbs', 'dqs', 'stbs-lbs', 'stbs-dqs', got 'lbs2'"),
    (dict(dtype=np.int32), "dtype must be float32 or float64"),
])
def test_deform_rejects(rig, change, match):
    sk, V, W, E = rig
    args = dict(V=V, W=W, E=E, method="stbs-dqs", dtype=None)
    args.update(change)
    with pytest.raises(ValueError, match=match):
        stbs.Deformer(args["V"], sk, args["W"], args["E"], method=args["method"],
                      dtype=args["dtype"])


def test_sparse_negative_weight_named(rig):
    sk, V, W, E = rig
    Ws = sp.csr_array(np.array([[1.0, 0], [0, 1], [1.5, -0.5]]))
    with pytest.raises(ValueError, match=r"\(vertex, bone\) = \(2, 1\)"):
        stbs.deform(V, sk, stbs.Pose.rest(sk), Ws, E)


def test_unnormalised_weights_warn_and_renormalise(rig):
    sk, V, W, E = rig
    pose = stbs.forward_kinematics(sk, stretch=[1.5, 0.8])
    with pytest.warns(UserWarning, match="1 of 3 rows do not sum to 1"):
        U = stbs.deform(V, sk, pose, W * [[1], [1], [3]], E)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        np.testing.assert_allclose(U, stbs.deform(V, sk, pose, W, E), atol=1e-14)
        # solver round-off below -1e-10 is clipped silently
        stbs.deform(V, sk, pose, W + [[0, -1e-13], [0, 0], [0, 0]], E)


def test_pose_of_another_skeleton(rig):
    sk, V, W, E = rig
    other = stbs.Skeleton([[0.0, 0, 0], [1, 0, 0], [3, 0, 0]], [[0, 1], [1, 2]])
    with pytest.raises(ValueError, match="different skeleton"):
        stbs.Deformer(V, sk, W, E)(stbs.Pose.rest(other))
    with pytest.raises(TypeError, match="pose must be a stbs.Pose"):
        stbs.Deformer(V, sk, W, E)("rest")
    with pytest.raises(TypeError, match="sk must be a stbs.Skeleton"):
        stbs.Deformer(V, "sk", W, E)


def test_stbs_without_E_uses_projection(rig):
    sk, V, W, _ = rig
    pose = stbs.forward_kinematics(sk, stretch=[2.0, 1.0])
    np.testing.assert_allclose(
        stbs.deform(V, sk, pose, W, method="stbs-lbs"),
        stbs.deform(V, sk, pose, W, stbs.endpoint_weights(V, sk), method="stbs-lbs"))


def test_antipodal_and_past_360_twists_are_continuous():
    # twist theta_b from 0 to 4 turns in small steps: stbs-dqs never jumps
    sk = stbs.Skeleton([[0.0, 0, 0], [1, 0, 0]], [[0, 1]])
    V = np.array([[0.37, 0.3, 0.1], [1.0, 0.0, 0.3]])
    E = stbs.endpoint_weights(V, sk)
    dfm = stbs.Deformer(V, sk, np.ones((2, 1)), E, method="stbs-dqs")
    prev = None
    for th in np.linspace(0, 8 * np.pi, 801):
        U = dfm(stbs.Pose(sk, rotations=[np.eye(3)], origins=[[0.0, 0, 0]], twist=[[0, th]]))
        if prev is not None:
            assert np.abs(U - prev).max() < 0.02
        prev = U.copy()
    # 4 full turns: the end section is back home, the one at e = 0.37 turned 0.37 * 4 turns
    np.testing.assert_allclose(prev[1], V[1], atol=1e-12)
    R = stbs.transforms.axis_angle_to_matrix([1.0, 0, 0], 0.37 * 8 * np.pi)
    np.testing.assert_allclose(prev[0], R @ V[0], atol=1e-12)
