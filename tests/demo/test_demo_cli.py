"""stbs demo on the command line: the demo extra checked first, --data DIR, user-facing text."""

from __future__ import annotations

import importlib.util
import re
import subprocess
import sys

import pytest

from stbs._optional import OptionalDependencyError
from stbs.cli import main
from stbs.demo import run_demo
from stbs.demo.run import LIBIGL_ARM_FILES, libigl_arm_folder


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


# ---------------------------------------------------------------- the demo extra
@pytest.mark.parametrize("blocked", [["matplotlib"], ["PIL"], ["matplotlib", "PIL"]])
def test_missing_extra_is_one_line_before_any_work(tmp_path, blocked):
    out = tmp_path / "demo"
    code = ("import sys\n"
            f"for m in {blocked!r}:\n"
            "    sys.modules[m] = None  # as if not installed: find_spec says None\n"
            "from stbs.cli import main\n"
            f"sys.exit(main(['demo', '--quick', '--only', 'fig2,fig6', '--out', {str(out)!r}]))\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 2, r.stderr
    assert r.stdout == ""
    lines = r.stderr.splitlines()
    assert len(lines) == 1 and "Traceback" not in r.stderr, r.stderr
    dist = "matplotlib" if "matplotlib" in blocked else "pillow"
    assert lines[0].startswith("stbs demo: error: ")
    assert f"needs {dist}" in lines[0] and "pip install 'stbs-skinning[demo]'" in lines[0]
    assert not out.exists()  # nothing computed, nothing written


def test_run_demo_checks_the_extra_before_computing(tmp_path, monkeypatch):
    real = importlib.util.find_spec

    def find_spec(name, *args, **kwargs):
        return None if name == "matplotlib" else real(name, *args, **kwargs)

    calls = []
    from stbs.demo import figures

    monkeypatch.setattr(figures.shapes, "cigar", lambda *a, **k: calls.append(a))
    monkeypatch.setattr(importlib.util, "find_spec", find_spec)
    with pytest.raises(OptionalDependencyError, match=r"stbs-skinning\[demo\]"):
        run_demo(tmp_path / "d", quick=True, only="fig2", quiet=True)
    assert calls == [] and not (tmp_path / "d").exists()


# ---------------------------------------------------------------- --data DIR
def test_data_accepts_the_folder_or_its_parent(shared_data):
    folder = shared_data / "libigl-tutorial-data"
    assert libigl_arm_folder(folder) == folder
    assert libigl_arm_folder(shared_data) == folder
    assert libigl_arm_folder(str(shared_data)) == folder


def test_data_adds_libigls_arm_to_fig5(capsys, tmp_path, shared_data):
    code, out, err = run(capsys, "demo", "--quick", "--only", "fig5", "--data", shared_data,
                         "--out", tmp_path / "d")
    assert code == 0, err
    assert "Fig. 5 on a scan" in out and (tmp_path / "d" / "fig5_libigl_arm.png").is_file()


def _with_file(folder, name):
    (folder / name).write_text("x")
    return folder


@pytest.mark.parametrize("make, why", [
    (lambda p: p / "missing", "no such folder"),
    (lambda p: p, "missing: arm.obj, arm.tgf, arm-weights.dmat"),
    (lambda p: _with_file(p, "arm.obj"), "missing: arm.tgf, arm-weights.dmat"),
    (lambda p: _with_file(p, "f") / "f", "not a folder"),
])
def test_bad_data_is_one_line_naming_the_path_and_the_files(capsys, tmp_path, make, why):
    bad = make(tmp_path)
    code, out, err = run(capsys, "demo", "--quick", "--only", "fig5", "--data", bad,
                         "--out", tmp_path / "d")
    assert code == 2 and out == "" and err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith(f"stbs demo: error: --data {bad}: ")
    assert all(f in err for f in LIBIGL_ARM_FILES) and why in err
    assert not (tmp_path / "d").exists()
    with pytest.raises(FileNotFoundError) as info:
        run_demo(tmp_path / "d", quick=True, only="fig5", data=bad, quiet=True)
    assert info.value.filename == str(bad) and why in info.value.strerror
    assert not (tmp_path / "d").exists()
    with pytest.raises(TypeError, match="data must be a folder path, got True"):
        run_demo(tmp_path / "d", quick=True, only="fig5", data=True, quiet=True)


# ---------------------------------------------------------------- user-facing text
def test_help_and_docs_say_nothing_internal(capsys):
    code, out, _ = run(capsys, "demo", "--help")
    assert code == 0
    assert "arm.obj,arm.tgfandarm-weights.dmat" in re.sub(r"\s+", "", out)
    assert "stbs-skinning[demo]" in out
    from pathlib import Path

    import stbs.demo

    texts = {"help": out}
    src = Path(stbs.demo.__file__).parent
    for f in ("paper.py", "figures.py", "run.py", "gallery.py"):
        texts[f] = (src / f).read_text()
    docs = Path(__file__).resolve().parents[2] / "docs" / "demo.md"
    if docs.is_file():
        texts["docs/demo.md"] = docs.read_text()
    bad = re.compile(r"\bissue\b|\bsession\b|\.\./shared|shared/data|make test\b|"
                     r"\b20\d\d-\d\d-\d\d\b|\b[0-9a-f]{7,40}\b(?<![0-9]{7})", re.I)
    for name, text in texts.items():
        hits = [m.group(0) for m in bad.finditer(text)]
        assert not hits, (name, hits)


# ---------------------------------------------------------------- boundaries
def test_demo_uses_public_apis_of_other_packages():
    from pathlib import Path

    import stbs.demo

    for path in Path(stbs.demo.__file__).parent.glob("*.py"):
        for mod in re.findall(r"^\s*(?:from|import)\s+(\S+)", path.read_text(), flags=re.M):
            # A private module of another subpackage (stbs.meshing._x, ..io._x).
            assert not re.match(r"(stbs\.|\.\.)\w+\._", mod), (path.name, mod)
            assert not re.match(r"(stbs\.|\.\.)cli\b", mod), (path.name, mod)
