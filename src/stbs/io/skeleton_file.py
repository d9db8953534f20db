"""Read a skeleton file of any supported kind into a :class:`stbs.Skeleton`."""

from __future__ import annotations

import os
import warnings

from ..skeleton import Skeleton
from ._parse import Dim, check_dim, input_path, suffix
from .bf import read_bf
from .errors import FormatError
from .tgf import read_tgf

__all__ = ["read_skeleton", "SKELETON_READ_EXTENSIONS"]

#: Extensions :func:`read_skeleton` understands.
SKELETON_READ_EXTENSIONS = (".tgf", ".bf")


def read_skeleton(path: str | os.PathLike, *, dim: Dim = "auto") -> Skeleton:
    """Read a ``.tgf`` or ``.bf`` file as a validated :class:`stbs.Skeleton` (names None).

    Parameters
    ----------
    path : str or os.PathLike
        Skeleton file.
    dim : {"auto", 2, 3}, keyword-only
        As in :func:`read_tgf`: ``"auto"`` gives a 2-D skeleton when every
        joint has z == 0. When pairing with a mesh pass ``dim=V.shape[1]``.

    Returns
    -------
    Skeleton
        For ``.tgf``: the bones of :func:`read_tgf` in file order (weight column
        ``i`` = ``i``-th bone edge line). For ``.bf``: the bones of
        :func:`read_bf` sorted by weight column (:meth:`BoneForest.skeleton`);
        point handles (weighted roots) are not bones and are left out, with a
        ``UserWarning`` that counts them.

    Raises
    ------
    FileNotFoundError, FormatError
        As the readers; also a FormatError when the file's bones do not form a
        valid skeleton (no bones at all, zero-length bones, cycles, ...), with
        :class:`stbs.Skeleton`'s reason in the message.
    ValueError
        Unknown extension (the message lists the supported ones).
    """
    dim = check_dim(dim)
    ext = suffix(path, SKELETON_READ_EXTENSIONS, "read_skeleton")
    p = input_path(path, "skeleton")
    if ext == ".tgf":
        C, BE = read_tgf(p, dim=dim)
    else:
        bf = read_bf(p, dim=dim)
        if bf.BE.shape[0] == 0 and bf.handles.size:
            raise FormatError(p, "at least one bone (a node with a parent)",
                              f"only {bf.handles.size} point handles (weighted roots); "
                              "use read_bf for point handles")
        C, BE = bf.C, bf.BE[bf.bone_order]
        if bf.handles.size:
            warnings.warn(f"read_skeleton: {p}: {bf.handles.size} point handle(s) (weighted "
                          "roots) left out: STBS rigs have bones only, so weights computed "
                          "for this skeleton have no column for them (read_bf lists them)",
                          UserWarning, stacklevel=2)
    try:
        return Skeleton(C, BE)
    except ValueError as exc:
        raise FormatError(p, "bones that form a valid skeleton", str(exc)) from None
