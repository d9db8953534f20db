"""Rigs: the rest mesh with one skeleton and its weights, and the pipeline that builds one.

=====================  ==========================================================
name                   what it is
=====================  ==========================================================
:class:`Rig`           ``V``, ``F`` and/or ``T``, one :class:`stbs.Skeleton`, ``W``, ``E``
:func:`build_rig`      mesh + skeleton -> rig (meshing with the bones inside,
                       bone weights, endpoint weights, restricted to ``V``)
=====================  ==========================================================

Rig files (``.npz``) are read and written by :func:`stbs.io.load_rig` and
:func:`stbs.io.save_rig`.
"""

from .build import BONE_METHODS, DEFAULT_TOL, ENDPOINT_METHODS, build_rig
from .model import Rig

__all__ = ["Rig", "build_rig", "BONE_METHODS", "ENDPOINT_METHODS", "DEFAULT_TOL"]
