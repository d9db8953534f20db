"""``stbs demo``: the paper's Figs. 2 and 3 on built-in shapes (no input files)."""

from __future__ import annotations

import argparse

NAME = "demo"
HELP = "stretch and twist built-in shapes with every method; write meshes and a table"
EXAMPLE = "stbs demo --out demo-out"
DESCRIPTION = """\
Run the paper's Figs. 2 and 3 on shapes generated in code, with lbs, dqs,
stbs-lbs and stbs-dqs, and projection endpoint weights:
  cigar  one bone, stretched x2: length beyond the bone's end (LBS/DQS double it)
  box    one bone, twisted 315 deg at its far end: twist of the middle and far
         cross-sections (STBS spreads it; LBS/DQS can only turn the box rigidly)
  bar    two bones, bent 60 deg, twisted 180 deg and stretched x1.5: smallest
         cross-section near the joint (LBS candy wrapper) and twist mid-upper-bone
Writes <case>_rest.obj and <case>_<method>.obj for each case, summary.txt and
summary.json into the output folder (created if missing; nothing else is written)
and prints the table. Takes a few seconds."""
EPILOG = f"example:\n  {EXAMPLE}"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", default="demo-out", metavar="DIR",
                   help="output folder (default: %(default)s)")
    p.add_argument("--quick", action="store_true", help="coarser meshes")


def run(args: argparse.Namespace) -> int:
    from ..demo import run_demo

    run_demo(args.out, quick=args.quick)
    return 0
