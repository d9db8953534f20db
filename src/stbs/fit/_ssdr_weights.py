"""The bone-weight step of STBS-SSDR (private to :mod:`stbs.fit.ssdr`).

With every bone's transforms and endpoint weights held, each vertex's weights are one
small least-squares problem on the simplex: the columns are the candidate bones'
predictions of the vertex in all frames, minus the vertex itself (the weights sum to
one, so this leaves the fit unchanged and keeps translations out of the normal
equations), solved by :func:`stbs.fit._lsq.simplex_qp` at most ``k`` bones per vertex,
pulled towards the average of the vertex's mesh neighbours.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ._lsq import simplex_objective, simplex_qp
from ._ssdr_model import Bones, State, bone_points

#: Candidate bones per vertex beyond ``max_influences`` (the closest fits by one bone).
EXTRA_CANDIDATES = 4


def neighbour_average(F: np.ndarray | None, n: int):
    """(n, n) CSR averaging each vertex's edge neighbours (mesh ``F``), or None."""
    if F is None or len(F) == 0:
        return None
    F = np.asarray(F, dtype=np.int64)
    i = np.concatenate([F[:, 0], F[:, 1], F[:, 2], F[:, 1], F[:, 2], F[:, 0]])
    j = np.concatenate([F[:, 1], F[:, 2], F[:, 0], F[:, 0], F[:, 1], F[:, 2]])
    A = sp.csr_array((np.ones(i.size), (i, j)), shape=(n, n))
    A.data[:] = 1.0                                  # duplicates summed: back to 0/1
    deg = np.asarray(A.sum(axis=1)).ravel()
    inv = np.divide(1.0, deg, out=np.zeros(n), where=deg > 0)
    return sp.csr_array(sp.diags_array(inv) @ A)


def _candidates(X, Y, bones: Bones, st: State, count: int) -> np.ndarray:
    """(n, count) bones per vertex: its current bones first, then the best single fits."""
    n, b = st.W.shape
    err = np.empty((n, b))
    for i in range(b):
        D = bone_points(X, st.E[:, i], bones, i, st) - Y
        err[:, i] = np.einsum("fni,fni->n", D, D)
    score = np.where(st.W > 0, -1.0, err)
    return np.argsort(score, axis=1, kind="stable")[:, :count]


def _design(X, Y, bones: Bones, st: State, cand: np.ndarray) -> np.ndarray:
    """(n, 3F, c) the candidate bones' predictions minus the targets."""
    n, c = cand.shape
    A = np.empty((n, 3 * Y.shape[0], c))
    for i in range(st.W.shape[1]):
        rows, slots = np.nonzero(cand == i)
        if rows.size:
            D = bone_points(X[rows], st.E[rows, i], bones, i, st) - Y[:, rows]
            A[rows, :, slots] = D.transpose(1, 0, 2).reshape(rows.size, -1)
    return A


def fit_weights(X, Y, bones: Bones, st: State, *, k: int, avg, lam: float) -> None:
    """New ``st.W`` (in place): per vertex, at most ``k`` bones, >= 0, summing to 1,
    kept only where it lowers the vertex's objective (fit + ``lam |w - prior|^2``)."""
    n, b = st.W.shape
    c = min(b, k + EXTRA_CANDIDATES)
    cand = _candidates(X, Y, bones, st, c)
    A = _design(X, Y, bones, st, cand)
    H = A.transpose(0, 2, 1) @ A
    rows = np.arange(n)[:, None]
    if avg is not None and lam > 0:
        prior = (avg @ st.W)[rows, cand]
        H[:, np.arange(c), np.arange(c)] += lam
        g = lam * prior
    else:
        g = np.zeros((n, c))
    w_new = simplex_qp(H, g, k=min(k, c))
    w_old = st.W[rows, cand]
    w_old = w_old / w_old.sum(axis=1, keepdims=True)
    better = simplex_objective(H, g, w_new) < simplex_objective(H, g, w_old)
    W = np.zeros((n, b))
    W[rows, cand] = np.where(better[:, None], w_new, w_old)
    st.W = W
