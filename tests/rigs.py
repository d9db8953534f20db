"""Seeded random rigs and poses for property tests."""

from __future__ import annotations

import numpy as np

import stbs
from stbs import transforms as tf


def random_skeleton(rng: np.random.Generator, d: int, b: int = 5) -> stbs.Skeleton:
    """A forest: a chain, a branch off it, and one free-standing bone with its own joints."""
    C = [rng.normal(size=d)]
    BE = []
    for i in range(b - 1):
        parent_joint = len(C) - 1 if i != 2 else 1  # bone 2 branches off joint 1
        C.append(C[parent_joint] + rng.normal(size=d) * 0.6 + 0.4)
        BE.append([parent_joint, len(C) - 1])
    C.append(rng.normal(size=d) + 2.0)
    C.append(C[-1] + rng.normal(size=d) + 0.5)
    BE.append([len(C) - 2, len(C) - 1])
    return stbs.Skeleton(np.array(C), np.array(BE))


def random_weights(rng: np.random.Generator, n: int, b: int, k: int = 3):
    """Dense W with k non-zeros per row summing to 1, and E in [0, 1]."""
    W = np.zeros((n, b))
    for v in range(n):
        cols = rng.choice(b, size=min(k, b), replace=False)
        W[v, cols] = rng.random(cols.size) + 0.05
    W /= W.sum(axis=1, keepdims=True)
    E = rng.random((n, b))
    return W, E


def random_rotations(rng: np.random.Generator, b: int, d: int) -> np.ndarray:
    if d == 2:
        return tf.rotation_2d(rng.uniform(-np.pi, np.pi, b))
    return tf.quat_to_matrix(rng.normal(size=(b, 4)))


def random_pose(rng: np.random.Generator, sk: stbs.Skeleton, *, stretch=True,
                twist=True) -> stbs.Pose:
    b, d = sk.n_bones, sk.dim
    return stbs.Pose(
        sk, rotations=random_rotations(rng, b, d), origins=sk.A + rng.normal(size=(b, d)) * 0.3,
        stretch=rng.uniform(0.5, 2.0, b) if stretch else None,
        twist=rng.uniform(-2 * np.pi, 2 * np.pi, (b, 2)) if (twist and d == 3) else None)


def random_rig(seed: int, d: int, n: int = 400, b: int = 5):
    rng = np.random.default_rng(seed)
    sk = random_skeleton(rng, d, b)
    V = rng.normal(size=(n, d)) * 1.5 + sk.C.mean(axis=0)
    W, E = random_weights(rng, n, b)
    return rng, sk, V, W, E


def icosphere(level: int = 2, radius: float = 1.0, center=(0.0, 0.0, 0.0)):
    """A subdivided icosahedron, outward-facing."""
    t = (1 + 5 ** 0.5) / 2
    V = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
                  [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]],
                 float)
    F = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9],
                  [5, 11, 4], [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2],
                  [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10],
                  [8, 6, 7], [9, 8, 1]])
    for _ in range(level):
        E = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
        E, inv = np.unique(E, axis=0, return_inverse=True)
        inv = inv.ravel()
        mid = V.shape[0] + inv.reshape(3, -1).T  # midpoints of edges 01, 12, 20
        V = np.vstack([V, (V[E[:, 0]] + V[E[:, 1]]) / 2])
        a, b, c = F.T
        ab, bc, ca = mid.T
        F = np.concatenate([np.stack(x, axis=1) for x in
                            ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))])
    V = V / np.linalg.norm(V, axis=1, keepdims=True)
    return np.asarray(center) + radius * V, F


def u_shape():
    """A U (3 x 3 square without the notch [1, 2] x [1, 3]), grid spacing 0.1.

    Bones: the base (0.5, 0.5) -> (2.5, 0.5) and one up each arm; every bone runs along
    grid lines, so the mesh holds samples of all of them.
    """
    n = 30
    I, J = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
    V = np.c_[I.ravel(), J.ravel()] / 10
    idx = np.arange(V.shape[0]).reshape(n + 1, n + 1)
    a, b = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel()
    c, d = idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    centre = (V[a] + V[c]) / 2
    keep = ~((centre[:, 0] > 1) & (centre[:, 0] < 2) & (centre[:, 1] > 1))
    F = np.r_[np.c_[a, b, c][keep], np.c_[a, c, d][keep]]
    used = np.unique(F)
    remap = np.full(V.shape[0], -1)
    remap[used] = np.arange(used.size)
    C = np.array([[0.5, 0.5], [2.5, 0.5], [0.5, 2.7], [2.5, 2.7]])
    BE = np.array([[0, 1], [0, 2], [1, 3]])
    return V[used], remap[F], stbs.Skeleton(C, BE, names=["base", "left", "right"])
