"""Bounded biharmonic weights on this machine (``stbs bench --weights``).

Each solve case builds a mesh with the skeleton's samples among its vertices, takes
the boundary conditions ``b``, ``bc`` of :func:`stbs.weights.boundary_conditions`
(the first ``m`` functions) and times ``BBWSolver(V, Ele, backend=...)`` followed by
``.solve(b, bc, tol=...)`` (matrices, factorization and the bounded solve, as a user
pays them). The result is checked against the KKT conditions of the QP (the natural
residual, :func:`kkt_residual`). Meshing is timed apart and never counted.

The ``rig-*`` case makes a complete rig the way a user would, through the library's
pipeline :func:`stbs.build_rig` (bone weights by BBW, then endpoint weights by BBW
restricted to each bone's support), timed per stage.

Meshes (deterministic, rebuilt each run):

- 2D: a wavy blob around a 3-bone chain, :func:`stbs.triangulate_2d` with the bones
  inserted as constrained segments;
- 3D: a built-in ellipsoid around a straight 20-bone chain, tetrahedralized by
  :func:`stbs.tetrahedralize` with the bones inserted as vertices; or, given a folder
  holding libigl's tutorial ``hand.mesh`` and ``hand.tgf`` (``mesh_dir``,
  ``--mesh-dir``), the surface of that hand with its 20 bones.

Nothing here touches the network or starts a process. Docs: ``docs/benchmarks.md``.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..skeleton import Skeleton
from .report import (
    check_json_path,
    cpu_model,
    int_at_least,
    load_average,
    machine_lines,
    platform_name,
    positive_float,
    quiet,
    write_json,
)

__all__ = ["CASES", "DEFAULT_CASES", "BACKENDS", "DEFAULT_TOL", "HAND_FILES", "COLUMNS",
           "CaseSpec", "Problem", "make_problem", "boundary", "bilaplacian", "kkt_residual",
           "warm_up", "solve_case", "rig_case", "machine_info", "format_table", "format_rigs",
           "add_arguments", "collect", "run", "main"]

BACKENDS: tuple[str, ...] = ("auto", "cholmod", "cholespy", "scipy")
#: Our KKT tolerance unless --tol says otherwise (the rig pipeline's default too).
DEFAULT_TOL = 1e-6
#: What ``mesh_dir`` must hold: libigl's tutorial hand (tetrahedra) and its skeleton.
HAND_FILES = ("hand.mesh", "hand.tgf")

Log = Callable[[str], None]


@dataclass(frozen=True)
class CaseSpec:
    """One benchmark case.

    Attributes
    ----------
    name : str
    dim : int
        2 or 3.
    vertices : int
        The vertex count the mesh is made for (it has about this many); 0 for a mesh
        used as it is read.
    kind : {"solve", "rig"}
        A timed BBW solve of ``m`` functions, or a complete rig through the library.
    about : str
        One line for ``--help`` and the report.
    """

    name: str
    dim: int
    vertices: int
    kind: str
    about: str


CASES: dict[str, CaseSpec] = {c.name: c for c in (
    CaseSpec("2d-small", 2, 1_000, "solve", "2D blob, 3-bone chain, ~1k vertices"),
    CaseSpec("2d-5k", 2, 5_000, "solve", "2D blob, 3-bone chain, ~5k vertices"),
    CaseSpec("2d-20k", 2, 20_000, "solve", "2D blob, 3-bone chain, ~20k vertices"),
    CaseSpec("3d-10k", 3, 10_000, "solve",
             "20-bone surface tetrahedralized, ~10k vertices (built-in, or --mesh-dir's hand)"),
    CaseSpec("3d-50k", 3, 50_000, "solve",
             "20-bone surface tetrahedralized, ~50k vertices (built-in, or --mesh-dir's hand)"),
    CaseSpec("hand", 3, 0, "solve", "libigl's hand.mesh as shipped (needs --mesh-dir)"),
    CaseSpec("rig-50k", 3, 50_000, "rig",
             "complete 20-bone rig (bone + endpoint BBW) of the 3d-50k mesh"),
)}
DEFAULT_CASES: tuple[str, ...] = ("2d-5k", "2d-20k", "3d-10k", "3d-50k", "rig-50k")


# --------------------------------------------------------------------------- meshes
@dataclass
class Problem:
    """A mesh with a skeleton whose samples are among its vertices.

    Attributes
    ----------
    name : str
        The case.
    V : (n, d) float64
    Ele : (f, 3) or (t, 4) int64
        Triangles (2D) or tetrahedra (3D).
    sk : Skeleton
    source : str
        Where the mesh came from, one line.
    meshing_s : float
        Seconds spent meshing (0 for a mesh read as is); not part of any BBW time.
    """

    name: str
    V: np.ndarray
    Ele: np.ndarray
    sk: Skeleton
    source: str
    meshing_s: float

    @property
    def n(self) -> int:
        return int(self.V.shape[0])

    @property
    def element_kind(self) -> str:
        return "tri" if self.Ele.shape[1] == 3 else "tet"


def _blob_outline() -> tuple[np.ndarray, Skeleton, float]:
    """A wavy blob (200 outline points), a 3-bone chain inside it, and its area."""
    t = np.linspace(0, 2 * np.pi, 200, endpoint=False)
    r = 1 + 0.25 * np.sin(3 * t)
    outline = np.c_[2.2 * r * np.cos(t), r * np.sin(t)]
    C = np.array([[-1.5, 0.0], [-0.5, 0.1], [0.5, -0.1], [1.5, 0.0]])
    sk = Skeleton(C, np.array([[0, 1], [1, 2], [2, 3]]))
    area = 2.2 * np.pi * (1 + 0.25 ** 2 / 2)          # (1/2) * integral of (2.2 r) r dt
    return outline, sk, area


def _hand_folder(mesh_dir: str | os.PathLike | None) -> Path | None:
    """``mesh_dir`` checked to hold :data:`HAND_FILES`; None when not given.

    Raises
    ------
    ValueError
        ``mesh_dir`` is given but is not a folder holding both files.
    """
    if mesh_dir is None:
        return None
    folder = Path(mesh_dir)
    if not folder.is_dir():
        raise ValueError(f"--mesh-dir: {folder} is not a folder")
    absent = [f for f in HAND_FILES if not (folder / f).is_file()]
    if absent:
        raise ValueError(f"--mesh-dir: {folder} has no {' or '.join(absent)} (expected "
                         "libigl's tutorial hand.mesh and hand.tgf)")
    return folder


def _hand_surface(folder: Path) -> tuple[np.ndarray, np.ndarray, Skeleton, str]:
    """libigl's hand: the boundary triangles of ``hand.mesh`` (compacted) and ``hand.tgf``."""
    from ..io import read_mesh, read_tgf

    m = read_mesh(folder / "hand.mesh")
    C, BE = read_tgf(folder / "hand.tgf")
    used = np.unique(m.F)
    remap = np.full(m.V.shape[0], -1, dtype=np.int64)
    remap[used] = np.arange(used.size)
    return m.V[used], remap[m.F], Skeleton(C, BE), f"libigl hand surface ({folder})"


def _chain_surface(bones: int = 20) -> tuple[np.ndarray, np.ndarray, Skeleton, str]:
    """Built-in: an ellipsoid (4 x 1 x 1) around a straight chain of ``bones`` bones."""
    from ..shapes import cigar

    shape = cigar(30, half_length=2.0, radius=0.5)
    V, F = shape[0], shape[1]
    x = np.linspace(-1.6, 1.6, bones + 1)
    C = np.c_[x, np.zeros_like(x), np.zeros_like(x)]
    BE = np.c_[np.arange(bones), np.arange(1, bones + 1)]
    return V, F, Skeleton(C, BE), f"built-in ellipsoid around a {bones}-bone chain"


def _enclosed_volume(V: np.ndarray, F: np.ndarray) -> float:
    """Volume inside a closed, outward-oriented surface (divergence theorem)."""
    return abs(float(np.einsum("ij,ij->i", V[F[:, 0]], np.cross(V[F[:, 1]], V[F[:, 2]])).sum())
               / 6.0)


class _Meshes:
    """Builds the cases' meshes, each (shape, size) once per run: 3d-50k and rig-50k share."""

    def __init__(self, mesh_dir: str | os.PathLike | None = None, log: Log = quiet):
        self.folder = _hand_folder(mesh_dir)
        self.log = log
        self._done: dict[tuple, Problem] = {}
        self._surface = None

    def surface(self):
        if self._surface is None:
            if self.folder is None:
                self.log("3D cases: a built-in ellipsoid around a 20-bone chain (--mesh-dir "
                         "with libigl's hand.mesh and hand.tgf uses the hand instead)")
                self._surface = _chain_surface(20)
            else:
                self._surface = _hand_surface(self.folder)
        return self._surface

    def get(self, name: str) -> Problem:
        spec = CASES[name]
        key = (spec.dim, spec.vertices)
        if key not in self._done:
            self._done[key] = self._build(spec)
        P = self._done[key]
        return Problem(name, P.V, P.Ele, P.sk, P.source, P.meshing_s)

    def _build(self, spec: CaseSpec) -> Problem:
        from ..meshing import tetrahedralize, triangulate_2d

        if spec.dim == 2:
            outline, sk, area = _blob_outline()
            self.log(f"{spec.name}: triangulating")
            t = time.perf_counter()
            # Measured with Triangle (30-degree bound): about 0.8 area / max_area vertices
            tm = triangulate_2d(outline, sk, max_area=0.8 * area / spec.vertices)
            return Problem(spec.name, tm.V, tm.F, sk, f"2D wavy blob, {tm.engine}",
                           time.perf_counter() - t)
        if spec.vertices == 0:              # "hand": libigl's own tetrahedral mesh
            return self._hand_as_shipped(spec)
        V, F, sk, source = self.surface()
        # Measured on the hand and the ellipsoid (TetGen, radius-edge 2): about 0.235
        # inner vertices per max_volume of enclosed volume; the surface is kept.
        inner = max(spec.vertices - V.shape[0], spec.vertices // 10)
        max_volume = 0.235 * _enclosed_volume(V, F) / inner
        self.log(f"{spec.name}: tetrahedralizing ({source})")
        t = time.perf_counter()
        with warnings.catch_warnings():
            # a TetGen failure falls back to the builtin mesher with a warning; the
            # row's source names the engine that made the mesh
            warnings.simplefilter("ignore")
            tm = tetrahedralize(V, F, sk, max_volume=max_volume)
        return Problem(spec.name, tm.V, tm.T, sk, f"{source}, {tm.engine}",
                       time.perf_counter() - t)

    def _hand_as_shipped(self, spec: CaseSpec) -> Problem:
        from ..io import read_mesh, read_tgf

        if self.folder is None:
            raise ValueError(_needs_mesh_dir(spec.name))
        m = read_mesh(self.folder / "hand.mesh")
        C, BE = read_tgf(self.folder / "hand.tgf")
        return Problem(spec.name, m.V, m.T, Skeleton(C, BE),
                       f"libigl hand.mesh ({self.folder})", 0.0)


def _needs_mesh_dir(case: str) -> str:
    return (f"case {case!r} needs --mesh-dir DIR, a folder holding libigl's tutorial "
            "hand.mesh and hand.tgf")


def make_problem(name: str, *, mesh_dir: str | os.PathLike | None = None,
                 log: Log = quiet) -> Problem:
    """The mesh of case ``name`` (one of :data:`CASES`).

    Parameters
    ----------
    name : str
    mesh_dir : path, optional
        A folder holding libigl's ``hand.mesh`` and ``hand.tgf``: the 3D cases then
        tetrahedralize the hand's surface, and the ``hand`` case (which needs it) uses
        the mesh as it is.
    log : callable
        Progress messages.
    """
    if name not in CASES:
        raise ValueError(f"case must be one of {', '.join(CASES)}, got {name!r}")
    return _Meshes(mesh_dir, log).get(name)


def boundary(P: Problem) -> tuple[np.ndarray, np.ndarray]:
    """``b`` (k,) and ``bc`` (k, b) of :func:`stbs.weights.boundary_conditions` on ``P``."""
    from ..weights import boundary_conditions

    tri = P.Ele.shape[1] == 3
    return boundary_conditions(P.V, P.sk, F=P.Ele if tri else None, T=None if tri else P.Ele)


# --------------------------------------------------------------------------- checks
def bilaplacian(V: np.ndarray, Ele: np.ndarray):
    """``Q = L M^-1 L`` (n, n) CSR, built independently of the solver (libigl's default
    mass matrix: voronoi for triangles, barycentric for tetrahedra)."""
    import scipy.sparse as sp

    from ..weights import cotmatrix, massmatrix

    L = sp.csr_array(cotmatrix(V, Ele))
    m = massmatrix(V, Ele).diagonal()
    minv = np.divide(1.0, m, out=np.zeros_like(m), where=m > 0)
    return sp.csr_array(L @ sp.diags_array(minv) @ L)


def kkt_residual(Q, W: np.ndarray, b: np.ndarray) -> float:
    """Natural KKT residual of the BBW QP, in weight units.

    ``max |x - clip(x - g / diag Q, 0, 1)|`` over the unconstrained vertices, with
    ``g = (Q W)`` the gradient of ``1/2 w^T Q w``: 0 exactly at the bounded minimiser.

    Parameters
    ----------
    Q : (n, n) sparse
        Bilaplacian (:func:`bilaplacian`).
    W : (n, m) float
        Weights, ``W[b] = bc``.
    b : (k,) int
        Constrained vertices.
    """
    import scipy.sparse as sp

    from ..weights import kkt_residual as box_kkt_residual

    W = np.asarray(W, dtype=float)
    U = np.setdiff1d(np.arange(W.shape[0]), b)
    if not U.size:
        return 0.0
    Q = sp.csr_array(Q)
    QU = Q[U]
    # the QP over the free vertices: min 1/2 w_U^T Q_UU w_U + (Q_Ub W_b)^T w_U, 0 <= w_U <= 1
    return float(np.max(box_kkt_residual(QU[:, U], W[U], QU[:, b] @ W[b])))


# --------------------------------------------------------------------------- cases
_WARM: set = set()


def warm_up(backend: str = "auto", *, tol: float = DEFAULT_TOL) -> None:
    """Solve the ``2d-small`` case once per process and backend before anything is timed.

    The first BBW solve in a process also loads the compiled (numba) kernels from
    their cache, starts the solve threads and touches the Cholesky library for the
    first time: about 0.5 s that a long-running process pays once.
    """
    from ..weights import BBWSolver

    if ("stbs", backend) in _WARM:
        return
    P = make_problem("2d-small")
    b, bc = boundary(P)
    BBWSolver(P.V, P.Ele, backend=backend).solve(b, bc, tol=tol)
    _WARM.add(("stbs", backend))


def solve_case(P: Problem, *, functions: int = 3, backend: str = "auto", repeat: int = 1,
               tol: float = DEFAULT_TOL, return_weights: bool = False,
               log: Log = quiet) -> dict | tuple[dict, np.ndarray]:
    """Time our BBW on ``P`` with its ``b`` and the first ``functions`` columns of ``bc``;
    best of ``repeat`` runs.

    Returns
    -------
    row : dict
        ``case, kind ("solve"), vertices, elements, element_kind, functions,
        constrained, meshing_s, source, repeat, tol, stbs_s, backend, converged,
        kkt_stbs`` (:func:`kkt_residual` of the result) and ``kkt_stbs_reported`` (the
        solver's own). Times in seconds.
    W : (n, functions) float64
        Only with ``return_weights``: the weights of the best run.
    """
    from ..weights import BBWSolver

    b, bc = boundary(P)
    m = min(int(functions), bc.shape[1])
    bc = np.ascontiguousarray(bc[:, :m])
    row = {"case": P.name, "kind": "solve", "vertices": P.n, "elements": int(P.Ele.shape[0]),
           "element_kind": P.element_kind, "functions": m, "constrained": int(b.size),
           "meshing_s": P.meshing_s, "source": P.source, "repeat": int(repeat), "tol": tol}
    best, W, report = np.inf, None, None
    warm_up(backend, tol=tol)
    for r in range(int(repeat)):
        log(f"{P.name}: BBW ({P.n:,} vertices, m={m}, backend {backend}), "
            f"run {r + 1}/{repeat}")
        t = time.perf_counter()
        solver = BBWSolver(P.V, P.Ele, backend=backend)
        Wr = solver.solve(b, bc, tol=tol)
        dt = time.perf_counter() - t
        if dt < best:
            best, W, report = dt, Wr, solver.last_report
    row["stbs_s"] = best
    row["backend"] = getattr(report, "backend", backend)
    row["converged"] = bool(getattr(report, "all_converged", True))
    res = getattr(report, "kkt_residual", None)
    row["kkt_stbs_reported"] = None if res is None else float(np.max(res))
    row["kkt_stbs"] = kkt_residual(bilaplacian(P.V, P.Ele), W, b)
    return (row, W) if return_weights else row


def _stage_clock(marks: list) -> Callable[[str, int, int], None]:
    """A ``build_rig`` progress callback that appends ``(stage, start time)`` to ``marks``."""
    def progress(stage: str, done: int, total: int) -> None:
        if done == 0 and total == 0:          # a stage starts
            marks.append((stage, time.perf_counter()))
    return progress


def rig_case(P: Problem, *, repeat: int = 1, tol: float = DEFAULT_TOL,
             log: Log = quiet) -> dict:
    """A complete rig of ``P`` through :func:`stbs.build_rig` (bone weights by BBW, then
    endpoint weights by BBW restricted to each bone's support, KKT tolerance ``tol``),
    timed per stage; the best total of ``repeat`` runs.

    A tetrahedral ``P`` is given as ``T``, used as it is; a 2D ``P`` as ``F`` (the
    pipeline re-triangulates its outline with the bones inside, a stage of its own).

    Returns
    -------
    dict
        ``case, kind ("rig"), vertices, elements, element_kind, bones, meshing_s,
        source, repeat, tol, stages`` (stage name to seconds, in order), ``total_s`` (the
        wall time of ``build_rig``), ``W_row_sum_error`` and ``E_range``.
    """
    from ..rig import build_rig

    mesh = {"F": P.Ele} if P.Ele.shape[1] == 3 else {"T": P.Ele}
    best = None
    warm_up(tol=tol)
    for r in range(int(repeat)):
        log(f"{P.name}: complete rig ({P.n:,} vertices, {P.sk.n_bones} bones), "
            f"run {r + 1}/{repeat}")
        marks: list[tuple[str, float]] = []
        t0 = time.perf_counter()
        rig = build_rig(P.V, P.sk, bone="bbw", endpoint="bbw", tol=tol,
                        progress=_stage_clock(marks), **mesh)
        t1 = time.perf_counter()
        total = t1 - t0
        ends = [t for _, t in marks[1:]] + [t1]
        stages = {name: end - start for (name, start), end in zip(marks, ends, strict=True)}
        if best is None or total < best[0]:
            best = (total, stages, rig)
    total, stages, rig = best
    W = rig.W.toarray() if hasattr(rig.W, "toarray") else np.asarray(rig.W)
    E = rig.E.toarray() if hasattr(rig.E, "toarray") else np.asarray(rig.E)
    return {"case": P.name, "kind": "rig", "vertices": P.n, "elements": int(P.Ele.shape[0]),
            "element_kind": P.element_kind, "bones": P.sk.n_bones, "meshing_s": P.meshing_s,
            "source": P.source, "repeat": int(repeat), "tol": float(tol), "stages": stages,
            "total_s": total, "W_row_sum_error": float(np.abs(W.sum(axis=1) - 1).max()),
            "E_range": [float(E.min()), float(E.max())]}


# --------------------------------------------------------------------------- report
def _f(x, spec: str, missing: str = "-") -> str:
    return missing if x is None else format(x, spec)


COLUMNS = ("case", "vertices", "elements", "m", "stbs s", "KKT", "backend")


def format_table(rows: Sequence[dict], machine: dict | None = None,
                 settings: dict | None = None) -> str:
    """A plain-text report: the solve cases' table, then each rig's stages."""
    lines = machine_lines(machine, f"Python {machine.get('python')}, NumPy "
                          f"{machine.get('numpy')}, SciPy {machine.get('scipy')}",
                          "times") if machine else []
    if settings:
        lines.append(f"tol {settings['tol']:g}; best of {settings['repeat']} run(s)")
    lines.append("stbs s = BBWSolver(V, Ele) + solve (matrices, factorization, bounded "
                 "solve); meshing not counted; KKT = natural residual of the QP, in weight "
                 "units")
    lines.append("warmed up by one untimed solve of a small problem (loads compiled "
                 "kernels, starts threads)")
    solve_rows = [r for r in rows if r["kind"] == "solve"]
    if solve_rows:
        w = (9, 9, 12, 3, 8, 8, 8)
        head = "  ".join(f"{c:<{w[i]}}" if i in (0, 6) else f"{c:>{w[i]}}"
                         for i, c in enumerate(COLUMNS))
        lines += ["", head.rstrip(), "-" * len(head.rstrip())]
        for r in solve_rows:
            cells = (r["case"], f"{r['vertices']:,}", f"{r['elements']:,} {r['element_kind']}",
                     str(r["functions"]), f"{r['stbs_s']:.2f}", f"{r['kkt_stbs']:.0e}",
                     r["backend"])
            lines.append("  ".join(f"{c:<{w[i]}}" if i in (0, 6) else f"{c:>{w[i]}}"
                                   for i, c in enumerate(cells)).rstrip())
        lines.append("")
        for r in solve_rows:
            extra = "" if r["converged"] else "; did NOT reach tol on every function"
            lines.append(f"{r['case']}: {r['source']}; meshing {r['meshing_s']:.1f} s; "
                         f"{r['constrained']} constrained vertices{extra}")
    return "\n".join(lines + format_rigs(rows))


def format_rigs(rows: Sequence[dict]) -> list[str]:
    """The report's lines for the rig rows among ``rows``: each stage's time, the total."""
    lines = []
    for r in rows:
        if r["kind"] != "rig":
            continue
        lines += ["", f"complete rig: {r['case']}, {r['vertices']:,} vertices, "
                      f"{r['elements']:,} {r['element_kind']}, {r['bones']} bones "
                      f"({r['source']}; meshing {r['meshing_s']:.1f} s, not counted)"]
        for k, v in r["stages"].items():
            lines.append(f"  {k:<30} {v:8.2f} s")
        lines.append(f"  {'total (stbs.build_rig)':<30} {r['total_s']:8.2f} s")
    return lines


def machine_info() -> dict:
    """CPU model, core count, load and library versions (no heavy imports)."""
    from importlib.metadata import PackageNotFoundError, version

    info = {"cpu": cpu_model(), "cpus": os.cpu_count(), "python": platform.python_version(),
            "platform": platform_name(), "numpy": np.__version__,
            "load_average": load_average()}
    for dist in ("scipy", "cholespy", "scikit-sparse", "tetgen", "triangle"):
        try:
            info[dist] = version(dist)
        except PackageNotFoundError:
            pass
    return info


# --------------------------------------------------------------------------- command line
def _parse_cases(text: str) -> tuple[str, ...]:
    out = tuple(s.strip() for s in str(text).split(",") if s.strip())
    if out == ("all",):
        return tuple(CASES)
    bad = [s for s in out if s not in CASES]
    if bad or not out:
        raise argparse.ArgumentTypeError(
            f"cases must be a comma-separated list from {', '.join(CASES)} (or all), "
            f"got {bad[0] if bad else text!r}")
    return tuple(dict.fromkeys(out))


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add ``stbs bench --weights``'s options to ``parser``."""
    parser.add_argument("--weights", action="store_true",
                        help="time bounded biharmonic weights (this mode)")
    parser.add_argument("--cases", type=_parse_cases, default=DEFAULT_CASES,
                        help=f"comma-separated cases (listed below), or all (default "
                             f"{','.join(DEFAULT_CASES)})")
    parser.add_argument("--mesh-dir", metavar="DIR", default=None,
                        help="a folder holding libigl's tutorial hand.mesh and hand.tgf: the "
                             "3D cases then tetrahedralize the hand (needed by the hand case)")
    parser.add_argument("--functions", type=int_at_least(1), default=3, metavar="M",
                        help="weight functions (columns of bc) in the solve cases "
                             "(default 3; capped at the skeleton's bones); the rig case "
                             "uses every bone")
    parser.add_argument("--repeat", type=int_at_least(1), default=1,
                        help="runs per case; the best is reported (default 1)")
    parser.add_argument("--backend", choices=BACKENDS, default="auto",
                        help="the sparse Cholesky backend in the solve cases (default "
                             "auto); the rig case uses the library's default")
    parser.add_argument("--tol", type=positive_float, default=DEFAULT_TOL,
                        help=f"KKT tolerance, solve and rig cases (default {DEFAULT_TOL:g})")
    parser.add_argument("--json", metavar="OUT.json", default=None,
                        help="also write machine, settings and rows as JSON "
                             "(written to a temporary file, then renamed)")


def collect(args: argparse.Namespace, *, log: Log = quiet,
            solve: Callable[..., dict] | None = None) -> dict:
    """Run the cases of parsed ``args`` (:func:`add_arguments`).

    ``solve(P, args, log)``, when given, replaces :func:`solve_case` for the solve cases
    (a script that times a peer beside ours returns its own rows).

    Returns
    -------
    dict
        The JSON document: ``schema``, ``benchmark`` ("weights"), ``machine``,
        ``settings``, ``rows``.

    Raises
    ------
    ValueError
        An unusable ``--mesh-dir``, or a case whose mesh needs it, before any solve.
    """
    meshes = _Meshes(args.mesh_dir, log)
    if meshes.folder is None and "hand" in args.cases:
        raise ValueError(_needs_mesh_dir("hand"))           # up front, before any solve
    settings = {"cases": list(args.cases), "functions": args.functions,
                "mesh_dir": None if args.mesh_dir is None else str(args.mesh_dir),
                "repeat": args.repeat, "backend": args.backend, "tol": args.tol}
    rows = []
    for name in args.cases:
        P = meshes.get(name)
        if CASES[name].kind == "rig":
            rows.append(rig_case(P, repeat=args.repeat, tol=args.tol, log=log))
        elif solve is not None:
            rows.append(solve(P, args, log))
        else:
            rows.append(solve_case(P, functions=args.functions, backend=args.backend,
                                   repeat=args.repeat, tol=args.tol, log=log))
    return {"schema": 1, "benchmark": "weights", "machine": machine_info(),
            "settings": settings, "columns": list(COLUMNS), "rows": rows}


def run(args: argparse.Namespace) -> int:
    """Run the cases of parsed ``args``; print the table; return 0.

    Raises
    ------
    ValueError
        An unusable ``--json`` or ``--mesh-dir`` path, or a case whose mesh is missing,
        before anything runs.
    """
    out = check_json_path(args.json)

    def log(msg: str) -> None:
        print(f"stbs bench --weights: {msg}", file=sys.stderr, flush=True)

    doc = collect(args, log=log)
    print(format_table(doc["rows"], doc["machine"], doc["settings"]))
    if out is not None:
        write_json(out, doc)
        log(f"wrote {out}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m stbs.bench --weights [options]``: the same as ``stbs bench --weights``;
    returns the exit status (2 and one line on stderr for a bad option)."""
    p = argparse.ArgumentParser(prog="stbs bench --weights",
                                description=__doc__.splitlines()[0],
                                epilog="cases:\n" + "".join(
                                    f"  {c.name:<10} {c.about}\n" for c in CASES.values()),
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    add_arguments(p)
    args = p.parse_args(argv)
    try:
        return run(args)
    except (ValueError, OSError) as exc:
        print(f"stbs bench --weights: error: {exc}", file=sys.stderr)
        return 2
