"""Bone weights and endpoint weights (DESIGN §4)."""

from .endpoint import (
    DEFAULT_THRESHOLD,
    ENDPOINT_METHODS,
    IDW_NORMALIZATIONS,
    bbw_endpoint,
    endpoint_weights,
    heat_endpoint,
    idw,
    idw_joint_weights,
    joints_to_endpoint,
    projection,
)
from .heat import BoneHeatSolver, BoneHeatWarning, HeatReport, bone_heat, heat_joint_weights
from .spline import SplineFilter, spline_filter

__all__ = [
    "DEFAULT_THRESHOLD", "ENDPOINT_METHODS", "IDW_NORMALIZATIONS", "bbw_endpoint",
    "endpoint_weights", "heat_endpoint", "idw", "idw_joint_weights", "joints_to_endpoint",
    "projection", "BoneHeatSolver", "BoneHeatWarning", "HeatReport", "bone_heat",
    "heat_joint_weights", "SplineFilter", "spline_filter",
]
