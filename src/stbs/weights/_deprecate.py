"""Renamed arguments, kept one release under their old name with a ``DeprecationWarning``.

``E`` means endpoint weights everywhere (the package's glossary); the mesh elements (triangles or
tetrahedra) that the BBW and Laplacian functions once called ``E`` are ``Ele``
(libigl's name). :func:`renamed` keeps the real signature (``inspect.signature``
shows the new name) and maps the old keyword onto it.
"""

from __future__ import annotations

import functools
import inspect
import warnings
from collections.abc import Callable
from typing import TypeVar

_F = TypeVar("_F", bound=Callable)


def renamed(old: str, new: str) -> Callable[[_F], _F]:
    """Decorator: accept the keyword ``old`` for the parameter ``new``, with a warning.

    Passing both (``new`` by position or keyword, and ``old``) is a ``TypeError``.
    """

    def wrap(func: _F) -> _F:
        params = list(inspect.signature(func).parameters)
        pos = params.index(new)
        qual = func.__qualname__.replace(".__init__", "")

        @functools.wraps(func)
        def inner(*args, **kwargs):
            if old in kwargs:
                if new in kwargs or len(args) > pos:
                    raise TypeError(f"{qual}() got both {new!r} and its deprecated name "
                                    f"{old!r}; pass {new} only")
                warnings.warn(f"{qual}({old}=...) is deprecated and will be removed in the "
                              f"next release: the argument is called {new} "
                              f"({old} means endpoint weights in stbs); pass {new}=... "
                              "or by position", DeprecationWarning, stacklevel=2)
                kwargs[new] = kwargs.pop(old)
            return func(*args, **kwargs)

        return inner  # type: ignore[return-value]

    return wrap
