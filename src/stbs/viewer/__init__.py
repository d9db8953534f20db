"""``stbs view``: the browser viewer's server and its rig data API (a front end).

:class:`ViewerServer` serves one rig on 127.0.0.1 with a fresh token per run: the page
and its assets (``static/``), the rig's summary and arrays as the page's shaders take
them (:class:`RigPayload`: positions, faces, skeleton, the four heaviest bones per
vertex with their bone and endpoint weights), the current pose, and atomic saves of
poses and of the rig. The rules it enforces (Host, token, confined paths, body
limits) are in :mod:`stbs.viewer.server` and docs/viewer.md.

The page that renders and skins the rig in the browser is not part of this release:
the ``static/index.html`` shipped here says so and lists the API.
"""

from .payload import ARRAY_DOCS, MAX_INFLUENCES, RigPayload
from .server import HOST, MAX_BODY, STATIC_DIR, TOKEN_HEADER, ViewerServer, static_path

__all__ = ["ViewerServer", "RigPayload", "static_path", "STATIC_DIR", "HOST", "MAX_BODY",
           "TOKEN_HEADER", "MAX_INFLUENCES", "ARRAY_DOCS"]
