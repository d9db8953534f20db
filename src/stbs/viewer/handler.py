"""The viewer's HTTP layer: connections, framing and the rules every request meets.

Standard library only (:class:`http.server.ThreadingHTTPServer`). The handler checks,
in this order (docs/viewer-api.md has the whole API):

1. **Framing**: exactly one ``Content-Length`` of at most 20 digits, never beside a
   ``Transfer-Encoding`` (else 400, and the connection is closed).
2. **Host**: the ``Host`` header must be ``127.0.0.1:PORT`` or ``localhost:PORT``
   (one header, this server's port), else 403: a page on another origin whose name
   was rebound to 127.0.0.1 (DNS rebinding) sends its own name.
3. **Method**: one the route table knows (GET, POST), else 405.
4. **Token**: every path but the public ones (the page and its assets) carries the
   run's token, as the query parameter ``token=`` or the header ``X-Stbs-Token``
   (compared in constant time), else 403; a request that sends an ``Origin`` must
   come from this server's own origin, else 403. Only then is an unknown path 404,
   so nothing about the API is learnt without the token.
5. **Route**: :data:`stbs.viewer.routes.ROUTES` finds the handler (404, 405 with
   ``Allow``), which reads the body on demand: at most ``max_body`` bytes (else 413,
   unread; chunked: 411); a body that stops short (the connection idle for
   :attr:`Handler.timeout` seconds, or closed) is 400 and closes the connection.

Every refusal is a :class:`stbs.viewer.refusal.Refusal`, answered as JSON
``{"error": one line, "status": N}``; client input never gets a 500 or prints on
stderr. Connections: the listen queue holds :data:`REQUEST_QUEUE` connections and at
most :data:`MAX_HANDLERS` are answered at once (a thread each).
"""

from __future__ import annotations

import hmac
import json
import socket
import socketserver
import sys
import threading
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any
from urllib.parse import parse_qs

from .refusal import Refusal, one_line
from .routes import ROUTES, Reply, Request

__all__ = ["HTTPServer", "Handler", "REQUEST_QUEUE", "MAX_HANDLERS", "TOKEN_HEADER"]

#: Connections the listen queue holds while every handler is busy.
REQUEST_QUEUE = 256
#: Connections answered at once, one thread each; more wait in the listen queue.
MAX_HANDLERS = 128
#: The header that may carry the token instead of the ``token=`` query parameter.
TOKEN_HEADER = "X-Stbs-Token"


class _BodyLost(Exception):
    """The connection broke while its request body was read: nothing to answer."""


class _Slot:
    """One handler slot of the semaphore, released exactly once by its claimer."""

    def __init__(self, slots: threading.BoundedSemaphore):
        self._slots = slots
        self._lock = threading.Lock()
        self._claimed = False
        self._released = False

    def claim(self) -> None:
        with self._lock:
            self._claimed = True

    def release(self) -> None:
        with self._lock:
            if self._released:
                return
            self._released = True
        self._slots.release()

    def release_if_unclaimed(self) -> None:
        with self._lock:
            if self._claimed:
                return
            self._claimed = True    # a thread starting late finds it taken: it releases
        self.release()             # only what it claimed, which is nothing now


class HTTPServer(ThreadingHTTPServer):
    """A thread per connection, at most MAX_HANDLERS at once; the rest wait in a listen
    queue of REQUEST_QUEUE (the default of 5 resets connections under a burst).
    ``app`` is the :class:`stbs.viewer.ViewerServer` the routes answer for."""

    daemon_threads = True
    request_queue_size = REQUEST_QUEUE
    app: Any

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
        # The slot is released once, by whoever claims it: the handler's thread when it
        # runs, else this thread when starting it failed (a Ctrl-C may arrive while the
        # thread starts: it must neither release the slot twice nor be lost).
        slot = _Slot(self._slots)
        try:
            super().process_request(request, (client_address, slot))
        except BaseException:
            slot.release_if_unclaimed()
            raise

    def process_request_thread(self, request, address) -> None:
        client_address, slot = address
        slot.claim()
        try:
            super().process_request_thread(request, client_address)
        finally:
            slot.release()

    def handle_error(self, request, client_address) -> None:
        # A connection the client dropped, reset or let time out is no error of ours;
        # anything else is a bug, said in one line (socketserver prints a traceback).
        exc = sys.exc_info()[1]
        if isinstance(exc, OSError):
            return
        print(f"stbs view: internal error: {type(exc).__name__}: {one_line(exc)}",
              file=sys.stderr)


class Handler(BaseHTTPRequestHandler):
    """Frames one connection's requests and answers each from the route table."""

    server: HTTPServer
    server_version = "stbs-view"
    sys_version = ""
    protocol_version = "HTTP/1.1"
    timeout = 30    # seconds a connection may sit idle or dribble its request
    # Headers and body go out in two writes: without TCP_NODELAY the body waits for the
    # client's delayed ACK of the headers (about 40 ms on Linux) on every answer.
    disable_nagle_algorithm = True

    # ---------------------------------------------------------------- plumbing
    def version_string(self) -> str:
        return self.server_version

    def __getattr__(self, name: str):
        # Every method, known or not (PUT, HEAD, OPTIONS, FOO, ...), goes to _dispatch.
        if name.startswith("do_"):
            return lambda: self._dispatch(name[3:])
        raise AttributeError(name)

    def log_request(self, code: Any = "-", size: Any = "-") -> None:
        if self.server.app.verbose:   # never the query: it may hold the token
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
            self._refuse(Refusal(int(code), f"request: {one_line(Exception(why))}"))
        except OSError:
            pass

    def _send(self, reply: Reply) -> None:
        self.send_response(reply.status)
        self.send_header("Content-Type", reply.content_type)
        self.send_header("Content-Length", str(len(reply.body)))
        self.send_header("Cache-Control", "no-store")
        self.send_header("X-Content-Type-Options", "nosniff")
        self.send_header("Referrer-Policy", "no-referrer")
        self.send_header("Cross-Origin-Resource-Policy", "same-origin")
        for k, v in reply.headers.items():
            self.send_header(k, v)
        if not self._body_read and self._has_body():
            self.close_connection = True        # the unread body would be the next request
        if self.close_connection:
            self.send_header("Connection", "close")
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(reply.body)

    def _refuse(self, r: Refusal) -> None:
        body = json.dumps({"error": r.message, "status": r.status}).encode()
        try:
            self._send(Reply(body, "application/json", r.headers, r.status))
        except (BrokenPipeError, ConnectionResetError):
            self.close_connection = True

    def _dispatch(self, method: str) -> None:
        self._body_read = False
        try:
            self._send(self._answer(method))
        except Refusal as r:
            self._refuse(r)
        except (BrokenPipeError, ConnectionResetError, _BodyLost):
            self.close_connection = True        # no one to answer: the client has gone
        except Exception as exc:    # a bug: answer 500, say it once on stderr
            print(f"stbs view: internal error on {method} "
                  f"{getattr(self, 'path', '').split('?', 1)[0]}: {type(exc).__name__}: "
                  f"{one_line(exc)}", file=sys.stderr)
            self._refuse(Refusal(500, f"internal error: {type(exc).__name__}"))

    def _has_body(self) -> bool:
        cls = self.headers.get_all("Content-Length") or []
        return "Transfer-Encoding" in self.headers or any(c.strip() != "0" for c in cls)

    # ---------------------------------------------------------------- the rules
    def _answer(self, method: str) -> Reply:
        self._check_framing()
        self._check_host()
        if method not in ROUTES.methods:
            allow = ", ".join(ROUTES.methods)
            raise Refusal(405, f"method {method} not allowed: {' or '.join(ROUTES.methods)}",
                          {"Allow": allow})
        if not self.path.startswith("/"):
            raise Refusal(400, "request target: expected a path starting with /")
        path, _, query = self.path.partition("?")
        if not ROUTES.is_public(path):
            self._check_token(query)
        handler, groups = ROUTES.find(method, path)
        request = Request(method, path, query, self.headers, self._body)
        return handler(request, self.server.app, *groups)

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
            raise Refusal(400, why)

    def _check_host(self) -> None:
        port = self.server.app.port
        hosts = self.headers.get_all("Host") or []
        allowed = (f"127.0.0.1:{port}", f"localhost:{port}")
        if len(hosts) != 1 or hosts[0].strip().lower() not in allowed:
            got = "none" if not hosts else ", ".join(repr(h) for h in hosts)
            raise Refusal(403, f"Host header: expected 127.0.0.1:{port} or localhost:{port}, "
                               f"got {got}")

    def _check_token(self, query: str) -> None:
        app = self.server.app
        given = self.headers.get_all(TOKEN_HEADER) or []
        if not given:
            try:
                given = parse_qs(query, keep_blank_values=True,
                                 max_num_fields=20).get("token", [])
            except ValueError:
                given = []
        if len(given) != 1 or not hmac.compare_digest(given[0].encode("utf-8", "replace"),
                                                      app.token.encode()):
            raise Refusal(403, f"this request needs the token of this stbs view run (query "
                               f"token= or header {TOKEN_HEADER}, from the URL it printed)")
        origin = self.headers.get_all("Origin") or []
        port = app.port
        if origin and (len(origin) != 1 or origin[0].strip().lower() not in
                       (f"http://127.0.0.1:{port}", f"http://localhost:{port}")):
            raise Refusal(403, f"Origin {origin[0]!r}: requests come from the viewer's own "
                               "page only")

    def _body(self) -> bytes:
        self._body_read = True
        if "Transfer-Encoding" in self.headers:
            self.close_connection = True
            raise Refusal(411, "request body: send it with a Content-Length (no chunked "
                               "transfer encoding)")
        cl = self.headers.get("Content-Length")       # one, digits: _check_framing
        if cl is None:
            return b""
        n = int(cl.strip())
        limit = self.server.app.max_body
        if n > limit:
            self.close_connection = True
            raise Refusal(413, f"request body of {n} bytes: the limit is {limit} bytes "
                               "(max_body)")
        return self._read(n)

    def _ack_now(self) -> None:
        """Acknowledge what has arrived at once (Linux TCP_QUICKACK). A browser sends a
        POST's headers and its body in two packets, the body only once the headers are
        acknowledged (Nagle's algorithm); with the delayed ACK that costs about 40 ms a
        request. Elsewhere a no-op."""
        quickack = getattr(socket, "TCP_QUICKACK", None)
        if quickack is None:
            return
        try:
            self.connection.setsockopt(socket.IPPROTO_TCP, quickack, 1)
        except (OSError, AttributeError):
            pass

    def _read(self, n: int) -> bytes:
        chunks, got = [], 0
        if n:
            self._ack_now()
        try:
            while got < n:      # read1: what has arrived, so a short body counts as such
                chunk = self.rfile.read1(min(n - got, 1 << 20))
                if not chunk:
                    break
                chunks.append(chunk)
                got += len(chunk)
        except TimeoutError:
            self.close_connection = True
            raise Refusal(400, f"request body: expected {n} bytes, got {got} before the "
                               f"connection was idle for {self.timeout:g} s") from None
        except OSError:
            raise _BodyLost from None
        if got != n:
            self.close_connection = True
            raise Refusal(400, f"request body: expected {n} bytes, got {got} before the "
                               "connection was closed")
        return b"".join(chunks)
