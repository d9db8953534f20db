"""The ``stbs`` command line: ``stbs rig``, ``stbs weights``, ``stbs deform``,
``stbs view``, ``stbs demo``, ``stbs bench``, ``stbs version``.

``main(argv)`` returns the exit status instead of exiting, so it can be tested in
process; the console script ``stbs`` is ``sys.exit(main())``.
"""

from ._main import CommandError, build_parser, main

__all__ = ["main", "build_parser", "CommandError"]
