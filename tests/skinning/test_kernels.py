"""The kernels' own sin/cos and the 4-slot vs blocked stbs-dqs paths."""

import numpy as np
import pytest

import stbs
from rigs import random_pose, random_rig
from stbs.skinning import _kernels


def test_sincos_accuracy_and_exact_zero():
    # documented bound: 2e-16 + |x| 1e-16 (one-step reduction by pi/2)
    x = np.concatenate([np.linspace(-50, 50, 20001), [np.pi / 4, -np.pi / 4, 1e4 + 0.3]])
    s, c = np.array([_kernels._sincos(float(t)) for t in x]).T
    bound = 2e-16 + np.abs(x) * 1e-16
    assert np.all(np.abs(s - np.sin(x)) <= bound)
    assert np.all(np.abs(c - np.cos(x)) <= bound)
    assert _kernels._sincos(0.0) == (0.0, 1.0)  # keeps the rest pose exact


@pytest.mark.parametrize("k", [4, 7])
def test_four_slot_and_blocked_stbs_dqs_agree_with_reference(k):
    from rigs import random_skeleton, random_weights
    from stbs.skinning.reference import reference_deform
    rng = np.random.default_rng(k)
    sk = random_skeleton(rng, 3, 9)
    V = rng.normal(size=(700, 3)) + sk.C.mean(axis=0)  # > 2 blocks of 256
    W, E = random_weights(rng, 700, 9, k=k)
    dfm = stbs.Deformer(V, sk, W, E, method="stbs-dqs")
    assert dfm.layout.k == (4 if k == 4 else 8)
    for _ in range(3):
        pose = random_pose(rng, sk)
        ref = reference_deform(V, pose, W, E, "stbs-dqs")
        assert np.abs(dfm(pose) - ref).max() <= 1e-11 * np.abs(ref).max()


def test_float32_storage_float64_arithmetic():
    rng, sk, V, W, E = random_rig(40, 3)
    pose = random_pose(rng, sk)
    U64 = stbs.Deformer(V, sk, W, E, method="stbs-dqs")(pose)
    U32 = stbs.Deformer(V.astype(np.float32), sk, W, E, method="stbs-dqs")(pose)
    assert U32.dtype == np.float32
    assert np.abs(U32 - U64).max() < 2e-6 * np.abs(U64).max()
