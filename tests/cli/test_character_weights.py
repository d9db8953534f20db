"""stbs weights / stbs rig on real characters: open, multi-part surfaces with bones and
leaf tails outside the mesh get bone and endpoint weights; bone heat on a .mesh."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import stbs
from stbs.cli import main


def _read(path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")          # what the reader says about the file
        return stbs.io.read_rig(path)


def _check_E_along_bones(rig, *, min_bones, enough=10):
    """Where a bone holds most of a vertex near it (closer than half its length), e grows
    along it from ~0 to ~1."""
    sk, V = rig.skeleton, rig.V
    W, E = np.asarray(rig.W), np.asarray(rig.E)
    checked = 0
    for i in range(sk.n_bones):
        t = (V - sk.A[i]) @ (sk.B[i] - sk.A[i]) / sk.lengths[i] ** 2
        d = np.linalg.norm(V - (sk.A[i] + np.clip(t, 0, 1)[:, None] * (sk.B[i] - sk.A[i])),
                           axis=1)
        mine = (W[:, i] > 0.5) & (d < 0.5 * sk.lengths[i])
        start, stop = mine & (t > -0.1) & (t < 0.2), mine & (t > 0.8) & (t < 1.1)
        if start.sum() < enough or stop.sum() < enough:
            continue
        assert E[start, i].mean() < 0.35 < 0.65 < E[stop, i].mean(), sk.names[i]
        checked += 1
    assert checked >= min_bones


def test_weights_endpoint_bbw_on_a_character(shared_data, tmp_path, capsys):
    src = shared_data / "characters" / "gltf" / "CesiumMan.glb"
    out = tmp_path / "cesium-stbs.glb"
    assert main(["weights", str(src), "--endpoint", "bbw", "--tet-size", "0.04",
                 "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert "volume mesh" in err and "endpoint weights (bbw)" in err
    a, b = _read(src), _read(out)
    assert a.E is None and b.E is not None
    np.testing.assert_array_equal(b.V, a.V)
    np.testing.assert_array_equal(np.asarray(b.W), np.asarray(a.W))   # kept
    E = np.asarray(b.E)
    assert E.shape == (len(a.V), a.skeleton.n_bones) and E.min() >= 0 and E.max() <= 1
    _check_E_along_bones(b, min_bones=5)


def test_bone_and_endpoint_bbw_on_a_character_with_bones_outside(shared_data, tmp_path,
                                                                  capsys):
    # The Fox's root bone starts on the floor, far below the body: it is left out of
    # the volume where it is outside, with a warning naming it, never a dead end.
    src = shared_data / "characters" / "gltf" / "Fox.glb"
    out = tmp_path / "fox.npz"
    assert main(["weights", str(src), "--bone", "bbw", "--endpoint", "bbw", "--tet-size", "6",
                 "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert "warning: volume mesh:" in err and "'_rootJoint'" in err and "outside" in err
    rig = stbs.load_rig(out)
    W = np.asarray(rig.W)
    assert W.shape == (1728, 24) and rig.meta["bone"] == "bbw"
    np.testing.assert_allclose(W.sum(axis=1), 1.0, atol=1e-9)
    assert W.min() >= 0 and np.asarray(rig.E).min() >= 0 and np.asarray(rig.E).max() <= 1
    # the bones carry the parts of the fox the file's own weights give them, mostly
    ref = np.asarray(_read(src).W)
    assert (W.argmax(axis=1) == ref.argmax(axis=1)).mean() > 0.6
    _check_E_along_bones(rig, min_bones=3, enough=3)


@pytest.mark.slow
def test_xbot_bone_and_endpoint_bbw_at_the_default_size(shared_data, tmp_path, capsys):
    """The Mixamo robot: 95 closed parts, 28k vertices, 67 bones, finger tails outside."""
    src = shared_data / "characters" / "gltf" / "threejs_Xbot.glb"
    out = tmp_path / "xbot.glb"
    assert main(["weights", str(src), "--bone", "bbw", "--endpoint", "bbw",
                 "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert "LeftHandIndex4" in err                     # a fingertip tail, named
    rig = _read(out)
    W, E = np.asarray(rig.W), np.asarray(rig.E)
    np.testing.assert_allclose(W.sum(axis=1), 1.0, atol=1e-6)
    assert W.min() >= 0 and E.min() >= 0 and E.max() <= 1
    ref = np.asarray(_read(src).W)
    assert (W.argmax(axis=1) == ref.argmax(axis=1)).mean() > 0.6     # measured 0.69
    _check_E_along_bones(rig, min_bones=20)


def test_bone_heat_on_a_tetrahedral_mesh(shared_data, tmp_path):
    d = shared_data / "libigl-tutorial-data"
    out = tmp_path / "hand.npz"
    assert main(["rig", str(d / "hand.mesh"), str(d / "hand.tgf"), "--bone", "heat",
                 "--endpoint", "projection", "-o", str(out)]) == 0
    rig = stbs.load_rig(out)
    W = np.asarray(rig.W)
    assert W.shape == (7234, 20) and rig.T is not None
    np.testing.assert_allclose(W.sum(axis=1), 1.0, atol=1e-9)     # inside vertices too
    # the inside follows the nearest bone, as the surface does
    A, B = rig.skeleton.A, rig.skeleton.B
    t = np.clip(np.einsum("nbd,bd->nb", rig.V[:, None] - A, B - A)
                / rig.skeleton.lengths ** 2, 0, 1)
    near = np.linalg.norm(rig.V[:, None] - (A + t[..., None] * (B - A)), axis=2).argmin(axis=1)
    assert (W.argmax(axis=1) == near).mean() > 0.7


@pytest.mark.parametrize("extra, match", [
    (["--tet-size", "0"], "--tet-size: expected a positive number, got 0.0"),
    (["--tet-size", "1", "--tets", "conforming"], "--tet-size applies to --tets auto or winding"),
    (["--tets", "x.mesh"], "--tets 'x.mesh': a tetrahedra file applies when the bone weights"),
])
def test_weights_option_errors_exit_2_one_line(shared_data, tmp_path, capsys, extra, match):
    src = shared_data / "characters" / "gltf" / "CesiumMan.glb"
    assert main(["weights", str(src), "-o", str(tmp_path / "x.glb"), *extra]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and match in err[0] and "Traceback" not in err[0]
    assert not (tmp_path / "x.glb").exists()


def test_a_skeleton_wholly_outside_is_one_line(shared_data, tmp_path, capsys):
    d = shared_data / "libigl-tutorial-data"
    tgf = tmp_path / "away.tgf"
    tgf.write_text("1 900 900 900\n2 901 900 900\n#\n1 2\n#\n")
    assert main(["rig", str(d / "arm.obj"), str(tgf), "-o", str(tmp_path / "x.npz")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no joint or bone of the skeleton lies inside" in err[0]
