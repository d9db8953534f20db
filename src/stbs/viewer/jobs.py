"""Work that takes longer than a request: endpoint weight recomputes as jobs.

``POST /api/jobs/endpoint`` starts a job in a worker thread and answers its id at
once; ``GET /api/jobs/ID`` says how far it is (``state``: running, done, failed or
cancelled; ``stage``; ``done`` of ``total`` steps), ``GET /api/jobs/ID/result`` answers
its result once done and ``POST /api/jobs/ID/cancel`` stops it. The work reports
progress through a callback, which raises :class:`Cancelled` once the job is
cancelled, so a cancel takes effect at the next step (a bone of a BBW solve).

Bounds: one job runs at a time per server (a second start while one runs is 409,
naming it); the :data:`MAX_JOBS` started last are kept, finished or not (older ids
answer 404).
"""

from __future__ import annotations

import secrets
import sys
import threading
from collections import OrderedDict
from collections.abc import Callable
from typing import Any

import numpy as np

from ..rig import Rig
from .bodies import with_weights
from .refusal import Refusal, one_line, show

__all__ = ["Job", "JobRunner", "Cancelled", "MAX_JOBS", "JOB_ID", "ENDPOINT_OPTIONS",
           "endpoint_methods", "read_endpoint_request", "endpoint_column"]

#: Jobs a server keeps (the oldest go first); one of them runs at a time.
MAX_JOBS = 8
#: A job id: 16 hex digits.
JOB_ID = r"[0-9a-f]{16}"
#: The options of an endpoint recompute, as :func:`stbs.weights.endpoint_weights` takes them.
ENDPOINT_OPTIONS = ("threshold", "alpha", "normalize", "tol", "backend")


class Cancelled(Exception):
    """Raised by a job's progress callback once the job is cancelled."""


def endpoint_methods(rig: Rig) -> list[str]:
    """The endpoint methods that can work on ``rig`` (:func:`stbs.rig.endpoint_methods`:
    no BBW on a 3D surface rig without its volume, no heat in 2D)."""
    from ..rig import endpoint_methods as methods

    return list(methods(rig))


def read_endpoint_request(obj: Any, rig: Rig, *, nested: bool) -> tuple[int, str, Any, dict]:
    """An endpoint recompute's body -> (bone index, method, W or None, options).

    ``{"bone": index or name, "method": ..., "W": (n, b) rows (optional), "options":
    {...}}`` (``nested``), or the options beside the other keys (the older route).
    """
    from ..weights import ENDPOINT_METHODS

    keys = ("bone", "method", "W", "options") if nested else ("bone", "method", "W",
                                                                *ENDPOINT_OPTIONS)
    if not isinstance(obj, dict):
        raise Refusal(400, 'request body: expected a JSON object {"bone": index or name, '
                           f'"method": one of {", ".join(ENDPOINT_METHODS)}}}, found '
                           f"{type(obj).__name__}")
    extra = sorted(set(obj) - set(keys))
    if extra:
        raise Refusal(400, f"request body: unexpected key {extra[0]!r}; expected "
                           f"{', '.join(keys)}")
    options = obj.get("options", {}) if nested else {k: obj[k] for k in ENDPOINT_OPTIONS
                                                     if k in obj}
    if not isinstance(options, dict) or set(options) - set(ENDPOINT_OPTIONS):
        bad = sorted(set(options) - set(ENDPOINT_OPTIONS)) if isinstance(options, dict) else []
        got = f"key {bad[0]!r}" if bad else show(options)
        raise Refusal(400, f'"options": expected an object with any of '
                           f"{', '.join(ENDPOINT_OPTIONS)}, got {got}")
    sk = rig.skeleton
    bone = obj.get("bone")
    if isinstance(bone, bool) or not isinstance(bone, (int, str)):
        raise Refusal(400, f'"bone": expected a bone index 0..{sk.n_bones - 1} or a bone '
                           f"name, got {show(bone)}")
    try:
        i = int(sk.bone_index(bone))
    except (ValueError, KeyError, IndexError, TypeError) as exc:
        raise Refusal(400, f'"bone": {one_line(exc)}') from None
    method = obj.get("method")
    if method not in ENDPOINT_METHODS:
        raise Refusal(400, f'"method": expected one of {", ".join(ENDPOINT_METHODS)}, '
                           f"got {show(method)}")
    W = obj.get("W")
    if W is not None:
        W = with_weights(rig, W, None).W
    return i, str(method), W, {k: options[k] for k in ENDPOINT_OPTIONS if k in options}


def endpoint_column(rig: Rig, W, bone: int, method: str, options: dict,
                    progress: Callable[[str, int, int], None] | None = None) -> np.ndarray:
    """Bone ``bone``'s endpoint weights by ``method``, solved again on what the rig
    holds (:func:`stbs.rig.rig_endpoint_weights`: its rest mesh, or the volume it
    kept): (n,) float64 in [0, 1]. ``W``: the bone weights to use (the rig's when
    None); ``progress(stage, done, total)`` as that function takes it (raise from it
    to cancel)."""
    from ..rig import rig_endpoint_weights

    try:
        # errstate is per thread: an option that overflows (alpha=1e308) gives a
        # non-finite column, refused below, and no RuntimeWarning on stderr.
        with np.errstate(all="ignore"):
            E = rig_endpoint_weights(rig, method, bones=[bone], W=W, progress=progress,
                                     **options)
    except (ValueError, TypeError, ArithmeticError) as exc:
        raise Refusal(400, one_line(exc)) from None
    col = np.asarray(E[:, bone], dtype=np.float64)
    if not np.isfinite(col).all():
        given = ", ".join(f"{k}={show(v)}" for k, v in options.items()) or "no options"
        raise Refusal(400, f"method {method!r} with {given} gives endpoint weights that are "
                           f"not finite for bone {bone}; choose other options")
    return np.clip(col, 0.0, 1.0)


class Job:
    """One piece of work in a worker thread: its state, stage, progress and result."""

    def __init__(self, kind: str, describe: dict):
        self.id = secrets.token_hex(8)
        self.kind = kind
        self.describe = describe
        self.state = "running"
        self.stage = "starting"
        self.done = 0
        self.total = 0
        self.error: str | None = None
        self.result: Any = None
        self.cancel_event = threading.Event()
        self.thread: threading.Thread | None = None

    def progress(self, stage: str, done: int, total: int) -> None:
        """Record progress; raise :class:`Cancelled` once the job is cancelled."""
        if self.cancel_event.is_set():
            raise Cancelled
        self.stage, self.done, self.total = stage, int(done), int(total)

    def status(self) -> dict:
        out = {"id": self.id, "kind": self.kind, "state": self.state, "stage": self.stage,
               "done": self.done, "total": self.total, **self.describe}
        if self.error is not None:
            out["error"] = self.error
        return out


class JobRunner:
    """The jobs of one server: one running at a time, the :data:`MAX_JOBS` last kept."""

    def __init__(self) -> None:
        self._jobs: OrderedDict[str, Job] = OrderedDict()
        self._lock = threading.Lock()

    def start(self, kind: str, work: Callable[[Job], Any], describe: dict) -> Job:
        """Run ``work(job)`` in a worker thread; its return value is the job's result."""
        with self._lock:
            running = next((j for j in self._jobs.values() if j.state == "running"), None)
            if running is not None:
                raise Refusal(409, f"job {running.id} ({running.kind}) is running; one job "
                                   f"runs at a time: wait for it or POST /api/jobs/"
                                   f"{running.id}/cancel")
            job = Job(kind, describe)
            self._jobs[job.id] = job
            while len(self._jobs) > MAX_JOBS:
                self._jobs.popitem(last=False)
        job.thread = threading.Thread(target=self._run, args=(job, work), daemon=True,
                                      name=f"stbs-view-job-{job.id}")
        job.thread.start()
        return job

    @staticmethod
    def _run(job: Job, work: Callable[[Job], Any]) -> None:
        try:
            result = work(job)
        except Cancelled:
            job.state, job.stage = "cancelled", "cancelled"
            return
        except Refusal as r:
            job.error, job.state = r.message, "failed"
            return
        except Exception as exc:    # a bug: say it once on stderr, the job failed
            job.error = f"internal error: {type(exc).__name__}"
            print(f"stbs view: internal error in job {job.id} ({job.kind}): "
                  f"{type(exc).__name__}: {one_line(exc)}", file=sys.stderr)
            job.state = "failed"
            return
        if job.cancel_event.is_set():
            job.state, job.stage = "cancelled", "cancelled"
            return
        job.result, job.stage, job.done = result, "done", max(job.done, job.total)
        job.state = "done"

    def get(self, jid: str) -> Job:
        with self._lock:
            job = self._jobs.get(jid)
        if job is None:
            raise Refusal(404, f"no job {jid!r} on this server (it keeps the {MAX_JOBS} jobs "
                               "started last)")
        return job

    def cancel(self, jid: str) -> Job:
        """Ask job ``jid`` to stop (it stops at its next step); a finished job is left
        as it is."""
        job = self.get(jid)
        if job.state == "running":
            job.cancel_event.set()
            job.stage = "cancelling"
        return job

    def result(self, jid: str) -> Any:
        job = self.get(jid)
        if job.state != "done":
            why = f": {job.error}" if job.error else ""
            raise Refusal(409, f"job {jid} is {job.state}{why}; its result comes once it is "
                               "done")
        return job.result

    def close(self, timeout: float = 5.0) -> None:
        """Cancel every running job and wait a little for their threads."""
        with self._lock:
            jobs = list(self._jobs.values())
        for job in jobs:
            job.cancel_event.set()
        for job in jobs:
            if job.thread is not None:
                job.thread.join(timeout=timeout)
