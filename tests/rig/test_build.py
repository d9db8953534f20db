"""stbs.build_rig: the rig pipeline as a library function (what stbs rig runs)."""

import numpy as np
import pytest

import stbs
from rigs import u_shape


def test_2d_bbw_rig_keeps_the_users_mesh_and_gives_valid_weights():
    V, F, sk = u_shape()
    stages = []
    rig = stbs.build_rig(V, sk, F=F, progress=lambda s, d, t: stages.append((s, d, t)))
    assert rig.skeleton is sk
    np.testing.assert_array_equal(rig.V, V)
    np.testing.assert_array_equal(rig.F, F)
    W, E = np.asarray(rig.W), np.asarray(rig.E)
    assert W.shape == E.shape == (len(V), 3)
    np.testing.assert_allclose(W.sum(axis=1), 1.0, atol=1e-9)
    assert W.min() >= -1e-9 and E.min() >= -1e-9 and E.max() <= 1 + 1e-9
    # each bone dominates on its own part of the U; e grows along the base bone
    base = (V[:, 1] < 1) & (V[:, 0] > 0.8) & (V[:, 0] < 2.2)
    assert np.mean(W[base].argmax(axis=1) == 0) > 0.9
    mid = base & (np.abs(V[:, 1] - 0.5) < 0.05)
    order = np.argsort(V[mid, 0])
    assert np.all(np.diff(E[mid, 0][order]) > -1e-6)
    assert rig.meta == {"bone": "bbw", "endpoint": "bbw"}
    labels = [s for s, d, t in stages if t == 0]
    assert labels == ["triangulate (bones inside)", "bone weights (bbw)",
                      "endpoint weights (bbw)"]
    assert ("bone weights (bbw)", 3, 3) in stages


def test_the_cli_and_the_library_give_the_same_rig(tmp_path):
    from stbs.cli import main
    from stbs.io import write_mesh, write_tgf

    V, F, sk = u_shape()
    write_mesh(tmp_path / "u.obj", V, F)
    write_tgf(tmp_path / "u.tgf", sk.C, sk.BE)
    assert main(["rig", str(tmp_path / "u.obj"), str(tmp_path / "u.tgf"), "-o",
                 str(tmp_path / "u.npz"), "--endpoint", "bbw-joints"]) == 0
    cli = stbs.load_rig(tmp_path / "u.npz")
    lib = stbs.build_rig(V, stbs.Skeleton(sk.C, sk.BE), F=F, endpoint="bbw-joints")
    np.testing.assert_allclose(np.asarray(cli.W), np.asarray(lib.W), atol=1e-12)
    np.testing.assert_allclose(np.asarray(cli.E), np.asarray(lib.E), atol=1e-12)


def test_given_bone_weights_are_kept_and_only_E_is_computed():
    V, F, sk = u_shape()
    W = stbs.bone_weights(V, sk, F=F)
    rig = stbs.build_rig(V, sk, F=F, W=W, endpoint="projection")
    assert rig.W is not None and np.array_equal(np.asarray(rig.W), np.asarray(W))
    np.testing.assert_allclose(rig.E, stbs.endpoint_weights(V, sk, method="projection"))
    assert rig.meta["bone"] == "given"


def test_3d_heat_rig_on_a_real_surface(shared_data):
    from stbs.io import read_mesh, read_skeleton

    d = shared_data / "libigl-tutorial-data"
    m = read_mesh(d / "arm.obj")
    sk = read_skeleton(d / "arm.tgf", dim=3)
    rig = stbs.build_rig(m.V, sk, F=m.F, bone="heat", endpoint="projection")
    W = np.asarray(rig.W)
    np.testing.assert_allclose(W.sum(axis=1), 1.0, atol=1e-9)
    assert rig.T is None and rig.F.shape == m.F.shape
    # the bone nearest a vertex mostly carries it (bone heat's point of departure)
    assert np.mean(W.argmax(axis=1) == _nearest_bone(m.V, sk)) > 0.8


def _nearest_bone(V, sk):
    A, B = sk.A, sk.B
    t = np.clip(np.einsum("nbi,bi->nb", V[:, None] - A, B - A) / sk.lengths ** 2, 0, 1)
    P = A + t[..., None] * (B - A)
    return np.linalg.norm(V[:, None] - P, axis=2).argmin(axis=1)


@pytest.mark.parametrize("kw, exc, match", [
    (dict(bone="paint"), ValueError, "bone must be one of bbw, heat, got 'paint'"),
    (dict(endpoint="x"), ValueError, "endpoint must be one of bbw, bbw-joints, heat"),
    (dict(bone="heat"), ValueError, "bone='heat' needs a 3D triangle surface"),
    (dict(endpoint="heat"), ValueError, "endpoint='heat' needs a 3D triangle surface"),
    (dict(tol=0.0), ValueError, "tol must be a positive number"),
    (dict(F=None), ValueError, "a 2D rig needs triangles F"),
    (dict(clip_skeleton=True, remesh=False), ValueError, "clip_skeleton applies"),
    (dict(F=[[0, 1, 99999]]), ValueError, "F must hold vertex indices"),
])
def test_bad_arguments_name_themselves(kw, exc, match):
    V, F, sk = u_shape()
    args = dict(F=F)
    args.update(kw)
    with pytest.raises(exc, match=match):
        stbs.build_rig(V, sk, **args)


def test_wrong_skeleton_argument():
    V, F, sk = u_shape()
    with pytest.raises(TypeError, match="sk must be a stbs.Skeleton, got ndarray"):
        stbs.build_rig(V, sk.C, F=F)
    with pytest.raises(ValueError, match=r"V must have shape \(\d+, 2\) to match the 2D"):
        stbs.build_rig(np.c_[V, V[:, :1]], sk, F=F)


def test_inputs_are_checked_before_any_work(monkeypatch):
    import stbs.weights as weights

    def no_work(*a, **kw):
        raise AssertionError("weights were computed before the inputs were checked")

    monkeypatch.setattr(weights, "bone_weights", no_work)
    monkeypatch.setattr(weights, "endpoint_weights", no_work)
    V, F, sk = u_shape()
    with pytest.raises(ValueError, match="endpoint='heat' needs a 3D triangle surface"):
        stbs.build_rig(V, sk, F=F, endpoint="heat")
    with pytest.raises(ValueError, match=r"W must have shape \(\d+, 3\)"):
        stbs.build_rig(V, sk, F=F, W=np.ones((len(V), 2)), endpoint="projection")
