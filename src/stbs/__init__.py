"""stbs: skeletal shape deformation with stretchable, twistable bones.

Jacobson & Sorkine, "Stretchable and Twistable Bones for Skeletal Shape
Deformation", SIGGRAPH Asia 2011. The names exported here are stable.

Names are loaded on first use (PEP 562), so ``import stbs`` and ``stbs --help`` stay
fast and numba is imported only when skinning is first needed. Subpackages: the maths
(:mod:`stbs.geometry`, :mod:`stbs.transforms`, :mod:`stbs.skinning`, :mod:`stbs.weights`,
:mod:`stbs.meshing`, :mod:`stbs.shapes`; :mod:`stbs.skin`, differentiable skinning on
PyTorch and JAX), the data (:mod:`stbs.rig`, :mod:`stbs.io`; :mod:`stbs.fit`, rigs fitted
to examples) and the front ends (:mod:`stbs.cli`, :mod:`stbs.demo`, :mod:`stbs.bench`).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

__version__ = "0.1.0"

_EXPORTS = {
    "Skeleton": "stbs.skeleton",
    "Pose": "stbs.pose",
    "forward_kinematics": "stbs.pose",
    "Clip": "stbs.clip",
    "Motion": "stbs.motion",
    "retarget": "stbs.retargeting",
    "Deformer": "stbs.skinning",
    "deform": "stbs.skinning",
    "METHODS": "stbs.skinning",
    "endpoint_weights": "stbs.weights",
    "Rig": "stbs.rig",
    "build_rig": "stbs.rig",
    "load_rig": "stbs.io",
    "save_rig": "stbs.io",
    "read_pose": "stbs.io",
    "write_pose": "stbs.io",
    "read_clip": "stbs.io",
    "write_clip": "stbs.io",
    "read_bvh": "stbs.io",
    "bone_heat": "stbs.weights",
    "bone_weights": "stbs.weights",
    "BBWSolver": "stbs.weights",
    "bbw": "stbs.weights",
    "boundary_conditions": "stbs.weights",
    "SplineFilter": "stbs.weights",
    "triangulate_2d": "stbs.meshing",
    "tetrahedralize": "stbs.meshing",
    "outline_from_image": "stbs.meshing",
}

__all__ = ["Skeleton", "Pose", "forward_kinematics", "Clip", "Motion", "retarget", "Deformer",
           "deform", "METHODS",
           "endpoint_weights", "Rig", "build_rig", "load_rig", "save_rig", "read_pose",
           "write_pose", "read_clip", "write_clip", "read_bvh", "bone_heat",
           "bone_weights", "BBWSolver", "bbw", "boundary_conditions",
           "SplineFilter", "triangulate_2d", "tetrahedralize", "outline_from_image",
           "__version__"]


#: Subpackages reachable as attributes (``stbs.shapes.cigar``), imported on first use.
_SUBPACKAGES = ("geometry", "transforms", "skinning", "weights", "meshing", "shapes", "rig",
                "io", "cli", "demo", "bench", "bake", "skin", "fit")


def __getattr__(name: str):
    if name in _SUBPACKAGES:
        return importlib.import_module(f"stbs.{name}")
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'stbs' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted([*__all__, *_SUBPACKAGES])


if TYPE_CHECKING:  # pragma: no cover - for type checkers and IDEs
    from .clip import Clip
    from .io import load_rig, read_bvh, read_clip, read_pose, save_rig, write_clip, write_pose
    from .meshing import outline_from_image, tetrahedralize, triangulate_2d
    from .motion import Motion
    from .pose import Pose, forward_kinematics
    from .retargeting import retarget
    from .rig import Rig, build_rig
    from .skeleton import Skeleton
    from .skinning import METHODS, Deformer, deform
    from .weights import (
        BBWSolver,
        SplineFilter,
        bbw,
        bone_heat,
        bone_weights,
        boundary_conditions,
        endpoint_weights,
    )
