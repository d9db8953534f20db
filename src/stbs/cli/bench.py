"""``stbs bench``: delegates to :mod:`stbs.bench.skinning` (skinning throughput), with
``--weights`` to :mod:`stbs.bench.weights` (bounded biharmonic weights), or with
``--viewer`` to :mod:`stbs.bench.viewer` (the viewer's frame time in a headless
browser), imported only when the command runs."""

from __future__ import annotations

import argparse
import importlib
from collections.abc import Sequence

from .._optional import OptionalDependencyError, missing
from ._errors import CommandError

NAME = "bench"
HELP = ("throughput of the four skinning methods, or (--weights) of bounded biharmonic "
        "weights, (--viewer) the viewer's frame time, (--animate) baking")
EXAMPLE = "stbs bench"
DESCRIPTION = ("Time lbs, dqs, stbs-lbs and stbs-dqs per vertex on this machine, beside "
               "a NumPy and a SciPy LBS timed the same way (the options below come from "
               "stbs.bench.skinning). With --weights: time bounded biharmonic weights and a "
               "complete rig instead (its own options: stbs bench --weights --help). With "
               "--viewer: time the viewer's page in headless Chromium beside three.js's "
               "SkinnedMesh (stbs bench --viewer --help).")
EPILOG = (f"examples:\n  {EXAMPLE}\n  stbs bench --sizes 100k --dtype float32 --no-peers\n"
          "  stbs bench --weights --cases 2d-5k,3d-10k --json bbw.json\n"
          "  stbs bench --viewer --sizes 10k,100k --json viewer.json\n"
          "  stbs bench --animate --workers 1,2 --json bake.json")
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


VIEWER_DESCRIPTION = (
    "Time the viewer's page (stbs view) in headless Chromium: milliseconds per frame of "
    "each skinning method on a synthetic tube rig with a stretched and twisted pose, "
    "beside three.js's own SkinnedMesh (three-lbs) on the same mesh (the options below "
    "come from stbs.bench.viewer).")
VIEWER_EPILOG = ("examples:\n  stbs bench --viewer\n"
                 "  stbs bench --viewer --sizes 10k,100k --frames 20 --json viewer.json\n"
                 "  stbs bench --viewer --gpu --browser /usr/bin/chromium")


ANIMATE_DESCRIPTION = (
    "Time baking (stbs animate): frames per second of each skinning method on a synthetic "
    "arm and motion, in this process and on a local Dask cluster, beside plain Deformer "
    "calls in the same run (the options below come from stbs.bench.animate).")
ANIMATE_EPILOG = ("examples:\n  stbs bench --animate\n"
                  "  stbs bench --animate --vertices 100000 --workers 0 --json bake.json")


def _wants(argv: Sequence[str], flag: str) -> bool:
    args = list(argv)
    if "--" in args:
        args = args[:args.index("--")]
    return flag in args


def _wants_weights(argv: Sequence[str]) -> bool:
    return _wants(argv, "--weights")


def run_delegated(argv: Sequence[str], *, debug: bool,
                  parser_class: type[argparse.ArgumentParser]) -> int:
    """Parse ``argv`` with the benchmark module's ``add_arguments`` and call its ``run``:
    :mod:`stbs.bench.weights` when ``--weights`` is given, :mod:`stbs.bench.viewer` when
    ``--viewer`` is, else :mod:`stbs.bench` (the names of :mod:`stbs.bench.skinning`).
    A module's ``requires(args)`` (optional import names) is checked first."""
    weights, viewer = _wants_weights(argv), _wants(argv, "--viewer")
    animate = _wants(argv, "--animate")
    if weights + viewer + animate > 1:
        raise CommandError("--weights, --viewer and --animate are three benchmarks: give "
                           "one of them")
    # stbs.bench is the skinning benchmark's API (stbs.bench.skinning's names)
    bench = _module("stbs.bench.weights" if weights else
                    "stbs.bench.viewer" if viewer else
                    "stbs.bench.animate" if animate else "stbs.bench")
    epilog = VIEWER_EPILOG if viewer else ANIMATE_EPILOG if animate else EPILOG
    description = (WEIGHTS_DESCRIPTION if weights else
                   VIEWER_DESCRIPTION if viewer else
                   ANIMATE_DESCRIPTION if animate else DESCRIPTION)
    viewer = viewer or animate          # neither adds the skinning benchmark's flags below
    if weights:
        cases = getattr(bench, "CASES", {})
        epilog = "cases:\n" + "".join(f"  {c.name:<10} {c.about}\n" for c in cases.values())
        epilog += "\n" + WEIGHTS_EPILOG
    p = parser_class(prog=f"stbs {NAME}", description=description,
                     epilog=epilog,
                     formatter_class=argparse.RawDescriptionHelpFormatter)
    bench.add_arguments(p)
    if not weights and not viewer and not any("--weights" in a.option_strings
                                              for a in p._actions):
        p.add_argument("--weights", action="store_true",
                       help="time bounded biharmonic weights instead "
                            "(its options: stbs bench --weights --help)")
    if not weights and not viewer and not any("--viewer" in a.option_strings
                                              for a in p._actions):
        p.add_argument("--viewer", action="store_true",
                       help="time the viewer's page in headless Chromium instead "
                            "(its options: stbs bench --viewer --help)")
    if not weights and not viewer and not any("--animate" in a.option_strings
                                              for a in p._actions):
        p.add_argument("--animate", action="store_true",
                       help="time baking animations instead "
                            "(its options: stbs bench --animate --help)")
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
