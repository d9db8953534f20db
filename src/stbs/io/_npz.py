"""NumPy ``.npz``/``.npy`` members read within a budget: a small archive cannot make a
reader allocate gigabytes.

An ``.npz`` is a zip of ``.npy`` files, and a deflated member of zeros shrinks a
thousandfold (a 3 MB rig can hold a 3 GB weight matrix). Before a member is
decompressed, its ``.npy`` header (a few hundred bytes) is read to learn its shape and
dtype; the bytes it needs are checked against the member's size as the archive records
it (a member shorter than its header says is refused) and against a budget of
:data:`BUDGET_BASE` plus :data:`BUDGET_FACTOR` times the file's size, shared by all the
members one reader loads. Object arrays are never unpickled.
"""

from __future__ import annotations

import os
import zipfile

import numpy as np

from .errors import FormatError

__all__ = ["Budget", "BUDGET_BASE", "BUDGET_FACTOR", "npy_header"]

#: Arrays read from one NumPy file may take this many bytes plus BUDGET_FACTOR times the
#: file's size.
BUDGET_BASE = 256 * 2**20
BUDGET_FACTOR = 32


def npy_header(fh, path, what: str) -> tuple[tuple[int, ...], np.dtype, int]:
    """Shape, dtype and data bytes of the ``.npy`` stream ``fh`` (left at its data)."""
    fmt = np.lib.format
    try:
        version = fmt.read_magic(fh)
        if version == (1, 0):
            shape, _, dtype = fmt.read_array_header_1_0(fh)
        elif version == (2, 0):
            shape, _, dtype = fmt.read_array_header_2_0(fh)
        else:
            raise ValueError(f"an .npy format version {version} this reader does not know")
    except (ValueError, OSError, EOFError, SyntaxError, TypeError) as exc:
        raise FormatError(path, f"{what}: an .npy array", " ".join(str(exc).split())[:160]
                          ) from None
    if dtype.hasobject:
        raise FormatError(path, f"{what}: a numeric or text array (object arrays are never "
                                "unpickled)", f"dtype {dtype}")
    n = 1
    for s in shape:
        n *= int(s)
    return tuple(int(s) for s in shape), dtype, n * dtype.itemsize


class Budget:
    """The bytes of arrays the readers may still take from one file ``path``."""

    def __init__(self, path: str | os.PathLike):
        self.path = path
        self.size = os.path.getsize(path)
        self.limit = BUDGET_BASE + BUDGET_FACTOR * self.size
        self.used = 0

    def take(self, nbytes: int, what: str) -> None:
        if self.used + nbytes > self.limit:
            raise FormatError(
                self.path, f"at most {self.limit} bytes of arrays from a file of {self.size} "
                f"bytes ({BUDGET_BASE >> 20} MiB + {BUDGET_FACTOR} times its size)",
                f"{what} needing {nbytes} bytes (a hostile or damaged file?)")
        self.used += nbytes

    def npz_member(self, npz, key: str) -> np.ndarray:
        """``npz[key]`` of an open ``np.load`` archive, its size checked first."""
        self.check_member(npz, key)
        try:
            return npz[key]
        except (zipfile.BadZipFile, EOFError, OSError) as exc:
            raise FormatError(self.path, f"an undamaged member {key!r}", str(exc)) from None

    def check_member(self, npz, key: str) -> None:
        """Count member ``key`` of an open ``np.load`` archive against the budget, from
        its header, and check the archive holds the bytes it needs."""
        name = key if key in npz.zip.namelist() else f"{key}.npy"
        try:
            info = npz.zip.getinfo(name)
            with npz.zip.open(info) as fh:
                shape, dtype, nbytes = npy_header(fh, self.path, f"member {key!r}")
                at = fh.tell()
        except KeyError:
            raise FormatError(self.path, f"a member {key!r}", "none") from None
        if info.file_size < at + nbytes:
            raise FormatError(self.path, f"member {key!r} of {at + nbytes} bytes (its "
                              f"shape {shape}, dtype {dtype})",
                              f"{info.file_size} bytes in the archive")
        self.take(nbytes, f"member {key!r} of shape {shape}")

    def npy(self, fh) -> np.ndarray:
        """The array of an open ``.npy`` file, its size checked against the file's."""
        shape, dtype, nbytes = npy_header(fh, self.path, "the file")
        if self.size < fh.tell() + nbytes:
            raise FormatError(self.path, f"an .npy file of {fh.tell() + nbytes} bytes (its "
                              f"shape {shape}, dtype {dtype})", f"{self.size} bytes")
        self.take(nbytes, f"an array of shape {shape}")
        fh.seek(0)
        return np.load(fh, allow_pickle=False)
