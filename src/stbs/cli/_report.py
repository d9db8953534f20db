"""How the command line reports: one line per input error and per warning.

Shared by :mod:`stbs.cli._main` and the commands that report warnings themselves before
they end (``stbs view`` prints the warnings of loading a rig before it serves), so a
command never imports the entry point that imports it.
"""

from __future__ import annotations

import sys

__all__ = ["PROG", "one_line", "describe", "flush_warnings"]

PROG = "stbs"


def one_line(text: str) -> str:
    """``text`` with every run of white space (newlines included) as one space."""
    return " ".join(str(text).split())


def describe(exc: BaseException) -> str:
    """One line for an input error: what is wrong with which input."""
    if isinstance(exc, OSError) and exc.filename is not None and exc.strerror:
        return one_line(f"{exc.filename}: {exc.strerror}")
    msg = str(exc) or type(exc).__name__
    return one_line(msg)


def flush_warnings(caught) -> None:
    """Print recorded warnings to stderr, one line each: ``stbs: warning: ...`` (the
    category named unless it is a plain UserWarning)."""
    for w in caught:
        kind = "" if issubclass(w.category, UserWarning) else f"{w.category.__name__}: "
        print(f"{PROG}: warning: {kind}{one_line(w.message)}", file=sys.stderr)
