"""``Skinner`` (precompute once, skin batches of poses) and the functional ``skin``."""

from __future__ import annotations

import warnings
from typing import Any, Literal

import array_api_compat
import numpy as np
import scipy.sparse as sp

from .. import _checks
from ..methods import SKINNING_METHODS as METHODS
from ..skinning.layout import top_k
from . import _backend as bk
from . import _core
from ._inputs import _arr, embed_points, pose_arrays

__all__ = ["Skinner", "skin"]

Method = Literal["lbs", "dqs", "stbs-lbs", "stbs-dqs"]

_POSE_DOC = """rotations : (*B, b, d, d) float, optional
        World rotations ``R_i``; identity when no rotation form is given.
    origins : (*B, b, d) float, optional
        Posed start joints ``a'_i``; the rest starts when omitted.
    stretch : (*B, b) float, optional
        ``sigma_i > 0``; 1 when omitted.
    twist : (*B, b, 2) float, optional
        Twist angles (radians, any size) at each bone's start and end; 0 when omitted.
        Must be 0 (or omitted) in 2D.
    quaternions : (*B, b, 4) float, optional
        World rotations as (w, x, y, z) quaternions (normalised here) instead of
        ``rotations``; the dual-quaternion methods use them directly.
    angles : (*B, b) float, optional
        2D rotation angles in radians instead of ``rotations``.
    rot6d : (*B, b, 6) float, optional
        World rotations in the continuous 6D form (:func:`rot6d_to_matrix`)."""


def _is_backend_array(xp, x) -> bool:
    return (x is not None and not isinstance(x, np.ndarray) and not sp.issparse(x)
            and bk.belongs(xp, x))


def _gather_rows(xp, X, rows_idx, b: int):
    """X[v, idx[v]] for an (n, b) backend array X and (n,) bone indices, differentiably."""
    n = X.shape[0]
    flat = xp.reshape(X, (n * b,))
    base = xp.arange(n, dtype=rows_idx.dtype, device=array_api_compat.device(rows_idx)) * b
    return xp.take(flat, base + rows_idx)


def _trim(layout):
    """Drop trailing slots in which every weight is zero (the kernels' padding)."""
    used = np.flatnonzero(np.any(layout.w > 0, axis=1))
    k = int(used[-1]) + 1 if used.size else 1
    return layout.idx[:k].astype(np.int64), layout.w[:k], None if layout.e is None else \
        layout.e[:k]


class Skinner:
    """Skin a fixed mesh under batches of poses on NumPy, PyTorch, JAX or CuPy.

    Precomputes a sparse top-k layout (per vertex its k heaviest bones, slot 0 the
    heaviest: indices, weights and endpoint weights as backend arrays); a call gathers
    per-bone constants for every vertex and blends them, with any leading batch axes on
    the pose. Differentiable (on a backend with autograd) in the pose, in ``V``, and in
    ``W`` and ``E`` when they are given as backend arrays (then only their kept entries,
    the top-k ones, carry gradient). Usable under ``torch.compile(fullgraph=True)`` and
    ``jax.jit``: the skeleton, method and layout are fixed at construction.

    With the NumPy backend the call runs the compiled kernels of
    :class:`stbs.Deformer`, one pose at a time (no gradients there).

    Parameters
    ----------
    V : (n, d) float
        Rest positions, d = ``sk.dim``.
    sk : Skeleton
    W : (n, b) float array or scipy.sparse
        Bone weights (>= 0, rows summing to 1; rows that do not are renormalised with a
        warning, as by :class:`stbs.Deformer`).
    E : (n, b) float array or scipy.sparse, optional
        Endpoint weights in [0, 1], used by ``stbs-lbs`` and ``stbs-dqs``; projection
        endpoint weights (eq. 8) when omitted.
    method : {"lbs", "dqs", "stbs-lbs", "stbs-dqs"}
    backend : {"numpy", "torch", "jax", "cupy"}, module or None
        None: the library of V, W or E (NumPy if all are NumPy).
    dtype : float32 or float64, optional
        Default: V's dtype if floating, else float64. Poses are cast to it.
    device : optional
        Backend device for the precomputed arrays (e.g. ``"cuda"``); default V's.
    max_influences : int, optional
        Keep at most this many bones per vertex and renormalise.
    engine : {"auto", "array"}
        "auto" runs the NumPy backend on the compiled kernels; "array" always runs the
        array-API code.

    Notes
    -----
    The result is smooth in every input except where (i) for ``dqs``/``stbs-dqs`` a
    bone's quaternion is orthogonal to the pivot's (the hemisphere flip switches sign),
    (ii) two bone weights of a vertex tie for the largest (the pivot switches), (iii) the
    blended rotation quaternion is zero (the normalisation is undefined), and (iv) the
    rotation form is singular (a zero quaternion, parallel 6D columns). 180-degree
    rotations, antipodal quaternions and twists past 2 pi are fine. Value checks
    (finiteness, positive stretch) run only outside ``torch.compile``/``jax.jit`` tracing.

    Examples
    --------
    >>> import numpy as np
    >>> import stbs
    >>> from stbs.skin import Skinner
    >>> V, F, sk, W = stbs.shapes.cigar(8)           # one bone along x, from -1 to 1
    >>> skinner = Skinner(V, sk, W, method="stbs-dqs")
    >>> U = skinner(stretch=np.array([[2.0], [3.0]]))   # two poses at once
    >>> U.shape == (2,) + V.shape
    True
    >>> tip = np.argmax(V[:, 0])
    >>> np.round(U[:, tip, 0] - V[tip, 0], 6).tolist()   # the tip moves by the growth
    [2.0, 4.0]
    """

    def __init__(self, V, sk, W, E=None, *, method: Method = "stbs-dqs", backend: Any = None,
                 dtype: Any = None, device: Any = None, max_influences: int | None = None,
                 engine: Literal["auto", "array"] = "auto"):
        _checks.skeleton(sk)
        self.method = _checks.choice("method", method, METHODS)
        self.engine = _checks.choice("engine", engine, ("auto", "array"))
        xp = bk.namespace(backend, V, W, E)
        self.xp = xp
        self._uses_kernels = self.engine == "auto" and bk.is_numpy(xp)
        self.dtype = bk.float_dtype(xp, dtype, V)
        if device is None and _is_backend_array(xp, V):
            device = array_api_compat.device(V)
        self.device = device
        Vn = _checks.vertices(bk.to_numpy(V))
        n, d = Vn.shape
        b = sk.n_bones
        if d != sk.dim:
            raise ValueError(f"V must have shape ({n}, {sk.dim}) to match the {sk.dim}D "
                             f"skeleton, got {Vn.shape}")
        self.skeleton, self.n, self.dim = sk, n, d
        uses_e = self.method.startswith("stbs")
        Wraw = W if sp.issparse(W) else bk.to_numpy(W)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            Wn = _checks.bone_weights(Wraw, n, b)
        renormalised = bool(caught)
        for w in caught:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
        En = None
        if uses_e:
            if E is None:
                from ..weights.endpoint import endpoint_weights

                En = endpoint_weights(Vn, sk, method="projection")
            else:
                En = _checks.endpoint_weights(E if sp.issparse(E) else bk.to_numpy(E), n, b)
        self._numpy_inputs = (Vn, Wn, En, max_influences)
        if max_influences is None:
            layout = top_k(Wn, En, dtype=np.float64)
        else:       # truncated exactly as the kernels' Deformer truncates
            from ..skinning import Deformer

            layout = Deformer(Vn, sk, Wn, En if uses_e else None, method=self.method,
                              dtype=np.float64, max_influences=max_influences).layout
        idx, w, e = _trim(layout)
        truncated = max_influences is not None and idx.shape[0] < int(
            np.max(np.count_nonzero(np.asarray(Wn.todense() if sp.issparse(Wn) else Wn) > 0,
                                    axis=1)))
        self.k = idx.shape[0]
        dt, dev = self.dtype, device
        self._idx = [xp.asarray(idx[j], device=dev) for j in range(self.k)]
        self._P = embed_points(xp, bk.asarray(xp, V, dtype=dt, device=dev)) if d == 2 else \
            bk.asarray(xp, V, dtype=dt, device=dev)
        if _is_backend_array(xp, W):
            cols = [_gather_rows(xp, bk.asarray(xp, W, dtype=dt), self._idx[j], b)
                    for j in range(self.k)]
            mask = xp.asarray(w.T > 0, device=dev)
            wt = xp.where(mask, xp.stack(cols, axis=1), xp.zeros_like(mask, dtype=dt))
            if renormalised or truncated:
                wt = wt / xp.sum(wt, axis=1, keepdims=True)
            self._w = wt
        else:
            self._w = xp.asarray(np.ascontiguousarray(w.T), dtype=dt, device=dev)
        self._e = None
        if uses_e:
            if _is_backend_array(xp, E):
                cols = [_gather_rows(xp, bk.asarray(xp, E, dtype=dt), self._idx[j], b)
                        for j in range(self.k)]
                self._e = xp.stack(cols, axis=1)
            else:
                self._e = xp.asarray(np.ascontiguousarray(e.T), dtype=dt, device=dev)
        C = bk.asarray(xp, sk.C, dtype=dt, device=dev)
        if d == 2:
            C = embed_points(xp, C)
        self._A = bk.asarray(xp, sk.A, dtype=dt, device=dev)
        self._bones = _core.Bones(xp, xp.take(C, bk.index(xp, sk.BE[:, 0], C), axis=0),
                                  xp.take(C, bk.index(xp, sk.BE[:, 1], C), axis=0))
        # the blends' dense rows and per-slot constants are built once unless V, W or E
        # carry a gradient tape (PyTorch), which must be recorded anew in every call
        taped = any(bool(getattr(x, "requires_grad", False))
                    for x in (self._P, self._w, self._e))
        cache = not taped and not self.uses_kernels
        self._lay = _core.Layout(xp, self._P, self._idx, self._w, self._e, b, cache=cache,
                                 pivots=idx[0] if self.method == "dqs" else None)
        if cache:
            _core.prepare(xp, self.method, self._bones, self._lay)
        self._deformer = None

    @property
    def uses_kernels(self) -> bool:
        """Whether calls run the compiled NumPy kernels (NumPy backend, engine "auto")."""
        return self._uses_kernels

    def __call__(self, rotations=None, origins=None, stretch=None, twist=None, *,
                 quaternions=None, angles=None, rot6d=None):
        xp = self.xp
        sk = self.skeleton
        pose, batch = pose_arrays(xp, sk.n_bones, sk.dim, self._A, rotations=rotations,
                                  origins=origins, stretch=stretch, twist=twist,
                                  quaternions=quaternions, angles=angles, rot6d=rot6d,
                                  dtype=self.dtype, device=self.device)
        if self.uses_kernels:
            return self._kernels(pose, batch)
        out = _core.deform(xp, self.method, self._bones, pose, self._lay, batch)
        return out[..., :self.dim] if self.dim == 2 else out

    __call__.__doc__ = f"""Deformed positions (*B, n, d) for a batch of world poses.

    Parameters
    ----------
    {_POSE_DOC}

    Returns
    -------
    U : (*B, n, d) float array of the backend
    """

    def pose(self, p):
        """Deformed positions (n, d) for a :class:`stbs.Pose`."""
        from ..pose import Pose

        if not isinstance(p, Pose):
            raise TypeError(f"p must be a stbs.Pose, got {type(p).__name__}")
        if p.skeleton != self.skeleton:
            raise ValueError("p belongs to a different skeleton than this Skinner's")
        return self(rotations=p.rotations, origins=p.origins,
                    stretch=p.stretch if np.any(p.stretch != 1) else None,
                    twist=p.twist if np.any(p.twist != 0) else None)

    def _kernels(self, pose, batch):
        from ..pose import Pose
        from ..skinning import Deformer

        if self._deformer is None:
            Vn, Wn, En, mi = self._numpy_inputs
            self._deformer = Deformer(Vn, self.skeleton, Wn, En, method=self.method,
                                      dtype=np.dtype(self.dtype), max_influences=mi)
        d, sk = self.dim, self.skeleton
        R = np.asarray(pose.matrices(self.xp), dtype=np.float64)[..., :d, :d]
        O = np.asarray(pose.O, dtype=np.float64)[..., :d]
        m = bk.prod(batch)
        R = R.reshape((m,) + R.shape[len(batch):])
        O = O.reshape((m,) + O.shape[len(batch):])
        S = None if pose.sigma is None else np.asarray(pose.sigma, np.float64).reshape(m, -1)
        T = None if pose.theta is None else np.asarray(pose.theta, np.float64).reshape(
            m, -1, 2)
        out = np.empty((m, self.n, d), dtype=np.dtype(self.dtype))
        for i in range(m):
            p = Pose(sk, rotations=R[i], origins=O[i], stretch=None if S is None else S[i],
                     twist=None if T is None else T[i])
            out[i] = self._deformer(p)
        return out.reshape(tuple(batch) + (self.n, d))

    def __repr__(self) -> str:
        return (f"Skinner(n={self.n}, bones={self.skeleton.n_bones}, k={self.k}, "
                f"method={self.method!r}, backend={self.xp.__name__!r})")


def skin(V, C, BE, W, E, rotations=None, origins=None, stretch=None, twist=None, *,
         method: Method = "stbs-dqs", quaternions=None, angles=None, rot6d=None,
         backend: Any = None):
    """Skin ``V`` by a batch of poses, every input a (differentiable) backend array.

    The functional form of :class:`Skinner` for fitting rest geometry: dense weights,
    all bones per vertex (the heaviest is the pivot of the dual-quaternion blends), and
    the rest joints ``C`` as an input, so gradients reach ``V``, ``C``, ``W``, ``E`` and
    every pose array.

    Parameters
    ----------
    V : (n, d) float
        Rest positions.
    C : (j, d) float
        Rest joint positions.
    BE : (b, 2) int
        Bones as joint pairs (a concrete array: it fixes the computation).
    W : (n, b) float
        Bone weights, rows summing to 1 (used as given).
    E : (n, b) float or None
        Endpoint weights; for the STBS methods, None means projection endpoint weights
        (eq. 8) computed from V and C (differentiable too).
    {pose}
    method : {{"lbs", "dqs", "stbs-lbs", "stbs-dqs"}}
    backend : str or module, optional
        Inferred from the arrays when None.

    Returns
    -------
    U : (*B, n, d) float array of the backend
    """
    method = _checks.choice("method", method, METHODS)
    arrays = (V, C, W, E, rotations, origins, stretch, twist, quaternions, angles, rot6d)
    xp = bk.namespace(backend, *arrays)
    like = next((x for x in arrays if _is_backend_array(xp, x) and x.dtype in (
        xp.float32, xp.float64)), V)
    dt = bk.float_dtype(xp, None, like)
    V = _arr(xp, "V", V, dt, None)
    if V.ndim != 2 or V.shape[1] not in (2, 3):
        raise ValueError(f"V must have shape (n, 2) or (n, 3), got {tuple(V.shape)}")
    n, d = V.shape
    dev = array_api_compat.device(V)
    C = _arr(xp, "C", C, dt, dev)
    BE = np.asarray(bk.to_numpy(BE))
    b = BE.shape[0] if BE.ndim == 2 else -1
    if BE.ndim != 2 or BE.shape[1] != 2 or not np.issubdtype(BE.dtype, np.integer):
        raise ValueError(f"BE must be a (b, 2) integer array, got shape {BE.shape} "
                         f"dtype {BE.dtype}")
    if C.ndim != 2 or C.shape[1] != d or (BE.size and BE.max() >= C.shape[0]) or (
            BE.size and BE.min() < 0):
        raise ValueError(f"C must have shape (j, {d}) with j > every joint in BE, got "
                         f"{tuple(C.shape)}")
    W = _arr(xp, "W", W, dt, dev)
    if tuple(W.shape) != (n, b):
        raise ValueError(f"W must have shape ({n}, {b}), got {tuple(W.shape)}")
    if d == 2:
        V3, C3 = embed_points(xp, V), embed_points(xp, C)
    else:
        V3, C3 = V, C
    bones = _core.Bones(xp, xp.take(C3, bk.index(xp, BE[:, 0], C3), axis=0),
                        xp.take(C3, bk.index(xp, BE[:, 1], C3), axis=0))
    Ed = None
    if method.startswith("stbs"):
        if E is None:
            rel = xp.sum((V3[:, None, :] - bones.a) * bones.vec, axis=-1)
            Ed = xp.clip(rel / (bones.ell * bones.ell), 0.0, 1.0)
        else:
            Ed = _arr(xp, "E", E, dt, dev)
            if tuple(Ed.shape) != (n, b):
                raise ValueError(f"E must have shape ({n}, {b}), got {tuple(Ed.shape)}")
    pose, batch = pose_arrays(xp, b, d, bones.a[:, :d], rotations=rotations, origins=origins,
                          stretch=stretch, twist=twist, quaternions=quaternions,
                          angles=angles, rot6d=rot6d, dtype=dt, device=dev)
    # every bone is a slot, heaviest first (stable: the lower bone wins a tie)
    order = xp.argsort(-W, axis=1, stable=True)
    idx = [order[:, j] for j in range(b)]
    w = xp.stack([_gather_rows(xp, W, i, b) for i in idx], axis=1)
    e = None if Ed is None else xp.stack([_gather_rows(xp, Ed, i, b) for i in idx], axis=1)
    lay = _core.Layout(xp, V3, idx, w, e, b, W=W, E=Ed)
    out = _core.deform(xp, method, bones, pose, lay, batch)
    return out[..., :d] if d == 2 else out


skin.__doc__ = skin.__doc__.format(pose=_POSE_DOC)
