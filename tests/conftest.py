"""Shared fixtures."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from shared_data import data_dir


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """The shared third-party test data folder (``../shared/data`` or ``$STBS_DATA``).

    Skips the test when the folder is missing, except under CI (``$CI`` set),
    where a missing folder is a failure.
    """
    d = data_dir()
    if d is None or not d.is_dir():
        msg = "shared test data not found (set STBS_DATA)"
        if d is not None:
            msg += f": {d} is not a folder"
        if os.environ.get("CI"):
            pytest.fail(msg)
        pytest.skip(msg)
    return d
