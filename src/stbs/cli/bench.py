"""``stbs bench``: delegates to :mod:`stbs.bench.skinning` (skinning throughput), with
``--weights`` to :mod:`stbs.bench.weights` (bounded biharmonic weights), ``--viewer`` to
:mod:`stbs.bench.viewer` (the viewer's frame time in a headless browser), ``--animate``
to :mod:`stbs.bench.animate` (baking), ``--learn`` to :mod:`stbs.bench.learn`
(differentiable skinning) or ``--fit`` to :mod:`stbs.bench.fit` (decomposing a mesh
animation), each imported only when the command runs."""

from __future__ import annotations

import argparse
import importlib
from collections.abc import Sequence

from .._optional import OptionalDependencyError, missing
from ._errors import CommandError

NAME = "bench"
HELP = ("throughput of the four skinning methods, or (--weights) of bounded biharmonic "
        "weights, (--viewer) the viewer's frame time, (--animate) baking, (--learn) "
        "differentiable skinning, (--fit) fitting")
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


LEARN_DESCRIPTION = (
    "Time differentiable skinning (stbs.skin): poses x vertices per second of each "
    "method's batched forward and backward passes on PyTorch and JAX, beside the compiled "
    "NumPy kernels and an LBS written the usual PyTorch way, on one rig in one run (the "
    "options below come from stbs.bench.learn).")
LEARN_EPILOG = ("examples:\n  stbs bench --learn\n"
                "  stbs bench --learn --vertices 100000 --batch 16 --backends torch\n"
                "  stbs bench --learn --compile --device cuda --json learn.json")
FIT_DESCRIPTION = (
    "Time and score skinning decomposition (stbs.fit.decompose) of a mesh animation: RMSE "
    "as a percentage of the bounding-box diagonal and seconds, beside Dem Bones' LBS on "
    "the same frames in the same run (the options below come from stbs.bench.fit).")
FIT_EPILOG = ("examples:\n  stbs bench --fit\n  stbs bench --fit --bones 10 --json fit.json")

# flag -> (module, description, epilog); no flag: the skinning benchmark (stbs.bench's
# names, those of stbs.bench.skinning)
BENCHMARKS = {
    "--weights": ("stbs.bench.weights", WEIGHTS_DESCRIPTION, None),
    "--viewer": ("stbs.bench.viewer", VIEWER_DESCRIPTION, VIEWER_EPILOG),
    "--animate": ("stbs.bench.animate", ANIMATE_DESCRIPTION, ANIMATE_EPILOG),
    "--learn": ("stbs.bench.learn", LEARN_DESCRIPTION, LEARN_EPILOG),
    "--fit": ("stbs.bench.fit", FIT_DESCRIPTION, FIT_EPILOG),
}
BENCH_HELP = {
    "--weights": "time bounded biharmonic weights instead",
    "--viewer": "time the viewer's page in headless Chromium instead",
    "--animate": "time baking animations instead",
    "--learn": "time differentiable skinning (PyTorch, JAX) instead",
    "--fit": "time and score fitting a rig to a mesh animation instead",
}


def _wants(argv: Sequence[str], flag: str) -> bool:
    args = list(argv)
    if "--" in args:
        args = args[:args.index("--")]
    return flag in args


def _weights_epilog(bench) -> str:
    cases = getattr(bench, "CASES", {})
    return ("cases:\n" + "".join(f"  {c.name:<10} {c.about}\n" for c in cases.values())
            + "\n" + WEIGHTS_EPILOG)


def run_delegated(argv: Sequence[str], *, debug: bool,
                  parser_class: type[argparse.ArgumentParser]) -> int:
    """Parse ``argv`` with the benchmark module's ``add_arguments`` and call its ``run``:
    the module :data:`BENCHMARKS` names for the flag given (``--weights``, ``--viewer``,
    ``--animate``, ``--learn``, ``--fit``), else :mod:`stbs.bench` (the names of
    :mod:`stbs.bench.skinning`). A module's ``requires(args)`` (optional import names) is
    checked first."""
    chosen = [flag for flag in BENCHMARKS if _wants(argv, flag)]
    if len(chosen) > 1:
        raise CommandError(f"{', '.join(chosen)} are different benchmarks: give one of them")
    flag = chosen[0] if chosen else None
    name, description, epilog = BENCHMARKS[flag] if flag else ("stbs.bench", DESCRIPTION,
                                                                 EPILOG)
    bench = _module(name)
    if flag == "--weights":
        epilog = _weights_epilog(bench)
    p = parser_class(prog=f"stbs {NAME}", description=description,
                     epilog=epilog,
                     formatter_class=argparse.RawDescriptionHelpFormatter)
    bench.add_arguments(p)
    if flag is None:
        for other, text in BENCH_HELP.items():
            if not any(other in a.option_strings for a in p._actions):
                p.add_argument(other, action="store_true",
                               help=f"{text} (its options: stbs bench {other} --help)")
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
