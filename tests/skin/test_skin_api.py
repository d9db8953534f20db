"""stbs.skin: batch axes, invariants, forward kinematics, converters and bad input."""

import subprocess
import sys

import numpy as np
import pytest

import stbs
from conftest import as_backend, pose_stack, to_np, x64
from rigs import random_rig
from stbs import transforms as tf
from stbs.skin import (
    Skinner,
    angle_to_matrix,
    forward_kinematics,
    matrix_to_quat,
    matrix_to_rot6d,
    quat_to_matrix,
    rest_joints,
    rot6d_to_matrix,
    skin,
)
from stbs.skinning.reference import reference_deform


def offset_skeleton():
    """Hips with a leg hanging off their middle (an offset child) and a chain below it."""
    C = np.array([[0, 0, 0], [0, 1, 0], [0.2, 0.4, 0.1], [0.3, -0.6, 0.1], [0.3, -1.5, 0.3]])
    return stbs.Skeleton(C, [[0, 1], [2, 3], [3, 4]], P=[-1, 0, 1])


# JAX runs op by op here (slow without jit); its batches are checked jitted elsewhere
@pytest.mark.parametrize("backend", ["numpy", "torch"])
@pytest.mark.parametrize("d", [3, 2])
def test_batch_axes_equal_the_loop(backend, d):
    pytest.importorskip(backend)
    rng, sk, V, W, E = random_rig(2, d, n=30, b=4)
    R, O, S, T = pose_stack(rng, sk, 6)
    shape = (2, 3)
    kw = dict(rotations=R.reshape(shape + R.shape[1:]), origins=O.reshape(shape + O.shape[1:]),
              stretch=S[0])               # one stretch for all: broadcast over the batch
    if d == 3:
        kw["twist"] = T.reshape(shape + T.shape[1:])
    with x64(backend):
        skinner = Skinner(V, sk, W, E, method="stbs-dqs", backend=backend, engine="array")
        got = to_np(skinner(**{k: as_backend(backend, v) for k, v in kw.items()}))
    assert got.shape == shape + V.shape
    for i in range(6):
        pose = stbs.Pose(sk, rotations=R[i], origins=O[i], stretch=S[0],
                         twist=T[i] if d == 3 else None)
        np.testing.assert_allclose(got.reshape((6,) + V.shape)[i],
                                   reference_deform(V, pose, W, E, "stbs-dqs"), atol=1e-12)


@pytest.mark.parametrize("method", stbs.METHODS)
def test_rest_pose_reproduces_V_and_bone_order_does_not_matter(method):
    torch = pytest.importorskip("torch")
    rng, sk, V, W, E = random_rig(4, 3, n=40, b=5)
    U = Skinner(V, sk, W, E, method=method, backend="torch")()
    np.testing.assert_allclose(U.numpy(), V, atol=1e-12)
    R, O, S, T = pose_stack(rng, sk, 2)
    perm = np.array([3, 0, 4, 2, 1])
    inv = np.argsort(perm)
    sk2 = stbs.Skeleton(sk.C, sk.BE[perm])
    a = skin(torch.tensor(V), sk.C, sk.BE, W, E, R, O, S, T, method=method)
    b = skin(V, sk2.C, sk2.BE, torch.tensor(W[:, perm]), E[:, perm], R[:, perm], O[:, perm],
             S[:, perm], T[:, perm], method=method)
    np.testing.assert_allclose(a.numpy(), b.numpy(), atol=1e-12)
    assert inv.size == 5


@pytest.mark.parametrize("method", stbs.METHODS)
def test_vertices_in_chunks_give_the_same_skinning_and_gradients(method, monkeypatch):
    """Eager CPU calls take the vertices in cache-sized chunks: many small chunks (the dqs
    pivot groups cut across them) must give the one-piece result and gradients."""
    torch = pytest.importorskip("torch")
    from stbs.skin import _core

    rng, sk, V, W, E = random_rig(7, 3, n=200, b=6)
    R, O, S, T = pose_stack(rng, sk, 5)

    def run(chunk_elements):
        monkeypatch.setattr(_core, "CHUNK_ELEMENTS", chunk_elements)
        leaves = [torch.tensor(x, requires_grad=True) for x in (R, O, S, T)]
        Wt = torch.tensor(W, requires_grad=True)
        U = Skinner(V, sk, Wt, E, method=method, backend="torch")(*leaves)
        (U * torch.tensor(V)).sum().backward()
        return U.detach().numpy(), [None if x.grad is None else x.grad.numpy()
                                    for x in leaves + [Wt]]

    whole, g_whole = run(10**9)
    parts, g_parts = run(7 * len(R))           # chunks of 7 vertices
    assert _core.CHUNK_ELEMENTS // len(R) == 7
    for i in range(len(R)):
        pose = stbs.Pose(sk, rotations=R[i], origins=O[i], stretch=S[i], twist=T[i])
        np.testing.assert_allclose(parts[i], reference_deform(V, pose, W, E, method),
                                   atol=1e-12)
    np.testing.assert_allclose(parts, whole, atol=1e-12)
    assert sum(g is not None for g in g_parts) >= 4
    for a, b in zip(g_parts, g_whole, strict=True):
        assert (a is None) == (b is None)
        if a is not None:
            np.testing.assert_allclose(a, b, atol=1e-10)
    arr = Skinner(V, sk, W, E, method=method, engine="array")(R, O, S, T)   # NumPy, chunked
    np.testing.assert_allclose(arr, whole, atol=1e-12)


@pytest.mark.parametrize("backend", ["numpy", "torch"])
def test_pose_method_and_quaternions_match_matrices(backend):
    pytest.importorskip(backend)
    rng, sk, V, W, E = random_rig(6, 3, n=30)
    pose = stbs.Pose(sk, rotations=tf.quat_to_matrix(rng.normal(size=(5, 4))),
                     origins=sk.A + 0.1, stretch=np.full(5, 1.2),
                     twist=rng.uniform(-7, 7, (5, 2)))
    want = reference_deform(V, pose, W, E, "dqs")
    with x64(backend):
        sk_ = Skinner(V, sk, W, E, method="dqs", backend=backend, engine="array")
        np.testing.assert_allclose(to_np(sk_.pose(pose)), want, atol=1e-12)
        q = tf.matrix_to_quat(pose.rotations) * np.array([[1], [-1], [1], [-1], [1]])
        got = sk_(quaternions=as_backend(backend, 3.0 * q), origins=pose.origins,
                  stretch=pose.stretch)
    np.testing.assert_allclose(to_np(got), want, atol=1e-12)


def test_forward_kinematics_equals_stbs_with_offset_children_and_batches():
    torch = pytest.importorskip("torch")
    sk = offset_skeleton()
    rng = np.random.default_rng(8)
    L = tf.quat_to_matrix(rng.normal(size=(2, 3, 3, 4)))
    S = rng.uniform(0.5, 2, (2, 3, 3))
    tau = rng.uniform(-8, 8, (2, 3, 5))
    D = rng.normal(size=(2, 3, 3))
    fk = forward_kinematics(sk, torch.tensor(L), torch.tensor(S), torch.tensor(tau),
                            torch.tensor(D))
    for i in range(2):
        for j in range(3):
            p = stbs.forward_kinematics(sk, L[i, j], S[i, j], tau[i, j], D[i, j])
            np.testing.assert_allclose(fk.rotations[i, j].numpy(), p.rotations, atol=1e-12)
            np.testing.assert_allclose(fk.origins[i, j].numpy(), p.origins, atol=1e-12)
            np.testing.assert_allclose(fk.twist[i, j].numpy(), p.twist, atol=1e-12)
    # per-bone translation, and quaternion / 6D local rotations give the same pose
    Db = rng.normal(size=(3, 3))
    p = stbs.forward_kinematics(sk, L[0, 0], translation=Db)
    for kw in ({"quaternions": tf.matrix_to_quat(L[0, 0])},
               {"rot6d": matrix_to_rot6d(torch.tensor(L[0, 0])).numpy()}):
        f = forward_kinematics(sk, translation=torch.tensor(Db),
                               **{k: torch.tensor(v) for k, v in kw.items()})
        np.testing.assert_allclose(f.origins.numpy(), p.origins, atol=1e-12)


def test_rest_joints_with_the_skeleton_lengths_give_C_and_follow_new_lengths():
    sk = offset_skeleton()
    np.testing.assert_allclose(rest_joints(sk, sk.lengths), sk.C, atol=1e-15)
    L = sk.lengths * np.array([2.0, 0.5, 1.5])
    C = rest_joints(sk, L)
    sk2 = stbs.Skeleton(C, sk.BE, P=sk.parents)
    np.testing.assert_allclose(sk2.lengths, L, atol=1e-12)
    np.testing.assert_allclose(sk2.axes, sk.axes, atol=1e-12)
    np.testing.assert_allclose(sk2.hang, sk.hang, atol=1e-12)   # hangs where it did


def test_converters_agree_with_stbs_transforms():
    torch = pytest.importorskip("torch")
    rng = np.random.default_rng(9)
    q = rng.normal(size=(50, 4))
    R = tf.quat_to_matrix(q)
    R[0] = np.diag([1.0, -1.0, -1.0])                  # 180 degrees
    R[1] = tf.axis_angle_to_matrix(np.array([1.0, 1, 1]), np.pi)
    np.testing.assert_allclose(quat_to_matrix(torch.tensor(q)).numpy(), tf.quat_to_matrix(q),
                               atol=1e-14)
    qq = matrix_to_quat(torch.tensor(R)).numpy()
    np.testing.assert_allclose(np.abs(np.sum(qq * tf.matrix_to_quat(R), -1)), 1, atol=1e-12)
    np.testing.assert_allclose(rot6d_to_matrix(matrix_to_rot6d(torch.tensor(R))).numpy(), R,
                               atol=1e-12)
    x6 = rng.normal(size=(5, 6))
    M = rot6d_to_matrix(x6)
    np.testing.assert_allclose(M @ np.swapaxes(M, -1, -2), np.broadcast_to(np.eye(3),
                                                                            M.shape), atol=1e-12)
    np.testing.assert_allclose(M[:, :, 0], x6[:, :3] / np.linalg.norm(x6[:, :3], axis=1,
                                                                        keepdims=True))
    a = rng.uniform(-7, 7, 4)
    np.testing.assert_allclose(angle_to_matrix(a), tf.rotation_2d(a), atol=1e-15)


def test_bad_input_is_named():
    rng, sk, V, W, E = random_rig(1, 3, n=10)
    with pytest.raises(ValueError, match="backend must be one of 'numpy', 'torch', 'jax'"):
        Skinner(V, sk, W, E, backend="tensorflow")
    with pytest.raises(ValueError, match="method"):
        Skinner(V, sk, W, E, method="slerp")
    with pytest.raises(ValueError, match=r"V must have shape \(10, 3\)"):
        Skinner(V[:, :2], sk, W, E)
    with pytest.raises(ValueError, match=r"W must have shape"):
        Skinner(V, sk, W[:, :3], E)
    s = Skinner(V, sk, W, E, engine="array")
    R, O, S, T = pose_stack(rng, sk, 2)
    with pytest.raises(ValueError, match=r"rotations must have shape \(\*B, 5, 3, 3\)"):
        s(rotations=R[:, :4])
    with pytest.raises(ValueError, match="batch"):
        s(rotations=R, origins=O[:1].repeat(3, axis=0))
    with pytest.raises(ValueError, match="one form only"):
        s(rotations=R, quaternions=np.ones((2, 5, 4)))
    bad = O.copy()
    bad[1, 2, 0] = np.nan
    with pytest.raises(ValueError, match="origins must be finite"):
        s(rotations=R, origins=bad)
    with pytest.raises(ValueError, match="stretch must be > 0"):
        s(stretch=-S)
    with pytest.raises(ValueError, match="angles"):
        s(angles=np.zeros(5))
    rng2, sk2, V2, W2, E2 = random_rig(1, 2, n=10)
    s2 = Skinner(V2, sk2, W2, E2, engine="array")
    with pytest.raises(ValueError, match="twist must be 0 in 2D"):
        s2(twist=np.ones((5, 2)))
    with pytest.raises(ValueError, match="quaternions"):
        s2(quaternions=np.ones((5, 4)))
    with pytest.raises(ValueError, match="W must be finite"):
        skin(V, sk.C, sk.BE, np.full_like(W, np.nan), E)
    with pytest.raises(ValueError, match="BE must be a"):
        skin(V, sk.C, sk.BE.astype(float), W, E)
    with pytest.raises(ValueError, match="float32 or float64"):
        Skinner(V, sk, W, E, dtype="int32")


def test_importing_stbs_skin_loads_neither_torch_nor_jax():
    code = ("import sys, numpy as np, stbs, stbs.skin\n"
            "from stbs.skin import Skinner, skin, forward_kinematics, quat_to_matrix\n"
            "V, F, sk, W = stbs.shapes.cigar(4)\n"
            "Skinner(V, sk, W)(stretch=np.array([2.0]))\n"
            "print('torch' in sys.modules, 'jax' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.split() == ["False", "False"], out.stdout + out.stderr


def test_max_influences_truncates_as_the_kernels_do():
    torch = pytest.importorskip("torch")
    rng, sk, V, W, E = random_rig(12, 3, n=30, b=5)
    W = W + 0.05                           # every bone weighs every vertex
    W /= W.sum(1, keepdims=True)
    R, O, S, T = pose_stack(rng, sk, 2)
    dfm = stbs.Deformer(V, sk, W, E, method="stbs-dqs", max_influences=2)
    s = Skinner(V, sk, torch.tensor(W), E, method="stbs-dqs", max_influences=2)
    assert s.k == 2
    got = s(rotations=torch.tensor(R), origins=torch.tensor(O), stretch=torch.tensor(S),
            twist=torch.tensor(T)).numpy()
    for i in range(2):
        want = dfm(stbs.Pose(sk, rotations=R[i], origins=O[i], stretch=S[i], twist=T[i]))
        np.testing.assert_allclose(got[i], want, atol=1e-12)
