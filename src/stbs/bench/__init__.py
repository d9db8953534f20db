"""``stbs bench``: how fast stbs runs on this machine (a front end, like ``stbs.cli``).

- :mod:`stbs.bench.skinning`: throughput of the four skinning methods per vertex,
  beside a NumPy and a SciPy LBS timed the same way in the same run (``stbs bench``);
- :mod:`stbs.bench.weights`: our bounded biharmonic weights on built-in meshes and a
  complete rig through :func:`stbs.build_rig` (``stbs bench --weights``);
- :mod:`stbs.bench.viewer`: the viewer's frame time in headless Chromium beside
  three.js's ``SkinnedMesh`` (``stbs bench --viewer``; needs Playwright and Chromium,
  imported only when it runs).

The names below are :mod:`stbs.bench.skinning`'s, for scripts that add their own peers
(the source tree's ``benchmarks/`` times libigl's this way). Nothing here touches the
network or needs an optional dependency. Docs: ``docs/benchmarks.md``.
"""

from .skinning import (
    DEFAULT_SIZES,
    DTYPES,
    PEERS,
    WARMUP,
    BenchRig,
    Peer,
    add_arguments,
    auto_repeats,
    collect,
    csr_bytes,
    format_table,
    lbs_affines,
    lbs_matrix_sparse,
    machine_info,
    make_pose,
    make_rig,
    make_row,
    measure_bandwidth,
    numpy_lbs,
    print_report,
    run,
    run_bench,
    stacked_transforms,
    time_frames,
)

__all__ = ["DEFAULT_SIZES", "DTYPES", "PEERS", "WARMUP", "BenchRig", "Peer", "add_arguments",
           "auto_repeats", "collect", "csr_bytes", "format_table", "lbs_affines",
           "lbs_matrix_sparse", "machine_info", "make_pose", "make_rig", "make_row",
           "measure_bandwidth", "numpy_lbs", "print_report", "run", "run_bench",
           "stacked_transforms", "time_frames"]
