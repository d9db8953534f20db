"""The build hook (setup.py) and the one description of the viewer's bundles.

The bundles (entry points, outputs, esbuild's options) are declared once, in
viewer/bundles.json; viewer/build.mjs builds them, and npm's build script, the Makefile
and setup.py's hook call it. The hook builds them when they are missing or older than
their sources and npm is there, and otherwise warns. Here its decisions are checked on a
small tree with a stand-in for npm; tests/test_packaging_install.py builds for real.
See docs/dev/packaging.md.
"""

from __future__ import annotations

import importlib.util
import json
import os
import shutil
import subprocess
import tomllib
from fnmatch import fnmatch
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def load_hook():
    """setup.py as a module (its setup() call runs only as __main__)."""
    spec = importlib.util.spec_from_file_location("stbs_build_hook", ROOT / "setup.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


hook = load_hook()
SPEC = json.loads((ROOT / "viewer" / "bundles.json").read_text(encoding="utf-8"))
OUTPUTS = [p.relative_to(ROOT).as_posix() for p in hook.bundle_outputs(ROOT)]


# --------------------------------------------------------------------------- declared once
def test_the_bundles_are_the_viewers_two_pages_in_the_package():
    assert OUTPUTS == ["src/stbs/viewer/static/viewer.js", "src/stbs/viewer/static/three-lbs.js"]
    for b in SPEC["bundles"]:
        assert (ROOT / "viewer" / b["entry"]).is_file(), b
    # package data, so that the wheel has them; ignored by git, so never committed
    patterns = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))[
        "tool"]["setuptools"]["package-data"]["stbs"]
    ignored = subprocess.run(["git", "-C", str(ROOT), "check-ignore", *OUTPUTS],
                             capture_output=True, text=True, check=False).stdout.split()
    for out in OUTPUTS:
        assert any(fnmatch(out.removeprefix("src/stbs/"), p) for p in patterns), out
        assert out in ignored, f"{out} is not ignored by git"


@pytest.mark.skipif(shutil.which("node") is None, reason="no node (make test needs Node)")
def test_build_mjs_reads_the_same_description():
    out = subprocess.run(["node", "viewer/build.mjs", "--outputs"], cwd=ROOT, capture_output=True,
                         text=True, check=True, timeout=60).stdout.split()
    assert out == OUTPUTS
    bad = subprocess.run(["node", "viewer/build.mjs", "--bogus"], cwd=ROOT, capture_output=True,
                         text=True, check=False, timeout=60)
    assert bad.returncode == 2 and "--bogus" in bad.stderr


def test_npm_the_makefile_and_the_hook_call_build_mjs_and_nothing_else_names_esbuild():
    package = json.loads((ROOT / "viewer" / "package.json").read_text(encoding="utf-8"))
    assert package["scripts"]["build"] == "node build.mjs"
    makefile = (ROOT / "Makefile").read_text(encoding="utf-8")
    assert "node viewer/build.mjs" in makefile
    # no second description: no esbuild command line, entry point or output anywhere else
    for name, text in (("Makefile", makefile), ("viewer/package.json", json.dumps(package)),
                       ("setup.py", (ROOT / "setup.py").read_text(encoding="utf-8"))):
        for word in ("esbuild viewer", "--bundle", "--outfile", "--minify", "main.js",
                     "three_lbs.js",
                     "viewer.js", "three-lbs.js"):
            assert word not in text, f"{name} names {word!r}: the bundles live in bundles.json"


# --------------------------------------------------------------------------- the hook's decisions
class FakeNpm:
    """Stands in for subprocess.run: records the commands; the build writes the outputs."""

    def __init__(self, root: Path, *, fail: str | None = None, write: bool = True):
        self.root, self.fail, self.write, self.calls = root, fail, write, []

    def __call__(self, cmd, *, cwd, check):
        self.calls.append([Path(cmd[0]).name, *cmd[1:]])
        assert Path(cwd) == self.root and check is False
        if self.fail and Path(cmd[0]).name == self.fail:
            return subprocess.CompletedProcess(cmd, 1)
        if Path(cmd[0]).name == "npm":
            stamp = self.root / "viewer" / "node_modules" / ".package-lock.json"
            stamp.parent.mkdir(parents=True, exist_ok=True)
            stamp.write_text("{}")
        elif self.write:
            for p in hook.bundle_outputs(self.root):
                p.parent.mkdir(parents=True, exist_ok=True)
                p.write_text("// built")
        return subprocess.CompletedProcess(cmd, 0)


def with_npm(name):
    return f"/usr/bin/{name}"


def without_npm(name):
    return None


@pytest.fixture
def tree(tmp_path):
    """A source tree with the viewer's description and sources, nothing built."""
    v = tmp_path / "viewer"
    (v / "src").mkdir(parents=True)
    shutil.copy(ROOT / "viewer" / "bundles.json", v)
    for name in ("package.json", "package-lock.json", "build.mjs"):
        (v / name).write_text("{}")
    for b in SPEC["bundles"]:
        (v / b["entry"]).write_text("export {};\n")
    return tmp_path


def age(paths, seconds):
    for p in paths:
        st = p.stat()
        os.utime(p, (st.st_atime - seconds, st.st_mtime - seconds))


def test_without_npm_and_without_bundles_the_build_goes_on_with_a_clear_warning(tree, capsys):
    run = FakeNpm(tree)
    assert hook.build_bundles(tree, which=without_npm, run=run) == "missing"
    assert run.calls == []
    err = capsys.readouterr().err
    assert "WARNING: the viewer's page is missing: " + ", ".join(OUTPUTS) in err
    assert "npm and node not found on PATH" in err and "'stbs view'" in err


def test_bundles_older_than_their_sources_are_kept_with_a_warning_without_npm(tree, capsys):
    FakeNpm(tree)(["node", "build.mjs"], cwd=tree, check=False)
    age(hook.bundle_outputs(tree), 60)
    assert hook.build_bundles(tree, which=without_npm, run=FakeNpm(tree)) == "stale"
    err = capsys.readouterr().err
    assert "WARNING: the viewer's bundles are older than viewer/src" in err
    assert all(p.read_text() == "// built" for p in hook.bundle_outputs(tree))


def test_fresh_bundles_are_used_as_they_are_npm_or_not(tree, capsys):
    # an sdist: the bundles built after their sources, no node_modules
    FakeNpm(tree)(["node", "build.mjs"], cwd=tree, check=False)
    age(hook.bundle_inputs(tree), 60)
    for which in (with_npm, without_npm):
        run = FakeNpm(tree)
        assert hook.build_bundles(tree, which=which, run=run) == "fresh"
        assert run.calls == []
    assert capsys.readouterr().err == ""


def test_with_npm_the_packages_are_installed_from_the_lock_file_then_built(tree):
    run = FakeNpm(tree)
    assert hook.build_bundles(tree, which=with_npm, run=run) == "built"
    viewer = str(tree / "viewer")
    assert run.calls == [["npm", "ci", "--prefix", viewer, "--no-audit", "--no-fund",
                          "--ignore-scripts"], ["node", str(tree / "viewer" / "build.mjs")]]
    # again after a source changes: node_modules is current, only the build runs
    age(hook.bundle_outputs(tree), 60)
    age([tree / "viewer" / "package.json", tree / "viewer" / "package-lock.json"], 120)
    run = FakeNpm(tree)
    assert hook.build_bundles(tree, which=with_npm, run=run) == "built"
    assert [c[0] for c in run.calls] == ["node"]
    # a new lock file: npm ci again
    age(hook.bundle_outputs(tree), 60)
    (tree / "viewer" / "package-lock.json").write_text('{"new": 1}')
    run = FakeNpm(tree)
    hook.build_bundles(tree, which=with_npm, run=run)
    assert [c[0] for c in run.calls] == ["npm", "node"]


@pytest.mark.parametrize("fail", ["npm", "node"])
def test_a_failed_build_fails_the_package_build_naming_the_command(tree, fail):
    with pytest.raises(RuntimeError, match=rf"building the viewer's page failed: \S*{fail} "
                                           r".* exited with status 1"):
        hook.build_bundles(tree, which=with_npm, run=FakeNpm(tree, fail=fail))


def test_a_build_that_writes_no_bundle_fails_naming_it(tree):
    with pytest.raises(RuntimeError, match="did not write src/stbs/viewer/static/viewer.js"):
        hook.build_bundles(tree, which=with_npm, run=FakeNpm(tree, write=False))


def test_a_tree_without_the_viewers_sources_builds_nothing(tmp_path):
    run = FakeNpm(tmp_path)
    assert hook.build_bundles(tmp_path, which=with_npm, run=run) == "no-source"
    assert run.calls == []
