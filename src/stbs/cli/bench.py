"""``stbs bench``: delegates to :mod:`stbs.bench.skinning` (skinning throughput) or, with
``--weights``, to :mod:`stbs.bench.weights` (bounded biharmonic weights), imported only
when the command runs."""

from __future__ import annotations

import argparse
import importlib
from collections.abc import Sequence

from .._optional import OptionalDependencyError, missing
from ._errors import CommandError

NAME = "bench"
HELP = "throughput of the four skinning methods, or (--weights) of bounded biharmonic weights"
EXAMPLE = "stbs bench"
DESCRIPTION = ("Time lbs, dqs, stbs-lbs and stbs-dqs per vertex on this machine, beside "
               "a NumPy and a SciPy LBS timed the same way (the options below come from "
               "stbs.bench.skinning). With --weights: time bounded biharmonic weights and a "
               "complete rig instead (its own options: stbs bench --weights --help).")
EPILOG = (f"examples:\n  {EXAMPLE}\n  stbs bench --sizes 100k --dtype float32 --no-peers\n"
          "  stbs bench --weights --cases 2d-5k,3d-10k --json bbw.json")
WEIGHTS_DESCRIPTION = (
    "Time stbs's bounded biharmonic weights (BBWSolver construction + solve) on built-in "
    "meshes, and a complete 20-bone rig (bone + endpoint weights, stbs.build_rig) per stage "
    "(the options below come from stbs.bench.weights).")
WEIGHTS_EPILOG = ("examples:\n  stbs bench --weights\n"
                  "  stbs bench --weights --cases 2d-small,3d-10k --repeat 3\n"
                  "  stbs bench --weights --cases hand,3d-50k --mesh-dir "
                  "libigl-tutorial-data --json bbw.json")


def _module(name: str):
    try:
        return importlib.import_module(name)
    except ModuleNotFoundError as exc:
        # the module itself or the package holding it; another missing import is a bug
        if exc.name is None or not (name == exc.name or name.startswith(exc.name + ".")):
            raise
        raise CommandError(f"the benchmark module {exc.name} is missing from this "
                           "installation (reinstall stbs-skinning)") from None


def _wants_weights(argv: Sequence[str]) -> bool:
    args = list(argv)
    if "--" in args:
        args = args[:args.index("--")]
    return "--weights" in args


def run_delegated(argv: Sequence[str], *, debug: bool,
                  parser_class: type[argparse.ArgumentParser]) -> int:
    """Parse ``argv`` with the benchmark module's ``add_arguments`` and call its ``run``:
    :mod:`stbs.bench.weights` when ``--weights`` is given, else :mod:`stbs.bench` (the
    names of :mod:`stbs.bench.skinning`).
    A module's ``requires(args)`` (optional import names) is checked first."""
    weights = _wants_weights(argv)
    # stbs.bench is the skinning benchmark's API (stbs.bench.skinning's names)
    bench = _module("stbs.bench.weights" if weights else "stbs.bench")
    epilog = EPILOG
    if weights:
        cases = getattr(bench, "CASES", {})
        epilog = "cases:\n" + "".join(f"  {c.name:<10} {c.about}\n" for c in cases.values())
        epilog += "\n" + WEIGHTS_EPILOG
    p = parser_class(prog=f"stbs {NAME}",
                     description=WEIGHTS_DESCRIPTION if weights else DESCRIPTION,
                     epilog=epilog,
                     formatter_class=argparse.RawDescriptionHelpFormatter)
    bench.add_arguments(p)
    if not weights and not any("--weights" in a.option_strings for a in p._actions):
        p.add_argument("--weights", action="store_true",
                       help="time bounded biharmonic weights instead "
                            "(its options: stbs bench --weights --help)")
    if not any("--debug" in a.option_strings for a in p._actions):
        p.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                       help="show the full traceback instead of a one-line error")
    args = p.parse_args(list(argv))
    if not hasattr(args, "debug"):
        args.debug = debug
    need = getattr(bench, "requires", None)
    advice = missing(need(args), f"stbs {NAME}") if need else None
    if advice:
        raise OptionalDependencyError(advice)
    return int(bench.run(args) or 0)
