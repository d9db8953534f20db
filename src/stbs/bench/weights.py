"""Bounded biharmonic weights against libigl's ``igl.bbw`` (``stbs bench --weights``).

Each comparison case builds a mesh with the skeleton's samples among its vertices,
takes the boundary conditions ``b``, ``bc`` of :func:`stbs.weights.boundary_conditions`
(the first ``m`` functions), and gives *the same* ``b`` and ``bc`` to both solvers:

- ``stbs``: ``BBWSolver(V, E, backend=...)`` followed by ``.solve(b, bc, tol=...)``;
  both are timed, as ``igl.bbw`` also builds its matrices (L, M, Q) inside;
- ``igl.bbw``: libigl's Python binding with its default parameters (the ``bench``
  extra), run only up to ``igl_max_vertices`` vertices, since it takes minutes on
  large meshes.

Both results are checked against the KKT conditions of the same QP (the natural
residual, :func:`kkt_residual`), and against each other (``max |W_stbs - W_igl|``).
Meshing is timed apart and never counted in the BBW times.

The ``rig-*`` case makes a complete rig the way a user would, through the library:
``stbs.weights.bone_weights(..., method="bbw", T=T)`` then
``stbs.weights.endpoint_weights(..., method="bbw", W=W, T=T)``, timed per stage and
judged against the issue's goal (under 60 s for a 20-bone rig of a ~50k-vertex mesh).

Meshes (deterministic, rebuilt each run):

- 2D: a wavy blob around a 3-bone chain, :func:`stbs.triangulate_2d` with the bones
  inserted as constrained segments;
- 3D: the surface of libigl's ``hand.mesh`` (tutorial data, 20-bone ``hand.tgf``)
  tetrahedralized by :func:`stbs.tetrahedralize` with the bones inserted as vertices;
  without the shared data folder (:func:`stbs.io.shared_data.data_dir`), a built-in
  ellipsoid around a 20-bone chain (:func:`stbs.demo.shapes.cigar`) instead.

Docs: ``docs/benchmarks.md``. Timing lives here, never in the tests.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .skeleton import Skeleton

__all__ = ["CASES", "DEFAULT_CASES", "BACKENDS", "SPEEDUP_GOAL", "DIFF_GOAL", "RIG_GOAL_S",
           "CaseSpec", "Problem", "make_problem", "kkt_residual", "igl_bbw", "compare_case",
           "rig_case", "warm_up", "check_targets", "format_table", "add_arguments", "run", "main"]

#: The issue's goals: stbs at least 10x faster than igl.bbw with max |dW| <= 1e-3 on
#: every comparison case, and a complete 20-bone rig of a ~50k-vertex mesh in < 60 s.
SPEEDUP_GOAL, DIFF_GOAL, RIG_GOAL_S = 10.0, 1e-3, 60.0
BACKENDS: tuple[str, ...] = ("auto", "cholmod", "cholespy", "scipy")
DEFAULT_IGL_MAX_VERTICES = 20_000
#: stbs's KKT tolerance unless --tol says otherwise: the accuracy class of igl.bbw,
#: which stops at a natural residual of ~5e-7 (docs/bbw.md).
DEFAULT_TOL = 1e-6

Log = Callable[[str], None]


def _quiet(msg: str) -> None:
    pass


@dataclass(frozen=True)
class CaseSpec:
    """One benchmark case.

    Attributes
    ----------
    name : str
    dim : int
        2 or 3.
    vertices : int
        Target vertex count of the mesh (the mesh has about this many).
    kind : {"compare", "rig"}
        Against igl.bbw, or a complete rig through the library.
    about : str
        One line for ``--help`` and the report.
    goal : bool
        One of the issue's sizes, judged against the goals (the others are extras).
    """

    name: str
    dim: int
    vertices: int
    kind: str
    about: str
    goal: bool = True


CASES: dict[str, CaseSpec] = {c.name: c for c in (
    CaseSpec("2d-small", 2, 1_000, "compare", "2D blob, 3-bone chain, ~1k vertices (for tests)",
             goal=False),
    CaseSpec("2d-5k", 2, 5_000, "compare", "2D blob, 3-bone chain, ~5k vertices"),
    CaseSpec("2d-20k", 2, 20_000, "compare", "2D blob, 3-bone chain, ~20k vertices"),
    CaseSpec("3d-10k", 3, 10_000, "compare", "hand surface tetrahedralized, ~10k vertices"),
    CaseSpec("3d-50k", 3, 50_000, "compare", "hand surface tetrahedralized, ~50k vertices"),
    CaseSpec("hand", 3, 0, "compare", "libigl's hand.mesh as shipped (7,234 vertices)",
             goal=False),
    CaseSpec("rig-50k", 3, 50_000, "rig",
             "complete 20-bone rig (bone + endpoint BBW) of the ~50k-vertex hand mesh"),
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
    E : (f, 3) or (t, 4) int64
        Triangles (2D) or tetrahedra (3D).
    sk : Skeleton
    source : str
        Where the mesh came from, one line.
    meshing_s : float
        Seconds spent meshing (0 for a mesh read as is); not part of any BBW time.
    """

    name: str
    V: np.ndarray
    E: np.ndarray
    sk: Skeleton
    source: str
    meshing_s: float

    @property
    def n(self) -> int:
        return int(self.V.shape[0])

    @property
    def element_kind(self) -> str:
        return "tri" if self.E.shape[1] == 3 else "tet"


def _blob_outline() -> tuple[np.ndarray, Skeleton, float]:
    """A wavy blob (200 outline points), a 3-bone chain inside it, and its area."""
    t = np.linspace(0, 2 * np.pi, 200, endpoint=False)
    r = 1 + 0.25 * np.sin(3 * t)
    outline = np.c_[2.2 * r * np.cos(t), r * np.sin(t)]
    C = np.array([[-1.5, 0.0], [-0.5, 0.1], [0.5, -0.1], [1.5, 0.0]])
    sk = Skeleton(C, np.array([[0, 1], [1, 2], [2, 3]]))
    area = 2.2 * np.pi * (1 + 0.25 ** 2 / 2)          # (1/2) * integral of (2.2 r) r dt
    return outline, sk, area


def _hand_folder() -> Path | None:
    """The shared data's ``libigl-tutorial-data`` when it holds the hand, else None."""
    from .io.shared_data import data_dir

    root = data_dir()
    folder = None if root is None else root / "libigl-tutorial-data"
    if folder is None or not all((folder / f).is_file() for f in ("hand.mesh", "hand.tgf")):
        return None
    return folder


def _hand_surface() -> tuple[np.ndarray, np.ndarray, Skeleton, str] | None:
    """libigl's hand: the boundary triangles of ``hand.mesh`` (compacted) and ``hand.tgf``."""
    from .io import read_mesh, read_tgf

    folder = _hand_folder()
    if folder is None:
        return None
    m = read_mesh(folder / "hand.mesh")
    C, BE = read_tgf(folder / "hand.tgf")
    used = np.unique(m.F)
    remap = np.full(m.V.shape[0], -1, dtype=np.int64)
    remap[used] = np.arange(used.size)
    return m.V[used], remap[m.F], Skeleton(C, BE), f"libigl hand surface ({folder})"


def _chain_surface(bones: int = 20) -> tuple[np.ndarray, np.ndarray, Skeleton, str]:
    """Built-in stand-in: an ellipsoid (4 x 1 x 1) around a straight chain of ``bones`` bones."""
    from .demo.shapes import cigar

    V, F, _, _ = cigar(30, half_length=2.0, radius=0.5)
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

    def __init__(self, log: Log = _quiet):
        self.log = log
        self._done: dict[tuple, Problem] = {}
        self._surface = None

    def surface(self):
        if self._surface is None:
            self._surface = _hand_surface()
            if self._surface is None:
                self.log("shared data (libigl-tutorial-data/hand.mesh) not found: the 3D "
                         "cases use a built-in ellipsoid around a 20-bone chain instead")
                self._surface = _chain_surface(20)
        return self._surface

    def get(self, name: str) -> Problem:
        spec = CASES[name]
        key = (spec.dim, spec.vertices)
        if key not in self._done:
            self._done[key] = self._build(spec)
        P = self._done[key]
        return Problem(name, P.V, P.E, P.sk, P.source, P.meshing_s)

    def _build(self, spec: CaseSpec) -> Problem:
        from .meshing import tetrahedralize, triangulate_2d

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
        from .io import read_mesh, read_tgf

        folder = _hand_folder()
        if folder is None:
            raise ValueError(f"case {spec.name!r} needs the shared data folder "
                             "(libigl-tutorial-data/hand.mesh, hand.tgf); set STBS_DATA")
        m = read_mesh(folder / "hand.mesh")
        C, BE = read_tgf(folder / "hand.tgf")
        return Problem(spec.name, m.V, m.T, Skeleton(C, BE), f"libigl hand.mesh ({folder})", 0.0)


def make_problem(name: str, *, log: Log = _quiet) -> Problem:
    """The mesh of case ``name`` (one of :data:`CASES`)."""
    if name not in CASES:
        raise ValueError(f"case must be one of {', '.join(CASES)}, got {name!r}")
    return _Meshes(log).get(name)


def _boundary(P: Problem) -> tuple[np.ndarray, np.ndarray]:
    from .weights.boundary import boundary_conditions

    tri = P.E.shape[1] == 3
    return boundary_conditions(P.V, P.sk, F=P.E if tri else None, T=None if tri else P.E)


# --------------------------------------------------------------------------- checks
def bilaplacian(V: np.ndarray, E: np.ndarray):
    """``Q = L M^-1 L`` (n, n) CSR, built independently of either solver (libigl's default
    mass matrix: voronoi for triangles, barycentric for tetrahedra)."""
    import scipy.sparse as sp

    from .weights.laplacian import cotmatrix, massmatrix

    L = sp.csr_array(cotmatrix(V, E))
    m = massmatrix(V, E).diagonal()
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
    W = np.asarray(W, dtype=float)
    U = np.setdiff1d(np.arange(W.shape[0]), b)
    X = W[U]
    Z = (Q @ W)[U] / Q.diagonal()[U][:, None]
    return float(np.abs(X - np.clip(X - Z, 0.0, 1.0)).max()) if U.size else 0.0


# --------------------------------------------------------------------------- igl.bbw
_CHILD = """\
import sys, time
import numpy as np
import igl
z = np.load(sys.argv[1])
args = [np.ascontiguousarray(z[k]) for k in ("V", "E", "b", "bc")]
t = time.perf_counter()
W = igl.bbw(*args)
t = time.perf_counter() - t
np.savez(sys.argv[2], W=W, seconds=t)
"""


def igl_available() -> tuple[bool, str]:
    """Whether ``igl.bbw`` can run here, and if not, why (one phrase)."""
    if importlib.util.find_spec("igl") is None:
        return False, "libigl not installed: pip install 'stbs-skinning[bench]'"
    try:
        import igl
    except ImportError as exc:  # broken installation
        return False, f"import igl failed: {exc}"
    if not hasattr(igl, "bbw"):
        return False, "this libigl has no igl.bbw"
    return True, ""


def igl_bbw(V, E, b, bc, *, timeout: float | None = None) -> tuple[np.ndarray | None, float]:
    """Run ``igl.bbw(V, E, b, bc)`` (default parameters) and time it.

    Parameters
    ----------
    V : (n, d) float, E : (f, 3) or (t, 4) int, b : (k,) int, bc : (k, m) float
    timeout : float, optional
        Seconds. When given, igl runs in a child Python process (a C++ call cannot be
        interrupted in-process), which is killed after ``timeout`` seconds; the time
        is measured around ``igl.bbw`` in the child, so start-up is not counted.

    Returns
    -------
    W : (n, m) float64, or None when the time limit was reached
    seconds : float
        Wall time of ``igl.bbw`` (``timeout`` when it was reached).
    """
    V = np.ascontiguousarray(V, dtype=np.float64)
    E = np.ascontiguousarray(E, dtype=np.int64)
    b = np.ascontiguousarray(b, dtype=np.int64)
    bc = np.ascontiguousarray(bc, dtype=np.float64)
    if timeout is None:
        import igl

        t = time.perf_counter()
        W = igl.bbw(V, E, b, bc)
        return np.asarray(W), time.perf_counter() - t
    with tempfile.TemporaryDirectory(prefix="stbs-igl-bbw-") as d:
        src, dst = Path(d) / "in.npz", Path(d) / "out.npz"
        np.savez(src, V=V, E=E, b=b, bc=bc)
        try:
            subprocess.run([sys.executable, "-c", _CHILD, str(src), str(dst)], check=True,
                           capture_output=True, text=True, timeout=timeout, cwd=d)
        except subprocess.TimeoutExpired:
            return None, float(timeout)
        except subprocess.CalledProcessError as exc:
            tail = (exc.stderr or "").strip().splitlines()[-1:] or [f"exit status {exc.returncode}"]
            raise RuntimeError(f"igl.bbw failed in its child process: {tail[0]}") from None
        with np.load(dst) as z:
            return np.array(z["W"]), float(z["seconds"])


# --------------------------------------------------------------------------- cases
_WARM: set = set()


def warm_up(backend: str = "auto", *, igl: bool = False, tol: float = DEFAULT_TOL) -> None:
    """Solve the ``2d-small`` case once per process before anything is timed.

    The first BBW solve in a process also loads the compiled (numba) kernels from
    their cache, starts the solve threads and touches CHOLMOD for the first time:
    about 0.5 s that a long-running process pays once. ``igl.bbw`` is imported
    outside its timing too, so neither side's one-time start-up is counted.
    """
    from .weights.bbw import BBWSolver

    if ("stbs", backend) in _WARM and (not igl or "igl" in _WARM):
        return
    P = make_problem("2d-small")
    b, bc = _boundary(P)
    if ("stbs", backend) not in _WARM:
        BBWSolver(P.V, P.E, backend=backend).solve(b, bc, tol=tol)
        _WARM.add(("stbs", backend))
    if igl and "igl" not in _WARM:
        igl_bbw(P.V, P.E, b, bc)
        _WARM.add("igl")


def compare_case(P: Problem, *, functions: int = 3, backend: str = "auto", repeat: int = 1,
                 tol: float = DEFAULT_TOL, igl_max_vertices: int = DEFAULT_IGL_MAX_VERTICES,
                 igl_timeout: float | None = None, log: Log = _quiet) -> dict:
    """Time stbs's BBW and igl.bbw on ``P`` with the same ``b`` and the first
    ``functions`` columns of ``bc``; best of ``repeat`` runs each.

    Returns
    -------
    dict
        One row: ``case, vertices, elements, element_kind, functions, meshing_s,
        stbs_s, igl_s, igl_status ("ok" or why not), speedup, max_abs_dW, kkt_stbs,
        kkt_igl, kkt_stbs_reported, backend, converged, constrained, source``.
        Times in seconds; quantities that were not measured are None.
    """
    from .weights.bbw import BBWSolver

    b, bc = _boundary(P)
    m = min(int(functions), bc.shape[1])
    bc = np.ascontiguousarray(bc[:, :m])
    row = {"case": P.name, "kind": "compare", "vertices": P.n, "elements": int(P.E.shape[0]),
           "element_kind": P.element_kind, "functions": m, "constrained": int(b.size),
           "meshing_s": P.meshing_s, "source": P.source, "repeat": int(repeat), "tol": tol}
    best, W, report = np.inf, None, None
    warm_up(backend, tol=tol)
    for r in range(int(repeat)):
        log(f"{P.name}: stbs BBW ({P.n:,} vertices, m={m}, backend {backend}), "
            f"run {r + 1}/{repeat}")
        t = time.perf_counter()
        solver = BBWSolver(P.V, P.E, backend=backend)
        Wr = solver.solve(b, bc, tol=tol)
        dt = time.perf_counter() - t
        if dt < best:
            best, W, report = dt, Wr, solver.last_report
    row["stbs_s"] = best
    row["backend"] = getattr(report, "backend", backend)
    row["converged"] = bool(getattr(report, "all_converged", True))
    res = getattr(report, "kkt_residual", None)
    row["kkt_stbs_reported"] = None if res is None else float(np.max(res))
    Q = bilaplacian(P.V, P.E)
    row["kkt_stbs"] = kkt_residual(Q, W, b)

    row.update(igl_s=None, speedup=None, max_abs_dW=None, kkt_igl=None)
    ok, why = igl_available()
    if P.n > igl_max_vertices:
        row["igl_status"] = f"not run (n > {igl_max_vertices})"
    elif not ok:
        row["igl_status"] = f"not run ({why})"
    else:
        best_igl, Wi = np.inf, None
        if igl_timeout is None:          # in-process: warm it up as stbs was
            warm_up(backend, igl=True, tol=tol)
        for r in range(int(repeat)):
            log(f"{P.name}: igl.bbw, run {r + 1}/{repeat}"
                + (f" (time limit {igl_timeout:g} s)" if igl_timeout else ""))
            Wr, dt = igl_bbw(P.V, P.E, b, bc, timeout=igl_timeout)
            if Wr is None:
                row["igl_status"] = f"timed out (> {igl_timeout:g} s)"
                row["igl_s"] = None
                break
            if dt < best_igl:
                best_igl, Wi = dt, Wr
        else:
            row.update(igl_status="ok", igl_s=best_igl, speedup=best_igl / best,
                       max_abs_dW=float(np.abs(W - Wi).max()), kkt_igl=kkt_residual(Q, Wi, b))
    return row


def rig_case(P: Problem, *, repeat: int = 1, tol: float = DEFAULT_TOL,
             log: Log = _quiet) -> dict:
    """A complete rig of ``P`` through the library, timed per stage (best total of
    ``repeat`` runs): bone weights by BBW (all bones, normalised), then endpoint
    weights by BBW restricted to each bone's support, both with KKT tolerance ``tol``.

    Returns
    -------
    dict
        ``case, vertices, elements, element_kind, bones, meshing_s, stages`` (a dict
        of stage name to seconds), ``total_s``, ``goal_s`` and ``met``.
    """
    from .weights import bone_weights, endpoint_weights

    tri = P.E.shape[1] == 3
    mesh = {"F": P.E} if tri else {"T": P.E}
    best = None
    warm_up(tol=tol)
    for r in range(int(repeat)):
        log(f"{P.name}: complete rig ({P.n:,} vertices, {P.sk.n_bones} bones), "
            f"run {r + 1}/{repeat}")
        stages = {}
        t = time.perf_counter()
        W = bone_weights(P.V, P.sk, method="bbw", tol=tol, **mesh)
        stages["bone weights (bbw)"] = time.perf_counter() - t
        t = time.perf_counter()
        E = endpoint_weights(P.V, P.sk, method="bbw", W=W, tol=tol, **mesh)
        stages["endpoint weights (bbw)"] = time.perf_counter() - t
        total = sum(stages.values())
        if best is None or total < best[0]:
            best = (total, stages, W, E)
    total, stages, W, E = best
    return {"case": P.name, "kind": "rig", "vertices": P.n, "elements": int(P.E.shape[0]),
            "element_kind": P.element_kind, "bones": P.sk.n_bones, "meshing_s": P.meshing_s,
            "source": P.source, "repeat": int(repeat), "tol": float(tol), "stages": stages,
            "total_s": total,
            "goal_s": RIG_GOAL_S, "met": total < RIG_GOAL_S,
            "W_row_sum_error": float(np.abs(W.sum(axis=1) - 1).max()),
            "E_range": [float(E.min()), float(E.max())]}


# --------------------------------------------------------------------------- report
def check_targets(rows: Sequence[dict]) -> list[dict]:
    """The issue's goals, one entry per case plus the overall verdict.

    Each entry: ``target`` (text), ``case``, ``status`` (``"met"``, ``"MISSED"`` or
    ``"not judged"``) and ``detail``. Only the issue's cases are judged (not the
    extras ``2d-small`` and ``hand``), a comparison case only where igl ran.
    """
    out = []
    judged = []
    for r in rows:
        spec = CASES.get(r["case"])
        if spec is not None and not spec.goal:
            continue
        if r["kind"] == "rig":
            out.append({"target": f"complete {r['bones']}-bone rig in < {r['goal_s']:g} s",
                        "case": r["case"], "status": "met" if r["met"] else "MISSED",
                        "detail": f"{r['total_s']:.1f} s"})
            continue
        target = f"stbs >= {SPEEDUP_GOAL:g}x igl.bbw with max|dW| <= {DIFF_GOAL:g}"
        if r["igl_status"] != "ok":
            out.append({"target": target, "case": r["case"], "status": "not judged",
                        "detail": f"igl.bbw {r['igl_status']}"})
            judged.append(None)
            continue
        met = r["speedup"] >= SPEEDUP_GOAL and r["max_abs_dW"] <= DIFF_GOAL
        judged.append(met)
        out.append({"target": target, "case": r["case"], "status": "met" if met else "MISSED",
                    "detail": f"{r['speedup']:.1f}x, max|dW| {r['max_abs_dW']:.1e}"})
    if judged:
        if any(j is False for j in judged):
            status = "MISSED"
        elif all(j is True for j in judged):
            status = "met"
        else:
            status = "not judged"
        n_ok = sum(j is not None for j in judged)
        out.append({"target": f"stbs >= {SPEEDUP_GOAL:g}x igl.bbw with max|dW| <= "
                              f"{DIFF_GOAL:g} on every size", "case": "all",
                    "status": status, "detail": f"{n_ok} of {len(judged)} cases judged"})
    return out


def _f(x, spec: str, missing: str = "-") -> str:
    return missing if x is None else format(x, spec)


COLUMNS = ("case", "vertices", "elements", "m", "igl.bbw s", "stbs s", "speed-up",
           "max|dW|", "KKT stbs", "KKT igl", "backend")


def format_table(rows: Sequence[dict], machine: dict | None = None,
                 settings: dict | None = None) -> str:
    """A plain-text report: the comparison table, the rig stages, the goals."""
    from .bench import machine_lines

    lines = machine_lines(machine, f"Python {machine.get('python')}, NumPy "
                          f"{machine.get('numpy')}, SciPy {machine.get('scipy')}",
                          "times") if machine else []
    if settings:
        nmax = settings["igl_max_vertices"]
        lines.append(f"stbs tol {settings['tol']:g}; best of {settings['repeat']} run(s); "
                     + (f"igl.bbw default parameters, up to {nmax:,} vertices" if nmax
                        else "igl.bbw not run (--igl-max-vertices 0)"))
    lines.append("stbs s = BBWSolver(V, E) + solve (igl.bbw also builds L, M, Q); meshing "
                 "not counted; KKT = natural residual of the same QP, in weight units")
    lines.append("both warmed up by one untimed solve of a small problem (loads compiled "
                 "kernels, starts threads)")
    cmp_rows = [r for r in rows if r["kind"] == "compare"]
    if cmp_rows:
        w = (9, 9, 12, 3, 22, 8, 9, 8, 8, 8, 8)
        head = "  ".join(f"{c:<{w[i]}}" if i in (0, 10) else f"{c:>{w[i]}}"
                         for i, c in enumerate(COLUMNS))
        lines += ["", head.rstrip(), "-" * len(head.rstrip())]
        for r in cmp_rows:
            igl = _f(r["igl_s"], ".2f") if r["igl_status"] == "ok" else r["igl_status"]
            cells = (r["case"], f"{r['vertices']:,}", f"{r['elements']:,} {r['element_kind']}",
                     str(r["functions"]), igl, f"{r['stbs_s']:.2f}",
                     _f(r["speedup"], ".1f") + ("x" if r["speedup"] is not None else ""),
                     _f(r["max_abs_dW"], ".1e"), f"{r['kkt_stbs']:.0e}",
                     _f(r["kkt_igl"], ".0e"), r["backend"])
            lines.append("  ".join(f"{c:<{w[i]}}" if i in (0, 10) else f"{c:>{w[i]}}"
                                   for i, c in enumerate(cells)).rstrip())
        lines.append("")
        for r in cmp_rows:
            extra = "" if r["converged"] else "; stbs did NOT reach tol on every function"
            lines.append(f"{r['case']}: {r['source']}; meshing {r['meshing_s']:.1f} s; "
                         f"{r['constrained']} constrained vertices{extra}")
    for r in rows:
        if r["kind"] != "rig":
            continue
        lines += ["", f"complete rig: {r['case']}, {r['vertices']:,} vertices, "
                      f"{r['elements']:,} {r['element_kind']}, {r['bones']} bones "
                      f"({r['source']}; meshing {r['meshing_s']:.1f} s, not counted)"]
        for k, v in r["stages"].items():
            lines.append(f"  {k:<24} {v:8.2f} s")
        lines.append(f"  {'total':<24} {r['total_s']:8.2f} s   goal < {r['goal_s']:g} s: "
                     f"{'met' if r['met'] else 'MISSED'}")
    targets = check_targets(rows)
    if targets:
        lines += ["", "goals:"]
        for t in targets:
            lines.append(f"  [{t['status']}] {t['case']}: {t['target']} ({t['detail']})")
    return "\n".join(lines)


def machine_info() -> dict:
    """CPU model, core count, load and library versions (no heavy imports)."""
    from importlib.metadata import PackageNotFoundError, version

    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            cpu = next((ln.split(":", 1)[1].strip() for ln in f
                        if ln.startswith("model name")), cpu)
    except OSError:
        pass
    info = {"cpu": cpu, "cpus": os.cpu_count(), "python": platform.python_version(),
            "platform": platform.platform(), "numpy": np.__version__}
    try:
        info["load_average"] = [round(x, 2) for x in os.getloadavg()]
    except (AttributeError, OSError):
        info["load_average"] = None
    for dist in ("scipy", "libigl", "cholespy", "scikit-sparse", "tetgen", "triangle"):
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


def _int_at_least(low: int) -> Callable[[str], int]:
    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            v = None
        if v is None or v < low:
            raise argparse.ArgumentTypeError(f"expected a whole number >= {low}, got {text!r}")
        return v
    return parse


def _positive_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        v = float("nan")
    if not (np.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"expected a number > 0, got {text!r}")
    return v


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add ``stbs bench --weights``'s options to ``parser``."""
    parser.add_argument("--weights", action="store_true",
                        help="time bounded biharmonic weights against igl.bbw (this mode)")
    parser.add_argument("--cases", type=_parse_cases, default=DEFAULT_CASES,
                        help=f"comma-separated cases (listed below), or all (default "
                             f"{','.join(DEFAULT_CASES)})")
    parser.add_argument("--functions", type=_int_at_least(1), default=3, metavar="M",
                        help="weight functions (columns of bc) in the comparison cases "
                             "(default 3; capped at the skeleton's bones); the rig case "
                             "uses every bone")
    parser.add_argument("--igl-max-vertices", type=_int_at_least(0),
                        default=DEFAULT_IGL_MAX_VERTICES, metavar="N",
                        help=f"run igl.bbw only on meshes of at most N vertices (default "
                             f"{DEFAULT_IGL_MAX_VERTICES}; it takes minutes beyond); 0: never")
    parser.add_argument("--igl-timeout", type=_positive_float, default=None, metavar="S",
                        help="run igl.bbw in a child process and stop it after S seconds "
                             "(default: in this process, no limit)")
    parser.add_argument("--repeat", type=_int_at_least(1), default=1,
                        help="runs per solver and case; the best is reported (default 1)")
    parser.add_argument("--backend", choices=BACKENDS, default="auto",
                        help="stbs's sparse Cholesky backend in the comparison cases (default "
                             "auto); the rig case uses the library's default")
    parser.add_argument("--tol", type=_positive_float, default=DEFAULT_TOL,
                        help=f"stbs's KKT tolerance, comparison and rig cases (default "
                             f"{DEFAULT_TOL:g}: libigl's own residual is ~5e-7)")
    parser.add_argument("--json", metavar="OUT.json", default=None,
                        help="also write machine, settings, rows and goals as JSON "
                             "(written to a temporary file, then renamed)")


def _check_json_path(path: str | None) -> Path | None:
    if path is None:
        return None
    out = Path(path)
    if out.is_dir():
        raise ValueError(f"--json: {out} is a folder, expected a file path")
    parent = out.parent if str(out.parent) else Path(".")
    if not parent.is_dir():
        raise ValueError(f"--json: folder {parent} does not exist")
    if not os.access(parent, os.W_OK):
        raise ValueError(f"--json: folder {parent} is not writable")
    return out


def _jsonable(x):
    if isinstance(x, dict):
        return {k: _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, (np.floating, float)):
        return float(x) if np.isfinite(x) else None
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


def run(args: argparse.Namespace) -> int:
    """Run the cases of parsed ``args``; print the table; return 0.

    Raises
    ------
    ValueError
        An unusable ``--json`` path (before anything runs), or a case whose data
        is missing.
    """
    out = _check_json_path(args.json)

    def log(msg: str) -> None:
        print(f"stbs bench --weights: {msg}", file=sys.stderr, flush=True)

    machine = machine_info()
    settings = {"cases": list(args.cases), "functions": args.functions,
                "igl_max_vertices": args.igl_max_vertices, "igl_timeout": args.igl_timeout,
                "repeat": args.repeat, "backend": args.backend, "tol": args.tol,
                "date": time.strftime("%Y-%m-%d")}
    meshes = _Meshes(log)
    rows = []
    for name in args.cases:
        P = meshes.get(name)
        if CASES[name].kind == "rig":
            rows.append(rig_case(P, repeat=args.repeat, tol=args.tol, log=log))
        else:
            rows.append(compare_case(P, functions=args.functions, backend=args.backend,
                                     repeat=args.repeat, tol=args.tol,
                                     igl_max_vertices=args.igl_max_vertices,
                                     igl_timeout=args.igl_timeout, log=log))
    print(format_table(rows, machine, settings))
    if out is not None:
        from .io._atomic import atomic_open

        doc = {"schema": 1, "benchmark": "weights", "machine": machine, "settings": settings,
               "columns": list(COLUMNS), "rows": rows, "goals": check_targets(rows)}
        with atomic_open(out, "w") as f:
            f.write(json.dumps(_jsonable(doc), indent=1, allow_nan=False))
        log(f"wrote {out}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m stbs.bench_weights [options]``: the same as ``stbs bench --weights``."""
    from .cli import main as cli_main

    argv = list(sys.argv[1:] if argv is None else argv)
    return cli_main(["bench", "--weights", *[a for a in argv if a != "--weights"]])


if __name__ == "__main__":
    sys.exit(main())
