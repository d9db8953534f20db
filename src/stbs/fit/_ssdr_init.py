"""The starting point of STBS-SSDR (private to :mod:`stbs.fit.ssdr`).

As in SSDR (Le & Deng 2012): vertices are clustered by their motion (k-means++ on the
vertex trajectories, seeded), then the clusters are refined as rigid bones: fit one
rigid transform per cluster and frame (Procrustes), give each vertex to the cluster
whose transforms reproduce it best, repeat. A cluster left with too few vertices is
started again at the worst-fitted vertex and its rest-space neighbours. Each bone's
rest segment is then its cluster's principal axis, spanning the cluster's extent
along it, and its endpoint weights are the projections on that segment (eq. 8).
"""

from __future__ import annotations

import numpy as np

from ._ssdr_model import Bones, State, procrustes

#: A cluster needs this many vertices to fix a rotation (three not on one line).
MIN_CLUSTER = 3


def kmeans(Z: np.ndarray, b: int, rng: np.random.Generator, rounds: int = 15) -> np.ndarray:
    """Labels (n,) of k-means with k-means++ seeding on the rows of ``Z`` (n, q)."""
    n = Z.shape[0]
    sq = np.einsum("nq,nq->n", Z, Z)
    centres = [int(rng.integers(n))]
    d2 = np.maximum(sq - 2 * Z @ Z[centres[0]] + sq[centres[0]], 0.0)
    for _ in range(1, b):
        p = d2 / d2.sum() if d2.sum() > 0 else np.full(n, 1.0 / n)
        c = int(rng.choice(n, p=p))
        centres.append(c)
        d2 = np.minimum(d2, np.maximum(sq - 2 * Z @ Z[c] + sq[c], 0.0))
    C = Z[centres].copy()
    labels = np.zeros(n, dtype=np.int64)
    for r in range(rounds):
        D = sq[:, None] - 2 * Z @ C.T + np.einsum("bq,bq->b", C, C)
        new = np.argmin(D, axis=1)
        if r and np.array_equal(new, labels):
            break
        labels = new
        counts = np.bincount(labels, minlength=b)
        for j in np.flatnonzero(counts):
            C[j] = Z[labels == j].mean(axis=0)
    return labels


def rigid_fits(X: np.ndarray, Y: np.ndarray, labels: np.ndarray, b: int):
    """Per cluster and frame the rigid ``x -> R x + t`` best fitting its vertices:
    ``R`` (F, b, 3, 3), ``t`` (F, b, 3) (identity for an empty cluster)."""
    Fn = Y.shape[0]
    R = np.tile(np.eye(3), (Fn, b, 1, 1))
    t = np.zeros((Fn, b, 3))
    for j in range(b):
        idx = np.flatnonzero(labels == j)
        if idx.size == 0:
            continue
        Xc = X[idx] - X[idx].mean(axis=0)
        Yb = Y[:, idx].mean(axis=1)
        H = np.einsum("mi,fmj->fij", Xc, Y[:, idx] - Yb[:, None])
        R[:, j] = procrustes(H)
        t[:, j] = Yb - np.einsum("fij,j->fi", R[:, j], X[idx].mean(axis=0))
    return R, t


def _rigid_errors(X, Y, R, t) -> np.ndarray:
    """(n, b) squared error over the frames of each vertex under each cluster's fits."""
    n, b = X.shape[0], R.shape[1]
    err = np.empty((n, b))
    for j in range(b):
        D = X @ R[:, j].transpose(0, 2, 1) + t[:, j, None, :] - Y
        err[:, j] = np.einsum("fni,fni->n", D, D)
    return err


def _reseed(X, labels, err_own, b: int) -> np.ndarray:
    """Clusters with fewer than MIN_CLUSTER vertices restart at the worst-fitted vertex
    (taking it and its nearest rest-space neighbours)."""
    n = X.shape[0]
    take = max(MIN_CLUSTER, n // (4 * b))
    err = err_own.copy()
    for j in np.flatnonzero(np.bincount(labels, minlength=b) < MIN_CLUSTER):
        v = int(np.argmax(err))
        near = np.argsort(np.einsum("ni,ni->n", X - X[v], X - X[v]), kind="stable")[:take]
        labels[near] = j
        err[near] = -1.0
    return labels


def rigid_clusters(X, Y, b: int, rng, *, rounds: int, report) -> np.ndarray:
    """Labels (n,): k-means++ on the trajectories, then ``rounds`` of rigid refinement."""
    n = X.shape[0]
    Z = Y.transpose(1, 0, 2).reshape(n, -1)
    labels = kmeans(Z, b, rng)
    for r in range(rounds):
        report(r, rounds)
        R, t = rigid_fits(X, Y, labels, b)
        err = _rigid_errors(X, Y, R, t)
        new = np.argmin(err, axis=1)
        new = _reseed(X, new, err[np.arange(n), new], b)
        if np.array_equal(new, labels):
            break
        labels = new
    report(rounds, rounds)
    return labels


def segments(X: np.ndarray, labels: np.ndarray, b: int, diag: float) -> Bones:
    """Each cluster's principal axis through its centroid, spanning its extent on it."""
    a = np.zeros((b, 3))
    u = np.zeros((b, 3))
    ell = np.zeros(b)
    floor = 1e-2 * diag
    for j in range(b):
        P = X[labels == j]
        c = P.mean(axis=0)
        _, _, Vt = np.linalg.svd(P - c, full_matrices=False)
        axis = Vt[0]
        axis = axis * (1.0 if axis[np.argmax(np.abs(axis))] > 0 else -1.0)
        s = (P - c) @ axis
        lo, hi = float(s.min()), float(s.max())
        if hi - lo < floor:                      # a point-like cluster: a short bone
            lo, hi = -0.5 * floor, 0.5 * floor
        a[j], u[j], ell[j] = c + lo * axis, axis, hi - lo
    return Bones(a=a, u=u, ell=ell)


def projection_E(X: np.ndarray, bones: Bones) -> np.ndarray:
    """(n, b) eq. 8: the clamped position of each vertex's projection on each bone."""
    t = (np.einsum("ni,bi->nb", X, bones.u) - np.einsum("bi,bi->b", bones.a, bones.u))
    return np.clip(t / bones.ell, 0.0, 1.0)


def start(X, Y, b: int, rng, *, rounds: int, diag: float, report) -> tuple[Bones, State]:
    """Bones, hard weights, projection endpoint weights and rigid per-frame transforms."""
    labels = rigid_clusters(X, Y, b, rng, rounds=rounds, report=report)
    bones = segments(X, labels, b, diag)
    R, t = rigid_fits(X, Y, labels, b)
    W = np.zeros((X.shape[0], b))
    W[np.arange(X.shape[0]), labels] = 1.0
    Fn = Y.shape[0]
    st = State(W=W, E=projection_E(X, bones), R=R,
               O=np.einsum("fbij,bj->fbi", R, bones.a) + t,
               sig=np.ones((Fn, b)), th=np.zeros((Fn, b, 2)))
    return bones, st
