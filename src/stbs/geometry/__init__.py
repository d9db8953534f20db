"""Geometry shared by the whole library: mesh connectivity, normals, polygons, winding.

Small, vectorised functions on the glossary's arrays (``V`` (n, d) float, ``F``
(f, 3) int, ``T`` (t, 4) int). The meshers, the weight solvers, the demo and the
command line all use these; none of them keeps a copy of its own.

=========================  ====================================================
function                   what it gives
=========================  ====================================================
:func:`unique_rows`        ``np.unique(A, axis=0)`` for integer rows, much faster
:func:`unique_edges`       undirected edges of triangles or polygons, with counts
:func:`boundary_faces`     the outward boundary triangles of a tetrahedral mesh
:func:`boundary_loops`     the boundary loops of a triangle mesh
:func:`face_normals`       area-weighted triangle normals (3D)
:func:`vertex_normals`     unit, area-weighted vertex normals (3D)
:func:`triangle_areas`     signed areas of 2D triangles
:func:`tet_volumes`        signed volumes of tetrahedra
:func:`signed_area`        signed area of a closed polygon
:func:`points_in_loops`    even-odd inclusion of 2D points in polygons
:func:`polygons_area`      area inside polygons, holes subtracted by nesting
:func:`winding_numbers`    generalised winding numbers of points for a 3D surface
:class:`WindingTree`       the same, hierarchical: fast for many points and triangles
:func:`cycles`             the cycles of a permutation (loops from successor arrays)
=========================  ====================================================
"""

from __future__ import annotations

import numpy as np

from ._mesh import (
    boundary_faces,
    boundary_loops,
    cycles,
    face_normals,
    tet_volumes,
    triangle_areas,
    unique_edges,
    unique_rows,
    vertex_normals,
)
from ._polygon import points_in_loops, polygons_area, signed_area

__all__ = ["unique_rows", "unique_edges", "boundary_faces", "boundary_loops",
           "face_normals", "vertex_normals", "triangle_areas", "tet_volumes",
           "signed_area", "points_in_loops", "polygons_area", "winding_numbers", "WindingTree",
           "cycles"]


def winding_numbers(Q, V, F) -> np.ndarray:
    """Generalised winding numbers of points for a triangle surface (Jacobson et al. 2013).

    Parameters
    ----------
    Q : (q, 3) float
        Query points.
    V : (n, 3) float
        Surface vertices.
    F : (f, 3) int
        Surface triangles.

    Returns
    -------
    (q,) float64
        About 1 inside a closed, outward-oriented surface, 0 outside; a fraction near
        holes, and a sum where sheets overlap. Compiled, in parallel over ``Q``.

    Examples
    --------
    >>> import numpy as np
    >>> from stbs.geometry import winding_numbers
    >>> V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    >>> F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    >>> np.round(winding_numbers([[0.1, 0.1, 0.1], [2, 2, 2]], V, F), 6) + 0.0
    array([1., 0.])
    """
    from ._winding import winding_numbers as _wn

    return _wn(np.asarray(Q, dtype=np.float64).reshape(-1, 3), V, F)


def __getattr__(name: str):
    # The winding kernels are numba's: compiled code loads on first use, not on import.
    if name == "WindingTree":
        from ._winding import WindingTree

        return WindingTree
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
