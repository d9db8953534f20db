"""Endpoint weights of a rig, solved again: which methods can work on it, and the solve.

Bounded biharmonic endpoint weights need a volume: a 2D rig's triangles, a rig's own
tetrahedra, or the volume mesh a 3D surface's weights were solved on, when the rig
kept it (:func:`stbs.build_rig` with ``keep_volume=True``, ``rig.volume``). Heat needs
a 3D surface (or tetrahedra, whose boundary it uses); projection and idw work on any
rig.
"""

from __future__ import annotations

import numpy as np

from .. import _checks
from ..methods import ENDPOINT_METHODS
from .build import Progress, _extend, _extend_values, _to_volume
from .model import Rig, _weights

__all__ = ["endpoint_methods", "rig_endpoint_weights"]

#: Options :func:`rig_endpoint_weights` passes on (:func:`stbs.endpoint_weights`'s).
OPTIONS = ("threshold", "alpha", "normalize", "backend", "tol")


def _bbw_volume(rig: Rig) -> bool:
    return rig.volume is not None or rig.T is not None or (rig.dim == 2 and rig.F is not None)


def _why_not(rig: Rig, method: str) -> str | None:
    """Why ``method`` cannot work on ``rig``, or None when it can."""
    if method in ("bbw", "bbw-joints") and not _bbw_volume(rig):
        return ("BBW needs a volume (2D triangles, tetrahedra, or the volume mesh kept "
                "with the rig) and this 3D rig has only " +
                ("a surface; build it with keep_volume=True (stbs rig --keep-volume)"
                 if rig.F is not None else "vertices"))
    if method == "heat" and (rig.dim != 3 or (rig.F is None and rig.T is None)):
        return ("heat needs a 3D triangle surface or tetrahedra, and this rig is "
                + (f"{rig.dim}D" if rig.dim != 3 else "a point cloud"))
    return None


def endpoint_methods(rig: Rig) -> tuple[str, ...]:
    """The endpoint weight methods that can work on ``rig``, in the order of
    :data:`stbs.methods.ENDPOINT_METHODS`.

    ``bbw`` and ``bbw-joints`` need a volume (2D triangles, tetrahedra, or a kept
    ``rig.volume``), ``heat`` a 3D surface or tetrahedra; ``projection`` and ``idw``
    always work.

    Examples
    --------
    >>> import numpy as np
    >>> import stbs
    >>> sk = stbs.Skeleton([[0, 0, 0], [1, 0, 0]], [[0, 1]])
    >>> rig = stbs.Rig(V=[[0, 0.1, 0], [1, 0.1, 0], [1, -0.1, 0]], F=[[0, 2, 1]],
    ...                skeleton=sk, W=np.ones((3, 1)))
    >>> endpoint_methods(rig)                     # a 3D surface without its volume
    ('heat', 'projection', 'idw')
    """
    if not isinstance(rig, Rig):
        raise TypeError(f"rig must be a stbs.Rig, got {type(rig).__name__}")
    return tuple(m for m in ENDPOINT_METHODS if _why_not(rig, m) is None)


def rig_endpoint_weights(rig: Rig, method: str, *, bones=None, W=None,
                         progress: Progress | None = None, **options) -> np.ndarray:
    """Endpoint weights of some of a rig's bones, solved again on what the rig holds.

    Parameters
    ----------
    rig : Rig
    method : {"bbw", "bbw-joints", "heat", "projection", "idw"}
        One of :func:`endpoint_methods` ``(rig)``.
    bones : sequence of int, optional
        The bones to solve (default all).
    W : (n, b) float, optional
        Bone weights that restrict the solved methods (paper §3); default ``rig.W``.
    progress : callable, optional
        ``progress(stage, done, total)``: ``(stage, 0, 0)`` first, then ``done`` of
        ``total`` bones (and solver rounds within). Raise any exception from it to
        cancel: the solve stops at its next report and the exception propagates
        (``progress`` is not called again).
    **options
        ``threshold``, ``alpha``, ``normalize``, ``backend``, ``tol``: as for
        :func:`stbs.endpoint_weights`.

    Returns
    -------
    E : (n, b) float64
        In [0, 1], ready for ``rig.replace(E=E)``: the columns of ``bones`` solved,
        the others ``rig.E``'s (the projection, eq. 8, when the rig has none). BBW on a
        kept volume is solved there, with ``W`` carried into it (harmonically where the
        volume holds the rig's vertices, else from the nearest rig vertices), and
        brought to the rig's vertices by ``rig.volume.M``.

    Raises
    ------
    ValueError
        An unknown method, or one that cannot work on this rig (the message names the
        method and says why), bad ``bones`` or ``W``, or an unknown option.
    """
    from ..weights import endpoint_weights, projection

    methods = endpoint_methods(rig)
    _checks.choice("method", method, ENDPOINT_METHODS)
    if method not in methods:
        raise ValueError(f"endpoint method {method!r} cannot work on this rig: "
                         f"{_why_not(rig, method)}")
    unknown = sorted(set(options) - set(OPTIONS))
    if unknown:
        raise ValueError(f"options must be among {', '.join(OPTIONS)}, got {unknown[0]!r}")
    sk, n, b = rig.skeleton, rig.V.shape[0], rig.skeleton.n_bones
    W = rig.W if W is None else _weights("W", W, n, b)
    todo = _checks.bone_list(bones, b)
    stage = f"endpoint weights ({method})"
    say = progress or (lambda s, done, total: None)
    say(stage, 0, 0)

    def bar(done, total):
        say(stage, done, total)

    solved = method in ("bbw", "bbw-joints", "heat")
    kw = dict(options, bones=todo, progress=bar, **({"W": W} if solved else {}))
    if method in ("bbw", "bbw-joints") and rig.volume is not None:
        E_new = _on_volume(rig, method, W, todo, kw)
    elif method == "heat" and rig.F is None:
        E_new = _heat_on_tets(rig, kw)
    else:
        E_new = endpoint_weights(rig.V, sk, method=method, F=rig.F, T=rig.T, **kw)
    E = projection(rig.V, sk) if rig.E is None else _dense(rig.E).copy()
    E[:, todo] = E_new[:, todo]
    return E


def _dense(X) -> np.ndarray:
    return X.toarray() if hasattr(X, "toarray") else np.asarray(X, dtype=float)


def _volume_weights(rig: Rig, W) -> np.ndarray:
    """The rig's bone weights W (n, b) carried into its kept volume (m, b)."""
    vol = rig.volume
    index = vol.index
    Wd = _dense(W)
    if index is None:                 # the winding-number volume: interpolated
        return _to_volume(vol, rig.V, Wd, vol.M)
    m = vol.V.shape[0]
    Wv = np.zeros((m, Wd.shape[1]))
    np.add.at(Wv, index, Wd)          # welded copies: their mean
    count = np.bincount(index, minlength=m)
    known = count > 0
    Wv[known] /= count[known, None]
    return _extend(vol.V, vol.T, Wv, known)


def _on_volume(rig: Rig, method: str, W, todo: list[int], kw: dict) -> np.ndarray:
    """BBW endpoint weights on the kept volume, brought to the rig's vertices."""
    from ..weights import endpoint_weights
    from ..weights.endpoint import bone_points

    vol, sk = rig.volume, rig.skeleton
    kw = dict(kw, W=_volume_weights(rig, W))
    if vol.index is None:
        # A bone with fewer than two volume vertices on it (outside the shape) has
        # nothing to spread e from 0 to 1 along: it keeps the projection, as at build.
        inside = bone_points(vol.V, sk, vol.T) >= 2
        kw["bones"] = [i for i in todo if inside[i]]
    Ev = endpoint_weights(vol.V, sk, method=method, T=vol.T, **kw)
    return np.clip(np.asarray(vol.M @ Ev), 0.0, 1.0)


def _heat_on_tets(rig: Rig, kw: dict) -> np.ndarray:
    """Heat endpoint weights of a tetrahedral rig: on its boundary, extended inside."""
    from ..geometry import boundary_faces
    from ..weights import endpoint_weights

    Fs = boundary_faces(rig.T)
    known = np.zeros(rig.V.shape[0], dtype=bool)
    known[np.unique(Fs)] = True
    E = endpoint_weights(rig.V, rig.skeleton, method="heat", F=Fs, **kw)
    return E if known.all() else _extend_values(rig.V, rig.T, E, known)
