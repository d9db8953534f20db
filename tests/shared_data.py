"""Where the third-party test data lives: ``$STBS_DATA``, else ``../shared/data`` beside
the checkout. Test support only; the library takes paths from its users."""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["data_dir"]

#: Environment variable that points at the shared test data folder.
ENV_VAR = "STBS_DATA"


def data_dir() -> Path | None:
    """The shared test data folder, or None when it cannot be found.

    Returns
    -------
    Path or None
        ``$STBS_DATA`` when that variable is set and not empty (returned even if
        the folder does not exist, so a wrong setting shows up instead of being
        skipped over); else ``<repo>/../shared/data`` when that folder exists,
        where ``<repo>`` is the checkout holding this ``tests/`` folder; else None.
    """
    env = os.environ.get(ENV_VAR)
    if env:
        return Path(env).expanduser()
    repo = Path(__file__).resolve().parents[1]
    cand = repo.parent / "shared" / "data"
    return cand if cand.is_dir() else None
