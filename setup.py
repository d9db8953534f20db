"""The build hook: the viewer's page is built with esbuild before the package is.

Everything else about the package is in pyproject.toml; this file only adds one step to
setuptools' ``build_py`` (wheels, ``pip install .``, editable installs) and ``sdist``:
the bundles that viewer/bundles.json declares (in ``stbs/viewer/static/``: the page's,
and the peer page's of ``stbs bench --viewer``) are built by
``node viewer/build.mjs`` when they are missing or older than their sources, after
``npm ci`` from the committed lock file when ``viewer/node_modules`` is missing or older
than it. The sdist carries the built bundles with the sources, so a wheel built from it
needs no npm. Without npm and without built bundles the build still succeeds, with a
warning that the package lacks the viewer's page. See docs/dev/packaging.md.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parent
# the viewer's own files besides viewer/src/ whose change calls for a new build
VIEWER_CONFIG = ("build.mjs", "bundles.json", "package.json", "package-lock.json")


def bundle_outputs(root: Path) -> list[Path]:
    """The bundles viewer/bundles.json declares, as absolute paths under ``root``."""
    viewer = root / "viewer"
    spec = json.loads((viewer / "bundles.json").read_text(encoding="utf-8"))
    return [(viewer / b["outfile"]).resolve() for b in spec["bundles"]]


def bundle_inputs(root: Path) -> list[Path]:
    """The files the bundles are built from: viewer/src/ and the viewer's configuration."""
    viewer = root / "viewer"
    found = [p for p in (viewer / "src").rglob("*") if p.is_file()]
    return found + [viewer / n for n in VIEWER_CONFIG if (viewer / n).is_file()]


def _older_than(outputs: list[Path], inputs: list[Path]) -> list[Path]:
    """The outputs that are missing or older than the newest input."""
    newest = max((p.stat().st_mtime for p in inputs), default=0.0)
    return [p for p in outputs if not p.is_file() or p.stat().st_mtime < newest]


def _warn(lines: list[str]) -> None:
    """A warning on stderr that stands out in a build's log."""
    bar = "*" * 78
    text = [bar, "WARNING: " + lines[0], *("  " + line for line in lines[1:]), bar]
    print("\n".join(text), file=sys.stderr, flush=True)


def build_bundles(root: Path = ROOT, *, which: Callable[[str], str | None] = shutil.which,
                  run: Callable[..., object] = subprocess.run) -> str:
    """Build the viewer's bundles under ``root`` when they are missing or out of date.

    Returns what happened: ``"fresh"`` (every bundle newer than its sources: nothing to
    do, npm or not), ``"built"``, ``"missing"`` or ``"stale"`` (no npm or node to build
    them: a warning on stderr, and the package goes without them or with the old ones),
    or ``"no-source"`` (no viewer/bundles.json: nothing to build from). Raises
    ``RuntimeError`` naming the command when npm or the build fails.
    """
    viewer = root / "viewer"
    if not (viewer / "bundles.json").is_file():
        return "no-source"
    outputs = bundle_outputs(root)
    inputs = bundle_inputs(root)
    todo = _older_than(outputs, inputs)
    if not todo:
        return "fresh"
    names = ", ".join(p.relative_to(root).as_posix() for p in todo)
    npm, node = which("npm"), which("node")
    if not (npm and node):
        lacking = " and ".join(n for n, p in (("npm", npm), ("node", node)) if not p)
        if any(p.is_file() for p in todo):
            _warn([f"the viewer's bundles are older than viewer/src: {names}",
                   f"({lacking} not found on PATH to rebuild them); they are packaged as "
                   "they are.",
                   "Install Node.js with npm and build again for the current page."])
            return "stale"
        _warn([f"the viewer's page is missing: {names}",
               f"({lacking} not found on PATH to build it). The package is built without",
               "it: everything works but 'stbs view', which cannot show its page.",
               "Install Node.js with npm and build again, or install from the sdist,",
               "which carries the built page."])
        return "missing"
    stamp = viewer / "node_modules" / ".package-lock.json"
    lock = [viewer / n for n in ("package.json", "package-lock.json") if (viewer / n).is_file()]
    commands = []
    if _older_than([stamp], lock):
        # --ignore-scripts: esbuild's install script only checks its binary, which npm
        # installs as esbuild's optional dependency for this platform
        commands.append([npm, "ci", "--prefix", str(viewer), "--no-audit", "--no-fund",
                         "--ignore-scripts"])
    commands.append([node, str(viewer / "build.mjs")])
    for cmd in commands:
        print("building the viewer's page:", " ".join(cmd), file=sys.stderr, flush=True)
        done = run(cmd, cwd=root, check=False)
        if getattr(done, "returncode", 1) != 0:
            raise RuntimeError(f"building the viewer's page failed: {' '.join(cmd)} exited "
                               f"with status {getattr(done, 'returncode', None)}")
    absent = [p.relative_to(root).as_posix() for p in outputs if not p.is_file()]
    if absent:
        raise RuntimeError(f"building the viewer's page: {' '.join(commands[-1])} "
                           f"did not write {', '.join(absent)}")
    return "built"


if __name__ == "__main__":  # run by setuptools (build_meta runs this file as __main__)
    from setuptools import setup
    from setuptools.command.build_py import build_py
    from setuptools.command.sdist import sdist

    class BuildPy(build_py):
        """build_py that builds the viewer's bundles first, so that package-data has them."""

        def run(self):
            build_bundles(ROOT)
            # setuptools lists package data once, lazily: list it again with the bundles
            self.__dict__.pop("data_files", None)
            super().run()

    class Sdist(sdist):
        """sdist that builds the viewer's bundles first, so that the sdist carries them."""

        def run(self):
            build_bundles(ROOT)
            super().run()

    setup(cmdclass={"build_py": BuildPy, "sdist": Sdist})
