"""Many rigs × motions baked on Dask: in-process, a local cluster, or an existing one.

A manifest is a JSON list of jobs ``{"rig", "motion", "output", "method"}`` (paths
relative to the manifest; optional ``"fps"``, ``"frames"``, ``"mapping"``, ``"twist"``,
``"stretch"``, ``"animation"``, ``"max_frames"``). The same task graph runs on every
scheduler:

- **What is shipped per task**: paths, content hashes, options and a list of frame
  times, never arrays. Each worker process loads a rig once (keyed by its path and the
  hash of its content) and keeps its :class:`stbs.Deformer`; a motion is loaded and
  retargeted once per worker and rig.
- **Chunks**: a job's frames are cut into chunks of ``chunk`` frames, one task each,
  which writes its frames to a part file ``.OUTPUT-HASH.EXT.partNNNNN.npz`` beside the
  output (atomically); the job's last task joins the parts into the output
  (atomically) and removes them.
- **Names from inputs**: a job's output is ``OUTPUT-HASH.EXT``, where HASH (16 hex
  digits) covers the rig's and the motion's bytes, the mapping's, the method, the
  options and the stbs version. Equal inputs give equal names, so nothing is baked
  twice.
- **Bounded**: a job bakes at most :func:`stbs.bake.core.frame_limit` frames (its
  frames × vertices within :data:`stbs.bake.core.MAX_BAKE_BYTES`, the job's
  ``"max_frames"`` when given): more is an error before any work, since its last task
  holds all its frames at once.
- **Done means sound**: a re-run skips an output only when it is a regular file that
  checks out (``.npz``: a readable zip whose ``U`` has the job's frames × vertices and
  whose ``times`` are the job's; ``.glb``: the header's magic, version and length
  agree with the file; ``.gltf``: JSON); a damaged one is baked again
  (:attr:`BatchReport.rebaked`). Part files are checked the same way before they are
  skipped and again when joined; a damaged part is baked again, never joined. When a
  job is done, its leftover part files and the temporary files of killed writers are
  removed, so a run killed at any moment (while writing a part, between parts, while
  writing the output, after it) loses nothing and leaves nothing once re-run. One run
  at a time per output folder: a run removes the temporary files of another's writers.
- **Checked before any work**: the manifest is read with the safe JSON reader
  (:func:`stbs._json.read_json`), and every error is a ``ValueError`` naming the
  manifest and the job: unknown keys or values, missing inputs, an output listed twice
  (after resolving paths), an output that is a job's rig, motion or mapping, an output
  outside the manifest's folder (after resolving symbolic links; allowed with
  ``outputs_anywhere=True``), and, when planning, anything but a regular file where an
  output goes.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import os
import re
import stat
import struct
import time
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .. import __version__
from .._json import load_json, read_json
from ..io import atomic_open
from ..methods import SKINNING_METHODS
from .core import _npz_bytes, frame_limit, frame_times, load_motion, output_kind, write_frames

__all__ = ["Job", "read_manifest", "run_manifest", "BatchReport", "job_hash", "plan",
           "local_cluster"]

_KEYS = {"rig", "motion", "output", "method", "fps", "frames", "mapping", "twist",
         "stretch", "animation", "max_frames"}
_CHOICES = {"method": SKINNING_METHODS, "twist": ("spread", "joint"), "stretch": ("keep", "match")}
_INPUTS = ("rig", "motion", "mapping")
#: The name of a batch's work file, which runs remove: a part, or a temporary file
#: (``atomic_open``'s ``.NAME.RANDOM.tmpEXT``) of an output or of a part.
_WORK = re.compile(r"\.\.?.*-[0-9a-f]{16}\.(?:npz|glb|gltf)\."
                   r"(?:part\d{5,}\.npz(?:\.[a-z0-9_]+\.tmp\.npz)?|[a-z0-9_]+\.tmp\.\w+)",
                   re.IGNORECASE)


@dataclass(frozen=True)
class Job:
    """One job of a manifest, its paths absolute; ``where`` names it in errors."""

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
    max_frames: int | None = None
    where: str = field(default="", compare=False)

    @property
    def name(self) -> str:
        return self.where or f"job {self.output!r}"


def _resolve(base: Path, value: str, what: str, where: str) -> Path:
    try:
        return (base / value).resolve()
    except (OSError, ValueError, RuntimeError) as exc:   # NUL bytes, link loops, too long
        raise ValueError(f"{where}: {what} {value!r} is not a usable path ({exc})") from None


def _regular(path: Path) -> bool:
    try:
        return stat.S_ISREG(os.stat(path).st_mode)
    except (OSError, ValueError):
        return False


def _identity(path: Path) -> tuple[int, int] | None:
    try:
        st = os.stat(path)
    except (OSError, ValueError):
        return None
    return st.st_dev, st.st_ino


def read_manifest(path: str | os.PathLike, *, outputs_anywhere: bool = False) -> list[Job]:
    """The jobs of a manifest file, paths made absolute (symbolic links resolved).

    Parameters
    ----------
    path : str or os.PathLike
        The manifest: a JSON list of jobs (see the module docs).
    outputs_anywhere : bool
        Allow outputs outside the manifest's folder (by default refused).

    Raises
    ------
    ValueError
        Naming the manifest and the job: a document that is not safe JSON, a job that
        is not an object, unknown keys, values out of their choices, inputs that are
        not files, an output that is not a ``.npz``/``.glb``/``.gltf`` in an existing
        folder, one output listed by two jobs, an output outside the manifest's
        folder, an output that is a job's input, or an input named as a batch's work
        file (which runs remove).
    """
    p, doc = read_json(path, "manifest")
    name = f"manifest {str(p)!r}"
    if not isinstance(doc, list) or not doc:
        raise ValueError(f"{name}: expected a non-empty JSON list of jobs")
    base = p.resolve().parent
    jobs: list[Job] = []
    outputs: dict[Path, int] = {}
    for k, j in enumerate(doc):
        where = f"{name}, job {k}"
        if not isinstance(j, dict):
            raise ValueError(f"{where}: expected an object, got {type(j).__name__}")
        unknown = set(j) - _KEYS
        if unknown:
            raise ValueError(f"{where}: unknown keys {sorted(unknown)}; expected {sorted(_KEYS)}")
        fields = _fields(j, where)
        paths: dict[str, str] = {}
        for key in ("rig", "motion", "mapping"):
            if j.get(key) is None and key == "mapping":
                continue
            q = _resolve(base, j[key], key, where)
            if not _regular(q):
                raise ValueError(f"{where}: {key} {j[key]!r} not found (or not a file)")
            if _WORK.fullmatch(q.name):
                raise ValueError(f"{where}: {key} {j[key]!r} is named as a batch's part or "
                                 f"temporary file, which a run removes; rename it")
            paths[key] = str(q)
        out = _resolve(base, j["output"], "output", where)
        try:
            kind = output_kind(out)
        except ValueError:
            kind = "other"
        if kind not in ("npz", "gltf"):
            raise ValueError(f"{where}: output {j['output']!r} must be a .npz, .glb or "
                             f".gltf file")
        if not outputs_anywhere and not out.is_relative_to(base):
            raise ValueError(f"{where}: output {j['output']!r} is {str(out)!r}, outside the "
                             f"manifest's folder {str(base)!r}; allow it with "
                             f"outputs_anywhere=True (--outputs-anywhere)")
        if not out.parent.is_dir():
            raise ValueError(f"{where}: output folder {str(out.parent)!r} does not exist")
        if out in outputs:
            raise ValueError(f"{name}: jobs {outputs[out]} and {k} have the same output "
                             f"{str(out)!r}; list each output once")
        outputs[out] = k
        paths["output"] = str(out)
        jobs.append(Job(**paths, **fields, where=where))
    inputs = _inputs_of(jobs)
    for job in jobs:
        _not_an_input(Path(job.output), inputs, job, "output")
    return jobs


def _fields(j: dict, where: str) -> dict[str, Any]:
    """The options of a job object, checked."""
    for key in ("rig", "motion", "output"):
        if not isinstance(j.get(key), str) or not j[key]:
            raise ValueError(f"{where}: {key!r} must be a path")
    out: dict[str, Any] = {}
    for key, choices in _CHOICES.items():
        if key in j:
            if not isinstance(j[key], str) or j[key] not in choices:
                raise ValueError(f"{where}: {key!r} must be one of {', '.join(choices)}, "
                                 f"got {j[key]!r}")
            out[key] = j[key]
    fps = j.get("fps")
    if fps is not None:
        if isinstance(fps, bool) or not isinstance(fps, (int, float)) or not fps > 0:
            raise ValueError(f"{where}: 'fps' must be a number above 0, got {fps!r}")
        out["fps"] = float(fps)
    top = j.get("max_frames")
    if top is not None:
        if isinstance(top, bool) or not isinstance(top, int) or top < 1:
            raise ValueError(f"{where}: 'max_frames' must be an integer of 1 or more, got "
                             f"{top!r}")
        out["max_frames"] = top
    for key, what in (("frames", "a string A:B:STEP"), ("mapping", "a path"),
                      ("animation", "an animation's name")):
        if j.get(key) is not None:
            if not isinstance(j[key], str) or not j[key]:
                raise ValueError(f"{where}: {key!r} must be {what}, got {j[key]!r}")
            if key != "mapping":
                out[key] = j[key]
    return out


def _inputs_of(jobs: list[Job]) -> dict:
    """Every job's inputs by resolved path and by (device, inode): what and whose."""
    found: dict = {}
    for k, job in enumerate(jobs):
        for key in _INPUTS:
            q = getattr(job, key)
            if q is not None:
                whose = f"the {key} of job {k}"
                found.setdefault(q, whose)
                ident = _identity(Path(q))
                if ident is not None:
                    found.setdefault(ident, whose)
    return found


def _not_an_input(path: Path, inputs: dict, job: Job, what: str) -> None:
    real = str(path.resolve())
    whose = inputs.get(real) or inputs.get(_identity(path) or ("", ""))
    if whose is not None:
        raise ValueError(f"{job.name}: {what} {str(path)!r} is {whose}; an input is never "
                         f"written over, choose another output")


def _file_hash(path: str) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _digests(job: Job, cache: dict | None = None) -> tuple[str, str, str | None]:
    """SHA-256 of the job's rig, motion and mapping (``cache``: path -> digest)."""
    cache = {} if cache is None else cache
    for q in (job.rig, job.motion, job.mapping):
        if q is not None and q not in cache:
            cache[q] = _file_hash(q)
    return cache[job.rig], cache[job.motion], cache[job.mapping] if job.mapping else None


def _key(job: Job, digests: tuple[str, str, str | None]) -> str:
    # max_frames bounds the work, it does not change the frames: not part of the name
    rd, md, mapd = digests
    parts = {"stbs": __version__, "rig": rd, "motion": md, "mapping": mapd,
             "method": job.method, "fps": job.fps, "frames": job.frames, "twist": job.twist,
             "stretch": job.stretch, "animation": job.animation}
    return hashlib.sha256(json.dumps(parts, sort_keys=True).encode()).hexdigest()[:16]


def job_hash(job: Job) -> str:
    """16 hex digits naming a job's output by everything that makes it."""
    return _key(job, _digests(job))


def _final(job: Job, key: str) -> Path:
    p = Path(job.output)
    return p.with_name(f"{p.stem}-{key}{p.suffix}")


def _part(job: Job, key: str, c: int) -> Path:
    # named after the output's whole name: the same job to .npz and .glb has two sets
    return Path(job.output).with_name(f".{_final(job, key).name}.part{c:05d}.npz")


# ------------------------------------------------------------ checks and clean-up
def _npz_sound(path: str | os.PathLike, times: np.ndarray, shape: tuple[int, int]) -> bool:
    """Whether ``path`` is a readable .npz whose ``U`` is float32 (len(times), *shape)
    (read up to its header, the size of its data checked against the member's) and
    whose ``times`` are ``times``: cheap, and it catches an empty, cut or foreign file."""
    try:
        with zipfile.ZipFile(path) as z:
            info = z.getinfo("U.npy")
            with z.open(info) as f:
                version = np.lib.format.read_magic(f)
                read = (np.lib.format.read_array_header_1_0 if version == (1, 0)
                        else np.lib.format.read_array_header_2_0)
                U_shape, _, dtype = read(f)
                start = f.tell()
            t = np.load(io.BytesIO(z.read("times.npy")), allow_pickle=False)
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile, struct.error):
        return False
    want = (len(times), *shape)
    return (tuple(U_shape) == want and dtype == np.float32
            and info.file_size == start + 4 * int(np.prod(want))
            and t.shape == times.shape and bool(np.array_equal(t, times)))


def _gltf_sound(path: Path) -> bool:
    """A .glb whose header (magic, version 2, length) and first chunk (JSON, inside the
    file) agree with the file, or a .gltf that parses as a JSON object with "asset"."""
    try:
        if path.suffix.lower() == ".glb":
            size = path.stat().st_size
            with open(path, "rb") as f:
                head = f.read(20)
            if len(head) < 20:
                return False
            magic, version, length, chunk, kind = struct.unpack("<4sIIII", head)
            return (magic == b"glTF" and version == 2 and length == size
                    and kind == 0x4E4F534A and 20 + chunk <= size)
        doc = load_json(path.read_bytes(), str(path), what="glTF")
        return isinstance(doc, dict) and isinstance(doc.get("asset"), dict)
    except (OSError, ValueError):
        return False


def _work_files(final: Path) -> list[Path]:
    """The part files of ``final`` (any chunk size) and the temporary files that
    killed writers of it or of its parts left, in its folder."""
    F, ext = re.escape(final.name), re.escape(final.suffix)
    ours = re.compile(rf"\.{F}\.part\d{{5,}}\.npz|\.\.{F}\.part\d{{5,}}\.npz\.[a-z0-9_]+\.tmp\.npz"
                      rf"|\.{F}\.[a-z0-9_]+\.tmp{ext}")
    names = []
    with contextlib.suppress(OSError), os.scandir(final.parent) as it:
        for e in it:
            if e.name.startswith(".") and ours.fullmatch(e.name):
                names.append(final.parent / e.name)
    return sorted(names)


def _clean(final: Path) -> list[str]:
    """Remove :func:`_work_files` of ``final`` (files and links only); what went."""
    gone = []
    for q in _work_files(final):
        if q.is_symlink() or _regular(q):
            with contextlib.suppress(FileNotFoundError):
                q.unlink()
                gone.append(str(q))
    return gone


@contextlib.contextmanager
def _about(job: Job):
    """Errors of a job's work name the manifest and the job."""
    try:
        yield
    except ValueError as exc:
        if job.name in str(exc):
            raise
        raise ValueError(f"{job.name}: {exc}") from None
    except OSError as exc:
        raise ValueError(f"{job.name}: {exc}") from None


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


def _bake(job: Job, rig_digest: str, motion_digest: str, times: list[float]):
    """The frames (len(times), n, d) float32 at ``times``, and the seconds skinning."""
    clip = _clip(job, rig_digest, motion_digest)
    dfm = _deformer(job, rig_digest)
    U = np.empty((len(times), *_rig(job.rig, rig_digest).V.shape), dtype=np.float32)
    t0 = time.perf_counter()
    for k, t in enumerate(times):
        U[k] = dfm(clip.pose(float(t)))
    return U, time.perf_counter() - t0


def bake_chunk(job: Job, rig_digest: str, motion_digest: str, times: list[float],
               part: str) -> dict:
    """One task: bake ``times`` into the part file ``part``, skipped when a sound one
    (:func:`_npz_sound`) is there; a damaged one is baked again."""
    with _about(job):
        shape = _rig(job.rig, rig_digest).V.shape
        T = np.asarray(times, dtype=np.float64)
        out = {"part": part, "times": times, "frames": len(times), "skinning_s": 0.0,
               "skipped": True, "damaged": False}
        if _regular(Path(part)) and _npz_sound(part, T, shape):
            return out
        out["damaged"] = os.path.lexists(part)
        U, out["skinning_s"] = _bake(job, rig_digest, motion_digest, times)
        with atomic_open(part, "wb") as f:
            f.write(_npz_bytes({"U": U, "times": T}))
        out["skipped"] = False
        return out


def _joined(part: str, times: np.ndarray, shape: tuple[int, int]):
    """A part's frames, or None when it is missing or damaged (a zip member's CRC is
    checked as it is read)."""
    try:
        with np.load(part, allow_pickle=False) as q:
            U, t = q["U"], q["times"]
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile):
        return None
    ok = U.shape == (len(times), *shape) and U.dtype == np.float32 and np.array_equal(t, times)
    return U if ok else None


def assemble(job: Job, rig_digest: str, motion_digest: str, final: str, chunks: list) -> dict:
    """The job's last task: join the parts into ``final`` (a part found damaged now is
    baked again, not joined), then remove the parts and killed writers' leftovers."""
    with _about(job):
        rig = _rig(job.rig, rig_digest)
        clip = _clip(job, rig_digest, motion_digest)
        Us, skin, baked, again = [], 0.0, 0, 0
        for c in chunks:
            times = np.asarray(c["times"], dtype=np.float64)
            U = _joined(c["part"], times, rig.V.shape)
            if not c["skipped"]:
                skin, baked = skin + c["skinning_s"], baked + c["frames"]
            damaged = U is None or c["damaged"]
            if U is None:
                U, s = _bake(job, rig_digest, motion_digest, c["times"])
                skin, baked = skin + s, baked + len(times)
            again += damaged
            Us.append(U)
        times = np.concatenate([np.asarray(c["times"], dtype=np.float64) for c in chunks])
        write_frames(final, rig, clip, times, np.concatenate(Us), job.method)
        removed = _clean(Path(final))
        return {"output": final, "frames": int(len(times)), "skinning_s": float(skin),
                "baked": int(baked), "parts_rebaked": int(again), "removed": removed}


# ---------------------------------------------------------------- client side
@dataclass
class BatchReport:
    """What a run did: outputs written (``rebaked``: those found damaged and written
    again) and skipped (done and sound), part files baked again (damaged), leftover
    files removed (parts and temporary files of killed runs), frames baked, seconds."""

    written: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    rebaked: list[str] = field(default_factory=list)
    removed: list[str] = field(default_factory=list)
    parts_rebaked: int = 0
    frames: int = 0
    skinning_s: float = 0.0
    wall_s: float = 0.0
    where: str = "in-process"

    @property
    def fps(self) -> float:
        return self.frames / self.wall_s if self.wall_s > 0 else float("inf")

    def summary(self) -> str:
        notes = [f"{n} {what}{'' if n == 1 else 's'} {done}" for n, what, done in (
            (len(self.rebaked), "damaged output", "rebaked"),
            (self.parts_rebaked, "damaged part", "rebaked"),
            (len(self.removed), "leftover file", "removed")) if n]
        return (f"{len(self.written)} outputs written, {len(self.skipped)} already done"
                f"{''.join('; ' + s for s in notes)}; {self.frames} frames baked in "
                f"{self.wall_s:.2f} s ({self.fps:.1f} frames/s, {self.where})")


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


def _times(job: Job, rig) -> np.ndarray:
    """The job's frame times; more than :func:`frame_limit` allows is a ValueError."""
    n = len(rig.V)
    return frame_times(_timeline(job, rig), fps=job.fps, frames=job.frames,
                       limit=frame_limit(n, job.max_frames), n_vertices=n)


def plan(jobs: list[Job], chunk: int, *, report: BatchReport | None = None):
    """The task graph (dask.delayed) of the jobs not finished yet, and the outputs done.

    An output is done when it is a regular file that checks out (see the module docs);
    then its leftover work files are removed (listed in ``report.removed``). A damaged
    one is planned again (``report.rebaked``). Anything else at an output's path (a
    folder, a link, a device) is a ``ValueError`` naming the job and the path, as is an
    output that is a job's input.
    """
    import dask

    from ..io import read_rig

    report = BatchReport() if report is None else report
    inputs = _inputs_of(jobs)
    hashes: dict = {}
    rigs: dict = {}
    todo, skipped = [], []
    for job in jobs:
        with _about(job):
            digests = _digests(job, hashes)
            key = _key(job, digests)
            final = _final(job, key)
            _not_an_input(final, inputs, job, "output")
            try:
                mode = os.lstat(final).st_mode
            except FileNotFoundError:
                mode = None
            if mode is not None and not stat.S_ISREG(mode):
                raise ValueError(f"output {str(final)!r} is not a regular file (a folder, a "
                                 f"link or a device is there); move it away and re-run")
            if job.rig not in rigs:
                rigs[job.rig] = read_rig(job.rig)
            rig = rigs[job.rig]
            times = None
            if mode is not None:
                if final.suffix.lower() == ".npz":
                    times = _times(job, rig)
                    sound = _npz_sound(final, times, rig.V.shape)
                else:
                    sound = _gltf_sound(final)
                if sound:
                    skipped.append(str(final))
                    report.removed.extend(_clean(final))
                    continue
                report.rebaked.append(str(final))
            if times is None:
                times = _times(job, rig)
            # a part never replaces an input: inputs named as work files are refused,
            # and an atomic write replaces a name, never the file a link leads to
            parts = [_part(job, key, c) for c in range(-(-len(times) // chunk))]
        # dask keys: the hash and the output's name (equal jobs to .npz and .glb are two)
        tag = f"{key}-{hashlib.sha256(str(final).encode()).hexdigest()[:8]}"
        rd, md, _ = digests
        chunks = [dask.delayed(bake_chunk, pure=False)(
                      job, rd, md, times[s:s + chunk].tolist(), str(q),
                      dask_key_name=f"bake-{tag}-{c}")
                  for c, (s, q) in enumerate(zip(range(0, len(times), chunk), parts, strict=True))]
        todo.append(dask.delayed(assemble, pure=False)(job, rd, md, str(final), chunks,
                                                        dask_key_name=f"assemble-{tag}"))
    report.skipped.extend(skipped)
    return todo, skipped


def local_cluster(workers: int):
    """A local Dask cluster of ``workers`` processes, one thread each, quiet logs."""
    import logging

    from distributed import LocalCluster

    return LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                        dashboard_address=None, silence_logs=logging.CRITICAL)


def run_manifest(path: str | os.PathLike, *, workers: int | None = None,
                 scheduler: str | None = None, chunk: int = 64, client=None,
                 outputs_anywhere: bool = False) -> BatchReport:
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
    outputs_anywhere : bool
        Allow outputs outside the manifest's folder (after resolving symbolic links);
        by default such a job is a ``ValueError``.

    Returns
    -------
    BatchReport
        Outputs written, rebaked (found damaged) and skipped (done), leftover files
        removed, frames baked.
    """
    import dask

    if isinstance(chunk, bool) or not isinstance(chunk, int) or chunk < 1:
        raise ValueError(f"chunk must be an integer of 1 or more frames, got {chunk!r}")
    jobs = read_manifest(path, outputs_anywhere=outputs_anywhere)
    t0 = time.perf_counter()
    report = BatchReport()
    todo, _ = plan(jobs, chunk, report=report)
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
        report.parts_rebaked += r["parts_rebaked"]
        report.removed.extend(r["removed"])
    return report
