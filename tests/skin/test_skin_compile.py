"""stbs.skin under torch.compile(fullgraph=True) and jax.jit, and JAX gradients."""

import numpy as np
import pytest

import stbs
from conftest import pose_stack
from rigs import random_rig, random_weights
from stbs.skin import Skinner
from stbs.skinning.reference import reference_deform

torch = pytest.importorskip("torch")


def _case(d=3, seed=11):
    """A small rig with two bones per vertex: tracing cost grows with the slot count."""
    rng, sk, V, _, _ = random_rig(seed, d, n=40, b=5)
    W, E = random_weights(rng, len(V), sk.n_bones, k=2)
    R, O, S, T = pose_stack(rng, sk, 2)
    return sk, V, W, E, R, O, S, T


def _ref(V, sk, W, E, method, R, O, S, T):
    return np.stack([reference_deform(V, stbs.Pose(sk, rotations=R[i], origins=O[i],
                                                   stretch=S[i], twist=T[i]), W, E, method)
                     for i in range(len(R))])


@pytest.mark.parametrize("method", stbs.METHODS)
def test_torch_compile_fullgraph_aot_eager(method):
    """No graph breaks (fullgraph), and autograd traced through (aot_eager)."""
    import torch._dynamo

    sk, V, W, E, R, O, S, T = _case()
    skinner = Skinner(V, sk, W, E, method=method, backend="torch")
    torch._dynamo.reset()
    fn = torch.compile(lambda R, O, S, T: skinner(rotations=R, origins=O, stretch=S,
                                                  twist=T), fullgraph=True,
                       backend="aot_eager")
    args = [torch.tensor(x, requires_grad=True) for x in (R, O, S, T)]
    U = fn(*args)
    np.testing.assert_allclose(U.detach().numpy(), _ref(V, sk, W, E, method, R, O, S, T),
                               atol=1e-10)
    U.square().sum().backward()
    eager = [torch.tensor(x, requires_grad=True) for x in (R, O, S, T)]
    skinner(rotations=eager[0], origins=eager[1], stretch=eager[2],
            twist=eager[3]).square().sum().backward()
    for a, b in zip(args, eager, strict=True):
        assert (a.grad is None) == (b.grad is None)   # lbs and dqs have no twist
        if a.grad is not None:
            np.testing.assert_allclose(a.grad.numpy(), b.grad.numpy(), atol=1e-9)


@pytest.mark.slow
def test_torch_compile_inductor_stbs_dqs():
    import torch._dynamo

    sk, V, W, E, R, O, S, T = _case()
    skinner = Skinner(V.astype(np.float32), sk, W, E, method="stbs-dqs", backend="torch")
    torch._dynamo.reset()
    fn = torch.compile(lambda R, O, S, T: skinner(rotations=R, origins=O, stretch=S,
                                                  twist=T), fullgraph=True)
    args = [torch.tensor(x, dtype=torch.float32) for x in (R, O, S, T)]
    np.testing.assert_allclose(fn(*args).numpy(), skinner(*args[:3], twist=args[3]).numpy(),
                               atol=1e-5)


@pytest.mark.parametrize("d, method", [
    (2, "dqs"), pytest.param(3, "stbs-dqs", marks=pytest.mark.slow),
    pytest.param(3, "stbs-lbs", marks=pytest.mark.slow)])
def test_jax_jit_and_grad_agree_with_the_reference_and_torch(d, method):
    """One jitted value_and_grad per case (jit of every method on real rigs elsewhere),
    with two batch axes (1, 2) on rotations and origins and stretch broadcast over them."""
    jax = pytest.importorskip("jax")
    import jax.numpy as jnp

    sk, V, W, E, R, O, S, T = _case(d)
    with jax.enable_x64(True):
        sj = Skinner(V, sk, W, E, method=method, backend="jax")

        def loss(R, O, S, *T):
            U = sj(rotations=R, origins=O, stretch=S, twist=T[0] if T else None)
            return jnp.sum(U ** 2), U

        args = [jnp.asarray(R)[None], jnp.asarray(O)[None], jnp.asarray(S)]
        args += [jnp.asarray(T)[None]] if d == 3 else []
        (_, U), grads = jax.jit(jax.value_and_grad(loss, argnums=tuple(range(len(args))),
                                                   has_aux=True))(*args)
    U = np.asarray(U)
    assert U.shape == (1, 2) + V.shape
    np.testing.assert_allclose(U[0], _ref(V, sk, W, E, method, R, O, S, T), atol=1e-10)
    st = Skinner(V, sk, W, E, method=method, backend="torch")
    tt = [torch.tensor(x, requires_grad=True) for x in (R, O, S, T)]
    st(rotations=tt[0], origins=tt[1], stretch=tt[2],
       twist=tt[3] if d == 3 else None).square().sum().backward()
    for a, b in zip(grads, tt, strict=False):
        tg = np.zeros(b.shape) if b.grad is None else b.grad.numpy()
        np.testing.assert_allclose(np.asarray(a).reshape(tg.shape), tg, atol=1e-8)


def test_jax_retraces_and_eager_calls_reuse_no_traced_value(method="stbs-lbs"):
    """What a Skinner keeps between calls is made outside any trace: a second trace (new
    batch shape) and an eager call after jit must not meet the first trace's values."""
    jax = pytest.importorskip("jax")
    import jax.numpy as jnp

    sk, V, W, E, R, O, S, T = _case()
    with jax.enable_x64(True):
        sj = Skinner(V, sk, W, E, method=method, backend="jax")
        fn = jax.jit(lambda R, O, S, T: sj(rotations=R, origins=O, stretch=S, twist=T))
        a = fn(*(jnp.asarray(x) for x in (R, O, S, T)))
        b = fn(*(jnp.asarray(x)[None] for x in (R, O, S, T)))
        c = sj(rotations=jnp.asarray(R), origins=jnp.asarray(O), stretch=jnp.asarray(S),
               twist=jnp.asarray(T))
    want = _ref(V, sk, W, E, method, R, O, S, T)
    for U in (a, b[0], c):
        np.testing.assert_allclose(np.asarray(U), want, atol=1e-10)
