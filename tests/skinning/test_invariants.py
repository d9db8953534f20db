"""DESIGN §3 invariants on seeded random rigs: every method, 2D and 3D, float64 and float32."""

import numpy as np
import pytest
import scipy.sparse as sp

import stbs
from rigs import random_pose, random_rig, random_rotations, random_skeleton, random_weights
from stbs.skinning.reference import reference_deform

METHODS = stbs.METHODS
DIMS = (2, 3)
DTYPES = (np.float64, np.float32)


def tol(dtype, scale):
    # float64: a few ulps of the coordinate scale. float32: V, W, E are rounded to
    # float32 on storage (relative error 6e-8 each) and the output once more; the
    # kernels compute in float64, so the error stays below ~10 float32 ulps of the
    # largest coordinate (|U| <= ~10 here), i.e. 1e-6 * scale. We allow 2e-6 * scale.
    return (1e-11 if dtype == np.float64 else 2e-6) * scale


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("d", DIMS)
@pytest.mark.parametrize("method", METHODS)
def test_rest_pose_reproduces_V(method, d, dtype):
    _, sk, V, W, E = random_rig(1, d)
    U = stbs.Deformer(V, sk, W, E, method=method, dtype=dtype)(stbs.Pose.rest(sk))
    assert U.dtype == dtype
    assert np.abs(U - V).max() <= tol(dtype, np.abs(V).max())


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("d", DIMS)
@pytest.mark.parametrize("method", METHODS)
def test_matches_reference(method, d, dtype):
    rng, sk, V, W, E = random_rig(2, d)
    for _ in range(3):
        pose = random_pose(rng, sk)
        ref = reference_deform(V, pose, W, E, method)
        U = stbs.Deformer(V, sk, W, E, method=method, dtype=dtype)(pose)
        assert np.abs(U - ref).max() <= tol(dtype, np.abs(ref).max())


@pytest.mark.parametrize("d", DIMS)
@pytest.mark.parametrize("base", ["lbs", "dqs"])
def test_stbs_reduces_to_base_without_stretch_or_twist(base, d):
    rng, sk, V, W, E = random_rig(3, d)
    pose = random_pose(rng, sk, stretch=False, twist=False)
    U0 = stbs.deform(V, sk, pose, W, method=base)
    for E_any in (E, np.zeros_like(E), np.ones_like(E)):
        U1 = stbs.deform(V, sk, pose, W, E_any, method="stbs-" + base)
        assert np.abs(U1 - U0).max() <= 1e-11 * np.abs(U0).max()


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("d", DIMS)
@pytest.mark.parametrize("method", METHODS)
def test_rigid_motion_of_skeleton_moves_result_rigidly(method, d, dtype):
    rng, sk, V, W, E = random_rig(4, d)
    pose = random_pose(rng, sk)
    Rg = random_rotations(rng, 1, d)[0]
    tg = rng.normal(size=d) * 3
    dfm = stbs.Deformer(V, sk, W, E, method=method, dtype=dtype)
    U = dfm(pose).astype(np.float64)
    U2 = dfm(pose.transformed(Rg, tg)).astype(np.float64)
    assert np.abs(U2 - (U @ Rg.T + tg)).max() <= tol(dtype, np.abs(U2).max() + 3)


@pytest.mark.parametrize("d", DIMS)
@pytest.mark.parametrize("method", METHODS)
def test_independent_of_bone_order(method, d):
    rng, sk, V, W, E = random_rig(5, d)
    pose = random_pose(rng, sk)
    U = stbs.deform(V, sk, pose, W, E, method=method)
    perm = rng.permutation(sk.n_bones)
    sk2 = stbs.Skeleton(sk.C, sk.BE[perm])
    pose2 = stbs.Pose(sk2, rotations=pose.rotations[perm], origins=pose.origins[perm],
                      stretch=pose.stretch[perm], twist=pose.twist[perm])
    U2 = stbs.deform(V, sk2, pose2, W[:, perm], E[:, perm], method=method)
    assert np.abs(U2 - U).max() <= 1e-11 * np.abs(U).max()


@pytest.mark.parametrize("method", METHODS)
def test_sparse_weights_equal_dense(method):
    rng, sk, V, W, E = random_rig(6, 3)
    pose = random_pose(rng, sk)
    U = stbs.deform(V, sk, pose, W, E, method=method)
    Us = stbs.deform(V, sk, pose, sp.csr_array(W), sp.csc_array(E * (W > 0)), method=method)
    assert np.abs(Us - U).max() <= 1e-12 * np.abs(U).max()


def test_max_influences_truncates_and_renormalises():
    rng, sk, V, W, E = random_rig(7, 3)
    pose = random_pose(rng, sk)
    dfm = stbs.Deformer(V, sk, W, E, method="lbs", max_influences=1)
    assert dfm.layout.k == 4  # one influence, padded to the 4-slot kernel
    assert np.count_nonzero(dfm.layout.w, axis=1).tolist() == [len(V), 0, 0, 0]
    hard = np.zeros_like(W)
    hard[np.arange(len(W)), W.argmax(axis=1)] = 1.0
    assert np.allclose(dfm(pose), reference_deform(V, pose, hard, None, "lbs"))


def test_output_buffer_is_reused():
    rng, sk, V, W, E = random_rig(8, 3)
    dfm = stbs.Deformer(V, sk, W, E)
    buf = np.empty((len(V), 3))
    U = dfm(random_pose(rng, sk), out=buf)
    assert np.shares_memory(U, buf)
    with pytest.raises(ValueError, match="out must be"):
        dfm(random_pose(rng, sk), out=np.empty((len(V), 2)))


def test_deformer_holds_few_copies():
    _, sk, V, W, E = random_rig(9, 3, n=5000)
    dfm = stbs.Deformer(V, sk, W, E, method="stbs-dqs")
    # V (24 B) + k=3 influences padded to 4 x (1 B index + 8 B weight + 8 B endpoint)
    assert dfm.nbytes == V.nbytes + len(V) * 4 * (1 + 8 + 8)
    assert dfm.nbytes < V.nbytes + W.nbytes + E.nbytes  # less than one copy of the input


@pytest.mark.parametrize("k", [1, 2, 5, 12])
@pytest.mark.parametrize("method", METHODS)
def test_every_slot_count_path(method, k):
    # k <= 4 and k <= 8 run unrolled kernels on padded layouts, larger k the generic loop
    rng = np.random.default_rng(30 + k)
    sk = random_skeleton(rng, 3, 14)
    V = rng.normal(size=(300, 3)) + sk.C.mean(axis=0)
    W, E = random_weights(rng, 300, 14, k=k)
    pose = random_pose(rng, sk)
    dfm = stbs.Deformer(V, sk, W, E, method=method)
    assert dfm.layout.k == (4 if k <= 4 else 8 if k <= 8 else k)
    ref = reference_deform(V, pose, W, E, method)
    assert np.abs(dfm(pose) - ref).max() <= 1e-11 * np.abs(ref).max()
