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

    part = re.compile(r"^\.long-[0-9a-f]{16}\.part\d{5}\.npz$")
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
                          "output": "o.npz", "method": "fast"}], "method must be one of"),
                       ([{"rig": str(inputs / "arm.npz"), "motion": str(inputs / "wave.bvh"),
                          "output": "o.npz", "colour": 1}], "unknown keys ['colour']")):
        bad.write_text(json.dumps(doc))
        assert main(["animate", "--manifest", str(bad)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and match in err[0], err
    assert main(["animate", "--manifest", str(bad), "--workers", "2", "--scheduler", "x"]) == 2
    assert "not both" in capsys.readouterr().err
