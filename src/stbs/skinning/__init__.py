"""The four skinning methods: lbs, dqs, stbs-lbs (eq. 5), stbs-dqs (eq. 6)."""

from .deformer import METHODS, Deformer, deform
from .layout import TopK, top_k

__all__ = ["METHODS", "Deformer", "deform", "TopK", "top_k"]
