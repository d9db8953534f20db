"""Array namespaces: which library a call runs on, and moving constants onto it.

Nothing here imports torch, jax or cupy at import time; a backend is imported when
it is asked for by name or when one of its arrays arrives.
"""

from __future__ import annotations

import importlib
import math
from types import ModuleType
from typing import Any

import array_api_compat
import numpy as np

from .._optional import require

#: Backend names accepted by ``backend=``.
BACKENDS = ("numpy", "torch", "jax", "cupy")


def namespace(backend: Any = None, *arrays: Any) -> ModuleType:
    """The array-API namespace for ``backend`` or, when None, for ``arrays``.

    Parameters
    ----------
    backend : {"numpy", "torch", "jax", "cupy"}, module or None
        A name, a module (``numpy``, ``torch``, ``jax.numpy``, ``cupy`` or their
        array-API namespaces), or None to infer from ``arrays``: the library of the
        first array that is not a NumPy array (plain sequences and NumPy arrays mean
        NumPy).
    """
    if backend is None:
        lib = [a for a in arrays if a is not None and array_api_compat.is_array_api_obj(a)
               and not isinstance(a, np.ndarray)]
        if not lib:
            return array_api_compat.array_namespace(np.empty(0))
        return array_api_compat.array_namespace(lib[0])
    if isinstance(backend, ModuleType):
        name = backend.__name__.split(".")
        top = "jax" if "jax" in name else name[-1] if name[0] == "array_api_compat" else name[0]
        backend = top
    if not isinstance(backend, str) or backend not in BACKENDS:
        raise ValueError(f"backend must be one of {', '.join(map(repr, BACKENDS))}, a module "
                         f"of one of them, or None (inferred from the arrays), got {backend!r}")
    if backend == "numpy":
        return array_api_compat.array_namespace(np.empty(0))
    if backend == "jax":
        require("jax", "backend='jax'")
        return importlib.import_module("jax.numpy")
    mod = require(backend, f"backend={backend!r}")
    return array_api_compat.array_namespace(mod.asarray([0.0]))


def is_numpy(xp: ModuleType) -> bool:
    return array_api_compat.is_numpy_namespace(xp)


def is_torch(xp: ModuleType) -> bool:
    return array_api_compat.is_torch_namespace(xp)


def is_jax(xp: ModuleType) -> bool:
    return array_api_compat.is_jax_namespace(xp)


def float_dtype(xp: ModuleType, dtype: Any, like: Any = None):
    """The backend's floating dtype for ``dtype`` (a name, NumPy or backend dtype).

    None: the dtype of ``like`` when it is a floating array, else float64 (float32 on
    JAX while its 64-bit mode is off).
    """
    if dtype is None:
        name = "float64"
        dt = getattr(like, "dtype", None)
        if dt is not None and str(dt).rsplit(".", 1)[-1] in ("float32", "float64"):
            name = str(dt).rsplit(".", 1)[-1]
        if name == "float64" and is_jax(xp) and not _jax_x64():
            name = "float32"
        return getattr(xp, name)
    name = str(getattr(dtype, "__name__", dtype)).rsplit(".", 1)[-1]
    if name in ("float", "double"):
        name = "float64"
    if name not in ("float32", "float64"):
        raise ValueError(f"dtype must be float32 or float64, got {dtype!r}")
    if name == "float64" and is_jax(xp) and not _jax_x64():
        raise ValueError("dtype float64 on JAX needs its 64-bit mode: "
                         "jax.config.update('jax_enable_x64', True) or "
                         "'with jax.enable_x64(True):', got it switched off")
    return getattr(xp, name)


def _jax_x64() -> bool:
    import jax

    return bool(jax.config.jax_enable_x64)


def is_traced(x: Any) -> bool:
    """Whether ``x`` is being traced (jax.jit, torch.compile): its values are unknown."""
    mod = type(x).__module__
    if mod.startswith("jax"):
        import jax

        return isinstance(x, jax.core.Tracer)
    if mod.startswith("torch"):
        import torch

        return bool(torch.compiler.is_compiling())
    return False


def to_numpy(x: Any) -> np.ndarray:
    """A NumPy copy of a concrete array of any backend (detached from autograd)."""
    if isinstance(x, np.ndarray):
        return x
    if hasattr(x, "detach"):
        x = x.detach().cpu()
    elif hasattr(x, "get") and type(x).__module__.startswith("cupy"):
        x = x.get()
    return np.asarray(x)


def library(xp: ModuleType) -> str:
    """The library behind a namespace: "numpy", "torch", "jax", "cupy", ..."""
    name = xp.__name__.split(".")
    return name[1] if name[0] == "array_api_compat" and len(name) > 1 else name[0]


def belongs(xp: ModuleType, x: Any) -> bool:
    """Whether ``x`` is an array of ``xp``'s library (by its type's module: cheap, and
    plain Python under torch.compile's tracing)."""
    if x is None or isinstance(x, (list, tuple, float, int)):
        return False
    lib = library(xp)
    mod = type(x).__module__.split(".")[0]
    if lib == "numpy":
        return isinstance(x, np.ndarray)
    return mod == lib or (lib == "jax" and mod == "jaxlib")


def asarray(xp: ModuleType, x: Any, dtype=None, device=None):
    """``x`` on the backend: backend arrays pass through (cast only when the dtype
    differs, which keeps them differentiable); anything else is converted."""
    if belongs(xp, x):
        if dtype is not None and x.dtype != dtype:
            x = xp.astype(x, dtype)
        if device is not None and array_api_compat.device(x) != device:
            x = array_api_compat.to_device(x, device)
        return x
    if not isinstance(x, np.ndarray) and array_api_compat.is_array_api_obj(x):
        x = to_numpy(x)
    x = np.asarray(x)
    if not x.flags.writeable:       # PyTorch warns about sharing read-only memory
        x = x.copy()
    return xp.asarray(x, dtype=dtype, device=device)


def broadcast_batch(name_shapes: list[tuple[str, tuple]]) -> tuple:
    """The common leading (batch) shape of several inputs, or a ValueError naming them."""
    out: tuple = ()
    for name, shape in name_shapes:
        n = max(len(out), len(shape))
        a = (1,) * (n - len(out)) + tuple(out)
        b = (1,) * (n - len(shape)) + tuple(shape)
        res = []
        for x, y in zip(a, b, strict=True):
            if x == y or y == 1:
                res.append(x)
            elif x == 1:
                res.append(y)
            else:
                listed = ", ".join(f"{m} {s}" for m, s in name_shapes)
                raise ValueError(f"the leading (batch) axes of the pose inputs must broadcast "
                                 f"together; {name} has batch shape {tuple(shape)}, which does "
                                 f"not match ({listed})")
        out = tuple(res)
    return out


def prod(shape) -> int:
    return math.prod(shape)


def index(xp: ModuleType, x, like):
    """Integer index array (int64) on ``like``'s device, from a (possibly read-only)
    NumPy array."""
    return xp.asarray(np.array(x, dtype=np.int64), device=array_api_compat.device(like))
