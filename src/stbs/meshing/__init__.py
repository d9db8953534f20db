"""Meshing with the skeleton built in (skeleton samples are mesh vertices).

=========================  ====================================================
function                   what it does
=========================  ====================================================
:func:`triangulate_2d`     2D outline -> quality triangle mesh, bones as
                           constrained segments (Triangle, or builtin Ruppert)
:func:`tetrahedralize`     closed surface -> tetrahedral mesh with joints and
                           bone samples as vertices (TetGen, or builtin lattice)
:func:`volume_mesh`        any surface (open, parts, self-intersecting) -> a
                           tetrahedral mesh of its inside by winding number, at
                           a size of its own, skeleton points as vertices
:func:`check_surface`      closed, manifold, oriented, not self-intersecting?
:func:`outline_from_image` image mask -> polygons (marching squares)
:func:`boundary_loops`     a 2D mesh's boundary loops (from :mod:`stbs.geometry`)
=========================  ====================================================

Triangle ``.poly`` files are read by :func:`stbs.io.read_polygons`. The optional
engines are imported on first use only; see ``docs/meshing.md`` for their licences
and the extras that install them.
"""

from ..geometry import boundary_loops
from .outline import outline_from_image
from .result import TetMesh, TriMesh
from .surface import check_surface
from .tetrahedra import ENGINES_3D, tetrahedralize
from .triangulate import ENGINES_2D, triangulate_2d
from .volume import VolumeMesh, volume_mesh

__all__ = ["TriMesh", "TetMesh", "VolumeMesh", "triangulate_2d", "tetrahedralize",
           "volume_mesh", "check_surface", "outline_from_image", "boundary_loops",
           "ENGINES_2D", "ENGINES_3D"]
