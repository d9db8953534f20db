"""The peer scripts in ``benchmarks/`` (loaded by path): their plumbing, without libigl's
C++ headers (which the suite does not have): the C++ peer says what it needs in one
line and is skipped, nothing is downloaded unless asked, the speed targets are judged.

Nothing here asserts a speed.
"""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import pytest

from stbs.bench import skinning as sk_bench
from stbs.bench import weights as bw

BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"
_BW = {"gbs": 10.0, "copy_gbs": 10.0, "triad_gbs": 10.0, "triad_threads": 1,
       "array_bytes": 1 << 20, "counted": "test"}


def _load(name: str):
    if name in sys.modules:
        return sys.modules[name]
    sys.path.insert(0, str(BENCHMARKS))       # the scripts import speed_targets beside them
    try:
        spec = importlib.util.spec_from_file_location(name, BENCHMARKS / f"{name}.py")
        mod = importlib.util.module_from_spec(spec)
        sys.modules[name] = mod
        spec.loader.exec_module(mod)
    finally:
        sys.path.remove(str(BENCHMARKS))
    return mod


@pytest.fixture(scope="module")
def targets():
    return _load("speed_targets")


@pytest.fixture(scope="module")
def skin():
    _load("speed_targets")
    return _load("skinning_vs_igl")


@pytest.fixture(scope="module")
def bbw():
    _load("speed_targets")
    return _load("bbw_vs_igl")


@pytest.fixture
def no_headers(skin, monkeypatch, tmp_path):
    """No libigl or Eigen anywhere, a compiler present, no process may start."""
    for var in ("LIBIGL_INCLUDE", "EIGEN_INCLUDE", "CONDA_PREFIX"):
        monkeypatch.delenv(var, raising=False)
    monkeypatch.setattr(skin, "SYSTEM_PREFIXES", [])
    monkeypatch.setattr(skin, "cache_dir", lambda: tmp_path / "cache")
    monkeypatch.setattr(skin, "_compiler", lambda: "/usr/bin/c++")

    def refuse(*a, **k):
        raise AssertionError(f"started a process: {a[:1]}")

    monkeypatch.setattr(subprocess, "run", refuse)
    monkeypatch.setattr(subprocess, "Popen", refuse)


@pytest.mark.parametrize("name, needle", [("skinning_vs_igl", "--libigl-include"),
                                          ("bbw_vs_igl", "--igl-max-vertices"),
                                          ("speed_targets", "RESULT.json")])
def test_every_script_has_help(name, needle, capsys):
    _load("speed_targets")
    with pytest.raises(SystemExit) as exc:
        _load(name).main(["--help"])
    assert exc.value.code == 0 and needle in capsys.readouterr().out


# --------------------------------------------------------------------------- skinning_vs_igl
def test_without_headers_the_cpp_peer_says_what_it_needs_in_one_line(skin, no_headers):
    exe, why = skin.build_igl_dqs()
    assert exe is None and "\n" not in why
    assert "LIBIGL_INCLUDE" in why and "EIGEN_INCLUDE" in why and "libigl" in why
    exe, why = skin.build_igl_dqs(libigl="/nonexistent/include")
    assert exe is None and "/nonexistent/include has no igl/dqs.h" in why and "\n" not in why


def test_the_sdist_is_fetched_only_when_asked(skin, no_headers, monkeypatch):
    asked = []
    monkeypatch.setattr(skin, "headers_from_sdist",
                        lambda cache, log: asked.append(cache) or (None, None, "none there"))
    found = skin.find_headers()
    assert found["libigl"] is None and found["eigen"] is None and asked == []
    found = skin.find_headers(download=True)
    assert len(asked) == 1 and "none there" in found["notes"]


def test_explicit_folders_are_used(skin, no_headers, tmp_path):
    igl_inc, eig_inc = tmp_path / "igl" / "include", tmp_path / "eigen"
    (igl_inc / "igl").mkdir(parents=True)
    (igl_inc / "igl" / "dqs.h").write_text("")
    (eig_inc / "Eigen").mkdir(parents=True)
    (eig_inc / "Eigen" / "Core").write_text("")
    found = skin.find_headers(str(igl_inc), str(eig_inc))
    assert found == {"eigen": str(eig_inc), "libigl": str(igl_inc), "notes": []}


def test_a_run_without_headers_skips_the_cpp_peer_with_one_line(skin, no_headers, capsys,
                                                                  monkeypatch):
    monkeypatch.setattr(sk_bench, "measure_bandwidth", lambda: _BW)
    code = skin.main(["--sizes", "300", "--repeats", "1", "--dtype", "float64",
                      "--methods", "lbs,stbs-dqs"])
    out, err = capsys.readouterr()
    assert code == 0, err
    said = [ln for ln in err.splitlines() if "igl-dqs skipped" in ln]
    assert len(said) == 1 and "LIBIGL_INCLUDE" in said[0]
    assert "igl-dqs    skipped:" in out
    for name in ("lbs", "stbs-dqs", "numpy-lbs", "scipy-lbs", "igl-lbs"):
        assert f"float64  {name} " in out, name
    try:
        import igl  # noqa: F401
    except ImportError:                      # the binding's absence is one line too
        assert sum("igl-lbs skipped" in ln for ln in err.splitlines()) == 1
    else:                                    # the peer was checked against stbs.deform
        assert "check: igl-lbs equals stbs lbs" in err
        assert "igl-lbs    skipped" not in out


# --------------------------------------------------------------------------- bbw_vs_igl
def test_bbw_comparison_without_igl_runs_ours(bbw, tmp_path, capsys):
    out = tmp_path / "bbw.json"
    assert bbw.main(["--cases", "2d-small", "--igl-max-vertices", "0", "--json", str(out)]) == 0
    text = capsys.readouterr().out
    row = next(ln for ln in text.splitlines() if ln.startswith("2d-small "))
    assert "not run (n > 0)" in row
    doc = json.loads(out.read_text())
    assert doc["columns"] == list(bbw.COLUMNS) and doc["settings"]["igl_max_vertices"] == 0
    (r,) = doc["rows"]
    assert r["igl_status"] == "not run (n > 0)" and r["speedup"] is None
    assert r["kkt_stbs"] <= bw.DEFAULT_TOL
    assert doc["targets"] == []                    # 2d-small is not a judged case


# --------------------------------------------------------------------------- speed_targets
def test_skinning_targets_at_1m_float64(targets):
    base = {"size": 1_000_000, "dtype": "float64", "status": "ok"}
    rows = [dict(base, method="lbs", bound_ns_per_vertex=4.0, ns_per_vertex=7.0,
                 min_ns_per_vertex=5.0),
            dict(base, method="stbs-dqs", ns_per_vertex=30.0, min_ns_per_vertex=28.0),
            dict(base, method="igl-dqs", ns_per_vertex=29.0, min_ns_per_vertex=28.5)]
    t = targets.skinning_targets(rows)
    # median: lbs 1.75x (missed), stbs-dqs 30 > 29 (missed); best: 1.25x, 28 <= 28.5
    assert [x["met"] for x in t] == [False, False, True, True]
    assert [x["value"] for x in t] == [1.75, 30.0, 1.25, 28.0]
    assert [x["status"] for x in t] == ["MISSED", "MISSED", "met", "met"]
    assert targets.skinning_targets([dict(r, size=10) for r in rows]) == []


def _row(case, speedup, diff, status="ok"):
    return {"case": case, "kind": "solve", "igl_status": status, "speedup": speedup,
            "max_abs_dW": diff}


def test_bbw_targets_are_judged_only_where_igl_ran(targets):
    rows = [_row("2d-5k", 12.0, 1e-9), _row("2d-20k", 11.0, 1e-9),
            _row("3d-10k", 10.5, 1e-9), _row("3d-50k", None, None, "not run (n > 20000)"),
            _row("2d-small", 1.0, 1e-9)]                      # an extra: never judged
    goals = {g["case"]: g["status"] for g in targets.bbw_targets(rows)}
    assert goals == {"2d-5k": "met", "2d-20k": "met", "3d-10k": "met",
                     "3d-50k": "not judged", "all": "not judged"}
    rows[3] = _row("3d-50k", 10.0, 2e-3)                     # too far from igl
    goals = {g["case"]: g["status"] for g in targets.bbw_targets(rows)}
    assert goals["3d-50k"] == "MISSED" and goals["all"] == "MISSED"
    rows[3] = _row("3d-50k", 20.0, 1e-4)
    assert {g["case"]: g["status"] for g in targets.bbw_targets(rows)}["all"] == "met"
    rows[0] = _row("2d-5k", 9.9, 1e-9)                       # too slow
    assert {g["case"]: g["status"] for g in targets.bbw_targets(rows)}["all"] == "MISSED"
    rig = {"case": "rig-50k", "kind": "rig", "bones": 20, "total_s": 59.0}
    (g,) = targets.bbw_targets([rig])
    assert g["status"] == "met" and "60 s" in g["target"]
    assert targets.bbw_targets([dict(rig, total_s=61.0)])[0]["status"] == "MISSED"
    assert targets.bbw_targets([dict(rig, case="rig-small")]) == []


def test_the_targets_script_exits_1_on_a_missed_target(targets, tmp_path, capsys):
    row = {"size": 1_000_000, "dtype": "float64", "status": "ok", "method": "lbs",
           "bound_ns_per_vertex": 4.0, "ns_per_vertex": 5.0, "min_ns_per_vertex": 5.0}
    good, bad = tmp_path / "good.json", tmp_path / "bad.json"
    good.write_text(json.dumps({"rows": [row]}))
    bad.write_text(json.dumps({"rows": [dict(row, ns_per_vertex=7.0)]}))
    assert targets.main([str(good)]) == 0
    assert "[met]" in capsys.readouterr().out
    assert targets.main([str(good), str(bad)]) == 1
    assert "[MISSED]" in capsys.readouterr().out
    assert targets.main([str(tmp_path / "absent.json")]) == 2
    assert "error" in capsys.readouterr().err
