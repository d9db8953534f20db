"""Gradients of stbs.skin against central finite differences (float64, torch.gradcheck)."""

import numpy as np
import pytest

import stbs
from stbs.skin import Skinner, forward_kinematics, matrix_to_quat, matrix_to_rot6d, skin
from stbs.skinning.reference import reference_deform
from stbs.transforms import axis_angle_to_matrix

torch = pytest.importorskip("torch")
METHODS = stbs.METHODS


def tiny_rig(d: int):
    """Three bones: a chain of two and an offset child hanging off the first bone."""
    if d == 3:
        C = np.array([[0, 0, 0], [1.0, 0.1, 0], [1.9, 0.3, 0.1], [0.5, 0.05, 0.4],
                      [0.6, 0.2, 1.2]])
    else:
        C = np.array([[0, 0], [1.0, 0.1], [1.9, 0.3], [0.5, 0.4], [0.6, 1.2]])
    sk = stbs.Skeleton(C, [[0, 1], [1, 2], [3, 4]], P=[-1, 0, 0])
    rng = np.random.default_rng(5)
    V = np.concatenate([C[:3] + 0.1, rng.normal(size=(5, d)) * 0.5 + C.mean(0)])
    W = rng.random((len(V), 3)) + 0.1
    W[0, 2] = 0.0                      # a zero weight: the slot layout must still agree
    W /= W.sum(1, keepdims=True)
    E = rng.random((len(V), 3))
    return sk, V, W, E


def pose(sk, seed=0, flip=False):
    """World pose with stretch and twists past 2 pi; bone 0 at exactly 180 degrees."""
    rng = np.random.default_rng(seed)
    b, d = sk.n_bones, sk.dim
    if d == 3:
        R = np.stack([axis_angle_to_matrix(rng.normal(size=3), rng.uniform(0.3, 1.2))
                      for _ in range(b)])
        R[0] = axis_angle_to_matrix(np.array([0.0, 0.6, 0.8]), np.pi)
        T = rng.uniform(2 * np.pi, 3 * np.pi, (b, 2)) * np.array([1, -1])
    else:
        ang = rng.uniform(0.3, 1.2, b)
        ang[0] = np.pi
        R = np.stack([[[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]] for a in ang])
        T = np.zeros((b, 2))
    O = sk.A + rng.normal(size=(b, d)) * 0.2
    S = rng.uniform(0.6, 1.6, b)
    return R, O, S, T


def t(x, grad=True):
    return torch.tensor(np.asarray(x, dtype=np.float64), requires_grad=grad)


def gradcheck(f, inputs):
    assert torch.autograd.gradcheck(f, inputs, eps=1e-6, atol=1e-6, rtol=1e-5)


@pytest.mark.parametrize("d", [3, 2])
@pytest.mark.parametrize("method", METHODS)
def test_pose_gradients(d, method):
    sk, V, W, E = tiny_rig(d)
    R, O, S, T = pose(sk)
    skinner = Skinner(V, sk, W, E, method=method, backend="torch")
    want = reference_deform(V, stbs.Pose(sk, rotations=R, origins=O, stretch=S,
                                         twist=T if d == 3 else None), W, E, method)
    Tw = t(T) if d == 3 else None
    got = skinner(rotations=t(R, False), origins=t(O, False), stretch=t(S, False),
                  twist=None if Tw is None else Tw.detach())
    np.testing.assert_allclose(got.detach().numpy(), want, atol=1e-12)
    # every pose input, rotation matrices included (at 180 degrees for bone 0)
    args = (t(R), t(O), t(S)) + ((Tw,) if d == 3 else ())
    gradcheck(lambda *a: skinner(rotations=a[0], origins=a[1], stretch=a[2],
                                 twist=a[3] if d == 3 else None), args)
    if d == 3:
        q = t(matrix_to_quat(torch.tensor(R)).numpy())
        gradcheck(lambda q: skinner(quaternions=q, origins=t(O, False), stretch=t(S, False),
                                    twist=t(T, False)), (q,))
        x6 = t(matrix_to_rot6d(torch.tensor(R)).numpy())
        gradcheck(lambda x: skinner(rot6d=x, origins=t(O, False), twist=t(T, False)), (x6,))
    else:
        ang = t(np.arctan2(R[:, 1, 0], R[:, 0, 0]))
        gradcheck(lambda a: skinner(angles=a, origins=t(O, False), stretch=t(S, False)),
                  (ang,))


@pytest.mark.parametrize("d", [3, 2])
@pytest.mark.parametrize("method", METHODS)
def test_rest_geometry_and_weight_gradients(d, method):
    sk, V, W, E = tiny_rig(d)
    R, O, S, T = pose(sk, seed=1)
    Tw = t(T, False) if d == 3 else None

    def f(V_, C_, W_, E_):
        return skin(V_, C_, sk.BE, W_, E_, t(R, False), t(O, False), t(S, False), Tw,
                    method=method)

    want = reference_deform(V, stbs.Pose(sk, rotations=R, origins=O, stretch=S,
                                         twist=T if d == 3 else None), W, E, method)
    np.testing.assert_allclose(f(t(V), t(sk.C), t(W), t(E)).detach().numpy(), want,
                               atol=1e-12)
    gradcheck(f, (t(V), t(sk.C), t(W), t(E)))
    # Skinner: W and E given as tensors carry gradient at their kept (non-zero) entries
    Wt, Et = t(W), t(E)
    skinner = Skinner(t(V), sk, Wt, Et, method=method)
    U = skinner(rotations=t(R, False), origins=t(O, False), stretch=t(S, False), twist=Tw)
    U.square().sum().backward()
    Wg = Wt.grad.clone()
    Eg = None if Et.grad is None else Et.grad.clone()
    assert (Eg is None) == (method in ("lbs", "dqs"))
    Wt.grad = Et.grad = None
    ref = f(t(V, False), t(sk.C, False), Wt, Et)
    ref.square().sum().backward()
    np.testing.assert_allclose(U.detach().numpy(), ref.detach().numpy(), atol=1e-12)
    keep = torch.tensor(W > 0)
    np.testing.assert_allclose(Wg[keep].numpy(), Wt.grad[keep].numpy(), atol=1e-9)
    assert torch.all(Wg[~keep] == 0)
    if method.startswith("stbs"):
        np.testing.assert_allclose(Eg[keep].numpy(), Et.grad[keep].numpy(), atol=1e-9)


@pytest.mark.parametrize("method", ["dqs", "stbs-dqs"])
def test_antipodal_quaternions_same_skin_consistent_gradients(method):
    sk, V, W, E = tiny_rig(3)
    R, O, S, T = pose(sk, seed=2)
    q = matrix_to_quat(torch.tensor(R)).numpy()
    skinner = Skinner(V, sk, W, E, method=method, backend="torch")
    outs, grads = [], []
    for sign in (1.0, -1.0):
        qq = q.copy()
        qq[1] *= sign                        # bone 1 given as -q
        qq[0] *= sign                        # and bone 0 too (the pivot of some vertices)
        qt = t(qq)
        U = skinner(quaternions=qt, origins=t(O, False), stretch=t(S, False),
                    twist=t(T, False))
        U.square().sum().backward()
        outs.append(U.detach().numpy())
        grads.append(qt.grad.numpy())
    np.testing.assert_allclose(outs[0], outs[1], atol=1e-12)
    # f(q) = f(-q) for each bone, so the gradient at -q is minus the gradient at q
    np.testing.assert_allclose(grads[1][:2], -grads[0][:2], atol=1e-10)
    np.testing.assert_allclose(grads[1][2], grads[0][2], atol=1e-10)


@pytest.mark.parametrize("d", [3, 2])
def test_forward_kinematics_gradients(d):
    sk, V, W, E = tiny_rig(d)
    rng = np.random.default_rng(3)
    b, j = sk.n_bones, sk.n_joints
    if d == 3:
        L = np.stack([axis_angle_to_matrix(rng.normal(size=3), 0.7) for _ in range(b)])
        L[1] = axis_angle_to_matrix(np.array([0.0, 0.0, 1.0]), np.pi)     # exactly 180
        tau = rng.uniform(-9, 9, j)                                        # past 2 pi
    else:
        L = rng.uniform(-3, 3, b)
        tau = None
    S = rng.uniform(0.6, 1.5, b)
    D = rng.normal(size=d)
    skinner = Skinner(V, sk, W, E, method="stbs-dqs", backend="torch")

    def f(L_, S_, D_, lengths, *tw):
        fk = forward_kinematics(sk, L_, S_, tw[0] if tw else None, D_, lengths=lengths)
        return skinner(*fk[:3], twist=fk.twist if d == 3 else None)

    args = (t(L), t(S), t(D), t(sk.lengths)) + ((t(tau),) if d == 3 else ())
    gradcheck(f, args)
    want = stbs.forward_kinematics(sk, L, S, tau, D)
    fk = forward_kinematics(sk, args[0].detach(), args[1].detach(),
                            None if d == 2 else args[4].detach(), args[2].detach())
    np.testing.assert_allclose(fk.rotations.numpy(), want.rotations, atol=1e-12)
    np.testing.assert_allclose(fk.origins.numpy(), want.origins, atol=1e-12)
    np.testing.assert_allclose(fk.twist.numpy(), want.twist, atol=1e-12)
