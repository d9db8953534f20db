"""Own readers for the mesh formats where meshio is unreliable.

- OBJ: meshio 5.3 refuses files with polygons and texture coordinates
  (``cylinder.obj``: "len(points) = 220, but len(point_data["obj:vt"]) = 271").
- OFF: meshio reads triangles only and calls ``sys.exit`` on quads (``cube.off``).
- Medit ``.mesh``: meshio reads ``MeshVersionFormatted 1`` coordinates as float32
  and fails on an empty ``Edges`` block (``hand.mesh``).
- Gmsh 2.2 ``.msh``: meshio fails on the binary ``hand.msh`` (cell data lengths).

Every reader returns ``(V, polys, T)``: V (n, k) float64 with k = 2 or 3, polys a
list of (m, a) int64 blocks of 0-based polygons (a >= 3, triangulated later),
and T (t, 4) int64 or None. Indices are checked against ``n`` here, so errors
can name the line.
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

from ._parse import parse_block, quote, read_lines
from .errors import FormatError

Polys = list[np.ndarray]


def _check_range(p: Path, idx: np.ndarray, n: int, what: str, lines_at, base: int) -> None:
    """Raise if any (0-based) index is outside 0..n-1, naming the line of the first one."""
    bad = np.flatnonzero(((idx < 0) | (idx >= n)).any(axis=1)) if idx.size else []
    if len(bad):
        k = int(bad[0])
        ln = lines_at + k if isinstance(lines_at, int) else int(lines_at[k])
        row = (idx[k] + base).tolist()
        raise FormatError(p, f"{what} with vertex indices in {base}..{n - 1 + base}",
                          f"{row}", line=ln)


# ----------------------------------------------------------------------------- OBJ

def _obj_records(lines: list[str]) -> tuple[list[str], list[int], list[tuple[int, list[str], int]]]:
    """The vertex lines' text after ``v`` and their line numbers, and each face line's
    (line number, corners, count of vertices before it)."""
    vrec: list[str] = []
    vnum: list[int] = []
    frec: list[tuple[int, list[str], int]] = []
    for ln, s in enumerate(lines, 1):
        if not s:
            continue
        if s[0] in " \t":
            s = s.lstrip()
            if not s:
                continue
        c = s[0]
        if c == "v" and s[1:2] in (" ", "\t"):
            vrec.append(s[2:])
            vnum.append(ln)
        elif c == "f" and s[1:2] in (" ", "\t"):
            frec.append((ln, s[2:].split(), len(vrec)))
    return vrec, vnum, frec


def _obj_corner(p: Path, t: str, nv: int, n: int, ln: int) -> int:
    """The 0-based vertex of face corner ``t`` on line ``ln`` (``nv`` vertices before
    it, ``n`` in all)."""
    head = t.split("/", 1)[0]
    try:
        i = int(head)
    except ValueError:
        raise FormatError(p, "a face corner 'v', 'v/vt', 'v//vn' or 'v/vt/vn' "
                          "with an integer v", quote(t), line=ln) from None
    if i > 0:
        i -= 1
    elif i < 0:
        # Relative index: -1 is the latest vertex defined before this line.
        if -i > nv:
            raise FormatError(p, f"a relative vertex index in -{nv}..-1 "
                              f"({nv} vertices precede this face)", quote(t), line=ln)
        i += nv
    else:
        raise FormatError(p, "a vertex index != 0 (OBJ is 1-based)", quote(t), line=ln)
    if i >= n:
        raise FormatError(p, f"a vertex index in 1..{n}", quote(t), line=ln)
    return i


def read_obj(p: Path) -> tuple[np.ndarray, Polys, None]:
    """Wavefront OBJ: ``v x y z [w | r g b]`` and ``f`` with ``v``, ``v/vt``, ``v//vn``,
    ``v/vt/vn`` corners, 1-based or negative (relative) indices. Other records
    (``vt``, ``vn``, ``g``, ``o``, ``s``, ``usemtl``, ``l``, ``p``, ...) are ignored."""
    vrec, vnum, frec = _obj_records(read_lines(p))
    if not vrec:
        raise FormatError(p, "at least one vertex line 'v x y z'", "none")
    V = parse_block(p, vrec, vnum, 3, "a vertex 'v x y z'")
    n = V.shape[0]
    faces: list[list[int]] = []
    for ln, toks, nv in frec:
        if len(toks) < 3:
            raise FormatError(p, "a face with at least 3 vertices", f"{len(toks)}", line=ln)
        faces.append([_obj_corner(p, t, nv, n, ln) for t in toks])
    return V, _runs(faces), None


def _runs(faces: list[list[int]]) -> Polys:
    """Group faces into blocks of equal arity, keeping the file order (runs)."""
    if not faces:
        return []
    if len({len(f) for f in faces}) == 1:
        return [np.asarray(faces, dtype=np.int64)]
    out: Polys = []
    run: list[list[int]] = []
    for face in faces:
        if run and len(run[0]) != len(face):
            out.append(np.asarray(run, dtype=np.int64))
            run = []
        run.append(face)
    out.append(np.asarray(run, dtype=np.int64))
    return out


# ----------------------------------------------------------------------------- OFF

def read_off(p: Path) -> tuple[np.ndarray, Polys, None]:
    """Object File Format: header ``OFF`` (also ``COFF``, ``NOFF``, ``STOFF``...), then
    ``nV nF nE``, vertex lines (extra colour/normal columns ignored) and face lines
    ``k i_1 ... i_k [colour]`` with 0-based indices. ``#`` starts a comment."""
    raw = read_lines(p)
    recs: list[tuple[int, str]] = []
    for ln, s in enumerate(raw, 1):
        s = s.split("#", 1)[0].strip()
        if s:
            recs.append((ln, s))
    if not recs:
        raise FormatError(p, "an 'OFF' header", "an empty file")
    ln, head = recs[0]
    toks = head.split()
    kw = toks[0]
    if not kw.endswith("OFF") or kw.startswith(("4", "n")):
        raise FormatError(p, "an 'OFF' header (OFF, COFF, NOFF, STOFF)", quote(head), line=ln)
    if len(toks) > 1 and toks[1].upper() == "BINARY":
        raise FormatError(p, "an ASCII OFF file", "'OFF BINARY' (not supported)", line=ln)
    k = 1
    counts = toks[1:]
    if not counts:
        if len(recs) < 2:
            raise FormatError(p, "a line 'nV nF nE' after the header", "end of file", line=ln)
        ln, s = recs[1]
        counts = s.split()
        k = 2
    try:
        nv, nf = int(counts[0]), int(counts[1])
        if nv < 0 or nf < 0:
            raise ValueError
    except (ValueError, IndexError):
        raise FormatError(p, "counts 'nV nF nE' (non-negative integers)",
                          quote(" ".join(counts)), line=ln) from None
    if len(recs) < k + nv + nf:
        have = len(recs) - k
        raise FormatError(p, f"{nv} vertex lines and {nf} face lines",
                          f"only {have} data lines before the end of file", line=recs[-1][0])
    vrec = recs[k:k + nv]
    V = parse_block(p, [s for _, s in vrec], [n for n, _ in vrec], 3, "a vertex 'x y z'")
    faces: list[list[int]] = []
    for ln, s in recs[k + nv:k + nv + nf]:
        t = s.split()
        try:
            a = int(t[0])
            face = [int(x) for x in t[1:1 + a]]
        except ValueError:
            raise FormatError(p, "a face 'k i_1 ... i_k' of integers", quote(s), line=ln) from None
        if a < 3 or len(face) != a:
            raise FormatError(p, "a face 'k i_1 ... i_k' with k >= 3 indices", quote(s), line=ln)
        bad = [i for i in face if not 0 <= i < nv]
        if bad:
            raise FormatError(p, f"vertex indices in 0..{nv - 1}", f"{bad[0]} in {quote(s)}",
                              line=ln)
        faces.append(face)
    return V, _runs(faces), None


# ----------------------------------------------------------------------------- Medit

_MEDIT_ELEMENTS = {"triangles": 3, "quadrilaterals": 4, "tetrahedra": 4}
_MEDIT_SINGULAR = {"triangles": "triangle", "quadrilaterals": "quadrilateral",
                   "tetrahedra": "tetrahedron"}
_MEDIT_UNSUPPORTED = ("hexahedra", "prisms", "pyramids")


def _medit_count(p: Path, lines: list[str], i: int, kw: str, rest: list[str]
                 ) -> tuple[int, int, int]:
    """The non-negative integer after keyword ``kw`` on line ``i`` (same line or the
    next non-empty one): (value, its line, the line after it)."""
    if rest:
        val, at, nxt = rest[0], i, i + 1
    else:
        j = i + 1
        while j < len(lines) and not lines[j].split():
            j += 1
        if j == len(lines):
            raise FormatError(p, f"a value after '{kw}'", "end of file", line=i + 1)
        val, at, nxt = lines[j].split()[0], j, j + 1
    try:
        num = int(val)
        if num < 0:
            raise ValueError
    except ValueError:
        raise FormatError(p, f"a non-negative integer after '{kw}'", quote(val),
                          line=at + 1) from None
    return num, at, nxt


def _medit_cells(p: Path, blocks: dict[str, list[tuple[np.ndarray, int]]], n: int
                 ) -> tuple[Polys, np.ndarray | None]:
    """The polygons and tetrahedra of the element blocks, checked against ``n``
    vertices."""
    polys: Polys = []
    T = None
    for key in ("triangles", "quadrilaterals", "tetrahedra"):
        for E, at in blocks.get(key, []):
            _check_range(p, E, n, _MEDIT_SINGULAR[key], at, base=1)
            if key == "tetrahedra":
                T = E if T is None else np.vstack([T, E])
            else:
                polys.append(E)
    return polys, T


def read_medit(p: Path) -> tuple[np.ndarray, Polys, np.ndarray | None]:
    """Medit ``.mesh`` (ASCII): ``Dimension``, ``Vertices`` (coordinates + reference),
    ``Triangles``, ``Quadrilaterals``, ``Tetrahedra`` (1-based + reference). Other
    blocks (``Edges``, ``Corners``, ``Normals``, ...) are skipped by their count."""
    lines = read_lines(p)
    i, n_lines = 0, len(lines)
    dim = 3
    V = None
    blocks: dict[str, list[tuple[np.ndarray, int]]] = {}
    while i < n_lines:
        toks = lines[i].split()
        if not toks or toks[0].startswith("#"):
            i += 1
            continue
        kw, key = toks[0], toks[0].lower()
        if key == "end":
            break
        num, at, nxt = _medit_count(p, lines, i, kw, toks[1:])
        if key == "meshversionformatted":
            i = nxt
            continue
        if key == "dimension":
            if num not in (2, 3):
                raise FormatError(p, "Dimension 2 or 3", str(num), line=at + 1)
            dim = num
            i = nxt
            continue
        if key in _MEDIT_UNSUPPORTED and num > 0:
            raise FormatError(p, "only Triangles, Quadrilaterals and Tetrahedra elements",
                              f"a {kw} block with {num} elements", line=i + 1)
        first, stop = nxt, nxt + num
        if stop > n_lines:
            raise FormatError(p, f"{num} lines in the {kw} block",
                              f"end of file after {n_lines - first}", line=n_lines)
        body = lines[first:stop]
        if key == "vertices":
            V = parse_block(p, body, first + 1, dim, "a vertex (coordinates, reference)")
        elif key in _MEDIT_ELEMENTS:
            k = _MEDIT_ELEMENTS[key]
            E = parse_block(p, body, first + 1, k, f"an element of {kw}", dtype=np.int64) - 1
            blocks.setdefault(key, []).append((E, first + 1))
        i = stop
    if V is None:
        raise FormatError(p, "a Vertices block", "none")
    polys, T = _medit_cells(p, blocks, V.shape[0])
    return V, polys, T


# ----------------------------------------------------------------------------- Gmsh 2.2

#: Nodes per element for the Gmsh element types we may meet (for skipping).
_GMSH_NODES = {1: 2, 2: 3, 3: 4, 4: 4, 5: 8, 6: 6, 7: 5, 8: 3, 9: 6, 10: 9, 11: 10,
               12: 27, 13: 18, 14: 14, 15: 1, 16: 8, 17: 20, 18: 15, 19: 13}
_GMSH_TRI, _GMSH_QUAD, _GMSH_TET = 2, 3, 4
_GMSH_POINT_LINE = (1, 8, 15)


def msh_version(p: Path) -> str | None:
    """The version string of a Gmsh file (``"2.2"``, ``"4.1"``), None if there is no header."""
    with open(p, "rb") as f:
        head = f.read(256)
    if not head.startswith(b"$MeshFormat"):
        return None
    parts = head.split(b"\n", 2)
    if len(parts) < 2 or not parts[1].split():
        return None
    return parts[1].split()[0].decode("latin-1")


def read_msh2(p: Path) -> tuple[np.ndarray, Polys, np.ndarray | None]:
    """Gmsh MSH 2.x, ASCII or binary: ``$Nodes`` and ``$Elements`` (triangles,
    quadrangles, tetrahedra; points and lines ignored, other volume types rejected)."""
    data = p.read_bytes()
    nl1 = data.index(b"\n")
    nl2 = data.index(b"\n", nl1 + 1)
    fmt = data[nl1 + 1:nl2].split()
    try:
        binary, dsize = int(fmt[1]) == 1, int(fmt[2])
    except (IndexError, ValueError):
        raise FormatError(p, "'version file-type data-size' on line 2",
                          quote(data[nl1 + 1:nl2].decode("latin-1")), line=2) from None
    if binary:
        return _read_msh2_binary(p, data, nl2 + 1, dsize)
    return _read_msh2_ascii(p)


def _elements_to_mesh(p: Path, kinds: dict[int, list[np.ndarray]], node_ids: np.ndarray,
                      where: str) -> tuple[Polys, np.ndarray | None]:
    order = np.argsort(node_ids, kind="stable")
    sorted_ids = node_ids[order]

    def to_index(E: np.ndarray) -> np.ndarray:
        pos = np.searchsorted(sorted_ids, E)
        pos_c = np.minimum(pos, len(sorted_ids) - 1)
        bad = sorted_ids[pos_c] != E
        if np.any(bad):
            raise FormatError(p, f"element nodes that appear in $Nodes ({where})",
                              f"node id {int(E[bad][0])}")
        return order[pos_c]

    polys: Polys = []
    T = None
    for t, arrs in kinds.items():
        if not arrs:
            continue
        E = to_index(np.vstack(arrs))
        if t in (_GMSH_TRI, _GMSH_QUAD):
            polys.append(E)
        elif t == _GMSH_TET:
            T = E
    return polys, T


def _accept_type(p: Path, t: int, where: str) -> bool:
    if t in (_GMSH_TRI, _GMSH_QUAD, _GMSH_TET):
        return True
    if t in _GMSH_POINT_LINE:
        return False
    raise FormatError(p, "elements of type 1, 2, 3, 4, 8 or 15 (points, lines, triangles, "
                      "quadrangles, tetrahedra)", f"element type {t} ({where})")


def _read_msh2_ascii(p: Path) -> tuple[np.ndarray, Polys, np.ndarray | None]:
    lines = read_lines(p)
    idx = {s.strip(): k for k, s in enumerate(lines) if s.startswith("$")}
    for sec in ("$Nodes", "$Elements"):
        if sec not in idx:
            raise FormatError(p, f"a {sec} section", "none")
    k = idx["$Nodes"] + 1
    try:
        n = int(lines[k])
    except (ValueError, IndexError):
        raise FormatError(p, "the node count", quote(lines[k] if k < len(lines) else ""),
                          line=k + 1) from None
    if k + 1 + n > len(lines):
        raise FormatError(p, f"{n} node lines", "end of file", line=len(lines))
    nodes = parse_block(p, lines[k + 1:k + 1 + n], k + 2, 4, "a node 'id x y z'", exact=True)
    ids = nodes[:, 0].astype(np.int64)
    V = nodes[:, 1:]
    k = idx["$Elements"] + 1
    try:
        m = int(lines[k])
    except (ValueError, IndexError):
        raise FormatError(p, "the element count", quote(lines[k] if k < len(lines) else ""),
                          line=k + 1) from None
    kinds: dict[int, list[np.ndarray]] = {_GMSH_TRI: [], _GMSH_QUAD: [], _GMSH_TET: []}
    for j in range(k + 1, k + 1 + m):
        if j >= len(lines):
            raise FormatError(p, f"{m} element lines", "end of file", line=len(lines))
        try:
            t = [int(x) for x in lines[j].split()]
            etype, ntags = t[1], t[2]
        except (ValueError, IndexError):
            raise FormatError(p, "an element 'id type ntags tags... nodes...' of integers",
                              quote(lines[j]), line=j + 1) from None
        if not _accept_type(p, etype, f"line {j + 1}"):
            continue
        nodes_e = t[3 + ntags:]
        if len(nodes_e) != _GMSH_NODES[etype]:
            raise FormatError(p, f"{_GMSH_NODES[etype]} nodes for element type {etype}",
                              f"{len(nodes_e)}", line=j + 1)
        kinds[etype].append(np.asarray([nodes_e], dtype=np.int64))
    polys, T = _elements_to_mesh(p, kinds, ids, "ASCII")
    return V, polys, T


def _read_msh2_binary(p: Path, data: bytes, pos: int, dsize: int):
    if dsize != 8:
        raise FormatError(p, "data-size 8 (float64)", str(dsize), line=2)
    one = struct.unpack_from("<i", data, pos)[0]
    if one != 1:
        raise FormatError(p, "a little-endian binary Gmsh file", "another byte order")
    sec = data.find(b"$Nodes\n", pos)
    if sec < 0:
        raise FormatError(p, "a $Nodes section", "none")
    pos = sec + len(b"$Nodes\n")
    end = data.index(b"\n", pos)
    n = int(data[pos:end])
    pos = end + 1
    rec = np.dtype([("id", "<i4"), ("x", "<f8", (3,))])
    if pos + n * rec.itemsize > len(data):
        raise FormatError(p, f"{n} binary nodes ({n * rec.itemsize} bytes)",
                          f"{len(data) - pos} bytes (truncated file)")
    nodes = np.frombuffer(data, dtype=rec, count=n, offset=pos)
    ids = nodes["id"].astype(np.int64)
    V = nodes["x"].astype(np.float64)
    pos += n * rec.itemsize
    sec = data.find(b"$Elements\n", pos)
    if sec < 0:
        raise FormatError(p, "an $Elements section after $Nodes", "none")
    pos = sec + len(b"$Elements\n")
    end = data.index(b"\n", pos)
    m = int(data[pos:end])
    pos = end + 1
    kinds: dict[int, list[np.ndarray]] = {_GMSH_TRI: [], _GMSH_QUAD: [], _GMSH_TET: []}
    done = 0
    while done < m:
        if pos + 12 > len(data):
            raise FormatError(p, f"{m} binary elements", f"{done} before the end of file")
        etype, count, ntags = struct.unpack_from("<3i", data, pos)
        pos += 12
        if etype not in _GMSH_NODES or count <= 0 or ntags < 0:
            raise FormatError(p, "an element block header 'type count ntags'",
                              f"({etype}, {count}, {ntags}) at byte {pos - 12}")
        width = 1 + ntags + _GMSH_NODES[etype]
        size = 4 * width * count
        if pos + size > len(data):
            raise FormatError(p, f"{count} elements of type {etype}", "a truncated file")
        if _accept_type(p, etype, f"byte {pos - 12}"):
            blk = np.frombuffer(data, dtype="<i4", count=width * count, offset=pos)
            kinds[etype].append(blk.reshape(count, width)[:, 1 + ntags:].astype(np.int64))
        pos += size
        done += count
    polys, T = _elements_to_mesh(p, kinds, ids, "binary")
    return V, polys, T
