"""Shapes generated in code: rigged test shapes, distance fields and their meshes.

Everything here is plain NumPy (no optional dependency) and deterministic, so the
same call gives the same mesh on every machine: handy for examples, tests and
benchmarks that need a shape without input files.

=============================  ======================================================
function                       what it gives
=============================  ======================================================
:func:`cigar`                  an ellipsoid with one bone inside: ``(V, F, sk, W)``
:func:`box`                    a box with one bone along it: ``(V, F, sk, W)``
:func:`bar`                    a box with two bones meeting at its middle
:func:`box_tets`               a box as tetrahedra with its surface: ``(V, T, F)``
:func:`sections`               the cross-sections across x of a grid shape
:func:`arm`                    an arm with a hand and three bones, a :class:`Model`
:func:`sphere_sdf`, ...        signed distances: sphere, round cone
                               (:func:`capsule_sdf`), ellipsoid, rounded box
:func:`smooth_union`           a blended union of two distance fields
:func:`round_cone`, ...        primitives (:class:`Primitive`) to :func:`blend`
                               into one field, :func:`mirror` in x = 0
:func:`implicit_surface`       the closed surface of a 3D distance field
                               (marching tetrahedra, relaxed onto the zero set)
:func:`mesh_primitives`        the surface of blended primitives
:func:`outline_of_field`       the zero set of a 2D field as polygons, ready for
                               :func:`stbs.triangulate_2d`
:func:`resample_loop`          a polygon resampled at equal arc-length steps
=============================  ======================================================

Examples
--------
A rig in a few lines: an arm, bone weights by bone heat, a 90 degree twist at the
wrist spread along the forearm by STBS:

>>> import numpy as np
>>> import stbs
>>> from stbs.shapes import arm
>>> m = arm(quick=True)
>>> W = stbs.bone_heat(m.V, m.F, m.sk)
>>> pose = stbs.forward_kinematics(m.sk, twist=[0, 0, np.pi / 2, 0])
>>> E = stbs.endpoint_weights(m.V, m.sk, method="projection")
>>> U = stbs.deform(m.V, m.sk, pose, W, E)
>>> U.shape == m.V.shape
True
"""

from __future__ import annotations

from ._fields import (
    Primitive,
    blend,
    bounds,
    box_sdf,
    capsule_sdf,
    ellipsoid,
    ellipsoid_sdf,
    mirror,
    round_cone,
    rounded_box,
    smooth_union,
    sphere_sdf,
)
from ._grid import bar, box, box_tets, cigar, sections
from ._marching import implicit_surface, mesh_primitives
from ._models import Model, arm
from ._outline import outline_of_field, resample_loop

__all__ = ["cigar", "box", "bar", "box_tets", "sections", "Model", "arm",
           "sphere_sdf", "capsule_sdf", "ellipsoid_sdf", "box_sdf", "smooth_union",
           "Primitive", "round_cone", "ellipsoid", "rounded_box", "blend", "mirror", "bounds",
           "implicit_surface", "mesh_primitives", "outline_of_field", "resample_loop"]
