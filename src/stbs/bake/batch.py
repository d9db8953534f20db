"""Many rigs × motions baked on Dask: in-process, a local cluster, or an existing one.

A manifest is a JSON list of jobs ``{"rig", "motion", "output", "method"}`` (paths
relative to the manifest; optional ``"fps"``, ``"frames"``, ``"mapping"``, ``"twist"``,
``"stretch"``, ``"animation"``). The same task graph runs on every scheduler:

- **What is shipped per task**: paths, content hashes, options and a list of frame
  times, never arrays. Each worker process loads a rig once (keyed by its path and the
  hash of its content) and keeps its :class:`stbs.Deformer`; a motion is loaded and
  retargeted once per worker and rig.
- **Chunks**: a job's frames are cut into chunks of ``chunk`` frames, one task each,
  which writes its frames to a part file beside the output (atomically); the job's
  last task joins the parts into the output (atomically) and removes them.
- **Names from inputs**: a job's output is ``OUTPUT-HASH.EXT``, where HASH (16 hex
  digits) covers the rig's and the motion's bytes, the mapping's, the method, the
  options and the stbs version. A re-run skips every output that exists and every part
  that exists, so a killed worker or a killed run loses nothing (the rest is done
  again) and duplicates nothing (equal inputs, equal names).
"""

from __future__ import annotations

import hashlib
import json
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .. import __version__
from ..io import atomic_open
from .core import _npz_bytes, frame_times, load_motion, output_kind, write_frames

__all__ = ["Job", "read_manifest", "run_manifest", "BatchReport", "job_hash", "plan",
           "local_cluster"]

_KEYS = {"rig", "motion", "output", "method", "fps", "frames", "mapping", "twist",
         "stretch", "animation"}
_METHODS = ("lbs", "dqs", "stbs-lbs", "stbs-dqs")


@dataclass(frozen=True)
class Job:
    rig: str
    motion: str
    output: str
    method: str = "stbs-dqs"
    fps: float | None = None
    frames: str | None = None
    mapping: str | None = None
    twist: str = "spread"
    stretch: str = "keep"
    animation: str | None = None


def read_manifest(path: str | os.PathLike) -> list[Job]:
    """The jobs of a manifest file, paths made absolute; errors name the job."""
    p = Path(os.fspath(path))
    try:
        doc = json.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise FileNotFoundError(f"manifest not found: {str(p)!r}") from None
    except json.JSONDecodeError as exc:
        raise ValueError(f"manifest {str(p)!r}: not JSON ({exc})") from None
    if not isinstance(doc, list) or not doc:
        raise ValueError(f"manifest {str(p)!r}: expected a non-empty JSON list of jobs")
    base = p.resolve().parent
    jobs = []
    for k, j in enumerate(doc):
        where = f"manifest {str(p)!r}, job {k}"
        if not isinstance(j, dict):
            raise ValueError(f"{where}: expected an object, got {type(j).__name__}")
        unknown = set(j) - _KEYS
        if unknown:
            raise ValueError(f"{where}: unknown keys {sorted(unknown)}; expected {sorted(_KEYS)}")
        for key in ("rig", "motion", "output"):
            if not isinstance(j.get(key), str) or not j[key]:
                raise ValueError(f"{where}: {key!r} must be a path")
        method = j.get("method", "stbs-dqs")
        if method not in _METHODS:
            raise ValueError(f"{where}: method must be one of {', '.join(_METHODS)}, got "
                             f"{method!r}")
        fields = {k2: j[k2] for k2 in ("fps", "frames", "twist", "stretch", "animation")
                  if k2 in j}
        paths = {key: str((base / j[key]).resolve()) for key in ("rig", "motion", "output")}
        if j.get("mapping") is not None:
            paths["mapping"] = str((base / j["mapping"]).resolve())
        for key in ("rig", "motion", "mapping"):
            if key in paths and not Path(paths[key]).is_file():
                raise ValueError(f"{where}: {key} {j[key]!r} not found")
        kind = output_kind(paths["output"])
        if kind.startswith("folder"):
            raise ValueError(f"{where}: output must be a .npz, .glb or .gltf file")
        jobs.append(Job(method=method, **paths, **fields))
    return jobs


def _file_hash(path: str) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def job_hash(job: Job) -> str:
    """16 hex digits naming a job's output by everything that makes it."""
    parts = {"stbs": __version__, "rig": _file_hash(job.rig), "motion": _file_hash(job.motion),
             "mapping": _file_hash(job.mapping) if job.mapping else None,
             "method": job.method, "fps": job.fps, "frames": job.frames, "twist": job.twist,
             "stretch": job.stretch, "animation": job.animation}
    return hashlib.sha256(json.dumps(parts, sort_keys=True).encode()).hexdigest()[:16]


def _final(job: Job, key: str) -> Path:
    p = Path(job.output)
    return p.with_name(f"{p.stem}-{key}{p.suffix}")


def _part(job: Job, key: str, c: int) -> Path:
    p = Path(job.output)
    return p.with_name(f".{p.stem}-{key}.part{c:05d}.npz")


# ---------------------------------------------------------------- worker side
#: Per worker process: (rig path, hash) -> rig; (rig key, method) -> Deformer;
#: (rig key, motion path, hash, options) -> clip.
_RIGS: dict = {}
_DEFORMERS: dict = {}
_CLIPS: dict = {}


def _rig(path: str, digest: str):
    from ..io import read_rig

    key = (path, digest)
    if key not in _RIGS:
        _RIGS[key] = read_rig(path)
    return _RIGS[key]


def _clip(job: Job, rig_digest: str, motion_digest: str):
    key = (job.rig, rig_digest, job.motion, motion_digest, job.mapping, job.twist,
           job.stretch, job.animation)
    if key not in _CLIPS:
        _CLIPS[key] = load_motion(job.motion, _rig(job.rig, rig_digest), mapping=job.mapping,
                                  twist=job.twist, stretch=job.stretch,
                                  animation=job.animation)
    return _CLIPS[key]


def _deformer(job: Job, rig_digest: str):
    from ..skinning import Deformer

    key = (job.rig, rig_digest, job.method)
    if key not in _DEFORMERS:
        rig = _rig(job.rig, rig_digest)
        _DEFORMERS[key] = Deformer(rig.V, rig.skeleton, rig.W, rig.E, method=job.method,
                                   dtype=np.float32)
    return _DEFORMERS[key]


def bake_chunk(job: Job, rig_digest: str, motion_digest: str, times: list[float],
               part: str) -> dict:
    """One task: bake ``times`` into the part file ``part`` (skipped when it exists)."""
    if Path(part).exists():
        return {"part": part, "frames": len(times), "skinning_s": 0.0, "skipped": True}
    clip = _clip(job, rig_digest, motion_digest)
    dfm = _deformer(job, rig_digest)
    U = np.empty((len(times), *_rig(job.rig, rig_digest).V.shape), dtype=np.float32)
    t0 = time.perf_counter()
    for k, t in enumerate(times):
        U[k] = dfm(clip.pose(float(t)))
    skin = time.perf_counter() - t0
    data = _npz_bytes({"U": U, "times": np.asarray(times, dtype=np.float64)})
    with atomic_open(part, "wb") as f:
        f.write(data)
    return {"part": part, "frames": len(times), "skinning_s": skin, "skipped": False}


def assemble(job: Job, rig_digest: str, motion_digest: str, final: str, chunks: list) -> dict:
    """The job's last task: join the parts into ``final`` and remove them."""
    rig = _rig(job.rig, rig_digest)
    clip = _clip(job, rig_digest, motion_digest)
    parts = [np.load(c["part"]) for c in chunks]
    U = np.concatenate([q["U"] for q in parts])
    times = np.concatenate([q["times"] for q in parts])
    write_frames(final, rig, clip, times, U, job.method)
    for c in chunks:
        Path(c["part"]).unlink(missing_ok=True)
    p = Path(final)
    for stale in p.parent.glob(f".{p.stem}.*.tmp*"):        # left by a killed writer
        stale.unlink(missing_ok=True)
    for stale in p.parent.glob(f"..{p.stem}.part*.tmp*"):     # a part's (".PART.xyz.tmp")
        stale.unlink(missing_ok=True)
    return {"output": final, "frames": int(len(times)),
            "skinning_s": float(sum(c["skinning_s"] for c in chunks)),
            "baked": int(sum(c["frames"] for c in chunks if not c["skipped"]))}


# ---------------------------------------------------------------- client side
@dataclass
class BatchReport:
    """What a run did: outputs written and skipped, frames baked, seconds."""

    written: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    frames: int = 0
    skinning_s: float = 0.0
    wall_s: float = 0.0
    where: str = "in-process"

    @property
    def fps(self) -> float:
        return self.frames / self.wall_s if self.wall_s > 0 else float("inf")

    def summary(self) -> str:
        return (f"{len(self.written)} outputs written, {len(self.skipped)} already done; "
                f"{self.frames} frames baked in {self.wall_s:.2f} s ({self.fps:.1f} frames/s, "
                f"{self.where})")


def _timeline(job: Job, rig):
    """A clip with the job's motion's start, end and rate, for planning the frames: for
    a BVH the capture's frames alone (the workers retarget it), else the motion."""
    from ..clip import Clip
    from ..io import read_bvh
    from ..pose import Pose

    if Path(job.motion).suffix.lower() != ".bvh":
        return load_motion(job.motion, rig, mapping=job.mapping, twist=job.twist,
                           stretch=job.stretch, animation=job.animation)
    m = read_bvh(job.motion)
    rest = Pose.rest(rig.skeleton)
    t = m.times
    keys = [(float(t[0]), rest)] + ([(float(t[-1]), rest)] if len(t) > 1 else [])
    return Clip(keys, fps=m.fps)


def plan(jobs: list[Job], chunk: int):
    """The task graph (dask.delayed) of the jobs not finished yet, and their outputs."""
    import dask

    from ..io import read_rig

    todo, skipped = [], []
    for job in jobs:
        key = job_hash(job)
        final = _final(job, key)
        if final.exists():
            skipped.append(str(final))
            continue
        rd, md = _file_hash(job.rig), _file_hash(job.motion)
        rig = read_rig(job.rig)
        times = frame_times(_timeline(job, rig), fps=job.fps, frames=job.frames)
        chunks = [dask.delayed(bake_chunk, pure=False)(
                      job, rd, md, times[s:s + chunk].tolist(), str(_part(job, key, c)),
                      dask_key_name=f"bake-{key}-{c}")
                  for c, s in enumerate(range(0, len(times), chunk))]
        todo.append(dask.delayed(assemble, pure=False)(job, rd, md, str(final), chunks,
                                                        dask_key_name=f"assemble-{key}"))
    return todo, skipped


def local_cluster(workers: int):
    """A local Dask cluster of ``workers`` processes, one thread each, quiet logs."""
    import logging

    from distributed import LocalCluster

    return LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                        dashboard_address=None, silence_logs=logging.CRITICAL)


def run_manifest(path: str | os.PathLike, *, workers: int | None = None,
                 scheduler: str | None = None, chunk: int = 64, client=None) -> BatchReport:
    """Bake every job of a manifest not done yet; see the module docs.

    Parameters
    ----------
    path : str or os.PathLike
        The manifest (JSON list of jobs).
    workers : int, optional
        Run on a local cluster of that many worker processes (one thread each).
    scheduler : str, optional
        Run on the Dask cluster at this address.
    chunk : int
        Frames per task.
    client : distributed.Client, optional
        Run on this client's cluster (e.g. one kept for several manifests).
    """
    import dask

    jobs = read_manifest(path)
    t0 = time.perf_counter()
    todo, skipped = plan(jobs, chunk)
    report = BatchReport(skipped=skipped)
    results: list[dict[str, Any]] = []
    if todo and client is not None:
        results = client.gather(client.compute(todo))
        report.where = "the given cluster"
    elif todo:
        if workers is None and scheduler is None:
            # one task at a time in this process: the Deformer itself uses every core
            results = list(dask.compute(*todo, scheduler="synchronous"))
        else:
            from distributed import Client

            if scheduler is not None:
                with Client(scheduler) as c:
                    results = c.gather(c.compute(todo))
                report.where = f"cluster {scheduler}"
            else:
                with local_cluster(workers) as cluster, Client(cluster) as c:
                    results = c.gather(c.compute(todo))
                report.where = f"{workers} local workers"
    report.wall_s = time.perf_counter() - t0
    for r in results:
        report.written.append(r["output"])
        report.frames += r["baked"]
        report.skinning_s += r["skinning_s"]
    return report
