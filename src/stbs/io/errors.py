"""Errors raised by the readers and writers of :mod:`stbs.io`."""

from __future__ import annotations

import os


class FormatError(ValueError):
    """A file exists but its content does not follow the expected format.

    The message always names the file, the line (where one applies), what the
    reader expected and what it found, e.g.
    ``arm.tgf, line 9: expected a joint index in 1..5, found '7'``.

    Parameters
    ----------
    path : str or os.PathLike
        The offending file.
    expected : str
        What the reader expected at that place.
    found : str
        What it found instead.
    line : int, optional
        1-based line number, where the format is line oriented.

    Attributes
    ----------
    path : str
    line : int or None
    expected : str
    found : str
    """

    def __init__(self, path: str | os.PathLike, expected: str, found: str,
                 line: int | None = None):
        self.path = os.fspath(path)
        self.expected = expected
        self.found = found
        self.line = line
        where = self.path if line is None else f"{self.path}, line {line}"
        super().__init__(f"{where}: expected {expected}, found {found}")

    def __reduce__(self):
        # Keeps the exception picklable (multiprocessing) despite the custom signature.
        return (type(self), (self.path, self.expected, self.found, self.line))
