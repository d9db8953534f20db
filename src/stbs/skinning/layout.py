"""Top-k sparse weight layout: per vertex, the bones with non-zero weight, heaviest first."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp


@dataclass(frozen=True)
class TopK:
    """Padded per-vertex influence lists.

    Attributes
    ----------
    idx : (k, n) uint8/uint16/int32
        Slot-major bone indices, per vertex sorted by decreasing weight (smallest
        dtype that holds b; padding slots point at bone 0 with weight 0).
    w : (k, n) float
        Bone weights, zero-padded; each column sums to 1.
    e : (k, n) float or None
        Endpoint weights of the same (vertex, bone) pairs.
    """

    idx: np.ndarray
    w: np.ndarray
    e: np.ndarray | None

    @property
    def k(self) -> int:
        return int(self.idx.shape[0])

    @property
    def nbytes(self) -> int:
        return self.idx.nbytes + self.w.nbytes + (0 if self.e is None else self.e.nbytes)


def _index_dtype(b: int) -> np.dtype:
    if b <= 256:
        return np.dtype(np.uint8)
    if b <= 65536:
        return np.dtype(np.uint16)
    return np.dtype(np.int32)


def _gather(E, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """E[rows, cols] for dense or sparse E, without densifying a sparse E."""
    if not sp.issparse(E):
        return E[rows, cols]
    coo = sp.coo_array(E)
    b = E.shape[1]
    key = coo.row.astype(np.int64) * b + coo.col
    order = np.argsort(key)
    key, data = key[order], coo.data[order]
    want = rows.astype(np.int64) * b + cols
    pos = np.clip(np.searchsorted(key, want), 0, max(key.size - 1, 0))
    if key.size == 0:
        return np.zeros(want.shape)
    return np.where(key[pos] == want, data[pos], 0.0)


def top_k(W, E=None, *, max_influences: int | None = None, dtype=np.float64,
          pad: tuple[int, ...] = (4, 8)) -> TopK:
    """Build the layout from validated W (n, b) and optional E (n, b).

    Parameters
    ----------
    W : (n, b) ndarray or scipy.sparse
        Bone weights, rows summing to 1.
    E : (n, b) ndarray or scipy.sparse, optional
        Endpoint weights.
    max_influences : int, optional
        Keep at most this many bones per vertex and renormalise (the usual GPU
        limit is 4). Default keeps every non-zero weight, so the result is exact.
    dtype : float32 or float64
        Storage dtype of ``w`` and ``e``.
    pad : tuple of int
        Slot counts the kernels specialise for: k is padded (weight 0) up to the
        smallest of these that holds it.
    """
    n, b = W.shape
    if sp.issparse(W):
        csr = sp.csr_array(W)
        csr.eliminate_zeros()
        counts = np.diff(csr.indptr)
        rows = np.repeat(np.arange(n), counts)
        # sort within rows by decreasing weight (stable over bone index for ties)
        order = np.lexsort((csr.indices, -csr.data, rows))
        cols_sorted = csr.indices[order]
        vals_sorted = csr.data[order]
        k = int(counts.max()) if n else 0
        pos = np.arange(rows.size) - np.repeat(csr.indptr[:-1], counts)
        idx = np.zeros((n, k), dtype=np.int64)
        w = np.zeros((n, k))
        idx[rows, pos] = cols_sorted
        w[rows, pos] = vals_sorted
    else:
        Wd = np.asarray(W, dtype=np.float64)
        k = int((Wd > 0).sum(axis=1).max())
        # stable argsort on -W keeps bone order among equal weights
        idx = np.argsort(-Wd, axis=1, kind="stable")[:, :k]
        w = np.take_along_axis(Wd, idx, axis=1)
    if max_influences is not None:
        if int(max_influences) < 1:
            raise ValueError(f"max_influences must be >= 1, got {max_influences}")
        if k > max_influences:
            k = int(max_influences)
            idx, w = idx[:, :k], w[:, :k]
            w = w / w.sum(axis=1, keepdims=True)
    target = next((p for p in sorted(pad) if p >= k), k)
    if target > k:
        idx = np.hstack([idx, np.zeros((n, target - k), dtype=idx.dtype)])
        w = np.hstack([w, np.zeros((n, target - k))])
    idx = np.where(w > 0, idx, 0)
    e = None
    if E is not None:
        rows = np.broadcast_to(np.arange(n)[:, None], idx.shape)
        e = np.where(w > 0, _gather(E, rows.ravel(), idx.ravel()).reshape(idx.shape), 0.0)
        e = np.ascontiguousarray(e.T, dtype=dtype)
    return TopK(idx=np.ascontiguousarray(idx.T, dtype=_index_dtype(b)),
                w=np.ascontiguousarray(w.T, dtype=dtype), e=e)


#: Bones per vertex in the formats that carry a fixed count (glTF ``JOINTS_0``, UsdSkel
#: ``elementSize 4``, the viewer's ``I4``/``W4``/``E4``).
FOUR = 4


def four_heaviest(W, E=None) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Per vertex the four heaviest bones, their weights renormalised, and their endpoint
    weights: the one layout every file writer, the viewer and the bake share.

    The bones are those of :func:`top_k` with ``max_influences=4`` (heaviest first; among
    equal weights the lower bone index first), so every consumer breaks ties alike.

    Parameters
    ----------
    W : (n, b) ndarray or scipy.sparse
        Bone weights.
    E : (n, b) ndarray or scipy.sparse, optional
        Endpoint weights.

    Returns
    -------
    I4 : (n, 4) int64
        Bone indices, heaviest first; an empty slot names bone 0.
    W4 : (n, 4) float64
        Their weights, each row renormalised in float64 to sum to 1 (a row of zeros
        stays zero); 0 in an empty slot.
    E4 : (n, 4) float64 or None
        Their endpoint weights clipped to [0, 1], 0 in an empty slot; None without ``E``.

    Examples
    --------
    >>> I4, W4, _ = four_heaviest(np.array([[0.1, 0.2, 0.3, 0.2, 0.2]]))
    >>> I4.tolist(), W4.round(3).tolist()
    ([[2, 1, 3, 4]], [[0.333, 0.222, 0.222, 0.222]])
    """
    layout = top_k(W, E, max_influences=FOUR, pad=(FOUR,))
    I4 = layout.idx.T.astype(np.int64)
    W4 = layout.w.T.astype(np.float64)
    s = W4.sum(axis=1, keepdims=True)
    W4 = np.where(s > 0, W4 / np.where(s > 0, s, 1.0), 0.0)
    E4 = None
    if layout.e is not None:
        E4 = np.where(W4 > 0, np.clip(layout.e.T, 0.0, 1.0), 0.0)
    return np.ascontiguousarray(I4), np.ascontiguousarray(W4), E4
