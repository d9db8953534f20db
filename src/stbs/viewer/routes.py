"""The viewer's API as one route table: (method, path pattern) -> handler.

The HTTP handler (:mod:`stbs.viewer.handler`) frames requests and checks the rules
every request goes through; then it asks :data:`ROUTES` for the handler of the
request's method and path. A path no route matches is 404; a path some route matches
but not with this method is 405 with an ``Allow`` header listing the methods that
path takes. Public routes (the page and its assets) need no token; every other route
does.

A handler is ``handler(request, app, *groups) -> Reply``: ``request`` the
:class:`Request` (method, path, query, headers, the body read on demand), ``app``
the :class:`stbs.viewer.ViewerServer` (its :class:`stbs.viewer.state.ViewerState` as
``app.state``, its jobs as ``app.jobs``), ``groups`` what the path pattern captured.
It checks what it reads, calls the state, and returns a :class:`Reply`; a bad request
is a :class:`stbs.viewer.refusal.Refusal`.
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .._json import JsonError, load_json
from ..pose import Pose
from . import bodies, bones, clips, jobs, saves
from .refusal import Refusal
from .static import PAGE_HEADERS, content_type, static_path

__all__ = ["Request", "Reply", "Route", "RouteTable", "ROUTES", "json_reply", "array_reply"]

BINARY = "application/octet-stream"


class Request:
    """What a handler reads of a request: method, path, query, headers, the body."""

    def __init__(self, method: str, path: str, query: str, headers, read_body):
        self.method, self.path, self.query, self.headers = method, path, query, headers
        self._read_body = read_body
        self._body: bytes | None = None

    def body(self) -> bytes:
        """The body's bytes (read once, on first use, within the framing rules)."""
        if self._body is None:
            self._body = self._read_body()
        return self._body

    def json(self) -> Any:
        """The body read by :func:`stbs._json.load_json` (400 for bad JSON)."""
        try:
            return load_json(self.body(), "request body")
        except JsonError as exc:
            raise Refusal(400, str(exc)) from None

    @property
    def has_body(self) -> bool:
        lengths = self.headers.get_all("Content-Length") or []
        return "Transfer-Encoding" in self.headers or any(c.strip() != "0" for c in lengths)

    @property
    def content_type(self) -> str:
        return (self.headers.get("Content-Type") or "").split(";")[0].strip().lower()

    @property
    def wants_binary(self) -> bool:
        """Whether the client asked for raw arrays (``Accept: application/octet-stream``)."""
        return BINARY in (self.headers.get("Accept") or "").lower()


@dataclass
class Reply:
    """An answer: body, content type, extra headers, status."""

    body: bytes
    content_type: str = "application/json"
    headers: dict = field(default_factory=dict)
    status: int = 200


def json_reply(obj: Any, status: int = 200) -> Reply:
    return Reply(json.dumps(obj, allow_nan=False, separators=(",", ":")).encode(),
                 status=status)


def array_reply(a: np.ndarray, **headers: str) -> Reply:
    """A little-endian C-order array, described by ``X-Stbs-Dtype``, ``X-Stbs-Shape`` and
    ``X-Stbs-Byte-Order``; ``headers``: more ``X-Stbs-*`` headers (``Bone="1"``)."""
    a = np.ascontiguousarray(a, dtype=a.dtype.newbyteorder("<"))
    head = {"X-Stbs-Dtype": a.dtype.name, "X-Stbs-Shape": ",".join(str(s) for s in a.shape),
            "X-Stbs-Byte-Order": "little"}
    head.update({f"X-Stbs-{k}": v for k, v in headers.items()})
    return Reply(a.tobytes(), BINARY, head)


@dataclass(frozen=True)
class Route:
    """``method`` and a path ``pattern`` (a full-match regular expression) -> ``handler``;
    ``public`` routes need no token."""

    method: str
    pattern: str
    handler: Callable[..., Reply]
    public: bool = False


class RouteTable:
    """The routes, matched in order; 404 and 405 (with ``Allow``) answered from them."""

    def __init__(self, routes: list[Route]):
        self.routes = [(r, re.compile(r.pattern)) for r in routes]
        self.methods = tuple(dict.fromkeys(r.method for r in routes))

    def is_public(self, path: str) -> bool:
        """Whether ``path`` is one of the public routes' (no token needed)."""
        return any(r.public and rx.fullmatch(path) for r, rx in self.routes)

    def find(self, method: str, path: str) -> tuple[Callable[..., Reply], tuple]:
        """The handler of ``method path`` and the groups its pattern captured."""
        allow = []
        for r, rx in self.routes:
            m = rx.fullmatch(path)
            if m is None:
                continue
            if r.method == method:
                return r.handler, m.groups()
            allow.append(r.method)
        if not allow:
            raise Refusal(404, f"{path}: not found")
        allow = list(dict.fromkeys(allow))
        raise Refusal(405, f"{path}: {' or '.join(allow)} only", {"Allow": ", ".join(allow)})


# ---------------------------------------------------------------------- the page
def _page(req: Request, app) -> Reply:
    return _static(req, app, "index.html")


def _static(req: Request, app, rel: str) -> Reply:
    p = static_path(app.static_dir, rel)
    if p is None:
        raise Refusal(404, "not found")
    try:
        body = p.read_bytes()
    except OSError:
        raise Refusal(404, "not found") from None
    kind = content_type(p)
    return Reply(body, kind, dict(PAGE_HEADERS) if kind.startswith("text/html") else {})


# ---------------------------------------------------------------------- the rig
def _rig(req: Request, app) -> Reply:
    return json_reply(app.state.info())


def _array(req: Request, app, name: str) -> Reply:
    payload = app.state.payload
    try:
        a = payload.array(name)
    except KeyError:
        raise Refusal(404, f"no array {name!r} for this rig; it has "
                           f"{', '.join(payload.names)}") from None
    return array_reply(a)


# ---------------------------------------------------------------------- the pose
def _get_pose(req: Request, app) -> Reply:
    return json_reply(app.state.pose_object())


def _set_pose(req: Request, app) -> Reply:
    pose = saves.read_request_pose(req.json(), app.state)
    app.state.set_pose(pose)
    return json_reply({"pose": app.state.pose_object()})


def _bones_reply(req: Request, pose: Pose, *, binary: bool, **headers: str) -> Reply:
    if binary:
        return array_reply(bones.pose_rows(pose), **headers)
    return json_reply(bones.pose_json(pose))


def _get_bones(req: Request, app) -> Reply:
    return _bones_reply(req, app.state.pose, binary=req.wants_binary)


def _set_world(req: Request, app) -> Reply:
    """The page's world transforms -> the forward-kinematics pose made of them
    (:meth:`stbs.Pose.local`, :meth:`stbs.Pose.from_local`), now the current pose."""
    state = app.state
    world = bones.read_world(req.json(), state.rig.skeleton)
    with np.errstate(all="ignore"):     # huge values overflow: refused below, no warning
        L, D = world.local()
        finite = np.isfinite(L).all() and np.isfinite(D).all()
        pose = Pose.from_local(world.skeleton, L, stretch=world.stretch, twist=world.twist,
                               offsets=D) if finite else None
        # the pose file form is in degrees: a twist past the float64 range in degrees too
        ok = pose is not None and np.isfinite(pose.origins).all() and \
            np.isfinite(np.rad2deg(pose.twist)).all()
    if not ok:
        raise Refusal(400, "request body: these world transforms give a pose that is not "
                           "finite (a stretch, twist or position too large); expected a pose "
                           "within the range of float64")
    state.set_pose(pose)
    return json_reply({"pose": state.pose_object(), "bones": bones.pose_json(pose)})


def _save_pose(req: Request, app) -> Reply:
    return json_reply(saves.save_pose(app.state, req.json()))


def _save_rig(req: Request, app) -> Reply:
    rig = app.state.rig
    n, b = len(rig.V), rig.skeleton.n_bones
    if req.content_type == BINARY:
        got = bodies.binary_weights(req.body(), req.headers.get("X-Stbs-Arrays"),
                                    req.headers.get("X-Stbs-Dtype"), n, b)
        flag = (req.headers.get("X-Stbs-Overwrite") or "false").strip().lower()
        if flag not in ("true", "false"):
            raise Refusal(400, f"X-Stbs-Overwrite: expected true or false, got {flag[:20]!r}")
        overwrite = flag == "true"
    else:
        got = bodies.json_weights(req.json() if req.has_body else {}, n, b, also=("overwrite",))
        overwrite = got.pop("overwrite", False)
        if not isinstance(overwrite, bool):
            raise Refusal(400, f'"overwrite": expected true or false, got {overwrite!r}')
    return json_reply(saves.save_rig(app.state, got["W"], got["E"], overwrite=overwrite))


# ---------------------------------------------------------------------- clips
def _capture(req: Request, app) -> Reply:
    return json_reply(app.state.clip_summary())


def _add_clip(req: Request, app) -> Reply:
    clip = clips.read_request_clip(req.json(), app.state.rig.skeleton)
    return json_reply(app.state.add_clip(clip))


def _clip(req: Request, app, cid: str) -> Reply:
    return json_reply(app.state.clip_summary(cid))


def _clip_keys(req: Request, app, cid: str) -> Reply:
    return json_reply({"clip": app.state.clip_file(cid)})


def _clip_frames(req: Request, app, cid: str) -> Reply:
    return array_reply(clips.frames(app.state.clip(cid), req.query))


def _seek(req: Request, app, cid: str) -> Reply:
    """``{"time": t}``: the clip's pose at t becomes the current pose; its binary bones,
    or (``Accept: application/json``) ``{"pose", "bones", "time"}`` in one answer."""
    clip = app.state.clip(cid)
    pose, t = clips.clip_pose_at(clip, req.json())
    app.state.set_pose(pose)
    if "application/json" in (req.headers.get("Accept") or "").lower():
        return json_reply({"pose": app.state.pose_object(), "bones": bones.pose_json(pose),
                           "time": t})
    return _bones_reply(req, pose, binary=True, Time=repr(t))


def _clip_pose(req: Request, app, cid: str) -> Reply:
    pose, t = clips.clip_pose_at(app.state.clip(cid), req.json())
    app.state.set_pose(pose)
    return json_reply({"pose": app.state.pose_object(), "time": t})


def _sample(req: Request, app) -> Reply:
    return json_reply(clips.sample(req.json(), app.state.rig.skeleton))


def _sent_clip_pose(req: Request, app) -> Reply:
    pose, t = clips.clip_pose(req.json(), app.state.rig.skeleton)
    app.state.set_pose(pose)
    return json_reply({"pose": app.state.pose_object(), "time": t})


def _save_clip(req: Request, app) -> Reply:
    obj, state = req.json(), app.state
    with state.writing():
        return json_reply(clips.save_clip(obj, state.clips, state.pose_folder, state.name))


def _export(req: Request, app) -> Reply:
    obj, state = req.json(), app.state
    with state.writing():
        return json_reply(clips.export_gif(obj, state.pose_folder, state.name))


# ---------------------------------------------------------------------- weights and jobs
def _column_reply(req: Request, bone: int, method: str, col: np.ndarray) -> Reply:
    if req.wants_binary:
        return array_reply(col.astype(np.float32).reshape(-1), Bone=str(bone))
    return json_reply({"bone": bone, "method": method, "E": col.tolist()})


def _endpoint_now(req: Request, app) -> Reply:
    bone, method, col = app.endpoint_column(req.json())
    return _column_reply(req, bone, method, col)


def _start_endpoint(req: Request, app) -> Reply:
    rig = app.state.rig
    bone, method, W, options = jobs.read_endpoint_request(req.json(), rig, nested=True)
    can = jobs.endpoint_methods(rig)
    if method not in can:
        raise Refusal(400, f'"method": {method!r} cannot work on this rig; it takes '
                           f"{', '.join(can)}")

    def work(job: jobs.Job):
        return bone, method, jobs.endpoint_column(rig, W, bone, method, options,
                                                  progress=job.progress)

    job = app.jobs.start("endpoint", work, {"bone": bone, "method": method})
    return json_reply({"job": job.id, **job.status()})


def _job(req: Request, app, jid: str) -> Reply:
    return json_reply(app.jobs.get(jid).status())


def _job_result(req: Request, app, jid: str) -> Reply:
    bone, method, col = app.jobs.result(jid)
    return _column_reply(req, bone, method, col)


def _cancel(req: Request, app, jid: str) -> Reply:
    return json_reply(app.jobs.cancel(jid).status())


_CID = r"([0-9a-f]{16})"
_JID = f"({jobs.JOB_ID})"

#: Every route of the viewer's server.
ROUTES = RouteTable([
    Route("GET", r"/", _page, public=True),
    Route("GET", r"/static/(.*)", _static, public=True),
    Route("GET", r"/api/rig", _rig),
    Route("GET", r"/api/rig/([A-Za-z0-9]+)\.bin", _array),
    Route("GET", r"/api/pose", _get_pose),
    Route("POST", r"/api/pose", _set_pose),
    Route("GET", r"/api/pose/bones", _get_bones),
    Route("POST", r"/api/pose/bones", _set_world),
    Route("POST", r"/api/save-pose", _save_pose),
    Route("POST", r"/api/save-rig", _save_rig),
    Route("GET", r"/api/clip", _capture),
    Route("POST", r"/api/clip", _add_clip),
    Route("POST", r"/api/clip/sample", _sample),
    Route("POST", r"/api/clip/pose", _sent_clip_pose),
    Route("GET", f"/api/clip/{_CID}", _clip),
    Route("GET", f"/api/clip/{_CID}/keys", _clip_keys),
    Route("GET", f"/api/clip/{_CID}/frames", _clip_frames),
    Route("POST", f"/api/clip/{_CID}/seek", _seek),
    Route("POST", f"/api/clip/{_CID}/pose", _clip_pose),
    Route("POST", r"/api/save-clip", _save_clip),
    Route("POST", r"/api/export", _export),
    Route("POST", r"/api/endpoint-weights", _endpoint_now),
    Route("POST", r"/api/jobs/endpoint", _start_endpoint),
    Route("GET", f"/api/jobs/{_JID}", _job),
    Route("GET", f"/api/jobs/{_JID}/result", _job_result),
    Route("POST", f"/api/jobs/{_JID}/cancel", _cancel),
])
