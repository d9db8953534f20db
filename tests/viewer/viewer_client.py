"""Test support for the viewer: small rigs, and requests to a server on 127.0.0.1 only."""

from __future__ import annotations

import http.client
import json
import socket
from dataclasses import dataclass

import numpy as np

import stbs
from stbs.shapes import bar
from stbs.weights import projection

TIMEOUT = 10  # seconds for every connection and read


@dataclass
class Reply:
    status: int
    headers: dict
    body: bytes

    def json(self):
        return json.loads(self.body)

    def array(self) -> np.ndarray:
        dtype = np.dtype(self.headers["x-stbs-dtype"]).newbyteorder("<")
        shape = tuple(int(s) for s in self.headers["x-stbs-shape"].split(","))
        return np.frombuffer(self.body, dtype=dtype).reshape(shape)


def bar_rig(with_E: bool = True) -> stbs.Rig:
    """A two-bone 3D bar (74 vertices), bone heat-free: its analytic weights."""
    V, F, sk, W = bar(8, 2, 2)
    return stbs.Rig(V=V, F=F, skeleton=sk, W=W, E=projection(V, sk) if with_E else None)


def grid_mesh(xs, ys) -> tuple[np.ndarray, np.ndarray]:
    """A 2D grid's vertices (row by row along ``xs``) and its triangles, two a cell."""
    X, Y = np.meshgrid(xs, ys)
    V = np.column_stack([X.ravel(), Y.ravel()])
    nx = len(xs)
    F = []
    for i in range(len(ys) - 1):
        for j in range(nx - 1):
            q = i * nx + j
            F += [[q, q + 1, q + nx + 1], [q, q + nx + 1, q + nx]]
    return V, np.array(F)


def request(srv, method: str, path: str, *, body: bytes | str | None = None,
            token: bool | str = False, host: str | None = None,
            headers: dict | None = None) -> Reply:
    """One request on a fresh connection to ``srv`` (127.0.0.1).

    ``token``: True sends the server's token in the ``X-Stbs-Token`` header, a string
    sends that string; ``host`` replaces the Host header (default 127.0.0.1:PORT).
    """
    h = dict(headers or {})
    h["Host"] = host if host is not None else f"127.0.0.1:{srv.port}"
    if token is True:
        h["X-Stbs-Token"] = srv.token
    elif token:
        h["X-Stbs-Token"] = token
    if isinstance(body, str):
        body = body.encode()
    c = http.client.HTTPConnection("127.0.0.1", srv.port, timeout=TIMEOUT)
    try:
        c.request(method, path, body=body, headers=h)
        r = c.getresponse()
        return Reply(r.status, {k.lower(): v for k, v in r.getheaders()}, r.read())
    finally:
        c.close()


def post_json(srv, path: str, obj, **kw) -> Reply:
    return request(srv, "POST", path, body=json.dumps(obj), token=True,
                   headers={"Content-Type": "application/json"}, **kw)


def raw(srv, data: bytes) -> bytes:
    """Send raw bytes on a socket to 127.0.0.1:PORT; the whole answer (bounded)."""
    with socket.create_connection(("127.0.0.1", srv.port), timeout=TIMEOUT) as s:
        s.sendall(data)
        s.shutdown(socket.SHUT_WR)
        chunks = []
        for _ in range(1000):
            b = s.recv(65536)
            if not b:
                break
            chunks.append(b)
        return b"".join(chunks)
