"""Bounded biharmonic weights against libigl's ``igl.bbw``: ``stbs bench --weights`` plus
the peer, on the same meshes and the *same* boundary conditions.

Each solve case of :mod:`stbs.bench.weights` is timed for us (``BBWSolver(V, Ele)`` +
``.solve(b, bc)``, as there) and then given to ``igl.bbw(V, Ele, b, bc)`` with libigl's
default parameters (it builds its L, M, Q inside its own call too), only up to
``--igl-max-vertices`` vertices, since it takes minutes on large meshes. Both results
are checked against the KKT conditions of the same QP and against each other
(``max |W_stbs - W_igl|``). The ``rig-*`` case is ours alone (``stbs.build_rig``). The
report ends with the project's speed targets (``speed_targets.py``).

Needs libigl's Python binding (``pip install 'stbs-skinning[bench]'``); without it
the igl columns say so. libigl's tutorial hand (``hand.mesh``, ``hand.tgf``) is used
for the 3D cases when ``--mesh-dir`` names its folder. Usage::

    python benchmarks/bbw_vs_igl.py                                  # default cases
    python benchmarks/bbw_vs_igl.py --cases 2d-5k,hand --mesh-dir DIR --tol 1e-10
    python benchmarks/bbw_vs_igl.py --cases 3d-50k --igl-max-vertices 100000 --igl-timeout 2400

Every ``stbs bench --weights`` option applies (``--help``). Docs: ``docs/benchmarks.md``.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from speed_targets import bbw_targets, format_targets
from stbs.bench import weights as bw
from stbs.bench.report import (
    check_json_path,
    int_at_least,
    machine_lines,
    positive_float,
    quiet,
    write_json,
)

PROG = "bbw_vs_igl"
DEFAULT_IGL_MAX_VERTICES = 20_000
COLUMNS = ("case", "vertices", "elements", "m", "igl.bbw s", "stbs s", "speed-up",
           "max|dW|", "KKT stbs", "KKT igl", "backend")

Log = Callable[[str], None]

_CHILD = """\
import sys, time
import numpy as np
import igl
z = np.load(sys.argv[1])
args = [np.ascontiguousarray(z[k]) for k in ("V", "Ele", "b", "bc")]
t = time.perf_counter()
W = igl.bbw(*args)
t = time.perf_counter() - t
np.savez(sys.argv[2], W=W, seconds=t)
"""


def igl_available() -> tuple[bool, str]:
    """Whether ``igl.bbw`` can run here, and if not, why (one phrase)."""
    try:
        import igl
    except ImportError:
        return False, "libigl not installed: pip install 'stbs-skinning[bench]'"
    if not hasattr(igl, "bbw"):
        return False, "this libigl has no igl.bbw"
    return True, ""


def igl_bbw(V, Ele, b, bc, *, timeout: float | None = None) -> tuple[np.ndarray | None, float]:
    """Run ``igl.bbw(V, Ele, b, bc)`` (default parameters) and time it.

    Parameters
    ----------
    V : (n, d) float, Ele : (f, 3) or (t, 4) int, b : (k,) int, bc : (k, m) float
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
    Ele = np.ascontiguousarray(Ele, dtype=np.int64)
    b = np.ascontiguousarray(b, dtype=np.int64)
    bc = np.ascontiguousarray(bc, dtype=np.float64)
    if timeout is None:
        import igl

        t = time.perf_counter()
        W = igl.bbw(V, Ele, b, bc)
        return np.asarray(W), time.perf_counter() - t
    with tempfile.TemporaryDirectory(prefix="stbs-igl-bbw-") as d:
        src, dst = Path(d) / "in.npz", Path(d) / "out.npz"
        np.savez(src, V=V, Ele=Ele, b=b, bc=bc)
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


_IGL_WARM = []


def warm_up_igl() -> None:
    """One untimed ``igl.bbw`` on the ``2d-small`` case per process (imports, first touch)."""
    if _IGL_WARM:
        return
    P = bw.make_problem("2d-small")
    b, bc = bw.boundary(P)
    igl_bbw(P.V, P.Ele, b, bc)
    _IGL_WARM.append(True)


def compare_case(P: bw.Problem, *, functions: int = 3, backend: str = "auto",
                 repeat: int = 1, tol: float = bw.DEFAULT_TOL,
                 igl_max_vertices: int = DEFAULT_IGL_MAX_VERTICES,
                 igl_timeout: float | None = None, log: Log = quiet) -> dict:
    """Our BBW (:func:`stbs.bench.weights.solve_case`) and ``igl.bbw`` on ``P`` with the
    same ``b`` and first ``functions`` columns of ``bc``; best of ``repeat`` runs each.

    Returns
    -------
    dict
        The row of ``solve_case`` plus ``igl_s``, ``igl_status`` ("ok" or why not),
        ``speedup``, ``max_abs_dW`` and ``kkt_igl`` (None where not measured).
    """
    row, W = bw.solve_case(P, functions=functions, backend=backend, repeat=repeat, tol=tol,
                           return_weights=True, log=log)
    b, bc = bw.boundary(P)
    bc = np.ascontiguousarray(bc[:, :row["functions"]])
    row.update(igl_s=None, speedup=None, max_abs_dW=None, kkt_igl=None)
    ok, why = igl_available()
    if P.n > igl_max_vertices:
        row["igl_status"] = f"not run (n > {igl_max_vertices})"
        return row
    if not ok:
        row["igl_status"] = f"not run ({why})"
        return row
    best, Wi = np.inf, None
    if igl_timeout is None:          # in-process: warm it up as ours was
        warm_up_igl()
    for r in range(int(repeat)):
        log(f"{P.name}: igl.bbw, run {r + 1}/{repeat}"
            + (f" (time limit {igl_timeout:g} s)" if igl_timeout else ""))
        Wr, dt = igl_bbw(P.V, P.Ele, b, bc, timeout=igl_timeout)
        if Wr is None:
            row["igl_status"] = f"timed out (> {igl_timeout:g} s)"
            return row
        if dt < best:
            best, Wi = dt, Wr
    row.update(igl_status="ok", igl_s=best, speedup=best / row["stbs_s"],
               max_abs_dW=float(np.abs(W - Wi).max()),
               kkt_igl=bw.kkt_residual(bw.bilaplacian(P.V, P.Ele), Wi, b))
    return row


def _f(x, spec: str) -> str:
    return "-" if x is None else format(x, spec)


def format_table(rows: Sequence[dict], machine: dict, settings: dict) -> str:
    """The comparison table, the rig stages (ours), the targets."""
    lines = machine_lines(machine, f"Python {machine.get('python')}, NumPy "
                            f"{machine.get('numpy')}, SciPy {machine.get('scipy')}, libigl "
                            f"{machine.get('libigl', 'not installed')}", "times")
    nmax = settings["igl_max_vertices"]
    lines.append(f"stbs tol {settings['tol']:g}; best of {settings['repeat']} run(s); "
                 + (f"igl.bbw default parameters, up to {nmax:,} vertices" if nmax
                    else "igl.bbw not run (--igl-max-vertices 0)"))
    lines.append("stbs s = BBWSolver(V, Ele) + solve (igl.bbw also builds L, M, Q); meshing "
                 "not counted; KKT = natural residual of the same QP, in weight units")
    lines.append("both warmed up by one untimed solve of a small problem (loads compiled "
                 "kernels, starts threads)")
    cmp_rows = [r for r in rows if r["kind"] == "solve"]
    if cmp_rows:
        w = (9, 9, 12, 3, 22, 8, 9, 8, 8, 8, 8)

        def line(cells) -> str:
            return "  ".join(f"{c:<{w[i]}}" if i in (0, 10) else f"{c:>{w[i]}}"
                             for i, c in enumerate(cells)).rstrip()

        head = line(COLUMNS)
        lines += ["", head, "-" * len(head)]
        for r in cmp_rows:
            igl = _f(r["igl_s"], ".2f") if r["igl_status"] == "ok" else r["igl_status"]
            lines.append(line((r["case"], f"{r['vertices']:,}",
                               f"{r['elements']:,} {r['element_kind']}", str(r["functions"]),
                               igl, f"{r['stbs_s']:.2f}",
                               _f(r["speedup"], ".1f") + ("x" if r["speedup"] else ""),
                               _f(r["max_abs_dW"], ".1e"), f"{r['kkt_stbs']:.0e}",
                               _f(r["kkt_igl"], ".0e"), r["backend"])))
        lines.append("")
        for r in cmp_rows:
            extra = "" if r["converged"] else "; stbs did NOT reach tol on every function"
            lines.append(f"{r['case']}: {r['source']}; meshing {r['meshing_s']:.1f} s; "
                         f"{r['constrained']} constrained vertices{extra}")
    lines += bw.format_rigs(rows)
    targets = format_targets(bbw_targets(rows))
    if targets:
        lines += [""] + targets
    return "\n".join(lines)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog=f"python benchmarks/{PROG}.py", description=__doc__.split("\n\n")[0],
        epilog="cases:\n" + "".join(f"  {c.name:<10} {c.about}\n" for c in bw.CASES.values())
               + f"\nexamples:\n  python benchmarks/{PROG}.py --cases 2d-small --repeat 2\n"
               f"  python benchmarks/{PROG}.py --cases 3d-10k,hand --mesh-dir "
               "libigl-tutorial-data --json bbw.json",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    bw.add_arguments(p)
    p.add_argument("--igl-max-vertices", type=int_at_least(0),
                   default=DEFAULT_IGL_MAX_VERTICES, metavar="N",
                   help=f"run igl.bbw only on meshes of at most N vertices (default "
                        f"{DEFAULT_IGL_MAX_VERTICES}; it takes minutes beyond); 0: never")
    p.add_argument("--igl-timeout", type=positive_float, default=None, metavar="S",
                   help="run igl.bbw in a child process and stop it after S seconds "
                        "(default: in this process, no limit)")
    return p


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)

    def log(msg: str) -> None:
        print(f"{PROG}: {msg}", file=sys.stderr, flush=True)

    ok, why = igl_available()
    if not ok and args.igl_max_vertices:
        print(f"{PROG}: igl.bbw skipped: {why}", file=sys.stderr)

    def solve(P, a, lg):
        return compare_case(P, functions=a.functions, backend=a.backend, repeat=a.repeat,
                            tol=a.tol, igl_max_vertices=a.igl_max_vertices,
                            igl_timeout=a.igl_timeout, log=lg)

    try:
        out = check_json_path(args.json)
        doc = bw.collect(args, log=log, solve=solve)
    except (ValueError, RuntimeError, OSError) as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 2
    from importlib.metadata import PackageNotFoundError, version

    try:
        doc["machine"]["libigl"] = version("libigl")
    except PackageNotFoundError:
        pass
    doc["settings"].update(igl_max_vertices=args.igl_max_vertices,
                           igl_timeout=args.igl_timeout)
    doc["columns"] = list(COLUMNS)
    doc["targets"] = bbw_targets(doc["rows"])
    print(format_table(doc["rows"], doc["machine"], doc["settings"]))
    if out is not None:
        write_json(out, doc)
        log(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
