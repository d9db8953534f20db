"""The demo job: the paper's Figs. 2 and 3 on built-in shapes, written as meshes plus a table."""

from __future__ import annotations

import json
import os
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import TextIO

from .figures import FIGURES, Figure

__all__ = ["run_demo", "DemoResult", "format_summary"]


@dataclass(eq=False)
class DemoResult:
    """What :func:`run_demo` computed and wrote.

    Attributes
    ----------
    figures : dict[str, Figure]
        By name: ``"cigar"``, ``"box"``, ``"bar"``.
    files : list of Path
        Every file written, in order.
    summary : str
        The table printed by :func:`run_demo`.
    """

    figures: dict[str, Figure] = field(default_factory=dict)
    files: list[Path] = field(default_factory=list)
    summary: str = ""

    @property
    def numbers(self) -> dict[str, dict[str, dict[str, float]]]:
        """``numbers[figure][method][column]``."""
        return {k: f.numbers for k, f in self.figures.items()}


def format_summary(figures) -> str:
    """A plain-text table per figure: one row per method, one column per number."""
    lines = []
    for fig in figures:
        lines.append(fig.title)
        heads = [h for _, h, _ in fig.columns]
        width = max(len("method"), *(len(m) for m in fig.numbers))
        lines.append("  " + "method".ljust(width) + "".join(f"  {h:>22}" for h in heads))
        for m, nums in fig.numbers.items():
            cells = "".join(f"  {fmt.format(nums[k]):>22}" for k, _, fmt in fig.columns)
            lines.append("  " + m.ljust(width) + cells)
        for k, h, _ in fig.columns:
            lines.append(f"  expected {h}: {fig.expected[k]}")
        lines += [f"  note: {s}" for s in fig.notes]
        lines.append("")
    return "\n".join(lines).rstrip() + "\n"


def run_demo(out_dir: str | os.PathLike = "demo-out", quick: bool = False, *,
             stream: TextIO | None = None, quiet: bool = False) -> DemoResult:
    """Run the demo: stretch a cigar (Fig. 2), twist a box and a two-bone bar (Fig. 3).

    For each case every method of DESIGN §3 is run (lbs, dqs, stbs-lbs, stbs-dqs)
    with projection endpoint weights (eq. 8), and one or two numbers per method are
    measured that show the paper's point:

    - cigar, stretched x2: length of the part beyond the bone's end, relative to
      rest. LBS/DQS double it (explosion), STBS keeps it (1).
    - box, one bone twisted 315 degrees at its far end: twist of the middle and the
      far cross-section. STBS: mid = 157.5, far = 315. LBS/DQS have no twist
      term, so there the bone is rotated 315 degrees about its own axis instead and
      the box turns rigidly (mid = far = 315).
    - bar, two bones, bent 60 degrees at the middle joint, twisted 180 degrees there
      and the upper bone stretched x1.5 (one forward-kinematics pose for all
      methods; LBS/DQS see the twist through the lower bone's inherited rotation):
      the smallest cross-section near the joint relative to rest (LBS collapses to
      about 0.35, the candy wrapper) and the twist half-way along the upper bone
      (STBS 90: spread; LBS/DQS 0: packed at the joint).

    See :mod:`stbs.demo.figures` for the computations (one function per figure).

    Parameters
    ----------
    out_dir : str or os.PathLike
        Folder for the output (created, with its parents, if missing). Written:
        ``<case>_rest.obj`` and ``<case>_<method>.obj`` for each case, plus
        ``summary.txt`` (the table) and ``summary.json`` (the numbers). Nothing
        is written elsewhere; every file is written atomically.
    quick : bool
        Coarser meshes (for tests); the numbers are the same to printed precision.
    stream : text file, optional
        Where the table is printed (default: ``sys.stdout`` at call time).
    quiet : bool
        Print nothing.

    Returns
    -------
    DemoResult
    """
    from ..io import atomic_open, write_mesh

    out = Path(os.fspath(out_dir))
    if out.exists() and not out.is_dir():
        raise NotADirectoryError(20, "demo output path exists and is not a folder", str(out))
    out.mkdir(parents=True, exist_ok=True)
    res = DemoResult()
    for make in FIGURES:
        fig = make(quick)
        res.figures[fig.name] = fig
        path = out / f"{fig.name}_rest.obj"
        write_mesh(path, fig.V, fig.F)
        res.files.append(path)
        for m, U in fig.U.items():
            path = out / f"{fig.name}_{m}.obj"
            write_mesh(path, U, fig.F)
            res.files.append(path)
    res.summary = format_summary(res.figures.values())
    with atomic_open(out / "summary.txt", "w") as f:
        f.write(res.summary)
    with atomic_open(out / "summary.json", "w") as f:
        json.dump({"quick": quick, "numbers": res.numbers,
                   "expected": {k: fig.expected for k, fig in res.figures.items()},
                   "notes": {k: fig.notes for k, fig in res.figures.items()}}, f, indent=2)
        f.write("\n")
    res.files += [out / "summary.txt", out / "summary.json"]
    if not quiet:
        stream = sys.stdout if stream is None else stream
        stream.write(res.summary)
        stream.write(f"wrote {len(res.files)} files to {out}\n")
    return res
