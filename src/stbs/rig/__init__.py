"""Rigs: the rest mesh with one skeleton and its weights, and the pipelines that build one.

==============================  =================================================================
name                            what it is
==============================  =================================================================
:class:`Rig`                    ``V``, ``F`` and/or ``T``, one :class:`stbs.Skeleton`, ``W``, ``E``
:class:`Volume`                 the volume mesh a rig's weights were solved on, when kept
:func:`build_rig`               mesh + skeleton -> rig (meshing with the bones inside,
                                bone weights, endpoint weights, restricted to ``V``)
:func:`rig_from_files`          mesh (or outline, or picture) and skeleton files -> rig
:func:`rig_from_mesh`           :func:`build_rig` with a given tetrahedral mesh too
:func:`rig_from_outline`        a 2D shape's polygons + skeleton -> rig
:func:`rig_from_picture`        a picture + skeleton -> 2D rig with the picture as texture
:func:`endpoint_methods`        the endpoint weight methods that can work on a rig
:func:`rig_endpoint_weights`    endpoint weights of a rig's bones, solved again
==============================  =================================================================

The long functions take ``progress(stage, done, total)``; raise any exception from it
to cancel (it propagates). Rig files (``.npz``) are read and written by
:func:`stbs.io.load_rig` and :func:`stbs.io.save_rig`.
"""

from .build import BONE_METHODS, DEFAULT_TOL, ENDPOINT_METHODS, VOLUME_METHODS, build_rig
from .endpoints import endpoint_methods, rig_endpoint_weights
from .model import Rig, Volume
from .pipeline import (
    IMAGE_EXTENSIONS,
    OUTLINE_EXTENSIONS,
    OUTLINE_TRIANGLES,
    read_image,
    rig_from_files,
    rig_from_mesh,
    rig_from_outline,
    rig_from_picture,
)

__all__ = ["Rig", "Volume", "build_rig", "rig_from_files", "rig_from_mesh", "rig_from_outline",
           "rig_from_picture", "read_image", "endpoint_methods", "rig_endpoint_weights",
           "BONE_METHODS", "ENDPOINT_METHODS", "VOLUME_METHODS", "DEFAULT_TOL",
           "IMAGE_EXTENSIONS", "OUTLINE_EXTENSIONS", "OUTLINE_TRIANGLES"]
