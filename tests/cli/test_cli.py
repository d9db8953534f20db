"""The ``stbs`` command line: results match the API, and bad input gives one line and exit 2."""

import json
import shutil
import subprocess
import sys
import types
from pathlib import Path

import numpy as np
import pytest

import stbs
from stbs import Rig
from stbs.cli import main
from stbs.cli.deform import METHODS as CLI_METHODS
from stbs.io import read_mesh, read_pose, save_rig, write_dmat, write_mesh, write_tgf
from stbs.shapes import bar
from stbs.weights.endpoint import projection

POSE = {"rotate": {"lower": {"axis": [0, 0, 1], "angle": 60}},
        "twist": {"upper": [0, 180]}, "stretch": {"upper": 1.5}}
POSE_BY_INDEX = {"rotate": {"1": {"axis": [0, 0, 1], "angle": 60}},
                 "twist": {"0": [0, 180]}, "stretch": {"0": 1.5}}


def write_json(path: Path, obj) -> Path:
    path.write_text(json.dumps(obj))
    return path


@pytest.fixture
def case(tmp_path):
    """A two-bone bar as a rig (with E), as a rig without E, and as obj + tgf + dmat files."""
    V, F, sk, W = bar(8, 2, 2)
    E = projection(V, sk)
    d = tmp_path
    save_rig(d / "rig.npz", Rig(V=V, F=F, C=sk.C, BE=sk.BE, names=sk.names, W=W, E=E))
    save_rig(d / "rigW.npz", Rig(V=V, F=F, C=sk.C, BE=sk.BE, names=sk.names, W=W))
    write_mesh(d / "bar.obj", V, F)
    write_tgf(d / "bar.tgf", sk.C, sk.BE)
    write_dmat(d / "W.dmat", W)
    write_dmat(d / "E.dmat", E)
    write_json(d / "pose.json", POSE)
    write_json(d / "pose_idx.json", POSE_BY_INDEX)
    # A 2D rig: a square of two triangles with one bone.
    V2 = np.array([[0, -1], [2, -1], [2, 1], [0, 1.0]])
    sk2 = stbs.Skeleton([[0, 0], [2, 0]], [[0, 1]])
    save_rig(d / "rig2d.npz", Rig(V=V2, F=[[0, 1, 2], [0, 2, 3]], C=sk2.C, BE=sk2.BE,
                                   W=np.ones((4, 1))))
    return types.SimpleNamespace(dir=d, V=V, F=F, sk=sk, W=W, E=E, pose=read_pose(POSE, sk))


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def snapshot(folder: Path) -> dict:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir()) if p.is_file()}


# ---------------------------------------------------------------- help and version
def test_help_lists_commands_with_examples(capsys):
    code, out, _ = run(capsys, "--help")
    assert code == 0
    for cmd in ("deform", "demo", "bench", "version"):
        assert cmd in out
    assert "stbs deform arm.npz --pose twist.json --method stbs-dqs -o arm-twisted.obj" in out


@pytest.mark.parametrize("cmd", ["deform", "demo", "version"])
def test_subcommand_help_has_an_example(capsys, cmd):
    code, out, _ = run(capsys, cmd, "--help")
    assert code == 0
    assert "example" in out and f"stbs {cmd}" in out


def test_version(capsys):
    assert run(capsys, "version")[:2] == (0, f"stbs {stbs.__version__}\n")
    assert run(capsys, "--version")[:2] == (0, f"stbs {stbs.__version__}\n")


def test_cli_methods_are_the_library_methods():
    assert CLI_METHODS == stbs.METHODS


def test_no_command_and_unknown_arguments(capsys):
    code, _, err = run(capsys)
    assert code == 2 and err.count("\n") == 1 and "a command is required" in err
    code, _, err = run(capsys, "version", "--frobnicate")
    assert code == 2 and err.count("\n") == 1 and "unrecognized arguments: --frobnicate" in err


# ---------------------------------------------------------------- deform: results
@pytest.mark.parametrize("method", stbs.METHODS)
def test_deform_rig_matches_api(capsys, case, method):
    out = case.dir / f"out-{method}.obj"
    code, stdout, err = run(capsys, "deform", case.dir / "rig.npz", "--pose",
                            case.dir / "pose.json", "--method", method, "-o", out)
    assert code == 0, err
    assert err == ""
    assert f"wrote {out}" in stdout
    want = stbs.deform(case.V, case.sk, case.pose, case.W, case.E, method=method)
    got = read_mesh(out)
    np.testing.assert_allclose(got.V, want, rtol=0, atol=1e-12)  # OBJ text is lossless
    np.testing.assert_array_equal(got.F, case.F)
    assert not np.allclose(want, case.V)  # the pose really moved the mesh


def test_deform_files_without_endpoint_uses_projection_and_says_so(capsys, case):
    d = case.dir
    before = snapshot(d)
    code, _, err = run(capsys, "deform", "--mesh", d / "bar.obj", "--skeleton", d / "bar.tgf",
                       "--weights", d / "W.dmat", "--pose", d / "pose_idx.json",
                       "--method", "stbs-lbs", "-o", d / "out.npz")
    assert code == 0
    assert err.splitlines() == ["stbs: warning: no endpoint weights given; stbs-lbs uses "
                                "projection endpoint weights (paper eq. 8)"]
    with np.load(d / "out.npz") as z:
        assert sorted(z.files) == ["F", "U", "method"]
        want = stbs.deform(case.V, case.sk, case.pose, case.W, None, method="stbs-lbs")
        np.testing.assert_array_equal(z["U"], want)
        np.testing.assert_array_equal(z["F"], case.F)
        assert str(z["method"]) == "stbs-lbs"
    after = snapshot(d)
    assert after.pop("out.npz")
    assert after == before  # inputs untouched, nothing else written


def test_deform_endpoint_file_ply_and_npy(capsys, case):
    d = case.dir
    E2 = case.E ** 2  # a different, valid E
    write_dmat(d / "E2.dmat", E2)
    files = ["--mesh", d / "bar.obj", "--skeleton", d / "bar.tgf", "--weights", d / "W.dmat",
             "--endpoint", d / "E2.dmat", "--pose", d / "pose_idx.json"]
    want = stbs.deform(case.V, case.sk, case.pose, case.W, E2, method="stbs-dqs")
    code, _, err = run(capsys, "deform", *files, "-o", d / "out.ply")
    assert (code, err) == (0, "")
    np.testing.assert_array_equal(read_mesh(d / "out.ply").V, want)
    code, _, err = run(capsys, "deform", *files, "-o", d / "out.npy")
    assert (code, err) == (0, "")
    np.testing.assert_array_equal(np.load(d / "out.npy"), want)


def test_endpoint_file_with_lbs_is_ignored_with_a_warning(capsys, case):
    d = case.dir
    code, _, err = run(capsys, "deform", d / "rig.npz", "--endpoint", d / "E.dmat", "--pose",
                       d / "pose.json", "--method", "lbs", "-o", d / "out.npy")
    assert code == 0
    assert err == f"stbs: warning: {d / 'E.dmat'}: endpoint weights are not used by lbs\n"
    want = stbs.deform(case.V, case.sk, case.pose, case.W, method="lbs")
    np.testing.assert_array_equal(np.load(d / "out.npy"), want)


def test_deform_replaces_rig_endpoint_weights(capsys, case):
    d = case.dir
    write_dmat(d / "E0.dmat", np.zeros_like(case.E))  # e = 0: no twist spread at all
    code, _, _ = run(capsys, "deform", d / "rig.npz", "--endpoint", d / "E0.dmat", "--pose",
                     d / "pose.json", "--method", "stbs-lbs", "-o", d / "out.npy")
    assert code == 0
    want = stbs.deform(case.V, case.sk, case.pose, case.W, np.zeros_like(case.E),
                       method="stbs-lbs")
    np.testing.assert_array_equal(np.load(d / "out.npy"), want)


def test_unnormalised_weights_warn_once_and_succeed(capsys, case):
    d = case.dir
    write_dmat(d / "W2.dmat", 2 * case.W)
    code, _, err = run(capsys, "deform", "--mesh", d / "bar.obj", "--skeleton", d / "bar.tgf",
                       "--weights", d / "W2.dmat", "--pose", d / "pose_idx.json",
                       "--method", "lbs", "-o", d / "out.npy")
    assert code == 0
    lines = err.splitlines()
    assert len(lines) == 1
    assert lines[0].startswith(f"stbs: warning: {d / 'W2.dmat'}: W: ")
    assert "renormalising" in lines[0]
    want = stbs.deform(case.V, case.sk, case.pose, case.W, method="lbs")
    np.testing.assert_allclose(np.load(d / "out.npy"), want, atol=1e-12)


def test_deform_2d_rig(capsys, case):
    d = case.dir
    write_json(d / "p2.json", {"rotate": {"0": {"angle": 90}}})
    code, _, err = run(capsys, "deform", d / "rig2d.npz", "--pose", d / "p2.json",
                       "--method", "lbs", "-o", d / "out2.obj")
    assert (code, err) == (0, "")
    U = read_mesh(d / "out2.obj").V
    np.testing.assert_allclose(U, [[1, 0], [1, 2], [-1, 2], [-1, 0]], atol=1e-12)


def test_tet_rig_writes_the_boundary(capsys, tmp_path):
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    save_rig(tmp_path / "tet.npz", Rig(V=V, T=[[0, 1, 2, 3]], C=[[0, 0, 0], [1, 0, 0]],
                                        BE=[[0, 1]], W=np.ones((4, 1))))
    write_json(tmp_path / "p.json", {"stretch": {"0": 2}})
    code, _, _ = run(capsys, "deform", tmp_path / "tet.npz", "--pose", tmp_path / "p.json",
                     "--method", "lbs", "-o", tmp_path / "o.obj")
    assert code == 0
    m = read_mesh(tmp_path / "o.obj")
    assert m.F.shape == (4, 3)
    np.testing.assert_allclose(m.V[1], [2, 0, 0])


# ---------------------------------------------------------------- deform: bad input
def _bad_cases(d: Path, case):
    V, W = case.V, case.W
    n = V.shape[0]
    (d / "bad.json").write_text('{"stretch": {"upper": 1.5,}}')
    write_json(d / "nobone.json", {"stretch": {"elbow": 1.5}})
    write_json(d / "twist2d.json", {"twist": {"0": [0, 90]}})
    Wn = W.copy()
    Wn[3, 0] = np.nan
    body = "\n".join(repr(float(x)) for x in Wn.T.ravel())  # column-major, as DMAT
    (d / "nan.dmat").write_text(f"2 {n}\n{body}\n")
    Wneg = W.copy()
    Wneg[5] = [-0.5, 1.5]
    write_dmat(d / "neg.dmat", Wneg)
    Eout = case.E.copy()
    Eout[7, 1] = 1.5
    write_dmat(d / "Eout.dmat", Eout)
    write_dmat(d / "short.dmat", W[:-1])
    write_dmat(d / "three.dmat", np.hstack([W, np.zeros((n, 1))]))
    (d / "junk.npz").write_bytes(b"not a zip file")
    (d / "adir").mkdir()
    files = ["--mesh", d / "bar.obj", "--skeleton", d / "bar.tgf"]
    rig, pose, pose_i = d / "rig.npz", d / "pose.json", d / "pose_idx.json"
    return {
        "missing rig": ([d / "nope.npz", "--pose", pose], "nope.npz: rig file not found"),
        "missing pose": ([rig, "--pose", d / "nope.json"], "nope.json: pose file not found"),
        "malformed pose": ([rig, "--pose", d / "bad.json"], "bad.json, line 1"),
        "nonexistent bone": ([rig, "--pose", d / "nobone.json"], "bone 'elbow' does not exist"),
        "unknown method": ([rig, "--pose", pose, "--method", "skinny"],
                           "invalid choice: 'skinny'"),
        "twist in 2D": ([d / "rig2d.npz", "--pose", d / "twist2d.json"],
                        "twist must be 0 for a 2D skeleton"),
        "NaN weights": ([*files, "--weights", d / "nan.dmat", "--pose", pose_i],
                        "nan.dmat"),
        "negative weights": ([*files, "--weights", d / "neg.dmat", "--pose", pose_i],
                             "neg.dmat: W must be >= 0, got -0.5"),
        "endpoint outside [0, 1]": ([rig, "--endpoint", d / "Eout.dmat", "--pose", pose],
                                    "Eout.dmat: E must lie in [0, 1], got 1.5"),
        "too few weight rows": ([*files, "--weights", d / "short.dmat", "--pose", pose_i],
                                f"short.dmat: bone weights must have shape ({n}, 2)"),
        "too many weight columns": ([*files, "--weights", d / "three.dmat", "--pose", pose_i],
                                    f"found ({n}, 3)"),
        "rig and files": ([rig, *files, "--weights", d / "W.dmat", "--pose", pose],
                          "not both"),
        "files incomplete": ([*files, "--pose", pose_i], "missing --weights"),
        "malformed rig": ([d / "junk.npz", "--pose", pose], "junk.npz: expected an .npz"),
        "output folder missing": ([rig, "--pose", pose, "-o", d / "no" / "out.obj"],
                                  "does not exist"),
        "output is a folder": ([rig, "--pose", pose, "-o", d / "adir"], "is a folder"),
        "output extension": ([rig, "--pose", pose, "-o", d / "out.stl"],
                             "cannot write extension '.stl'"),
        "output is an input": ([*files, "--weights", d / "W.dmat", "--pose", pose_i,
                                "-o", d / "bar.obj"], "refusing to write over a file"),
    }


BAD = ["missing rig", "missing pose", "malformed pose", "nonexistent bone", "unknown method",
       "twist in 2D", "NaN weights", "negative weights", "endpoint outside [0, 1]",
       "too few weight rows", "too many weight columns", "rig and files", "files incomplete",
       "malformed rig", "output folder missing", "output is a folder", "output extension",
       "output is an input"]


@pytest.mark.parametrize("name", BAD)
def test_bad_input_one_line_exit_2_nothing_written(capsys, case, name):
    d = case.dir
    argv, expect = _bad_cases(d, case)[name]
    if "-o" not in argv:
        argv = [*argv, "-o", d / "out.obj"]
    before = snapshot(d)
    code, out, err = run(capsys, "deform", *argv)
    assert code == 2
    assert err.count("\n") == 1 and err.endswith("\n"), err
    assert err.startswith("stbs deform: error: "), err
    assert "Traceback" not in err
    assert expect in err, err
    assert out == ""
    assert snapshot(d) == before  # no partial output, inputs byte-for-byte unchanged
    assert not (d / "out.obj").exists()


def test_failed_run_keeps_an_existing_output(capsys, case):
    d = case.dir
    (d / "out.obj").write_text("previous result\n")
    code, _, _ = run(capsys, "deform", d / "rig.npz", "--pose", d / "nope.json",
                     "-o", d / "out.obj")
    assert code == 2
    assert (d / "out.obj").read_text() == "previous result\n"


def test_debug_reraises(case):
    d = case.dir
    with pytest.raises(FileNotFoundError):
        main(["deform", str(d / "rig.npz"), "--pose", str(d / "nope.json"), "-o",
              str(d / "o.obj"), "--debug"])
    with pytest.raises(ValueError, match="elbow"):
        write_json(d / "nobone.json", {"stretch": {"elbow": 1.5}})
        main(["--debug", "deform", str(d / "rig.npz"), "--pose", str(d / "nobone.json"),
              "-o", str(d / "o.obj")])


# ---------------------------------------------------------------- bench delegation
def test_bench_delegates_to_stbs_bench(capsys, monkeypatch):
    seen = {}
    fake = types.ModuleType("stbs.bench")

    def add_arguments(p):
        p.add_argument("--vertices", type=int, default=10)

    def run_bench(args):
        seen["vertices"] = args.vertices
        print("bench ran")
        return 0

    fake.add_arguments, fake.run = add_arguments, run_bench
    monkeypatch.setitem(sys.modules, "stbs.bench", fake)
    code, out, _ = run(capsys, "bench", "--vertices", "123")
    assert (code, out, seen) == (0, "bench ran\n", {"vertices": 123})
    code, out, _ = run(capsys, "bench", "--help")
    assert code == 0 and "--vertices" in out and "example" in out
    code, _, err = run(capsys, "bench", "--nope")
    assert code == 2 and err.count("\n") == 1 and "stbs bench: error:" in err


def test_bench_missing_module_is_one_clear_line(capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "stbs.bench", None)  # import raises ModuleNotFoundError
    code, _, err = run(capsys, "bench")
    assert code == 2
    assert err == ("stbs bench: error: the benchmark module stbs.bench is missing from this "
                   "installation (reinstall stbs-skinning)\n")


# ---------------------------------------------------------------- demo
def test_demo_command(capsys, tmp_path):
    code, out, err = run(capsys, "demo", "--quick", "--only", "fig2", "--out", tmp_path / "demo")
    assert code == 0 and "stbs demo: [" in err
    assert "Fig. 2" in out and "wrote 10 files" in out
    assert (tmp_path / "demo" / "cigar_stbs-dqs.obj").is_file()
    assert (tmp_path / "demo" / "fig2_cigar.png").is_file()
    assert (tmp_path / "demo" / "index.html").is_file()


@pytest.mark.parametrize("args, match", [
    (["--only", "fig2,fig9"], "--only: unknown figure 'fig9'"),
    (["--only", ","], "--only: expected at least one of"),
])
def test_demo_bad_only(capsys, tmp_path, args, match):
    code, out, err = run(capsys, "demo", "--quick", "--out", tmp_path / "d", *args)
    assert code == 2 and out == "" and err.count("\n") == 1 and match in err
    assert "Traceback" not in err and not (tmp_path / "d").exists()


def test_demo_unwritable_out(capsys, tmp_path):
    (tmp_path / "f").write_text("x")
    code, out, err = run(capsys, "demo", "--quick", "--only", "fig2", "--out", tmp_path / "f")
    assert code == 2 and err.startswith("stbs demo: error:") and err.count("\n") == 1
    code, out, err = run(capsys, "demo", "--quick", "--only", "fig2", "--out",
                         tmp_path / "f" / "sub")
    assert code == 2 and err.startswith("stbs demo: error:") and err.count("\n") == 1
    assert (tmp_path / "f").read_text() == "x"


# ---------------------------------------------------------------- installed script
def _script() -> str:
    cand = Path(sys.executable).parent / "stbs"
    found = str(cand) if cand.is_file() else shutil.which("stbs")
    if not found:
        pytest.skip("the stbs console script is not installed")
    return found


def test_script_deform_and_error(case):
    d = case.dir
    exe = _script()
    ok = subprocess.run([exe, "deform", str(d / "rig.npz"), "--pose", str(d / "pose.json"),
                         "-o", str(d / "out.obj")], capture_output=True, text=True, timeout=120)
    assert ok.returncode == 0, ok.stderr
    want = stbs.deform(case.V, case.sk, case.pose, case.W, case.E, method="stbs-dqs")
    np.testing.assert_allclose(read_mesh(d / "out.obj").V, want, atol=1e-12)
    write_json(d / "nobone.json", {"rotate": {"wrist": {"axis": [1, 0, 0], "angle": 1}}})
    before = snapshot(d)
    bad = subprocess.run([exe, "deform", str(d / "rig.npz"), "--pose", str(d / "nobone.json"),
                          "-o", str(d / "out2.obj")], capture_output=True, text=True,
                         timeout=120)
    assert bad.returncode == 2
    assert bad.stderr.count("\n") == 1 and "Traceback" not in bad.stderr
    assert bad.stderr.startswith("stbs deform: error: ")
    assert "bone 'wrist' does not exist" in bad.stderr
    assert snapshot(d) == before


def test_script_help_exits_0():
    res = subprocess.run([_script(), "--help"], capture_output=True, text=True, timeout=60)
    assert res.returncode == 0 and "deform" in res.stdout


@pytest.mark.parametrize("case", ["export over its rig", "animate over its motion",
                                  "animate over its rig", "a hard link to the rig",
                                  "a symbolic link to the motion", "weights over its rig",
                                  "a glTF's buffer file"])
def test_no_command_writes_over_a_file_it_reads(tmp_path, capsys, shared_data, case):
    """Every command refuses, with one line and exit 2, an output that is one of its
    inputs: the same path, a hard link (same inode), a symbolic link, or a file an input
    names (a glTF's .bin); the input keeps its bytes."""
    src = shared_data / "characters" / "gltf" / "Fox_separate"
    for name in ("Fox.gltf", "Fox.bin"):
        shutil.copy(src / name, tmp_path / name)
    rig = tmp_path / "Fox.gltf"
    clip = tmp_path / "clip.json"
    assert main(["animate", str(rig), "--motion", str(rig), "--frames", "0:3",
                 "-o", str(clip)]) == 0
    (tmp_path / "hard.gltf").hardlink_to(rig)
    (tmp_path / "soft.json").symlink_to(clip)
    argv, victim = {
        "export over its rig": (["export", str(rig), "-o", str(rig)], rig),
        "animate over its motion": (["animate", str(rig), "--motion", str(clip), "-o",
                                     str(clip)], clip),
        "animate over its rig": (["animate", str(rig), "--motion", str(clip), "-o",
                                  str(rig)], rig),
        "a hard link to the rig": (["export", str(rig), "-o", str(tmp_path / "hard.gltf")],
                                   rig),
        "a symbolic link to the motion": (["animate", str(rig), "--motion", str(clip), "-o",
                                           str(tmp_path / "soft.json")], clip),
        "weights over its rig": (["weights", str(rig), "--endpoint", "projection", "-o",
                                  str(rig)], rig),
        # the character's buffer file renamed to what the bake would write
        "a glTF's buffer file": (["animate", str(rig), "--motion", str(clip), "--frames",
                                  "0:2", "-o", str(tmp_path / "frames.npz")],
                                 tmp_path / "frames.npz"),
    }[case]
    if case == "a glTF's buffer file":
        (tmp_path / "Fox.bin").rename(tmp_path / "frames.npz")
        rig.write_text(rig.read_text().replace('"Fox.bin"', '"frames.npz"'))
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir() if p.is_file()}
    capsys.readouterr()
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "refusing to write over a file this command reads" in err[0]
    assert victim.read_bytes() == before[victim.name]
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir() if p.is_file()} == before
