"""The viewer's HTTP server: the page, its assets and the rig data API, on 127.0.0.1 only.

Standard library only (:class:`http.server.ThreadingHTTPServer`). The rules every
request goes through, in this order (docs/viewer.md has the full API):

1. **Host**: the ``Host`` header must be ``127.0.0.1:PORT`` or ``localhost:PORT``
   (one header, this server's port), else 403: a page on another origin whose name
   was rebound to 127.0.0.1 (DNS rebinding) sends its own name.
2. **Method**: GET or POST, else 405.
3. **Page and assets** (``GET /`` and ``GET /static/<path>``) need no token. The path
   is taken as sent, never decoded: each segment is letters, digits, ``_``, ``-`` and
   dots, not starting with a dot, so ``..``, percent escapes (``%2e%2e``, ``%2f``,
   ``%252e``), backslashes, NUL, empty segments and hidden files are not found
   (404); the file's real path (symlinks resolved) must lie inside the static
   folder, so a symlink out is not found either.
4. **Everything else** carries the run's token, as the query parameter ``token=`` or
   the header ``X-Stbs-Token`` (compared in constant time), else 403; a request that
   sends an ``Origin`` must come from this server's own origin, else 403. Only then
   is an unknown path 404, so nothing about the API is learnt without the token.
5. **Bodies** are read only with exactly one ``Content-Length`` (two, or one beside a
   ``Transfer-Encoding``: 400, checked before any other rule; chunked bodies: 411) of
   at most ``max_body`` bytes (else 413, without reading it); a body that stops short
   (the connection idle for ``_Handler.timeout`` seconds, or closed) is 400 and closes
   the connection. JSON bodies are read by :func:`stbs._json.load_json` (nesting,
   digits, finite numbers). Every refusal is a JSON ``{"error": one line, "status":
   N}``; client input never gets a 500 or prints on stderr.

Connections: the listen queue holds :data:`REQUEST_QUEUE` connections and at most
:data:`MAX_HANDLERS` are answered at once (a thread each); the rest wait in the queue.
The limits on the work one request may ask for are those of :mod:`stbs.viewer.clips`.

The clips the page plays are held by the server (:class:`stbs.viewer.clips.ClipStore`):
the page registers a clip once per edit (``POST /api/clip``) and asks for its poses at
any times (``GET /api/clip/ID/frames?t=...``, evaluated by :meth:`stbs.Clip.arrays`), so
a seek or playback never sends the clip again.

Writes (``/api/save-pose``, ``/api/save-clip``, ``/api/export``, ``/api/save-rig``)
go to a temporary file then rename
(:mod:`stbs.io`'s atomic writers), only into the folder and the file the server was
given (``pose_folder``, ``rig_target``); the client names at most a bare ``.json``
file name in that folder (a bare ``.gif`` name for an export). Every save runs inside
:func:`stbs._inputs.tracking` with the files the server reads noted (its
``rig_source`` and ``inputs``, plus those of a ``stbs view`` run): a save over one of
them is 409, ``"overwrite"`` or not, and leaves it untouched.
"""

from __future__ import annotations

import contextlib
import hmac
import json
import os
import re
import secrets
import socketserver
import sys
import threading
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any
from urllib.parse import parse_qs

import numpy as np

from .._inputs import SameFileError, note_input, tracking
from .._json import JsonError, load_json
from ..io import pose_to_dict, read_pose, write_pose, write_rig
from ..pose import Pose
from ..rig import Rig
from . import clips
from .payload import RigPayload

__all__ = ["ViewerServer", "STATIC_DIR", "MAX_BODY", "HOST", "TOKEN_HEADER",
           "POSE_NAME", "RIG_TARGETS", "REQUEST_QUEUE", "MAX_HANDLERS", "static_path"]

#: The only address the server listens on.
HOST = "127.0.0.1"
#: The package's own page and assets.
STATIC_DIR = Path(__file__).resolve().parent / "static"
#: Largest request body accepted, in bytes (64 MiB).
MAX_BODY = 64 * 1024 * 1024
#: Connections the listen queue holds while every handler is busy.
REQUEST_QUEUE = 256
#: Connections answered at once, one thread each; more wait in the listen queue.
MAX_HANDLERS = 128
#: The header that may carry the token instead of the ``token=`` query parameter.
TOKEN_HEADER = "X-Stbs-Token"
#: A pose file name the client may give ``/api/save-pose``: a bare ``.json`` name.
POSE_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]{0,99}\.json\Z")

_SEGMENT = re.compile(r"[A-Za-z0-9_-][A-Za-z0-9_.-]*\Z")
_ARRAY = re.compile(r"/api/rig/([A-Za-z0-9]+)\.bin\Z")
#: ``/api/clip/ID`` and its sub-resources: (id, "" | "/keys" | "/frames" | "/pose").
_CLIP = re.compile(r"/api/clip/([0-9a-f]{16})(|/keys|/frames|/pose)\Z")
#: The methods each ``/api/clip/ID`` resource takes.
_CLIP_METHODS = {"": ("GET",), "/keys": ("GET",), "/frames": ("GET",), "/pose": ("POST",)}
#: Rig files the page's rig may be saved as.
RIG_TARGETS = (".npz", ".glb", ".gltf")
#: The clip routes (all POST) and the ViewerServer method that answers each.
_CLIP_ROUTES = {"/api/clip/sample": "clip_sample", "/api/clip/pose": "set_clip_pose",
                "/api/save-clip": "save_clip", "/api/export": "export_clip"}
_TYPES = {".html": "text/html; charset=utf-8", ".js": "text/javascript; charset=utf-8",
          ".mjs": "text/javascript; charset=utf-8", ".css": "text/css; charset=utf-8",
          ".json": "application/json", ".map": "application/json",
          ".wasm": "application/wasm", ".png": "image/png", ".jpg": "image/jpeg",
          ".svg": "image/svg+xml", ".ico": "image/x-icon", ".txt": "text/plain; charset=utf-8",
          ".glsl": "text/plain; charset=utf-8"}
_PAGE_POLICY = ("default-src 'self'; img-src 'self' data: blob:; style-src 'self' "
                "'unsafe-inline'; connect-src 'self'; frame-ancestors 'none'; base-uri 'none'")


def static_path(static_dir: str | os.PathLike, rel: str) -> Path | None:
    """The file ``rel`` (a path as sent, ``/``-separated, not decoded) of the static folder.

    None unless every segment is a plain name (letters, digits, ``_``, ``-``, dots; no
    leading dot) and the real path of the file, symlinks resolved, is a regular file
    inside the real path of ``static_dir``.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> d = Path(tempfile.mkdtemp())
    >>> _ = (d / "app.js").write_text("")
    >>> static_path(d, "app.js") == (d / "app.js").resolve()
    True
    >>> [static_path(d, r) for r in ("../app.js", "%2e%2e/app.js", "a\\\\b", "", ".hidden")]
    [None, None, None, None, None]
    """
    segments = rel.split("/")
    if not all(_SEGMENT.match(s) for s in segments):
        return None
    root = Path(os.path.realpath(static_dir))
    p = Path(os.path.realpath(root.joinpath(*segments)))
    if not p.is_relative_to(root) or p == root or not p.is_file():
        return None
    return p


class _BodyLost(Exception):
    """The connection broke while its request body was read: nothing to answer."""


class _Refused(Exception):
    """An answer other than 200: the status and a one-line message (a JSON body)."""

    def __init__(self, status: int, message: str, headers: dict | None = None):
        super().__init__(message)
        self.status = int(status)
        self.message = " ".join(str(message).split())
        self.headers = headers or {}


def _le_f32(a) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.dtype(np.float32).newbyteorder("<"))


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split()) or type(exc).__name__


def _show(x: Any) -> str:
    """A JSON value in a message: short values as JSON, others by their kind."""
    if isinstance(x, (bool, int, float, str)) or x is None:
        s = json.dumps(x)
        return s if len(s) <= 40 else s[:37] + "..."
    return {dict: "an object", list: "a list"}.get(type(x), type(x).__name__)


def _what_rows(X: Any, b: int) -> str:
    """What arrived where (n, b) rows of numbers were expected: the first thing wrong."""
    if not isinstance(X, list):
        return _show(X)
    for k, row in enumerate(X):
        if not isinstance(row, list):
            return f"{_show(row)} as row {k}"
        if len(row) != b:
            return f"row {k} of length {len(row)}"
        for j, x in enumerate(row):
            if isinstance(x, bool) or not isinstance(x, (int, float)):
                return f"{_show(x)} at [{k}][{j}]"
            if isinstance(x, int) and abs(x) >= 2**63:
                return f"{_show(x)} at [{k}][{j}], too large"
    return f"{len(X)} rows"


def _rows(key: str, X: Any, n: int, b: int) -> np.ndarray:
    """``X`` (JSON rows, or an array read from a binary body) as an (n, b) float64 array,
    else 400 naming the field, the expectation and what arrived."""
    A = None
    if isinstance(X, np.ndarray):
        A = X
    elif isinstance(X, list):
        try:
            A = np.array(X)     # no dtype: strings, bools and ragged rows stay visible
        except (ValueError, TypeError, OverflowError):
            A = None
    if A is None or A.dtype.kind not in "iuf" or A.ndim != 2:
        raise _Refused(400, f'"{key}": expected {n} rows of {b} numbers (vertices x bones), '
                            f"got {_what_rows(X, b)}")
    if A.shape != (n, b):
        raise _Refused(400, f"{key} must have shape ({n}, {b}) (vertices, bones), got "
                            f"{A.shape}")
    return A.astype(np.float64)


def _same_file(a: Path, b: Path) -> bool:
    if os.path.realpath(a) == os.path.realpath(b):
        return True
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


class _HTTPServer(ThreadingHTTPServer):
    """A thread per connection, at most MAX_HANDLERS at once; the rest wait in a listen
    queue of REQUEST_QUEUE (the default of 5 resets connections under a burst)."""

    daemon_threads = True
    request_queue_size = REQUEST_QUEUE
    viewer: ViewerServer

    def __init__(self, *args, **kwargs):
        self.closing = False
        self._slots = threading.BoundedSemaphore(MAX_HANDLERS)
        super().__init__(*args, **kwargs)

    def server_bind(self) -> None:
        # HTTPServer.server_bind looks the address up in DNS (getfqdn); 127.0.0.1 needs none.
        socketserver.TCPServer.server_bind(self)
        self.server_name, self.server_port = self.server_address[:2]

    def process_request(self, request, client_address) -> None:
        # Wait for a free handler; meanwhile new connections wait in the listen queue.
        while not self._slots.acquire(timeout=0.1):
            if self.closing:
                self.shutdown_request(request)
                return
        try:
            super().process_request(request, client_address)
        except BaseException:
            self._slots.release()
            raise

    def process_request_thread(self, request, client_address) -> None:
        try:
            super().process_request_thread(request, client_address)
        finally:
            self._slots.release()

    def handle_error(self, request, client_address) -> None:
        # A connection the client dropped, reset or let time out is no error of ours;
        # anything else is a bug, said in one line (socketserver prints a traceback).
        exc = sys.exc_info()[1]
        if isinstance(exc, OSError):
            return
        print(f"stbs view: internal error: {type(exc).__name__}: {_one_line(exc)}",
              file=sys.stderr)


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
        file whose folder exists, written by :func:`stbs.io.write_rig`); None: saving
        the rig is refused (409).
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
        self.payload = RigPayload(rig, extras=extras)
        self.static_dir = Path(STATIC_DIR if static_dir is None else static_dir)
        self.rig_target = None if rig_target is None else Path(rig_target)
        if self.rig_target is not None and (self.rig_target.suffix.lower() not in RIG_TARGETS
                                            or not self.rig_target.parent.is_dir()):
            raise ValueError(f"rig_target must be a {', '.join(RIG_TARGETS)} file in an "
                             f"existing folder, got {str(self.rig_target)!r}")
        self.rig_source = None if rig_source is None else Path(rig_source)
        if isinstance(inputs, (str, os.PathLike)):
            inputs = [inputs]
        try:
            self.inputs = [Path(os.fspath(p)) for p in inputs]
        except TypeError:
            raise ValueError(f"inputs must be paths (str or os.PathLike), got "
                             f"{inputs!r}") from None
        if self.rig_source is not None:
            self.inputs.insert(0, self.rig_source)
        if self.rig_target is not None:
            same = next((p for p in self.inputs if _same_file(p, self.rig_target)), None)
            if same is not None:
                raise ValueError(f"rig_target {str(self.rig_target)!r} is a file this viewer "
                                 f"reads ({str(same)!r}); choose another path")
        self.pose_folder = None if pose_folder is None else Path(pose_folder)
        if self.pose_folder is not None and not self.pose_folder.is_dir():
            raise ValueError(f"pose_folder must be an existing folder, got "
                             f"{str(self.pose_folder)!r}")
        self.name = str(name)
        self.clips = clips.ClipStore(rig.skeleton, clip)
        self.max_body = max_body
        self.verbose = bool(verbose)
        self.token = secrets.token_hex(16)
        self.pose = Pose.rest(rig.skeleton)
        self._pose_obj: dict = pose_to_dict(self.pose)
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None
        self._serving = False
        self._httpd = _HTTPServer((HOST, port), _Handler)
        self._httpd.viewer = self
        self.port = int(self._httpd.server_address[1])

    # ------------------------------------------------------------------ lifecycle
    @property
    def rig(self) -> Rig:
        """The rig served now (replaced by ``POST /api/save-rig`` with new weights)."""
        return self.payload.rig

    @property
    def server_address(self) -> tuple[str, int]:
        """``("127.0.0.1", port)``: where the server listens."""
        host, port = self._httpd.server_address[:2]
        return str(host), int(port)

    @property
    def url(self) -> str:
        """The page's URL with the token: ``http://127.0.0.1:PORT/?token=TOKEN``."""
        return f"http://{HOST}:{self.port}/?token={self.token}"

    @contextlib.contextmanager
    def _writing(self):
        """Every save runs inside :func:`stbs._inputs.tracking` with this server's
        inputs noted, so the atomic writers refuse to write over one of them (and over
        a file the writer itself reads, such as a glTF ``rig_source``'s buffers).

        Per save rather than for the server's whole life: a run tracked for its life
        would also record every file the rest of the process reads meanwhile (a script
        loading the rig the page just saved), and refuse the next save over it.
        """
        with tracking():
            for p in self.inputs:
                note_input(p)
            yield

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
        """Stop serving (waits for the serving loop to end) and close the socket."""
        self._httpd.closing = True
        if self._serving:
            self._httpd.shutdown()
            self._serving = False
        if self._thread is not None:
            self._thread.join(timeout=10)
            self._thread = None
        self._httpd.server_close()

    close = shutdown

    def __enter__(self) -> ViewerServer:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.shutdown()

    # ------------------------------------------------------------------ the API
    def info(self) -> dict:
        info = self.payload.info()
        info.update(name=self.name, save={"rig": self.rig_target is not None,
                                          "pose": self.pose_folder is not None},
                    clip=self.clips.started is not None)
        return info

    def get_clip(self) -> dict:
        """``GET /api/clip``: the summary of the clip the server was started with."""
        with self._lock:
            cid = self.clips.started
            if cid is None:
                raise _Refused(404, "/api/clip: this viewer was started without a clip "
                                    "(stbs view RIG --motion FILE)")
            return clips.summary(cid, self.clips.get(cid))

    def add_clip(self, obj: Any) -> dict:
        """``POST /api/clip``: hold a clip (a clip file object); its summary with its id."""
        clip = clips.read_request_clip(obj, self.rig.skeleton)
        with self._lock:
            return clips.summary(self.clips.add(clip), clip)

    def clip_resource(self, cid: str, part: str, query: str = "", obj: Any = None):
        """``/api/clip/ID`` (summary), ``/keys`` (the clip file object), ``/frames``
        (rows, :func:`stbs.viewer.clips.frames`) and ``/pose`` (the clip's pose at a
        time becomes the current pose)."""
        with self._lock:
            clip = self.clips.get(cid)
            if part == "":
                return clips.summary(cid, clip)
            if part == "/keys":
                return {"clip": self.clips.file(cid)}
        if part == "/frames":
            return clips.frames(clip, query)
        pose, t = clips.clip_pose_at(clip, obj)
        pose_obj = pose_to_dict(pose)
        with self._lock:
            self.pose = pose
            self._pose_obj = pose_obj
        return {"pose": dict(pose_obj), "time": t}

    def get_pose(self) -> dict:
        with self._lock:
            return dict(self._pose_obj)

    def set_pose(self, obj: Any) -> dict:
        pose = self._read_pose(obj)
        with self._lock:
            self.pose = pose
            self._pose_obj = pose_to_dict(pose)
            return dict(self._pose_obj)

    def pose_bones(self) -> dict:
        """The current pose as its per-bone arrays (see :class:`stbs.Pose`), for the page's shader.

        ``{"rotations": (b, d, d), "origins": (b, d), "stretch": (b,), "twist": (b, 2)}``
        as nested lists, twists in radians: the pose ``POST /api/pose`` read with
        :func:`stbs.io.read_pose`.
        """
        with self._lock:
            pose = self.pose
        return {"rotations": pose.rotations.tolist(), "origins": pose.origins.tolist(),
                "stretch": pose.stretch.tolist(), "twist": pose.twist.tolist()}

    def _read_pose(self, obj: Any) -> Pose:
        if not isinstance(obj, dict):
            raise _Refused(400, f"pose: expected a JSON object (a pose in either form of "
                                f"the pose files), found {type(obj).__name__}")
        try:
            return read_pose(obj, self.rig.skeleton)
        except (ValueError, TypeError) as exc:
            raise _Refused(400, _one_line(exc)) from None

    def save_pose(self, obj: Any) -> dict:
        if not isinstance(obj, dict):
            raise _Refused(400, "request body: expected a JSON object (a pose, or "
                                '{"pose": ..., "name": "NAME.json", "overwrite": false})')
        name, overwrite = None, False
        if "pose" in obj:
            extra = sorted(set(obj) - {"pose", "name", "overwrite"})
            if extra:
                raise _Refused(400, f"request body: unexpected key {extra[0]!r}; expected "
                                    "pose, name, overwrite")
            name, overwrite = obj.get("name"), obj.get("overwrite", False)
            obj = obj["pose"]
            if not isinstance(overwrite, bool):
                raise _Refused(400, f'"overwrite": expected true or false, got {overwrite!r}')
            if name is not None and not (isinstance(name, str) and POSE_NAME.match(name)):
                raise _Refused(400, f'"name": expected a bare file name ending in .json '
                                    f'(letters, digits, _ - and dots, no folder), got '
                                    f'{json.dumps(name)[:80]}')
        pose = self._read_pose(obj)
        if self.pose_folder is None:
            raise _Refused(409, "saving poses is off: this rig has no folder of its own "
                                "(start stbs view with --save-as PATH)")
        folder = self.pose_folder
        with self._lock, self._writing():
            try:
                target = clips.target_in(folder, name, default_stem=f"{self.name}-pose",
                                         pattern=POSE_NAME, suffix=".json",
                                         overwrite=overwrite)
            except clips.Refusal as r:
                raise _Refused(r.status, r.message) from None
            name = target.name
            try:
                write_pose(target, pose)
            except SameFileError:
                raise _Refused(409, clips.same_file_message(name)) from None
            except OSError as exc:
                raise _Refused(500, f"could not write {str(target)!r}: "
                                    f"{exc.strerror or _one_line(exc)}") from None
        return {"path": str(target), "name": name}

    # ------------------------------------------------------------------ clips (clips.py)
    def clip_sample(self, obj: Any) -> dict:
        """``POST /api/clip/sample``: the clip's poses as per-frame bone arrays."""
        return clips.sample(obj, self.rig.skeleton)

    def set_clip_pose(self, obj: Any) -> dict:
        """``POST /api/clip/pose``: make the pose at a time of a clip sent whole the
        current pose (the page uses ``POST /api/clip/ID/pose``)."""
        pose, t = clips.clip_pose(obj, self.rig.skeleton)
        pose_obj = pose_to_dict(pose)
        with self._lock:
            self.pose = pose
            self._pose_obj = pose_obj
        return {"pose": dict(pose_obj), "time": t}

    def save_clip(self, obj: Any) -> dict:
        """``POST /api/save-clip``: write a clip file into the pose folder."""
        with self._lock, self._writing():
            return clips.save_clip(obj, self.clips, self.pose_folder, self.name)

    def export_clip(self, obj: Any) -> dict:
        """``POST /api/export``: write the page's frames as an animated GIF (pose folder)."""
        with self._lock, self._writing():
            return clips.export_gif(obj, self.pose_folder, self.name)

    def save_rig(self, W=None, E=None) -> dict:
        if self.rig_target is None:
            raise _Refused(409, "saving the rig is off: start stbs view with --save-as PATH")
        with self._lock:
            rig = self.rig
            if W is not None or E is not None:
                rig = self._with_weights(rig, W, E)
                try:
                    payload = RigPayload(rig, extras=self.payload.extras)
                except (ValueError, TypeError) as exc:
                    raise _Refused(400, _one_line(exc)) from None
            try:
                with self._writing():
                    write_rig(self.rig_target, rig, source=self.rig_source)
            except SameFileError:
                raise _Refused(409, clips.same_file_message(self.rig_target.name)) from None
            except ValueError as exc:   # e.g. no endpoint weights to add to a glTF file
                raise _Refused(409, f"could not write {self.rig_target.name}: "
                                    f"{_one_line(exc)}") from None
            except OSError as exc:
                raise _Refused(500, f"could not write {str(self.rig_target)!r}: "
                                    f"{exc.strerror or _one_line(exc)}") from None
            if W is not None or E is not None:
                self.payload = payload
        return {"path": str(self.rig_target), "vertices": int(len(rig.V)),
                "bones": int(rig.skeleton.n_bones), "has_E": rig.E is not None}

    def endpoint_column(self, obj: Any) -> tuple[int, str, np.ndarray]:
        """One bone's endpoint weights by a method of :func:`stbs.weights.endpoint_weights`.

        ``obj``: ``{"bone": index or name, "method": ..., "W": (n, b) rows (optional:
        the page's current bone weights; default the rig's), "threshold", "alpha",
        "normalize", "tol", "backend" (each optional, as endpoint_weights takes them)}``.
        Computed with the rig's rest mesh (``F``, ``T``). Returns ``(bone, method,
        column (n,) float64 in [0, 1])``.
        """
        from ..weights import ENDPOINT_METHODS, endpoint_weights

        options = ("threshold", "alpha", "normalize", "tol", "backend")
        if not isinstance(obj, dict):
            raise _Refused(400, 'request body: expected a JSON object {"bone": index or name, '
                                f'"method": one of {", ".join(ENDPOINT_METHODS)}}}, found '
                                f"{type(obj).__name__}")
        extra = sorted(set(obj) - {"bone", "method", "W", *options})
        if extra:
            raise _Refused(400, f"request body: unexpected key {extra[0]!r}; expected bone, "
                                f"method, W, {', '.join(options)}")
        rig = self.rig
        sk = rig.skeleton
        bone = obj.get("bone")
        if isinstance(bone, bool) or not isinstance(bone, (int, str)):
            raise _Refused(400, f'"bone": expected a bone index 0..{sk.n_bones - 1} or a bone '
                                f"name, got {json.dumps(bone)[:80]}")
        try:
            i = int(sk.bone_index(bone))
        except (ValueError, KeyError, IndexError, TypeError) as exc:
            raise _Refused(400, f'"bone": {_one_line(exc)}') from None
        method = obj.get("method")
        if method not in ENDPOINT_METHODS:
            raise _Refused(400, f'"method": expected one of {", ".join(ENDPOINT_METHODS)}, '
                                f"got {json.dumps(method)[:80]}")
        W = obj.get("W")
        if W is None:
            W = self.payload.W
        else:
            W = self._with_weights(rig, W, None).W
        kw = {k: obj[k] for k in options if k in obj}
        try:
            # errstate is per thread: an option that overflows (alpha=1e308) gives a
            # non-finite column, refused below, and no RuntimeWarning on stderr.
            with np.errstate(all="ignore"):
                E = endpoint_weights(rig.V, sk, method=method, W=W, F=rig.F, T=rig.T, **kw)
        except (ValueError, TypeError, ArithmeticError) as exc:
            raise _Refused(400, _one_line(exc)) from None
        col = E[:, [i]].toarray()[:, 0] if hasattr(E, "toarray") else np.asarray(E)[:, i]
        col = np.asarray(col, dtype=np.float64)
        if not np.isfinite(col).all():
            given = ", ".join(f"{k}={_show(v)}" for k, v in kw.items()) or "no options"
            raise _Refused(400, f"method {method!r} with {given} gives endpoint weights that "
                                f"are not finite for bone {i}; choose other options")
        return i, str(method), np.clip(col, 0.0, 1.0)

    @staticmethod
    def _with_weights(rig: Rig, W, E) -> Rig:
        from .._checks import PARTITION_TOL

        n, b = len(rig.V), rig.skeleton.n_bones
        changes = {}
        for key, X in (("W", W), ("E", E)):
            if X is None:
                continue
            X = _rows(key, X, n, b)
            if not np.isfinite(X).all():
                raise _Refused(400, f"{key} must be finite")
            lo, hi = float(X.min(initial=0)), float(X.max(initial=0))
            if lo < 0 or (key == "E" and hi > 1):
                raise _Refused(400, f"{key} must lie in {'[0, 1]' if key == 'E' else '[0, inf)'}"
                                    f", got {lo if lo < 0 else hi:.6g}")
            if key == "W":
                off = np.abs(X.sum(axis=1) - 1.0)
                if off.max(initial=0) > PARTITION_TOL:
                    i = int(np.argmax(off))
                    raise _Refused(400, f"W rows must sum to 1, row {i} sums to "
                                        f"{X[i].sum():.6g}")
            changes[key] = X
        try:
            return rig.replace(**changes)
        except (ValueError, TypeError) as exc:
            raise _Refused(400, _one_line(exc)) from None


class _Handler(BaseHTTPRequestHandler):
    server: _HTTPServer
    server_version = "stbs-view"
    sys_version = ""
    protocol_version = "HTTP/1.1"
    timeout = 30    # seconds a connection may sit idle or dribble its request

    # ---------------------------------------------------------------- plumbing
    def version_string(self) -> str:
        return self.server_version

    def __getattr__(self, name: str):
        # Every method other than GET and POST (PUT, HEAD, OPTIONS, FOO, ...) gets a 405.
        if name.startswith("do_"):
            return lambda: self._dispatch(name[3:])
        raise AttributeError(name)

    def do_GET(self) -> None:
        self._dispatch("GET")

    def do_POST(self) -> None:
        self._dispatch("POST")

    def log_request(self, code: Any = "-", size: Any = "-") -> None:
        if self.server.viewer.verbose:   # never the query: it may hold the token
            path = getattr(self, "path", "").split("?", 1)[0]
            print(f"stbs view: {self.command} {path} {int(code)}", file=sys.stderr)

    def log_message(self, format: str, *args: Any) -> None:
        pass

    def send_error(self, code: int, message: str | None = None, explain: str | None = None
                   ) -> None:
        # The refusals http.server makes itself (a malformed request line, a header line
        # over 64 KiB or over 100 headers, an unsupported HTTP version) are JSON too, and
        # end the connection: what follows cannot be trusted to start a request.
        self.close_connection = True
        self._body_read = True
        why = message or HTTPStatus(code).phrase
        try:
            self._json({"error": f"request: {_one_line(Exception(why))}", "status": int(code)},
                       int(code))
        except OSError:
            pass

    def _send(self, status: int, body: bytes, content_type: str, *,
              headers: dict | None = None) -> None:
        self.send_response(status)
        self.send_header("Content-Type", content_type)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.send_header("X-Content-Type-Options", "nosniff")
        self.send_header("Referrer-Policy", "no-referrer")
        self.send_header("Cross-Origin-Resource-Policy", "same-origin")
        for k, v in (headers or {}).items():
            self.send_header(k, v)
        if not self._body_read and self._has_body():
            self.close_connection = True        # the unread body would be the next request
        if self.close_connection:
            self.send_header("Connection", "close")
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(body)

    def _json(self, obj: Any, status: int = 200, headers: dict | None = None) -> None:
        body = json.dumps(obj, allow_nan=False, separators=(",", ":")).encode()
        self._send(status, body, "application/json", headers=headers)

    def _dispatch(self, method: str) -> None:
        self._body_read = False
        try:
            self._route(method)
        except _Refused as r:
            self._refuse(r)
        except (BrokenPipeError, ConnectionResetError):
            self.close_connection = True
        except _BodyLost:
            self.close_connection = True        # no one to answer: the client has gone
        except Exception as exc:    # a bug: answer 500, say it once on stderr
            print(f"stbs view: internal error on {method} "
                  f"{getattr(self, 'path', '').split('?', 1)[0]}: {type(exc).__name__}: "
                  f"{_one_line(exc)}", file=sys.stderr)
            self._refuse(_Refused(500, f"internal error: {type(exc).__name__}"))

    def _refuse(self, r: _Refused) -> None:
        try:
            self._json({"error": r.message, "status": r.status}, r.status, r.headers)
        except (BrokenPipeError, ConnectionResetError):
            self.close_connection = True

    def _has_body(self) -> bool:
        cls = self.headers.get_all("Content-Length") or []
        return "Transfer-Encoding" in self.headers or any(c.strip() != "0" for c in cls)

    # ---------------------------------------------------------------- the rules
    def _check_framing(self) -> None:
        """Where the body ends must be unambiguous: one Content-Length, a number of at
        most 20 digits, and never beside a Transfer-Encoding (else 400, and the
        connection is closed: its next request could not be found)."""
        cls = self.headers.get_all("Content-Length") or []
        te = self.headers.get_all("Transfer-Encoding") or []
        why = None
        if len(cls) > 1:
            why = (f"Content-Length: expected one header, got {len(cls)} "
                   f"({', '.join(repr(c.strip()[:24]) for c in cls[:4])})")
        elif cls and te:
            why = ("request body: expected a Content-Length or a Transfer-Encoding, got both "
                   "(send one Content-Length)")
        elif cls:
            cl = cls[0].strip()
            if not (cl.isascii() and cl.isdigit() and len(cl) <= 20):
                why = (f"Content-Length: expected a number of bytes (at most 20 digits), got "
                       f"{cl[:24]!r}{'...' if len(cl) > 24 else ''}")
        if why is not None:
            self.close_connection = True
            raise _Refused(400, why)

    def _check_host(self) -> None:
        port = self.server.viewer.port
        hosts = self.headers.get_all("Host") or []
        allowed = (f"127.0.0.1:{port}", f"localhost:{port}")
        if len(hosts) != 1 or hosts[0].strip().lower() not in allowed:
            got = "none" if not hosts else ", ".join(repr(h) for h in hosts)
            raise _Refused(403, f"Host header: expected 127.0.0.1:{port} or localhost:{port}, "
                                f"got {got}")

    def _check_token(self, query: str) -> None:
        viewer = self.server.viewer
        given = self.headers.get_all(TOKEN_HEADER) or []
        if not given:
            try:
                given = parse_qs(query, keep_blank_values=True,
                                 max_num_fields=20).get("token", [])
            except ValueError:
                given = []
        if len(given) != 1 or not hmac.compare_digest(given[0].encode("utf-8", "replace"),
                                                      viewer.token.encode()):
            raise _Refused(403, f"this request needs the token of this stbs view run (query "
                                f"token= or header {TOKEN_HEADER}, from the URL it printed)")
        origin = self.headers.get_all("Origin") or []
        port = viewer.port
        if origin and (len(origin) != 1 or origin[0].strip().lower() not in
                       (f"http://127.0.0.1:{port}", f"http://localhost:{port}")):
            raise _Refused(403, f"Origin {origin[0]!r}: requests come from the viewer's own "
                                "page only")

    def _body(self) -> bytes:
        self._body_read = True
        if "Transfer-Encoding" in self.headers:
            self.close_connection = True
            raise _Refused(411, "request body: send it with a Content-Length (no chunked "
                                "transfer encoding)")
        cl = self.headers.get("Content-Length")       # one, digits: _check_framing
        if cl is None:
            return b""
        n = int(cl.strip())
        limit = self.server.viewer.max_body
        if n > limit:
            self.close_connection = True
            raise _Refused(413, f"request body of {n} bytes: the limit is {limit} bytes "
                                "(max_body)")
        chunks, got = [], 0
        try:
            while got < n:      # read1: what has arrived, so a short body counts as such
                chunk = self.rfile.read1(min(n - got, 1 << 20))
                if not chunk:
                    break
                chunks.append(chunk)
                got += len(chunk)
        except TimeoutError:
            self.close_connection = True
            raise _Refused(400, f"request body: expected {n} bytes, got {got} before the "
                                f"connection was idle for {self.timeout:g} s") from None
        except OSError:
            raise _BodyLost from None
        if got != n:
            self.close_connection = True
            raise _Refused(400, f"request body: expected {n} bytes, got {got} before the "
                                "connection was closed")
        return b"".join(chunks)

    def _json_body(self) -> Any:
        try:
            return load_json(self._body(), "request body")
        except JsonError as exc:
            raise _Refused(400, str(exc)) from None

    # ---------------------------------------------------------------- routes
    def _route(self, method: str) -> None:
        self._check_framing()
        self._check_host()
        if method not in ("GET", "POST"):
            raise _Refused(405, f"method {method} not allowed: GET or POST",
                           {"Allow": "GET, POST"})
        target = self.path
        if not target.startswith("/"):
            raise _Refused(400, "request target: expected a path starting with /")
        path, _, query = target.partition("?")
        if path == "/" or path.startswith("/static/"):
            if method != "GET":
                raise _Refused(405, f"{path}: GET only", {"Allow": "GET"})
            return self._static("index.html" if path == "/" else path[len("/static/"):])
        self._check_token(query)
        viewer = self.server.viewer
        routes = {"/api/rig": ("GET",), "/api/pose": ("GET", "POST"),
                  "/api/pose/bones": ("GET",),
                  "/api/save-pose": ("POST",), "/api/save-rig": ("POST",),
                  "/api/endpoint-weights": ("POST",), "/api/clip": ("GET", "POST")}
        routes.update(dict.fromkeys(_CLIP_ROUTES, ("POST",)))
        m = _ARRAY.match(path)
        c = None if m or path in routes else _CLIP.match(path)
        allowed = ("GET",) if m else _CLIP_METHODS[c.group(2)] if c else routes.get(path)
        if allowed is None:
            raise _Refused(404, f"{path}: not found")
        if method not in allowed:
            raise _Refused(405, f"{path}: {' or '.join(allowed)} only",
                           {"Allow": ", ".join(allowed)})
        if m:
            return self._array(m.group(1))
        if c:
            return self._clip_resource(c.group(1), c.group(2), query)
        if path == "/api/rig":
            return self._json(viewer.info())
        if path == "/api/pose":
            if method == "GET":
                return self._json(viewer.get_pose())
            return self._json({"pose": viewer.set_pose(self._json_body())})
        if path == "/api/pose/bones":
            return self._json(viewer.pose_bones())
        if path == "/api/clip":
            if method == "GET":
                return self._json(viewer.get_clip())
            return self._clip_call(viewer.add_clip, self._json_body())
        if path == "/api/save-pose":
            return self._json(viewer.save_pose(self._json_body()))
        if path == "/api/endpoint-weights":
            return self._endpoint_weights()
        if path in _CLIP_ROUTES:
            return self._clip_route(path)
        return self._json(viewer.save_rig(*self._weights_body()))

    def _clip_route(self, path: str) -> None:
        viewer = self.server.viewer
        return self._clip_call(getattr(viewer, _CLIP_ROUTES[path]), self._json_body())

    def _clip_call(self, call, *args) -> None:
        try:
            return self._json(call(*args))
        except clips.Refusal as r:
            raise _Refused(r.status, r.message) from None

    def _clip_resource(self, cid: str, part: str, query: str) -> None:
        viewer = self.server.viewer
        body = self._json_body() if part == "/pose" else None
        try:
            out = viewer.clip_resource(cid, part, query, body)
        except clips.Refusal as r:
            raise _Refused(r.status, r.message) from None
        if part != "/frames":
            return self._json(out)
        a = np.ascontiguousarray(out, dtype=np.dtype(np.float64).newbyteorder("<"))
        self._send(200, a.tobytes(), "application/octet-stream",
                   headers={"X-Stbs-Dtype": "float64",
                            "X-Stbs-Shape": ",".join(str(s) for s in a.shape),
                            "X-Stbs-Byte-Order": "little"})

    def _static(self, rel: str) -> None:
        p = static_path(self.server.viewer.static_dir, rel)
        if p is None:
            raise _Refused(404, "not found")
        try:
            body = p.read_bytes()
        except OSError:
            raise _Refused(404, "not found") from None
        kind = _TYPES.get(p.suffix.lower(), "application/octet-stream")
        headers = {}
        if kind.startswith("text/html"):
            headers = {"Content-Security-Policy": _PAGE_POLICY, "X-Frame-Options": "DENY"}
        self._send(200, body, kind, headers=headers)

    def _array(self, name: str) -> None:
        try:
            a = self.server.viewer.payload.array(name)
        except KeyError:
            raise _Refused(404, f"no array {name!r} for this rig; it has "
                                f"{', '.join(self.server.viewer.payload.names)}") from None
        shape = ",".join(str(s) for s in a.shape)
        self._send(200, a.tobytes(), "application/octet-stream",
                   headers={"X-Stbs-Dtype": a.dtype.name, "X-Stbs-Shape": shape,
                            "X-Stbs-Byte-Order": "little"})

    def _endpoint_weights(self) -> None:
        """One bone's recomputed endpoint weights: raw float32 (``Accept:
        application/octet-stream``) or JSON ``{"bone", "method", "E": [...]}``."""
        bone, method, col = self.server.viewer.endpoint_column(self._json_body())
        accept = (self.headers.get("Accept") or "").lower()
        if "application/octet-stream" in accept:
            a = _le_f32(col)
            return self._send(200, a.tobytes(), "application/octet-stream",
                              headers={"X-Stbs-Dtype": "float32", "X-Stbs-Shape": str(a.size),
                                       "X-Stbs-Byte-Order": "little", "X-Stbs-Bone": str(bone)})
        return self._json({"bone": bone, "method": method, "E": col.tolist()})

    def _weights_body(self) -> tuple:
        """New ``(W, E)`` for save-rig: none (empty body), JSON, or raw little-endian."""
        kind = (self.headers.get("Content-Type") or "").split(";")[0].strip().lower()
        if kind == "application/octet-stream":
            return self._binary_weights(self._body())
        obj = self._json_body() if self._has_body() else {}
        if not isinstance(obj, dict) or set(obj) - {"W", "E"}:
            raise _Refused(400, 'request body: expected a JSON object {"W": [[...]], "E": '
                                "[[...]]} (both optional), or raw weights with "
                                "Content-Type application/octet-stream")
        rig = self.server.viewer.rig
        n, b = len(rig.V), rig.skeleton.n_bones
        return tuple(None if obj.get(key) is None else _rows(key, obj[key], n, b)
                     for key in ("W", "E"))

    def _binary_weights(self, data: bytes) -> tuple:
        names = [s.strip() for s in (self.headers.get("X-Stbs-Arrays") or "W").split(",")]
        if not names or len(set(names)) != len(names) or set(names) - {"W", "E"}:
            raise _Refused(400, f"X-Stbs-Arrays: expected W, E or W,E, got {names!r}")
        dtype = (self.headers.get("X-Stbs-Dtype") or "float32").strip().lower()
        if dtype not in ("float32", "float64"):
            raise _Refused(400, f"X-Stbs-Dtype: expected float32 or float64, got {dtype!r}")
        rig = self.server.viewer.rig
        n, b = len(rig.V), rig.skeleton.n_bones
        dt = np.dtype(dtype).newbyteorder("<")
        want = len(names) * n * b * dt.itemsize
        if len(data) != want:
            raise _Refused(400, f"request body: expected {want} bytes ({', '.join(names)}: "
                                f"{n} x {b} {dtype} each), got {len(data)}")
        flat = np.frombuffer(data, dtype=dt).astype(np.float64).reshape(len(names), n, b)
        got = dict(zip(names, flat, strict=True))
        return got.get("W"), got.get("E")

