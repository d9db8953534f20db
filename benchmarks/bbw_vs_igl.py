"""Time stbs's bounded biharmonic weights against libigl's ``igl.bbw``: a thin wrapper.

The benchmark lives in :mod:`stbs.bench_weights`; this script is the same as
``stbs bench --weights`` (``make bench-bbw`` runs it). Usage::

    python benchmarks/bbw_vs_igl.py                        # the issue's cases
    python benchmarks/bbw_vs_igl.py --cases 2d-5k,hand --backend cholespy --tol 1e-6

See ``stbs bench --weights --help`` and ``docs/benchmarks.md``.
"""

from __future__ import annotations

import sys

from stbs.bench_weights import main

if __name__ == "__main__":
    sys.exit(main())
