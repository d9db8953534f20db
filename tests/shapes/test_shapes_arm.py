"""stbs.shapes.arm and the package's boundaries (public APIs only, nothing heavy)."""

import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import stbs
from shape_checks import assert_closed_outward, components
from stbs.geometry import winding_numbers
from stbs.meshing._geometry import triangle_angles
from stbs.shapes import Model, arm

SRC = Path(stbs.__file__).parent / "shapes"


@pytest.fixture(scope="module")
def full_arm() -> Model:
    return arm()


def test_arm_layout_and_hand(full_arm):
    m = full_arm
    assert isinstance(m, Model) and m.name == "arm" and m.dim == 3
    assert m.sk.names == ["upper", "fore", "hand"]
    assert np.all(np.abs(m.sk.axes[:, 0]) > 0.99)  # roughly along x
    wrist, axis, hand = m.extra["wrist"], m.extra["wrist_axis"], m.extra["hand"]
    assert np.array_equal(wrist, m.sk.C[2])
    assert np.allclose(axis, m.sk.axes[1])
    assert hand.shape == (m.V.shape[0],) and hand.dtype == bool
    assert np.array_equal(hand, (m.V - wrist) @ axis > 0)
    assert 0.05 < hand.mean() < 0.3
    # The thumb points to +z: the hand is lopsided that way.
    assert m.V[hand, 2].max() > 0.3 > -m.V[hand, 2].min()


@pytest.mark.parametrize("quick", [False, True], ids=["full", "quick"])
def test_arm_is_a_closed_surface_around_its_skeleton(full_arm, quick):
    m = arm(quick=True) if quick else full_arm
    V, F, sk = m.V, m.F, m.sk
    assert V.dtype == np.float64 and F.dtype == np.int64 and sk.dim == 3
    assert_closed_outward(V, F)
    assert components(V.shape[0], F) == 1
    assert np.degrees(triangle_angles(V, F)).min() > 5.0  # no slivers
    lo, hi = (1000, 3000) if quick else (3000, 8000)
    assert lo <= V.shape[0] <= hi
    t = np.linspace(0.0, 1.0, 25)
    X = (sk.A[:, None] + t[None, :, None] * (sk.B - sk.A)[:, None]).reshape(-1, 3)
    assert np.allclose(winding_numbers(X, V, F), 1.0, atol=1e-6)
    assert m.extra["sdf"](X).max() < -0.05
    assert np.abs(m.extra["sdf"](V)).max() < 1e-3  # vertices on the zero set


def test_arm_is_deterministic_and_checks_quick(full_arm):
    again = arm(quick=True)
    assert np.array_equal(again.V, arm(quick=True).V)
    assert again.V.shape[0] < 0.6 * full_arm.V.shape[0]
    assert repr(again).startswith("Model('arm', ") and "3 bones, 3-D" in repr(again)
    with pytest.raises(ValueError, match="quick must be True or False, got 'yes'"):
        arm(quick="yes")
    with pytest.raises(TypeError):
        arm(True)  # quick is keyword-only


def test_an_arm_rig_twists_with_stbs(full_arm):
    # The package docstring's example, checked: a wrist twist spread along the forearm.
    m = arm(quick=True)
    W = stbs.bone_heat(m.V, m.F, m.sk)
    E = stbs.endpoint_weights(m.V, m.sk, method="projection")
    pose = stbs.forward_kinematics(m.sk, twist=[0, 0, np.pi / 2, 0])
    U = stbs.deform(m.V, m.sk, pose, W, E)
    far = m.V[:, 0] > 3.2   # the hand's tip turns by the whole twist about x
    R = np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]], float)
    np.testing.assert_allclose(U[far], m.V[far] @ R.T, atol=1e-4)
    near = m.V[:, 0] < 0.5  # the upper arm does not move
    np.testing.assert_allclose(U[near], m.V[near], atol=1e-4)


def test_shapes_use_public_apis_only():
    for path in SRC.glob("*.py"):
        text = path.read_text()
        for mod in re.findall(r"^\s*(?:from|import)\s+(\S+)", text, flags=re.M):
            assert not re.match(r"(stbs|\.\.)\.?(demo|cli)\b", mod), (path.name, mod)
            # A private module of another subpackage (stbs.meshing._x, ..io._x).
            assert not re.match(r"(stbs\.|\.\.)\w+\._", mod), (path.name, mod)


def test_importing_shapes_loads_no_front_end_and_no_optional_library():
    code = ("import sys, stbs.shapes; bad = [m for m in sys.modules if m.split('.')[0] in "
            "('matplotlib', 'PIL', 'numba') or m.startswith(('stbs.demo', 'stbs.cli'))]; "
            "print(bad)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert out.strip() == "[]"
