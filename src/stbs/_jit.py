"""numba's on-disk cache of the compiled kernels, for any user.

The kernels are compiled with ``cache=True`` so that a second run starts at once. numba
caches beside the module (``__pycache__``) or, when that folder is not writable (a
package installed by root), in the user's cache folder; when neither is writable (a
service account without a home, a read-only container) numba refuses to compile a cached
function at all, and importing the module fails. :func:`cache_enabled` checks this before
the kernels are decorated: it keeps numba's own choice when one works, else points
``numba.config.CACHE_DIR`` at a private folder in the temporary directory, else turns
caching off (the kernels then compile on each run). ``NUMBA_CACHE_DIR``, when set, is
always respected.
"""

from __future__ import annotations

import contextlib
import functools
import os
import stat
import tempfile

__all__ = ["cache_enabled"]


def _probe() -> None:  # a function for numba's cache locators to locate
    pass


def _numba_can_cache(py_file: str) -> bool:
    try:
        from numba.core import caching, config
    except ImportError:         # pragma: no cover - numba's layout changed: trust it
        return True
    if config.CACHE_DIR:
        return caching.UserProvidedCacheLocator.from_function(_probe, py_file) is not None
    return any(cls.from_function(_probe, py_file) is not None
               for cls in (caching.InTreeCacheLocator, caching.UserWideCacheLocator))


def _private_temp_folder() -> str | None:
    """``$TMPDIR/stbs-numba-UID``, made 0700 and checked to be ours (not a link)."""
    uid = os.getuid() if hasattr(os, "getuid") else 0
    path = os.path.join(tempfile.gettempdir(), f"stbs-numba-{uid}")
    with contextlib.suppress(OSError):
        os.mkdir(path, 0o700)
    try:
        st = os.lstat(path)
    except OSError:
        return None
    if not stat.S_ISDIR(st.st_mode) or (hasattr(os, "getuid") and st.st_uid != uid):
        return None
    return path


@functools.cache
def cache_enabled(py_file: str) -> bool:
    """Whether the kernels of the module ``py_file`` may be compiled with ``cache=True``
    (see the module docs); may set ``numba.config.CACHE_DIR``."""
    if _numba_can_cache(py_file):
        return True
    from numba.core import config

    if not os.environ.get("NUMBA_CACHE_DIR"):
        folder = _private_temp_folder()
        if folder is not None:
            config.CACHE_DIR = folder
            if _numba_can_cache(py_file):
                return True
            config.CACHE_DIR = ""
    return False
