"""The package surface: DESIGN §5 names resolve, and importing stbs stays light."""

import subprocess
import sys

import pytest

import stbs


@pytest.mark.parametrize("name", [n for n in stbs.__all__ if n != "__version__"])
def test_exported_names_resolve(name):
    assert getattr(stbs, name) is not None


def test_unknown_name():
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        stbs.nope  # noqa: B018


def test_import_does_not_load_numba_or_scipy():
    code = "import sys, stbs; print('numba' in sys.modules, 'scipy' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "False"]
