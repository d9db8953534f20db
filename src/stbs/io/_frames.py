"""Frames for a writer asked to bake without them (``write_gltf(..., bake=METHOD)``).

The writers take frames; :func:`stbs.bake.export` is the pipeline that skins a clip
(limits, progress, timing) and hands them over. A writer called as the stable API
promises, with ``bake`` and no ``frames``, skins the clip here: the skinning module is
imported only then, so ``import stbs.io`` stays free of the compiled kernels.
"""

from __future__ import annotations

import numpy as np


def skinned_frames(rig, clip, times, method: str) -> np.ndarray:
    """``rig`` skinned by ``method`` at each of ``times`` of ``clip``: (k, n, d) float."""
    from ..skinning import Deformer

    dfm = Deformer(rig.V, rig.skeleton, rig.W, rig.E, method=method)
    return np.stack([np.asarray(dfm(pose), dtype=np.float64) for pose in clip.poses(times)])
