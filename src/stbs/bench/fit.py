"""Skinning decomposition of the horse gallop: STBS-SSDR beside Dem Bones.

``stbs bench --fit`` runs :func:`stbs.fit.decompose` and EA's Dem Bones (rigid-bone
LBS, ``py_dem_bones``) on the same frames in the same run, at each bone count.

The sequence is the horse gallop of Sumner & Popovic (2004): 48 frames of one
8431-vertex mesh, no skeleton. Each method gets the rest mesh, the frames, the
triangles, at most 4 bones per vertex and the same bone count; each is timed from
the call to its result (Dem Bones on all the threads OpenMP gives it, ours in NumPy).
Our fit with rigid bones (``method="lbs"``) runs too, unless turned off, to show how
much of the difference comes from stretch and twist and how much from the fitting.

Error: the root mean squared distance between the reproduced and the given vertex
positions over all frames and vertices, as a percentage of the diagonal of the rest
mesh's bounding box; the same function measures both. The SSDR papers (Kavan et al.
2010, Le & Deng 2012) divide by three coordinates per vertex (``sqrt(sum |.|^2 /
(3 n F))``), which is our figure divided by sqrt(3): the table prints both, and the
published SSDR figures for this sequence (0.49 % with 10 bones, 0.243 % with 20) in
that convention.

The data file is ``horse-gallop.npz`` (a mesh animation as :func:`stbs.io.read_sequence`
reads it: ``frames``, ``rest``, ``F``): ``data=`` (``--data``) names it, or a folder
holding it or ``sequences/horse-gallop.npz``; otherwise ``$STBS_DATA`` is searched the
same way. Docs: ``docs/fitting.md``.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from .report import (
    check_json_path,
    cpu_model,
    int_at_least,
    load_average,
    machine_lines,
    platform_name,
    write_json,
)

__all__ = ["DEFAULT_BONES", "PUBLISHED", "FILE", "find_data", "load_sequence", "rmse",
           "dem_bones", "collect", "format_table", "report", "run", "requires",
           "add_arguments", "main"]

#: Bone counts of the default run (those the SSDR paper reports for the horse).
DEFAULT_BONES: tuple[int, ...] = (10, 20)
#: SSDR's published error on the horse gallop (Le & Deng 2012), % of the bounding-box
#: diagonal in their per-coordinate convention, by bone count.
PUBLISHED: dict[int, float] = {10: 0.49, 20: 0.243}
#: The sequence's file name.
FILE = "horse-gallop.npz"
#: Iterations of our alternation (decompose's default).
DEFAULT_ITERATIONS = 20
#: Iterations of Dem Bones (its own default).
PEER_ITERATIONS = 30

Out = Callable[[str], None]


# --------------------------------------------------------------------------- data
def find_data(data: str | os.PathLike | None = None) -> Path:
    """The horse gallop's ``.npz``: ``data`` (the file, or a folder holding it or
    ``sequences/`` + it), else the same under ``$STBS_DATA``.

    Raises
    ------
    ValueError
        Nothing found; the message lists the places tried.
    """
    roots = [Path(data)] if data is not None else []
    if data is None and os.environ.get("STBS_DATA"):
        roots.append(Path(os.environ["STBS_DATA"]).expanduser())
    tried = []
    for root in roots:
        for cand in (root, root / FILE, root / "sequences" / FILE):
            if cand.is_file():
                return cand
            tried.append(str(cand))
    if not roots:
        raise ValueError(f"no data given: pass the path of {FILE} (--data) or set STBS_DATA "
                         f"to a folder holding sequences/{FILE}")
    raise ValueError(f"{FILE} not found; tried {', '.join(tried)}")


def load_sequence(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``rest`` (n, 3), ``frames`` (F, n, 3) float64 and ``F`` (f, 3) int64 of a mesh
    animation (:func:`stbs.io.read_sequence`); the triangles are required here (both
    methods smooth their weights across them)."""
    from ..io import read_sequence

    seq = read_sequence(path)
    if seq.F is None:
        raise ValueError(f"{path} has no triangles 'F': both methods smooth their weights "
                         "across the surface")
    return seq.rest, seq.frames, seq.F


def rmse(U: np.ndarray, Y: np.ndarray) -> float:
    """``sqrt(mean over frames and vertices of |U - Y|^2)`` for (F, n, 3) arrays."""
    D = np.asarray(U, dtype=np.float64) - Y
    return float(np.sqrt(np.einsum("fni,fni->", D, D) / (D.shape[0] * D.shape[1])))


# --------------------------------------------------------------------------- the peer
def dem_bones(rest, frames, F, bones: int, *, iterations: int = PEER_ITERATIONS,
              max_influences: int = 4) -> tuple[np.ndarray, int]:
    """Dem Bones' reproduction of ``frames`` (F, n, 3) and the bones it used.

    ``py_dem_bones`` comes with the ``bench`` extra.
    """
    from py_dem_bones import solve_skinning

    res = solve_skinning(rest, frames, bones, faces=F, max_influences=max_influences,
                         iterations=iterations)
    W = res.weights.T                                   # (n, b)
    T = res.transforms                                  # (F, b, 4, 4), column vectors
    U = np.einsum("nb,fbij,nj->fni", W, T[:, :, :3, :3], rest) \
        + np.einsum("nb,fbi->fni", W, T[:, :, :3, 3])
    return U, int(np.count_nonzero(W.max(axis=0) > 0))


# --------------------------------------------------------------------------- run
def collect(bones: Sequence[int] = DEFAULT_BONES, *, seed: int = 0,
            iterations: int = DEFAULT_ITERATIONS, peer_iterations: int = PEER_ITERATIONS,
            rigid: bool = True, data=None, log: Out = lambda msg: None) -> dict:
    """Run the methods at each bone count; the JSON document of :func:`report`."""
    from ..fit.ssdr import decompose

    path = find_data(data)
    rest, frames, F = load_sequence(path)
    diag = float(np.linalg.norm(rest.max(axis=0) - rest.min(axis=0)))
    rows = []
    ours = [("STBS-SSDR (stbs-lbs)", "stbs-lbs")] + ([("ours, rigid (lbs)", "lbs")]
                                                    if rigid else [])
    for b in bones:
        for name, method in ours:
            log(f"{b} bones: {name}, {iterations} iterations")
            t = time.perf_counter()
            d = decompose(rest, frames, b, F=F, iterations=iterations, seed=seed,
                          method=method)
            ours_s = time.perf_counter() - t
            e = rmse(d.frames(), frames)
            rows.append({"bones": b, "method": name, "bones_used": b,
                         "rmse": e, "percent": 100 * e / diag, "seconds": ours_s})
        log(f"{b} bones: Dem Bones, {peer_iterations} iterations")
        t = time.perf_counter()
        U, used = dem_bones(rest, frames, F, b, iterations=peer_iterations)
        peer_s = time.perf_counter() - t
        e = rmse(U, frames)
        rows.append({"bones": b, "method": "Dem Bones (lbs)", "bones_used": used,
                     "rmse": e, "percent": 100 * e / diag, "seconds": peer_s})
    machine = {"cpu": cpu_model(), "cpus": os.cpu_count(), "platform": platform_name(),
               "numpy": np.__version__, "load_average": load_average()}
    return {"schema": 1, "benchmark": "fit", "machine": machine,
            "settings": {"data": str(path), "bones": list(bones), "seed": seed,
                         "iterations": iterations, "peer_iterations": peer_iterations,
                         "max_influences": 4,
                         "vertices": int(rest.shape[0]), "frames": int(frames.shape[0]),
                         "diagonal": diag},
            "rows": rows}


def format_table(doc: dict) -> list[str]:
    """The report's lines: the machine, the settings, one row per method and bone count,
    and for each count how much lower STBS-SSDR's error is than Dem Bones'."""
    s = doc["settings"]
    m = doc["machine"]
    lines = machine_lines(m, f"NumPy {m.get('numpy')}", "times")
    lines.append(f"{Path(s['data']).name}: {s['vertices']} vertices, {s['frames']} frames; "
                 f"iterations: ours {s['iterations']}, Dem Bones {s['peer_iterations']}; "
                 f"<= {s['max_influences']} bones per vertex; seed {s['seed']}")
    lines.append(f"RMSE % = 100 sqrt(mean |p' - p|^2) / rest bounding-box diagonal "
                 f"({s['diagonal']:.4g}); per coord = that / sqrt(3), the SSDR papers' "
                 f"convention")
    head = f"{'bones':>5}  {'method':<22} {'RMSE %':>8} {'per coord':>10} {'time s':>8}  " \
           f"{'SSDR published (per coord)':<26}"
    lines += ["", head, "-" * len(head)]
    for r in doc["rows"]:
        pub = PUBLISHED.get(r["bones"])
        used = "" if r["bones_used"] == r["bones"] else f" ({r['bones_used']} used)"
        lines.append(f"{r['bones']:>5}  {r['method'] + used:<22} {r['percent']:>8.3f} "
                     f"{r['percent'] / np.sqrt(3):>10.3f} {r['seconds']:>8.1f}  "
                     f"{'' if pub is None else f'{pub:.3f}':<26}".rstrip())
    lines.append("")
    for b in s["bones"]:
        by = {r["method"].split()[0]: r["rmse"] for r in doc["rows"] if r["bones"] == b}
        if "STBS-SSDR" in by and "Dem" in by:
            text = f"{b} bones: STBS-SSDR's RMSE is {_versus(by['STBS-SSDR'], by['Dem'])}"
            if "ours," in by:
                text += (f" (our rigid bones: {_versus(by['ours,'], by['Dem'])}; "
                         f"STBS-SSDR against them: {_versus(by['STBS-SSDR'], by['ours,'], '')})")
            lines.append(text)
    return lines


def _versus(a: float, b: float, whose: str = " than Dem Bones'") -> str:
    gain = 100 * (1 - a / b)
    return f"{abs(gain):.0f} % {'lower' if gain >= 0 else 'higher'}{whose}"


def report(bones: Sequence[int] = DEFAULT_BONES, *, seed: int = 0,
        iterations: int = DEFAULT_ITERATIONS, peer_iterations: int = PEER_ITERATIONS,
        rigid: bool = True, out: Out = print, data=None,
        log: Out = lambda msg: None) -> dict:
    """Decompose the horse gallop with STBS-SSDR and Dem Bones at each bone count and
    print the table through ``out`` (one call per line).

    Parameters
    ----------
    bones : sequence of int
        Bone counts.
    seed : int
        Seed of STBS-SSDR's clustering (Dem Bones is deterministic).
    iterations : int
        Iterations of our alternation.
    peer_iterations : int
        Iterations of Dem Bones.
    rigid : bool
        Also run :func:`stbs.fit.decompose` with rigid bones (``method="lbs"``), which
        tells how much of the difference stretch and twist make.
    out : callable
        Receives the report's lines.
    data : path, optional
        ``horse-gallop.npz``, or a folder holding it (see the module docs).
    log : callable
        Progress messages.

    Returns
    -------
    dict
        The JSON document: ``schema``, ``benchmark`` ("fit"), ``machine``, ``settings``,
        ``rows`` (``bones, method, bones_used, rmse, percent, seconds`` each).
    """
    doc = collect(bones, seed=seed, iterations=iterations, peer_iterations=peer_iterations,
                  rigid=rigid, data=data, log=log)
    for line in format_table(doc):
        out(line)
    return doc


# --------------------------------------------------------------------------- command line
def _bone_counts(text: str) -> tuple[int, ...]:
    parse = int_at_least(1)
    out = tuple(parse(s.strip()) for s in str(text).split(",") if s.strip())
    if not out:
        raise argparse.ArgumentTypeError(f"expected comma-separated bone counts, got {text!r}")
    return out


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add ``stbs bench --fit``'s options to ``parser``."""
    parser.add_argument("--fit", action="store_true",
                        help="decompose the horse gallop, STBS-SSDR beside Dem Bones (this mode)")
    parser.add_argument("--bones", type=_bone_counts, default=DEFAULT_BONES,
                        help="comma-separated bone counts (default 10,20)")
    parser.add_argument("--iterations", type=int_at_least(0), default=DEFAULT_ITERATIONS,
                        help=f"iterations of ours (default {DEFAULT_ITERATIONS})")
    parser.add_argument("--peer-iterations", type=int_at_least(0), default=PEER_ITERATIONS,
                        help=f"iterations of Dem Bones (default {PEER_ITERATIONS}, its own)")
    parser.add_argument("--no-rigid", dest="rigid", action="store_false",
                        help="skip our rigid-bone (lbs) fit")
    parser.add_argument("--seed", type=int, default=0, help="STBS-SSDR's seed (default 0)")
    parser.add_argument("--data", metavar="PATH", default=None,
                        help=f"{FILE}, or a folder holding it or sequences/{FILE} "
                             f"(default: $STBS_DATA)")
    parser.add_argument("--json", metavar="OUT.json", default=None,
                        help="also write machine, settings and rows as JSON")


def requires(args: argparse.Namespace) -> list[str]:
    return ["py_dem_bones"]


def run(args: argparse.Namespace) -> int:
    """``stbs bench --fit`` with parsed options: print the table, write ``--json``."""
    json_path = check_json_path(args.json)

    def log(msg: str) -> None:
        print(f"stbs bench --fit: {msg}", file=sys.stderr, flush=True)

    doc = report(args.bones, seed=args.seed, iterations=args.iterations,
                 peer_iterations=args.peer_iterations, rigid=args.rigid, data=args.data,
                 log=log)
    if json_path is not None:
        write_json(json_path, doc)
        print(f"\nwrote {json_path}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m stbs.bench.fit [options]``: the same as ``stbs bench --fit``; returns
    the exit status (2 and one line on stderr for a bad option or missing data)."""
    p = argparse.ArgumentParser(prog="stbs bench --fit", description=__doc__.splitlines()[0])
    add_arguments(p)
    args = p.parse_args(argv)
    try:
        return run(args)
    except (ValueError, OSError, ImportError) as exc:
        print(f"stbs bench --fit: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
