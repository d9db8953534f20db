"""``stbs bench``: delegates to :mod:`stbs.bench`, imported only when the command runs."""

from __future__ import annotations

import argparse
import importlib
from collections.abc import Sequence

from ._errors import CommandError

NAME = "bench"
HELP = "throughput of the four skinning methods on this machine"
EXAMPLE = "stbs bench"
DESCRIPTION = ("Time lbs, dqs, stbs-lbs and stbs-dqs per vertex on this machine, beside "
               "NumPy, SciPy and libigl peers (the options below come from stbs.bench).")
EPILOG = f"examples:\n  {EXAMPLE}\n  stbs bench --sizes 100k --dtype float32 --no-peers"


def _module():
    try:
        bench = importlib.import_module("stbs.bench")
    except ModuleNotFoundError as exc:
        if exc.name != "stbs.bench":
            raise
        raise CommandError("the benchmark module stbs.bench is missing from this installation "
                         "(reinstall stbs-skinning)") from None
    return bench


def run_delegated(argv: Sequence[str], *, debug: bool,
                  parser_class: type[argparse.ArgumentParser]) -> int:
    """Parse ``argv`` with :func:`stbs.bench.add_arguments` and call :func:`stbs.bench.run`."""
    bench = _module()
    p = parser_class(prog=f"stbs {NAME}", description=DESCRIPTION, epilog=EPILOG,
                     formatter_class=argparse.RawDescriptionHelpFormatter)
    bench.add_arguments(p)
    if not any("--debug" in a.option_strings for a in p._actions):
        p.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                       help="show the full traceback instead of a one-line error")
    args = p.parse_args(list(argv))
    if not hasattr(args, "debug"):
        args.debug = debug
    return int(bench.run(args) or 0)
