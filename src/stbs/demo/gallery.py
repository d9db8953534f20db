"""The demo's ``index.html``: one self-contained page showing every figure and its numbers.

The page has inline CSS, no script and no external resource: images are linked by
relative file names in the same folder, so the output folder can be moved, zipped or
served as it is. All text is escaped.
"""

from __future__ import annotations

import html
import os
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from typing import Any
from urllib.parse import quote

from ..io import atomic_open

__all__ = ["GalleryEntry", "write_gallery"]

_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")

_CSS = """
:root { color-scheme: light; }
body { font-family: system-ui, -apple-system, "Segoe UI", Helvetica, Arial, sans-serif;
       margin: 0 auto; max-width: 1500px; padding: 1.5rem 2rem 3rem; color: #1d1d1f;
       background: #fafafa; line-height: 1.45; }
h1 { font-size: 1.7rem; margin: 0.2rem 0 0.6rem; }
h2 { font-size: 1.3rem; margin: 0 0 0.4rem; }
nav ol { columns: 2; padding-left: 1.4rem; }
nav a, h2 a { color: #30638e; text-decoration: none; }
section { background: #fff; border: 1px solid #e3e3e3; border-radius: 8px;
          padding: 1.1rem 1.3rem 1.3rem; margin: 1.4rem 0; }
.caption { max-width: 75rem; white-space: pre-line; }
figure { margin: 0.8rem 0; }
figure img { max-width: 100%; height: auto; border: 1px solid #eee; background: #fff; }
figcaption { font-size: 0.85rem; color: #666; }
table { border-collapse: collapse; margin-top: 0.6rem; font-size: 0.95rem; }
th, td { border-bottom: 1px solid #e5e5e5; padding: 0.3rem 0.9rem; text-align: right; }
th:first-child, td:first-child { text-align: left; }
thead th { border-bottom: 2px solid #bbb; }
tr.expected td { color: #555; font-style: italic; border-bottom: none; }
p.expected { color: #555; font-style: italic; margin: 0.4rem 0 0; }
footer { color: #888; font-size: 0.85rem; margin-top: 2rem; }
"""


@dataclass(eq=False)
class GalleryEntry:
    """One section of the gallery: a figure of the paper, its pictures and numbers.

    Parameters
    ----------
    name : str
        Short identifier (letters, digits, ``_ . -``), used as the section's anchor.
    title : str
        The section heading, e.g. "Fig. 3 left: one bone twisted 315 degrees".
    caption : str
        What the paper says and what to look for (plain text; line breaks kept).
    images : list of str
        Relative file names of the pictures (PNG or GIF) in the output folder,
        shown in order.
    table : dict[str, dict[str, Any]] or list of sequences, optional
        The measured numbers. Either ``table[method][column]``, or rows
        ``[method, value, value, ...]`` aligned with ``columns``. Values are shown
        as given (``str``) or with 4 significant digits (numbers); missing cells as
        a dash.
    columns : list of str
        The table's column headers (besides the first, "method").
    expected : str or dict[str, str]
        What the paper predicts: one line under the table, or one cell per column
        in a last "expected" row.
    """

    name: str
    title: str
    caption: str = ""
    images: Sequence[str] = field(default_factory=list)
    table: Mapping[str, Mapping[str, Any]] | Sequence[Sequence[Any]] | None = None
    columns: Sequence[str] = field(default_factory=list)
    expected: str | Mapping[str, str] = ""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not _NAME.match(self.name):
            raise ValueError(f"name must be letters, digits, '_', '.' or '-' (starting with a "
                             f"letter or digit), got {self.name!r}")
        for k in ("title", "caption"):
            if not isinstance(getattr(self, k), str):
                raise ValueError(f"{k} must be a str, got {type(getattr(self, k)).__name__}")
        if isinstance(self.images, str) or not isinstance(self.images, Sequence):
            raise ValueError(f"images must be a list of relative file names, got "
                             f"{self.images!r}")
        self.images = [_relative_name(f"images[{k}]", im) for k, im in enumerate(self.images)]
        if isinstance(self.columns, str) or not all(isinstance(c, str) for c in self.columns):
            raise ValueError(f"columns must be a list of str, got {self.columns!r}")
        self.columns = list(self.columns)
        self.table = _table_rows(self.table, self.columns)
        if isinstance(self.expected, Mapping):
            unknown = [k for k in self.expected if k not in self.columns]
            if unknown:
                raise ValueError(f"expected names columns not in columns {self.columns}: "
                                 f"{unknown}")
        elif not isinstance(self.expected, str):
            raise ValueError(f"expected must be a str or a dict column -> str, got "
                             f"{type(self.expected).__name__}")


def _relative_name(name: str, value: Any) -> str:
    if not isinstance(value, (str, os.PathLike)):
        raise ValueError(f"{name} must be a relative file name, got {value!r}")
    s = os.fspath(value).replace("\\", "/")
    p = PurePosixPath(s)
    if not s or p.is_absolute() or ".." in p.parts or re.match(r"^[A-Za-z]:", s) or \
            re.match(r"^[A-Za-z][A-Za-z0-9+.-]*:", s):
        raise ValueError(f"{name} must be a file name relative to the gallery's folder "
                         f"(no absolute path, URL or '..'), got {value!r}")
    return s


def _cell(v: Any) -> str:
    if v is None:
        return "\u2013"
    if isinstance(v, str):
        return v
    if isinstance(v, bool):
        return str(v)
    try:
        return f"{float(v):.4g}"
    except (TypeError, ValueError):
        return str(v)


def _table_rows(table, columns: list[str]) -> list[list[str]]:
    """The table as rows of strings ``[method, cell per column]``."""
    if table is None:
        return []
    rows = []
    if isinstance(table, Mapping):
        for method, cells in table.items():
            if not isinstance(cells, Mapping):
                raise ValueError(f"table[{method!r}] must be a dict column -> value, got "
                                 f"{type(cells).__name__}")
            unknown = [k for k in cells if k not in columns]
            if unknown:
                raise ValueError(f"table[{method!r}] names columns not in columns "
                                 f"{columns}: {unknown}")
            rows.append([str(method)] + [_cell(cells.get(c)) for c in columns])
        return rows
    if isinstance(table, str) or not isinstance(table, Sequence):
        raise ValueError(f"table must be a dict method -> dict column -> value, or a list "
                         f"of rows, got {type(table).__name__}")
    for k, row in enumerate(table):
        if isinstance(row, str) or not isinstance(row, Sequence) or \
                len(row) != len(columns) + 1:
            raise ValueError(f"table[{k}] must be a row [method, {len(columns)} values] "
                             f"matching columns {columns}, got {row!r}")
        rows.append([str(row[0])] + [_cell(v) for v in row[1:]])
    return rows


def _e(text: str) -> str:
    return html.escape(text, quote=True)


def _section(entry: GalleryEntry) -> str:
    out = [f'<section id="{_e(entry.name)}">',
           f'<h2><a href="#{_e(entry.name)}">{_e(entry.title)}</a></h2>']
    if entry.caption:
        out.append(f'<p class="caption">{_e(entry.caption)}</p>')
    for im in entry.images:
        src = _e(quote(im))
        alt = _e(f"{entry.title}: {im}")
        out.append(f'<figure><a href="{src}"><img src="{src}" alt="{alt}" loading="lazy">'
                   f'</a><figcaption>{_e(im)}</figcaption></figure>')
    if entry.table or entry.columns:
        out.append("<table>")
        head = "".join(f"<th>{_e(c)}</th>" for c in ["method", *entry.columns])
        out.append(f"<thead><tr>{head}</tr></thead>")
        out.append("<tbody>")
        for row in entry.table:
            cells = "".join(f"<td>{_e(c)}</td>" for c in row)
            out.append(f"<tr>{cells}</tr>")
        if isinstance(entry.expected, Mapping) and entry.expected:
            cells = "".join(f"<td>{_e(entry.expected.get(c, ''))}</td>" for c in entry.columns)
            out.append(f'<tr class="expected"><td>expected</td>{cells}</tr>')
        out.append("</tbody></table>")
    if isinstance(entry.expected, str) and entry.expected:
        out.append(f'<p class="expected">expected: {_e(entry.expected)}</p>')
    out.append("</section>")
    return "\n".join(out)


def write_gallery(out_dir: str | os.PathLike, entries: Sequence[GalleryEntry], *,
                  title: str = "stbs demo: the paper's figures", intro: str | None = None,
                  check_images: bool = True) -> Path:
    """Write ``index.html`` into ``out_dir``: every figure, caption, picture and table.

    Parameters
    ----------
    out_dir : str or os.PathLike
        The folder holding the pictures; must exist. ``out_dir/index.html`` is
        written atomically (an existing one is replaced only once the new one is
        complete).
    entries : sequence of GalleryEntry
        The sections, in order; their names must be distinct.
    title : str
        The page's title and heading.
    intro : str, optional
        A paragraph under the heading (plain text; line breaks kept).
    check_images : bool
        Require every image to exist in ``out_dir`` (a broken gallery is a bug).

    Returns
    -------
    Path
        The path of ``index.html``.

    Raises
    ------
    FileNotFoundError
        When ``out_dir`` is missing, or an image is missing and ``check_images``.
    ValueError
        When ``entries`` holds something other than :class:`GalleryEntry`, or two
        entries share a name.

    Notes
    -----
    The page is self-contained: inline CSS, no script, no external resource; images
    are linked by relative names. All text is escaped with :func:`html.escape`.
    """
    out = Path(os.fspath(out_dir))
    if not out.is_dir():
        raise FileNotFoundError(f"out_dir must be an existing folder, got {str(out)!r}")
    if isinstance(entries, GalleryEntry) or not isinstance(entries, Sequence):
        raise ValueError(f"entries must be a list of GalleryEntry, got "
                         f"{type(entries).__name__}")
    seen: set[str] = set()
    for k, e in enumerate(entries):
        if not isinstance(e, GalleryEntry):
            raise ValueError(f"entries[{k}] must be a GalleryEntry, got {type(e).__name__}")
        if e.name in seen:
            raise ValueError(f"entries[{k}].name {e.name!r} is used twice; names must differ")
        seen.add(e.name)
        if check_images:
            missing = [im for im in e.images if not (out / im).is_file()]
            if missing:
                raise FileNotFoundError(f"entry {e.name!r}: image {missing[0]!r} not found in "
                                        f"{str(out)!r}")
    if not isinstance(title, str) or (intro is not None and not isinstance(intro, str)):
        raise ValueError(f"title and intro must be str, got {title!r} and {intro!r}")
    parts = ["<!DOCTYPE html>", '<html lang="en">', "<head>", '<meta charset="utf-8">',
             '<meta name="viewport" content="width=device-width, initial-scale=1">',
             f"<title>{_e(title)}</title>", f"<style>{_CSS}</style>", "</head>", "<body>",
             f"<h1>{_e(title)}</h1>"]
    if intro:
        parts.append(f'<p class="caption">{_e(intro)}</p>')
    if len(entries) > 1:
        items = "".join(f'<li><a href="#{_e(e.name)}">{_e(e.title)}</a></li>' for e in entries)
        parts.append(f"<nav><ol>{items}</ol></nav>")
    parts += [_section(e) for e in entries]
    parts += ["<footer>Generated by <code>stbs demo</code>. Pictures drawn headless with "
              "matplotlib (Agg).</footer>", "</body>", "</html>", ""]
    path = out / "index.html"
    with atomic_open(path, "w", newline="\n") as f:
        f.write("\n".join(parts))
    return path
