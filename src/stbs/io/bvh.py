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
- LF, CRLF and CR line ends, mixed in one file; a UTF-8 byte order mark; tabs or
  spaces; keywords in any case; a ``Frame Time`` written ``.0083333``; frame lines
  that wrap (the values of the MOTION block are read as one stream and must number
  ``Frames`` × channels).

What it refuses, with one :class:`~stbs.io.FormatError` naming the file, the line, what
was expected and what was found, before allocating anything the file's content does
not justify:

- more than :data:`MAX_JOINTS` (10 000) joints, end sites included, a joint name longer
  than :data:`MAX_NAME` (256) characters, a repeated name, a second ``OFFSET`` or
  ``CHANNELS`` line in one joint; hierarchies of any depth are read without recursion;
- ``Frames`` that is not a whole number from 1 to :data:`MAX_FRAMES` (1 000 000;
  ``max_frames=`` overrides it), or frames × joints above :data:`MAX_JOINT_FRAMES`
  (10 000 000, the size of the per-frame transforms; ``max_joint_frames=`` overrides
  it);
- a ``Frame Time`` that is not a number of seconds from :data:`MIN_FRAME_TIME` (1e-6)
  to :data:`MAX_FRAME_TIME` (3600);
- a MOTION block whose values do not number ``Frames`` × channels, or, when no joint
  has a channel, that has fewer lines than ``Frames`` (one, empty, per frame);
- an OFFSET or channel value that is not a number, NaN, infinite, or larger in
  magnitude than :data:`MAX_VALUE` (1e6: centimetres, millimetres or degrees, far
  beyond any capture).
"""

from __future__ import annotations

import os
import re

import numpy as np

from ..motion import Motion
from ._parse import input_path, quote
from .errors import FormatError

__all__ = ["read_bvh", "MAX_FRAMES", "MAX_JOINTS", "MAX_JOINT_FRAMES", "MAX_VALUE",
           "MIN_FRAME_TIME", "MAX_FRAME_TIME", "MAX_NAME"]

#: Most frames :func:`read_bvh` reads unless told otherwise (``max_frames=``): 2.3 hours
#: at 120 fps.
MAX_FRAMES = 1_000_000
#: Most joints, end sites included, in one file.
MAX_JOINTS = 10_000
#: Most frames × joints unless told otherwise (``max_joint_frames=``): the per-frame
#: rotations and translations take 96 bytes each (about 1 GB at this limit; 100 joints
#: over 100 000 frames).
MAX_JOINT_FRAMES = 10_000_000
#: Largest magnitude of an OFFSET or channel value (a position or an angle in degrees).
MAX_VALUE = 1e6
#: Shortest and longest ``Frame Time`` in seconds.
MIN_FRAME_TIME = 1e-6
MAX_FRAME_TIME = 3600.0
#: Longest joint name, in characters.
MAX_NAME = 256

_AXES = {"x": 0, "y": 1, "z": 2}
_CHANNEL = re.compile(r"([xyz])(position|rotation)\Z", re.IGNORECASE)
_NUMBER = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?\Z")
_TOKEN = re.compile(r"\S+")
_BLANK_LINES = re.compile(r"(?:[^\S\n]*\n)*")
# The MOTION block is counted and converted in pieces of about this many characters, so
# that no list of a whole file's numbers is ever built.
_CHUNK = 1 << 20
# Python's whitespace (what str.split splits at) among the 256 latin-1 characters.
_SPACE = np.array([chr(c).isspace() for c in range(256)])


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
    """The whitespace tokens of the HIERARCHY part with their 1-based line numbers, read
    one at a time (never held as a list), up to a line that starts with ``MOTION``."""

    def __init__(self, p, text: str):
        self.p = p
        self.text = text
        self.n_lines = text.count("\n") + (1 if text and not text.endswith("\n") else 0)
        self.motion_line: int | None = None
        self.motion_end = len(text)     # where the line after MOTION starts
        self._it = _TOKEN.finditer(text)
        self._pos = 0
        self._line = 1
        self._prev_line = 0
        self._next: tuple[str, int] | None = None
        self._advance()

    def _advance(self) -> None:
        self._next = None
        if self.motion_line is not None:
            return
        m = next(self._it, None)
        if m is None:
            return
        self._line += self.text.count("\n", self._pos, m.start())
        self._pos = m.start()
        w = m.group()
        if self._line > self._prev_line and w.upper() == "MOTION":
            self.motion_line = self._line
            nl = self.text.find("\n", m.end())
            self.motion_end = len(self.text) if nl < 0 else nl + 1
            return
        self._prev_line = self._line
        self._next = (w, self._line)

    def peek(self) -> tuple[str, int] | None:
        return self._next

    def take(self, expected: str) -> tuple[str, int]:
        t = self._next
        if t is None:
            line = self.motion_line or self.n_lines
            found = "'MOTION'" if self.motion_line else "end of file"
            raise FormatError(self.p, expected, found, line=line)
        self._advance()
        return t

    def word(self, want: str) -> int:
        w, no = self.take(repr(want))
        if w.upper() != want.upper():
            raise FormatError(self.p, repr(want), quote(w), line=no)
        return no

    def number(self, what: str) -> float:
        w, no = self.take(what)
        if _NUMBER.match(w) is None:
            found = quote(w)
            if w.lower().lstrip("+-") in ("nan", "inf", "infinity"):
                found += " (not finite)"
            raise FormatError(self.p, what, found, line=no)
        x = float(w)
        if not abs(x) <= MAX_VALUE:
            raise FormatError(self.p, f"{what} of magnitude at most {MAX_VALUE:g}", quote(w),
                              line=no)
        return x


class _Joint:
    """An open ``{ ... }`` block of the hierarchy while it is read."""
    __slots__ = ("k", "is_end", "line", "offset", "channels")

    def __init__(self, k: int, is_end: bool, line: int):
        self.k, self.is_end, self.line = k, is_end, line
        self.offset = self.channels = False


class _Hierarchy:
    """The joints of the HIERARCHY part as they are read: names, parents, offsets,
    channels ((kind, axis) per channel) and end-site flags, one entry per joint, and
    the stack of open blocks."""

    def __init__(self, p, tok: _Tokens):
        self.p, self.tok = p, tok
        self.names: list[str] = []
        self.parents: list[int] = []
        self.offsets: list[list[float]] = []
        self.channels: list[list[tuple[str, int]]] = []
        self.end_site: list[bool] = []
        self.taken: set[str] = set()
        self.stack: list[_Joint] = []

    def open_block(self, name: str, parent: int, is_end: bool, line: int) -> None:
        """A joint (or end site) named ``name`` below ``parent``, its ``{`` read."""
        p, names = self.p, self.names
        if len(names) >= MAX_JOINTS:
            raise FormatError(p, f"at most {MAX_JOINTS} joints (end sites included)",
                              f"joint {len(names) + 1}, {quote(name)}", line=line)
        if len(name) > MAX_NAME:
            raise FormatError(p, f"a joint name of at most {MAX_NAME} characters",
                              f"one of {len(name)}: {quote(name)}", line=line)
        if name in self.taken:
            raise FormatError(p, "a joint name not used before", quote(name), line=line)
        self.taken.add(name)
        self.stack.append(_Joint(len(names), is_end, line))
        names.append(name)
        self.parents.append(parent)
        self.end_site.append(is_end)
        self.channels.append([])
        self.offsets.append([0.0, 0.0, 0.0])
        self.tok.word("{")

    def read_channels(self, k: int, name: str) -> None:
        """The count and names of joint ``k``'s channels (after ``CHANNELS``)."""
        p, tok = self.p, self.tok
        cw, cno = tok.take(f"the channel count of {name!r}")
        if not re.fullmatch(r"[0-9]{1,2}", cw) or int(cw) > 6:
            raise FormatError(p, f"0 to 6 channels for {name!r}", quote(cw), line=cno)
        count = int(cw)
        for _ in range(count):
            c, cl = tok.take(f"{count} channel names for {name!r}")
            m = _CHANNEL.match(c)
            if m is None:
                raise FormatError(p, f"a channel name (Xposition ... Zrotation) for "
                                     f"{name!r}, {count} in all", quote(c), line=cl)
            ch = (m.group(2).lower(), _AXES[m.group(1).lower()])
            if ch in self.channels[k]:
                raise FormatError(p, f"each channel of {name!r} once", quote(c), line=cl)
            self.channels[k].append(ch)

    def root(self) -> bool:
        """Open the next ROOT block; False at the end of the hierarchy."""
        if self.tok.peek() is None:
            return False
        w, no = self.tok.take("'ROOT'")
        if w.upper() != "ROOT":
            raise FormatError(self.p, "'ROOT' (or 'MOTION' after the hierarchy)", quote(w),
                              line=no)
        name, nno = self.tok.take("a root name")
        self.open_block(name, -1, False, nno)
        return True

    def close(self, top: _Joint) -> None:
        """The ``}`` of the innermost block, which must have had its OFFSET."""
        k = top.k
        if not top.offset:
            owner = (f"the End Site of {self.names[self.parents[k]]!r}" if top.is_end
                     else repr(self.names[k]))
            raise FormatError(self.p, f"an OFFSET line in {owner}", "none", line=top.line)
        self.stack.pop()

    def statement(self, top: _Joint) -> None:
        """One statement inside the innermost open block ``top``."""
        p, tok = self.p, self.tok
        k, is_end = top.k, top.is_end
        name = self.names[k]
        w, no = tok.take("'OFFSET', 'CHANNELS', 'JOINT', 'End Site' or '}'")
        key = w.upper()
        if key == "}":
            self.close(top)
        elif key == "OFFSET":
            if top.offset:
                raise FormatError(p, f"one OFFSET line in {name!r}", "a second one", line=no)
            self.offsets[k] = [tok.number(f"an OFFSET value of {name!r}") for _ in range(3)]
            top.offset = True
        elif key == "CHANNELS" and not is_end:
            if top.channels:
                raise FormatError(p, f"one CHANNELS line in {name!r}", "a second one", line=no)
            self.read_channels(k, name)
            top.channels = True
        elif key == "JOINT" and not is_end:
            child, cno = tok.take("a joint name")
            self.open_block(child, k, False, cno)
        elif key == "END" and not is_end:
            tok.word("Site")
            self.open_block(f"{name}_end", k, True, no)
        else:
            where = "an End Site" if is_end else f"joint {name!r}"
            raise FormatError(p, f"'OFFSET'{'' if is_end else ', CHANNELS, JOINT, End Site'}"
                                 f" or '}}' in {where}", quote(w), line=no)


def _parse_hierarchy(p, tok: _Tokens):
    """The joints of the HIERARCHY part, read with a stack of open blocks (never by
    recursion, so that a hierarchy of any depth reads)."""
    h = _Hierarchy(p, tok)
    t = tok.peek()
    if t is None or t[0].upper() != "HIERARCHY":
        raise FormatError(p, "'HIERARCHY' first", quote(t[0]) if t else "an empty file",
                          line=t[1] if t else 1)
    tok.take("HIERARCHY")
    while True:
        if not h.stack:
            if not h.root():
                break
            continue
        h.statement(h.stack[-1])
    if not h.names:
        raise FormatError(p, "a ROOT joint after 'HIERARCHY'", "none",
                          line=tok.motion_line or tok.n_lines)
    return h.names, h.parents, h.offsets, h.channels, h.end_site


def _header(p, text: str, pos: int, line: int, key: str) -> tuple[str, int]:
    """The text after ``key`` (e.g. 'Frames:') on the line starting at ``pos`` (line
    number ``line``), and where the next line starts."""
    if pos >= len(text):
        raise FormatError(p, f"a line '{key} ...'", "end of file", line=max(line - 1, 1))
    nl = text.find("\n", pos)
    end = len(text) if nl < 0 else nl
    s = text[pos:end]
    m = re.match(r"\s*" + r"\s*".join(map(re.escape, key.split())) + r"\s*(.*)$", s,
                 re.IGNORECASE)
    if m is None:
        raise FormatError(p, f"a line '{key} ...'", quote(s), line=line)
    return m.group(1).strip(), end + 1


def _chunks(text: str, pos: int):
    """(start, end) of consecutive pieces of ``text[pos:]`` of about ``_CHUNK``
    characters, each ending at a line end (or, in an over-long line, at whitespace), so
    that no number is cut."""
    n = len(text)
    while pos < n:
        end = pos + _CHUNK
        if end >= n:
            yield pos, n
            return
        cut = text.find("\n", end, end + _CHUNK)
        if cut < 0:
            m = re.compile(r"\s").search(text, end)
            cut = n - 1 if m is None else m.start()
        yield pos, cut + 1
        pos = cut + 1


def _line_counts(raw: bytes) -> np.ndarray:
    """Numbers (whitespace-separated words) on each line of ``raw``; the last entry is
    the text after the last line end (empty when ``raw`` ends with one)."""
    a = np.frombuffer(raw, dtype=np.uint8)
    nl = a == 10
    if a.size == 0:
        return np.zeros(1, dtype=np.int64)
    ws = _SPACE[a]
    starts = ~ws & np.concatenate([[True], ws[:-1]])
    line = np.cumsum(nl) - nl
    return np.bincount(line[starts], minlength=int(nl.sum()) + 1)


def _motion_values(p, text: str, raw: bytes, pos: int, first_line: int, n_frames: int,
                   n_ch: int) -> np.ndarray:
    """The (n_frames, n_ch) values of the MOTION block starting at ``pos`` (line
    ``first_line``): counted first, piece by piece, then converted into one array."""
    want = n_frames * n_ch
    pieces = []             # (start, end, first line, numbers)
    total = 0
    bad_line = None         # the first line of neither 0 nor n_ch numbers
    bad_count = 0
    line = first_line
    last_line = first_line - 1
    for s, e in _chunks(text, pos):
        counts = _line_counts(raw[s:e])
        full = counts if not text.endswith("\n", s, e) else counts[:-1]
        if bad_line is None:
            bad = np.flatnonzero((full != n_ch) & (full != 0))
            if bad.size:
                bad_line, bad_count = line + int(bad[0]), int(full[bad[0]])
        m = int(counts.sum())
        pieces.append((s, e, line, m))
        total += m
        last_line = line + full.size - 1
        line += full.size
    n_body = last_line - first_line + 1
    if total != want:
        why = [f"a frame line of {bad_count} values"] if bad_line is not None else []
        if total < want:
            why.insert(0, "a truncated MOTION block")
        found = f"{total} numbers" + (f" ({' or '.join(why)})" if why else "")
        raise FormatError(p, f"{n_frames} frames of {n_ch} values ({want} numbers; "
                             f"'Frames: {n_frames}')", found,
                          line=bad_line if bad_line is not None else max(last_line, 1))
    if n_ch == 0 and n_body < n_frames:
        lines = f"{n_frames} frame line{'s' if n_frames > 1 else ''}"
        raise FormatError(p, f"{lines} ('Frames: {n_frames}'; an empty line a frame, as no "
                             f"joint has a channel)", f"{n_body or 'none'}",
                          line=max(last_line, first_line - 1))
    data = np.empty(want, dtype=np.float64)
    at = 0
    for s, e, line, m in pieces:
        if not m:
            continue
        words = text[s:e].split()
        try:
            v = np.array(words, dtype=np.float64)
        except ValueError:
            v = None
        ok = None if v is None else np.abs(v) <= MAX_VALUE
        if v is None or not ok.all():
            k = next(i for i, w in enumerate(words) if not _finite_value(w)) if v is None \
                else int(np.flatnonzero(~ok)[0])
            where = line + int(np.searchsorted(np.cumsum(_line_counts(raw[s:e])), k,
                                               side="right"))
            raise FormatError(p, f"a number in the MOTION block (finite, of magnitude at "
                                 f"most {MAX_VALUE:g})", quote(words[k]), line=where)
        data[at:at + m] = v
        at += m
    return data.reshape(n_frames, n_ch)


def _finite_value(w: str) -> bool:
    try:
        return abs(float(w)) <= MAX_VALUE
    except ValueError:
        return False


def _limit(name: str, value, default: int) -> int:
    if value is None:
        return default
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ValueError(f"{name} must be a whole number >= 1, got {value!r}")
    return int(value)


def read_bvh(path: str | os.PathLike, *, max_frames: int | None = None,
             max_joint_frames: int | None = None) -> Motion:
    """Read a BVH motion capture file (see the module docs for the quirks accepted and
    the limits).

    Parameters
    ----------
    path : str or os.PathLike
        A ``.bvh`` file.
    max_frames : int, optional
        Most frames to accept; default :data:`MAX_FRAMES` (1 000 000).
    max_joint_frames : int, optional
        Most frames × joints (end sites included) to accept; default
        :data:`MAX_JOINT_FRAMES` (10 000 000, about 1 GB of per-frame transforms).

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
        channel list, a repeated joint name or OFFSET or CHANNELS line), more joints,
        frames or frames × joints than the limits, no MOTION part, a bad ``Frames`` or
        ``Frame Time`` line, a MOTION block whose values do not number ``Frames`` ×
        channels (a truncated file, a frame line with a wrong count), a value that is
        not a finite number of magnitude at most :data:`MAX_VALUE`; the message names
        the file and the line.
    ValueError
        ``max_frames`` or ``max_joint_frames`` is not a whole number >= 1.

    Examples
    --------
    >>> import os, tempfile
    >>> text = \'\'\'HIERARCHY
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
    ... \'\'\'
    >>> path = os.path.join(tempfile.mkdtemp(), "tiny.bvh")
    >>> with open(path, "w") as f:
    ...     _ = f.write(text)
    >>> m = read_bvh(path)
    >>> m, m.names
    (Motion(1 joints + 1 end sites, 2 frames at 2 fps), ['hip', 'hip_end'])
    >>> m.positions()[1].round(6).tolist()   # frame 1: moved by x = 1, turned 90 deg about z
    [[1.0, 0.0, 0.0], [0.0, 0.0, 0.0]]
    """
    max_frames = _limit("max_frames", max_frames, MAX_FRAMES)
    max_joint_frames = _limit("max_joint_frames", max_joint_frames, MAX_JOINT_FRAMES)
    p = input_path(path, "BVH")
    # One line end (LF) for all three; latin-1 never fails to decode and keeps the byte
    # offsets of ``raw`` and ``text`` equal.
    raw = p.read_bytes().replace(b"\r\n", b"\n").replace(b"\r", b"\n")
    if raw.startswith(b"\xef\xbb\xbf"):      # a UTF-8 byte order mark
        raw = raw[3:]
    text = raw.decode("latin-1")
    tok = _Tokens(p, text)
    names, parents, offsets, channels, end_site = _parse_hierarchy(p, tok)
    if tok.motion_line is None:
        raise FormatError(p, "a 'MOTION' line after the hierarchy", "end of file",
                          line=max(tok.n_lines, 1))
    line = tok.motion_line + 1
    pos = tok.motion_end
    blank = _BLANK_LINES.match(text, pos)
    line += text.count("\n", pos, blank.end())
    pos = blank.end()
    frames_text, nxt = _header(p, text, pos, line, "Frames:")
    if not re.fullmatch(r"[0-9]{1,20}", frames_text) or int(frames_text) < 1:
        raise FormatError(p, "'Frames: N' with N a whole number >= 1", quote(text[pos:nxt]),
                          line=line)
    n_frames = int(frames_text)
    j = len(names)
    if n_frames > max_frames:
        raise FormatError(p, f"at most {max_frames} frames (read_bvh's max_frames)",
                          f"'Frames: {n_frames}'", line=line)
    if n_frames * j > max_joint_frames:
        raise FormatError(p, f"at most {max_joint_frames} frames × joints (read_bvh's "
                             f"max_joint_frames)", f"{n_frames} frames × {j} joints",
                          line=line)
    pos, line = nxt, line + 1
    dt_text, nxt = _header(p, text, pos, line, "Frame Time:")
    dt = float(dt_text) if _NUMBER.match(dt_text) else float("nan")
    if not MIN_FRAME_TIME <= dt <= MAX_FRAME_TIME:
        raise FormatError(p, f"'Frame Time: SECONDS' with a number from {MIN_FRAME_TIME:g} "
                             f"to {MAX_FRAME_TIME:g}", quote(text[pos:nxt]), line=line)
    n_ch = sum(len(c) for c in channels)
    data = _motion_values(p, text, raw, nxt, line + 1, n_frames, n_ch)
    del raw, text

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
