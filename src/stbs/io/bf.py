"""Bone forest ``.bf`` files (libigl ``readBF``, FAST ``read_BF``).

Each non-empty line describes one *node* (a joint, i.e. a bone tip)::

    wi parent x y z                                    5 columns (libigl)
    wi parent x y z  qw qx qy qz  tx ty tz  stretch twist  T(3x4 row-major)  dof_type
                                                       27 columns (FAST)

- ``wi``: weight column of the bone ending at this node; any negative value
  (files use -1 and -3) means "no weights".
- ``parent``: 0-based index of the parent node (its line), -1 for a root.
- ``x y z``: offset of this node from its parent node (from the origin for a root).
- FAST columns 6-27 describe a pose (rotation quaternion **w x y z**, translation,
  stretch, twist, the last 3x4 transform, the tip's degree-of-freedom type); they
  are returned as raw numbers in :attr:`BoneForest.extra`.

Mapping to ``C``/``BE``: every node becomes a joint (row ``i`` of
``C`` is the node on the ``i``-th data line); every node with a parent gives a
bone from the parent's joint to its own joint. A root is not a bone. A *weighted*
root (``wi >= 0``, ``parent = -1``) is a **point handle** in FAST/BBW (a weight
column attached to a single point, e.g. the two handles of ``cactus_3d``);
STBS needs a bone direction, so point handles are not bones: they are listed in
:attr:`BoneForest.handles` / :attr:`BoneForest.handle_weight_index` and left out
of ``BE``.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from ..skeleton import Skeleton
from ._parse import Dim, apply_dim, check_dim, input_path, quote, read_lines
from .errors import FormatError

__all__ = ["BoneForest", "read_bf"]

_NCOLS = (5, 27)


@dataclass(eq=False)
class BoneForest:
    """A bone forest as read by :func:`read_bf`.

    Attributes
    ----------
    C : (j, d) float64
        Absolute joint positions, one per node, in file order.
    BE : (b, 2) int64
        Bones ``(parent node, node)``, one per non-root node, in file order.
    weight_index : (b,) int64
        Weight column of each bone, -1 for a bone without weights.
    node_parent : (j,) int64
        Parent node of each node, -1 for roots (the file's second column).
    node_weight_index : (j,) int64
        Weight column of each node, -1 for none (negative values normalised to -1).
    handles : (h,) int64
        Point handles: nodes that are weighted roots (joint indices into ``C``).
    handle_weight_index : (h,) int64
        Their weight columns.
    extra : (j, 22) float64 or None
        FAST columns 6-27 (``qw qx qy qz tx ty tz stretch twist T00..T23 dof_type``)
        of 27-column files, None for 5-column files.
    """

    C: np.ndarray
    BE: np.ndarray
    weight_index: np.ndarray
    node_parent: np.ndarray
    node_weight_index: np.ndarray
    handles: np.ndarray
    handle_weight_index: np.ndarray
    extra: np.ndarray | None = None

    @property
    def bone_order(self) -> np.ndarray:
        """(b,) int64: bones sorted by weight column (unweighted bones last, in file order)."""
        key = np.where(self.weight_index >= 0, self.weight_index, np.iinfo(np.int64).max)
        return np.argsort(key, kind="stable")

    def skeleton(self) -> Skeleton:
        """The bones as a :class:`stbs.Skeleton`, ordered by :attr:`bone_order`.

        When the weighted bones use weight columns ``0..b-1`` (every staged file
        without point handles), bone ``i`` of the result goes with weight column
        ``i``, whatever the line order in the file (FAST ``male`` lists them out
        of order). Point handles are not included.
        """
        return Skeleton(self.C, self.BE[self.bone_order])


def _int(p, tok: str, what: str, ln: int) -> int:
    try:
        v = float(tok)
    except ValueError:
        v = float("nan")
    if not np.isfinite(v) or v != int(v):
        raise FormatError(p, f"an integer {what}", quote(tok), line=ln)
    return int(v)


def read_bf(path: str | os.PathLike, *, dim: Dim = "auto") -> BoneForest:
    """Read a bone forest file.

    Parameters
    ----------
    path : str or os.PathLike
        A ``.bf`` file with 5 (libigl) or 27 (FAST) columns per line.
    dim : {"auto", 2, 3}, keyword-only
        ``"auto"`` (default) returns 2-D joints when z == 0 for every node,
        ``2`` requires that, ``3`` always returns 3 columns. Pass ``dim=3`` for a
        3-D rig: ``robot-arm.bf`` lies in the z = 0 plane but rigs a 3-D mesh.

    Returns
    -------
    BoneForest
        Joints, bones, weight columns, point handles and the raw FAST columns;
        ``.skeleton()`` gives a :class:`stbs.Skeleton` whose bone order follows
        the weight columns.

    Raises
    ------
    FileNotFoundError
        ``path`` does not exist.
    FormatError
        An empty file, a line with other than 5 or 27 columns (or a mix of
        both), a non-number, a parent index outside ``-1..j-1``, a node that is
        its own ancestor, or a weight column used twice; the message names the line.
    """
    dim = check_dim(dim)
    p = input_path(path, "skeleton")
    rows, nums = _node_lines(p)
    ncols = len(rows[0])
    pairs = list(zip(rows, nums, strict=True))
    wi = np.array([_int(p, t[0], "weight index", ln) for t, ln in pairs], dtype=np.int64)
    wi = np.where(wi < 0, -1, wi)
    par = np.array([_int(p, t[1], "parent index", ln) for t, ln in pairs], dtype=np.int64)
    vals = _node_values(p, rows, nums)
    _check_nodes(p, par, wi, nums)
    C = _positions(p, par, vals[:, :3], nums)
    child = np.flatnonzero(par >= 0)
    BE = np.stack([par[child], child], axis=1).astype(np.int64).reshape(-1, 2)
    handles = np.flatnonzero((par < 0) & (wi >= 0)).astype(np.int64)
    return BoneForest(
        C=apply_dim(C, dim, p, "joints"),
        BE=BE,
        weight_index=wi[child],
        node_parent=par,
        node_weight_index=wi,
        handles=handles,
        handle_weight_index=wi[handles],
        extra=vals[:, 3:].copy() if ncols == 27 else None,
    )


def _node_lines(p) -> tuple[list[list[str]], list[int]]:
    """The file's non-blank lines as tokens, and their line numbers; all of 5 or all of
    27 columns."""
    rows: list[list[str]] = []
    nums: list[int] = []
    for ln, s in enumerate(read_lines(p), 1):
        t = s.split()
        if t:
            rows.append(t)
            nums.append(ln)
    if not rows:
        raise FormatError(p, "node lines 'wi parent x y z'", "an empty file")
    ncols = len(rows[0])
    for t, ln in zip(rows, nums, strict=True):
        if len(t) not in _NCOLS or len(t) != ncols:
            want = ("5 columns 'wi parent x y z' or 27 (FAST)" if len(t) not in _NCOLS
                    else f"{ncols} columns like line {nums[0]}")
            raise FormatError(p, want, f"{len(t)} columns", line=ln)
    return rows, nums


def _node_values(p, rows: list[list[str]], nums: list[int]) -> np.ndarray:
    """Columns 3 on of every node line as finite floats (j, ncols - 2)."""
    vals = np.empty((len(rows), len(rows[0]) - 2))
    for k, (t, ln) in enumerate(zip(rows, nums, strict=True)):
        for c, tok in enumerate(t[2:]):
            try:
                vals[k, c] = float(tok)
            except ValueError:
                raise FormatError(p, f"a number in column {c + 3}", quote(tok), line=ln) from None
    if not np.all(np.isfinite(vals)):
        k = int(np.argwhere(~np.isfinite(vals))[0, 0])
        raise FormatError(p, "finite numbers", quote(" ".join(rows[k])), line=nums[k])
    return vals


def _check_nodes(p, par: np.ndarray, wi: np.ndarray, nums: list[int]) -> None:
    """Parents in -1..j-1 and not the node itself; each weight index used once."""
    j = len(par)
    bad = np.flatnonzero((par < -1) | (par >= j) | (par == np.arange(j)))
    if bad.size:
        k = int(bad[0])
        raise FormatError(p, f"a parent node index in -1..{j - 1} other than the node "
                          f"itself ({k})", str(int(par[k])), line=nums[k])
    seen: dict[int, int] = {}
    for k, w in enumerate(wi.tolist()):
        if w >= 0:
            if w in seen:
                raise FormatError(p, "each weight index used once",
                                  f"weight index {w} again (first on line {nums[seen[w]]})",
                                  line=nums[k])
            seen[w] = k


def _positions(p, par: np.ndarray, O: np.ndarray, nums: list[int]) -> np.ndarray:
    """Absolute node positions (j, 3): a node's offset ``O`` added to its parent's
    position; chains are resolved iteratively so any line order (and deep trees) work."""
    j = len(par)
    C = np.full((j, 3), np.nan)
    done = np.zeros(j, dtype=bool)
    for k in range(j):
        chain = []
        m = k
        while m >= 0 and not done[m]:
            chain.append(m)
            if len(chain) > j:
                raise FormatError(p, "a forest (no node its own ancestor)",
                                  f"a cycle through node {k}", line=nums[k])
            m = int(par[m])
        base = np.zeros(3) if m < 0 else C[m]
        for c in reversed(chain):
            base = base + O[c]
            C[c] = base
            done[c] = True
    return C
