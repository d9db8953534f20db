"""stbs.bench.weights: the solve and rig cases run and are right (KKT, partition of unity),
meshes come from built-in shapes or a folder the user names, never from the repository.

Nothing here asserts a speed: timing belongs in benchmarks (docs/benchmarks.md).
"""

from __future__ import annotations

import sys

import numpy as np
import pytest

from stbs.bench import weights as bw


@pytest.fixture(scope="module")
def small():
    return bw.make_problem("2d-small")


# --------------------------------------------------------------------------- meshes
def test_small_case_has_the_skeleton_in_its_mesh(small):
    assert small.sk.n_bones == 3 and small.sk.dim == 2
    assert 800 <= small.n <= 2000 and small.element_kind == "tri"
    b, bc = bw.boundary(small)
    assert b.size > 0 and bc.shape == (b.size, 3)
    np.testing.assert_allclose(bc.sum(axis=1), 1.0)


def test_without_mesh_dir_the_3d_cases_use_a_builtin_20_bone_shape():
    said = []
    meshes = bw._Meshes(None, said.append)
    V, F, sk, source = meshes.surface()
    assert sk.n_bones == 20 and sk.dim == 3 and "built-in" in source
    assert V.shape[1] == 3 and F.shape[1] == 3
    assert len(said) == 1 and "--mesh-dir" in said[0]
    meshes.surface()
    assert len(said) == 1                                     # said once


def test_the_hand_case_needs_a_mesh_dir(tmp_path):
    with pytest.raises(ValueError, match="--mesh-dir"):
        bw.make_problem("hand")
    with pytest.raises(ValueError, match="not a folder"):
        bw.make_problem("hand", mesh_dir=tmp_path / "absent")
    (tmp_path / "hand.mesh").write_text("")
    with pytest.raises(ValueError, match="hand.tgf"):
        bw.make_problem("hand", mesh_dir=tmp_path)
    with pytest.raises(ValueError, match="case must be one of"):
        bw.make_problem("3d-7k")


def test_mesh_dir_gives_libigls_hand(shared_data):
    folder = shared_data / "libigl-tutorial-data"
    P = bw.make_problem("hand", mesh_dir=folder)
    assert P.n == 7234 and P.element_kind == "tet" and P.sk.n_bones == 20
    assert P.meshing_s == 0.0 and str(folder) in P.source
    V, F, sk, source = bw._Meshes(folder).surface()
    assert F.shape[1] == 3 and V.shape[0] == np.unique(F).size < P.n
    assert "hand surface" in source


# --------------------------------------------------------------------------- checks
def test_kkt_residual_is_zero_at_the_solution_and_sees_a_violation(small):
    from stbs.weights import BBWSolver

    b, bc = bw.boundary(small)
    W = BBWSolver(small.V, small.Ele).solve(b, bc[:, :1])
    Q = bw.bilaplacian(small.V, small.Ele)
    assert bw.kkt_residual(Q, W, b) <= 1e-8
    U = np.setdiff1d(np.arange(small.n), b)
    W2 = W.copy()
    W2[U[0]] += 0.1                           # off the minimiser: the residual shows it
    assert bw.kkt_residual(Q, np.clip(W2, 0, 1), b) > 1e-3


# --------------------------------------------------------------------------- cases
@pytest.mark.parametrize("tol", [None, 1e-10])
def test_solve_case_reaches_its_tolerance(small, tol):
    kw = {} if tol is None else {"tol": tol}
    row, W = bw.solve_case(small, functions=2, return_weights=True, **kw)
    assert row["kind"] == "solve" and row["case"] == "2d-small" and row["functions"] == 2
    assert row["tol"] == (tol or bw.DEFAULT_TOL) and row["converged"] is True
    assert row["kkt_stbs"] <= row["tol"] and row["kkt_stbs_reported"] <= row["tol"]
    assert row["stbs_s"] > 0 and row["backend"] in ("cholmod", "cholespy", "scipy")
    assert W.shape == (small.n, 2) and W.min() >= 0 and W.max() <= 1
    assert row["vertices"] == small.n and row["constrained"] > 0
    assert bw.solve_case(small, functions=99)["functions"] == 3   # capped at the bones


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
    bw.solve_case(small, repeat=2)
    bw.solve_case(small, repeat=1)
    # one warm-up solve, then the timed ones; the second case finds it warm
    assert [e[0] for e in events] == ["solve"] * 4
    assert bw._WARM == {("stbs", "auto")}
    events.clear()
    bw.warm_up("auto")
    assert events == []


def test_rig_case_goes_through_build_rig_and_times_each_stage(small, monkeypatch):
    import stbs.rig

    calls = []
    real = stbs.rig.build_rig

    def spy(V, sk, **kw):
        calls.append(sorted(kw))
        return real(V, sk, **kw)

    monkeypatch.setattr(stbs.rig, "build_rig", spy)
    row = bw.rig_case(small)
    assert calls == [["F", "bone", "endpoint", "progress", "tol"]]
    assert list(row["stages"])[-2:] == ["bone weights (bbw)", "endpoint weights (bbw)"]
    assert all(v >= 0 for v in row["stages"].values())
    assert sum(row["stages"].values()) == pytest.approx(row["total_s"], rel=0.05, abs=0.05)
    assert row["bones"] == 3 and row["vertices"] == small.n and row["kind"] == "rig"
    assert row["W_row_sum_error"] <= 1e-8 and 0 <= row["E_range"][0] <= row["E_range"][1] <= 1
    text = bw.format_table([dict(row, case="rig-50k")])
    assert "complete rig: rig-50k" in text and "endpoint weights (bbw)" in text
    assert "total (stbs.build_rig)" in text
    assert "goal" not in text and "target" not in text


def test_format_table_has_every_column_in_order(small):
    row = bw.solve_case(small, functions=1)
    lines = bw.format_table([row], bw.machine_info(), {"tol": 1e-6, "repeat": 1}).splitlines()
    head = next(ln for ln in lines if ln.startswith("case "))
    pos = [head.index(c) for c in bw.COLUMNS]
    assert pos == sorted(pos)
    line = next(ln for ln in lines if ln.startswith("2d-small "))
    assert line.split()[-1] == row["backend"] and f"{small.n:,}" in line
    assert any(ln.startswith("machine: ") for ln in lines)
