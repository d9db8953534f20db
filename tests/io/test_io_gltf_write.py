"""glTF 2.0 out: stbs.io.write_gltf. Round trips, the Khronos validator on every file
written, clips that play as our lbs, baked morph targets equal to the Deformer."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from gltf_files import Reference

import stbs
from stbs import transforms as tf
from stbs.io import read_gltf, write_gltf
from stbs.io.gltf import GltfFile, quantize_weights, read_accessor
from stbs.shapes import bar

NODE_DIR = Path(__file__).resolve().parents[1] / "node"


def validate(*paths) -> list[dict]:
    """The Khronos glTF validator's reports (tests/node, installed by make test)."""
    node = shutil.which("node")
    assert node, "node is needed for the glTF validator (make test installs it)"
    assert (NODE_DIR / "node_modules" / "gltf-validator").is_dir(), (
        "npm ci --prefix tests/node (make test does)")
    out = subprocess.run([node, str(NODE_DIR / "validate.mjs"), *map(str, paths)],
                         capture_output=True, text=True, timeout=120, check=True)
    return [json.loads(line) for line in out.stdout.splitlines()]


@pytest.fixture(scope="module")
def rig():
    V, F, sk, W = bar(10, 3, 3)
    E = stbs.weights.projection(V, sk)
    return stbs.Rig(V=V, F=F, skeleton=sk, W=W, E=E)


@pytest.fixture(scope="module")
def clip(rig):
    sk = rig.skeleton
    R = tf.axis_angle_to_matrix(np.array([[0, 0, 1.0], [0, 1, 0]]), np.array([0.3, 0.9]))
    p1 = stbs.forward_kinematics(sk, rotations=R, stretch=[1, 1.4],
                                 twist=[0, 0, 1.5 * np.pi], translation=[0.2, 0, 0])
    p2 = stbs.forward_kinematics(sk, rotations=R.transpose(0, 2, 1), twist=[0, 2, -1])
    return stbs.Clip([(0.0, stbs.Pose.rest(sk)), (0.5, p1), (1.0, p2)], fps=8)


def _diag(V):
    return float(np.linalg.norm(np.ptp(V, axis=0)))


@pytest.mark.parametrize("ext", [".glb", ".gltf"])
def test_round_trip(tmp_path, rig, ext):
    path = tmp_path / f"bar{ext}"
    write_gltf(path, rig)
    back, clips = read_gltf(path)
    assert dict(clips) == {}
    np.testing.assert_array_equal(back.skeleton.parents, rig.skeleton.parents)
    np.testing.assert_allclose(back.V, rig.V, atol=1e-6 * _diag(rig.V))
    np.testing.assert_array_equal(back.F, rig.F)
    np.testing.assert_allclose(back.C, rig.C, atol=1e-6 * _diag(rig.V))
    np.testing.assert_array_equal(back.BE, rig.BE)
    assert back.skeleton.names == rig.skeleton.names
    top = stbs.skinning.top_k(rig.W, rig.E, max_influences=4, pad=(4,))
    W4 = np.zeros_like(rig.W)
    E4 = np.zeros_like(rig.W)
    rows = np.arange(len(rig.V))
    for c in range(4):
        W4[rows, top.idx[c]] += top.w[c]
        E4[rows, top.idx[c]] += np.where(top.w[c] > 0, top.e[c], 0)
    np.testing.assert_allclose(back.W, W4, atol=1 / 65535)
    on = back.W > 0
    np.testing.assert_allclose(back.E[on], E4[on], atol=1e-7)
    assert [r["errors"] for r in validate(path)] == [0]


def test_quantised_weights_sum_exactly(tmp_path, rig):
    rng = np.random.default_rng(3)
    w = rng.uniform(0, 1, (500, 4)) * (rng.uniform(size=(500, 4)) > 0.3)
    w[w.sum(1) == 0, 0] = 1
    q = quantize_weights(w)
    assert (q.sum(axis=1) == 65535).all()
    assert np.abs(q / 65535 - w / w.sum(1, keepdims=True)).max() < 1 / 65535
    path = tmp_path / "q.glb"
    write_gltf(path, rig)
    f = GltfFile(path)
    attrs = f.doc["meshes"][0]["primitives"][0]["attributes"]
    raw = read_accessor(f, attrs["WEIGHTS_0"], "w", floats=False)
    assert (raw.sum(axis=1) == 65535).all()
    J = read_accessor(f, attrs["JOINTS_0"], "j", floats=False)
    assert (J[raw == 0] == 0).all()


def test_a_clip_plays_as_our_lbs(tmp_path, rig, clip):
    path = tmp_path / "clip.glb"
    write_gltf(path, rig, clip)
    back, clips = read_gltf(path)
    played = clips["clip"]
    times = clip.sample_times()
    np.testing.assert_allclose(played.times, times - times[0], atol=1e-6)
    diag = _diag(rig.V)
    for t, (_, pose) in zip(times, played.keys, strict=True):
        # glTF skins rigidly: the clip's rotations and origins, stretch 1, no twist
        p = clip.pose(float(t))
        rigid = stbs.Pose(rig.skeleton, rotations=p.rotations, origins=p.origins)
        want = stbs.deform(rig.V, rig.skeleton, rigid, rig.W, method="lbs", max_influences=4)
        got = stbs.deform(back.V, back.skeleton, pose, back.W, method="lbs")
        assert np.abs(got - want).max() < 1e-4 * diag
        assert (pose.stretch == 1).all() and not pose.twist.any()
    assert [r["errors"] for r in validate(path)] == [0]


def _frames(rig, clip, method):
    dfm = stbs.Deformer(rig.V, rig.skeleton, rig.W, rig.E, method=method)
    return [dfm(clip.pose(float(t))) for t in clip.sample_times()]


def test_baked_frames_are_written_as_morph_targets(tmp_path, rig, clip):
    path = tmp_path / "baked.glb"
    frames = _frames(rig, clip, "stbs-dqs")
    write_gltf(path, rig, clip, bake="stbs-dqs", frames=frames)
    f = GltfFile(path)
    mesh = f.doc["meshes"][0]
    targets = mesh["primitives"][0]["targets"]
    times = clip.sample_times()
    assert len(targets) == len(times) and mesh["weights"] == [0.0] * len(times)
    assert f.doc["animations"][0]["name"] == "baked stbs-dqs"
    V32 = rig.V.astype(np.float32)
    for U, tgt in zip(frames, targets, strict=True):
        d = read_accessor(f, tgt["POSITION"], "target")
        np.testing.assert_allclose(V32 + d.astype(np.float32), U, atol=2e-6 * _diag(rig.V))
    # the weights channel shows frame k alone at its time
    anim = f.doc["animations"][0]
    out = read_accessor(f, anim["samplers"][0]["output"], "w").reshape(len(times), len(times))
    np.testing.assert_array_equal(out, np.eye(len(times)))
    # the stretch and twist are in the baked frames: far from what lbs gives
    lbs = stbs.deform(rig.V, rig.skeleton, clip.pose(0.5), rig.W, method="lbs")
    k = int(np.argmin(np.abs(times - 0.5)))
    baked = V32 + read_accessor(f, targets[k]["POSITION"], "t")
    assert np.abs(baked - lbs).max() > 0.05 * _diag(rig.V)
    assert [r["errors"] for r in validate(path)] == [0]


def test_bake_without_frames_skins_the_clip(tmp_path, rig, clip):
    """write_gltf(path, rig, clip, bake=METHOD): the clip's frames by that method."""
    write_gltf(tmp_path / "given.glb", rig, clip, bake="stbs-lbs",
               frames=_frames(rig, clip, "stbs-lbs"))
    write_gltf(tmp_path / "skinned.glb", rig, clip, bake="stbs-lbs")
    a, b = GltfFile(tmp_path / "given.glb"), GltfFile(tmp_path / "skinned.glb")
    ta, tb = a.doc["meshes"][0]["primitives"][0]["targets"], \
        b.doc["meshes"][0]["primitives"][0]["targets"]
    assert len(ta) == len(tb) == len(clip.sample_times())
    for x, y in zip(ta, tb, strict=True):
        np.testing.assert_allclose(read_accessor(b, y["POSITION"], "t"),
                                   read_accessor(a, x["POSITION"], "t"), atol=1e-6)
    with pytest.raises(ValueError, match="without frames= needs a clip"):
        write_gltf(tmp_path / "x.glb", rig, bake="lbs", times=[0, 1])


@pytest.fixture(scope="module")
def tree():
    """A rig of a hierarchical skeleton: legs and arms hang off their parents (offset
    children), a chain of connected bones up the spine."""
    C = np.array([[0, 0, 0], [0, 1, 0], [0, 2, 0], [0, 2.6, 0],
                  [0.3, 0, 0], [0.3, -1, 0], [-0.3, 0, 0], [-0.3, -1, 0],
                  [0.4, 1.8, 0], [1.4, 1.8, 0], [-0.4, 1.8, 0], [-1.4, 1.8, 0]], float)
    BE = [[0, 1], [1, 2], [2, 3], [4, 5], [6, 7], [8, 9], [10, 11]]
    sk = stbs.Skeleton(C, BE, names=["hips", "spine", "neck", "leg_l", "leg_r", "arm_l",
                                     "arm_r"], P=[-1, 0, 1, 0, 0, 1, 1])
    rng = np.random.default_rng(2)
    V = np.vstack([C[a] + t * (C[b] - C[a]) + 0.08 * rng.standard_normal((30, 3))
                   for a, b in BE for t in [rng.uniform(0, 1)]])
    W = rng.uniform(0, 1, (len(V), len(BE))) ** 6
    F = np.array([[i, i + 1, i + 2] for i in range(0, len(V) - 2, 3)])
    return stbs.Rig(V=V, F=F, skeleton=sk, W=W, E=stbs.weights.projection(V, sk))


def test_a_hierarchy_with_offset_children_round_trips_key_for_key(tmp_path, tree):
    # a clip without stretch and twist is written key for key, each bone's channels
    # with their own interpolation: the file plays as clip.pose(t) at any time
    sk = tree.skeleton
    rng = np.random.default_rng(5)
    k, b = 4, sk.n_bones
    times = np.array([0.0, 0.4, 1.1, 1.5])
    q = stbs.transforms.axis_angle_to_quat(rng.standard_normal((k, b, 3)),
                                           rng.uniform(-2, 2, (k, b)))
    D = 0.1 * rng.standard_normal((k, b, 3))
    modes = ["linear", "step", "cubic", "linear", "cubic", "step", "linear"]
    tan = (0.3 * rng.standard_normal((k, b, 4)), 0.3 * rng.standard_normal((k, b, 4)))
    dtan = (rng.standard_normal((k, b, 3)), rng.standard_normal((k, b, 3)))
    clip = stbs.Clip.from_local(sk, times, rotations=q, offsets=D, fps=10,
                                rotation_interpolation=modes, offset_interpolation=modes[::-1],
                                rotation_tangents=tan, offset_tangents=dtan)
    path = tmp_path / "tree.glb"
    write_gltf(path, tree, clip)
    back, clips = read_gltf(path)
    np.testing.assert_allclose(back.C, tree.C, atol=1e-6)
    np.testing.assert_array_equal(back.skeleton.parents, sk.parents)
    assert back.skeleton.names == sk.names
    played = clips["clip"]
    assert played.rotation_interpolation == modes
    assert played.offset_interpolation == modes[::-1]
    # between keys, and at the keys as the file stores them (float32: a STEP there
    # jumps at the stored time)
    t = np.concatenate([np.linspace(-0.2, 1.7, 77) + 0.0013, played.times])
    R0, O0, _, _ = clip.arrays(t)
    R1, O1, _, _ = played.arrays(t)
    np.testing.assert_allclose(R1, R0, atol=2e-6)
    np.testing.assert_allclose(O1, O0, atol=2e-6)
    # and as the glTF formula draws the file (an independent reader of its bytes)
    ref = Reference(path)
    dfm = stbs.Deformer(back.V, sk, back.W, method="lbs")
    for tt in t[::4]:
        want = ref.skin_at(0, float(tt))
        assert np.abs(dfm(clip.pose(float(tt))) - want).max() <= 1e-5 * _diag(want)
    report = validate(path)[0]
    assert (report["errors"], report["warnings"]) == (0, 0), report


def test_every_file_validates_with_no_warnings(tmp_path, rig, clip):
    paths = [tmp_path / "a.glb", tmp_path / "b.gltf", tmp_path / "c.glb"]
    write_gltf(paths[0], rig)
    write_gltf(paths[1], rig, clip)
    write_gltf(paths[2], rig, clip, bake="lbs", frames=_frames(rig, clip, "lbs"))
    reports = validate(*paths)
    assert [(r["errors"], r["warnings"]) for r in reports] == [(0, 0)] * 3, reports


def test_the_validator_catches_a_broken_file(tmp_path, rig):
    # the check above can fail: a file with an out-of-range index is an error
    path = tmp_path / "bad.gltf"
    write_gltf(path, rig)
    doc = json.loads(path.read_text())
    doc["meshes"][0]["primitives"][0]["indices"] = 999
    path.write_text(json.dumps(doc))
    assert validate(path)[0]["errors"] > 0


def test_errors(tmp_path, rig, clip):
    sk2 = stbs.Skeleton([[0, 0], [1, 0]], [[0, 1]])
    flat = stbs.Rig(V=[[0, 0.1], [1, 0.1], [1, -0.1]], F=[[0, 2, 1]], skeleton=sk2,
                    W=np.ones((3, 1)))
    with pytest.raises(ValueError, match="glTF holds 3D rigs"):
        write_gltf(tmp_path / "x.glb", flat)
    frames = [rig.V] * len(clip.sample_times())
    with pytest.raises(ValueError, match="bake needs a clip or times="):
        write_gltf(tmp_path / "x.glb", rig, bake="lbs", frames=frames)
    with pytest.raises(ValueError, match="bake must be one of"):
        write_gltf(tmp_path / "x.glb", rig, clip, bake="fast", frames=frames)
    with pytest.raises(ValueError, match="frames need bake="):
        write_gltf(tmp_path / "x.glb", rig, clip, frames=frames)
    with pytest.raises(ValueError, match=r"one mesh per time \(2\), got 3"):
        write_gltf(tmp_path / "x.glb", rig, bake="lbs", frames=frames[:3], times=[0, 1])
    with pytest.raises(ValueError, match="times must be finite and increasing"):
        write_gltf(tmp_path / "x.glb", rig, bake="lbs", frames=frames[:2], times=[1, 0])
    with pytest.raises(ValueError, match=r"each must have shape"):
        write_gltf(tmp_path / "x.glb", rig, bake="lbs", frames=[rig.V[:-1]], times=[0])
    other = stbs.Clip([(0.0, stbs.Pose.rest(stbs.Skeleton([[0, 0, 0], [0, 0, 1]], [[0, 1]])))])
    with pytest.raises(ValueError, match="clip must be of the rig's skeleton"):
        write_gltf(tmp_path / "x.glb", rig, other)
    with pytest.raises(ValueError, match="supported extensions are .gltf, .glb"):
        write_gltf(tmp_path / "x.obj", rig)
    assert not list(tmp_path.iterdir())


def test_the_four_heaviest_bones_by_hand(tmp_path):
    # six bones; ties among equal weights go to the lower bone index, the weights are
    # renormalised over the four kept and rounded to 16 bits summing to 65535
    C = [[float(i), 0.0, 0.0] for i in range(7)]
    sk = stbs.Skeleton(C, [[i, i + 1] for i in range(6)])
    W = np.array([[0.1, 0.2, 0.3, 0.2, 0.2, 0.0],
                  [0.0, 0.0, 0.0, 0.0, 0.5, 0.5],
                  [1.0, 0.0, 0.0, 0.0, 0.0, 0.0]])
    E = np.array([[0.9, 0.1, 0.2, 0.3, 0.4, 0.0],
                  [0.0, 0.0, 0.0, 0.0, 0.7, 0.8],
                  [0.5, 0.0, 0.0, 0.0, 0.0, 0.0]])
    rig = stbs.Rig(V=[[0, 0, 0], [1, 0, 0], [0, 1, 0.0]], F=[[0, 1, 2]], skeleton=sk, W=W, E=E)
    path = tmp_path / "ties.gltf"
    write_gltf(path, rig)
    f = GltfFile(path)
    attrs = f.doc["meshes"][0]["primitives"][0]["attributes"]
    assert read_accessor(f, attrs["JOINTS_0"], "j").tolist() == [
        [2, 1, 3, 4], [4, 5, 0, 0], [0, 0, 0, 0]]
    q = np.rint(read_accessor(f, attrs["WEIGHTS_0"], "w") * 65535).astype(int)
    assert q.tolist() == [[21845, 14564, 14563, 14563], [32768, 32767, 0, 0],
                          [65535, 0, 0, 0]]
    e = read_accessor(f, attrs["_ENDPOINT_WEIGHTS_0"], "e")
    np.testing.assert_allclose(e, [[0.2, 0.1, 0.3, 0.4], [0.7, 0.8, 0, 0], [0.5, 0, 0, 0]],
                               atol=1e-7)
