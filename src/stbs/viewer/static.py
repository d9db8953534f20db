"""The page and its assets: files of the package's static folder, confined to it."""

from __future__ import annotations

import os
import re
from pathlib import Path

__all__ = ["STATIC_DIR", "BUNDLE", "static_path", "content_type", "PAGE_HEADERS",
           "page_missing"]

#: The package's own page and assets.
STATIC_DIR = Path(__file__).resolve().parent / "static"
#: The page's script bundle inside the static folder (built from viewer/src).
BUNDLE = "viewer.js"

_SEGMENT = re.compile(r"[A-Za-z0-9_-][A-Za-z0-9_.-]*\Z")
_TYPES = {".html": "text/html; charset=utf-8", ".js": "text/javascript; charset=utf-8",
          ".mjs": "text/javascript; charset=utf-8", ".css": "text/css; charset=utf-8",
          ".json": "application/json", ".map": "application/json",
          ".wasm": "application/wasm", ".png": "image/png", ".jpg": "image/jpeg",
          ".svg": "image/svg+xml", ".ico": "image/x-icon", ".txt": "text/plain; charset=utf-8",
          ".glsl": "text/plain; charset=utf-8"}
_PAGE_POLICY = ("default-src 'self'; img-src 'self' data: blob:; style-src 'self' "
                "'unsafe-inline'; connect-src 'self'; frame-ancestors 'none'; base-uri 'none'")
#: Headers of the page itself (an HTML file): no framing, scripts of its own origin only.
PAGE_HEADERS = {"Content-Security-Policy": _PAGE_POLICY, "X-Frame-Options": "DENY"}


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


def content_type(p: Path) -> str:
    """The Content-Type a static file is served with."""
    return _TYPES.get(p.suffix.lower(), "application/octet-stream")


def page_missing(static_dir: str | os.PathLike | None = None) -> str | None:
    """None when the page's bundle is in ``static_dir`` (default :data:`STATIC_DIR`),
    else one line saying that this installation lacks it and how to get it."""
    folder = Path(STATIC_DIR if static_dir is None else static_dir)
    if (folder / BUNDLE).is_file():
        return None
    return (f"this installation of stbs lacks the viewer's page ({folder / BUNDLE} is "
            "missing): reinstall stbs-skinning from a release, or, in a source checkout, "
            "build it with make")
