"""The rig model: a rest mesh, one skeleton and the weights.

A :class:`Rig` is data, not a file: :func:`stbs.io.save_rig` and
:func:`stbs.io.load_rig` write and read it as a versioned ``.npz``, and
:func:`stbs.build_rig` computes one from a bare mesh and skeleton.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp

from .. import _checks
from ..skeleton import Skeleton

__all__ = ["Rig", "Volume"]


def _weights(name: str, X: Any, n: int, b: int):
    """Dense (n, b) float64 or CSR float64 of that shape, finite; values not constrained."""
    if X is None:
        return None
    if sp.issparse(X):
        X = sp.csr_array(X, dtype=np.float64)
        if X.shape != (n, b):
            raise ValueError(f"{name} must have shape ({n}, {b}) (vertices, bones), "
                             f"got {X.shape}")
        if not np.all(np.isfinite(X.data)):
            raise ValueError(f"{name} must be finite, got non-finite stored values")
        X.sort_indices()
        return X
    if np.ndim(X) == 1 and b == 1:
        X = np.asarray(X).reshape(-1, 1)
    X = _checks.real_array(name, X, ndim=2)
    if X.shape != (n, b):
        raise ValueError(f"{name} must have shape ({n}, {b}) (vertices, bones), got {X.shape}")
    return X


def _elements(name: str, X: Any, k: int, n: int):
    if X is None:
        return None
    X = _checks.index_array(name, X, ndim=2, shape=(None, k))
    if X.size and (X.min() < 0 or X.max() >= n):
        bad = int(X.min()) if X.min() < 0 else int(X.max())
        raise ValueError(f"{name} must hold vertex indices in 0..{n - 1}, got {bad}")
    return X


def _picture(texture: Any, UV: Any, n: int):
    """``(texture, UV)`` checked: both None, or an (H, W, 3|4) uint8 image and (n, 2) UVs."""
    if texture is None and UV is None:
        return None, None
    if texture is None or UV is None:
        given, missing = ("texture", "UV") if UV is None else ("UV", "texture")
        raise ValueError(f"{given} needs {missing}: give both (a picture and the vertices' "
                         f"texture coordinates) or neither")
    tex = np.asarray(texture)
    if tex.dtype != np.uint8 or tex.ndim != 3 or tex.shape[2] not in (3, 4) \
            or min(tex.shape[:2]) < 1:
        raise ValueError(f"texture must be an (H, W, 3) or (H, W, 4) uint8 image, got "
                         f"{tex.dtype} of shape {tex.shape}")
    uv = _checks.real_array("UV", UV, ndim=2, shape=(n, 2))
    lo, hi = float(uv.min(initial=0)), float(uv.max(initial=1))
    if lo < 0 or hi > 1:
        raise ValueError(f"UV must lie in [0, 1], got values in [{lo:.6g}, {hi:.6g}]")
    return np.ascontiguousarray(tex), uv


@dataclass(frozen=True, eq=False)
class Volume:
    """The volume mesh a rig's weights were solved on, kept so that BBW can run again.

    A 3D surface's rig solves its bounded biharmonic weights on a tetrahedral mesh of
    its inside, and a 2D shape's on a re-triangulation with the bones inside; the rig
    itself keeps only the given vertices. :func:`stbs.build_rig` with
    ``keep_volume=True`` keeps that mesh here (``rig.volume``), and
    :func:`stbs.rig.rig_endpoint_weights` solves on it.

    Attributes
    ----------
    V : (m, d) float64
        The volume's vertices.
    T : (t, d + 1) int64
        Its simplices: tetrahedra in 3D, triangles in 2D.
    M : (n, m) scipy.sparse.csr_array, float64
        How the rig's vertices come from the volume's: values on the rig are
        ``M @ values on the volume``. Row k holds rig vertex k's barycentric
        coordinates in a volume simplex (the winding-number volume, whose vertices
        are its own), or a single 1 where rig vertex k is a volume vertex (the
        conforming tetrahedra and the 2D re-triangulation, which keep the rig's
        vertices: see :attr:`index`). Rows are >= 0 and sum to 1.
    """

    V: np.ndarray
    T: np.ndarray
    M: Any

    @classmethod
    def selection(cls, V, T, index) -> Volume:
        """A volume holding the rig's vertices: rig vertex k is volume vertex ``index[k]``."""
        index = np.asarray(index, dtype=np.int64).ravel()
        M = sp.csr_array((np.ones(index.size), (np.arange(index.size), index)),
                         shape=(index.size, np.shape(V)[0]))
        return cls(V=np.asarray(V, dtype=np.float64), T=np.asarray(T, dtype=np.int64), M=M)

    @property
    def index(self) -> np.ndarray | None:
        """(n,) int64: the volume vertex each rig vertex is, or None when some rig vertex
        is interpolated (the winding-number volume)."""
        M = self.M
        if M.nnz != M.shape[0] or np.any(np.diff(M.indptr) != 1) or np.any(M.data != 1.0):
            return None
        return np.asarray(M.indices, dtype=np.int64)

    def __repr__(self) -> str:
        kind = "tetrahedra" if self.T.shape[1] == 4 else "triangles"
        return f"Volume({self.V.shape[0]} vertices, {self.T.shape[0]} {kind})"


def _volume(volume: Any, n: int, d: int) -> Volume | None:
    """``volume`` checked against the rig's n vertices in d dimensions."""
    if volume is None:
        return None
    if not isinstance(volume, Volume):
        raise TypeError(f"volume must be a stbs.rig.Volume or None, got "
                        f"{type(volume).__name__}")
    Vv = _checks.real_array("volume.V", volume.V, ndim=2, shape=(None, d))
    m = Vv.shape[0]
    Tv = _elements("volume.T", volume.T, d + 1, m)
    if Tv.shape[0] == 0:
        raise ValueError(f"volume.T must hold at least one simplex, got shape {Tv.shape}")
    if not sp.issparse(volume.M):
        raise ValueError(f"volume.M must be a scipy.sparse ({n}, {m}) array, got "
                         f"{type(volume.M).__name__}")
    M = sp.csr_array(volume.M, dtype=np.float64)
    if M.shape != (n, m):
        raise ValueError(f"volume.M must have shape ({n}, {m}) (rig vertices, volume "
                         f"vertices), got {M.shape}")
    M.sort_indices()
    rows = np.asarray(M.sum(axis=1)).ravel()
    bad_values = M.nnz > 0 and not (np.all(np.isfinite(M.data)) and M.data.min() >= 0)
    if bad_values or np.abs(rows - 1).max(initial=0) > 1e-9:
        raise ValueError("volume.M must hold non-negative weights whose rows sum to 1 "
                         "(each rig vertex a combination of volume vertices)")
    return Volume(V=Vv, T=Tv, M=M)


class Rig:
    """A rest mesh with its skeleton and weights.

    The skeleton is given either as a :class:`stbs.Skeleton` (``skeleton=``) or as its
    arrays (``C``, ``BE``, ``names``); the rig builds it once and always returns that
    same object, so poses made from ``rig.skeleton`` compose with each other.

    Parameters
    ----------
    V : (n, d) float
        Rest vertex positions, d = 2 or 3.
    W : (n, b) float, dense or scipy.sparse
        Bone weights.
    skeleton : Skeleton, optional
        The skeleton (d-dimensional). Give it, or ``C`` and ``BE``, not both.
    C : (j, d) float, optional
        Rest joint positions.
    BE : (b, 2) int, optional
        Bones as joint pairs; with ``C`` they must form a valid :class:`stbs.Skeleton`.
    names : sequence of b str, optional
        Bone names (with ``C`` and ``BE``; a ``skeleton`` brings its own).
    P : (b,) int, optional
        Parent bones (with ``C`` and ``BE``; see :class:`stbs.Skeleton`).
    F : (f, 3) int, optional
        Triangles.
    T : (t, 4) int, optional
        Tetrahedra.
    E : (n, b) float, dense or scipy.sparse, optional
        Endpoint weights.
    meta : dict, optional
        Free metadata (JSON-serialisable to be saved), e.g. how the weights were made.
    texture : (H, W, 3) or (H, W, 4) uint8, optional
        A picture drawn on the mesh (a 2D rig made from an image, paper Fig. 12): RGB or
        RGBA, row 0 at the top. Needs ``UV``.
    UV : (n, 2) float, optional
        Texture coordinates of the vertices in the OpenGL convention: ``u`` across from
        the picture's left edge, ``v`` up from its bottom edge, both in [0, 1]; vertex
        ``k`` shows pixel ``(row, col) = ((1 - v) H - 1/2, u W - 1/2)``. Needs
        ``texture``.
    volume : Volume, optional
        The volume mesh the weights were solved on, when it is not the rig's own
        (:func:`stbs.build_rig` with ``keep_volume=True``); its ``M`` maps its
        vertices to the rig's.

    Raises
    ------
    ValueError
        Shapes that do not fit together (``W`` not (n, b), a skeleton of another
        dimension than ``V``, indices out of range), non-finite values, or an invalid
        skeleton; the message names the argument.
    TypeError
        ``skeleton`` is not a :class:`stbs.Skeleton`, or both forms are given.

    Notes
    -----
    Only shapes and finiteness are checked here: the partition of unity of ``W`` and
    the range of ``E`` are checked where the weights are used, so a rig can hold
    painted, unnormalised weights as found in real files.

    Examples
    --------
    >>> import numpy as np
    >>> import stbs
    >>> sk = stbs.Skeleton([[0, 0], [1, 0]], [[0, 1]])
    >>> rig = stbs.Rig(V=[[0, 0.1], [1, 0.1], [1, -0.1]], F=[[0, 2, 1]], skeleton=sk,
    ...                W=np.ones((3, 1)))
    >>> rig
    Rig(V=(3, 2), F=(1, 3), C=(2, 2), BE=(1, 2), W=(3, 1))
    >>> rig.skeleton is sk, rig.dim
    (True, 2)
    """

    def __init__(self, *, V, W, skeleton: Skeleton | None = None, C=None, BE=None,
                 names=None, P=None, F=None, T=None, E=None, meta: dict | None = None,
                 texture=None, UV=None, volume: Volume | None = None):
        V = _checks.vertices(V)
        n, d = V.shape
        if skeleton is not None:
            if C is not None or BE is not None or names is not None or P is not None:
                raise TypeError("give the skeleton as skeleton= or as C, BE (and names, P), "
                                "not both")
            if not isinstance(skeleton, Skeleton):
                raise TypeError(f"skeleton must be a stbs.Skeleton, got "
                                f"{type(skeleton).__name__}")
            sk = skeleton
            named = True
        else:
            if C is None or BE is None:
                raise TypeError("a Rig needs its skeleton: skeleton=, or C and BE")
            sk = Skeleton(C, BE, names, P=P)
            named = names is not None
        if sk.dim != d:
            raise ValueError(f"C must have {d} columns like V (n, {d}), got {sk.C.shape}")
        self.V = V
        self.F = _elements("F", F, 3, n)
        self.T = _elements("T", T, 4, n)
        self._skeleton = sk
        self._named = named
        b = sk.n_bones
        self.W = _weights("W", W, n, b)
        if self.W is None:
            raise ValueError("W must be given: (n, b) bone weights")
        self.E = _weights("E", E, n, b)
        meta = {} if meta is None else meta
        if not isinstance(meta, dict):
            raise ValueError(f"meta must be a dict, got {type(meta).__name__}")
        self.meta = meta
        self.texture, self.UV = _picture(texture, UV, n)
        self.volume = _volume(volume, n, d)

    @property
    def skeleton(self) -> Skeleton:
        """The rig's one :class:`stbs.Skeleton` (the same object on every access)."""
        return self._skeleton

    @property
    def C(self) -> np.ndarray:
        """(j, d) rest joint positions (read-only, the skeleton's)."""
        return self._skeleton.C

    @property
    def BE(self) -> np.ndarray:
        """(b, 2) bones as joint pairs (read-only, the skeleton's)."""
        return self._skeleton.BE

    @property
    def names(self) -> list[str] | None:
        """The bone names given to the rig, or None when the defaults are used."""
        return list(self._skeleton.names) if self._named else None

    @property
    def dim(self) -> int:
        """2 or 3."""
        return int(self.V.shape[1])

    def replace(self, **changes) -> Rig:
        """A new rig with some fields replaced (checked again), e.g. ``rig.replace(E=E2)``.

        The skeleton object is kept unless ``skeleton`` (or ``C``/``BE``/``names``/``P``)
        is among the changes.
        """
        fields = dict(V=self.V, F=self.F, T=self.T, W=self.W, E=self.E, meta=self.meta,
                      texture=self.texture, UV=self.UV, volume=self.volume)
        if not ({"skeleton", "C", "BE", "names", "P"} & changes.keys()):
            fields["skeleton"] = self._skeleton
        elif "skeleton" not in changes:
            fields.update(C=self.C, BE=self.BE, names=self.names,
                          P=None if "BE" in changes else self._skeleton.parents)
        fields.update(changes)
        rig = Rig(**fields)
        if "skeleton" in fields and "names" not in changes:
            rig._named = self._named if fields["skeleton"] is self._skeleton else True
        return rig

    def __repr__(self) -> str:
        parts = [f"V={self.V.shape}"]
        parts += [f"{k}={getattr(self, k).shape}" for k in ("F", "T")
                  if getattr(self, k) is not None]
        parts += [f"C={self.C.shape}", f"BE={self.BE.shape}"]
        parts += [f"{k}={'sparse ' if sp.issparse(getattr(self, k)) else ''}"
                  f"{getattr(self, k).shape}" for k in ("W", "E") if getattr(self, k) is not None]
        if self.texture is not None:
            parts.append(f"texture={self.texture.shape}")
        if self.volume is not None:
            parts.append(f"volume={self.volume!r}")
        return f"Rig({', '.join(parts)})"
