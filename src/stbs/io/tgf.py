"""libigl's TGF skeleton files: joints ``C`` and bones ``BE``.

Format (libigl ``readTGF``)::

    1 x y z [ignored columns...]     joint lines, one per joint, in order
    2 x y z
    #
    1 2 [is_bone is_pseudo is_cage]  edge lines, 1-based joint indices
    #                                optional; anything after it is ignored

The joint index in the first column is not used (joints are numbered by line
order, as libigl does); several real files carry garbage doubles such as
``2.79e+199`` after ``x y z``, so only columns 2-4 are read.
"""

from __future__ import annotations

import os

import numpy as np

from .. import _checks
from ._atomic import atomic_open
from ._parse import Dim, apply_dim, check_dim, input_path, parse_block, quote, read_lines, suffix
from .errors import FormatError

__all__ = ["read_tgf", "write_tgf"]


def read_tgf(path: str | os.PathLike, *, dim: Dim = "auto") -> tuple[np.ndarray, np.ndarray]:
    """Read joints and bones from a TGF file.

    Parameters
    ----------
    path : str or os.PathLike
        A ``.tgf`` file.
    dim : {"auto", 2, 3}, keyword-only
        ``"auto"`` (default) returns 2-D joints when z == 0 for every joint,
        ``2`` requires that, ``3`` always returns 3 columns. When the skeleton
        goes with a 3-D mesh, pass ``dim=3`` (a 3-D rig may have a skeleton
        lying in the z = 0 plane).

    Returns
    -------
    C : (j, d) float64
        Joint positions.
    BE : (b, 2) int64
        Bones as 0-based joint pairs, in file order. If any edge line sets the
        ``is_bone`` flag (third column) to 1, the bones are exactly the flagged
        edges; otherwise every edge is a bone (as libigl's tutorials use
        ``readTGF(path, C, BE)``). ``b`` may be 0 for a file with joints only.

    Raises
    ------
    FileNotFoundError
        ``path`` does not exist.
    FormatError
        Empty file, no ``#`` separator, a non-number where a number belongs, an
        edge with fewer than two joints or a joint index outside ``1..j``; the
        message names the line.
    """
    dim = check_dim(dim)
    p = input_path(path, "skeleton")
    lines = read_lines(p)
    vlines: list[str] = []
    vnums: list[int] = []
    i = 0
    while i < len(lines) and not lines[i].lstrip().startswith("#"):
        if lines[i].strip():
            vlines.append(lines[i])
            vnums.append(i + 1)
        i += 1
    if not any(s.strip() for s in lines):
        raise FormatError(p, "joint lines 'index x y z', then '#', then edge lines",
                          "an empty file")
    if not vlines:
        raise FormatError(p, "joint lines 'index x y z' before the first '#'",
                          quote(lines[i]), line=i + 1)
    if i == len(lines):
        raise FormatError(p, "a '#' line after the joint lines", "end of file", line=len(lines))
    C = parse_block(p, vlines, vnums, 4, "a joint line 'index x y z'")[:, 1:]
    j = C.shape[0]
    edges: list[list[int]] = []
    is_bone: list[bool] = []
    any_flag = False
    for k in range(i + 1, len(lines)):
        s = lines[k]
        if s.lstrip().startswith("#"):
            break
        t = s.split()
        if not t:
            continue
        ln = k + 1
        if len(t) < 2:
            raise FormatError(p, "an edge line 'a b [is_bone is_pseudo is_cage]'", quote(s),
                              line=ln)
        try:
            row = [int(x) for x in t[:5]]
        except ValueError:
            raise FormatError(p, "integers in an edge line 'a b [is_bone is_pseudo is_cage]'",
                              quote(s), line=ln) from None
        for x in row[:2]:
            if not 1 <= x <= j:
                raise FormatError(p, f"a joint index in 1..{j} (TGF is 1-based)", str(x),
                                  line=ln)
        edges.append([row[0] - 1, row[1] - 1])
        flagged = len(row) > 2 and row[2] == 1
        any_flag |= flagged
        is_bone.append(flagged)
    BE = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    if any_flag:
        BE = BE[np.asarray(is_bone, dtype=bool)]
    return apply_dim(C, dim, p, "joints"), np.ascontiguousarray(BE)


def write_tgf(path: str | os.PathLike, C, BE) -> None:
    """Write joints and bones as TGF (1-based, no flags), atomically.

    Parameters
    ----------
    path : str or os.PathLike
        Destination ``.tgf`` file; its folder must exist.
    C : (j, 2) or (j, 3) float
        Joint positions; 2-D joints are written with z = 0.
    BE : (b, 2) int
        Bones as 0-based joint pairs.

    Raises
    ------
    ValueError
        Wrong extension, shapes, non-finite values or joint indices out of range.
    """
    suffix(path, (".tgf",), "write_tgf")
    C = _checks.real_array("C", C, ndim=2)
    if C.shape[1] not in (2, 3):
        raise ValueError(f"C must have shape (j, 2) or (j, 3), got {C.shape}")
    BE = _checks.index_array("BE", BE, ndim=2, shape=(None, 2))
    j = C.shape[0]
    if BE.size and (BE.min() < 0 or BE.max() >= j):
        bad = int(BE.min()) if BE.min() < 0 else int(BE.max())
        raise ValueError(f"BE must hold joint indices in 0..{j - 1}, got {bad}")
    if C.shape[1] == 2:
        C = np.hstack([C, np.zeros((j, 1))])
    with atomic_open(path, "w", newline="\n") as f:
        f.write("".join(f"{k + 1} {x!r} {y!r} {z!r}\n" for k, (x, y, z) in
                        enumerate(C.tolist())))
        f.write("#\n")
        f.write("".join(f"{a} {b}\n" for a, b in (BE + 1).tolist()))
        f.write("#\n")
