"""stbs.bench.skinning: the harness runs, reports every method, writes JSON, its peers
compute the same LBS as stbs.deform, and extra peers join the same run.

Nothing here asserts a speed: timing belongs in benchmarks (docs/benchmarks.md).
"""

from __future__ import annotations

import argparse
import json
import math

import numpy as np
import pytest

import stbs
from stbs import bench
from stbs.bench import skinning as sk_bench
from stbs.skinning import METHODS

N = 2000


@pytest.fixture(scope="module")
def small_bw():
    # a cache-sized copy/triad: fast, and enough to fill the rows' bound columns
    return bench.measure_bandwidth(nbytes=4 << 20, repeats=1)


@pytest.fixture(scope="module")
def rows(small_bw):
    return bench.run_bench(sizes=(N,), repeats=1, bandwidth=small_bw)


@pytest.fixture(scope="module")
def rig():
    return bench.make_rig(600, bones=20, influences=4, seed=3)


def _finite_pos(x) -> bool:
    return x is not None and math.isfinite(x) and x > 0


# --------------------------------------------------------------------------- the rig
def test_rig_has_k_weights_per_vertex_and_a_full_pose(rig):
    W = rig.W.toarray()
    assert W.shape == (600, 20)
    assert np.all((W > 0).sum(axis=1) == 4)
    np.testing.assert_allclose(W.sum(axis=1), 1.0, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(rig.W_dense(), W)
    E = rig.E.toarray()
    assert np.all((E >= 0) & (E <= 1))
    assert np.all((E != 0) <= (W != 0))                     # E only where W is non-zero
    pose = rig.pose
    assert np.all(np.abs(pose.stretch - 1) >= 0.1)          # stretch on every bone
    assert np.all(np.abs(pose.twist) >= 0.2)                 # both twist angles, every bone
    assert np.all(np.abs(np.einsum("bii->b", pose.rotations) - 3) > 1e-3)  # all rotated
    assert rig.sk.n_bones == 20 and len(rig.sk.roots) >= 1


def test_make_rig_rejects_bad_sizes():
    with pytest.raises(ValueError, match="influences"):
        bench.make_rig(10, bones=3, influences=4)
    with pytest.raises(ValueError, match="n must be"):
        bench.make_rig(0)


def test_a_rigid_pose_has_no_stretch_or_twist(rig):
    pose = bench.make_pose(rig.sk, 5, stretch=False, twist=False)
    np.testing.assert_array_equal(pose.stretch, 1.0)
    np.testing.assert_array_equal(pose.twist, 0.0)


# --------------------------------------------------------------------------- peers are right
def test_numpy_and_scipy_lbs_match_deform(rig):
    U = stbs.deform(rig.V, rig.sk, rig.pose, rig.W, method="lbs")
    A = bench.lbs_affines(rig.pose)
    np.testing.assert_allclose(bench.numpy_lbs(rig.V, rig.idx, rig.w, A), U, rtol=0, atol=1e-9)
    L = bench.lbs_matrix_sparse(rig.V, rig.idx, rig.w, rig.sk.n_bones)
    assert L.shape == (600, 80)
    np.testing.assert_allclose(L @ bench.stacked_transforms(A), U, rtol=0, atol=1e-9)


def test_stacked_transforms_by_hand():
    A = np.arange(24, dtype=float).reshape(2, 3, 4)
    T = bench.stacked_transforms(A)
    assert T.shape == (8, 3)
    np.testing.assert_array_equal(T[:4], A[0].T)
    np.testing.assert_array_equal(T[4:], A[1].T)


# --------------------------------------------------------------------------- timing helpers
def test_time_frames_warms_up_then_times_repeats():
    calls = []
    med, mn = bench.time_frames(lambda: calls.append(1), 5)
    assert len(calls) == bench.WARMUP + 5
    assert 0 <= mn <= med


def test_make_row_divides_by_size_and_bandwidth():
    r = bench.make_row(1000, "float64", "x", "peer", {"gbs": 10.0}, med=2e-6, mn=1e-6,
                       repeats=3, bytes_per_vertex=50)
    assert r["status"] == "ok" and r["ns_per_vertex"] == pytest.approx(2.0)
    assert r["min_ns_per_vertex"] == pytest.approx(1.0)
    assert r["bound_ns_per_vertex"] == pytest.approx(5.0)      # 50 B at 10 GB/s
    assert r["ratio_to_bound"] == pytest.approx(0.4)
    s = bench.make_row(1000, "float64", "x", "peer", {"gbs": 10.0}, reason="absent")
    assert s["status"] == "skipped" and s["reason"] == "absent" and s["ns_per_vertex"] is None
    assert bench.auto_repeats(10) == 300 and bench.auto_repeats(10**9) == 10


# --------------------------------------------------------------------------- rows and table
def test_rows_cover_every_method_and_peer_per_dtype(rows):
    got = {(r["dtype"], r["method"]): r for r in rows}
    assert len(got) == len(rows) == 2 * (len(METHODS) + len(bench.PEERS))
    for dtype in ("float64", "float32"):
        for method in (*METHODS, *bench.PEERS):
            r = got[(dtype, method)]
            assert r["status"] == "ok", r
            assert r["size"] == N and r["repeats"] == 1
            assert r["kind"] == ("peer" if method in bench.PEERS else "stbs")
            for key in ("ns_per_vertex", "min_ns_per_vertex", "bytes_per_vertex",
                        "bound_ns_per_vertex", "ratio_to_bound", "bandwidth_gbs"):
                assert _finite_pos(r[key]), (method, key, r[key])


def test_bytes_per_vertex_follow_the_layout(rows):
    got = {(r["dtype"], r["method"]): r for r in rows}
    # V (3) + idx (uint8) + w + output (3); STBS adds e
    assert got[("float64", "lbs")]["bytes_per_vertex"] == 3 * 8 + 4 * (1 + 8) + 3 * 8
    assert got[("float64", "stbs-dqs")]["bytes_per_vertex"] == 3 * 8 + 4 * (1 + 8 + 8) + 3 * 8
    assert got[("float32", "dqs")]["bytes_per_vertex"] == 3 * 4 + 4 * (1 + 4) + 3 * 4


def test_memory_is_reported_and_the_deformer_holds_few_copies(rows):
    ours = [r for r in rows if r["kind"] == "stbs"]
    assert len(ours) == 2 * len(METHODS)
    for r in ours:
        assert r["deformer_nbytes"] > 0 and r["input_bytes"] > 0
        assert r["nbytes_over_input"] <= 3.0, r        # "not more than a few copies"
        assert r["build_peak_bytes"] > 0 and r["frame_peak_bytes"] >= 0


def test_format_table_names_every_method_and_peer(rows, small_bw):
    text = bench.format_table(rows, bench.machine_info(), small_bw)
    for name in (*METHODS, *bench.PEERS):
        assert name in text
    assert "ns/vertex" in text and "median" in text and "memory" in text
    skipped = bench.make_row(N, "float64", "other", "peer", small_bw, reason="not here")
    assert "other      skipped: not here" in bench.format_table([*rows, skipped])


def test_extra_peers_join_the_same_run(small_bw):
    seen = []

    def peer(rig, V, reps, bw, log):
        seen.append((rig.n, V.dtype.name, reps))
        return bench.make_row(rig.n, V.dtype.name, "mine", "peer", bw, med=1e-3, mn=1e-3,
                              repeats=reps, note="test peer")

    rows = bench.run_bench(sizes=(300, 400), dtypes=("float32",), repeats=1, peers=False,
                           methods=("lbs",), bandwidth=small_bw, extra_peers=[peer])
    assert seen == [(300, "float32", 1), (400, "float32", 1)]
    assert [(r["size"], r["method"]) for r in rows] == [(300, "lbs"), (300, "mine"),
                                                        (400, "lbs"), (400, "mine")]
    assert "test peer" in bench.format_table(rows)


def test_run_bench_rejects_bad_choices_before_timing():
    for kw, needle in (({"dtypes": ("float16",)}, "dtypes"), ({"methods": ("foo",)}, "methods"),
                       ({"sizes": ()}, "sizes"), ({"influences": 30}, "influences")):
        with pytest.raises(ValueError, match=needle):
            bench.run_bench(**{"sizes": (10,), "peers": False, **kw},
                            bandwidth={"gbs": 1.0})


# --------------------------------------------------------------------------- command line
def _args(argv):
    p = argparse.ArgumentParser()
    bench.add_arguments(p)
    return p.parse_args(argv)


def test_flags_parse():
    a = _args(["--sizes", "10k,100k,1M", "--dtype", "float32", "--bones", "8",
               "--influences", "2", "--repeats", "3", "--no-peers", "--json", "x.json",
               "--methods", "lbs,dqs"])
    assert a.sizes == (10_000, 100_000, 1_000_000)
    assert a.dtype == ("float32",) and a.bones == 8 and a.influences == 2 and a.repeats == 3
    assert a.no_peers and a.json == "x.json" and a.methods == ("lbs", "dqs")
    d = _args([])
    assert d.sizes == (10_000, 100_000, 1_000_000) and d.dtype == ("float64", "float32")
    assert d.bones == 20 and d.influences == 4 and not d.no_peers and d.repeats is None


@pytest.mark.parametrize("argv", [["--sizes", "abc"], ["--sizes", "0"], ["--sizes", "1.5"],
                                  ["--dtype", "float16"], ["--repeats", "0"],
                                  ["--bones", "-2"], ["--methods", "lbs,foo"]])
def test_bad_flags_exit_2(argv, capsys):
    with pytest.raises(SystemExit) as exc:
        sk_bench.main(argv)
    assert exc.value.code == 2
    assert "error" in capsys.readouterr().err


def test_inconsistent_flags_error_before_timing(tmp_path, capsys, monkeypatch):
    def no_timing(*a, **k):
        raise AssertionError("measured before the options were checked")

    monkeypatch.setattr(sk_bench, "measure_bandwidth", no_timing)
    assert sk_bench.main(["--bones", "3", "--influences", "4"]) == 2
    assert "influences" in capsys.readouterr().err
    assert sk_bench.main(["--json", str(tmp_path / "no" / "such" / "out.json")]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert sk_bench.main(["--json", str(tmp_path)]) == 2
    assert "is a folder" in capsys.readouterr().err


def test_json_is_written_atomically_and_parses(tmp_path, monkeypatch, small_bw, capsys):
    monkeypatch.setattr(sk_bench, "measure_bandwidth", lambda: small_bw)
    out = tmp_path / "bench.json"
    code = sk_bench.main(["--sizes", "1500", "--repeats", "1", "--no-peers",
                          "--dtype", "float64", "--methods", "lbs,stbs-dqs",
                          "--json", str(out)])
    assert code == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bench.json"]  # no temp file left
    doc = json.loads(out.read_text())
    assert doc["schema"] == 1 and doc["benchmark"] == "skinning"
    assert doc["settings"]["stat"] == "median"
    assert doc["settings"]["methods"] == ["lbs", "stbs-dqs"]
    assert {r["method"] for r in doc["rows"]} == {"lbs", "stbs-dqs"}
    assert doc["bandwidth"]["gbs"] > 0 and doc["machine"]["cpus"] >= 1
    assert "targets" not in doc
    out_text = capsys.readouterr().out
    assert "lbs" in out_text and "target" not in out_text
