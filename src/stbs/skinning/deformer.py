"""``Deformer`` (precompute once, pose per frame) and the one-shot ``deform``."""

from __future__ import annotations

from typing import Literal

import numpy as np

from .. import _checks
from ..methods import SKINNING_METHODS as METHODS
from ..pose import Pose
from ..skeleton import Skeleton
from . import _frame, _kernels
from .layout import top_k

Method = Literal["lbs", "dqs", "stbs-lbs", "stbs-dqs"]


class Deformer:
    """Skin a fixed mesh under many poses.

    The weights are packed once into a top-k layout (per vertex, the bones with
    non-zero weight, heaviest first); each call only builds b per-bone constants
    from the pose and runs one compiled, multi-threaded pass over the vertices.

    Parameters
    ----------
    V : (n, d) float
        Rest positions, d = ``sk.dim``.
    sk : Skeleton
    W : (n, b) ndarray or scipy.sparse
        Bone weights: >= 0; rows are renormalised with a warning if they do not sum to 1.
    E : (n, b) ndarray or scipy.sparse, optional
        Endpoint weights in [0, 1]. Used by ``stbs-lbs`` and ``stbs-dqs``; when omitted
        for those methods, projection endpoint weights (eq. 8) are computed.
    method : {"lbs", "dqs", "stbs-lbs", "stbs-dqs"}
    dtype : float32 or float64, optional
        Storage and output dtype; default float32 if V is float32, else float64.
        Kernels compute in float64 either way.
    max_influences : int, optional
        Truncate to this many bones per vertex and renormalise (default: keep all).
    normals : (n, d) float, optional
        Rest vertex normals; when given, ``deform_with_normals`` can skin them.

    Examples
    --------
    >>> import numpy as np
    >>> import stbs
    >>> V, F, sk, W = stbs.shapes.cigar(8)           # one bone along x, from -1 to 1
    >>> E = stbs.endpoint_weights(V, sk, method="projection")
    >>> dfm = stbs.Deformer(V, sk, W, E, method="stbs-dqs")    # precompute once
    >>> U = dfm(stbs.forward_kinematics(sk, stretch=[2.0]))    # per frame
    >>> tip = np.argmax(V[:, 0])
    >>> round(float(U[tip, 0] - V[tip, 0]), 6)     # the tip moves by the bone's growth
    2.0
    """

    def __init__(self, V, sk: Skeleton, W, E=None, *, method: Method = "stbs-dqs",
                 dtype=None, max_influences: int | None = None, normals=None):
        _checks.skeleton(sk)
        self.method = _checks.choice("method", method, METHODS)
        if dtype is None:
            dtype = np.float32 if getattr(V, "dtype", None) == np.float32 else np.float64
        self.dtype = _checks.dtype_choice(dtype)
        V = _checks.vertices(V)
        n, d = V.shape
        if d != sk.dim:
            raise ValueError(f"V must have shape ({n}, {sk.dim}) to match the {sk.dim}D "
                             f"skeleton, got {V.shape}")
        b = sk.n_bones
        W = _checks.bone_weights(W, n, b)
        uses_e = self.method.startswith("stbs")
        if uses_e:
            if E is None:
                from ..weights.endpoint import endpoint_weights
                E = endpoint_weights(V, sk, method="projection")
            E = _checks.endpoint_weights(E, n, b)
        self.skeleton = sk
        self.n, self.dim = n, d
        self.layout = top_k(W, E if uses_e else None, max_influences=max_influences,
                            dtype=self.dtype)
        self._V = self._pad(V)
        self._N = None
        if normals is not None:
            N = _checks.real_array("normals", normals, shape=(n, d))
            self._N = self._pad(N)
        self._dummy = np.zeros((1, 3), dtype=self.dtype)

    def _pad(self, X: np.ndarray) -> np.ndarray:
        out = np.zeros((X.shape[0], 3), dtype=self.dtype)
        out[:, : X.shape[1]] = X
        return out

    @property
    def nbytes(self) -> int:
        """Bytes held by the precomputed arrays."""
        return self._V.nbytes + self.layout.nbytes + (0 if self._N is None else self._N.nbytes)

    def _check_pose(self, pose) -> Pose:
        if not isinstance(pose, Pose):
            raise TypeError(f"pose must be a stbs.Pose, got {type(pose).__name__}")
        if pose.skeleton is not self.skeleton and not (
                pose.skeleton.n_bones == self.skeleton.n_bones
                and np.array_equal(pose.skeleton.C, self.skeleton.C)
                and np.array_equal(pose.skeleton.BE, self.skeleton.BE)):
            raise ValueError("pose belongs to a different skeleton than this Deformer's")
        return pose

    def _run(self, pose: Pose, out, want_normals: bool, Nout):
        lay = self.layout
        N = self._N if want_normals else self._dummy
        if self.method == "lbs":
            with _kernels.slp():
                _kernels.lbs(self._V, lay.idx, lay.w, _frame.lbs_table(pose), out, N, Nout,
                             want_normals)
        elif self.method == "dqs":
            Q, S, has_stretch = _frame.dqs_tables(pose)
            _kernels.dqs(self._V, lay.idx, lay.w, Q, S, has_stretch, out, N, Nout, want_normals)
        elif self.method == "stbs-lbs":
            _kernels.stbs_lbs(self._V, lay.idx, lay.w, lay.e, _frame.stbs_lbs_table(pose), out,
                              N, Nout, want_normals)
        else:
            _kernels.stbs_dqs(self._V, lay.idx, lay.w, lay.e, _frame.stbs_dqs_table(pose), out,
                              N, Nout, want_normals)

    def __call__(self, pose: Pose, *, out: np.ndarray | None = None) -> np.ndarray:
        """Deformed positions (n, d) for ``pose``.

        Parameters
        ----------
        out : (n, 3) array of this Deformer's dtype, optional
            Reused output buffer (3 columns even in 2D); avoids one allocation per frame.
        """
        pose = self._check_pose(pose)
        if out is None:
            out = np.empty((self.n, 3), dtype=self.dtype)
        elif out.shape != (self.n, 3) or out.dtype != self.dtype or not out.flags.c_contiguous:
            raise ValueError(f"out must be a C-contiguous ({self.n}, 3) {self.dtype} array, "
                             f"got {out.shape} {out.dtype}")
        self._run(pose, out, False, self._dummy)
        return out[:, : self.dim]

    def deform_with_normals(self, pose: Pose) -> tuple[np.ndarray, np.ndarray]:
        """Deformed positions and unit normals, each (n, d).

        Normals are turned by the blended rotation: the normalised blended rotation
        quaternion for ``dqs``/``stbs-dqs``; for ``lbs``/``stbs-lbs`` the cofactor
        (inverse transpose times determinant) of the blended linear part, so stretch
        and blending shear tilt normals correctly.
        """
        if self._N is None:
            raise ValueError("normals were not given to this Deformer; pass normals=(n, d) "
                             "rest normals to the constructor")
        pose = self._check_pose(pose)
        out = np.empty((self.n, 3), dtype=self.dtype)
        Nout = np.empty((self.n, 3), dtype=self.dtype)
        self._run(pose, out, True, Nout)
        if self.dim == 2:
            Nout[:, :2] /= np.maximum(np.linalg.norm(Nout[:, :2], axis=1, keepdims=True), 1e-300)
        return out[:, : self.dim], Nout[:, : self.dim]


def deform(V, sk: Skeleton, pose: Pose, W, E=None, *, method: Method = "stbs-dqs",
           dtype=None, max_influences: int | None = None) -> np.ndarray:
    """Deform ``V`` by ``pose`` with one of the four skinning methods.

    A one-shot wrapper over :class:`Deformer`; build a ``Deformer`` to skin many poses.

    Parameters
    ----------
    V : (n, d) float
    sk : Skeleton
    pose : Pose
    W : (n, b) ndarray or scipy.sparse
    E : (n, b) ndarray or scipy.sparse, optional
        Endpoint weights; projection weights (eq. 8) when omitted for STBS methods.
    method : {"lbs", "dqs", "stbs-lbs", "stbs-dqs"}

    Returns
    -------
    U : (n, d) float
        Deformed positions.
    """
    return Deformer(V, sk, W, E, method=method, dtype=dtype, max_influences=max_influences)(pose)
