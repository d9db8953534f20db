"""Skinned normals: turned by the blended rotation."""

import numpy as np
import pytest

import stbs
from rigs import random_pose, random_rig
from stbs import transforms as tf


def unit(X):
    return X / np.linalg.norm(X, axis=1, keepdims=True)


@pytest.mark.parametrize("method", stbs.METHODS)
def test_rigid_single_bone_turns_normals_by_R(method):
    sk = stbs.Skeleton([[0.0, 0, 0], [1, 0, 0]], [[0, 1]])
    rng = np.random.default_rng(0)
    V = rng.normal(size=(50, 3))
    N = unit(rng.normal(size=(50, 3)))
    R = tf.quat_to_matrix(rng.normal(size=4))
    P = stbs.Pose(sk, rotations=[R], origins=[[1.0, 2, 3]])
    dfm = stbs.Deformer(V, sk, np.ones((50, 1)), rng.random((50, 1)), method=method, normals=N)
    U, Nd = dfm.deform_with_normals(P)
    np.testing.assert_allclose(Nd, N @ R.T, atol=1e-12)
    np.testing.assert_allclose(U, dfm(P), atol=0)


@pytest.mark.parametrize("method", ["stbs-lbs", "stbs-dqs"])
def test_twist_turns_normals_with_the_section(method):
    sk = stbs.Skeleton([[0.0, 0, 0], [1, 0, 0]], [[0, 1]])
    V = np.array([[0.5, 1.0, 0.0]])
    N = np.array([[0.0, 1.0, 0.0]])  # outward normal of a tube
    P = stbs.Pose(sk, rotations=[np.eye(3)], origins=[[0.0, 0, 0]], twist=[[0, np.pi / 2]])
    dfm = stbs.Deformer(V, sk, [[1.0]], [[0.5]], method=method, normals=N)
    _, Nd = dfm.deform_with_normals(P)
    np.testing.assert_allclose(Nd, [[0.0, np.sqrt(0.5), np.sqrt(0.5)]], atol=1e-14)


def test_lbs_stretch_tilts_normals_by_inverse_transpose():
    # a plane x + z = 0 stretched 2x along x: its normal becomes (1, 0, 2)/sqrt(5)
    sk = stbs.Skeleton([[0.0, 0, 0], [1, 0, 0]], [[0, 1]])
    N = unit(np.array([[1.0, 0, 1]]))
    P = stbs.Pose(sk, rotations=[np.eye(3)], origins=[[0.0, 0, 0]], stretch=[2.0])
    dfm = stbs.Deformer([[0.3, 0, -0.3]], sk, [[1.0]], method="lbs", normals=N)
    _, Nd = dfm.deform_with_normals(P)
    np.testing.assert_allclose(Nd, unit(np.array([[1.0, 0, 2]])), atol=1e-14)


@pytest.mark.parametrize("d", [2, 3])
@pytest.mark.parametrize("method", stbs.METHODS)
def test_normals_unit_and_rest_identity(method, d):
    rng, sk, V, W, E = random_rig(11, d)
    N = unit(rng.normal(size=V.shape))
    dfm = stbs.Deformer(V, sk, W, E, method=method, normals=N)
    U0, N0 = dfm.deform_with_normals(stbs.Pose.rest(sk))
    np.testing.assert_allclose(N0, N, atol=1e-12)
    _, N1 = dfm.deform_with_normals(random_pose(rng, sk))
    np.testing.assert_allclose(np.linalg.norm(N1, axis=1), 1.0, atol=1e-12)


def test_normals_missing_is_an_error():
    sk = stbs.Skeleton([[0.0, 0, 0], [1, 0, 0]], [[0, 1]])
    dfm = stbs.Deformer([[0.0, 0, 0]], sk, [[1.0]])
    with pytest.raises(ValueError, match="normals"):
        dfm.deform_with_normals(stbs.Pose.rest(sk))
