"""Fixtures for stbs.skin: backends, and pose stacks with stretch and large twists."""

from __future__ import annotations

import contextlib

import numpy as np
import pytest

import stbs
from rigs import random_rotations

BACKENDS = ("numpy", "torch", "jax")


def x64(backend: str):
    """JAX's 64-bit mode for the duration of a block (a no-op for other backends)."""
    if backend != "jax":
        return contextlib.nullcontext()
    import jax

    return jax.enable_x64(True)


def as_backend(backend: str, x, dtype=np.float64):
    x = np.asarray(x, dtype=dtype)
    if backend == "torch":
        import torch

        return torch.from_numpy(x.copy())
    if backend == "jax":
        import jax.numpy as jnp

        return jnp.asarray(x)
    return x


def to_np(x) -> np.ndarray:
    if hasattr(x, "detach"):
        x = x.detach()
    return np.asarray(x)


def pose_stack(rng, sk: stbs.Skeleton, m: int, *, big_twist: bool = True):
    """m random world poses as stacked arrays: R, origins, stretch, twist (3D: past 2 pi)."""
    b, d = sk.n_bones, sk.dim
    R = np.stack([random_rotations(rng, b, d) for _ in range(m)])
    scale = np.linalg.norm(np.ptp(sk.C, axis=0))
    O = sk.A + rng.normal(size=(m, b, d)) * 0.2 * scale
    S = rng.uniform(0.5, 2.0, (m, b))
    lim = 3 * np.pi if big_twist else np.pi
    T = rng.uniform(-lim, lim, (m, b, 2)) if d == 3 else np.zeros((m, b, 2))
    return R, O, S, T


def deformer_loop(V, sk, W, E, method, R, O, S, T, dtype=np.float64):
    dfm = stbs.Deformer(V, sk, W, E, method=method, dtype=dtype)
    return np.stack([dfm(stbs.Pose(sk, rotations=R[i], origins=O[i], stretch=S[i],
                                   twist=T[i])).copy() for i in range(len(R))])


@pytest.fixture(params=BACKENDS)
def backend(request):
    pytest.importorskip(request.param)
    return request.param
