"""Bone weights and endpoint weights (DESIGN §4)."""

from .endpoint import ENDPOINT_METHODS, endpoint_weights, joints_to_endpoint, projection

__all__ = ["ENDPOINT_METHODS", "endpoint_weights", "joints_to_endpoint", "projection"]
