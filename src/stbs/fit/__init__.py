"""Rigs fitted from examples.

- :func:`fit_endpoint_weights`: endpoint weights E of a rig from example meshes in known
  poses (an exact bounded least-squares solve per vertex);
- :func:`fit_weights`: bone weights W and endpoint weights E together, sparse, bounded
  and smooth across the surface;
- :func:`decompose`: a whole mesh animation decomposed into bones, W, E and per-frame
  rotations, translations, stretches and twists (STBS-SSDR);
- :func:`helper_joints`: an STBS rig turned into plain LBS with k helper joints per
  bone (twist bones), for engines that play LBS only.

Modules load on first use, so ``import stbs.fit`` is cheap.
"""

from __future__ import annotations

_EXPORTS = {
    "fit_endpoint_weights": "from_poses",
    "fit_weights": "from_poses",
    "decompose": "ssdr",
    "Decomposition": "ssdr",
    "helper_joints": "twist_bones",
    "HelperRig": "twist_bones",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str):
    if name in _EXPORTS:
        import importlib

        return getattr(importlib.import_module(f".{_EXPORTS[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
