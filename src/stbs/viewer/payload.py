"""What the viewer's page downloads: a rig's summary (JSON) and its arrays (binary).

The arrays are the ones a vertex shader takes: positions, faces, the skeleton, and
per vertex the four heaviest bones (``I4``), their weights renormalised to sum to 1
(``W4``) and the endpoint weights of the same (vertex, bone) pairs (``E4``), built
with the library's top-k layout (:func:`stbs.skinning.top_k`). Every array is
C-contiguous and little-endian, so the page reads it with one ``Float32Array`` (or
``Uint32Array``, ``Uint16Array``, ``Uint8Array``) over the response body.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
import scipy.sparse as sp

from .. import _checks
from ..rig import Rig
from ..skinning import METHODS, four_heaviest
from ..skinning.layout import FOUR

__all__ = ["RigPayload", "MAX_INFLUENCES", "ARRAY_DOCS"]

#: Bones per vertex in ``I4``/``W4``/``E4`` (a vec4 attribute each).
MAX_INFLUENCES = FOUR

#: Name -> meaning of every array the payload can serve (those the rig lacks are absent).
ARRAY_DOCS = {
    "V": "(n, d) float32 rest vertex positions",
    "F": "(f, 3) uint32 triangles (for a rig with tetrahedra only: their boundary)",
    "T": "(t, 4) uint32 tetrahedra",
    "C": "(j, d) float32 rest joint positions",
    "BE": "(b, 2) uint32 bones as joint pairs",
    "P": "(b,) int32 parent bone, -1 for roots",
    "I4": "(n, 4) uint16 (int32 past 65536 bones) the four heaviest bones, heaviest first",
    "W4": "(n, 4) float32 their bone weights, rows summing to 1 (unused slots 0)",
    "E4": "(n, 4) float32 the endpoint weights of the same (vertex, bone) pairs",
    "W": "(n, b) float32 all bone weights, rows summing to 1",
    "E": "(n, b) float32 all endpoint weights in [0, 1]",
}

#: Extras a caller may add (e.g. a 2D picture's texture), with the dtypes allowed.
_EXTRA_DTYPES = (np.float32, np.uint8, np.uint16, np.uint32, np.int32)


def _le(a: np.ndarray, dtype) -> np.ndarray:
    """``a`` as a C-contiguous little-endian array of ``dtype``."""
    return np.ascontiguousarray(a, dtype=np.dtype(dtype).newbyteorder("<"))


def _dense(X) -> np.ndarray:
    return X.toarray() if sp.issparse(X) else np.asarray(X)


class RigPayload:
    """A rig's summary and arrays as the viewer serves them, built once per rig.

    Parameters
    ----------
    rig : Rig
        The rig. Its bone weights are checked as :class:`stbs.Deformer` checks them
        (no negatives, rows summing to 1; rows off by more than a rounding error are
        renormalised with a warning). Without endpoint weights the projection
        endpoint weights (paper eq. 8) stand in, and ``info()["has_E"]`` is False.
    extras : mapping of str to ndarray, optional
        Further arrays to serve, e.g. ``{"UV": (n, 2) float32, "texture": (h, w, 4)
        uint8}`` for a textured 2D picture; names are letters and digits, dtypes
        float32, uint8, uint16, uint32 or int32. A rig with a picture
        (``rig.texture``, ``rig.UV``) serves it as ``texture`` (RGBA) and ``UV``
        unless extras of those names are given.

    Raises
    ------
    ValueError
        Bone weights that no skinning method accepts (a negative weight, a vertex
        attached to no bone), endpoint weights outside [0, 1], or a bad extra.
    """

    def __init__(self, rig: Rig, *, extras: Mapping[str, Any] | None = None):
        if not isinstance(rig, Rig):
            raise TypeError(f"rig must be a stbs.Rig, got {type(rig).__name__}")
        sk = rig.skeleton
        n, b = len(rig.V), sk.n_bones
        self.rig = rig
        self.W = _checks.bone_weights(rig.W, n, b)
        self.has_E = rig.E is not None
        if self.has_E:
            self.E = _checks.endpoint_weights(rig.E, n, b)
        else:
            from ..weights import projection

            self.E = projection(rig.V, sk)
        self._extras = {}
        for name, a in dict(extras or {}).items():
            if not (isinstance(name, str) and name.isascii() and name.isalnum()
                    and name not in ARRAY_DOCS):
                raise ValueError(f"extras: expected names of letters and digits other than "
                                 f"{', '.join(ARRAY_DOCS)}, got {name!r}")
            a = np.asarray(a)
            if a.dtype not in [np.dtype(t) for t in _EXTRA_DTYPES]:
                raise ValueError(f"extras[{name!r}]: expected dtype float32, uint8, uint16, "
                                 f"uint32 or int32, got {a.dtype}")
            self._extras[name] = _le(a, a.dtype)
        self._given = set(self._extras)
        if rig.texture is not None:     # a picture rig (stbs rig image.png): its picture
            tex = rig.texture
            if tex.shape[2] == 3:
                tex = np.concatenate([tex, np.full(tex.shape[:2] + (1,), 255, np.uint8)], axis=2)
            self._extras.setdefault("texture", _le(tex, np.uint8))
            self._extras.setdefault("UV", _le(rig.UV, np.float32))
        self._cache: dict[str, np.ndarray] = {}
        self._makers: dict[str, Callable[[], np.ndarray]] = {
            "V": lambda: _le(rig.V, np.float32),
            "C": lambda: _le(sk.C, np.float32),
            "BE": lambda: _le(sk.BE, np.uint32),
            "P": lambda: _le(sk.parents, np.int32),
            "W": lambda: _le(_dense(self.W), np.float32),
            "E": lambda: _le(np.clip(_dense(self.E), 0.0, 1.0), np.float32),
        }
        if rig.F is not None or rig.T is not None:
            self._makers["F"] = self._faces
        if rig.T is not None:
            self._makers["T"] = lambda: _le(rig.T, np.uint32)
        for key in ("I4", "W4", "E4"):
            self._makers[key] = lambda key=key: self._top4()[key]

    # ------------------------------------------------------------------ arrays
    def _faces(self) -> np.ndarray:
        if self.rig.F is not None:
            return _le(self.rig.F, np.uint32)
        from ..geometry import boundary_faces

        return _le(boundary_faces(self.rig.T, self.rig.V), np.uint32)

    def _top4(self) -> dict[str, np.ndarray]:
        idx, w, e = four_heaviest(self.W, self.E)            # (n, 4) each
        b = self.rig.skeleton.n_bones
        out = {"I4": _le(idx, np.uint16 if b <= 65536 else np.int32),
               "W4": _le(w, np.float32), "E4": _le(e, np.float32)}
        self._cache.update(out)
        return out

    @property
    def extras(self) -> dict[str, np.ndarray]:
        """The extra arrays given to the payload (name -> array), not the rig's picture."""
        return {k: a for k, a in self._extras.items() if k in self._given}

    @property
    def names(self) -> list[str]:
        """The names of the arrays served for this rig, in a fixed order."""
        return [k for k in ARRAY_DOCS if k in self._makers] + sorted(self._extras)

    def array(self, name: str) -> np.ndarray:
        """The array ``name`` (see :data:`ARRAY_DOCS`), computed on first use.

        Raises
        ------
        KeyError
            No such array for this rig.
        """
        if name in self._extras:
            return self._extras[name]
        if name not in self._makers:
            raise KeyError(name)
        if name not in self._cache:
            self._cache[name] = self._makers[name]()
        return self._cache[name]

    @staticmethod
    def describe(a: np.ndarray) -> dict:
        """``{"dtype": "float32", "shape": [n, 4]}`` of an array (little-endian)."""
        return {"dtype": a.dtype.name, "shape": [int(s) for s in a.shape]}

    def _shape(self, name: str) -> dict:
        """dtype and shape without computing a lazy array (both follow from the rig)."""
        if name in self._cache or name in self._extras:
            return self.describe(self.array(name))
        rig, sk = self.rig, self.rig.skeleton
        n, d, b = len(rig.V), rig.dim, sk.n_bones
        if name == "F":     # the boundary of tetrahedra: its size needs computing
            return self.describe(self.array(name))
        shapes = {"V": ("float32", [n, d]), "C": ("float32", [sk.n_joints, d]),
                  "BE": ("uint32", [b, 2]), "P": ("int32", [b]),
                  "T": ("uint32", [0 if rig.T is None else len(rig.T), 4]),
                  "I4": ("uint16" if b <= 65536 else "int32", [n, MAX_INFLUENCES]),
                  "W4": ("float32", [n, MAX_INFLUENCES]),
                  "E4": ("float32", [n, MAX_INFLUENCES]),
                  "W": ("float32", [n, b]), "E": ("float32", [n, b])}
        dtype, shape = shapes[name]
        return {"dtype": dtype, "shape": shape}

    # ------------------------------------------------------------------ summary
    def info(self) -> dict:
        """The summary ``GET /api/rig`` answers (see docs/viewer.md)."""
        rig, sk = self.rig, self.rig.skeleton
        faces = self._shape("F")["shape"][0] if "F" in self._makers else 0
        return {
            "vertices": int(len(rig.V)),
            "bones": int(sk.n_bones),
            "joints": int(sk.n_joints),
            "dim": int(rig.dim),
            "names": list(sk.names),
            "methods": list(METHODS),
            "method": "stbs-dqs",
            "parents": [int(p) for p in sk.parents],
            "connected": [bool(c) for c in sk.connected],
            "hang": [float(t) for t in sk.hang],
            "rest_joints": sk.C.tolist(),
            "has_E": bool(self.has_E),
            "faces": int(faces),
            "faces_from": ("rig" if rig.F is not None else
                           "tets" if rig.T is not None else None),
            "tets": 0 if rig.T is None else int(len(rig.T)),
            "max_influences": MAX_INFLUENCES,
            "byte_order": "little",
            "arrays": {k: {**self._shape(k), "url": f"/api/rig/{k}.bin"} for k in self.names},
        }
