"""Read and write meshes: ``V`` (n, d), triangles ``F`` (f, 3), tetrahedra ``T`` (t, 4).

Readers: ``.obj``, ``.off``, ``.mesh`` (Medit) and Gmsh 2.x ``.msh`` by our own
parsers (meshio 5.3 fails or loses precision on real files of these kinds, see
``_mesh_formats``); ``.ply``, ``.stl``, ``.vtk`` and Gmsh 4 ``.msh`` through meshio.
Polygons (quads, the twenty-gon caps of ``cylinder.obj``) are split into
triangle fans ``(v0, v_k, v_k+1)``, which is exact for convex faces.

Writers: ``.obj`` (ASCII), ``.off`` (ASCII), ``.ply`` (binary little-endian,
float64 coordinates), all written atomically and losslessly (ASCII numbers use
the shortest text that reads back to the same float64).
"""

from __future__ import annotations

import contextlib
import io
import os
import warnings
from dataclasses import dataclass

import numpy as np

from .. import _checks
from . import _mesh_formats
from ._atomic import atomic_open
from ._parse import Dim, apply_dim, check_dim, input_path, suffix
from .errors import FormatError

__all__ = ["Mesh", "read_mesh", "write_mesh", "MESH_READ_EXTENSIONS", "MESH_WRITE_EXTENSIONS"]

#: Extensions :func:`read_mesh` understands.
MESH_READ_EXTENSIONS = (".obj", ".off", ".ply", ".stl", ".mesh", ".msh", ".vtk")
#: Extensions :func:`write_mesh` understands.
MESH_WRITE_EXTENSIONS = (".obj", ".off", ".ply")


@dataclass(eq=False)
class Mesh:
    """A mesh as read from a file.

    Attributes
    ----------
    V : (n, d) float64
        Vertex positions, d = 2 or 3.
    F : (f, 3) int64 or None
        Triangles (0-based), polygons already split into fans. For a volume mesh
        (``.mesh``, ``.msh``) these are the boundary triangles stored in the file.
        None when the file has no surface elements.
    T : (t, 4) int64 or None
        Tetrahedra (0-based), None when the file has none.
    """

    V: np.ndarray
    F: np.ndarray | None = None
    T: np.ndarray | None = None

    def __post_init__(self):
        self.V = _checks.vertices(self.V)
        n = self.V.shape[0]
        for name, k in (("F", 3), ("T", 4)):
            X = getattr(self, name)
            if X is None:
                continue
            X = _checks.index_array(name, X, ndim=2, shape=(None, k))
            if X.size and (X.min() < 0 or X.max() >= n):
                bad = int(X.min()) if X.min() < 0 else int(X.max())
                raise ValueError(f"{name} must hold vertex indices in 0..{n - 1}, got {bad}")
            setattr(self, name, X)

    @property
    def dim(self) -> int:
        """2 or 3."""
        return int(self.V.shape[1])

    def __repr__(self) -> str:
        parts = [f"V={self.V.shape}"]
        parts += [f"{k}={getattr(self, k).shape}" for k in ("F", "T")
                  if getattr(self, k) is not None]
        return f"Mesh({', '.join(parts)})"


def fan_triangulate(polys: list[np.ndarray]) -> np.ndarray | None:
    """Split (m, a) polygon blocks into (m (a - 2), 3) triangle fans, keeping order."""
    out = []
    for P in polys:
        if P.shape[0] == 0:
            continue
        a = P.shape[1]
        if a == 3:
            out.append(P)
            continue
        k = np.arange(1, a - 1)
        tri = np.stack([np.broadcast_to(P[:, :1], (P.shape[0], a - 2)), P[:, k], P[:, k + 1]],
                       axis=2)
        out.append(tri.reshape(-1, 3))
    if not out:
        return None
    return np.ascontiguousarray(np.vstack(out), dtype=np.int64)


_MESHIO_SURFACE = ("triangle", "quad", "polygon")
_MESHIO_IGNORED = ("vertex", "line")


_PLY_SIZES = {"char": 1, "uchar": 1, "int8": 1, "uint8": 1, "short": 2, "ushort": 2,
              "int16": 2, "uint16": 2, "int": 4, "uint": 4, "int32": 4, "uint32": 4,
              "float": 4, "float32": 4, "double": 8, "float64": 8}


def _check_ply_header(p) -> None:
    """A PLY's declared element counts checked against the file's size before meshio
    allocates them: each element takes at least its fixed properties' bytes (binary) or
    two characters (ASCII: a digit and a separator)."""
    size = p.stat().st_size
    with open(p, "rb") as fh:
        head = fh.read(1 << 16)
    if not head.startswith(b"ply"):
        return
    end = head.find(b"end_header")
    if end < 0:
        raise FormatError(p, "a PLY header ending in 'end_header' within 64 KiB", "none")
    binary, elements = False, []
    for line in head[:end].decode("latin-1").splitlines():
        w = line.split()
        if not w:
            continue
        if w[0] == "format":
            binary = len(w) > 1 and w[1].startswith("binary")
        elif w[0] == "element" and len(w) == 3:
            try:
                count = int(w[2])
            except ValueError:
                raise FormatError(p, "a PLY element count", repr(line[:60])) from None
            if count < 0:
                raise FormatError(p, "a PLY element count >= 0", repr(line[:60]))
            elements.append([w[1], count, 0])
        elif w[0] == "property" and elements:
            item = (_PLY_SIZES.get(w[2], 1) if w[1] == "list" and len(w) > 2
                    else _PLY_SIZES.get(w[1], 1))
            elements[-1][2] += item if binary else 2
    need = sum(count * max(each, 1 if binary else 2) for _, count, each in elements)
    if need > size:
        what = ", ".join(f"{c} {n}" for n, c, _ in elements)
        raise FormatError(p, f"a PLY file of at least {need} bytes for the elements its "
                          f"header declares ({what})", f"{size} bytes")


def _read_meshio(p) -> tuple[np.ndarray, list[np.ndarray], np.ndarray | None]:
    import meshio  # lazy: only these formats need it

    if p.suffix.lower() == ".ply":
        _check_ply_header(p)

    log = io.StringIO()
    try:
        # meshio prints to stdout and raises SystemExit on some malformed files.
        with contextlib.redirect_stdout(log), contextlib.redirect_stderr(log), \
                warnings.catch_warnings():
            # e.g. an integer overflow in meshio's STL binary/ASCII sniffing: noise.
            warnings.simplefilter("ignore", RuntimeWarning)
            m = meshio.read(os.fspath(p))
    except (Exception, SystemExit) as exc:
        printed = " ".join(log.getvalue().split())
        msg = "" if isinstance(exc, SystemExit) else " ".join(str(exc).split())
        if msg and msg in printed:
            msg = ""
        detail = "; ".join(x for x in (msg, printed) if x) or type(exc).__name__
        raise FormatError(p, f"a readable {p.suffix} mesh", f"meshio error: {detail}") from None
    V = np.asarray(m.points, dtype=np.float64)
    if V.ndim != 2 or V.shape[1] not in (2, 3):
        raise FormatError(p, "points with 2 or 3 coordinates", f"points of shape {V.shape}")
    polys: list[np.ndarray] = []
    tets = []
    for block in m.cells:
        t = block.type
        data = np.asarray(block.data, dtype=np.int64)
        if t.startswith(_MESHIO_SURFACE):
            polys.append(data)
        elif t == "tetra":
            tets.append(data)
        elif not t.startswith(_MESHIO_IGNORED):
            raise FormatError(p, "triangles, polygons or tetrahedra",
                              f"{len(data)} '{t}' cells (not supported)")
    n = V.shape[0]
    for X in polys + tets:
        if X.size and (X.min() < 0 or X.max() >= n):
            raise FormatError(p, f"vertex indices in 0..{n - 1}",
                              f"{int(X.min()) if X.min() < 0 else int(X.max())}")
    T = np.vstack(tets) if tets else None
    return V, polys, T


def read_mesh(path: str | os.PathLike, *, dim: Dim = "auto") -> Mesh:
    """Read a triangle or tetrahedral mesh.

    Parameters
    ----------
    path : str or os.PathLike
        A ``.obj``, ``.off``, ``.ply``, ``.stl``, ``.mesh`` (Medit), ``.msh``
        (Gmsh) or ``.vtk`` file.
    dim : {"auto", 2, 3}, keyword-only
        ``"auto"`` (default) returns 2-D vertices when the file is planar with
        z == 0 exactly everywhere and has no tetrahedra, else 3-D. ``2`` requires
        z == 0 (a ValueError otherwise, never a silent projection); ``3`` always
        returns 3 columns (z = 0 added to 2-D input).

    Returns
    -------
    Mesh
        ``V`` (n, d) float64, ``F`` (f, 3) int64 or None, ``T`` (t, 4) int64 or None,
        all indices 0-based. All vertices of the file are kept, including ones no
        element uses (e.g. the interior Steiner points of a ``.mesh``), so weight
        rows keep matching vertex rows.

    Raises
    ------
    FileNotFoundError
        ``path`` does not exist.
    ValueError
        Unknown extension (the message lists the supported ones), a bad ``dim``,
        or ``dim=2`` for a non-planar file.
    FormatError
        A malformed file; the message names the file, the line where the format
        has lines, what was expected and what was found.

    Examples
    --------
    >>> import os, tempfile
    >>> from stbs.io import read_mesh, write_mesh
    >>> path = os.path.join(tempfile.mkdtemp(), "tri.obj")
    >>> write_mesh(path, [[0, 0, 0], [1, 0, 0], [0, 1, 1]], [[0, 1, 2]])
    >>> m = read_mesh(path)
    >>> m.V.shape, m.F.tolist()
    ((3, 3), [[0, 1, 2]])
    """
    dim = check_dim(dim)
    ext = suffix(path, MESH_READ_EXTENSIONS, "read_mesh")
    p = input_path(path, "mesh")
    if p.stat().st_size == 0:
        raise FormatError(p, f"a {ext} mesh", "an empty file")
    if ext == ".obj":
        V, polys, T = _mesh_formats.read_obj(p)
    elif ext == ".off":
        V, polys, T = _mesh_formats.read_off(p)
    elif ext == ".mesh":
        V, polys, T = _mesh_formats.read_medit(p)
    elif ext == ".msh" and (_mesh_formats.msh_version(p) or "").startswith("2"):
        V, polys, T = _mesh_formats.read_msh2(p)
    else:
        V, polys, T = _read_meshio(p)
    if V.shape[0] == 0:
        raise FormatError(p, "at least one vertex", "none")
    F = fan_triangulate(polys)
    if T is not None and dim == 2:
        raise ValueError(f"{p}: dim=2 asks for a planar mesh, but the file has "
                         f"{T.shape[0]} tetrahedra; use dim=3 or dim='auto'")
    V = apply_dim(V, 3 if (T is not None and dim == "auto") else dim, p, "vertices")
    return Mesh(V, F, T)


def _py_floats(V: np.ndarray) -> list[str]:
    # repr() gives the shortest decimal that reads back to the same float64.
    return [" ".join(map(repr, row)) for row in V.tolist()]


def write_mesh(path: str | os.PathLike, V, F=None) -> None:
    """Write a triangle mesh (or a point cloud when ``F`` is None), atomically.

    Parameters
    ----------
    path : str or os.PathLike
        Destination ``.obj`` (ASCII), ``.off`` (ASCII) or ``.ply`` (binary
        little-endian, float64 ``x y z``, int32 indices). The folder must exist.
    V : (n, 2) or (n, 3) float
        Vertex positions; 2-D input is written with z = 0.
    F : (f, 3) int, optional
        Triangles, 0-based (written 1-based in OBJ).

    Raises
    ------
    ValueError
        Unknown extension, or ``V`` / ``F`` of the wrong shape, non-finite
        values or indices out of range.

    Notes
    -----
    Output goes to a temporary file in the destination folder that is renamed
    over ``path`` only once it is complete. ASCII formats print every number
    with the shortest text that reads back to the same float64, so a round trip
    through :func:`read_mesh` is exact.
    """
    ext = suffix(path, MESH_WRITE_EXTENSIONS, "write_mesh")
    V = _checks.vertices(V)
    n = V.shape[0]
    if F is not None:
        F = _checks.index_array("F", F, ndim=2, shape=(None, 3))
        if F.size and (F.min() < 0 or F.max() >= n):
            bad = int(F.min()) if F.min() < 0 else int(F.max())
            raise ValueError(f"F must hold vertex indices in 0..{n - 1}, got {bad}")
    if V.shape[1] == 2:
        V = np.hstack([V, np.zeros((n, 1))])
    if ext == ".obj":
        _write_obj(path, V, F)
    elif ext == ".off":
        _write_off(path, V, F)
    else:
        _write_ply(path, V, F)


def _write_obj(path, V, F) -> None:
    with atomic_open(path, "w", newline="\n") as f:
        f.write("# written by stbs\n")
        f.write("".join(f"v {s}\n" for s in _py_floats(V)))
        if F is not None:
            f.write("".join(f"f {a} {b} {c}\n" for a, b, c in (F + 1).tolist()))


def _write_off(path, V, F) -> None:
    nf = 0 if F is None else F.shape[0]
    with atomic_open(path, "w", newline="\n") as f:
        f.write(f"OFF\n{V.shape[0]} {nf} 0\n")
        f.write("".join(f"{s}\n" for s in _py_floats(V)))
        if F is not None:
            f.write("".join(f"3 {a} {b} {c}\n" for a, b, c in F.tolist()))


def _write_ply(path, V, F) -> None:
    n = V.shape[0]
    if n >= 2**31:
        raise ValueError(f"V has {n} vertices; binary PLY with int32 indices holds < 2**31")
    head = ["ply", "format binary_little_endian 1.0", "comment written by stbs",
            f"element vertex {n}", "property double x", "property double y", "property double z"]
    if F is not None:
        head += [f"element face {F.shape[0]}", "property list uchar int vertex_indices"]
    head.append("end_header")
    with atomic_open(path, "wb") as f:
        f.write(("\n".join(head) + "\n").encode("ascii"))
        f.write(np.ascontiguousarray(V, dtype="<f8").tobytes())
        if F is not None:
            rec = np.zeros(F.shape[0], dtype=[("k", "u1"), ("i", "<i4", (3,))])
            rec["k"] = 3
            rec["i"] = F
            f.write(rec.tobytes())
