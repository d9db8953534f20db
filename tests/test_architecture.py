"""The layout shows the architecture: maths, then data, then front ends.

Walks every import statement in ``src/stbs`` (lazy ones inside functions too) with
``ast`` and fails on an import against the layering, naming the file and line:

- no module of the maths tier imports the data tier or a front end, and no module of
  the data tier imports a front end (front ends depend on the core, never the
  reverse);
- no subpackage imports another subpackage's private modules or private names
  (those starting with ``_``); the package root's own private helpers
  (``stbs._checks``, ``stbs._optional``, ``stbs._jit``, ``stbs._json``,
  ``stbs._inputs``) serve every tier.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "stbs"

MATHS = {"_checks", "_arrays", "_optional", "_jit", "_json", "_inputs", "methods", "geometry",
         "transforms", "skeleton", "pose", "clip", "motion", "retargeting", "skinning", "weights",
         "meshing", "shapes", "skin"}
DATA = {"rig", "io", "fit"}
FRONT = {"cli", "demo", "bench", "viewer", "bake"}
TIER = {**{m: 0 for m in MATHS}, **{m: 1 for m in DATA}, **{m: 2 for m in FRONT}}
NAMES = ("maths", "data", "front end")


def _modules():
    for p in sorted(SRC.rglob("*.py")):
        rel = p.relative_to(SRC.parent).with_suffix("")
        parts = list(rel.parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        yield p, parts


def _imports(path: Path, parts: list[str]):
    """(line, imported module as parts, imported names) for every import of stbs."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    package = parts if path.name == "__init__.py" else parts[:-1]
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                if a.name.split(".")[0] == "stbs":
                    yield node.lineno, a.name.split("."), []
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[:len(package) - node.level + 1]
                mod = base + (node.module.split(".") if node.module else [])
            elif node.module and node.module.split(".")[0] == "stbs":
                mod = node.module.split(".")
            else:
                continue
            names = [a.name for a in node.names]
            # "from . import x" / "from .. import io": x may be a module
            yield node.lineno, mod, names


def _top(parts: list[str]) -> str | None:
    return parts[1] if len(parts) > 1 else None


def violations() -> list[str]:
    out = []
    for path, parts in _modules():
        here = _top(parts)
        if here is None:            # stbs/__init__.py: the public facade
            continue
        here_tier = TIER.get(here)
        for line, mod, names in _imports(path, parts):
            where = f"{path.relative_to(SRC.parent)}:{line}"
            targets = [mod] if not names else [mod + [n] for n in names]
            for t in targets:
                other = _top(t)
                if other is None or other not in TIER:
                    continue
                if here_tier is not None and TIER[other] > here_tier:
                    out.append(f"{where}: {NAMES[here_tier]} module {'.'.join(parts)} imports "
                               f"{NAMES[TIER[other]]} {'.'.join(t[:3])}")
                if other != here and not other.startswith("_"):
                    private = [p for p in t[2:] if p.startswith("_")]
                    if private:
                        out.append(f"{where}: {'.'.join(parts)} imports {'.'.join(t)}, private "
                                   f"to stbs.{other}")
    return out


def test_every_top_level_module_has_a_tier():
    tops = {p.stem for p in SRC.glob("*.py")} | {p.parent.name for p in SRC.glob("*/__init__.py")}
    missing = sorted(tops - set(TIER) - {"__init__", "__main__"})
    assert not missing, f"modules without a tier in this test: {missing}"


def test_imports_follow_the_layers():
    bad = violations()
    assert not bad, "\n".join(bad)


@pytest.mark.parametrize("source, expect", [
    ("from ..cli import main\n", "imports front end stbs.cli"),
    ("from ..io._atomic import atomic_open\n", "private to stbs.io"),
    ("from ..weights.bbw import _blas_threads\n", "private to stbs.weights"),
    ("from ..io import read_mesh\n", "imports data stbs.io"),
])
def test_the_walk_catches_what_it_should(tmp_path, monkeypatch, source, expect):
    # A fake maths module placed in a copy of the layout: the check must name it.
    root = tmp_path / "stbs"
    (root / "meshing").mkdir(parents=True)
    (root / "__init__.py").write_text("")
    (root / "meshing" / "__init__.py").write_text("")
    (root / "meshing" / "bad.py").write_text(source)
    monkeypatch.setattr(__import__(__name__), "SRC", root)
    assert any(expect in v for v in violations()), violations()


def test_the_file_formats_load_without_the_compiled_kernels():
    # the io writers take baked frames; stbs.bake skins them, so reading and writing
    # files never pays for numba
    code = "import sys, stbs.io, stbs.io.gltf; print('numba' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "False", out.stdout + out.stderr


def test_the_four_heaviest_bones_are_chosen_in_one_place():
    # glTF, OpenUSD, the viewer and the bake all take stbs.skinning.layout.four_heaviest,
    # so a vertex's four bones (and the tie rule among equal weights) agree everywhere
    found = []
    for path, parts in _modules():
        if parts[:2] == ["stbs", "skinning"]:
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Call) and getattr(node.func, "id",
                                                      getattr(node.func, "attr", None)) \
                    == "top_k" and any(k.arg == "max_influences" for k in node.keywords):
                found.append(f"{path.relative_to(SRC)}:{node.lineno}")
    assert not found, f"use four_heaviest instead of top_k(max_influences=...) at {found}"


def _method_lists() -> dict[frozenset, str]:
    tree = ast.parse((SRC / "methods.py").read_text(encoding="utf-8"))
    return {frozenset(ast.literal_eval(node.value)): node.targets[0].id
            for node in tree.body if isinstance(node, ast.Assign)
            and isinstance(node.value, ast.Tuple)}


def test_the_method_lists_import_nothing():
    tree = ast.parse((SRC / "methods.py").read_text(encoding="utf-8"))
    imports = [n.lineno for n in ast.walk(tree) if isinstance(n, (ast.Import, ast.ImportFrom))]
    assert not imports, f"stbs/methods.py must import nothing (lines {imports})"
    assert set(_method_lists().values()) == {"SKINNING_METHODS", "BONE_METHODS",
                                             "ENDPOINT_METHODS"}


#: Copies of a method list in modules that take it from stbs.methods later (they are
#: another piece of work's files); the test below fails once a copy here is gone, so
#: the list only shrinks.
KNOWN_COPIES = {"weights/endpoint.py": "ENDPOINT_METHODS"}


def _typed_lists(path: Path, lists: dict[frozenset, str]) -> list[tuple[int, str]]:
    """(line, name) of each tuple, list or set literal of strings equal (as a set) to one
    of ``lists``; ``Literal[...]`` annotations, which cannot name a variable, excepted."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    in_literal = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Subscript) and getattr(
                node.value, "id", getattr(node.value, "attr", None)) == "Literal":
            in_literal.update(id(x) for x in ast.walk(node.slice))
    found = []
    for node in ast.walk(tree):
        if isinstance(node, (ast.Tuple, ast.List, ast.Set)) and id(node) not in in_literal \
                and node.elts and all(isinstance(e, ast.Constant) and isinstance(e.value, str)
                                      for e in node.elts):
            name = lists.get(frozenset(e.value for e in node.elts))
            if name:
                found.append((node.lineno, name))
    return found


def test_no_module_types_a_method_list_again():
    lists = _method_lists()
    typed, stale = [], []
    for path, _ in _modules():
        rel = path.relative_to(SRC).as_posix()
        if rel == "methods.py":
            continue
        found = _typed_lists(path, lists)
        if rel in KNOWN_COPIES:
            if KNOWN_COPIES[rel] not in {name for _, name in found}:
                stale.append(rel)
            continue
        typed += [f"{rel}:{line} {name}" for line, name in found]
    assert not typed, f"import these from stbs.methods instead: {typed}"
    assert not stale, f"no copy left in {stale}: drop it from KNOWN_COPIES"


def test_the_method_list_check_finds_a_copy(tmp_path):
    # the check above can fail: a module that types the list is found
    path = tmp_path / "copy.py"
    path.write_text('M = ("stbs-dqs", "lbs", "dqs", "stbs-lbs")\n'
                    'x: Literal["lbs", "dqs", "stbs-lbs", "stbs-dqs"]\n')
    assert _typed_lists(path, _method_lists()) == [(1, "SKINNING_METHODS")]


def import_graph() -> dict[str, dict[str, int]]:
    """module -> {module it imports: first line}, for every import in src/stbs (module
    level and inside functions); ``from P import x`` names the module ``P.x`` when there
    is one, else ``P``."""
    paths = dict((".".join(parts), p) for p, parts in _modules())
    graph: dict[str, dict[str, int]] = {}
    for name, path in paths.items():
        edges = graph.setdefault(name, {})
        for line, mod, names in _imports(path, name.split(".")):
            base = ".".join(mod)
            targets = [f"{base}.{n}" for n in names if f"{base}.{n}" in paths] or [base]
            if len(targets) < len(names) and base in paths:
                targets.append(base)
            for t in targets:
                if t in paths and t != name:
                    edges.setdefault(t, line)
    return graph


def import_cycles(graph: dict[str, dict[str, int]]) -> list[list[str]]:
    """One cycle (a list of modules, the first repeated at the end) per strongly
    connected component of more than one module (Tarjan, iterative)."""
    index, low, on, stack, comps, counter = {}, {}, set(), [], [], [0]
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(graph[root]))]
        index[root] = low[root] = counter[0]
        counter[0] += 1
        stack.append(root)
        on.add(root)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = counter[0]
                    counter[0] += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(graph.get(w, {}))))
                elif w in on:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = []
                while True:
                    w = stack.pop()
                    on.discard(w)
                    comp.append(w)
                    if w == v:
                        break
                if len(comp) > 1:
                    comps.append(comp)
    return [_cycle_in(graph, set(c)) for c in comps]


def _cycle_in(graph, comp: set[str]) -> list[str]:
    """A shortest cycle through the component's first module (breadth first)."""
    start = min(comp)
    prev, frontier = {start: None}, [start]
    while frontier:
        nxt = []
        for v in frontier:
            for w in graph[v]:
                if w == start:
                    path = [v]
                    while prev[path[-1]] is not None:
                        path.append(prev[path[-1]])
                    return [*reversed(path), start]
                if w in comp and w not in prev:
                    prev[w] = v
                    nxt.append(w)
        frontier = nxt
    return sorted(comp)


def test_no_import_cycles():
    graph = import_graph()
    cycles = [" -> ".join(f"{a} (line {graph[a][b]})" if b else a
                          for a, b in zip(c, [*c[1:], None], strict=True))
              for c in import_cycles(graph)]
    assert not cycles, "import cycles:\n" + "\n".join(cycles)


def test_the_cycle_check_finds_a_cycle():
    # the check above can fail: a loop of three modules is found and named
    graph = {"a": {"b": 1}, "b": {"c": 2}, "c": {"a": 3, "d": 4}, "d": {}}
    assert import_cycles(graph) == [["a", "b", "c", "a"]]
    assert import_cycles({"a": {"b": 1}, "b": {}}) == []
