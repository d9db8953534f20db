"""Hand-made 3D surfaces of the kinds real characters are made of: open, in several
parts, self-intersecting, non-manifold (for the winding-number volume mesh)."""

from __future__ import annotations

import numpy as np


def tube(around: int = 24, along: int = 17, length: float = 4.0, radius: float = 0.5):
    """A cylinder along x from 0 to ``length`` without caps (open at both ends):
    ``around * along`` vertices, ring k at x = k length / (along - 1)."""
    a = 2 * np.pi * np.arange(around) / around
    x = np.linspace(0.0, length, along)
    V = np.array([[xi, radius * np.cos(t), radius * np.sin(t)] for xi in x for t in a])
    i, j = np.meshgrid(np.arange(along - 1), np.arange(around), indexing="ij")
    p, q = i * around + j, i * around + (j + 1) % around
    F = np.r_[np.c_[p.ravel(), q.ravel(), (q + around).ravel()],
              np.c_[p.ravel(), (q + around).ravel(), (p + around).ravel()]]
    # outward: the normal of the first triangle points away from the axis
    P = V[F[0]]
    n = np.cross(P[1] - P[0], P[2] - P[0])
    if np.dot(n, P.mean(axis=0) * [0, 1, 1]) < 0:
        F = F[:, ::-1]
    return V, F


def box(lo, hi, n: int = 4):
    """The closed surface of the box ``[lo, hi]``, each face an n x n grid of squares
    (two triangles each), outward-facing, shared vertices merged."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    s = np.linspace(0.0, 1.0, n + 1)
    Vs, Fs, off = [], [], 0
    for axis in range(3):
        for side in (0.0, 1.0):
            u, v = [k for k in range(3) if k != axis]
            g1, g2 = np.meshgrid(s, s, indexing="ij")
            P = np.zeros((g1.size, 3))
            P[:, axis], P[:, u], P[:, v] = side, g1.ravel(), g2.ravel()
            i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
            a = (i * (n + 1) + j).ravel()
            F = np.r_[np.c_[a, a + n + 1, a + n + 2], np.c_[a, a + n + 2, a + 1]]
            Vs.append(lo + P * (hi - lo))
            Fs.append(F + off)
            off += P.shape[0]
    V, F = np.vstack(Vs), np.vstack(Fs)
    key = np.round(V, 9)
    _, first, inv = np.unique(key, axis=0, return_index=True, return_inverse=True)
    V, F = V[first], np.ravel(inv)[F]
    # each triangle faces away from the box's centre
    c = (lo + hi) / 2
    P = V[F]
    nrm = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
    flip = np.einsum("ij,ij->i", nrm, P.mean(axis=1) - c) < 0
    return V, np.where(flip[:, None], F[:, ::-1], F)


def join(*parts):
    """Several surfaces as one (vertices stacked, nothing merged)."""
    Vs, Fs, off = [], [], 0
    for V, F in parts:
        Vs.append(V)
        Fs.append(F + off)
        off += V.shape[0]
    return np.vstack(Vs), np.vstack(Fs)


def merged(V, F, decimals: int = 9):
    """Vertices at the same place merged (two surfaces touching become one)."""
    _, first, inv = np.unique(np.round(V, decimals), axis=0, return_index=True,
                              return_inverse=True)
    return V[first], np.ravel(inv)[F]
