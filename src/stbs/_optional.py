"""Optional dependencies: lazy imports with an error that names the extra to install.

STYLE habit 8: a heavy or optional library is imported on first use, never at package
import time, and a missing one is an :class:`OptionalDependencyError` (an
``ImportError``) that says which extra brings it. Front ends check what a command
needs with :func:`missing` before doing any work.
"""

from __future__ import annotations

import importlib
import importlib.util
from collections.abc import Iterable
from types import ModuleType

__all__ = ["OptionalDependencyError", "available", "missing", "require", "EXTRAS"]

#: import name -> (distribution name, the stbs-skinning extra that brings it)
EXTRAS = {
    "matplotlib": ("matplotlib", "demo"),
    "PIL": ("pillow", "demo"),
    "triangle": ("triangle", "triangle"),
    "tetgen": ("tetgen", "tetgen"),
    "embreex": ("embreex", "embree"),
    "cholespy": ("cholespy", "weights"),
    "igl": ("libigl", "bench"),
    "playwright": ("playwright", "bench"),
    "ufbx": ("ufbx", "fbx"),
    "dask": ("dask", "batch"),
    "distributed": ("distributed", "batch"),
    "pxr": ("usd-core", "usd"),
    "torch": ("torch", "torch"),
    "jax": ("jax", "jax"),
    "py_dem_bones": ("py-dem-bones", "bench"),
}


class OptionalDependencyError(ImportError):
    """An optional dependency is missing; the message names the extra to install."""


def available(module: str) -> bool:
    """Whether ``module`` can be imported, found without importing it."""
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):
        return False


def message(module: str, feature: str) -> str:
    """The one-line advice for a missing ``module`` that ``feature`` needs."""
    top = module.split(".")[0]
    dist, extra = EXTRAS.get(top, (top, None))
    how = (f"pip install 'stbs-skinning[{extra}]'" if extra else f"pip install {dist}")
    return f"{feature} needs {dist}, which is not installed: {how}"


def missing(modules: Iterable[str], feature: str) -> str | None:
    """The advice for the first of ``modules`` that is not installed, else None."""
    for m in modules:
        if not available(m):
            return message(m, feature)
    return None


def require(module: str, feature: str) -> ModuleType:
    """Import ``module`` or raise :class:`OptionalDependencyError` naming its extra."""
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise OptionalDependencyError(message(module, feature)) from exc
