"""The files a run has read, so that no output of that run is written over one of them.

A command runs inside :func:`tracking` (``stbs view`` for the server's whole life; a
viewer server started from Python tracks each save, with its own inputs noted). Every
reader notes the files it opens with :func:`note_input` (``input_path`` does it for the
readers that go through it), and every writer asks :func:`check_output` before it
writes (the atomic writers of :mod:`stbs.io._atomic` do). An output is refused when it
is the same file as an input, compared by resolved path (symbolic links followed) and
by device and inode (hard links). Outside :func:`tracking` nothing is recorded or
refused: a script may read a rig, change it and save it in place.
"""

from __future__ import annotations

import contextlib
import errno
import os
import threading
from collections.abc import Iterator
from pathlib import Path

__all__ = ["tracking", "note_input", "check_output", "SameFileError", "inputs",
           "input_path"]

_lock = threading.Lock()
#: The runs being tracked (a stack: a command may run inside another's tracking).
_runs: list[dict[str, tuple[int, int] | None]] = []


class SameFileError(ValueError):
    """An output path names a file the same run reads."""


@contextlib.contextmanager
def tracking() -> Iterator[None]:
    """Record the inputs read inside the block and refuse outputs written over them."""
    run: dict[str, tuple[int, int] | None] = {}
    with _lock:
        _runs.append(run)
    try:
        yield
    finally:
        with _lock:
            _runs.remove(run)


def _key(path: str | os.PathLike) -> tuple[str, tuple[int, int] | None]:
    real = os.path.realpath(os.fspath(path))
    try:
        st = os.stat(real)
        ident = (st.st_dev, st.st_ino)
    except OSError:
        ident = None
    return real, ident


def note_input(path: str | os.PathLike) -> None:
    """Record ``path`` as read by the current run (nothing when none is tracked)."""
    if not _runs:
        return
    real, ident = _key(path)
    with _lock:
        for run in _runs:
            run[real] = ident


def inputs() -> list[str]:
    """The resolved paths of the files the current run has read."""
    with _lock:
        return sorted({p for run in _runs for p in run})


def check_output(path: str | os.PathLike, what: str = "output") -> None:
    """Raise :class:`SameFileError` when ``path`` is a file the current run read."""
    if not _runs:
        return
    real, ident = _key(path)
    with _lock:
        seen = {p: i for run in _runs for p, i in run.items()}
    for p, i in seen.items():
        if p == real or (ident is not None and i == ident):
            same = "" if p == real else f" (the same file as {p!r})"
            raise SameFileError(
                f"{what} {os.fspath(path)!r}: refusing to write over a file this command "
                f"reads{same}; choose another output path")


def input_path(path: str | os.PathLike, what: str) -> Path:
    """``path`` as a Path that exists and is a file, else FileNotFoundError/IsADirectoryError."""
    try:
        p = Path(os.fspath(path))
    except TypeError:
        raise TypeError(f"{what} path must be a str or os.PathLike, "
                        f"got {type(path).__name__}") from None
    if not p.exists():
        raise FileNotFoundError(errno.ENOENT, f"{what} file not found", str(p))
    if p.is_dir():
        raise IsADirectoryError(errno.EISDIR, f"{what} path is a folder, expected a file", str(p))
    note_input(p)
    return p
