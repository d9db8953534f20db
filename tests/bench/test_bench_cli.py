"""``stbs bench`` and ``stbs bench --weights`` through the command line: they run with
no optional dependency, never start a process or touch the network, print their
tables, write JSON, reject bad options in one line; and the installed front end holds
no libigl peer, no harness lookup and no speed target.

Nothing here asserts a speed: timing belongs in benchmarks (docs/benchmarks.md).
"""

from __future__ import annotations

import ast
import json
import re
import runpy
import socket
import subprocess
import sys
import urllib.request
from pathlib import Path

import pytest

import stbs.bench
from stbs.bench import weights as bw
from stbs.cli import main
from stbs.skinning import METHODS

BENCH_DIR = Path(stbs.bench.__file__).parent


def run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture
def offline(monkeypatch):
    """Any process start or network connection fails the test (pip needs both)."""
    started = []

    def refuse(what):
        def f(*a, **k):
            started.append((what, a[:1]))
            raise AssertionError(f"stbs bench tried {what}: {a[:1]}")
        return f

    monkeypatch.setattr(subprocess, "Popen", refuse("a process"))
    monkeypatch.setattr(subprocess, "run", refuse("a process"))
    monkeypatch.setattr(urllib.request, "urlopen", refuse("the network"))
    monkeypatch.setattr(socket, "create_connection", refuse("the network"))
    monkeypatch.setattr(socket.socket, "connect", refuse("the network"))
    return started


# --------------------------------------------------------------------------- stbs bench
def test_the_default_bench_never_runs_pip_or_touches_the_network(capsys, offline):
    # default options except the size and frame count: peers on, both dtypes, all methods
    code, out, err = run(capsys, "bench", "--sizes", "10k", "--repeats", "2")
    assert code == 0, err
    assert offline == []
    for dtype in ("float64", "float32"):
        for name in (*METHODS, *stbs.bench.PEERS):
            assert any(ln.split()[1:3] == [dtype, name] for ln in out.splitlines()
                       if ln.strip().startswith("10,000")), (dtype, name)
    assert "skipped" not in out and "Traceback" not in err
    assert "igl" not in out + err and "pip" not in out + err and "target" not in out


def test_no_peers_runs_our_methods_only(capsys, offline):
    code, out, err = run(capsys, "bench", "--sizes", "10k", "--no-peers", "--repeats", "1",
                         "--dtype", "float32")
    assert code == 0, err
    timing = out.split("memory (MB")[0]                  # the timing table, not memory's
    rows = [ln.split() for ln in timing.splitlines() if ln.strip().startswith("10,000")]
    assert [r[2] for r in rows] == list(METHODS) and {r[1] for r in rows} == {"float32"}


def test_bench_rejects_bad_options_in_one_line(capsys):
    code, out, err = run(capsys, "bench", "--sizes", "lots")
    assert code == 2 and "sizes" in err and err.count("\n") == 1 and out == ""
    code, out, err = run(capsys, "bench", "--bones", "3", "--influences", "4")
    assert code == 2 and err.startswith("stbs bench: error:") and "influences" in err


def test_help_names_our_options_and_no_peer_or_download(capsys):
    code, out, _ = run(capsys, "bench", "--help")
    assert code == 0 and "--weights" in out and "--sizes" in out and "--no-peers" in out
    for word in ("igl", "download", "target", "goal"):
        assert word not in out.lower(), word


# --------------------------------------------------------------------------- --weights
def test_weights_mode_prints_the_table_and_writes_json(capsys, tmp_path, monkeypatch):
    launched = []
    monkeypatch.setattr(urllib.request, "urlopen", lambda *a, **k: launched.append(a))
    out_json = tmp_path / "bbw.json"
    code, out, err = run(capsys, "bench", "--weights", "--cases", "2d-small",
                         "--json", str(out_json))
    assert code == 0, err
    assert launched == []
    lines = out.splitlines()
    head = next(ln for ln in lines if ln.startswith("case "))
    pos = [head.index(c) for c in bw.COLUMNS]            # every column, in order
    assert pos == sorted(pos)
    row = next(ln for ln in lines if ln.startswith("2d-small "))
    assert row.split()[-1] in ("cholmod", "cholespy", "scipy")
    assert "Traceback" not in err and f"wrote {out_json}" in err
    assert "igl" not in out and "goal" not in out and "target" not in out

    doc = json.loads(out_json.read_text())
    assert doc["schema"] == 1 and doc["benchmark"] == "weights"
    assert doc["columns"] == list(bw.COLUMNS)
    assert doc["settings"]["cases"] == ["2d-small"] and doc["settings"]["mesh_dir"] is None
    (r,) = doc["rows"]
    assert r["case"] == "2d-small" and r["kind"] == "solve"
    assert 800 <= r["vertices"] <= 2000 and r["element_kind"] == "tri" and r["functions"] == 3
    assert r["stbs_s"] > 0 and r["converged"] is True
    assert doc["settings"]["tol"] == bw.DEFAULT_TOL == r["tol"]
    assert r["kkt_stbs"] <= bw.DEFAULT_TOL and r["kkt_stbs_reported"] <= bw.DEFAULT_TOL
    assert "goals" not in doc and "targets" not in doc


@pytest.mark.parametrize("argv, needle", [
    (["--cases", "2d-7k"], "--cases"),
    (["--cases", ""], "--cases"),
    (["--repeat", "-1"], "--repeat"),
    (["--repeat", "0"], "--repeat"),
    (["--functions", "0"], "--functions"),
    (["--backend", "magic"], "--backend"),
    (["--tol", "nan"], "--tol"),
    (["--json", "/nonexistent-folder/x.json"], "--json"),
    (["--mesh-dir", "/nonexistent-folder"], "--mesh-dir"),
    (["--cases", "hand"], "--mesh-dir"),
    (["--igl-max-vertices", "5"], "unrecognized"),          # the peer's options are not ours
])
def test_bad_weights_options_exit_2_with_one_line(capsys, argv, needle):
    code, out, err = run(capsys, "bench", "--weights", "--cases", "2d-small", *argv)
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("stbs bench: error:") and needle in err
    assert "Traceback" not in err and out == ""


def test_weights_help_lists_cases_and_mentions_no_peer(capsys):
    code, out, _ = run(capsys, "bench", "--weights", "--help")
    assert code == 0 and "--mesh-dir" in out and "--cases" in out
    assert all(name in out for name in bw.CASES)
    assert "igl." not in out and "--igl" not in out and "goal" not in out.lower()


def test_python_dash_m_stbs_bench_dispatches(capsys, monkeypatch):
    for argv, needle in ((["--help"], "--sizes"), (["--weights", "--help"], "--mesh-dir")):
        monkeypatch.setattr(sys, "argv", ["stbs.bench", *argv])
        with pytest.raises(SystemExit) as exc:
            runpy.run_module("stbs.bench", run_name="__main__", alter_sys=False)
        assert exc.value.code == 0 and needle in capsys.readouterr().out


# --------------------------------------------------------------------------- what ships
def _imports(path: Path) -> list[str]:
    """Absolute names of the stbs modules imported by ``path`` (relative imports resolved)."""
    package = "stbs.bench"
    names = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            names += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            names.append(mod)
            names += [f"{mod}.{a.name}" for a in node.names]
    return [n for n in names if n == "stbs" or n.startswith("stbs.")]


def test_the_front_end_imports_no_other_front_end_and_no_private_module():
    files = sorted(BENCH_DIR.glob("*.py"))
    assert {f.name for f in files} >= {"__init__.py", "skinning.py", "weights.py"}
    for f in files:
        for name in _imports(f):
            parts = name.split(".")
            # the viewer's benchmark times the viewer: it alone serves the page with
            # stbs.viewer's public server
            if f.name == "viewer.py" and parts[1] == "viewer" and not any(
                    p.startswith("_") for p in parts[2:]):
                continue
            assert parts[1:2] not in (["cli"], ["demo"], ["viewer"]), (f.name, name)
            private = [p for p in parts[2:] if p.startswith("_")]
            assert not private or parts[1] == "bench", (f.name, name)


def test_the_front_end_holds_no_peer_harness_download_or_target():
    for f in sorted(BENCH_DIR.glob("*.py")):
        text = f.read_text(encoding="utf-8")
        for word in (r"import igl", r"\bigl\.", r"import subprocess", r"subprocess\.", r"\bpip\b",
                     r"urllib", r"socket", r"bench_dqs", r"LIBIGL_INCLUDE", r"check_targets",
                     r"TARGET_", r"(?i)\bgoals?\b", r"(?i)\btargets?\b"):
            assert not re.search(word, text), (f.name, word)
