"""``stbs fit`` through the command line: each job on a small arm and its examples,
its outputs read back and checked against the truth they were made from, and every bad
input one line on stderr with exit status 2."""

from __future__ import annotations

import numpy as np
import pytest

import stbs
from stbs.bench.animate import arm_case
from stbs.cli import main
from stbs.io import load_rig, read_clip, save_rig, write_clip


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def _poses(sk, count, seed=0):
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(count):
        axes = rng.normal(size=(sk.n_bones, 3))
        ang = rng.uniform(-0.6, 0.6, sk.n_bones)
        R = stbs.transforms.axis_angle_to_matrix(axes / np.linalg.norm(axes, axis=1)[:, None],
                                                 ang)
        twist = rng.uniform(-4.0, 4.0, sk.n_joints)        # past 2 pi at times
        out.append(stbs.forward_kinematics(sk, rotations=R, stretch=rng.uniform(0.7, 1.4,
                                                                               sk.n_bones),
                                           twist=twist))
    return out


@pytest.fixture(scope="module")
def arm(tmp_path_factory):
    """A 3-bone arm (about 600 vertices), 12 example poses, their stbs-lbs meshes."""
    tmp = tmp_path_factory.mktemp("fit-cli")
    rig = arm_case(vertices=600, frames=2)[0]
    poses = _poses(rig.skeleton, 12)
    frames = np.stack([stbs.deform(rig.V, rig.skeleton, p, rig.W, rig.E, method="stbs-lbs")
                       for p in poses])
    save_rig(tmp / "arm.npz", rig)
    np.savez(tmp / "examples.npz", frames=frames)
    write_clip(tmp / "poses.json", stbs.Clip([(k / 30, p) for k, p in enumerate(poses)]))
    return tmp, rig, poses, frames


def test_endpoints_come_back_from_examples(capsys, arm):
    tmp, rig, poses, frames = arm
    start = rig.replace(E=np.full(rig.E.shape, 0.5))     # a wrong guess to start from
    save_rig(tmp / "arm-flat.npz", start)
    code, out, err = run(capsys, "fit", "endpoints", tmp / "arm-flat.npz",
                         tmp / "examples.npz", "--poses", tmp / "poses.json",
                         "-o", tmp / "fitted.npz")
    assert code == 0, err
    assert "wrote" in out and "fit: " in err                  # progress on stderr
    fitted = load_rig(tmp / "fitted.npz")
    W = np.asarray(rig.W)
    sure = W > 0.05
    assert np.abs(np.asarray(fitted.E) - np.asarray(rig.E))[sure].max() < 1e-3
    np.testing.assert_array_equal(np.asarray(fitted.W), W)


def test_weights_come_back_from_examples(capsys, arm):
    tmp, rig, poses, frames = arm
    code, out, err = run(capsys, "fit", "weights", tmp / "arm.npz", tmp / "examples.npz",
                         "--poses", tmp / "poses.json", "-o", tmp / "fitted-w.npz",
                         "--influences", "3", "--smoothness", "0", "--quiet")
    assert code == 0, err
    assert err == ""                                          # --quiet
    fitted = load_rig(tmp / "fitted-w.npz")
    W = fitted.W.toarray() if hasattr(fitted.W, "toarray") else np.asarray(fitted.W)
    assert np.abs(W - np.asarray(rig.W)).max() < 1e-2
    U = stbs.deform(rig.V, rig.skeleton, poses[3], fitted.W, fitted.E, method="stbs-lbs")
    assert np.abs(U - frames[3]).max() < 1e-3 * np.ptp(rig.V, axis=0).max()


def test_decompose_writes_a_rig_and_its_clip(capsys, arm):
    tmp, rig, poses, frames = arm
    np.savez(tmp / "anim.npz", frames=frames, rest=rig.V, F=rig.F)
    code, out, err = run(capsys, "fit", "decompose", tmp / "anim.npz", "--bones", "3",
                         "-o", tmp / "dec.npz", "--clip-out", tmp / "dec.json",
                         "--iterations", "4", "--seed", "3", "--quiet")
    assert code == 0, err
    dec = load_rig(tmp / "dec.npz")
    clip = read_clip(tmp / "dec.json", dec.skeleton)
    assert dec.skeleton.n_bones == 3 and len(clip.keys) == len(frames)
    # the files alone play the animation back
    diag = np.linalg.norm(np.ptp(rig.V, axis=0))
    err_rms = np.sqrt(np.mean([np.sum((stbs.deform(dec.V, dec.skeleton, p, dec.W, dec.E,
                                                   method="stbs-lbs") - f) ** 2, axis=1)
                               for (_, p), f in zip(clip.keys, frames, strict=True)]))
    # the error the command reports is the error of what it wrote
    said = float(out.split("RMSE ")[1].split()[0])
    assert err_rms == pytest.approx(said, rel=1e-4)
    assert err_rms < 0.05 * diag and "% of the bounding-box diagonal" in out


def test_helpers_write_a_plain_lbs_rig(capsys, arm):
    tmp, rig, poses, frames = arm
    code, out, err = run(capsys, "fit", "helpers", tmp / "arm.npz", "-k", "3",
                         "-o", tmp / "helpers.npz", "--quiet")
    assert code == 0, err
    helper = load_rig(tmp / "helpers.npz")
    assert helper.skeleton.n_bones >= 3 * rig.skeleton.n_bones
    U = stbs.deform(helper.V, helper.skeleton, stbs.Pose.rest(helper.skeleton), helper.W,
                    method="lbs")
    np.testing.assert_allclose(U, rig.V, atol=1e-9)
    code, out, err = run(capsys, "fit", "helpers", tmp / "arm.npz", "-k", "2",
                         "--clip", tmp / "poses.json", "-o", tmp / "helpers.glb", "--quiet")
    assert code == 0, err
    assert (tmp / "helpers.glb").read_bytes()[:4] == b"glTF"


@pytest.mark.parametrize("argv, says", [
    (["fit", "decompose", "{tmp}/anim.npz", "--bones", "0", "-o", "{tmp}/x.npz"],
     "--bones must be >= 1"),
    (["fit", "decompose", "{tmp}/anim.npz", "--bones", "2", "-o", "{tmp}/x.obj"],
     "expected .npz"),
    (["fit", "decompose", "{tmp}/nan.npz", "--bones", "2", "-o", "{tmp}/x.npz"],
     "finite values"),
    (["fit", "decompose", "{tmp}/one.npz", "--bones", "3", "-o", "{tmp}/x.npz"],
     "needs at least 2 frames"),
    (["fit", "endpoints", "{tmp}/arm.npz", "{tmp}/examples.npz", "--poses", "{tmp}/two.json",
      "-o", "{tmp}/x.npz"], "has 2 keys but the examples hold 12 meshes"),
    (["fit", "endpoints", "{tmp}/arm.npz", "{tmp}/small.npz", "--poses", "{tmp}/two.json",
      "-o", "{tmp}/x.npz"], "(2, 5, 3)"),
    (["fit", "helpers", "{tmp}/arm.npz", "-k", "0", "-o", "{tmp}/x.glb"], "-k must be >= 1"),
    (["fit", "juggle", "{tmp}/arm.npz"], "invalid choice"),
])
def test_bad_input_is_one_line(capsys, arm, argv, says):
    tmp, rig, poses, frames = arm
    np.savez(tmp / "anim.npz", frames=frames, rest=rig.V)
    np.savez(tmp / "nan.npz", frames=np.full((3, 4, 3), np.nan))
    np.savez(tmp / "small.npz", frames=np.zeros((2, 5, 3)))
    np.savez(tmp / "one.npz", frames=frames[:1], rest=rig.V)
    write_clip(tmp / "two.json", stbs.Clip([(0, poses[0]), (1, poses[1])]))
    code, out, err = run(capsys, *[a.format(tmp=tmp) for a in argv])
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("stbs fit") and says in lines[0], err
    assert "Traceback" not in err
    assert not (tmp / "x.npz").exists() and not (tmp / "x.glb").exists()


def test_help_of_every_job_has_an_example(capsys):
    for job in ("decompose", "endpoints", "weights", "helpers"):
        assert main(["fit", job, "--help"]) == 0
        out = capsys.readouterr().out
        assert f"stbs fit {job}" in out.split("example:\n")[-1], job
