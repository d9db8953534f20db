"""The ``stbs view`` server: one rig's page, assets and API on 127.0.0.1 only.

:class:`ViewerServer` ties the parts together and runs them: the state it serves
(:mod:`stbs.viewer.state`: the rig and its payload, the current pose, the clips), the
route table (:mod:`stbs.viewer.routes`), the HTTP layer and its rules
(:mod:`stbs.viewer.handler`: Host, token, framing, body limits) and the jobs
(:mod:`stbs.viewer.jobs`). docs/viewer-api.md is the API's reference.

Writes (``/api/save-pose``, ``/api/save-clip``, ``/api/export``, ``/api/save-rig``)
go to a temporary file then rename (:mod:`stbs.io`'s atomic writers), only into the
folder and the file the server was given (``pose_folder``, ``rig_target``), never over
an existing file unless the request says ``"overwrite": true``, and never over a file
the server reads (409, ``"overwrite"`` or not).
"""

from __future__ import annotations

import os
import secrets
import threading
from typing import Any

import numpy as np

from ..pose import Pose
from ..rig import Rig
from . import saves
from .handler import MAX_HANDLERS, REQUEST_QUEUE, TOKEN_HEADER, Handler, HTTPServer
from .jobs import JobRunner, endpoint_column, read_endpoint_request
from .payload import RigPayload
from .saves import POSE_NAME
from .state import RIG_TARGETS, ViewerState
from .static import STATIC_DIR, page_missing, static_path

__all__ = ["ViewerServer", "STATIC_DIR", "MAX_BODY", "HOST", "TOKEN_HEADER",
           "POSE_NAME", "RIG_TARGETS", "REQUEST_QUEUE", "MAX_HANDLERS", "static_path",
           "page_missing"]

#: The only address the server listens on.
HOST = "127.0.0.1"
#: Largest request body accepted, in bytes (64 MiB).
MAX_BODY = 64 * 1024 * 1024


class ViewerServer:
    """The ``stbs view`` server for one rig: the page, its assets and the rig API.

    Listens on 127.0.0.1 only, on ``port`` (0: a free port), with a fresh token
    (:func:`secrets.token_hex`, 32 hex characters) made for each server. Nothing is
    served until :meth:`serve_forever` (blocking) or :meth:`start` (a thread).

    Parameters
    ----------
    rig : Rig
        The rig (checked as :class:`stbs.viewer.payload.RigPayload` checks it).
    port : int, keyword-only
        0 (default: a free port chosen by the system) or 1..65535.
    static_dir : path, keyword-only
        The page (``index.html``) and its assets; default the package's
        :data:`STATIC_DIR`.
    rig_target : path, keyword-only
        Where ``POST /api/save-rig`` writes the rig (a ``.npz``, ``.glb`` or ``.gltf``
        file whose folder exists, written by :func:`stbs.io.write_rig`; an existing
        file is replaced only when the request says ``"overwrite": true``); None:
        saving the rig is refused (409).
    rig_source : path, keyword-only
        The glTF file the rig was read from: a glTF ``rig_target`` is then a copy of
        that file with the rig's endpoint weights added, and its bone weights where
        they were painted (``write_rig(..., source=)``), keeping its nodes, animations
        and materials; without it glTF is written afresh.
    pose_folder : path, keyword-only
        The folder ``POST /api/save-pose`` writes pose files into; None: refused (409).
    name : str, keyword-only
        The rig's name, shown by the page and used for default pose file names
        (``<name>-pose-001.json``, ...); default ``"rig"``.
    extras : mapping, keyword-only
        Further arrays to serve (see :class:`RigPayload`).
    max_body : int, keyword-only
        Largest request body, in bytes (default :data:`MAX_BODY`).
    verbose : bool, keyword-only
        Log each request (method, path without its query, status) on stderr.
    clip : Clip, keyword-only, optional
        An animation of the rig's skeleton to open the page's timeline with (``GET
        /api/clip``), e.g. a capture retargeted onto the rig or a character file's own
        animation; held as it is, so the page plays exactly :meth:`stbs.Clip.pose`.
    inputs : iterable of paths, keyword-only
        The files the rig, the clip and any pose were read from (the rig file, the
        motion, a mapping). For the server's life these and ``rig_source`` are its
        inputs: each save runs inside :func:`stbs._inputs.tracking` with them noted,
        so a save that would write over one of them answers 409, even with
        ``"overwrite": true``, and leaves it untouched.

    Raises
    ------
    ValueError
        A bad port or target (``rig_target`` one of the inputs included), or weights
        the viewer cannot use.
    OSError
        The port is taken.

    Examples
    --------
    >>> import http.client, json
    >>> import numpy as np
    >>> import stbs
    >>> from stbs.viewer import ViewerServer
    >>> rig = stbs.Rig(V=[[0, 0.1], [1, 0.1], [1, -0.1]], F=[[0, 2, 1]],
    ...                C=[[0, 0], [1, 0]], BE=[[0, 1]], W=np.ones((3, 1)))
    >>> with ViewerServer(rig) as srv:
    ...     c = http.client.HTTPConnection(*srv.server_address, timeout=10)
    ...     c.request("GET", "/api/rig", headers={"X-Stbs-Token": srv.token})
    ...     info = json.loads(c.getresponse().read())
    ...     c.close()
    >>> info["vertices"], info["bones"], info["dim"]
    (3, 1, 2)
    """

    def __init__(self, rig: Rig, *, port: int = 0, static_dir: str | os.PathLike | None = None,
                 rig_target: str | os.PathLike | None = None,
                 pose_folder: str | os.PathLike | None = None, name: str = "rig",
                 extras: dict | None = None, max_body: int = MAX_BODY, verbose: bool = False,
                 clip=None, rig_source: str | os.PathLike | None = None,
                 inputs=()):
        if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
            raise ValueError(f"port must be an integer in 0..65535 (0: any free port), "
                             f"got {port!r}")
        if isinstance(max_body, bool) or not isinstance(max_body, int) or max_body < 0:
            raise ValueError(f"max_body must be a non-negative integer, got {max_body!r}")
        self.state = ViewerState(rig, extras=extras, name=name, rig_target=rig_target,
                                 rig_source=rig_source, pose_folder=pose_folder,
                                 inputs=inputs, clip=clip)
        self.jobs = JobRunner()
        self.static_dir = STATIC_DIR if static_dir is None else static_dir
        self.max_body = max_body
        self.verbose = bool(verbose)
        self.token = secrets.token_hex(16)
        self._thread: threading.Thread | None = None
        self._serving = False
        self._httpd = HTTPServer((HOST, port), Handler)
        self._httpd.app = self
        self.port = int(self._httpd.server_address[1])

    # ------------------------------------------------------------------ what it serves
    @property
    def rig(self) -> Rig:
        """The rig served now (replaced by ``POST /api/save-rig`` with new weights)."""
        return self.state.rig

    @property
    def payload(self) -> RigPayload:
        """The rig's summary and arrays as the page downloads them."""
        return self.state.payload

    @property
    def pose(self) -> Pose:
        """The current pose."""
        return self.state.pose

    def set_pose(self, pose: Pose | dict) -> dict:
        """Make ``pose`` (a :class:`stbs.Pose` of the rig's skeleton, or a pose file's
        object, as ``POST /api/pose`` takes) the current pose; its pose object back."""
        if not isinstance(pose, Pose):
            pose = saves.read_request_pose(pose, self.state)
        elif pose.skeleton != self.rig.skeleton:
            raise ValueError("pose must be of the rig's skeleton")
        self.state.set_pose(pose)
        return self.state.pose_object()

    @property
    def clips(self):
        """The clips held (:class:`stbs.viewer.clips.ClipStore`)."""
        return self.state.clips

    @property
    def name(self) -> str:
        return self.state.name

    @property
    def rig_target(self):
        return self.state.rig_target

    @property
    def pose_folder(self):
        return self.state.pose_folder

    def endpoint_column(self, obj: Any) -> tuple[int, str, np.ndarray]:
        """``POST /api/endpoint-weights``: one bone's endpoint weights, computed now.

        ``obj``: ``{"bone": index or name, "method": ..., "W": (n, b) rows (optional),
        "threshold", "alpha", "normalize", "tol", "backend" (each optional)}``. Returns
        ``(bone, method, column (n,) float64 in [0, 1])``; the page's jobs
        (``POST /api/jobs/endpoint``) compute the same column in a worker thread.
        """
        rig = self.rig
        bone, method, W, options = read_endpoint_request(obj, rig, nested=False)
        return bone, method, endpoint_column(rig, W, bone, method, options)

    # ------------------------------------------------------------------ lifecycle
    @property
    def server_address(self) -> tuple[str, int]:
        """``("127.0.0.1", port)``: where the server listens."""
        host, port = self._httpd.server_address[:2]
        return str(host), int(port)

    @property
    def url(self) -> str:
        """The page's URL with the token: ``http://127.0.0.1:PORT/?token=TOKEN``."""
        return f"http://{HOST}:{self.port}/?token={self.token}"

    def serve_forever(self) -> None:
        """Serve until :meth:`shutdown` (from another thread) or KeyboardInterrupt."""
        self._serving = True
        try:
            self._httpd.serve_forever(poll_interval=0.2)
        finally:
            self._serving = False

    def start(self) -> ViewerServer:
        """Serve in a daemon thread; returns ``self``."""
        if self._thread is None:
            self._serving = True
            self._thread = threading.Thread(target=self._httpd.serve_forever,
                                            kwargs={"poll_interval": 0.05},
                                            name=f"stbs-view-{self.port}", daemon=True)
            self._thread.start()
        return self

    def shutdown(self) -> None:
        """Stop serving (waits for the serving loop to end), cancel running jobs and
        close the socket."""
        self._httpd.closing = True
        if self._serving:
            self._httpd.shutdown()
            self._serving = False
        if self._thread is not None:
            self._thread.join(timeout=10)
            self._thread = None
        self.jobs.close()
        self._httpd.server_close()

    close = shutdown

    def __enter__(self) -> ViewerServer:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.shutdown()
