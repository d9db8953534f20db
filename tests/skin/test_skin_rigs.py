"""stbs.skin against the compiled kernels (stbs.Deformer) on the shared real rigs."""

import functools
from pathlib import Path

import numpy as np
import pytest

import stbs
from conftest import as_backend, deformer_loop, pose_stack, to_np, x64
from stbs.skin import Skinner

RIGS = {  # mesh, skeleton, weights (relative to the shared data folder)
    "arm": ("libigl-tutorial-data/arm.obj", "libigl-tutorial-data/arm.tgf",
            "libigl-tutorial-data/arm-weights.dmat"),
    "elephant": ("libigl-tutorial-data/elephant.obj", "libigl-tutorial-data/elephant.tgf",
                 "libigl-tutorial-data/elephant-weights.dmat"),
    "hand": ("libigl-tutorial-data/hand.mesh", "libigl-tutorial-data/hand.tgf",
             "fast_support_reduction/hand.dmat"),
    "woody": ("fast_support_reduction/woody.obj", "fast_support_reduction/woody.tgf",
              "fast_support_reduction/woody.dmat"),
}
N_SUB = 400


@functools.cache
def _load(name: str, data: str):
    mesh, skel, weights = (Path(data) / p for p in RIGS[name])
    V = stbs.io.read_mesh(mesh).V
    sk = stbs.io.read_skeleton(skel)
    W = np.clip(stbs.io.read_dmat(weights), 0.0, None)
    rng = np.random.default_rng(7)
    sel = np.sort(rng.choice(len(V), size=min(N_SUB, len(V)), replace=False))
    V, W = V[sel], W[sel]
    W = W / W.sum(axis=1, keepdims=True)
    E = stbs.endpoint_weights(V, sk, method="projection")
    diag = float(np.linalg.norm(np.ptp(V, axis=0)))
    return name, V, sk, W, E, diag


def _check(rig, backend, dtype, rel, four=False):
    """Every method, random poses with stretch and twists past 360 degrees."""
    name, V, sk, W, E, diag = rig
    if four:      # the four heaviest bones per vertex, the same weights on both sides
        I4, W4, _ = stbs.skinning.four_heaviest(W)
        W = np.zeros_like(W)
        for s in range(4):    # added: an empty slot names bone 0 with weight 0
            W[np.arange(len(W)), I4[:, s]] += W4[:, s]
    pytest.importorskip(backend)
    R, O, S, T = pose_stack(np.random.default_rng(3), sk, 3)
    if sk.dim == 3:
        assert np.abs(T).max() > 2 * np.pi          # twists past a full turn are covered
    with x64(backend):
        for method in stbs.METHODS:
            want = deformer_loop(V, sk, W, E, method, R, O, S, T)
            skinner = Skinner(V.astype(dtype), sk, W, E, method=method, backend=backend,
                              dtype=dtype, engine="array")
            call = skinner.__call__
            if backend == "jax":     # one compiled call instead of hundreds of eager ops
                import jax

                call = jax.jit(call)
            got = call(rotations=as_backend(backend, R, dtype),
                       origins=as_backend(backend, O, dtype),
                       stretch=as_backend(backend, S, dtype),
                       twist=as_backend(backend, T, dtype) if sk.dim == 3 else None)
            got = to_np(got)
            assert got.shape == want.shape and got.dtype == dtype
            err = np.abs(got - want).max() / diag
            assert err <= rel, f"{name} {method} {backend} {dtype.__name__}: {err:.3g}"


@pytest.mark.parametrize("name", sorted(RIGS))
@pytest.mark.parametrize("backend, dtype, rel", [
    ("numpy", np.float64, 1e-6), ("numpy", np.float32, 1e-4), ("torch", np.float64, 1e-6),
    ("torch", np.float32, 1e-4)])
def test_equals_the_kernels_on_real_rigs(shared_data, name, backend, dtype, rel):
    _check(_load(name, str(shared_data)), backend, dtype, rel)


@pytest.mark.slow       # four XLA compiles per rig
@pytest.mark.parametrize("name", ["arm", "woody"])
def test_jax_jit_equals_the_kernels_on_real_rigs(shared_data, name):
    # four bones per vertex: XLA's compile time grows with the slot count
    _check(_load(name, str(shared_data)), "jax", np.float64, 1e-6, four=True)


@pytest.fixture(scope="module", params=sorted(RIGS))
def rig(request, shared_data):
    return _load(request.param, str(shared_data))


def test_numpy_skinner_runs_the_kernels(rig):
    name, V, sk, W, E, diag = rig
    R, O, S, T = pose_stack(np.random.default_rng(4), sk, 2)
    for method in ("lbs", "stbs-dqs"):
        skinner = Skinner(V, sk, W, E, method=method)
        assert skinner.uses_kernels
        got = skinner(rotations=R, origins=O, stretch=S, twist=T if sk.dim == 3 else None)
        array = Skinner(V, sk, W, E, method=method, engine="array")
        assert not array.uses_kernels
        want = array(rotations=R, origins=O, stretch=S, twist=T if sk.dim == 3 else None)
        assert np.abs(got - want).max() <= 1e-9 * diag, (name, method)
