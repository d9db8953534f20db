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


def test_subpackages_are_attributes_loaded_on_first_use():
    code = ("import sys, stbs; a = 'stbs.geometry' in sys.modules; g = stbs.geometry; "
            "print(a, 'stbs.geometry' in sys.modules, g.__name__, 'shapes' in dir(stbs))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "True", "stbs.geometry", "True"]


def test_design_names():
    # DESIGN §5: the names users rely on, where the contract puts them
    import stbs.io

    for name in ("Skeleton", "Pose", "forward_kinematics", "deform", "Deformer", "bone_weights",
                 "BBWSolver", "endpoint_weights", "load_rig", "save_rig", "build_rig", "Rig"):
        assert callable(getattr(stbs, name)), name
    for name in ("read_pose", "write_pose", "load_rig", "save_rig"):
        assert callable(getattr(stbs.io, name)), name
    assert stbs.Rig is stbs.rig.Rig and stbs.build_rig is stbs.rig.build_rig
