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
# docstring example that never runs. Expected failures (xfail) are left alone. A
# plugin rather than hooks here, so that it covers the doctests of src/stbs and
# README.md too (a conftest's own hooks see only the items below its folder).
class _SkipsFailUnderCI:
    @staticmethod
    def _fail(rep) -> None:
        lr = rep.longrepr
        reason = str(lr[2]) if isinstance(lr, tuple) and len(lr) == 3 else str(lr)
        rep.outcome = "failed"
        rep.longrepr = ("skipped under CI ($CI is set), which counts as a failure: "
                        + reason.removeprefix("Skipped: "))

    @pytest.hookimpl(hookwrapper=True)
    def pytest_runtest_makereport(self, item, call):
        rep = (yield).get_result()
        if rep.skipped and not hasattr(rep, "wasxfail"):
            self._fail(rep)

    @pytest.hookimpl(hookwrapper=True)
    def pytest_make_collect_report(self, collector):
        rep = (yield).get_result()
        if rep.skipped:  # a module-level skip or importorskip
            self._fail(rep)


def pytest_configure(config):
    if os.environ.get("CI") and not config.pluginmanager.has_plugin("stbs-ci-skips"):
        config.pluginmanager.register(_SkipsFailUnderCI(), "stbs-ci-skips")
