"""Bone weights and endpoint weights (docs/weights.md)."""

from .bbw import BONE_METHODS, BBWConvergenceWarning, BBWReport, BBWSolver, bbw, bone_weights
from .boundary import boundary_conditions
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
from .laplacian import cotmatrix, element_measures, massmatrix
from .qp import BoxQPResult, box_qp, kkt_residual
from .spline import SplineFilter, spline_filter

__all__ = [
    "DEFAULT_THRESHOLD", "ENDPOINT_METHODS", "IDW_NORMALIZATIONS", "bbw_endpoint",
    "endpoint_weights", "heat_endpoint", "idw", "idw_joint_weights", "joints_to_endpoint",
    "projection", "BoneHeatSolver", "BoneHeatWarning", "HeatReport", "bone_heat",
    "heat_joint_weights", "SplineFilter", "spline_filter", "BONE_METHODS",
    "BBWConvergenceWarning", "BBWReport", "BBWSolver", "bbw", "bone_weights",
    "boundary_conditions", "cotmatrix", "massmatrix", "element_measures", "box_qp",
    "kkt_residual", "BoxQPResult",
]
