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


# Under CI ($CI set) a skip is a failure, with its reason: a skip there hides missing
# test data, a missing extra or tool that `make test` should have installed, or a
# docstring example that never runs. Expected failures (xfail) are left alone.
def _ci_failure(reason: str) -> str:
    return f"skipped under CI ($CI is set), which counts as a failure: {reason}"


def _skip_reason(rep) -> str:
    lr = rep.longrepr
    reason = str(lr[2]) if isinstance(lr, tuple) and len(lr) == 3 else str(lr)
    return reason.removeprefix("Skipped: ")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    rep = outcome.get_result()
    if os.environ.get("CI") and rep.skipped and not hasattr(rep, "wasxfail"):
        rep.outcome = "failed"
        rep.longrepr = _ci_failure(_skip_reason(rep))


@pytest.hookimpl(hookwrapper=True)
def pytest_make_collect_report(collector):
    outcome = yield
    rep = outcome.get_result()
    if os.environ.get("CI") and rep.skipped:  # a module-level skip or importorskip
        rep.outcome = "failed"
        rep.longrepr = _ci_failure(_skip_reason(rep))
