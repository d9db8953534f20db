"""``stbs demo``: the paper's figures reproduced on built-in shapes (no input files)."""

from __future__ import annotations

import argparse

NAME = "demo"
HELP = "reproduce the paper's figures on built-in shapes: PNG panels, GIFs, index.html"
EXAMPLE = "stbs demo --out demo-out"
DESCRIPTION = """\
Build shapes in code, rig them with stbs's own weight methods, pose them and render
the paper's comparisons headless (matplotlib) into the output folder:
  fig2   a cigar stretched x2: LBS explodes the tip, STBS keeps it
  fig3   a box twisted 315 deg; two bones bent, twisted, stretched (plot of the twist)
  fig4   a leg bent and stretched: bone weights, point weights, STBS
  fig5   an arm twisted 180 deg, bent, stretched: LBS, DQS, STBS-DQS (fig1 = fig5)
  fig6   a character's bone weights as colours, endpoint weights as heat maps
  fig7   a 2D giraffe's neck stretched: projection, IDW, heat, BBW endpoint weights
  fig8   a box twisted 360 deg: heat vs BBW endpoint weights
  fig10  a torso twisted by one bone: identity vs spline-filtered endpoint weights
  fig12  a picture made in code, posed by dragging joints (textured)
Writes PNG panels, GIF animations, index.html (open it in a browser), summary.txt
and summary.json, and prints the table of numbers. Only the output folder is
written. About 10 s on two cores (--quick: a few seconds). Needs the demo extra
(pip install 'stbs-skinning[demo]': matplotlib and Pillow)."""
EPILOG = f"""examples:
  {EXAMPLE}
  stbs demo --quick --only fig2,fig5 --out /tmp/demo
  stbs demo --only fig5 --data ~/libigl-tutorial-data   # add libigl's arm scan to fig5"""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", default="demo-out", metavar="DIR",
                   help="output folder (default: %(default)s)")
    p.add_argument("--quick", action="store_true",
                   help="coarser meshes and fewer animation frames")
    p.add_argument("--only", metavar="FIGS", default=None,
                   help="comma-separated figures, e.g. fig2,fig5 (default: all)")
    p.add_argument("--data", metavar="DIR", default=None,
                   help="add libigl's arm scan, with its own weights, to fig5; DIR is "
                        "the folder of libigl's tutorial data with arm.obj, arm.tgf and "
                        "arm-weights.dmat, or a folder holding libigl-tutorial-data/")


def requires(args: argparse.Namespace) -> list[str]:
    """The optional modules this run needs: matplotlib and Pillow (the demo extra)."""
    from ..demo.run import REQUIRES

    return list(REQUIRES)


def run(args: argparse.Namespace) -> int:
    from ..demo import run_demo
    from ..demo.run import libigl_arm_folder, parse_only
    from ._errors import CommandError

    try:
        only = parse_only(args.only)
    except ValueError as exc:
        raise CommandError(str(exc)) from None
    if args.data is not None:
        try:
            libigl_arm_folder(args.data)
        except FileNotFoundError as exc:
            raise CommandError(f"--data {exc.filename}: {exc.strerror}") from None
    try:
        run_demo(args.out, quick=args.quick, only=only, data=args.data)
    except (NotADirectoryError, PermissionError, FileNotFoundError) as exc:
        raise CommandError(f"--out {args.out!r}: {exc.strerror}"
                           if not isinstance(exc, FileNotFoundError)
                           else f"{exc.strerror}: {exc.filename}") from None
    return 0
