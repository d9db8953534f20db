"""Differentiable, batched skinning on the array API (NumPy, PyTorch, JAX, CuPy).

One implementation of the four methods (``lbs``, ``dqs``, ``stbs-lbs``, ``stbs-dqs``)
written against the array API standard, dispatched through ``array_api_compat``:
give it PyTorch tensors and it runs (and differentiates) in PyTorch, JAX arrays and it
runs in JAX. Nothing here imports torch or jax until their arrays arrive or they are
asked for by name. See ``docs/learning.md``.

- :class:`Skinner` — precompute a top-k weight layout once, skin batches of poses;
- :func:`skin` — the functional form, every input (rest joints too) an array;
- :func:`forward_kinematics` — batched, differentiable forward kinematics;
- rotation converters: :func:`quat_to_matrix`, :func:`matrix_to_quat`,
  :func:`rot6d_to_matrix`, :func:`matrix_to_rot6d`, :func:`angle_to_matrix`.
"""

from __future__ import annotations

_EXPORTS = {
    "Skinner": "skinner", "skin": "skinner",
    "forward_kinematics": "kinematics", "rest_joints": "kinematics", "FKResult": "kinematics",
    "quat_to_matrix": "rotations", "matrix_to_quat": "rotations",
    "rot6d_to_matrix": "rotations", "matrix_to_rot6d": "rotations",
    "angle_to_matrix": "rotations", "angle_to_quat": "rotations",
    "axis_angle_to_quat": "rotations", "quat_mul": "rotations",
    "BACKENDS": "_backend",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str):
    mod = _EXPORTS.get(name)
    if mod is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    import importlib

    return getattr(importlib.import_module(f"{__name__}.{mod}"), name)


def __dir__():
    return __all__
