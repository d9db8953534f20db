"""Baking one motion on one rig: stbs.bake and stbs animate."""

from __future__ import annotations

import numpy as np
import pytest
from bake_fixtures import arm_bvh, arm_rig, clip_json

import stbs
from stbs.bake import bake, bake_frames, export, frame_times, load_motion
from stbs.cli import main


@pytest.fixture(scope="module")
def rig():
    return arm_rig()


def test_npz_frames_are_the_deformer_frames(tmp_path, rig):
    clip = stbs.io.read_clip(clip_json(tmp_path / "c.json", rig), rig.skeleton)
    out = bake(rig, clip, tmp_path / "out.npz", method="stbs-dqs")
    z = np.load(out.path)
    times = clip.sample_times()
    assert z["U"].shape == (len(times), len(rig.V), 3) and z["U"].dtype == np.float32
    np.testing.assert_array_equal(z["times"], times)
    dfm = stbs.Deformer(rig.V, rig.skeleton, rig.W, rig.E, method="stbs-dqs")
    for k, t in enumerate(times):
        np.testing.assert_allclose(z["U"][k], dfm(clip.pose(float(t))), atol=1e-5)
    assert str(z["method"]) == "stbs-dqs" and out.frames == len(times)
    assert 0 < out.skinning_s <= out.total_s


def test_frames_slices_the_sampled_grid(rig, tmp_path):
    clip = stbs.io.read_clip(clip_json(tmp_path / "c.json", rig), rig.skeleton)
    grid = clip.sample_times()                       # 0, 0.1, ..., 1.0
    np.testing.assert_array_equal(frame_times(clip, frames="2:9:3"), grid[2:9:3])
    np.testing.assert_array_equal(frame_times(clip, frames="-1"), grid[[-1]])
    np.testing.assert_array_equal(frame_times(clip, fps=4), [0, 0.25, 0.5, 0.75, 1.0])
    for bad, match in (("x", "A:B:STEP"), ("::0", "STEP must not be 0"), ("50", "outside"),
                       ("5:2", "selects none")):
        with pytest.raises(ValueError, match=match):
            frame_times(clip, frames=bad)


def test_folder_and_glb_outputs(tmp_path, rig):
    clip = stbs.io.read_clip(clip_json(tmp_path / "c.json", rig), rig.skeleton)
    folder = bake(rig, clip, tmp_path / "frames", frames="0:4", mesh_format=".ply")
    files = sorted(p.name for p in folder.path.iterdir())
    assert files == [f"frame_{k:05d}.ply" for k in range(4)]
    m = stbs.io.read_mesh(folder.path / "frame_00003.ply")
    dfm = stbs.Deformer(rig.V, rig.skeleton, rig.W, rig.E, method="stbs-dqs")
    np.testing.assert_allclose(m.V, dfm(clip.pose(0.3)), atol=1e-5)
    with pytest.raises(ValueError, match="exists and is not empty"):
        bake(rig, clip, folder.path)
    glb = bake(rig, clip, tmp_path / "baked.glb", frames="::2", method="stbs-lbs")
    f = stbs.io.gltf.GltfFile(glb.path)
    targets = f.doc["meshes"][0]["primitives"][0]["targets"]
    assert len(targets) == 6
    d = stbs.io.gltf.read_accessor(f, targets[5]["POSITION"], "t")
    dfm = stbs.Deformer(rig.V, rig.skeleton, rig.W, rig.E, method="stbs-lbs")
    np.testing.assert_allclose(rig.V + d, dfm(clip.pose(1.0)), atol=1e-5)
    anim = f.doc["animations"][0]
    assert anim["name"] == "baked stbs-lbs"
    t = stbs.io.gltf.read_accessor(f, anim["samplers"][0]["input"], "t").ravel()
    np.testing.assert_allclose(t, [0, 0.2, 0.4, 0.6, 0.8, 1.0], atol=1e-6)
    with pytest.raises(ValueError, match="expected .npz, .glb, .gltf or a folder"):
        bake(rig, clip, tmp_path / "x.obj")


def test_a_bvh_motion_is_retargeted(tmp_path, rig):
    clip = load_motion(arm_bvh(tmp_path / "wave.bvh"), rig)
    assert len(clip.keys) == 30 and clip.fps == pytest.approx(25)
    # the elbow's roll is spread along the forearm: the elbow bone's end twist grows
    tw = np.array([p.twist[1, 1] for _, p in clip.keys])
    np.testing.assert_allclose(np.degrees(tw), 6 * np.arange(30), atol=1e-6)
    joint = load_motion(tmp_path / "wave.bvh", rig, twist="joint")
    assert not any(p.twist.any() for _, p in joint.keys)


def test_stbs_animate(tmp_path, rig, capsys):
    rig_path = tmp_path / "arm.npz"
    stbs.save_rig(rig_path, rig)
    bvh = arm_bvh(tmp_path / "wave.bvh")
    out = tmp_path / "wave.npz"
    assert main(["animate", str(rig_path), "--motion", str(bvh), "--frames", "0:30:3",
                 "-o", str(out)]) == 0
    cap = capsys.readouterr()
    assert "frames/s" in cap.err and cap.out.startswith(f"wrote {out}: 10 frames")
    U = np.load(out)["U"]
    assert U.shape == (10, len(rig.V), 3) and np.isfinite(U).all()
    clip = load_motion(bvh, rig)
    want = stbs.deform(rig.V, rig.skeleton, clip.pose(clip.sample_times()[9]), rig.W, rig.E)
    np.testing.assert_allclose(U[3], want, atol=1e-5)
    for args, match in (([str(rig_path), "-o", str(out)], "give --motion"),
                        ([str(rig_path), "--motion", str(bvh), "-o", str(tmp_path / "x.txt")],
                         "expected .npz, .glb, .gltf or a folder"),
                        ([str(rig_path), "--motion", str(tmp_path / "none.bvh"), "-o",
                          str(tmp_path / "n.npz")], "not found"),
                        ([str(rig_path), "--motion", str(bvh), "-o", str(out), "--workers",
                          "2"], "--workers and --scheduler apply to --manifest")):
        assert main(["animate", *args]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and match in err[0], err
    assert not (tmp_path / "n.npz").exists()


def test_stbs_export(tmp_path, rig, capsys):
    rig_path = tmp_path / "arm.npz"
    stbs.save_rig(rig_path, rig)
    clip = clip_json(tmp_path / "c.json", rig)
    assert main(["export", str(rig_path), "-o", str(tmp_path / "a.glb")]) == 0
    assert main(["export", str(rig_path), "--clip", str(clip), "--bake", "stbs-dqs",
                 "-o", str(tmp_path / "b.gltf")]) == 0
    back = stbs.io.read_rig(tmp_path / "a.glb")
    np.testing.assert_allclose(back.V, rig.V, atol=1e-6)
    capsys.readouterr()
    assert main(["export", str(rig_path), "--bake", "lbs", "-o", str(tmp_path / "c.glb")]) == 2
    assert "--bake needs --clip" in capsys.readouterr().err
    assert main(["export", str(rig_path), "-o", str(tmp_path / "c.obj")]) == 2
    assert "expected .glb, .gltf, .usda, .usdc or .usd" in capsys.readouterr().err


def _long_clip(path, rig, seconds=3333.0):
    """A two-key clip whose last key is ``seconds`` in: at its 10 fps, ~33,000 frames."""
    sk = rig.skeleton
    stbs.io.write_clip(path, stbs.Clip([(0.0, stbs.Pose.rest(sk)),
                                        (seconds, stbs.Pose.rest(sk))], fps=10))
    return path


def test_frames_are_limited_before_any_work(rig, tmp_path, capsys, monkeypatch):
    """A tiny clip file spanning an hour cannot make a bake allocate gigabytes: the
    frames (times vertices) are checked against the limit before anything is made."""
    import stbs.bake.core as core

    n = len(rig.V)
    assert core.frame_limit(8300) == core.MAX_BAKE_BYTES // (12 * 8300) < 33_331
    assert core.frame_limit(1) == core.MAX_BAKE_FRAMES == 36_000
    assert core.frame_limit(10**9, max_frames=7) == 7
    with pytest.raises(ValueError, match="max_frames"):
        core.frame_limit(n, max_frames=0)
    stbs.save_rig(tmp_path / "rig.npz", rig)
    motion = _long_clip(tmp_path / "long.json", rig)
    out = tmp_path / "out.npz"
    # the rig's frames of the whole clip would not fit in the bytes allowed
    monkeypatch.setattr(core, "MAX_BAKE_BYTES", 12 * n * 1000)
    capsys.readouterr()
    assert main(["animate", str(tmp_path / "rig.npz"), "--motion", str(motion),
                 "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "33331 frames to bake" in err[0] and "--max-frames" in err[0]
    assert "at most 1000 are baked" in err[0] and not out.exists()
    # an explicit limit, or fewer frames, is the way through
    assert main(["animate", str(tmp_path / "rig.npz"), "--motion", str(motion),
                 "-o", str(out), "--frames", "0:900"]) == 0
    assert np.load(out)["U"].shape == (900, n, 3)
    assert main(["animate", str(tmp_path / "rig.npz"), "--motion", str(motion), "-o",
                 str(tmp_path / "o2.npz"), "--frames", "0:30", "--max-frames", "20"]) == 2
    assert "at most 20 are baked" in capsys.readouterr().err


def test_an_hour_at_a_huge_fps_is_refused_before_sampling(rig, tmp_path):
    clip = stbs.io.read_clip(_long_clip(tmp_path / "long.json", rig), rig.skeleton)
    with pytest.raises(ValueError, match="at most 100000 are sampled"):
        frame_times(clip, fps=1e6)
    with pytest.raises(ValueError, match="are sampled"):
        clip.sample_times(1e300)


def test_bake_frames_are_the_deformer_frames(tmp_path, rig):
    clip = stbs.io.read_clip(clip_json(tmp_path / "c.json", rig), rig.skeleton)
    times = clip.sample_times()[[0, 4, 7]]
    U = bake_frames(rig, clip, times, method="dqs")
    assert U.shape == (3, len(rig.V), 3) and U.dtype == np.float64
    dfm = stbs.Deformer(rig.V, rig.skeleton, rig.W, rig.E, method="dqs")
    for k, t in enumerate(times):
        np.testing.assert_array_equal(U[k], dfm(clip.pose(float(t))))
    assert len(bake_frames(rig, clip, method="lbs")) == len(clip.sample_times())
    with pytest.raises(ValueError, match="method must be one of"):
        bake_frames(rig, clip, method="fast")


def test_export_bakes_the_clip_into_the_file(tmp_path, rig):
    clip = stbs.io.read_clip(clip_json(tmp_path / "c.json", rig), rig.skeleton)
    path = tmp_path / "arm.glb"
    export(path, rig, clip, bake="stbs-dqs")
    f = stbs.io.gltf.GltfFile(path)
    targets = f.doc["meshes"][0]["primitives"][0]["targets"]
    dfm = stbs.Deformer(rig.V, rig.skeleton, rig.W, rig.E, method="stbs-dqs")
    times = clip.sample_times()
    assert len(targets) == len(times)
    for k in (0, len(times) // 2, len(times) - 1):
        d = stbs.io.gltf.read_accessor(f, targets[k]["POSITION"], "t")
        np.testing.assert_allclose(rig.V + d, dfm(clip.pose(float(times[k]))), atol=1e-5)
    export(tmp_path / "plain.gltf", rig, clip)          # no bake: the joints move
    doc = stbs.io.gltf.GltfFile(tmp_path / "plain.gltf").doc
    assert "targets" not in doc["meshes"][0]["primitives"][0]
    assert doc["animations"][0]["name"] == "clip"
    with pytest.raises(ValueError, match="bake needs a clip"):
        export(tmp_path / "x.glb", rig, bake="lbs")
    with pytest.raises(ValueError, match="method must be one of"):
        export(tmp_path / "x.glb", rig, clip, bake="fast")
    with pytest.raises(ValueError, match="expected a path ending in .gltf, .glb"):
        export(tmp_path / "x.obj", rig, clip, bake="lbs")
    assert not list(tmp_path.glob("x.*"))
