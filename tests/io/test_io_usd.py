"""OpenUSD out: stbs.io.write_usd. UsdSkel's own skinning of the file equals ours; the baked
points cache is the Deformer's; USD's validators report nothing."""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Usd, UsdGeom, UsdSkel, UsdValidation

import stbs
from stbs import transforms as tf
from stbs.cli import main
from stbs.io import write_usd
from stbs.shapes import bar


@pytest.fixture(scope="module")
def rig():
    V, F, sk, W = bar(10, 3, 3)
    return stbs.Rig(V=V, F=F, skeleton=sk, W=W, E=stbs.weights.projection(V, sk))


@pytest.fixture(scope="module")
def clip(rig):
    sk = rig.skeleton
    R = tf.axis_angle_to_matrix(np.array([[0, 0, 1.0], [0, 1, 0]]), np.array([0.5, 1.1]))
    p1 = stbs.forward_kinematics(sk, rotations=R, stretch=[1, 1.4], twist=[0, 0, 2.5],
                                 translation=[0.3, 0, 0])
    return stbs.Clip([(0.0, stbs.Pose.rest(sk)), (1.0, p1)], fps=5)


def _usd_skinned(path, frame):
    stage = Usd.Stage.Open(str(path))
    cache = UsdSkel.Cache()
    root = UsdSkel.Root(stage.GetPrimAtPath("/Rig"))
    cache.Populate(root, Usd.PrimDefaultPredicate)
    skel_q = cache.GetSkelQuery(UsdSkel.Skeleton(stage.GetPrimAtPath("/Rig/Skeleton")))
    skin_q = cache.GetSkinningQuery(stage.GetPrimAtPath("/Rig/Mesh"))
    xforms = skel_q.ComputeSkinningTransforms(frame)
    pts = UsdGeom.Mesh(stage.GetPrimAtPath("/Rig/Mesh")).GetPointsAttr().Get(frame)
    assert skin_q.ComputeSkinnedPoints(xforms, pts, frame)
    return np.array(pts, dtype=np.float64), stage


@pytest.mark.parametrize("skinning, method", [("lbs", "lbs"), ("dqs", "dqs")])
def test_usd_skins_the_clip_as_we_do(tmp_path, rig, clip, skinning, method):
    path = tmp_path / f"arm-{skinning}.usda"
    write_usd(path, rig, clip, skinning=skinning)
    diag = float(np.linalg.norm(np.ptp(rig.V, axis=0)))
    times = clip.sample_times()
    for k, t in enumerate(times):
        p = clip.pose(float(t))
        rigid = stbs.Pose(rig.skeleton, rotations=p.rotations, origins=p.origins)
        want = stbs.deform(rig.V, rig.skeleton, rigid, rig.W, method=method, max_influences=4)
        got, stage = _usd_skinned(path, k)
        assert np.abs(got - want).max() < 1e-4 * diag, (k, np.abs(got - want).max())
    assert stage.GetTimeCodesPerSecond() == 5 and stage.GetEndTimeCode() == len(times) - 1


def _frames(rig, clip, method):
    dfm = stbs.Deformer(rig.V, rig.skeleton, rig.W, rig.E, method=method)
    return [dfm(clip.pose(float(t))) for t in clip.sample_times()]


def test_the_baked_points_cache(tmp_path, rig, clip):
    path = tmp_path / "baked.usdc"
    frames = _frames(rig, clip, "stbs-dqs")
    write_usd(path, rig, clip, bake="stbs-dqs", frames=frames)
    stage = Usd.Stage.Open(str(path))
    baked = UsdGeom.Mesh(stage.GetPrimAtPath("/Baked")).GetPointsAttr()
    assert stage.GetPrimAtPath("/Baked").GetCustomDataByKey("stbs:method") == "stbs-dqs"
    for k, U in enumerate(frames):
        np.testing.assert_allclose(np.array(baked.Get(k)), U, atol=1e-5)
    E = UsdGeom.PrimvarsAPI(stage.GetPrimAtPath("/Rig/Mesh")).GetPrimvar(
        "stbs:endpointWeights")
    assert E.GetElementSize() == 4 and len(E.Get()) == 4 * len(rig.V)


def test_usd_validators_find_nothing(tmp_path, rig, clip):
    ctx = UsdValidation.ValidationContext(
        UsdValidation.ValidationRegistry().GetOrLoadAllValidators())
    baked = {"clip": clip, "bake": "lbs", "frames": _frames(rig, clip, "lbs")}
    for name, kw in (("a.usda", {}), ("b.usdc", baked),
                     ("c.usd", {"clip": clip})):
        write_usd(tmp_path / name, rig, **kw)
        assert list(ctx.Validate(Usd.Stage.Open(str(tmp_path / name)))) == [], name


def test_the_validators_catch_a_broken_binding(tmp_path, rig):
    # the check above can fail: a mesh bound to no skeleton is reported
    path = tmp_path / "bad.usda"
    write_usd(path, rig)
    stage = Usd.Stage.Open(str(path))
    stage.GetPrimAtPath("/Rig/Mesh").RemoveAPI(UsdSkel.BindingAPI)
    ctx = UsdValidation.ValidationContext(
        UsdValidation.ValidationRegistry().GetOrLoadAllValidators())
    assert list(ctx.Validate(stage)) != []


def test_stbs_export_usd_and_errors(tmp_path, rig, clip, capsys):
    rp = tmp_path / "arm.npz"
    stbs.save_rig(rp, rig)
    cp = tmp_path / "clip.json"
    stbs.io.write_clip(cp, clip)
    assert main(["export", str(rp), "--clip", str(cp), "--bake", "stbs-lbs", "--skinning",
                 "dqs", "-o", str(tmp_path / "arm.usda")]) == 0
    stage = Usd.Stage.Open(str(tmp_path / "arm.usda"))
    b = UsdSkel.BindingAPI(stage.GetPrimAtPath("/Rig/Mesh"))
    assert b.GetSkinningMethodAttr().Get() == "dualQuaternion"
    capsys.readouterr()
    assert main(["export", str(rp), "--skinning", "dqs", "-o", str(tmp_path / "a.glb")]) == 2
    assert "--skinning applies to OpenUSD" in capsys.readouterr().err
    frames = [rig.V] * len(clip.sample_times())
    with pytest.raises(ValueError, match="bake needs a clip"):
        write_usd(tmp_path / "x.usda", rig, bake="lbs", frames=frames)
    with pytest.raises(ValueError, match="frames need bake="):
        write_usd(tmp_path / "x.usda", rig, clip, frames=frames)
    with pytest.raises(ValueError, match="one mesh per sampled time"):
        write_usd(tmp_path / "x.usda", rig, clip, bake="lbs", frames=frames[1:])
    with pytest.raises(ValueError, match="supported extensions are .usda, .usdc, .usd"):
        write_usd(tmp_path / "x.obj", rig)
    assert not (tmp_path / "x.usda").exists()


def test_joint_paths_of_a_chain_thousands_deep():
    """Joint paths are built without recursion: a 3000-bone chain (a capture's deep
    hierarchy) gets its paths, each its parent's plus its own name."""
    from stbs.io.usd import _joint_paths

    n = 3000
    parents = np.arange(-1, n - 1)
    paths = _joint_paths([f"j{i}" for i in range(n)], parents)
    assert paths[0] == "j0" and paths[2] == "j0/j1/j2"
    assert all(paths[i] == f"{paths[i - 1]}/j{i}" for i in range(1, n))
    shuffled = _joint_paths(["a", "b", "c"], np.array([2, 0, -1]))
    assert shuffled == ["c/a", "c/a/b", "c"]
