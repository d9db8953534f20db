"""The native rig file: one ``.npz`` archive with documented, versioned keys.

A *rig* (:class:`stbs.Rig`) bundles the rest mesh, the skeleton and the weights. The
file is a plain NumPy ``.npz`` (zip of ``.npy`` arrays, written compressed),
readable without stbs and never containing pickled objects.

Format version 1
----------------

=========================  ================  ========  ======================================
key                        shape, dtype      required  meaning
=========================  ================  ========  ======================================
``stbs_rig_version``       (), int64         yes       format version, ``1``
``V``                      (n, d) float64    yes       rest vertex positions, d = 2 or 3
``F``                      (f, 3) int64      no        triangles, 0-based
``T``                      (t, 4) int64      no        tetrahedra, 0-based
``C``                      (j, d) float64    yes       rest joint positions
``BE``                     (b, 2) int64      yes       bones as 0-based joint pairs
``names``                  (b,) unicode      no        bone names
``P``                      (b,) int64        no [3]_   parent bone of each bone, -1 for roots
``W``                      (n, b) float64    yes [1]_  bone weights, dense
``W_data``                 (nnz,) float64    yes [1]_  bone weights, sparse CSR: values
``W_indices``              (nnz,) int64      yes [1]_  column (bone) index of each value
``W_indptr``               (n + 1,) int64    yes [1]_  row pointers
``W_shape``                (2,) int64        yes [1]_  ``[n, b]``
``E``, ``E_data``, ...     as ``W``          no        endpoint weights, dense or sparse CSR
``meta_json``              (), unicode       no        JSON object: free metadata
``texture``                (H, W, c) uint8   no [2]_   a picture on the mesh, RGB(A), row 0 on top
``UV``                     (n, 2) float64    no [2]_   texture coordinates, OpenGL convention
``volume_V``               (m, d) float64    no [4]_   the kept volume mesh's vertices
``volume_T``               (t, d+1) int64    no [4]_   its tetrahedra (3D) or triangles (2D)
``volume_M_data``, ...     CSR as ``W``      no [4]_   (n, m): rig vertices from the volume's
=========================  ================  ========  ======================================

.. [1] Exactly one of the two forms of ``W`` (dense ``W`` or the four ``W_*``
   keys) is present; the same holds for ``E`` when it is stored.
.. [2] ``texture`` and ``UV`` come together (a rig made from an image, see
   :class:`stbs.Rig`); readers of this version that predate them ignore both.
.. [3] Without ``P`` the parents are inferred from shared joints (every child starts
   at its parent's end joint); with it a child may hang anywhere on its parent (an
   offset child, as glTF, FBX and BVH hierarchies have).
.. [4] ``volume_V``, ``volume_T`` and the four ``volume_M_*`` keys (``data``,
   ``indices``, ``indptr``, ``shape``, sparse CSR as for ``W``) come together: the volume
   mesh the weights were solved on, kept with the rig (:class:`stbs.rig.Volume`,
   ``stbs rig --keep-volume``). Row k of ``volume_M`` gives rig vertex k as a
   combination of volume vertices (barycentric coordinates, or a single 1 where the rig
   vertex is a volume vertex). Readers that predate them ignore all six.

An absent optional key means None (no ``F``, no ``T``, default names, no
``E``, empty metadata). Readers check the version first and ignore keys not
in this table; any change to the meaning of a key gets a new version number.
"""

from __future__ import annotations

import json
import os
import zipfile
import zlib
from typing import Any

import numpy as np
import scipy.sparse as sp

from ..rig.model import Rig, Volume
from ._atomic import atomic_open
from ._npz import Budget
from ._parse import input_path, suffix
from .errors import FormatError

__all__ = ["save_rig", "load_rig", "RIG_VERSION"]

#: The format version :func:`save_rig` writes and :func:`load_rig` reads.
RIG_VERSION = 1

_SPARSE_PARTS = ("data", "indices", "indptr", "shape")


def _put_weights(out: dict, name: str, X) -> None:
    if X is None:
        return
    if sp.issparse(X):
        out[f"{name}_data"] = np.asarray(X.data, dtype=np.float64)
        out[f"{name}_indices"] = np.asarray(X.indices, dtype=np.int64)
        out[f"{name}_indptr"] = np.asarray(X.indptr, dtype=np.int64)
        out[f"{name}_shape"] = np.asarray(X.shape, dtype=np.int64)
    else:
        out[name] = np.asarray(X, dtype=np.float64)


def save_rig(path: str | os.PathLike, rig: Rig) -> None:
    """Write ``rig`` to one ``.npz`` file (format version 1, see the module docs), atomically.

    Parameters
    ----------
    path : str or os.PathLike
        Destination ending in ``.npz``; its folder must exist. The file is
        written to a temporary name and renamed, so a failure leaves any
        existing file untouched.
    rig : Rig

    Raises
    ------
    ValueError
        ``path`` does not end in ``.npz``, ``rig`` is not a :class:`Rig`, or
        ``rig.meta`` is not JSON-serialisable.
    """
    suffix(path, (".npz",), "save_rig")
    if not isinstance(rig, Rig):
        raise ValueError(f"rig must be a stbs.Rig, got {type(rig).__name__}")
    # Re-validate: the fields may have been reassigned since construction.
    rig = rig.replace()
    out: dict[str, np.ndarray] = {
        "stbs_rig_version": np.asarray(RIG_VERSION, dtype=np.int64),
        "V": rig.V,
        "C": rig.C,
        "BE": rig.BE,
        "P": rig.skeleton.parents,
    }
    if rig.F is not None:
        out["F"] = rig.F
    if rig.T is not None:
        out["T"] = rig.T
    if rig.names is not None:
        out["names"] = np.asarray(rig.names, dtype=np.str_).reshape(-1)
    _put_weights(out, "W", rig.W)
    _put_weights(out, "E", rig.E)
    if rig.texture is not None:
        out["texture"] = rig.texture
        out["UV"] = np.asarray(rig.UV, dtype=np.float64)
    if rig.volume is not None:
        out["volume_V"] = np.asarray(rig.volume.V, dtype=np.float64)
        out["volume_T"] = np.asarray(rig.volume.T, dtype=np.int64)
        _put_weights(out, "volume_M", rig.volume.M)
    if rig.meta:
        try:
            text = json.dumps(rig.meta, allow_nan=False)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"rig.meta must be JSON-serialisable, got {exc}") from None
        out["meta_json"] = np.asarray(text, dtype=np.str_)
    with atomic_open(path, "wb") as f:
        np.savez_compressed(f, **out)


def _get_weights(p, z, keys: set, name: str, required: bool):
    parts = [f"{name}_{s}" for s in _SPARSE_PARTS]
    have_dense = name in keys
    have_parts = [k for k in parts if k in keys]
    if have_dense and have_parts:
        raise FormatError(p, f"either '{name}' or the CSR keys {parts}", "both")
    if have_dense:
        return z[name]
    if have_parts:
        missing = [k for k in parts if k not in keys]
        if missing:
            raise FormatError(p, f"all CSR keys {parts}", f"{missing} missing")
        shape = z[f"{name}_shape"]
        if shape.shape != (2,) or shape.dtype.kind not in "iu" or np.any(shape < 0):
            raise FormatError(p, f"'{name}_shape' = [rows, cols] (2 non-negative integers)",
                              f"{shape!r}")
        try:
            return sp.csr_array((z[f"{name}_data"], z[f"{name}_indices"], z[f"{name}_indptr"]),
                                shape=tuple(int(s) for s in shape))
        except (ValueError, TypeError) as exc:
            raise FormatError(p, f"consistent CSR arrays for {name}", str(exc)) from None
    if required:
        raise FormatError(p, f"key '{name}' (dense) or {parts} (sparse)",
                          f"keys {sorted(keys)}")
    return None


def load_rig(path: str | os.PathLike) -> Rig:
    """Read a rig written by :func:`save_rig`.

    Parameters
    ----------
    path : str or os.PathLike
        A ``.npz`` rig file (format version 1).

    Returns
    -------
    Rig
        ``W`` and ``E`` come back dense or sparse as they were saved; ``names``
        and ``meta`` as saved (None and ``{}`` when absent).

    Raises
    ------
    FileNotFoundError
        ``path`` does not exist.
    FormatError
        Not an ``.npz`` archive, no or another ``stbs_rig_version``, a missing
        required key, wrong dtypes (object arrays are never unpickled), or
        arrays whose shapes do not fit together (e.g. ``W`` rows != ``V`` rows,
        ``W`` columns != bones); the message names the key.
    """
    p = input_path(path, "rig")
    if not zipfile.is_zipfile(p):
        raise FormatError(p, "an .npz (zip) archive written by stbs.io.save_rig",
                          "an empty file" if p.stat().st_size == 0 else "another kind of file")
    # np.load is given an open handle so that a broken archive cannot leak it.
    with open(p, "rb") as fh:
        try:
            z = np.load(fh, allow_pickle=False)
        except (ValueError, OSError, EOFError, zipfile.BadZipFile) as exc:
            raise FormatError(p, "a readable .npz archive", str(exc)) from None
        if not hasattr(z, "files"):
            raise FormatError(p, "an .npz archive", f"a {type(z).__name__}")
        with z:
            keys = set(z.files)
            try:
                return _load(p, _Arrays(p, z), keys)
            except FormatError:
                raise
            except (ValueError, zipfile.BadZipFile, zlib.error, OSError, EOFError) as exc:
                # Rig's shape checks and damaged members end up here.
                raise FormatError(p, "a consistent stbs rig", str(exc)) from None


class _Arrays:
    """``z[key]`` with object arrays reported as a FormatError naming the key."""

    def __init__(self, p, z):
        self.p, self.z = p, z
        self.budget = Budget(p)

    def __getitem__(self, key: str) -> np.ndarray:
        try:
            return self.budget.npz_member(self.z, key)
        except FormatError:
            raise
        except ValueError as exc:
            raise FormatError(self.p, f"'{key}' as a plain numeric or unicode array (object "
                              "arrays are never unpickled)", str(exc)) from None


def _load(p, z: _Arrays, keys: set) -> Rig:
    _check_version(p, z, keys)
    arrays = _mesh_arrays(p, z, keys)
    W = _get_weights(p, z, keys, "W", required=True)
    E = _get_weights(p, z, keys, "E", required=False)
    return Rig(V=arrays["V"], F=arrays.get("F"), T=arrays.get("T"), C=arrays["C"],
               BE=arrays["BE"], P=arrays.get("P"), names=_names(p, z, keys), W=W, E=E,
               meta=_meta(p, z, keys), volume=_volume(p, z, keys), **_picture(p, z, keys))


def _check_version(p, z: _Arrays, keys: set) -> None:
    if "stbs_rig_version" not in keys:
        raise FormatError(p, "a stbs rig with key 'stbs_rig_version'",
                          f"keys {sorted(keys)}")
    ver = z["stbs_rig_version"]
    if ver.shape != () or ver.dtype.kind not in "iu":
        raise FormatError(p, "'stbs_rig_version' as one integer", f"{ver!r}")
    if int(ver) != RIG_VERSION:
        raise FormatError(p, f"stbs_rig_version {RIG_VERSION} (the version this stbs reads)",
                          f"version {int(ver)}")
    for k in ("V", "C", "BE"):
        if k not in keys:
            raise FormatError(p, f"required key '{k}'", f"keys {sorted(keys)}")


def _typed(p, z: _Arrays, k: str, kinds: str) -> np.ndarray:
    """``z[k]`` of one of the dtype ``kinds`` ("f": float, "iu": integer)."""
    a = z[k]
    if a.dtype.kind not in kinds:
        want = "float" if kinds == "f" else "integer"
        raise FormatError(p, f"'{k}' of {want} dtype", f"dtype {a.dtype}")
    return a


def _mesh_arrays(p, z: _Arrays, keys: set) -> dict[str, Any]:
    return {k: _typed(p, z, k, kinds) for k, kinds in (
        ("V", "f"), ("C", "f"), ("BE", "iu"), ("P", "iu"), ("F", "iu"), ("T", "iu"))
        if k in keys}


def _names(p, z: _Arrays, keys: set) -> list[str] | None:
    if "names" not in keys:
        return None
    a = z["names"]
    if a.dtype.kind != "U" or a.ndim != 1:
        raise FormatError(p, "'names' as a 1-D unicode array",
                          f"dtype {a.dtype}, shape {a.shape}")
    return [str(s) for s in a.tolist()]


def _meta(p, z: _Arrays, keys: set) -> dict:
    if "meta_json" not in keys:
        return {}
    a = z["meta_json"]
    try:
        meta = json.loads(str(a[()])) if a.dtype.kind == "U" and a.shape == () else None
    except json.JSONDecodeError:
        meta = None
    if not isinstance(meta, dict):
        raise FormatError(p, "'meta_json' as the text of a JSON object",
                          f"dtype {a.dtype}, shape {a.shape}")
    return meta


def _picture(p, z: _Arrays, keys: set) -> dict[str, np.ndarray]:
    picture = {}
    for k, kinds, want in (("texture", "u", "uint8"), ("UV", "f", "float")):
        if k in keys:
            a = z[k]
            if a.dtype.kind not in kinds or (k == "texture" and a.dtype != np.uint8):
                raise FormatError(p, f"'{k}' of {want} dtype", f"dtype {a.dtype}")
            picture[k] = a
    return picture


_VOLUME_KEYS = ("volume_V", "volume_T", *(f"volume_M_{s}" for s in _SPARSE_PARTS))


def _volume(p, z: _Arrays, keys: set) -> Volume | None:
    """The kept volume mesh (all six keys), or None (none of them)."""
    have = [k for k in _VOLUME_KEYS if k in keys]
    if not have:
        return None
    if len(have) != len(_VOLUME_KEYS):
        raise FormatError(p, f"all the volume keys {list(_VOLUME_KEYS)} or none",
                          f"{sorted(set(_VOLUME_KEYS) - set(have))} missing")
    M = _get_weights(p, z, keys, "volume_M", required=True)
    # Rig checks the shapes against the rig's; a ValueError there names the key
    return Volume(V=_typed(p, z, "volume_V", "f"), T=_typed(p, z, "volume_T", "iu"), M=M)
