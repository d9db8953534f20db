"""``python -m stbs.bench [--weights | --viewer] [options]``: the same as ``stbs bench``."""

import sys


def _main() -> int:
    argv = sys.argv[1:]
    options = argv[:argv.index("--")] if "--" in argv else argv
    if "--weights" in options:
        from .weights import main
    elif "--viewer" in options:
        from .viewer import main
    else:
        from .skinning import main
    return main(argv)


if __name__ == "__main__":
    sys.exit(_main())
