"""Batches on Dask (stbs animate --manifest): the same files in-process and on a
2-worker local cluster; a killed run or a killed worker loses and duplicates nothing."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from bake_fixtures import arm_bvh, arm_rig, clip_json

import stbs
from stbs.bake import bake
from stbs.bake.batch import job_hash, plan, read_manifest, run_manifest
from stbs.cli import main
from stbs.shapes import bar


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    d = tmp_path_factory.mktemp("batch-inputs")
    rig = arm_rig()
    stbs.save_rig(d / "arm.npz", rig)
    arm_bvh(d / "wave.bvh", frames=40)
    clip_json(d / "bend.json", rig)
    return d


def _manifest(folder, inputs, name="batch.json"):
    jobs = [{"rig": str(inputs / "arm.npz"), "motion": str(inputs / "wave.bvh"),
             "output": "out/wave.npz", "method": "stbs-dqs"},
            {"rig": str(inputs / "arm.npz"), "motion": str(inputs / "bend.json"),
             "output": "out/bend.npz", "method": "stbs-lbs", "frames": "0:11:2"}]
    (folder / "out").mkdir(parents=True, exist_ok=True)
    p = folder / name
    p.write_text(json.dumps(jobs))
    return p


def _outputs(folder):
    return {p.name: p.read_bytes() for p in sorted((folder / "out").iterdir())}


@pytest.fixture(scope="module")
def reference(tmp_path_factory, inputs):
    d = tmp_path_factory.mktemp("batch-ref")
    m = _manifest(d, inputs)
    report = run_manifest(m, chunk=8)
    return d, m, report


def test_in_process_names_outputs_by_their_inputs(reference, inputs):
    d, m, report = reference
    jobs = read_manifest(m)
    names = sorted(f"{j.output.rsplit('/', 1)[1][:-4]}-{job_hash(j)}.npz" for j in jobs)
    assert sorted(_outputs(d)) == names                 # parts removed, nothing else
    assert report.frames == 40 + 6 and len(report.written) == 2
    # the frames are what baking the job alone gives
    rig = stbs.load_rig(inputs / "arm.npz")
    clip = stbs.io.read_clip(inputs / "bend.json", rig.skeleton)
    alone = bake(rig, clip, d / "alone.npz", method="stbs-lbs", frames="0:11:2")
    bend = [n for n in names if n.startswith("bend-")][0]
    np.testing.assert_array_equal(np.load(d / "out" / bend)["U"], np.load(alone.path)["U"])
    # a re-run skips both, writing nothing
    before = {p: p.stat().st_mtime_ns for p in (d / "out").iterdir()}
    again = run_manifest(m)
    assert len(again.skipped) == 2 and again.written == [] and again.frames == 0
    assert {p: p.stat().st_mtime_ns for p in (d / "out").iterdir()} == before


def test_two_local_workers_write_the_same_files(tmp_path, inputs, reference):
    m = _manifest(tmp_path, inputs)
    report = run_manifest(m, workers=2, chunk=8)
    assert report.where == "2 local workers" and report.frames == 46
    assert _outputs(tmp_path) == _outputs(reference[0])


def _big_manifest(folder, inputs, frames=240):
    V, F, sk, W = bar(60, 12, 12)
    sk = stbs.Skeleton(np.array([[0, 0, 0], [2, 0, 0], [3.6, 0, 0], [4.0, 0, 0]]),
                       [[0, 1], [1, 2], [2, 3]], names=["shoulder", "elbow", "wrist"])
    W3 = np.zeros((len(V), 3))
    W3[:, 0] = V[:, 0] < 2
    W3[:, 1] = (V[:, 0] >= 2) & (V[:, 0] < 3.6)
    W3[:, 2] = V[:, 0] >= 3.6
    rig = stbs.Rig(V=V, F=F, skeleton=sk, W=W3, E=stbs.weights.projection(V, sk))
    stbs.save_rig(folder / "big.npz", rig)
    arm_bvh(folder / "long.bvh", frames=frames)
    (folder / "out").mkdir(exist_ok=True)
    p = folder / "big.json"
    p.write_text(json.dumps([{"rig": "big.npz", "motion": "long.bvh", "output": "out/long.npz"}]))
    return p


def _parts(folder):
    """The finished part files (not a writer's temporary file of one)."""
    import re

    part = re.compile(r"^\.long-[0-9a-f]{16}\.npz\.part\d{5}\.npz$")
    return sorted(p for p in (folder / "out").iterdir() if part.match(p.name))


def test_a_killed_run_loses_and_duplicates_nothing(tmp_path, inputs):
    m = _big_manifest(tmp_path, inputs, frames=1200)
    ref_dir = tmp_path / "ref"
    ref_dir.mkdir()
    for f in ("big.npz", "long.bvh"):
        (ref_dir / f).write_bytes((tmp_path / f).read_bytes())
    (ref_dir / "big.json").write_text(m.read_text())
    (ref_dir / "out").mkdir()
    ref = run_manifest(ref_dir / "big.json", chunk=4)
    assert ref.frames == 1200
    code = "import sys; from stbs.cli import main; sys.exit(main())"
    p = subprocess.Popen([sys.executable, "-c", code, "animate", "--manifest", str(m),
                          "--chunk", "4"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                         start_new_session=True)
    deadline = time.monotonic() + 120
    while len(_parts(tmp_path)) < 3 and p.poll() is None and time.monotonic() < deadline:
        time.sleep(0.005)
    os.killpg(p.pid, signal.SIGKILL)
    p.wait(timeout=30)
    done = _parts(tmp_path)
    finals = [q for q in (tmp_path / "out").iterdir() if q.name.startswith("long-")]
    assert finals == [], "the run finished before it could be killed; make it longer"
    assert 3 <= len(done) < 300
    rerun = run_manifest(m, chunk=4)
    assert rerun.frames == 1200 - 4 * len(done)           # only the missing chunks
    assert _outputs(tmp_path) == _outputs(ref_dir)       # the same file, nothing left over


def test_a_killed_worker_loses_nothing(tmp_path, inputs):
    from distributed import Client, LocalCluster

    m = _big_manifest(tmp_path, inputs, frames=800)
    todo, _ = plan(read_manifest(m), chunk=4)
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster, Client(cluster) as client:
        futures = client.compute(todo)
        deadline = time.monotonic() + 120
        while len(_parts(tmp_path)) < 2 and time.monotonic() < deadline:
            time.sleep(0.005)
        pids = client.run(os.getpid)
        victim = sorted(pids.values())[0]
        os.kill(victim, signal.SIGKILL)
        assert not [q for q in (tmp_path / "out").iterdir() if q.name.startswith("long-")], \
            "the batch finished before a worker could be killed; make it longer"
        result = client.gather(futures)
    assert result[0]["frames"] == 800
    U = np.load(result[0]["output"])["U"]
    rig = stbs.load_rig(tmp_path / "big.npz")
    clip = stbs.bake.load_motion(tmp_path / "long.bvh", rig)
    dfm = stbs.Deformer(rig.V, rig.skeleton, rig.W, rig.E, dtype=np.float32)
    for k in (0, 377, 799):
        np.testing.assert_allclose(U[k], dfm(clip.pose(float(clip.sample_times()[k]))),
                                   atol=1e-5)
    assert _parts(tmp_path) == []


def test_manifest_errors(tmp_path, inputs, capsys):
    bad = tmp_path / "bad.json"
    for doc, match in (({"rig": "x"}, "expected a non-empty JSON list"),
                       ([{"rig": "arm.npz"}], "'motion' must be a path"),
                       ([{"rig": "none.npz", "motion": "m.bvh", "output": "o.npz"}],
                        "rig 'none.npz' not found"),
                       ([{"rig": str(inputs / "arm.npz"), "motion": str(inputs / "wave.bvh"),
                          "output": "o.npz", "method": "fast"}], "'method' must be one of"),
                       ([{"rig": str(inputs / "arm.npz"), "motion": str(inputs / "wave.bvh"),
                          "output": "o.npz", "colour": 1}], "unknown keys ['colour']")):
        bad.write_text(json.dumps(doc))
        assert main(["animate", "--manifest", str(bad)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and match in err[0], err
    assert main(["animate", "--manifest", str(bad), "--workers", "2", "--scheduler", "x"]) == 2
    assert "not both" in capsys.readouterr().err


# ------------------------------------------------ kills at every moment, damaged files
def _one_job(folder, inputs, output="out/bend.npz", **extra):
    """A manifest of one small job (6 frames of the bent arm), and the job."""
    (folder / "out").mkdir(parents=True, exist_ok=True)
    job = {"rig": str(inputs / "arm.npz"), "motion": str(inputs / "bend.json"),
           "output": output, "method": "stbs-lbs", "frames": "0:11:2", **extra}
    m = folder / "one.json"
    m.write_text(json.dumps([job]))
    return m


def _names(folder):
    return sorted(p.name for p in (folder / "out").iterdir())


def _final_and_parts(m):
    from stbs.bake.batch import _final, _part

    job = read_manifest(m)[0]
    key = job_hash(job)
    return _final(job, key), [_part(job, key, c) for c in range(3)]    # 6 frames, chunk 2


def _killed(monkeypatch, when):
    """Make the run die like a killed process: before the output's write ("before"), or
    after it, before the parts are removed ("after")."""
    import stbs.bake.batch as batch

    real = batch.write_frames

    def write_frames(*args, **kwargs):
        if when == "after":
            real(*args, **kwargs)
        raise KeyboardInterrupt("killed")
    monkeypatch.setattr(batch, "write_frames", write_frames)


@pytest.mark.parametrize("output", ["out/bend.npz", "out/.odd [1]*.glb"])
def test_a_run_killed_after_its_output_leaves_no_parts_on_the_rerun(tmp_path, inputs,
                                                                    monkeypatch, output):
    m = _one_job(tmp_path, inputs, output=output)
    final, parts = _final_and_parts(m)
    with monkeypatch.context() as mp:
        _killed(mp, "after")
        with pytest.raises(KeyboardInterrupt):
            run_manifest(m, chunk=2)
    assert final.is_file() and all(p.is_file() for p in parts)
    # and a writer killed mid-write left its temporary files (a part's, the output's)
    (final.parent / f".{parts[1].name}.k1ll3d_x.tmp.npz").write_bytes(b"PK\3\4")
    (final.parent / f".{final.name}.k1ll3d_y.tmp{final.suffix}").write_bytes(b"PK\3\4")
    (final.parent / f".{final.name}.other").write_bytes(b"")      # not the batch's: kept
    report = run_manifest(m, chunk=2)
    assert report.skipped == [str(final)] and report.written == [] and report.frames == 0
    assert _names(tmp_path) == sorted([final.name, f".{final.name}.other"])   # output kept
    assert len(report.removed) == 5 and "5 leftover files removed" in report.summary()


def test_a_run_killed_before_its_output_rebakes_only_damaged_parts(tmp_path, inputs,
                                                                   monkeypatch):
    ref = tmp_path / "ref"
    run_manifest(_one_job(ref, inputs), chunk=2)
    m = _one_job(tmp_path, inputs)
    final, parts = _final_and_parts(m)
    with monkeypatch.context() as mp:
        _killed(mp, "before")
        with pytest.raises(KeyboardInterrupt):
            run_manifest(m, chunk=2)
    assert not final.exists() and all(p.is_file() for p in parts)
    # killed during a part's write: a cut temporary file; and a part cut short on disk
    (final.parent / f".{parts[2].name}.k1ll3d_x.tmp.npz").write_bytes(b"PK\3\4")
    parts[1].write_bytes(parts[1].read_bytes()[:300])
    # killed during the output's write: its temporary file
    (final.parent / f".{final.name}.k1ll3d_y.tmp.npz").write_bytes(b"PK\3\4")
    report = run_manifest(m, chunk=2)
    assert report.written == [str(final)] and report.frames == 2     # the cut part alone
    assert _outputs(tmp_path) == _outputs(ref)           # the same bytes, nothing left over


def test_a_part_damaged_after_its_check_is_rebaked_not_joined(tmp_path, inputs, monkeypatch):
    import stbs.bake.batch as batch

    ref = tmp_path / "ref"
    run_manifest(_one_job(ref, inputs), chunk=2)
    m = _one_job(tmp_path, inputs)
    real = batch.bake_chunk

    def bake_chunk(job, rd, md, times, part):
        out = real(job, rd, md, times, part)
        if part.endswith("00001.npz"):
            data = bytearray(open(part, "rb").read())
            data[-200] ^= 0xFF                           # a flipped bit inside U
            open(part, "wb").write(bytes(data))
        return out
    monkeypatch.setattr(batch, "bake_chunk", bake_chunk)
    report = run_manifest(m, chunk=2)
    assert report.parts_rebaked == 1
    assert _outputs(tmp_path) == _outputs(ref)


@pytest.mark.parametrize("damage", ["empty", "cut", "other frames", "not a zip"])
def test_a_damaged_npz_output_is_rebaked(tmp_path, inputs, damage):
    m = _one_job(tmp_path, inputs)
    run_manifest(m, chunk=4)
    final, _ = _final_and_parts(m)
    good = final.read_bytes()
    if damage == "empty":
        final.write_bytes(b"")
    elif damage == "cut":
        final.write_bytes(good[:len(good) // 2])
    elif damage == "other frames":                       # a readable .npz of 5 frames
        with np.load(final) as z:
            np.savez(final, **{k: z[k][:5] if k in ("U", "times") else z[k] for k in z})
    else:
        final.write_bytes(b"\0" * len(good))
    report = run_manifest(m, chunk=4)
    assert report.rebaked == [str(final)] and report.written == [str(final)]
    assert report.frames == 6 and "1 damaged output rebaked" in report.summary()
    assert final.read_bytes() == good and _names(tmp_path) == [final.name]


@pytest.mark.parametrize("damage", ["glb length", "glb magic", "glb cut", "gltf cut"])
def test_a_damaged_gltf_output_is_rebaked(tmp_path, inputs, damage):
    ext = damage.split()[0]
    m = _one_job(tmp_path, inputs, output=f"out/bend.{ext}")
    run_manifest(m, chunk=4)
    final, _ = _final_and_parts(m)
    good = final.read_bytes()
    assert run_manifest(m, chunk=4).skipped == [str(final)]            # a sound file is done
    if damage == "glb length":
        final.write_bytes(good + b"\0" * 4)              # the header's length disagrees
    elif damage == "glb magic":
        final.write_bytes(b"glTX" + good[4:])
    else:
        final.write_bytes(good[:len(good) - 9])
    report = run_manifest(m, chunk=4)
    assert report.rebaked == [str(final)] and final.read_bytes() == good


def test_the_same_job_to_two_formats_writes_both(tmp_path, inputs):
    jobs = [{"rig": str(inputs / "arm.npz"), "motion": str(inputs / "bend.json"),
             "output": f"out/bend.{ext}", "frames": "0:11:2"} for ext in ("npz", "glb")]
    (tmp_path / "out").mkdir()
    m = tmp_path / "two.json"
    m.write_text(json.dumps(jobs))
    report = run_manifest(m, chunk=2)
    names = _names(tmp_path)
    assert len(report.written) == 2 and len(names) == 2, names
    assert {n.rsplit(".", 1)[1] for n in names} == {"npz", "glb"} and report.frames == 12


# ------------------------------------------------------------- what a manifest may say
def test_a_folder_at_the_output_is_an_error(tmp_path, inputs):
    m = _one_job(tmp_path, inputs)
    final, _ = _final_and_parts(m)
    final.mkdir()
    with pytest.raises(ValueError, match=r"job 0: .*is not a regular file") as err:
        run_manifest(m)
    assert str(final) in str(err.value) and str(m) in str(err.value)


def _jobs(folder, inputs, outputs, name="m.json"):
    (folder / "out").mkdir(parents=True, exist_ok=True)
    jobs = [{"rig": str(inputs / "arm.npz"), "motion": str(inputs / "bend.json"),
             "output": o, "frames": "0:3"} for o in outputs]
    m = folder / name
    m.write_text(json.dumps(jobs))
    return m


def test_one_output_listed_twice_is_refused(tmp_path, inputs, capsys):
    for outs in (["out/a.npz", "out/b.npz", "out/../out/a.npz"],
                 ["out/a.npz", "out/b.npz", str(tmp_path / "out" / "a.npz")]):
        m = _jobs(tmp_path, inputs, outs)
        with pytest.raises(ValueError, match=r"jobs 0 and 2 .*same output"):
            read_manifest(m)
        assert main(["animate", "--manifest", str(m)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "jobs 0 and 2" in err[0] and str(m) in err[0], err
    assert not any((tmp_path / "out").iterdir())


def test_outputs_outside_the_manifests_folder_need_an_option(tmp_path, inputs, capsys):
    (tmp_path / "elsewhere").mkdir()
    (tmp_path / "in" / "out").mkdir(parents=True)
    (tmp_path / "in" / "link").symlink_to(tmp_path / "elsewhere")
    for out in ("../elsewhere/x.npz", str(tmp_path / "elsewhere" / "x.npz"), "link/x.npz"):
        m = _jobs(tmp_path / "in", inputs, ["out/a.npz", out])
        with pytest.raises(ValueError, match=r"job 1: output .*outside the manifest's folder"):
            run_manifest(m)
        assert main(["animate", "--manifest", str(m)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "--outputs-anywhere" in err[0], err
        assert not any((tmp_path / "elsewhere").iterdir()) and not any((tmp_path / "in" /
                                                                         "out").iterdir())
    assert main(["animate", "--manifest", str(m), "--outputs-anywhere"]) == 0
    capsys.readouterr()
    assert len(list((tmp_path / "elsewhere").iterdir())) == 1
    assert len(run_manifest(m, outputs_anywhere=True).skipped) == 2
    # an absolute path inside the folder is fine
    inside = _jobs(tmp_path / "in", inputs, [str(tmp_path / "in" / "out" / "b.npz")])
    assert len(run_manifest(inside).written) == 1


def test_inputs_are_never_outputs(tmp_path, inputs):
    rig = tmp_path / "out" / "arm.npz"
    (tmp_path / "out").mkdir()
    rig.write_bytes((inputs / "arm.npz").read_bytes())
    jobs = [{"rig": str(rig), "motion": str(inputs / "bend.json"), "output": "out/a.npz"},
            {"rig": str(inputs / "arm.npz"), "motion": str(inputs / "bend.json"),
             "output": "out/arm.npz"}]
    m = tmp_path / "m.json"
    m.write_text(json.dumps(jobs))
    with pytest.raises(ValueError, match=r"job 1: output .* is the rig of job 0"):
        read_manifest(m)
    # an input named as a batch's part or temporary file (which a run removes)
    part = tmp_path / "out" / ".a-0123456789abcdef.npz.part00000.npz"
    part.write_bytes(rig.read_bytes())
    m.write_text(json.dumps([{**jobs[0], "rig": str(part)}]))
    with pytest.raises(ValueError, match=r"job 0: rig .* is named as a batch's part"):
        read_manifest(m)


def test_manifest_json_and_fields_are_checked(tmp_path, inputs, capsys):
    bad = tmp_path / "bad.json"
    job = {"rig": str(inputs / "arm.npz"), "motion": str(inputs / "bend.json"),
           "output": "o.npz"}
    for text, match in (("[" * 100 + "]" * 100, "nested at most"),
                        ('[{"fps": NaN}]', "finite numbers"),
                        ("[" + "1" * 30 + "]", "digits"),
                        (b"[\xff]", "UTF-8"),
                        (json.dumps([job, {**job, "fps": "fast"}]), "job 1: 'fps' must be"),
                        (json.dumps([{**job, "fps": 0}]), "job 0: 'fps' must be"),
                        (json.dumps([{**job, "twist": "all"}]), "job 0: 'twist' must be one"),
                        (json.dumps([{**job, "frames": 3}]), "job 0: 'frames' must be"),
                        (json.dumps([{**job, "frames": "a:b"}]), "job 0: frames must look"),
                        (json.dumps([{**job, "output": "o.txt"}]), "job 0: output 'o.txt'"),
                        (json.dumps([{**job, "output": "no/o.npz"}]), "job 0: output folder"),
                        (json.dumps([{**job, "rig": "a\0b"}]), "job 0: rig")):
        if isinstance(text, str):
            bad.write_text(text)
        else:
            bad.write_bytes(text)
        with pytest.raises(ValueError, match=match) as err:
            run_manifest(bad)
        assert str(bad) in str(err.value)
        assert main(["animate", "--manifest", str(bad)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and match in err[0], err


def test_a_job_of_too_many_frames_is_refused_before_any_work(tmp_path, inputs, capsys):
    m = _one_job(tmp_path, inputs, fps=1000, frames=None, max_frames=50)   # 1001 frames
    with pytest.raises(ValueError, match=r"job 0: 1001 frames to bake.*at most 50"):
        run_manifest(m)
    assert main(["animate", "--manifest", str(m)]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1
    assert _names(tmp_path) == []
    job = {**json.loads(m.read_text())[0], "max_frames": 2000, "fps": 100}     # 101 frames
    m.write_text(json.dumps([job]))
    assert run_manifest(m).frames == 101
    m.write_text(json.dumps([{**job, "max_frames": 0}]))
    with pytest.raises(ValueError, match=r"job 0: 'max_frames' must be an integer"):
        read_manifest(m)
