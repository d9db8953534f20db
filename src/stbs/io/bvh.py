"""BVH motion capture files (Biovision hierarchy): :func:`read_bvh` -> :class:`stbs.Motion`.

A BVH file has two parts::

    HIERARCHY
    ROOT Hips
    {
        OFFSET 0 0 0
        CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation
        JOINT Spine
        {
            OFFSET 0 5.2 0
            CHANNELS 3 Zrotation Xrotation Yrotation
            End Site
            {
                OFFSET 0 4 0
            }
        }
    }
    MOTION
    Frames: 2
    Frame Time: .0333333
    0 0 0 0 0 0 0 0 0
    0 0 0 90 0 0 0 0 0

What this reader accepts, as the files found in the wild have it:

- any channel order per joint; a joint's rotation is the product of its rotation
  channels in the order they are listed, ``R = R_1 R_2 R_3`` (``Zrotation Xrotation
  Yrotation``: ``R = Rz Rx Ry``), angles in degrees;
- position channels on any joint, not only the root: a position channel gives the
  joint's local translation on that axis in place of its offset (so a root's
  ``Xposition`` is its world x); axes without a position channel keep the offset;
- ``End Site`` blocks, which become joints of their own named ``PARENT_end``
  (``end_site`` True, rotation always the identity); zero offsets (zero-length bones);
  several roots;
- LF, CRLF and CR line ends, mixed in one file; tabs or spaces; keywords in any case;
  a ``Frame Time`` written ``.0083333``; frame lines that wrap (the values of the
  MOTION block are read as one stream and must number ``Frames`` × channels).
"""

from __future__ import annotations

import os
import re

import numpy as np

from ..motion import Motion
from ._parse import input_path, quote
from .errors import FormatError

__all__ = ["read_bvh"]

_AXES = {"x": 0, "y": 1, "z": 2}
_CHANNEL = re.compile(r"([xyz])(position|rotation)\Z", re.IGNORECASE)


def _axis_rotation(axis: int, deg: np.ndarray) -> np.ndarray:
    """(f, 3, 3) rotations by ``deg`` degrees about x, y or z (right-handed)."""
    a = np.radians(deg)
    c, s = np.cos(a), np.sin(a)
    R = np.zeros(a.shape + (3, 3))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    R[..., axis, axis] = 1.0
    R[..., i, i] = c
    R[..., j, j] = c
    R[..., i, j] = -s
    R[..., j, i] = s
    return R


class _Tokens:
    """Whitespace tokens of the HIERARCHY part with their 1-based line numbers."""

    def __init__(self, p, lines: list[str]):
        self.p = p
        self.items: list[tuple[str, int]] = []
        self.motion_line = None
        for no, line in enumerate(lines, start=1):
            words = line.split()
            if words and words[0].upper() == "MOTION":
                self.motion_line = no
                break
            self.items.extend((w, no) for w in words)
        self.i = 0
        self.last_line = len(lines)

    def peek(self) -> tuple[str, int] | None:
        return self.items[self.i] if self.i < len(self.items) else None

    def take(self, expected: str) -> tuple[str, int]:
        t = self.peek()
        if t is None:
            line = self.motion_line or self.last_line
            found = "'MOTION'" if self.motion_line else "end of file"
            raise FormatError(self.p, expected, found, line=line)
        self.i += 1
        return t

    def word(self, want: str) -> int:
        w, no = self.take(repr(want))
        if w.upper() != want.upper():
            raise FormatError(self.p, repr(want), quote(w), line=no)
        return no

    def number(self, what: str) -> float:
        w, no = self.take(what)
        try:
            x = float(w)
        except ValueError:
            raise FormatError(self.p, what, quote(w), line=no) from None
        if not np.isfinite(x):
            raise FormatError(self.p, f"{what} (finite)", quote(w), line=no)
        return x


def _parse_hierarchy(p, tok: _Tokens):
    names: list[str] = []
    parents: list[int] = []
    offsets: list[list[float]] = []
    channels: list[list[tuple[str, int]]] = []    # (kind, axis) per channel
    end_site: list[bool] = []

    def block(name: str, parent: int, is_end: bool, line: int) -> None:
        k = len(names)
        if name in names:
            raise FormatError(p, "a joint name not used before", quote(name), line=line)
        names.append(name)
        parents.append(parent)
        end_site.append(is_end)
        channels.append([])
        offsets.append([0.0, 0.0, 0.0])
        tok.word("{")
        seen_offset = False
        while True:
            w, no = tok.take("'OFFSET', 'CHANNELS', 'JOINT', 'End Site' or '}'")
            key = w.upper()
            if key == "}":
                break
            if key == "OFFSET":
                offsets[k] = [tok.number(f"an OFFSET value of {name!r}") for _ in range(3)]
                seen_offset = True
            elif key == "CHANNELS" and not is_end:
                cw, cno = tok.take(f"the channel count of {name!r}")
                try:
                    count = int(cw)
                except ValueError:
                    raise FormatError(p, f"the channel count of {name!r} (an integer)",
                                      quote(cw), line=cno) from None
                if not 0 <= count <= 6:
                    raise FormatError(p, f"0 to 6 channels for {name!r}", quote(cw), line=cno)
                for _ in range(count):
                    c, cl = tok.take(f"{count} channel names for {name!r}")
                    m = _CHANNEL.match(c)
                    if m is None:
                        raise FormatError(p, f"a channel name (Xposition ... Zrotation) for "
                                             f"{name!r}, {count} in all", quote(c), line=cl)
                    ch = (m.group(2).lower(), _AXES[m.group(1).lower()])
                    if ch in channels[k]:
                        raise FormatError(p, f"each channel of {name!r} once", quote(c), line=cl)
                    channels[k].append(ch)
            elif key == "JOINT" and not is_end:
                child, cno = tok.take("a joint name")
                block(child, k, False, cno)
            elif key == "END" and not is_end:
                tok.word("Site")
                block(f"{name}_end", k, True, no)
            else:
                where = "an End Site" if is_end else f"joint {name!r}"
                raise FormatError(p, f"'OFFSET'{'' if is_end else ', CHANNELS, JOINT, End Site'}"
                                     f" or '}}' in {where}", quote(w), line=no)
        if not seen_offset:
            raise FormatError(p, f"an OFFSET line in {'the End Site of ' if is_end else ''}"
                                 f"{names[parent] if is_end else name!r}", "none", line=line)

    t = tok.peek()
    if t is None or t[0].upper() != "HIERARCHY":
        raise FormatError(p, "'HIERARCHY' first", quote(t[0]) if t else "an empty file",
                          line=t[1] if t else 1)
    tok.take("HIERARCHY")
    while tok.peek() is not None:
        w, no = tok.take("'ROOT'")
        if w.upper() != "ROOT":
            raise FormatError(p, "'ROOT' (or 'MOTION' after the hierarchy)", quote(w), line=no)
        name, nno = tok.take("a root name")
        block(name, -1, False, nno)
    if not names:
        raise FormatError(p, "a ROOT joint after 'HIERARCHY'", "none",
                          line=tok.motion_line or tok.last_line)
    return names, parents, offsets, channels, end_site


def _header_value(p, lines: list[str], i: int, key: str) -> str:
    """The text after ``key`` (e.g. 'Frames:') on line ``i`` (0-based)."""
    if i >= len(lines):
        raise FormatError(p, f"a line '{key} ...'", "end of file", line=len(lines))
    m = re.match(r"\s*" + r"\s*".join(map(re.escape, key.split())) + r"\s*(.*)$", lines[i],
                 re.IGNORECASE)
    if m is None:
        raise FormatError(p, f"a line '{key} ...'", quote(lines[i]), line=i + 1)
    return m.group(1).strip()


def read_bvh(path: str | os.PathLike) -> Motion:
    """Read a BVH motion capture file (see the module docs for the quirks accepted).

    Parameters
    ----------
    path : str or os.PathLike
        A ``.bvh`` file.

    Returns
    -------
    Motion
        Joints in file order (depth first, end sites where they appear), their
        offsets, and per frame the local rotations (from the rotation channels, in
        each joint's own channel order) and translations (offsets, with position
        channels in their place); ``frame_time`` from the file. The file's raw
        channel values are kept as ``motion.channels`` ((f, c) float64) with
        ``motion.channel_names`` (c ``"Joint.Xrotation"`` strings).

    Raises
    ------
    FileNotFoundError
        ``path`` does not exist.
    FormatError
        A malformed hierarchy (unknown keyword, missing brace or OFFSET, a bad
        channel list, a repeated joint name), no MOTION part, a bad ``Frames`` or
        ``Frame Time`` line, or a MOTION block whose values do not number
        ``Frames`` × channels (a truncated file, a frame line with a wrong count);
        the message names the file and the line.

    Examples
    --------
    >>> import os, tempfile
    >>> text = '''HIERARCHY
    ... ROOT hip
    ... {
    ...   OFFSET 0 0 0
    ...   CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
    ...   End Site
    ...   {
    ...     OFFSET 0 1 0
    ...   }
    ... }
    ... MOTION
    ... Frames: 2
    ... Frame Time: .5
    ... 0 0 0 0 0 0
    ... 1 0 0 90 0 0
    ... '''
    >>> path = os.path.join(tempfile.mkdtemp(), "tiny.bvh")
    >>> with open(path, "w") as f:
    ...     _ = f.write(text)
    >>> m = read_bvh(path)
    >>> m, m.names
    (Motion(1 joints + 1 end sites, 2 frames at 2 fps), ['hip', 'hip_end'])
    >>> m.positions()[1].round(6).tolist()   # frame 1: moved by x = 1, turned 90 deg about z
    [[1.0, 0.0, 0.0], [0.0, 0.0, 0.0]]
    """
    p = input_path(path, "BVH")
    text = p.read_bytes().decode("latin-1")
    lines = re.split(r"\r\n|\r|\n", text)
    if lines and lines[-1] == "":
        lines.pop()             # the end of the last line, not a line of its own
    tok = _Tokens(p, lines)
    names, parents, offsets, channels, end_site = _parse_hierarchy(p, tok)
    if tok.motion_line is None:
        raise FormatError(p, "a 'MOTION' line after the hierarchy", "end of file",
                          line=len(lines))
    i = tok.motion_line                     # 0-based index of the line after MOTION
    while i < len(lines) and not lines[i].strip():
        i += 1
    frames_text = _header_value(p, lines, i, "Frames:")
    try:
        n_frames = int(frames_text)
    except ValueError:
        n_frames = -1
    if n_frames < 1:
        raise FormatError(p, "'Frames: N' with N a whole number >= 1", quote(lines[i]),
                          line=i + 1)
    i += 1
    dt_text = _header_value(p, lines, i, "Frame Time:")
    try:
        dt = float(dt_text)
    except ValueError:
        dt = float("nan")
    if not (np.isfinite(dt) and dt > 0):
        raise FormatError(p, "'Frame Time: SECONDS' with a positive number", quote(lines[i]),
                          line=i + 1)
    first = i + 1
    n_ch = sum(len(c) for c in channels)
    want = n_frames * n_ch
    body = lines[first:]
    counts = np.array([len(s.split()) for s in body], dtype=np.int64)
    total = int(counts.sum())
    if total != want:
        # Point at the first line that breaks a one-frame-per-line layout, or the end.
        bad = np.flatnonzero((counts != n_ch) & (counts != 0))
        line = first + (int(bad[0]) + 1 if bad.size else len(body))
        why = [f"a frame line of {counts[bad[0]]} values"] if bad.size else []
        if total < want:
            why.insert(0, "a truncated MOTION block")
        found = f"{total} numbers" + (f" ({' or '.join(why)})" if why else "")
        raise FormatError(p, f"{n_frames} frames of {n_ch} values ({want} numbers; "
                             f"'Frames: {n_frames}')", found, line=line)
    try:
        data = np.array(" ".join(body).split(), dtype=np.float64)
    except ValueError:
        for k, s in enumerate(body):
            for w in s.split():
                try:
                    float(w)
                except ValueError:
                    raise FormatError(p, "a number in the MOTION block", quote(w),
                                      line=first + k + 1) from None
        raise
    if not np.isfinite(data).all():
        k = int(np.flatnonzero(~np.isfinite(data))[0]) // max(n_ch, 1)
        raise FormatError(p, "finite channel values", f"a non-finite value in frame {k}")
    data = data.reshape(n_frames, n_ch)

    j = len(names)
    O = np.array(offsets, dtype=np.float64)
    R = np.tile(np.eye(3), (n_frames, j, 1, 1))
    T = np.broadcast_to(O, (n_frames, j, 3)).copy()
    col = 0
    channel_names = []
    for k, chs in enumerate(channels):
        Rk = None
        for kind, axis in chs:
            v = data[:, col]
            channel_names.append(f"{names[k]}.{'XYZ'[axis]}{kind}")
            col += 1
            if kind == "position":
                T[:, k, axis] = v
            else:
                A = _axis_rotation(axis, v)
                Rk = A if Rk is None else Rk @ A
        if Rk is not None:
            R[:, k] = Rk
    m = Motion(names, parents, O, rotations=R, translations=T, frame_time=dt,
               end_site=end_site, source=str(p))
    m.channels = data
    m.channel_names = channel_names
    return m
