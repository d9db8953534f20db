"""The four skinning methods: lbs, dqs, stbs-lbs (eq. 5), stbs-dqs (eq. 6).

The deformer and its compiled kernels load on first use (PEP 562), so the weight layout
(:mod:`stbs.skinning.layout`, which the file writers and the viewer use) comes without
numba.
"""

from ..methods import SKINNING_METHODS as METHODS
from .layout import TopK, four_heaviest, top_k

__all__ = ["METHODS", "Deformer", "deform", "TopK", "top_k", "four_heaviest"]


def __getattr__(name: str):
    if name in ("Deformer", "deform"):
        from . import deformer

        return getattr(deformer, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
