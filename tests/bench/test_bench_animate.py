"""stbs bench --animate: the table and the JSON of baking throughput (no timing asserted)."""

from __future__ import annotations

import json

import numpy as np

import stbs
from stbs.bench.animate import _write_bvh, arm_case
from stbs.cli import main


def test_the_case_and_its_bvh_agree(tmp_path):
    rig, motion = arm_case(2000, 12)
    assert 1500 < len(rig.V) < 2600
    np.testing.assert_allclose(rig.W.sum(axis=1), 1)
    _write_bvh(tmp_path / "m.bvh", motion)
    back = stbs.read_bvh(tmp_path / "m.bvh")
    assert back.names == motion.names and back.n_frames == 12
    np.testing.assert_allclose(back.rotations, motion.rotations, atol=1e-5)
    np.testing.assert_allclose(back.positions(), motion.positions(), atol=1e-5)


def test_bench_animate_json(tmp_path, capsys):
    out = tmp_path / "bake.json"
    assert main(["bench", "--animate", "--vertices", "600", "--frames", "16", "--repeat", "1",
                 "--workers", "1", "--json", str(out)]) == 0
    table = capsys.readouterr().out
    assert "frames/s" in table and "workers-1" in table
    doc = json.loads(out.read_text())
    rows = doc["animate"]
    modes = {(r["method"], r["mode"]) for r in rows}
    assert modes == {(m, mode) for m in stbs.METHODS for mode in ("deformer", "bake", "workers-1")}
    for r in rows:
        assert r["frames"] == 16 and r["frames_per_s"] > 0 and np.isfinite(r["frames_per_s"])
        assert (r["overhead"] is None) == (r["mode"] != "bake")
