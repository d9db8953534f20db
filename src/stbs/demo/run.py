"""The demo job: the paper's figures on built-in shapes, as pictures, numbers and a gallery."""

from __future__ import annotations

import functools
import json
import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TextIO

from .._optional import OptionalDependencyError, missing
from . import figures, paper
from .figures import Figure

__all__ = ["run_demo", "DemoResult", "format_summary", "FIGURE_KEYS", "parse_only",
           "LIBIGL_ARM_FILES", "libigl_arm_folder", "REQUIRES"]

#: The optional modules (import names) the demo's pictures need: the ``demo`` extra.
REQUIRES = ("matplotlib", "PIL")

#: The files of libigl's tutorial data that ``data=`` adds to Fig. 5 (the arm scan).
LIBIGL_ARM_FILES = ("arm.obj", "arm.tgf", "arm-weights.dmat")

#: ``stbs demo --only`` keys, in display order, and the functions that make them.
_MAKERS = {
    "fig2": (figures.fig2_cigar_stretch,),
    "fig3": (figures.fig3_box_twist, figures.fig3_bar_bend_twist),
    "fig4": (paper.fig4_leg,),
    "fig5": (paper.fig5_arm,),
    "fig6": (paper.fig6_character,),
    "fig7": (paper.fig7_neck,),
    "fig8": (paper.fig8_box_twist,),
    "fig10": (paper.fig10_torso,),
    "fig12": (paper.fig12_picture,),
}
FIGURE_KEYS: tuple[str, ...] = tuple(_MAKERS)
_ALIASES = {"fig1": "fig5"}


@dataclass(eq=False)
class DemoResult:
    """What :func:`run_demo` computed and wrote.

    Attributes
    ----------
    figures : dict[str, Figure]
        By name (``"cigar"``, ``"box"``, ``"arm"``, ...).
    files : list of Path
        Every file written, in order.
    summary : str
        The table printed by :func:`run_demo`.
    seconds : dict[str, float]
        Wall time per figure key.
    """

    figures: dict[str, Figure] = field(default_factory=dict)
    files: list[Path] = field(default_factory=list)
    summary: str = ""
    seconds: dict[str, float] = field(default_factory=dict)

    @property
    def numbers(self) -> dict[str, dict[str, dict[str, float]]]:
        """``numbers[figure][method][column]``."""
        return {k: f.numbers for k, f in self.figures.items()}


def parse_only(only) -> list[str]:
    """Figure keys from ``"fig2,fig5"`` (or a list); ``None`` means all of them."""
    if only is None:
        return list(FIGURE_KEYS)
    items = only.split(",") if isinstance(only, str) else list(only)
    keys = []
    for raw in items:
        k = str(raw).strip().lower()
        if not k:
            continue
        k = _ALIASES.get(k, k)
        if k not in _MAKERS:
            raise ValueError(f"--only: unknown figure {str(raw).strip()!r}; expected a "
                             f"comma-separated list of {', '.join(FIGURE_KEYS)} (fig1 = fig5)")
        if k not in keys:
            keys.append(k)
    if not keys:
        raise ValueError(f"--only: expected at least one of {', '.join(FIGURE_KEYS)}, got "
                         f"{only!r}")
    return keys


def libigl_arm_folder(data) -> Path:
    """The folder holding libigl's arm rig (:data:`LIBIGL_ARM_FILES`) for ``data``.

    Parameters
    ----------
    data : str or os.PathLike
        The folder holding the files, or a folder holding ``libigl-tutorial-data/``
        with them (a checkout of libigl's tutorial data, or its parent).

    Returns
    -------
    Path
        ``data`` or ``data / "libigl-tutorial-data"``, whichever holds all the files.

    Raises
    ------
    FileNotFoundError
        When neither holds all of them: ``filename`` is the path, ``strerror`` names
        the files expected and what is missing.
    """
    if isinstance(data, bool) or not isinstance(data, (str, os.PathLike)):
        raise TypeError(f"data must be a folder path, got {data!r}")
    base = Path(os.fspath(data)).expanduser()
    for d in (base, base / "libigl-tutorial-data"):
        if all((d / f).is_file() for f in LIBIGL_ARM_FILES):
            return d
    files = ", ".join(LIBIGL_ARM_FILES)
    if base.is_dir():
        why = "missing: " + ", ".join(f for f in LIBIGL_ARM_FILES if not (base / f).is_file())
    else:
        why = "not a folder" if base.exists() else "no such folder"
    msg = (f"expected libigl's tutorial data files {files} in this folder or in its "
           f"libigl-tutorial-data folder ({why})")
    raise FileNotFoundError(2, msg, str(base))


def format_summary(figs) -> str:
    """A plain-text table per figure: one row per method, one column per number."""
    lines = []
    for fig in figs:
        lines.append(fig.title)
        heads = [h for _, h, _ in fig.columns]
        width = max(len("method"), *(len(m) for m in fig.numbers))
        lines.append("  " + "method".ljust(width) + "".join(f"  {h:>26}" for h in heads))
        for m, nums in fig.numbers.items():
            cells = "".join(f"  {fmt.format(nums[k]):>26}" for k, _, fmt in fig.columns)
            lines.append("  " + m.ljust(width) + cells)
        for k, h, _ in fig.columns:
            lines.append(f"  expected {h}: {fig.expected[k]}")
        lines += [f"  note: {s}" for s in fig.notes]
        lines.append("")
    return "\n".join(lines).rstrip() + "\n"


class _Progress:
    """A one-line progress bar on a terminal; plain lines otherwise."""

    def __init__(self, total: int, stream: TextIO | None):
        self.total, self.done, self.stream = total, 0, stream
        self.live = stream is not None and stream.isatty()
        self.t0 = time.perf_counter()

    def step(self, label: str) -> None:
        if self.stream is None:
            return
        k = int(24 * self.done / max(self.total, 1))
        bar = f"[{'#' * k}{'.' * (24 - k)}] {self.done}/{self.total} " \
              f"{time.perf_counter() - self.t0:5.1f} s  {label}"
        if self.live:
            self.stream.write("\r" + bar.ljust(78))
        else:
            self.stream.write(f"stbs demo: {bar}\n")
        self.stream.flush()

    def close(self) -> None:
        if self.stream is not None and self.live:
            self.stream.write("\n")
            self.stream.flush()


def _check_out(out: Path) -> None:
    if out.exists() and not out.is_dir():
        raise NotADirectoryError(20, "demo output path exists and is not a folder", str(out))
    out.mkdir(parents=True, exist_ok=True)
    if not os.access(out, os.W_OK | os.X_OK):
        raise PermissionError(13, "demo output folder is not writable", str(out))


def run_demo(out_dir: str | os.PathLike = "demo-out", quick: bool = False, *,
             only=None, data: str | os.PathLike | None = None, stream: TextIO | None = None,
             progress: TextIO | None = None, quiet: bool = False) -> DemoResult:
    """Run the demo: the paper's figures on shapes built in code, as pictures and numbers.

    Figures (keys for ``only``): fig2 cigar stretched (LBS explodes the tip, STBS
    keeps it); fig3 a box twisted 315 degrees and a two-bone bar bent, twisted and
    stretched (STBS spreads the twist, LBS/DQS cannot); fig4 a leg bent and stretched
    with bone weights, point weights and STBS; fig5 (= fig1) an arm twisted, bent and
    stretched with LBS, DQS, STBS-DQS; fig6 a character's bone and endpoint weights;
    fig7 a 2D giraffe's neck stretched with four endpoint weights; fig8 a box twisted
    360 degrees with heat vs BBW endpoint weights; fig10 a torso twisted with and
    without a spline filter; fig12 a picture made in code posed by dragging joints.
    Each figure's numbers are in ``summary.txt`` / ``summary.json`` and in the
    gallery ``index.html`` next to its pictures.

    Parameters
    ----------
    out_dir : str or os.PathLike
        Output folder (created, with its parents, if missing). Written: one PNG per
        figure panel set, a few GIF animations, ``index.html``, ``summary.txt``,
        ``summary.json`` and OBJ meshes of Figs. 2 and 3. Nothing else is written;
        every file is written atomically.
    quick : bool
        Coarser meshes and fewer animation frames (under a minute).
    only : str or list of str, optional
        Figure keys, e.g. ``"fig2,fig5"``; default all.
    data : str or os.PathLike, optional
        A folder holding libigl's tutorial data files ``arm.obj``, ``arm.tgf`` and
        ``arm-weights.dmat`` (or holding ``libigl-tutorial-data/`` with them): adds
        that arm scan, with its own weights, to Fig. 5.
    stream : text file, optional
        Where the table is printed (default ``sys.stdout``).
    progress : text file, optional
        Where the progress bar goes (default ``sys.stderr``; a bar on a terminal,
        one line per figure otherwise).
    quiet : bool
        Print nothing.

    Returns
    -------
    DemoResult

    Raises
    ------
    ValueError
        For an unknown figure key.
    stbs._optional.OptionalDependencyError
        When matplotlib or Pillow (the ``demo`` extra) is missing; raised before
        anything is computed or written.
    FileNotFoundError
        When ``data`` does not hold libigl's arm files (before anything is written).
    OSError
        When the output folder cannot be created or written.
    """
    from ..io import atomic_open, write_mesh
    from .gallery import GalleryEntry, write_gallery
    from .render import render_animation, render_panels

    keys = parse_only(only)
    advice = missing(REQUIRES, "the demo's pictures")
    if advice:  # before any work: a missing extra must not cost a figure's computation
        raise OptionalDependencyError(advice)
    arm_dir = None if data is None else libigl_arm_folder(data)
    out = Path(os.fspath(out_dir))
    _check_out(out)
    res = DemoResult()
    makers = [(k, f.__name__, f) for k in keys for f in _MAKERS[k]]
    if arm_dir is not None and "fig5" in keys:
        makers.append(("fig5", "fig5_libigl_arm",
                       functools.partial(paper.fig5_libigl_arm, folder=arm_dir)))
    bar = _Progress(len(makers), None if quiet else (sys.stderr if progress is None
                                                     else progress))
    entries = []
    for key, label, make in makers:
        bar.step(f"{key}: {label}")
        t = time.perf_counter()
        fig = make(quick)
        images = []
        for name, kw in fig.pictures.items():
            res.files.append(render_panels(out / name, **kw))
            images.append(name)
        for name, kw in fig.animations.items():
            res.files.append(render_animation(out / name, **kw))
            images.append(name)
        if key in ("fig2", "fig3"):
            path = out / f"{fig.name}_rest.obj"
            write_mesh(path, fig.V, fig.F)
            res.files.append(path)
            for m, U in fig.U.items():
                path = out / f"{fig.name}_{m}.obj"
                write_mesh(path, U, fig.F)
                res.files.append(path)
        res.figures[fig.name] = fig
        res.seconds[key] = res.seconds.get(key, 0.0) + time.perf_counter() - t
        heads = [h for _, h, _ in fig.columns]
        entries.append(GalleryEntry(
            name=fig.name, title=fig.title, caption=fig.caption, images=images,
            table={m: {h: fmt.format(v[k]) for k, h, fmt in fig.columns}
                   for m, v in fig.numbers.items()},
            columns=heads, expected={h: fig.expected[k] for k, h, _ in fig.columns}))
        bar.done += 1
    bar.step("done")
    bar.close()
    res.summary = format_summary(res.figures.values())
    with atomic_open(out / "summary.txt", "w") as f:
        f.write(res.summary)
    with atomic_open(out / "summary.json", "w") as f:
        json.dump({"quick": quick, "figures": keys, "numbers": res.numbers,
                   "expected": {k: fig.expected for k, fig in res.figures.items()},
                   "notes": {k: fig.notes for k, fig in res.figures.items()},
                   "seconds": res.seconds}, f, indent=2)
        f.write("\n")
    intro = ("Every picture and number on this page was computed by `stbs demo` from shapes "
             "built in code, rigged with stbs's own weight methods.")
    res.files += [out / "summary.txt", out / "summary.json",
                  write_gallery(out, entries, intro=intro)]
    if not quiet:
        stream = sys.stdout if stream is None else stream
        stream.write(res.summary)
        stream.write(f"wrote {len(res.files)} files to {out}\n")
    return res
