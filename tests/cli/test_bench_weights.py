"""``stbs bench --weights``: runs, reports every column, writes JSON, rejects bad options;
and on the tiny case our BBW agrees with igl.bbw (a correctness check, not a timing).

Nothing here asserts a speed: timing belongs in benchmarks (docs/benchmarks.md).
"""

from __future__ import annotations

import json
import sys

import numpy as np
import pytest

from stbs import bench_weights as bw
from stbs.cli import main


def run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def small():
    return bw.make_problem("2d-small")


# --------------------------------------------------------------------------- the command
def test_weights_mode_prints_the_table_and_writes_json(capsys, tmp_path):
    out_json = tmp_path / "bbw.json"
    code, out, err = run(capsys, "bench", "--weights", "--cases", "2d-small",
                         "--igl-max-vertices", "0", "--json", str(out_json))
    assert code == 0, err
    lines = out.splitlines()
    head = next(ln for ln in lines if ln.startswith("case "))
    pos = [head.index(c) for c in bw.COLUMNS]            # every column, in order
    assert pos == sorted(pos)
    row = next(ln for ln in lines if ln.startswith("2d-small "))
    assert "not run (n > 0)" in row and row.split()[-1] in ("cholmod", "cholespy", "scipy")
    assert "Traceback" not in err and f"wrote {out_json}" in err

    doc = json.loads(out_json.read_text())
    assert doc["schema"] == 1 and doc["benchmark"] == "weights"
    assert doc["columns"] == list(bw.COLUMNS)
    assert doc["settings"]["cases"] == ["2d-small"] and doc["settings"]["igl_max_vertices"] == 0
    (r,) = doc["rows"]
    assert r["case"] == "2d-small" and r["kind"] == "compare"
    assert 800 <= r["vertices"] <= 2000 and r["element_kind"] == "tri" and r["functions"] == 3
    assert r["stbs_s"] > 0 and r["converged"] is True
    assert doc["settings"]["tol"] == bw.DEFAULT_TOL == r["tol"]
    assert r["kkt_stbs"] <= bw.DEFAULT_TOL and r["kkt_stbs_reported"] <= bw.DEFAULT_TOL
    assert r["igl_status"] == "not run (n > 0)"
    assert r["igl_s"] is None and r["speedup"] is None and r["max_abs_dW"] is None
    assert doc["goals"] == []                            # the tiny case is not one of the goals


@pytest.mark.parametrize("argv, needle", [
    (["--cases", "2d-7k"], "--cases"),
    (["--cases", ""], "--cases"),
    (["--repeat", "-1"], "--repeat"),
    (["--repeat", "0"], "--repeat"),
    (["--functions", "0"], "--functions"),
    (["--igl-max-vertices", "-5"], "--igl-max-vertices"),
    (["--igl-timeout", "0"], "--igl-timeout"),
    (["--backend", "magic"], "--backend"),
    (["--tol", "nan"], "--tol"),
    (["--json", "/nonexistent-folder/x.json"], "--json"),
])
def test_bad_options_exit_2_with_one_line(capsys, argv, needle):
    code, out, err = run(capsys, "bench", "--weights", "--cases", "2d-small", *argv)
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("stbs bench: error:") and needle in err
    assert "Traceback" not in err and out == ""


def test_help_lists_cases_and_the_skinning_bench_mentions_weights(capsys):
    code, out, _ = run(capsys, "bench", "--weights", "--help")
    assert code == 0 and "--igl-max-vertices" in out
    assert all(name in out for name in bw.CASES)
    code, out, _ = run(capsys, "bench", "--help")
    assert code == 0 and "--weights" in out and "--sizes" in out  # skinning options unchanged


# --------------------------------------------------------------------------- correctness
@pytest.mark.parametrize("tol", [None, 1e-10])
def test_tiny_case_matches_igl_bbw(small, tol):
    pytest.importorskip("igl")
    row = bw.compare_case(small, igl_max_vertices=10**6, **({} if tol is None else {"tol": tol}))
    assert row["igl_status"] == "ok" and row["tol"] == (tol or bw.DEFAULT_TOL)
    assert row["max_abs_dW"] <= 1e-3          # the agreement bound
    assert row["kkt_igl"] <= 1e-6
    if tol is None:                           # the bench's default: igl's accuracy class
        assert row["kkt_stbs"] <= bw.DEFAULT_TOL and row["max_abs_dW"] <= 1e-4
    else:                                     # both solve the QP to ~1e-10
        assert row["kkt_stbs"] <= 1e-8 and row["max_abs_dW"] <= 1e-6


def test_igl_in_a_child_process_gives_the_same_weights(small):
    pytest.importorskip("igl")
    b, bc = bw._boundary(small)
    W0, _ = bw.igl_bbw(small.V, small.E, b, bc[:, :2])
    W1, seconds = bw.igl_bbw(small.V, small.E, b, bc[:, :2], timeout=120)
    assert W1 is not None and seconds > 0
    np.testing.assert_array_equal(W0, W1)


def test_kkt_residual_is_zero_at_the_solution_and_sees_a_violation(small):
    from stbs.weights import BBWSolver

    b, bc = bw._boundary(small)
    W = BBWSolver(small.V, small.E).solve(b, bc[:, :1])
    Q = bw.bilaplacian(small.V, small.E)
    assert bw.kkt_residual(Q, W, b) <= 1e-8
    U = np.setdiff1d(np.arange(small.n), b)
    W2 = W.copy()
    W2[U[0]] += 0.1                           # off the minimiser: the residual shows it
    assert bw.kkt_residual(Q, np.clip(W2, 0, 1), b) > 1e-3


def test_warm_up_runs_once_before_the_first_timed_solve(small, monkeypatch):
    """The first solve in a process loads compiled kernels (~0.5 s): never timed."""
    bbw_module = sys.modules["stbs.weights.bbw"]   # the package's ``bbw`` is the function
    events = []
    real = bbw_module.BBWSolver.solve

    def spy(self, *a, **k):
        events.append(("solve", self.n))
        return real(self, *a, **k)

    monkeypatch.setattr(bbw_module.BBWSolver, "solve", spy)
    monkeypatch.setattr(bw, "_WARM", set())
    monkeypatch.setattr(bw, "igl_available", lambda: (False, "test"))
    bw.compare_case(small, repeat=2)
    bw.compare_case(small, repeat=1)
    # one warm-up solve, then the timed ones; the second case finds it warm
    assert [e[0] for e in events] == ["solve"] * 4
    assert bw._WARM == {("stbs", "auto")}
    events.clear()
    bw.warm_up("auto")
    assert events == []


# --------------------------------------------------------------------------- rig and goals
def test_rig_case_times_both_stages_and_is_judged(small):
    row = bw.rig_case(small)
    assert list(row["stages"]) == ["bone weights (bbw)", "endpoint weights (bbw)"]
    assert row["total_s"] == pytest.approx(sum(row["stages"].values()))
    assert row["bones"] == 3 and row["met"] == (row["total_s"] < bw.RIG_GOAL_S)
    assert row["W_row_sum_error"] <= 1e-8 and 0 <= row["E_range"][0] <= row["E_range"][1] <= 1
    text = bw.format_table([dict(row, case="rig-50k")])
    assert "complete rig" in text and "endpoint weights (bbw)" in text
    assert "goal < 60 s: met" in text or "goal < 60 s: MISSED" in text


def _row(case, speedup, diff, status="ok"):
    return {"case": case, "kind": "compare", "igl_status": status, "speedup": speedup,
            "max_abs_dW": diff}


def test_goals_are_judged_only_where_igl_ran():
    rows = [_row("2d-5k", 12.0, 1e-9), _row("2d-20k", 11.0, 1e-9),
            _row("3d-10k", 10.5, 1e-9), _row("3d-50k", None, None, "not run (n > 20000)"),
            _row("2d-small", 1.0, 1e-9)]                      # an extra: never judged
    goals = {g["case"]: g["status"] for g in bw.check_targets(rows)}
    assert goals == {"2d-5k": "met", "2d-20k": "met", "3d-10k": "met",
                     "3d-50k": "not judged", "all": "not judged"}
    rows[3] = _row("3d-50k", 10.0, 2e-3)                     # too far from igl
    goals = {g["case"]: g["status"] for g in bw.check_targets(rows)}
    assert goals["3d-50k"] == "MISSED" and goals["all"] == "MISSED"
    rows[3] = _row("3d-50k", 20.0, 1e-4)
    assert {g["case"]: g["status"] for g in bw.check_targets(rows)}["all"] == "met"
    rows[0] = _row("2d-5k", 9.9, 1e-9)                       # too slow
    assert {g["case"]: g["status"] for g in bw.check_targets(rows)}["all"] == "MISSED"


def test_without_shared_data_the_3d_cases_use_a_builtin_20_bone_shape(monkeypatch):
    import stbs.io.shared_data as sd

    monkeypatch.setattr(sd, "data_dir", lambda: None)
    said = []
    V, F, sk, source = bw._Meshes(said.append).surface()
    assert sk.n_bones == 20 and sk.dim == 3 and "built-in" in source
    assert V.shape[1] == 3 and F.shape[1] == 3
    assert len(said) == 1 and "not found" in said[0]
