"""``stbs``: argument parsing, dispatch and the error contract.

Every subcommand lives in its own module with ``NAME``, ``HELP``, ``DESCRIPTION``,
``EPILOG`` (an example), ``add_arguments(parser)`` and ``run(args) -> int``, and may
define ``requires(args)``: the optional modules (import names) that this run needs.
A missing one is one line naming the extra to install, before any work is done. The
modules import nothing heavy at the top, so building the parser (``stbs --help``)
costs no more than importing :mod:`stbs` itself.

Error contract: a problem with the inputs (``ValueError``, including
:class:`stbs.io.FormatError` and JSON errors, ``TypeError``, ``OSError`` such as a
missing file or an unwritable output) prints exactly one line
``stbs <cmd>: error: <message>`` on stderr and exits with status 2, without a
traceback; ``--debug`` re-raises instead. A missing optional dependency
(:class:`stbs._optional.OptionalDependencyError`) is reported the same way. Usage
errors (unknown option or choice) also print one line and exit 2. Warnings raised
while a command succeeds are printed as ``stbs: warning: <message>``, one line each.
"""

from __future__ import annotations

import argparse
import os
import sys
import warnings
from collections.abc import Sequence
from typing import NoReturn

from .._optional import OptionalDependencyError, missing
from . import animate as _animate
from . import bench as _bench
from . import deform as _deform
from . import demo as _demo
from . import export as _export
from . import fit as _fit
from . import rig as _rig
from . import view as _view
from . import weights as _weights
from ._errors import CommandError
from ._report import PROG, describe
from ._report import flush_warnings as _flush

__all__ = ["main", "build_parser", "CommandError"]

#: Input problems reported as one line and exit status 2.
INPUT_ERRORS = (ValueError, TypeError, OSError, OptionalDependencyError)


class _Parser(argparse.ArgumentParser):
    """An ArgumentParser whose usage errors are one line: ``prog: error: msg``."""

    def error(self, message: str) -> NoReturn:
        line = " ".join(message.split())
        self.exit(2, f"{self.prog}: error: {line} (see '{self.prog} --help')\n")


def _version() -> str:
    from .. import __version__

    return f"{PROG} {__version__}"


def _add_debug(p: argparse.ArgumentParser, *, top: bool) -> None:
    # On the subcommands the default is SUPPRESS so that "stbs --debug deform ..."
    # is not overwritten by the subparser's own default.
    p.add_argument("--debug", action="store_true",
                   default=False if top else argparse.SUPPRESS,
                   help="show the full traceback instead of a one-line error")


COMMANDS = (_deform, _rig, _weights, _demo, _bench, _view, _export, _animate, _fit)


def build_parser() -> argparse.ArgumentParser:
    """The ``stbs`` parser with its subcommands (nothing heavy is imported)."""
    fmt = argparse.RawDescriptionHelpFormatter
    examples = "\n".join(f"  {c.EXAMPLE}" for c in COMMANDS) + f"\n  {PROG} version"
    parser = _Parser(
        prog=PROG, formatter_class=fmt,
        description="Skeletal skinning with stretchable, twistable bones "
                    "(Jacobson & Sorkine 2011): lbs, dqs, stbs-lbs, stbs-dqs.",
        epilog=f"examples:\n{examples}\n\nRun '{PROG} COMMAND --help' for each command's "
               "options. Errors: one line on stderr, exit status 2.")
    parser.add_argument("--version", action="version", version=_version())
    _add_debug(parser, top=True)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for c in COMMANDS:
        # bench's options belong to stbs.bench, parsed on demand (see _run_bench).
        p = sub.add_parser(c.NAME, help=c.HELP, description=c.DESCRIPTION, epilog=c.EPILOG,
                           formatter_class=fmt, add_help=c is not _bench)
        if c is not _bench:
            c.add_arguments(p)
            _add_debug(p, top=False)
        p.set_defaults(_cmd=c)
    p = sub.add_parser("version", help="print the version", description="Print the version.",
                       epilog=f"example:\n  {PROG} version", formatter_class=fmt)
    _add_debug(p, top=False)
    p.set_defaults(_cmd=None)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``stbs`` with ``argv`` (default ``sys.argv[1:]``); return the exit status.

    0 on success, 2 for an input or usage error (one line on stderr), 130 when
    interrupted. Unexpected exceptions (bugs) propagate with their traceback.
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    try:
        args, extra = parser.parse_known_args(argv)
    except SystemExit as exc:  # --help, --version, usage errors
        return _code(exc)
    if args.command is None:
        print(f"{PROG}: error: a command is required: deform, rig, weights, demo, bench, view, "
              f"export, animate, fit or version (see '{PROG} --help')", file=sys.stderr)
        return 2
    prog = f"{PROG} {args.command}"
    if extra and args._cmd is not _bench:
        print(f"{prog}: error: unrecognized arguments: {' '.join(extra)} "
              f"(see '{prog} --help')", file=sys.stderr)
        return 2
    if args._cmd is None:
        print(_version())
        return 0
    debug = bool(getattr(args, "debug", False)) or (args._cmd is _bench and "--debug" in extra)
    with warnings.catch_warnings(record=True) as caught:
        # Ours are UserWarnings: show every one (not once per code location, which
        # would hide repeats in a long-lived process); other categories keep the
        # filters in force (DeprecationWarnings from libraries stay hidden).
        warnings.simplefilter("always", UserWarning)
        try:
            if args._cmd is _bench:
                code = _bench.run_delegated(extra, debug=debug, parser_class=_Parser)
            else:
                need = getattr(args._cmd, "requires", None)
                advice = missing(need(args), "this command") if need else None
                if advice:
                    raise OptionalDependencyError(advice)
                from .._inputs import tracking

                with tracking():
                    _refuse_output_over_input(args)
                    code = args._cmd.run(args)
        except SystemExit as exc:  # a delegated parser's --help or usage error
            return _code(exc)
        except KeyboardInterrupt:
            if debug:
                raise
            print(f"{prog}: interrupted", file=sys.stderr)
            return 130
        except INPUT_ERRORS as exc:
            if debug:
                _flush(caught)
                raise
            print(f"{prog}: error: {describe(exc)}", file=sys.stderr)
            return 2
    _flush(caught)
    return int(code or 0)


#: Arguments that name what a command writes; every other argument naming an existing
#: file is something it reads.
_OUTPUT_ARGS = ("output", "out", "save_as", "clip_out")


def _refuse_output_over_input(args: argparse.Namespace) -> None:
    """Note the files named on the command line as inputs and refuse, before any work,
    an output that is one of them (the writers check again, for files that inputs
    name in turn, such as a glTF's buffers)."""
    from .._inputs import check_output, note_input

    outs = []
    for key, value in vars(args).items():
        values = value if isinstance(value, list) else [value]
        for v in values:
            if not isinstance(v, str) or not v or key.startswith("_"):
                continue
            if key in _OUTPUT_ARGS:
                outs.append((key, v))
            elif os.path.isfile(v):
                note_input(v)
    for key, v in outs:
        check_output(v, "--" + key.replace("_", "-"))


def _code(exc: SystemExit) -> int:
    c = exc.code
    if c is None:
        return 0
    if isinstance(c, int):
        return c
    print(c, file=sys.stderr)
    return 1
