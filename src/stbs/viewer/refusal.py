"""The one refusal of the viewer's server: an HTTP status, a one-line message, headers.

Every check of a request (framing, Host, token, the route table, bodies, limits,
saves, jobs) raises :class:`Refusal`; the HTTP handler answers it as JSON
``{"error": message, "status": N}`` with its headers (e.g. ``Allow`` on a 405).
"""

from __future__ import annotations

import json
from typing import Any

__all__ = ["Refusal", "one_line", "show"]


class Refusal(Exception):
    """A request answered with an error: ``status``, a one-line ``message``, ``headers``.

    Parameters
    ----------
    status : int
        The HTTP status (4xx for the client's request, 5xx for the server's side).
    message : str
        What is wrong with which input and what was expected; newlines and runs of
        white space are folded to single spaces, so it is always one line.
    headers : dict, optional
        Extra response headers, e.g. ``{"Allow": "GET"}``.

    Examples
    --------
    >>> r = Refusal(405, "/api/rig: GET only", {"Allow": "GET"})
    >>> r.status, r.message, r.headers
    (405, '/api/rig: GET only', {'Allow': 'GET'})
    >>> Refusal(400, "two\\nlines").message
    'two lines'
    """

    def __init__(self, status: int, message: str, headers: dict | None = None):
        super().__init__(message)
        self.status = int(status)
        self.message = " ".join(str(message).split())
        self.headers = dict(headers or {})


def one_line(exc: BaseException) -> str:
    """An exception's message on one line (its type's name when it has none)."""
    return " ".join(str(exc).split()) or type(exc).__name__


def show(x: Any) -> str:
    """A JSON value in a message: short values as JSON, others by their kind."""
    if isinstance(x, (bool, int, float, str)) or x is None:
        s = json.dumps(x)
        return s if len(s) <= 40 else s[:37] + "..."
    return {dict: "an object", list: "a list"}.get(type(x), type(x).__name__)
