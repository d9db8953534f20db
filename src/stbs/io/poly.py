"""Triangle's ``.poly`` files (planar straight-line graphs) read as closed polygons."""

from __future__ import annotations

import os

import numpy as np

from ._parse import input_path, read_lines, suffix
from .errors import FormatError

__all__ = ["read_polygons"]


def read_polygons(path: str | os.PathLike) -> list[np.ndarray]:
    """Read the closed polygons of a Triangle ``.poly`` file (a planar straight-line graph).

    Parameters
    ----------
    path : str or os.PathLike
        A ``.poly`` file with its vertices inline (Shewchuk's format: a vertex
        section ``<#v> 2 <#attr> <#markers>`` then ``<id> x y ...``, a segment section
        ``<#s> <#markers>`` then ``<id> <v1> <v2> ...``, then holes, which are ignored:
        the even-odd rule decides what is inside). Vertex ids may start at 0 or 1.

    Returns
    -------
    list of (k, 2) float64
        The polygons the segments form (every vertex used by a segment must have
        exactly two).

    Raises
    ------
    FormatError
        Malformed file, vertices in a separate ``.node`` file, or segments that
        do not form closed loops.
    """
    suffix(path, (".poly",), "read_polygons")
    p = input_path(path, "polygon")
    rows = _Rows(p)
    X, base = _vertices(rows)
    S = _segments(rows, len(X), base)
    return _loops(p, X, S, base)


class _Rows:
    """The file's non-empty lines (comments dropped), read as numbers on demand."""

    def __init__(self, p):
        self.p = p
        self.rows = []
        for no, line in enumerate(read_lines(p), start=1):
            s = line.split("#", 1)[0].split()
            if s:
                self.rows.append((no, s))

    def numbers(self, k: int, what: str, kind=float):
        """Line k's numbers (of ``kind``) and its line number; ``what`` names what was due."""
        if k >= len(self.rows):
            raise FormatError(self.p, what, "the end of the file")
        no, s = self.rows[k]
        try:
            return [kind(x) for x in s], no
        except ValueError:
            raise FormatError(self.p, what, repr(" ".join(s)), line=no) from None


def _vertices(rows: _Rows) -> tuple[np.ndarray, int]:
    """The vertex section: positions (nv, 2) in id order and the first id (0 or 1)."""
    p = rows.p
    head, no = rows.numbers(0, "a vertex header '<#vertices> 2 <#attributes> <#markers>'",
                            int)
    if len(head) < 2 or head[1] != 2:
        raise FormatError(p, "dimension 2 in the vertex header", repr(head), line=no)
    nv = head[0]
    if nv == 0:
        raise FormatError(p, "vertices listed in the .poly file", "0 (a separate .node file, "
                          "which is not supported)", line=no)
    ids, X = [], []
    for k in range(1, nv + 1):
        v, no = rows.numbers(k, f"vertex line {k} of {nv}: '<id> x y ...'")
        if len(v) < 3:
            raise FormatError(p, "'<id> x y ...'", repr(rows.rows[k][1]), line=no)
        ids.append(int(v[0]))
        X.append(v[1:3])
    base = min(ids)
    if sorted(ids) != list(range(base, base + nv)) or base not in (0, 1):
        raise FormatError(p, "vertex ids numbered consecutively from 0 or 1",
                          f"ids {min(ids)}..{max(ids)}")
    return np.asarray(X)[np.argsort(ids)], base


def _segments(rows: _Rows, nv: int, base: int) -> np.ndarray:
    """The segment section as 0-based vertex pairs (s, 2)."""
    p = rows.p
    sh, no = rows.numbers(nv + 1, "a segment header '<#segments> <#markers>'", int)
    segs = []
    for k in range(nv + 2, nv + 2 + sh[0]):
        s, no = rows.numbers(k, "'<id> <v1> <v2> ...'", int)
        if len(s) < 3 or not all(base <= x < base + nv for x in s[1:3]):
            raise FormatError(p, f"'<id> <v1> <v2>' with vertex ids in {base}..{base + nv - 1}",
                              repr(" ".join(rows.rows[k][1])), line=no)
        segs.append(s[1:3])
    if not segs:
        raise FormatError(p, "segments forming closed polygons", "no segments")
    return np.asarray(segs, dtype=np.int64) - base


def _loops(p, X: np.ndarray, S: np.ndarray, base: int) -> list[np.ndarray]:
    """The closed polygons the segments form: two segments at every vertex used."""
    nv = len(X)
    deg = np.bincount(S.ravel(), minlength=nv)
    bad = np.flatnonzero((deg != 0) & (deg != 2))
    if bad.size:
        raise FormatError(p, "segments forming closed polygons (two segments at every vertex)",
                          f"vertex {int(bad[0]) + base} with {int(deg[bad[0]])} segments")
    adj = [[] for _ in range(nv)]
    for a, b in S.tolist():
        adj[a].append(b)
        adj[b].append(a)
    seen = np.zeros(nv, dtype=bool)
    polys = []
    for start in np.flatnonzero(deg == 2).tolist():
        if seen[start]:
            continue
        loop, prev, v = [start], -1, start
        seen[start] = True
        while True:
            a, b = adj[v]
            nxt = b if a == prev else a
            if nxt == start:
                break
            loop.append(nxt)
            seen[nxt] = True
            prev, v = v, nxt
        polys.append(X[loop])
    return polys
