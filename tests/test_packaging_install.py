"""The package as users get it: built from a clean clone of HEAD, installed into fresh
virtual environments, run from a folder outside the source tree, the viewer's page opened
in a browser.

From one clone (``git clone`` of the repository: committed files only, no bundle, no
node_modules): the wheel (``python -m build --wheel``, what ``pip install .`` builds,
its hook running ``npm ci`` and esbuild), then from a clean tree again the sdist, then
from a clean tree with no npm on PATH a wheel that must build with a warning. The wheel
goes into a fresh venv with its dependencies from the index (so an undeclared dependency
fails here) and must hold every file git has under src/stbs and the bundles, run
``stbs --help``, ``--version``, ``bench`` and, with the demo extra, ``demo --quick``. The
sdist is installed by pip, which builds its wheel with no npm on PATH, into a second
fresh venv (``--no-deps``; the dependencies are this interpreter's, put on sys.path after
the venv's own site-packages). In both, ``stbs view`` serves a small rig and Chromium
(Playwright, SwiftShader WebGL2) opens its page until ``stbsViewer.ready``; the page's
script must be the installed file. ``make wheel-check`` runs this file.
"""

from __future__ import annotations

import importlib.util
import os
import re
import selectors
import signal
import subprocess
import sys
import sysconfig
import tarfile
import urllib.request
import zipfile
from pathlib import Path

import numpy as np
import pytest

import stbs
from stbs.io import save_rig

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]
CHROMIUM = os.environ.get("STBS_CHROMIUM", "/usr/bin/chromium")
ARGS = ["--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--headless=new",
        "--disable-dev-shm-usage"]
URL = re.compile(r"^http://127\.0\.0\.1:(\d+)/\?token=[0-9a-f]{32,}$")
BUILD_S = 600       # one python -m build (an isolated environment, npm ci, esbuild)
INSTALL_S = 600     # pip installing the wheel with its dependencies
START_S = 120       # stbs view printing its URL
READY_S = 60        # the page ready (about 1 s here)


def _hook():
    spec = importlib.util.spec_from_file_location("stbs_build_hook", ROOT / "setup.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


# the bundles as paths inside the installed package, from the one description
BUNDLES = [p.relative_to(ROOT / "src").as_posix() for p in _hook().bundle_outputs(ROOT)]


def env(*, path: str | None = None) -> dict:
    """This process's environment (pip's configuration included) without a Python path
    or an active venv; ``path`` replaces PATH."""
    e = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    if path is not None:
        e["PATH"] = path
    return e


def sh(cmd, *, timeout, log: Path | None = None, **kw) -> str:
    """Run ``cmd``; its output (also written to ``log``); fail with its tail when it fails."""
    done = subprocess.run([str(c) for c in cmd], capture_output=True, text=True,
                          timeout=timeout, check=False, **{"env": env(), **kw})
    out = done.stdout + done.stderr
    if log is not None:
        log.write_text(out)
    if done.returncode != 0:
        pytest.fail(f"{' '.join(map(str, cmd))} exited with {done.returncode}:\n{out[-4000:]}")
    return out


# --------------------------------------------------------------------------- builds
@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """The wheel, the sdist and a wheel built without npm, from one clean clone of HEAD."""
    top = tmp_path_factory.mktemp("packaging")
    clone, dist = top / "clone", top / "dist"
    sh(["git", "clone", "-q", ROOT, clone], timeout=120)
    nobin = top / "no-npm-bin"   # an empty PATH: no npm, no node
    nobin.mkdir()

    def build(kind, *, path=None):
        sh(["git", "-C", clone, "clean", "-fdxq"], timeout=60)
        out = dist / (kind + ("-no-npm" if path else ""))
        log = top / f"{out.name}.log"
        sh([sys.executable, "-m", "build", f"--{kind}", "--outdir", out, clone], timeout=BUILD_S,
           log=log, env=env(path=path))
        (found,) = out.iterdir()
        return found, log.read_text()

    wheel, wheel_log = build("wheel")
    sdist, sdist_log = build("sdist")
    bare, bare_log = build("wheel", path=str(nobin))
    return {"top": top, "clone": clone, "nobin": nobin, "wheel": wheel, "wheel_log": wheel_log,
            "sdist": sdist, "sdist_log": sdist_log, "bare": bare, "bare_log": bare_log}


def _wheel_names(path: Path) -> set[str]:
    with zipfile.ZipFile(path) as z:
        return set(z.namelist())


def test_a_clean_clone_builds_the_page_into_the_wheel(built):
    assert "building the viewer's page: " in built["wheel_log"]
    assert "WARNING: the viewer's" not in built["wheel_log"]
    assert set(BUNDLES) <= _wheel_names(built["wheel"])


def test_the_sdist_carries_the_page_and_the_viewers_sources(built):
    with tarfile.open(built["sdist"]) as t:
        top = t.getnames()[0].split("/")[0]
        names = {n.removeprefix(top + "/") for n in t.getnames()}
    want = {f"src/{b}" for b in BUNDLES} | {
        "setup.py", "MANIFEST.in", "viewer/package.json", "viewer/package-lock.json",
        "viewer/build.mjs", "viewer/bundles.json", "viewer/src/main.js"}
    assert want <= names, sorted(want - names)
    assert not any(n.startswith("viewer/node_modules") for n in names)


def test_without_npm_the_build_succeeds_and_warns_that_the_page_is_missing(built):
    log = built["bare_log"]
    assert "WARNING: the viewer's page is missing: " in log, log[-3000:]
    assert all(b in log for b in BUNDLES)
    names = _wheel_names(built["bare"])
    assert "stbs/viewer/static/index.html" in names
    assert not set(BUNDLES) & names


# --------------------------------------------------------------------------- installs
def _venv(where: Path) -> Path:
    sh([sys.executable, "-m", "venv", where], timeout=300)
    return where


def _in_venv(venv: Path, code: str, *, cwd: Path) -> str:
    return sh([venv / "bin" / "python", "-c", code], timeout=120, cwd=cwd).strip()


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    """A folder outside the source tree, so that the checkout is not importable."""
    d = tmp_path_factory.mktemp("run")
    assert not d.is_relative_to(ROOT)
    return d


@pytest.fixture(scope="module")
def wheel_venv(built, run_dir):
    """A fresh venv with the wheel and its declared dependencies from the index."""
    venv = _venv(built["top"] / "venv-wheel")
    sh([venv / "bin" / "python", "-m", "pip", "install", "-q", built["wheel"]], timeout=INSTALL_S,
       cwd=run_dir)
    return venv


@pytest.fixture(scope="module")
def sdist_venv(built, run_dir):
    """A fresh venv with the sdist, built by pip with no npm on PATH, without dependencies;
    then this interpreter's site-packages after the venv's own for them."""
    venv = _venv(built["top"] / "venv-sdist")
    out = sh([venv / "bin" / "python", "-m", "pip", "install", "-v", "--no-deps",
              built["sdist"]], timeout=INSTALL_S, cwd=run_dir, env=env(path=str(built["nobin"])))
    # the sdist's bundles were used as they are: nothing built, nothing missing
    assert "building the viewer's page" not in out and "WARNING: the viewer's" not in out
    site = Path(_in_venv(venv, "import sysconfig; print(sysconfig.get_paths()['purelib'])",
                         cwd=run_dir))
    (site / "zz_test_dependencies.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    return venv


def _installed(venv: Path, run_dir: Path) -> Path:
    """The stbs package folder the venv imports, checked to lie inside the venv."""
    pkg = Path(_in_venv(venv, "import os, stbs; print(os.path.dirname(stbs.__file__))",
                        cwd=run_dir))
    assert pkg.is_relative_to(venv), f"stbs imported from {pkg}, not from {venv}"
    return pkg


def test_the_wheel_holds_every_file_and_its_commands_run(wheel_venv, built, run_dir):
    pkg = _installed(wheel_venv, run_dir)
    tracked = sh(["git", "-C", built["clone"] / "src", "ls-files", "--", "stbs"],
                 timeout=60).split()
    got = {p.relative_to(pkg.parent).as_posix() for p in pkg.rglob("*")
           if p.is_file() and "__pycache__" not in p.parts}
    lacking = sorted((set(tracked) | set(BUNDLES)) - got)
    assert not lacking, f"the wheel lacks: {lacking}"
    stbs_cmd = wheel_venv / "bin" / "stbs"
    sh([stbs_cmd, "--help"], timeout=120, cwd=run_dir)
    version = built["wheel"].name.split("-")[1]
    assert sh([stbs_cmd, "--version"], timeout=120, cwd=run_dir).strip() == f"stbs {version}"
    sh([stbs_cmd, "bench", "--sizes", "10k", "--no-peers"], timeout=600, cwd=run_dir)


def test_the_wheel_with_the_demo_extra_runs_the_quick_demo(wheel_venv, built, run_dir):
    sh([wheel_venv / "bin" / "python", "-m", "pip", "install", "-q", f"{built['wheel']}[demo]"],
       timeout=INSTALL_S, cwd=run_dir)
    sh([wheel_venv / "bin" / "stbs", "demo", "--quick", "--out", run_dir / "demo"], timeout=600,
       cwd=run_dir)
    assert (run_dir / "demo" / "index.html").stat().st_size > 0


# --------------------------------------------------------------------------- the page
@pytest.fixture(scope="module")
def browser():
    sync_api = pytest.importorskip("playwright.sync_api", reason="playwright is not installed "
                                   "(the test extra has it)")
    if not Path(CHROMIUM).is_file():
        pytest.skip(f"no Chromium at {CHROMIUM} (apt-get install chromium; make test does)")
    with sync_api.sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=ARGS, headless=True)
        yield b
        b.close()


@pytest.fixture(scope="module")
def rig_file(run_dir):
    """A small 2D rig: a strip of 40 vertices along two bones."""
    x, y = np.meshgrid(np.linspace(0, 2, 20), [-0.2, 0.2])
    V = np.c_[x.ravel(), y.ravel()]
    F = np.array([t for i in range(19) for t in ([i, i + 1, i + 21], [i, i + 21, i + 20])])
    sk = stbs.Skeleton(np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]]), np.array([[0, 1], [1, 2]]))
    w = np.clip(V[:, 0] - 0.5, 0, 1)
    path = run_dir / "strip.npz"
    save_rig(path, stbs.Rig(V=V, F=F, skeleton=sk, W=np.c_[1 - w, w]))
    return path


def _open_page(browser, venv: Path, rig: Path, run_dir: Path) -> None:
    """``stbs view RIG`` from the venv; its page in Chromium until stbsViewer.ready."""
    static = _installed(venv, run_dir) / "viewer" / "static"
    p = subprocess.Popen([venv / "bin" / "stbs", "view", rig, "--no-browser", "--port", "0"],
                         cwd=run_dir, env=env(), text=True, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE)
    page = None
    try:
        with selectors.DefaultSelector() as sel:
            sel.register(p.stdout, selectors.EVENT_READ)
            if not sel.select(timeout=START_S):
                pytest.fail(f"stbs view printed nothing in {START_S} s")
        url = p.stdout.readline().strip()
        m = URL.match(url)
        assert m, f"not a URL line: {url!r}"
        errors = []
        page = browser.new_page(viewport={"width": 640, "height": 480})
        page.on("console", lambda msg: msg.type == "error" and errors.append(msg.text))
        page.on("pageerror", lambda e: errors.append(str(e)))
        page.goto(url)
        page.wait_for_function("window.stbsViewer !== undefined", timeout=READY_S * 1000)
        info = page.evaluate(
            """s => Promise.race([stbsViewer.ready, new Promise((_, no) => setTimeout(
                   () => no(new Error(`not ready after ${s} s`)), s * 1000))])""", READY_S)
        assert info["vertices"] == 40 and info["bones"] == 2, info
        assert page.evaluate("document.body.dataset.ready") == "true"
        assert page.locator("#fallback").count() == 0   # the script ran and removed it
        assert not errors, errors
        # the page's script is the installed file
        for b in BUNDLES:
            name = b.rsplit("/", 1)[1]
            with urllib.request.urlopen(f"http://127.0.0.1:{m[1]}/static/{name}",
                                        timeout=30) as r:
                assert r.read() == (static / name).read_bytes(), name
    finally:
        if page is not None:
            page.close()
        p.send_signal(signal.SIGINT)
        try:
            p.communicate(timeout=30)
        except subprocess.TimeoutExpired:
            p.kill()
            p.communicate(timeout=30)


def test_the_wheel_serves_a_working_page(browser, wheel_venv, rig_file, run_dir):
    _open_page(browser, wheel_venv, rig_file, run_dir)


def test_the_sdist_installs_without_npm_and_serves_a_working_page(browser, sdist_venv, rig_file,
                                                                  run_dir):
    _open_page(browser, sdist_venv, rig_file, run_dir)
