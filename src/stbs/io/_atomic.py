"""Atomic file output: write to a temporary file beside the target, then rename.

A failed write never leaves a half-written file behind and never touches an
existing file at the destination. ``os.replace`` is atomic on POSIX
and on Windows when source and destination share a folder, which is why the
temporary file is created in the destination's folder.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import IO, Any

from .._inputs import check_output

__all__ = ["atomic_open", "atomic_save", "atomic_write"]


def _destination(path: str | os.PathLike) -> Path:
    p = Path(os.fspath(path))
    check_output(p)
    if p.is_dir():
        raise IsADirectoryError(f"cannot write {str(p)!r}: it is a folder, expected a file path")
    folder = p.parent if str(p.parent) else Path(".")
    if not folder.is_dir():
        raise FileNotFoundError(f"cannot write {str(p)!r}: folder {str(folder)!r} does not exist")
    return p


def _temp_path(p: Path) -> Path:
    # Keep the destination's suffix last: writers such as np.savez (appends ".npz"
    # otherwise) and meshio (picks the format from the suffix) look at it.
    fd, name = tempfile.mkstemp(dir=p.parent if str(p.parent) else ".",
                                prefix=f".{p.name}.", suffix=f".tmp{p.suffix}")
    os.close(fd)
    return Path(name)


def _final_mode(p: Path) -> int:
    # mkstemp creates the file 0600; give the result the permissions a plain
    # open() would (keep an existing file's mode, else 0666 minus the umask).
    try:
        return os.stat(p).st_mode & 0o7777
    except OSError:
        umask = os.umask(0)
        os.umask(umask)
        return 0o666 & ~umask


def _commit(tmp: Path, p: Path) -> None:
    with contextlib.suppress(OSError):
        os.chmod(tmp, _final_mode(p))
    os.replace(tmp, p)


def _discard(tmp: Path) -> None:
    with contextlib.suppress(OSError):
        os.unlink(tmp)


@contextlib.contextmanager
def atomic_open(path: str | os.PathLike, mode: str = "wb", **open_kwargs: Any) -> Iterator[IO]:
    """Open a temporary file for writing that replaces ``path`` on success.

    Parameters
    ----------
    path : str or os.PathLike
        Destination file. Its folder must exist.
    mode : {"wb", "w", "wt"}
        Binary or text mode.
    **open_kwargs
        Passed to :func:`open` (e.g. ``encoding``, ``newline``) in text mode.

    Yields
    ------
    file object
        Writes go to a hidden temporary file in the destination's folder. When
        the ``with`` block ends normally the file is flushed, synced and renamed
        onto ``path``; when it raises, the temporary file is deleted and
        ``path`` is left untouched.

    Examples
    --------
    >>> import os, tempfile
    >>> from stbs.io import atomic_open
    >>> path = os.path.join(tempfile.mkdtemp(), "out.txt")
    >>> with atomic_open(path, "w") as f:
    ...     _ = f.write("hello")
    >>> open(path).read()
    'hello'
    """
    if mode not in ("wb", "w", "wt"):
        raise ValueError(f"mode must be one of 'wb', 'w', 'wt', got {mode!r}")
    p = _destination(path)
    tmp = _temp_path(p)
    try:
        if "b" not in mode:
            open_kwargs.setdefault("encoding", "utf-8")
        with open(tmp, mode, **open_kwargs) as f:
            yield f
            f.flush()
            os.fsync(f.fileno())
        _commit(tmp, p)
    except BaseException:
        _discard(tmp)
        raise


def atomic_write(path: str | os.PathLike, writer_fn: Callable[[IO], Any],
                 mode: str = "wb", **open_kwargs: Any) -> None:
    """Call ``writer_fn(f)`` on a temporary file object, then replace ``path``.

    Same guarantees as :func:`atomic_open`.
    """
    with atomic_open(path, mode, **open_kwargs) as f:
        writer_fn(f)


def atomic_save(path: str | os.PathLike, fn: Callable[[str], Any]) -> None:
    """Call ``fn(tmp_path)`` for writers that need a file name, then replace ``path``.

    Parameters
    ----------
    path : str or os.PathLike
        Destination file. Its folder must exist.
    fn : callable
        Called with the temporary file's name (a ``str`` in the destination's
        folder, ending with the destination's suffix, e.g. ``.npz``, so that
        ``np.savez`` adds nothing and ``meshio.write`` picks the right format).
        The temporary file already exists (empty) when ``fn`` is called.

    Notes
    -----
    If ``fn`` raises, or writes to a different name, the temporary file is
    deleted and ``path`` is left untouched.
    """
    p = _destination(path)
    tmp = _temp_path(p)
    try:
        fn(str(tmp))
        if not tmp.is_file():
            raise FileNotFoundError(f"writer did not produce the temporary file {str(tmp)!r}")
        with open(tmp, "rb+") as f:
            os.fsync(f.fileno())
        _commit(tmp, p)
    except BaseException:
        _discard(tmp)
        raise
