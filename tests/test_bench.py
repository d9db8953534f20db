"""stbs.bench: the harness runs, reports every method, writes JSON, and its peers are right.

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
from stbs.skinning import METHODS

N = 2000


@pytest.fixture(scope="module")
def small_bw():
    # a cache-sized copy/triad: fast, and enough to fill the rows' bound columns
    return bench.measure_bandwidth(nbytes=4 << 20, repeats=1)


@pytest.fixture(scope="module")
def rows(small_bw):
    return bench.run_bench(sizes=(N,), repeats=1, bandwidth=small_bw, download=False)


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


# --------------------------------------------------------------------------- peers are right
def test_numpy_and_scipy_lbs_match_deform(rig):
    U = stbs.deform(rig.V, rig.sk, rig.pose, rig.W, method="lbs")
    A = bench.lbs_affines(rig.pose)
    np.testing.assert_allclose(bench.numpy_lbs(rig.V, rig.idx, rig.w, A), U, rtol=0, atol=1e-9)
    L = bench.lbs_matrix_sparse(rig.V, rig.idx, rig.w, rig.sk.n_bones)
    np.testing.assert_allclose(L @ bench.stacked_transforms(A), U, rtol=0, atol=1e-9)


def test_igl_lbs_matrix_product_matches_deform(rig):
    igl = pytest.importorskip("igl")
    U = stbs.deform(rig.V, rig.sk, rig.pose, rig.W, method="lbs")
    M = igl.lbs_matrix(rig.V, rig.W_dense())
    U_igl = M @ bench.stacked_transforms(bench.lbs_affines(rig.pose))
    np.testing.assert_allclose(U_igl, U, rtol=0, atol=1e-9)


def test_igl_cpp_dqs_matches_dqs_without_stretch_or_twist(rig):
    exe, why = bench.build_igl_dqs(download=False)
    if exe is None:
        pytest.skip(f"libigl C++ DQS harness unavailable: {why}")
    # rotations under 1.2 rad keep every quaternion in one hemisphere, where libigl's
    # running-sum sign rule and our pivot rule agree
    pose = bench.make_pose(rig.sk, 5, stretch=False, twist=False)
    report, U_igl = bench.igl_dqs_deform(exe, rig.V, rig.idx, rig.w, pose, want_output=True)
    U = stbs.deform(rig.V, rig.sk, pose, rig.W, method="dqs")
    np.testing.assert_allclose(U_igl, U, rtol=0, atol=1e-9)
    assert report["n"] == 600 and report["bones"] == 20 and report["threads"] >= 1


# --------------------------------------------------------------------------- rows and table
def test_rows_cover_every_method_and_dtype(rows):
    got = {(r["dtype"], r["method"]): r for r in rows}
    for dtype in ("float64", "float32"):
        for method in (*METHODS, "numpy-lbs", "scipy-lbs"):
            r = got[(dtype, method)]
            assert r["status"] == "ok", r
            assert r["size"] == N and r["repeats"] == 1
            for key in ("ns_per_vertex", "min_ns_per_vertex", "bytes_per_vertex",
                        "bound_ns_per_vertex", "ratio_to_bound", "bandwidth_gbs"):
                assert _finite_pos(r[key]), (method, key, r[key])
        for peer in ("igl-lbs", "igl-dqs"):
            r = got[(dtype, peer)]
            if r["status"] == "ok":
                assert _finite_pos(r["ns_per_vertex"]) and _finite_pos(r["ratio_to_bound"])
            else:
                assert r["status"] == "skipped" and r["reason"]


def test_bytes_per_vertex_follow_the_layout(rows):
    got = {(r["dtype"], r["method"]): r for r in rows}
    # V (3) + idx (uint8) + w + output (3); STBS adds e
    assert got[("float64", "lbs")]["bytes_per_vertex"] == 3 * 8 + 4 * (1 + 8) + 3 * 8
    assert got[("float64", "stbs-dqs")]["bytes_per_vertex"] == 3 * 8 + 4 * (1 + 8 + 8) + 3 * 8
    assert got[("float32", "dqs")]["bytes_per_vertex"] == 3 * 4 + 4 * (1 + 4) + 3 * 4


def test_memory_is_reported_and_the_deformer_holds_few_copies(rows):
    for r in rows:
        if r["kind"] != "stbs":
            continue
        assert r["deformer_nbytes"] > 0 and r["input_bytes"] > 0
        assert r["nbytes_over_input"] <= 3.0, r        # "not more than a few copies"
        assert r["build_peak_bytes"] > 0 and r["frame_peak_bytes"] >= 0


def test_format_table_names_every_method_and_peer(rows, small_bw):
    text = bench.format_table(rows, bench.machine_info(), small_bw)
    for name in (*METHODS, *bench.PEERS):
        assert name in text
    assert "ns/vertex" in text and "median" in text and "memory" in text
    for r in rows:
        if r["status"] == "skipped":
            assert f"skipped: {r['reason']}" in text


def test_check_targets_compares_at_1m_float64():
    base = {"size": 1_000_000, "dtype": "float64", "status": "ok"}
    rows = [dict(base, method="lbs", bound_ns_per_vertex=4.0, ns_per_vertex=7.0,
                 min_ns_per_vertex=5.0),
            dict(base, method="stbs-dqs", ns_per_vertex=30.0, min_ns_per_vertex=28.0),
            dict(base, method="igl-dqs", ns_per_vertex=29.0, min_ns_per_vertex=28.5)]
    t = bench.check_targets(rows)
    # median: lbs 1.75x (missed), stbs-dqs 30 > 29 (missed); best: 1.25x, 28 <= 28.5
    assert [x["met"] for x in t] == [False, False, True, True]
    assert [x["value"] for x in t] == [1.75, 30.0, 1.25, 28.0]
    assert bench.check_targets([dict(r, size=10) for r in rows]) == []


# --------------------------------------------------------------------------- command line
def _args(argv):
    p = argparse.ArgumentParser()
    bench.add_arguments(p)
    return p.parse_args(argv)


def test_flags_parse():
    a = _args(["--sizes", "10k,100k,1M", "--dtype", "float32", "--bones", "8",
               "--influences", "2", "--repeats", "3", "--no-peers", "--json", "x.json"])
    assert a.sizes == (10_000, 100_000, 1_000_000)
    assert a.dtype == ("float32",) and a.bones == 8 and a.influences == 2 and a.repeats == 3
    assert a.no_peers and a.json == "x.json"
    d = _args([])
    assert d.sizes == (10_000, 100_000, 1_000_000) and d.dtype == ("float64", "float32")
    assert d.bones == 20 and d.influences == 4 and not d.no_peers


@pytest.mark.parametrize("argv", [["--sizes", "abc"], ["--sizes", "0"], ["--sizes", "1.5"],
                                  ["--dtype", "float16"], ["--repeats", "0"],
                                  ["--bones", "-2"], ["--methods", "lbs,foo"]])
def test_bad_flags_exit_2(argv, capsys):
    with pytest.raises(SystemExit) as exc:
        bench.main_bench(argv)
    assert exc.value.code == 2
    assert "error" in capsys.readouterr().err


def test_inconsistent_flags_error_before_timing(tmp_path, capsys):
    assert bench.main_bench(["--bones", "3", "--influences", "4"]) == 2
    assert "influences" in capsys.readouterr().err
    assert bench.main_bench(["--json", str(tmp_path / "no" / "such" / "out.json")]) == 2
    assert "does not exist" in capsys.readouterr().err
    with pytest.raises(ValueError, match="dtypes"):
        bench.run_bench(sizes=(10,), dtypes=("float16",), peers=False)


def test_cli_bench_rejects_bad_sizes(capsys):
    from stbs.cli import main

    assert main(["bench", "--sizes", "lots"]) == 2
    assert "sizes" in capsys.readouterr().err


def test_json_is_written_atomically_and_parses(tmp_path, monkeypatch, small_bw, capsys):
    monkeypatch.setattr(bench, "measure_bandwidth", lambda: small_bw)
    out = tmp_path / "bench.json"
    code = bench.main_bench(["--sizes", "1500", "--repeats", "1", "--no-peers",
                             "--dtype", "float64", "--methods", "lbs,stbs-dqs",
                             "--json", str(out)])
    assert code == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bench.json"]  # no temp file left
    doc = json.loads(out.read_text())
    assert doc["schema"] == 1 and doc["settings"]["stat"] == "median"
    assert {r["method"] for r in doc["rows"]} == {"lbs", "stbs-dqs"}
    assert doc["bandwidth"]["gbs"] > 0 and doc["machine"]["cpus"] >= 1
    assert "lbs" in capsys.readouterr().out
