"""Mesh animations (a rest mesh and its frames) in: what the fitting commands take.

Two forms:

- one ``.npz`` with ``frames`` (f, n, d) float, and optionally ``rest`` (n, d) float and
  ``F`` (m, 3) int (0-based triangles); without ``rest`` the first frame is the rest
  mesh;
- mesh files of one topology (any format :func:`stbs.io.read_mesh` reads), the first the
  rest mesh and the others the frames in order.

Arrays are read within :mod:`stbs.io._npz`'s budget (a small archive cannot make the
reader allocate gigabytes) and every value must be finite.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ._npz import Budget
from ._parse import input_path
from .errors import FormatError

__all__ = ["MeshSequence", "read_sequence"]


@dataclass(frozen=True)
class MeshSequence:
    """A rest mesh and its frames.

    Attributes
    ----------
    rest : (n, d) float64
    frames : (f, n, d) float64
    F : (m, 3) int64 or None
        Triangles, 0-based.
    """

    rest: np.ndarray
    frames: np.ndarray
    F: np.ndarray | None


def _finite(p, what: str, X: np.ndarray) -> np.ndarray:
    if X.dtype.kind not in "fiu":
        raise FormatError(p, f"{what}: a numeric array", f"dtype {X.dtype}")
    X = np.asarray(X, dtype=np.float64)
    bad = ~np.isfinite(X)
    if bad.any():
        at = tuple(int(i) for i in np.argwhere(bad)[0])
        raise FormatError(p, f"{what}: finite values", f"{X[at]} at index {at}")
    return X


def _read_npz(p) -> MeshSequence:
    budget = Budget(p)
    try:
        npz = np.load(p, allow_pickle=False)
    except (OSError, ValueError, EOFError) as exc:
        raise FormatError(p, "an .npz archive", " ".join(str(exc).split())[:160]) from None
    with npz:
        keys = set(npz.files)
        if "frames" not in keys:
            raise FormatError(p, "a member 'frames' of shape (frames, vertices, dim)",
                              f"members {sorted(keys)}")
        frames = _finite(p, "'frames'", budget.npz_member(npz, "frames"))
        if frames.ndim != 3 or frames.shape[2] not in (2, 3) or 0 in frames.shape[:2]:
            raise FormatError(p, "'frames' of shape (frames, vertices, 2 or 3)",
                              f"shape {frames.shape}")
        rest = frames[0]
        if "rest" in keys:
            rest = _finite(p, "'rest'", budget.npz_member(npz, "rest"))
            if rest.shape != frames.shape[1:]:
                raise FormatError(p, f"'rest' of shape {frames.shape[1:]} (as each frame)",
                                  f"shape {rest.shape}")
        F = None
        if "F" in keys:
            F = budget.npz_member(npz, "F")
            n = frames.shape[1]
            if (F.dtype.kind not in "iu" or F.ndim != 2 or F.shape[1] != 3
                    or (F.size and (F.min() < 0 or F.max() >= n))):
                raise FormatError(p, f"'F' of shape (m, 3), integers in 0..{n - 1}",
                                  f"shape {F.shape}, dtype {F.dtype}")
            F = F.astype(np.int64)
    return MeshSequence(rest=rest, frames=frames, F=F)


def _read_meshes(paths: Sequence) -> MeshSequence:
    from .mesh import read_mesh

    meshes = [read_mesh(p) for p in paths]
    rest = meshes[0]
    for p, m in zip(paths[1:], meshes[1:], strict=True):
        if m.V.shape != rest.V.shape:
            raise FormatError(p, f"a frame of {paths[0]}'s {rest.V.shape[0]} vertices in "
                              f"{rest.V.shape[1]}D", f"{m.V.shape[0]} vertices in "
                              f"{m.V.shape[1]}D")
        if rest.F is not None and (m.F is None or not np.array_equal(m.F, rest.F)):
            raise FormatError(p, f"the faces of {paths[0]} (one topology)",
                              "different faces")
    return MeshSequence(rest=rest.V, frames=np.stack([m.V for m in meshes[1:]]), F=rest.F)


def read_sequence(paths: str | os.PathLike | Sequence[str | os.PathLike]) -> MeshSequence:
    """Read a mesh animation: one ``.npz``, or a rest mesh followed by its frames.

    Parameters
    ----------
    paths : path or list of paths
        One ``.npz`` (``frames``, optional ``rest`` and ``F``), or two or more mesh files
        of one topology: the rest mesh, then the frames.

    Returns
    -------
    MeshSequence

    Examples
    --------
    >>> import os, tempfile, numpy as np
    >>> from stbs.io import read_sequence
    >>> path = os.path.join(tempfile.mkdtemp(), "anim.npz")
    >>> np.savez(path, frames=np.zeros((4, 10, 3)), F=np.array([[0, 1, 2]]))
    >>> seq = read_sequence(path)
    >>> seq.frames.shape, seq.rest.shape, seq.F.tolist()
    ((4, 10, 3), (10, 3), [[0, 1, 2]])
    """
    if isinstance(paths, (str, os.PathLike)):
        paths = [paths]
    paths = list(paths)
    if not paths:
        raise ValueError("read_sequence needs an .npz or at least two mesh files, got none")
    if len(paths) == 1:
        p = input_path(paths[0], "mesh animation")
        if p.suffix.lower() != ".npz":
            raise ValueError(f"{p}: expected one .npz mesh animation or two or more mesh "
                             f"files (the rest mesh, then its frames), got one {p.suffix} "
                             "file")
        return _read_npz(p)
    return _read_meshes([input_path(p, "mesh") for p in paths])
