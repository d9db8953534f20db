"""``stbs view``: the browser viewer's server and its rig data API (a front end).

:class:`ViewerServer` serves one rig on 127.0.0.1 with a fresh token per run: the page
and its assets (``static/``), the rig's summary and arrays as the page's shaders take
them (:class:`RigPayload`: positions, faces, the skeleton with its hierarchy, the four
heaviest bones per vertex with their bone and endpoint weights), the current pose, the
clips the page plays (held by id and evaluated by :meth:`stbs.Clip.arrays`, see
:mod:`stbs.viewer.clips`), and atomic saves of poses, clips and the rig (``.npz`` or
glTF). The server is cut into units: :mod:`~stbs.viewer.state` (what it holds),
:mod:`~stbs.viewer.routes` (the route table), :mod:`~stbs.viewer.handler` (framing and
the Host, token and body rules), :mod:`~stbs.viewer.jobs` (work in a worker thread),
:mod:`~stbs.viewer.saves`, :mod:`~stbs.viewer.bones` (a pose on the wire) and
:mod:`~stbs.viewer.refusal` (the one error answer); docs/viewer-api.md is the API's
reference.

The page itself (``static/index.html`` and the bundle ``static/viewer.js``, built from
``viewer/src`` by ``make``) skins the rig in a vertex shader; without the bundle the
page says so and lists the API.
"""

from .payload import ARRAY_DOCS, MAX_INFLUENCES, RigPayload
from .server import HOST, MAX_BODY, STATIC_DIR, TOKEN_HEADER, ViewerServer, static_path

__all__ = ["ViewerServer", "RigPayload", "static_path", "STATIC_DIR", "HOST", "MAX_BODY",
           "TOKEN_HEADER", "MAX_INFLUENCES", "ARRAY_DOCS"]
