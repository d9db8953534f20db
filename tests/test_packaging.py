"""Packaging: the extras install on the platform, the floors cover what the code uses,
one version source. See docs/dependencies.md and docs/dev/testing.md."""

from __future__ import annotations

import ast
import fnmatch
import importlib.metadata
import re
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest
from packaging.requirements import Requirement
from packaging.specifiers import SpecifierSet
from packaging.version import Version

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src" / "stbs"
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
PROJECT = PYPROJECT["project"]
DIST = PROJECT["name"]

# Every package an extra may name, checked to install with pip from a wheel (no
# compiler, no system library) on a fresh Debian bookworm machine with Python 3.11,
# from the floor given here up. A new package goes in only after that check
# (`pip install --only-binary :all: 'PKG>=FLOOR'` in a fresh venv; docs/dev/testing.md).
INSTALLS_ON_BOOKWORM = {
    "libigl": "2.6.3",       # 2.6.0-2.6.2 lack lbs_matrix / boundary_conditions; 2.5 lacks bbw
    "embreex": "4.4",
    "triangle": "20250106",
    "tetgen": "0.8.1",       # 0.8.0 loses TetGen's error message (nanobind)
    "cholespy": "2.1",
    "matplotlib": "3.7",
    "pillow": "9.2",         # the first release with Python 3.11 wheels
    "pytest": "7",
    "ruff": "0.13",          # 0.12 and older report UP038 on this code base
    "build": "1",
    "hypothesis": "6.170",   # pure Python; the release the fuzz suite was written against
    "playwright": "1.65",    # with Debian's chromium (apt), never a downloaded browser
    "dask": "2024.8",        # pure Python
    "distributed": "2024.8",
    "usd-core": "26.11",     # the release tested (its UsdValidation checks the files)
    "ufbx": "0.0.5",         # the release tested (the binding by ufbx's author)
    "torch": "2.13",         # the release tested, in its CPU build (the Makefile pins it)
    "jax": "0.10",           # the release tested, with its jaxlib (CPU)
    "py-dem-bones": "0.13",  # the release tested (EA's Dem Bones, a benchmark peer)
}
# Known not to install there; the reason is the failure message.
NOT_ON_BOOKWORM = {
    "scikit-sparse": "no wheel: it builds against the system SuiteSparse, needs a C "
                     "compiler and libsuitesparse-dev, and 0.5 needs SuiteSparse 7 "
                     "(bookworm has 5.12); the ctypes CHOLMOD path and cholespy serve",
}

# (package, release it arrived in) for the names of newer APIs; a use anywhere in
# src/stbs needs the declared floor of that package at or above the release. The
# csgraph rows are behaviour, not names: on index arrays of 64 bits (what our sparse
# arrays built from int64 data carry) connected_components fails before SciPy 1.12
# and dijkstra before 1.15 ("Buffer dtype mismatch"), found by running the suite.
API_SINCE = {
    "scipy.sparse.sparray": ("scipy", "1.11"),
    "scipy.sparse.diags_array": ("scipy", "1.11"),
    "scipy.sparse.eye_array": ("scipy", "1.12"),
    "scipy.sparse.random_array": ("scipy", "1.12"),
    "scipy.sparse.block_array": ("scipy", "1.12"),
    "scipy.sparse.csgraph.connected_components": ("scipy", "1.12"),
    "scipy.sparse.csgraph.dijkstra": ("scipy", "1.15"),
    "numpy.exceptions": ("numpy", "1.25"),
    "numpy.dtypes": ("numpy", "1.25"),
    "numpy.isdtype": ("numpy", "2.0"),
    "numpy.concat": ("numpy", "2.0"),
    "numpy.permute_dims": ("numpy", "2.0"),
    "numpy.matrix_transpose": ("numpy", "2.0"),
    "numpy.vecdot": ("numpy", "2.0"),
    "numpy.linalg.vecdot": ("numpy", "2.0"),
    "numpy.linalg.vector_norm": ("numpy", "2.0"),
    "numpy.linalg.matrix_norm": ("numpy", "2.0"),
    "numpy.trapezoid": ("numpy", "2.0"),
    "numpy.unique_values": ("numpy", "2.0"),
    "numpy.unique_counts": ("numpy", "2.0"),
    "numpy.unique_inverse": ("numpy", "2.0"),
    "numpy.unique_all": ("numpy", "2.0"),
    "numpy.bitwise_count": ("numpy", "2.0"),
    "numpy.astype": ("numpy", "2.1"),
    "numpy.unstack": ("numpy", "2.1"),
    "numpy.cumulative_sum": ("numpy", "2.1"),
    "numpy.cumulative_prod": ("numpy", "2.1"),
    "numba.get_num_threads": ("numba", "0.49"),
    "numba.set_num_threads": ("numba", "0.49"),
    "numba.set_parallel_chunksize": ("numba", "0.57"),
    "numba.get_parallel_chunksize": ("numba", "0.57"),
    "threadpoolctl.ThreadpoolController": ("threadpoolctl", "3.0"),
    "tomllib": ("python", "3.11"),
    "datetime.UTC": ("python", "3.11"),
    "enum.StrEnum": ("python", "3.11"),
    "typing.Self": ("python", "3.11"),
    "typing.Never": ("python", "3.11"),
    "typing.LiteralString": ("python", "3.11"),
    "typing.assert_never": ("python", "3.11"),
    "typing.NotRequired": ("python", "3.11"),
    "typing.Required": ("python", "3.11"),
    "contextlib.chdir": ("python", "3.11"),
    "hashlib.file_digest": ("python", "3.11"),
    "asyncio.TaskGroup": ("python", "3.11"),
    "math.cbrt": ("python", "3.11"),
    "math.exp2": ("python", "3.11"),
    "operator.call": ("python", "3.11"),
    "itertools.batched": ("python", "3.12"),
    "typing.override": ("python", "3.12"),
    "math.sumprod": ("python", "3.12"),
}


def _floor(spec: str | SpecifierSet) -> Version | None:
    """The lowest version a specifier admits (its >= or == bound), or None."""
    bounds = [Version(s.version) for s in SpecifierSet(str(spec))
              if s.operator in (">=", "==", "~=")]
    return max(bounds) if bounds else None


def _requirements(reqs: list[str]) -> dict[str, Requirement]:
    return {Requirement(r).name.lower(): Requirement(r) for r in reqs}


def _floors() -> dict[str, Version | None]:
    floors = {name: _floor(r.specifier) for name, r in _requirements(
        PROJECT["dependencies"]).items()}
    floors["python"] = _floor(PROJECT["requires-python"])
    return floors


# --------------------------------------------------------------------------- extras
@pytest.mark.parametrize("extra", sorted(PROJECT["optional-dependencies"]))
def test_every_extra_names_only_packages_that_install_on_bookworm(extra):
    for req in map(Requirement, PROJECT["optional-dependencies"][extra]):
        name = req.name.lower()
        if name == DIST:  # an extra made of other extras
            assert req.extras <= set(PROJECT["optional-dependencies"]) - {extra}, req
            continue
        assert name not in NOT_ON_BOOKWORM, (
            f"extra {extra!r}: {req} cannot install on Debian bookworm: "
            f"{NOT_ON_BOOKWORM[name]}")
        assert name in INSTALLS_ON_BOOKWORM, (
            f"extra {extra!r}: {req} is not known to install on a fresh bookworm "
            "machine; check it there and add it to INSTALLS_ON_BOOKWORM")
        floor = _floor(req.specifier)
        known = Version(INSTALLS_ON_BOOKWORM[name])
        assert floor is not None and floor >= known, (
            f"extra {extra!r}: {req} admits releases below {known}, the oldest checked")


def test_the_system_cholmod_needs_no_extra():
    # CHOLMOD comes from the system library through ctypes (make installs it), not
    # from scikit-sparse, which cannot install on bookworm from a wheel.
    assert "cholmod" not in PROJECT["optional-dependencies"]
    makefile = (ROOT / "Makefile").read_text(encoding="utf-8")
    assert "scikit-sparse" not in makefile and "install-cholmod" not in makefile


# --------------------------------------------------------------------------- floors
def _used_names(path: Path) -> dict[str, int]:
    """Fully qualified names of modules' attributes used in a file, with a line each."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    alias: dict[str, str] = {}
    used: dict[str, int] = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                alias[a.asname or a.name.split(".")[0]] = a.name if a.asname else \
                    a.name.split(".")[0]
                used.setdefault(a.name, node.lineno)
        elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
            used.setdefault(node.module, node.lineno)
            for a in node.names:
                alias[a.asname or a.name] = f"{node.module}.{a.name}"
                used.setdefault(f"{node.module}.{a.name}", node.lineno)
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute):
            parts = []
            cur: ast.expr = node
            while isinstance(cur, ast.Attribute):
                parts.append(cur.attr)
                cur = cur.value
            if isinstance(cur, ast.Name) and cur.id in alias:
                name = ".".join([alias[cur.id], *reversed(parts)])
                used.setdefault(name, node.lineno)
    return used


def _uses() -> dict[str, str]:
    """Every name of API_SINCE used in src/stbs (or a longer name under it) -> where."""
    found: dict[str, str] = {}
    for path in sorted(SRC.rglob("*.py")):
        for name, line in _used_names(path).items():
            for api in API_SINCE:
                if name == api or name.startswith(api + "."):
                    found.setdefault(api, f"{path.relative_to(ROOT)}:{line}")
    return found


def test_the_scan_sees_the_code_base():
    names = set().union(*(_used_names(p) for p in SRC.rglob("*.py")))
    assert {"numpy.zeros", "scipy.sparse.csr_array", "numba.njit"} <= names


def test_core_floors_cover_the_newer_apis_the_code_uses():
    floors = _floors()
    bad = []
    for api, where in sorted(_uses().items()):
        pkg, since = API_SINCE[api]
        floor = floors.get(pkg)
        if floor is None or floor < Version(since):
            bad.append(f"{where}: {api} needs {pkg}>={since}, the floor is {pkg} {floor}")
    assert not bad, "raise the floors in pyproject.toml:\n" + "\n".join(bad)


def test_every_core_dependency_has_a_floor_and_the_known_ones():
    floors = _floors()
    assert all(floors.values()), floors
    # what running the suite on older releases showed (docs/dependencies.md)
    assert floors["scipy"] >= Version("1.15")    # csgraph.dijkstra on int64 indices
    assert floors["numpy"] >= Version("1.25")    # 1.24's float64 sin differs from libm
    assert floors["python"] >= Version("3.11")   # the platform; CI runs nothing older


def test_the_linters_target_is_the_python_floor():
    py = _floor(PROJECT["requires-python"])
    assert PYPROJECT["tool"]["ruff"]["target-version"] == f"py{py.major}{py.minor}"
    assert f"Programming Language :: Python :: {py.major}.{py.minor}" in PROJECT["classifiers"]


# --------------------------------------------------------------------------- the wheel's files
def _package_files() -> list[Path]:
    skip = {"__pycache__"}
    return [p for p in SRC.rglob("*") if p.is_file() and not skip & set(p.parts)
            and p.suffix not in (".pyc", ".nbi", ".nbc")]


def test_every_folder_of_python_files_is_a_package():
    # packages.find (not find_namespace) leaves out a folder without __init__.py: its
    # modules would be missing from the wheel
    folders = {p.parent for p in _package_files() if p.suffix == ".py"}
    missing = sorted(str(d.relative_to(ROOT)) for d in folders if not (d / "__init__.py").exists())
    assert not missing, f"no __init__.py (left out of the wheel): {missing}"


def test_every_data_file_is_package_data():
    # a file other than .py reaches the wheel only through [tool.setuptools.package-data]
    patterns = PYPROJECT["tool"]["setuptools"].get("package-data", {}).get("stbs", [])
    data = [p.relative_to(SRC).as_posix() for p in _package_files() if p.suffix != ".py"]
    left = [f for f in data if not any(fnmatch.fnmatch(f, pat) for pat in patterns)]
    assert not left, f"not in [tool.setuptools.package-data] stbs = {patterns}: {left}"


# --------------------------------------------------------------------------- version
def test_the_version_has_one_source():
    assert "version" not in PROJECT
    assert "version" in PROJECT.get("dynamic", [])
    attr = PYPROJECT["tool"]["setuptools"]["dynamic"]["version"]["attr"]
    assert attr == "stbs.__version__"
    # setuptools reads it without importing the package: a plain string literal
    text = (SRC / "__init__.py").read_text(encoding="utf-8")
    assert re.search(r'^__version__ = "[0-9][^"]*"$', text, re.M)


def test_stbs_version_is_the_installed_metadata_version():
    import stbs
    from stbs.cli import main

    meta = importlib.metadata.version(DIST)
    assert stbs.__version__ == meta
    script = shutil.which("stbs", path=str(Path(sys.executable).parent))
    assert script, f"no 'stbs' console script beside {sys.executable} (make install-test)"
    out = subprocess.run([script, "--version"], capture_output=True, text=True, check=True,
                         timeout=120)
    assert out.stdout.strip() == f"stbs {meta}"
    assert main(["--version"]) == 0
