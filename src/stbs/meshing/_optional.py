"""Lazy imports of the optional meshers, with an error that names the extra."""

from __future__ import annotations

import importlib
import importlib.util
from types import ModuleType

#: module -> (extra, what it is, licence note)
_OPTIONAL = {
    "triangle": ("triangle", "Shewchuk's Triangle (through the 'triangle' package)",
                 "Triangle is free for research and private use only; commercial "
                 "distribution needs the author's permission"),
    "tetgen": ("tetgen", "TetGen (through pyvista's 'tetgen' package)",
               "TetGen is AGPL-3.0 (copyleft)"),
}


def available(module: str) -> bool:
    """Whether the optional ``module`` can be imported (without importing the rest)."""
    return importlib.util.find_spec(module) is not None


def require(module: str) -> ModuleType:
    """Import an optional mesher or raise ``ImportError`` naming the extra to install."""
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        extra, what, licence = _OPTIONAL[module]
        raise ImportError(
            f"this needs {what}, an optional dependency: pip install 'stbs-skinning[{extra}]' "
            f"({licence}); or pass engine='builtin' for the bundled fallback mesher"
        ) from exc
