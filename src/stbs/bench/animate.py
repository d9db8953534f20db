"""Baking throughput (``stbs bench --animate``): frames per second of :func:`stbs.bake.bake`
for each method, in-process and on a local Dask cluster, beside plain
:class:`stbs.Deformer` calls in the same run.

The rig is a box of about ``--vertices`` surface vertices along an arm of three bones
(smooth analytic bone weights, projection endpoint weights; nothing to solve), the
motion a capture-like clip of ``--frames`` frames (the shoulder waving, the elbow
bending, the wrist rolling), retargeted from a :class:`stbs.Motion` with the roll spread
along the forearm. Three figures per method:

- ``deformer``: the Deformer called on the clip's poses into one reused buffer: the
  skinning itself;
- ``bake``: :func:`stbs.bake.bake` in this process: pose evaluation, skinning into the
  frames' array (its pages committed beforehand: that is the output's cost, excluded
  like the writing); ``overhead`` is ``bake / deformer - 1``;
- ``workers-N``: the same job as a one-job manifest on a local cluster of N processes
  (:func:`stbs.bake.batch.run_manifest`), started once and warmed (imports, compiled
  kernels) before timing; wall clock from the call to the output written: planning
  (reading the rig and retargeting the motion on the client), the chunks (``frames /
  4N`` frames each, each worker loading the rig once), the join and the writing
  included. The cluster's start is reported apart.

The in-process figures are medians over ``--repeat`` rounds, each round timing every
method in turn, so that a change of the machine's load falls on all alike.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from ..skeleton import Skeleton
from ..skinning import METHODS, Deformer
from .report import (
    check_json_path,
    cpu_model,
    int_at_least,
    load_average,
    machine_lines,
    platform_name,
    write_json,
)

__all__ = ["add_arguments", "run", "collect", "arm_case", "requires"]


def arm_case(vertices: int = 10_000, frames: int = 300):
    """(rig, motion) of the benchmark: a box along x with three bones, and a motion."""
    from ..motion import Motion
    from ..rig import Rig
    from ..shapes import box
    from ..weights import projection

    k = max(2, int(round(np.sqrt(vertices / 22.0))))        # box k x 5k, 2(k*5k*2 + k*k)
    V, F = box(2 * ((5 * k) // 2), k, k, size=(4.0, 0.8, 0.8))[:2]
    V = np.array(V, dtype=float)
    V[:, 0] -= V[:, 0].min()                                # x from 0 to 4, as the bones
    sk = Skeleton([[0, 0, 0], [2, 0, 0], [3.6, 0, 0], [4, 0, 0]], [[0, 1], [1, 2], [2, 3]],
                  names=["shoulder", "elbow", "wrist"])
    x = V[:, 0]
    centres = np.array([1.0, 2.8, 3.8])
    W = np.exp(-((x[:, None] - centres[None, :]) / 0.45) ** 2)
    W /= W.sum(axis=1, keepdims=True)
    rig = Rig(V=V, F=F, skeleton=sk, W=W, E=projection(V, sk))
    t = np.arange(frames)
    R = np.tile(np.eye(3), (frames, 4, 1, 1))

    def rot(axis, deg):
        from ..transforms import axis_angle_to_matrix

        return axis_angle_to_matrix(np.broadcast_to(axis, (frames, 3)), np.radians(deg))

    R[:, 0] = rot([0, 0, 1.0], 40 * np.sin(2 * np.pi * t / 60))
    R[:, 1] = rot([0, 1, 0.0], 30 * np.sin(2 * np.pi * t / 45))
    R[:, 2] = rot([1, 0, 0.0], 3.0 * t)
    motion = Motion(["shoulder", "elbow", "wrist", "wrist_end"], [-1, 0, 1, 2],
                    [[0, 0, 0], [2, 0, 0], [1.6, 0, 0], [0.4, 0, 0]], rotations=R,
                    frame_time=1 / 30, end_site=[False, False, False, True])
    return rig, motion


def _write_bvh(path: Path, motion) -> None:
    """The motion as a BVH file (Z X Y channels), for the cluster run's manifest."""
    names, par, off = motion.names, motion.parents, motion.offsets
    lines = ["HIERARCHY"]

    def block(k, depth):
        pad = "  " * depth
        if motion.end_site[k]:
            lines.extend([f"{pad}End Site", f"{pad}{{",
                          f"{pad}  OFFSET {' '.join(map(str, off[k]))}", f"{pad}}}"])
            return
        lines.append(f"{pad}{'ROOT' if par[k] < 0 else 'JOINT'} {names[k]}")
        lines.append(f"{pad}{{")
        lines.append(f"{pad}  OFFSET {' '.join(map(str, off[k]))}")
        lines.append(f"{pad}  CHANNELS 3 Zrotation Xrotation Yrotation")
        for c in motion.children(k):
            block(c, depth + 1)
        lines.append(f"{pad}}}")

    block(0, 0)
    # Z X Y Euler angles of each joint's rotation: R = Rz(a) Rx(b) Ry(c)
    R = motion.rotations[:, ~motion.end_site]
    b = np.arcsin(np.clip(R[..., 2, 1], -1, 1))
    a = np.arctan2(-R[..., 0, 1], R[..., 1, 1])
    c = np.arctan2(-R[..., 2, 0], R[..., 2, 2])
    ang = np.degrees(np.stack([a, b, c], axis=-1)).reshape(motion.n_frames, -1)
    lines += ["MOTION", f"Frames: {motion.n_frames}", f"Frame Time: {motion.frame_time:.10f}"]
    lines += [" ".join(f"{v:.6f}" for v in row) for row in ang]
    path.write_text("\n".join(lines) + "\n")


def _worker_counts(text: str) -> tuple[int, ...]:
    try:
        counts = tuple(int(t) for t in str(text).split(",") if t.strip())
    except ValueError:
        counts = ()
    if not counts or any(c < 0 for c in counts):
        raise argparse.ArgumentTypeError(f"expected worker counts like 1,2 (0: none), got "
                                         f"{text!r}")
    return tuple(c for c in counts if c > 0)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--animate", action="store_true", required=True,
                        help="time baking (this benchmark)")
    parser.add_argument("--vertices", type=int_at_least(100), default=10_000,
                        help="about this many vertices (default 10000)")
    parser.add_argument("--frames", type=int_at_least(1), default=300,
                        help="frames of the motion (default 300)")
    parser.add_argument("--repeat", type=int_at_least(1), default=5,
                        help="in-process rounds, each timing every method (default 5)")
    parser.add_argument("--workers", type=_worker_counts, default=(1, 2),
                        help="also bake on local clusters of these many processes, "
                             "comma-separated; 0: in-process only (default 1,2)")
    parser.add_argument("--json", metavar="OUT.json", default=None,
                        help='also write {"animate": [{"vertices", "method", "mode", '
                             '"frames", "frames_per_s", "overhead"}, ...]}')


def requires(args: argparse.Namespace) -> list[str]:
    return ["dask", "distributed"] if any(args.workers) else []


def collect(args: argparse.Namespace, *, log=lambda msg: None) -> dict:
    from ..bake import bake
    from ..retargeting import retarget

    rig, motion = arm_case(args.vertices, args.frames)
    clip = retarget(motion, rig)
    poses = [p for _, p in clip.keys]
    n = len(rig.V)
    rows = []
    times: dict[tuple[str, str], list[float]] = {}
    dfms = {m: Deformer(rig.V, rig.skeleton, rig.W, rig.E, method=m, dtype=np.float32)
            for m in METHODS}
    buf = np.empty((n, 3), dtype=np.float32)
    with tempfile.TemporaryDirectory(prefix="stbs-bench-animate-") as tmp:
        tmp = Path(tmp)
        for m in METHODS:                                   # warm-up (compilation)
            dfms[m](poses[0], out=buf)
            bake(rig, clip, tmp / "warm.npz", method=m, frames="0:2")
        for r in range(args.repeat):
            for m in METHODS:
                t0 = time.perf_counter()
                for p in poses:
                    dfms[m](p, out=buf)
                times.setdefault((m, "deformer"), []).append(time.perf_counter() - t0)
                b = bake(rig, clip, tmp / f"{m}.npz", method=m)
                times.setdefault((m, "bake"), []).append(b.total_s)
            log(f"round {r + 1}/{args.repeat} done")
        for m in METHODS:
            d = statistics.median(times[(m, "deformer")])
            b = statistics.median(times[(m, "bake")])
            rows.append({"vertices": n, "method": m, "mode": "deformer", "frames": len(poses),
                         "frames_per_s": len(poses) / d, "overhead": None})
            rows.append({"vertices": n, "method": m, "mode": "bake", "frames": len(poses),
                         "frames_per_s": len(poses) / b, "overhead": b / d - 1})
        if args.workers:
            from distributed import Client

            from ..bake.batch import local_cluster, run_manifest
            from ..io import save_rig

            save_rig(tmp / "arm.npz", rig)
            _write_bvh(tmp / "motion.bvh", motion)

            def manifest(name: str, m: str, frames: str | None = None) -> Path:
                job = {"rig": "arm.npz", "motion": "motion.bvh", "output": f"{name}.npz",
                       "method": m}
                if frames:
                    job["frames"] = frames
                man = tmp / f"{name}.json"
                man.write_text(json.dumps([job]))
                return man

            for w in args.workers:
                chunk = max(1, len(poses) // (4 * w))
                t0 = time.perf_counter()
                with local_cluster(w) as cluster, Client(cluster) as client:
                    started = time.perf_counter() - t0
                    for m in METHODS:   # warm the workers: imports, compiled kernels, rig
                        run_manifest(manifest(f"warm-{w}-{m}", m, "0:2"), chunk=1,
                                     client=client)
                    log(f"{w} workers started in {started:.1f} s and warmed")
                    for m in METHODS:
                        rep = run_manifest(manifest(f"{w}-{m}", m), chunk=chunk, client=client)
                        rows.append({"vertices": n, "method": m, "mode": f"workers-{w}",
                                     "frames": rep.frames,
                                     "frames_per_s": rep.frames / rep.wall_s,
                                     "overhead": None, "cluster_start_s": started})
                        log(f"{m} on {w} workers: {rep.wall_s:.2f} s")
    machine = {"cpu": cpu_model(), "cpus": os.cpu_count(), "platform": platform_name(),
               "load_average": load_average()}
    return {"animate": rows, "machine": machine}


def format_table(doc: dict) -> list[str]:
    rows = doc["animate"]
    lines = [f"{'vertices':>9}  {'method':<9} {'mode':<10} {'frames/s':>10} {'ms/frame':>9} "
             f"{'overhead':>9}"]
    lines.append("-" * len(lines[0]))
    for r in rows:
        ov = "" if r["overhead"] is None else f"{100 * r['overhead']:+.1f}%"
        lines.append(f"{r['vertices']:>9}  {r['method']:<9} {r['mode']:<10} "
                     f"{r['frames_per_s']:>10.1f} {1e3 / r['frames_per_s']:>9.3f} {ov:>9}")
    return lines


def run(args: argparse.Namespace) -> int:
    path = check_json_path(args.json)

    def log(msg: str) -> None:
        print(f"stbs bench: {msg}", file=sys.stderr, flush=True)

    doc = collect(args, log=log)
    versions = f"numpy {np.__version__}"
    for line in machine_lines(doc["machine"], versions, "baking"):
        print(line)
    print()
    for line in format_table(doc):
        print(line)
    if path is not None:
        write_json(path, doc)
        print(f"\nwrote {path}")
    return 0
