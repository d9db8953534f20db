"""The viewer server's clip routes: clips held by id, their frames, save, export a GIF.

The server holds the clips the page plays (:class:`ClipStore`: the clip it was started
with, and each clip the page built, registered once per edit with ``POST /api/clip``)
and answers their poses at any times from :meth:`stbs.Clip.arrays`, so the page plays
and seeks exactly :meth:`stbs.Clip.pose` (step and cubic channels of a character's
animation included) without sending the clip again. The clip routes
(:mod:`stbs.viewer.routes`) answer with these functions; they check the request, raise
:class:`stbs.viewer.refusal.Refusal` (an HTTP status and one line) for a bad one, and
leave the locking and the token and Host rules to the server.
Clip objects a request sends are read by :func:`stbs.io.read_clip`.

Each request's work is bounded before it is done, and a request over a bound is 413
with a message naming the limit and what arrived: keys (:data:`MAX_KEYS`, and
:data:`MAX_KEY_BONES` keys x bones: reading a key costs forward kinematics over every
bone), sampled frames (:data:`MAX_FRAMES`; :data:`MAX_SAMPLES` frames x bones as JSON,
:data:`MAX_FRAME_SAMPLES` as binary) and exported pixels (:data:`MAX_EXPORT_FRAMES`,
:data:`MAX_EXPORT_PIXELS` a frame, :data:`MAX_EXPORT_TOTAL_PIXELS` in all, read from
each PNG's header before any frame is decoded; frames are then decoded one at a time).
"""

from __future__ import annotations

import base64
import binascii
import io
import json
import math
import os
import re
import secrets
from collections import OrderedDict
from collections.abc import Mapping
from pathlib import Path
from typing import Any
from urllib.parse import parse_qs

import numpy as np

from .. import _optional
from .._inputs import SameFileError, check_output
from ..clip import Clip
from ..io import atomic_open, clip_to_dict, read_clip
from ..pose import Pose
from ..skeleton import Skeleton
from . import bones
from .refusal import Refusal
from .refusal import one_line as _one_line

__all__ = ["Refusal", "ClipStore", "MAX_FRAMES", "MAX_CLIPS", "MAX_KEYS", "MAX_KEY_BONES",
           "MAX_SAMPLES", "MAX_FRAME_SAMPLES", "MAX_EXPORT_FRAMES", "MAX_EXPORT_PIXELS",
           "MAX_EXPORT_TOTAL_PIXELS", "MIN_EXPORT_FPS", "CLIP_NAME", "GIF_NAME", "CLIP_ID",
           "read_request_clip", "summary", "frames", "sample", "clip_pose", "target_in",
           "same_file_message", "save_clip", "export_gif"]

#: Most frames one request answers (``/api/clip/ID/frames``, ``/api/clip/sample``).
MAX_FRAMES = 2000
#: Most keys in a clip a request sends (``POST /api/clip``, ``/api/clip/sample``,
#: ``/api/clip/pose``, ``/api/save-clip``).
MAX_KEYS = 10_000
#: Most keys x bones in a clip a request sends (each key is read with forward
#: kinematics over every bone, posed or not).
MAX_KEY_BONES = 100_000
#: Most frames x bones ``/api/clip/sample`` answers (JSON).
MAX_SAMPLES = 100_000
#: Most frames x bones ``/api/clip/ID/frames`` answers (binary float64: at most
#: 500,000 x 15 x 8 bytes = 60 MB for a 3D rig).
MAX_FRAME_SAMPLES = 500_000
#: Clips the page registered that the server keeps (the least recently used go first;
#: the clip the server was started with is always kept).
MAX_CLIPS = 16
#: A clip id: 16 hex digits.
CLIP_ID = re.compile(r"[0-9a-f]{16}\Z")
#: Most frames ``/api/export`` takes.
MAX_EXPORT_FRAMES = 600
#: Lowest fps ``/api/export`` takes: a GIF frame lasts at most 100 s (its delay is 16 bits
#: of 10 ms).
MIN_EXPORT_FPS = 0.01
#: Largest frame ``/api/export`` takes, in pixels (width x height).
MAX_EXPORT_PIXELS = 2048 * 2048
#: Most pixels ``/api/export`` takes over all its frames (frames x width x height, read
#: from the PNG headers before any frame is decoded): 2**28, e.g. 600 frames of
#: 640 x 360 or 129 of 1920 x 1080. The GIF writer holds every frame at a byte a pixel.
MAX_EXPORT_TOTAL_PIXELS = 2**28
#: A clip file name the client may give ``/api/save-clip``: a bare ``.json`` name.
CLIP_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]{0,99}\.json\Z")
#: A GIF file name the client may give ``/api/export``: a bare ``.gif`` name.
GIF_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]{0,99}\.gif\Z")

_PNG = b"\x89PNG\r\n\x1a\n"


def _show(x: Any) -> str:
    s = json.dumps(x) if isinstance(x, (str, int, float, bool, type(None))) else \
        type(x).__name__
    return s if len(s) <= 80 else s[:77] + "..."


def _object(where: str, obj: Any, keys: tuple[str, ...], need: tuple[str, ...]) -> Mapping:
    if not isinstance(obj, Mapping):
        raise Refusal(400, f"{where}: expected a JSON object with {', '.join(keys)}, found "
                           f"{_show(obj)}")
    extra = sorted(set(obj) - set(keys))
    if extra:
        raise Refusal(400, f"{where}: unexpected key {extra[0]!r}; expected {', '.join(keys)}")
    for k in need:
        if k not in obj:
            raise Refusal(400, f'{where}: missing "{k}"')
    return obj


def _time(where: str, x: Any) -> float:
    if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x):
        raise Refusal(400, f"{where}: expected a finite number of seconds, found {_show(x)}")
    return float(x)


def read_request_clip(obj: Any, sk: Skeleton) -> Clip:
    """The clip a request sends (the clip file's JSON object), read for ``sk``."""
    if not isinstance(obj, Mapping):
        raise Refusal(400, f'clip: expected a JSON object {{"fps", "interpolation", "keys"}} '
                           f"(a clip file), found {_show(obj)}")
    keys = obj.get("keys")
    if isinstance(keys, list):
        k, b = len(keys), sk.n_bones
        if k > MAX_KEYS:
            raise Refusal(413, f'clip: "keys": {k} keys; the limit is {MAX_KEYS} keys a '
                               "request")
        if k * b > MAX_KEY_BONES:
            raise Refusal(413, f'clip: "keys": {k} keys x {b} bones = {k * b} bone poses; the '
                               f"limit is {MAX_KEY_BONES} a request (at most "
                               f"{MAX_KEY_BONES // b} keys for this rig)")
    try:
        return read_clip(obj, sk)
    except (ValueError, TypeError) as exc:
        raise Refusal(400, str(exc)) from None


def sample(obj: Any, sk: Skeleton) -> dict:
    """``POST /api/clip/sample``: a clip (plus optional ``"times"``) -> per-frame bone arrays.

    The whole clip in the request and every frame as JSON: for scripts; the page uses
    the clips the server holds (:func:`frames`).

    The body is a clip file's object; an extra key ``"times": [t, ...]`` asks for the
    poses at those times instead of the clip's fps grid (:meth:`stbs.Clip.sample_times`).
    Each frame is the pose's arrays as ``GET /api/pose/bones`` gives them.
    """
    if isinstance(obj, Mapping) and "times" in obj:
        obj = dict(obj)
        given = obj.pop("times")
        if not isinstance(given, list) or not given:
            raise Refusal(400, f'"times": expected a list of 1 to {MAX_FRAMES} times in seconds, '
                               f"found {_show(given) if given != [] else 'an empty list'}")
        if len(given) > MAX_FRAMES:
            raise Refusal(413, f'"times": {len(given)} times; the limit is {MAX_FRAMES} a '
                               "request")
        _samples("times", len(given), sk.n_bones, MAX_SAMPLES)
        times = [_time(f'"times"[{k}]', t) for k, t in enumerate(given)]
        clip = read_request_clip(obj, sk)
    else:
        clip = read_request_clip(obj, sk)
        try:
            grid = clip.sample_times(limit=MAX_FRAMES)
        except ValueError:
            raise Refusal(413, f"clip: {clip.duration:g} s at {clip.fps:g} fps is "
                               f"{clip.duration * clip.fps + 1:.6g} frames; the limit is "
                               f"{MAX_FRAMES} a request (lower the fps, or send "
                               '"times")') from None
        _samples("clip", len(grid), sk.n_bones, MAX_SAMPLES)
        times = grid.tolist()
    R, O, sigma, theta = clip.arrays(np.asarray(times, dtype=float))
    rows = [{"rotations": R[k].tolist(), "origins": O[k].tolist(),
               "stretch": sigma[k].tolist(), "twist": theta[k].tolist()}
              for k in range(len(times))]
    return {"fps": clip.fps, "interpolation": clip.interpolation, "start": clip.start,
            "end": clip.end, "duration": clip.duration, "keys": clip.times.tolist(),
            "times": times, "frames": rows}


def _samples(where: str, k: int, b: int, limit: int) -> None:
    """Refuse (413) k frames of b bones beyond ``limit`` frames x bones."""
    if k * b > limit:
        raise Refusal(413, f"{where}: {k} frames x {b} bones = {k * b} samples; the limit is "
                           f"{limit} a request (at most {max(1, limit // b)} frames for this "
                           "rig)")


class ClipStore:
    """The clips the viewer plays, held by id (16 hex digits).

    The clip the server was started with (``started``) is kept for good; the page
    registers each clip it builds once per edit (``POST /api/clip``) and the server
    keeps the :data:`MAX_CLIPS` used last of those. Not thread-safe: the server calls
    it under its lock.

    Parameters
    ----------
    sk : Skeleton
        The rig's skeleton; every clip must pose an equal one.
    clip : Clip, optional
        The clip to start with.
    """

    def __init__(self, sk: Skeleton, clip: Clip | None = None):
        self.skeleton = sk
        self._clips: OrderedDict[str, Clip] = OrderedDict()
        self._files: dict[str, dict] = {}
        self.started: str | None = None
        if clip is not None:
            if not isinstance(clip, Clip) or clip.skeleton != sk:
                raise ValueError("clip must be a stbs.Clip of the rig's skeleton")
            self.started = self.add(clip)

    def add(self, clip: Clip) -> str:
        """Hold ``clip``; its new id."""
        cid = secrets.token_hex(8)
        self._clips[cid] = clip
        mine = [k for k in self._clips if k != self.started]
        for k in mine[:max(0, len(mine) - MAX_CLIPS)]:
            del self._clips[k]
            self._files.pop(k, None)
        return cid

    def get(self, cid: str) -> Clip:
        """The clip of id ``cid`` (404 for an unknown or dropped id)."""
        clip = self._clips.get(cid)
        if clip is None:
            raise Refusal(404, f"no clip {cid!r} on this server (the page's clips are kept "
                               f"until {MAX_CLIPS} newer ones replace them): POST /api/clip "
                               "it again")
        self._clips.move_to_end(cid)
        return clip

    def file(self, cid: str) -> dict:
        """The clip file object of clip ``cid`` (made once): its keys' poses."""
        clip = self.get(cid)
        if cid not in self._files:
            self._files[cid] = clip_to_dict(clip)
        return self._files[cid]


def summary(cid: str, clip: Clip) -> dict:
    """What ``GET /api/clip/ID`` answers: the clip's id, rate, interpolation, span, keys."""
    return {"id": cid, "fps": clip.fps, "interpolation": clip.interpolation,
            "start": clip.start, "end": clip.end, "duration": clip.duration,
            "keys": clip.times.tolist(), "bones": clip.skeleton.n_bones,
            "dim": clip.skeleton.dim}


def _times(query: str) -> np.ndarray:
    """The ``t=`` of a frames query: 1 to MAX_FRAMES comma-separated seconds."""
    try:
        fields = parse_qs(query, keep_blank_values=True, strict_parsing=False,
                          max_num_fields=8)
    except ValueError:
        raise Refusal(400, "query: too many fields; expected t=T0,T1,...") from None
    extra = sorted(set(fields) - {"t", "token"})
    if extra:
        raise Refusal(400, f"query: unexpected parameter {extra[0]!r}; expected t=T0,T1,...")
    given = fields.get("t", [])
    if len(given) != 1 or not given[0]:
        raise Refusal(400, f"query: expected t=T0,T1,... once (1 to {MAX_FRAMES} times in "
                           "seconds, comma-separated)")
    parts = given[0].split(",")
    if len(parts) > MAX_FRAMES:
        raise Refusal(413, f"t: {len(parts)} times; at most {MAX_FRAMES} a request")
    out = np.empty(len(parts))
    for k, x in enumerate(parts):
        try:
            out[k] = float(x)
        except ValueError:
            raise Refusal(400, f"t[{k}]: expected a number of seconds, found {_show(x)}") \
                from None
        if not math.isfinite(out[k]):
            raise Refusal(400, f"t[{k}]: expected a finite number of seconds, found "
                               f"{_show(x)}")
    return out


def frames(clip: Clip, query: str) -> np.ndarray:
    """``GET /api/clip/ID/frames?t=T0,T1,...``: the clip's poses at those times, as rows.

    Evaluated in one batch by :meth:`stbs.Clip.arrays`. Returns a (k, b, m) float64
    array, m = d*d + d + 3: per frame, the rows of :mod:`stbs.viewer.bones` (``R_i``
    row-major, ``a'_i``, ``sigma_i``, ``theta_a,i``, ``theta_b,i`` in radians).
    """
    t = _times(query)
    _samples("t", len(t), clip.skeleton.n_bones, MAX_FRAME_SAMPLES)
    return bones.rows(*clip.arrays(t))


def clip_pose_at(clip: Clip, obj: Any) -> tuple[Pose, float]:
    """``POST /api/clip/ID/pose``: ``{"time": t}`` -> (the clip's pose at t, t)."""
    obj = _object("request body", obj, ("time",), ("time",))
    t = _time('"time"', obj["time"])
    return clip.pose(t), t


def clip_pose(obj: Any, sk: Skeleton) -> tuple[Pose, float]:
    """``POST /api/clip/pose``: ``{"clip": CLIP, "time": t}`` -> (the clip's pose at t, t)."""
    obj = _object("request body", obj, ("clip", "time"), ("clip", "time"))
    t = _time('"time"', obj["time"])
    return read_request_clip(obj["clip"], sk).pose(t), t


def target_in(folder: Path, name: Any, *, default_stem: str, pattern: re.Pattern,
              suffix: str, overwrite: bool) -> Path:
    """The file a save writes: ``name`` (a bare file name) or the first free default.

    The default is ``<default_stem>-001<suffix>``, ``-002``, ... An existing file is
    replaced only with ``overwrite``; a link or a folder never.
    """
    if name is None:
        name = next((f"{default_stem}-{k:03d}{suffix}" for k in range(1, 1000)
                     if not os.path.lexists(folder / f"{default_stem}-{k:03d}{suffix}")), None)
        if name is None:
            raise Refusal(409, f"{default_stem}-001{suffix} .. -999{suffix} all exist in "
                               f"{str(folder)!r}; give a name")
    elif not (isinstance(name, str) and pattern.match(name)):
        raise Refusal(400, f'"name": expected a bare file name ending in {suffix} (letters, '
                           f"digits, _ - and dots, no folder), got {json.dumps(name)[:80]}")
    target = folder / name
    try:
        check_output(target)
    except SameFileError:
        raise Refusal(409, same_file_message(name)) from None
    if os.path.islink(target) or (os.path.lexists(target) and not target.is_file()):
        raise Refusal(403, f"{name!r}: exists and is not a plain file; not replaced")
    if target.exists() and not overwrite:
        raise Refusal(409, f"{name!r} exists in {str(folder)!r}; send \"overwrite\": true to "
                           "replace it")
    return target


def same_file_message(name: str) -> str:
    """The refusal of a save over a file the viewer reads (its rig, motion, mapping)."""
    return (f"{name!r} is a file this viewer reads (its rig, motion or mapping): never "
            'written over, even with "overwrite": true; choose another name')


def _overwrite(obj: Mapping) -> bool:
    ow = obj.get("overwrite", False)
    if not isinstance(ow, bool):
        raise Refusal(400, f'"overwrite": expected true or false, got {_show(ow)}')
    return ow


def _folder(folder: Path | None, what: str) -> Path:
    if folder is None:
        raise Refusal(409, f"saving {what} is off: this rig has no folder of its own (start "
                           "stbs view with --save-as PATH)")
    return folder


def save_clip(obj: Any, store: ClipStore, folder: Path | None, rig_name: str) -> dict:
    """``POST /api/save-clip``: ``{"clip" or "id", "fps"?, "name"?, "overwrite"?}`` -> the
    clip file written.

    ``"clip"``: a clip file object; ``"id"``: a clip the server holds (its keys' poses
    written, at ``"fps"`` when given). Call with the server's lock held (the name is
    chosen and written in one step).
    """
    obj = _object("request body", obj, ("clip", "id", "fps", "name", "overwrite"), ())
    if ("clip" in obj) == ("id" in obj):
        raise Refusal(400, 'request body: expected "clip" (a clip file object) or "id" (a '
                           "clip the server holds), one of them")
    overwrite = _overwrite(obj)
    if "clip" in obj:
        if "fps" in obj:
            raise Refusal(400, 'request body: "fps" goes with "id"; a clip object has its own')
        clip = read_request_clip(obj["clip"], store.skeleton)
        body = clip_to_dict(clip)
    else:
        clip = store.get(_clip_id(obj["id"]))
        body = dict(store.file(obj["id"]))
        if "fps" in obj:
            fps = obj["fps"]
            if isinstance(fps, bool) or not isinstance(fps, (int, float)) or \
                    not math.isfinite(fps) or fps <= 0:
                raise Refusal(400, f'"fps": expected a number > 0, found {_show(fps)}')
            body["fps"] = float(fps)
    folder = _folder(folder, "clips")
    target = target_in(folder, obj.get("name"), default_stem=f"{rig_name}-clip",
                       pattern=CLIP_NAME, suffix=".json", overwrite=overwrite)
    try:
        with atomic_open(target, "w") as f:
            f.write(json.dumps(body, indent=1) + "\n")
    except SameFileError:
        raise Refusal(409, same_file_message(target.name)) from None
    except OSError as exc:
        raise Refusal(500, f"could not write {str(target)!r}: "
                           f"{exc.strerror or exc}") from None
    return {"path": str(target), "name": target.name, "keys": len(clip)}


def _clip_id(x: Any) -> str:
    if not (isinstance(x, str) and CLIP_ID.match(x)):
        raise Refusal(400, f'"id": expected a clip id (16 hex digits), found {_show(x)}')
    return x


def _png(where: str, x: Any) -> bytes:
    if not isinstance(x, str):
        raise Refusal(400, f"{where}: expected a PNG image as base64 text (or a data: URL), "
                           f"found {_show(x)}")
    if x.startswith("data:"):
        head, sep, x = x.partition(",")
        if not sep or head != "data:image/png;base64":
            raise Refusal(400, f"{where}: expected a data:image/png;base64 URL, found "
                               f"{head[:40]!r}")
    try:
        data = base64.b64decode(x, validate=True)
    except (binascii.Error, ValueError):
        raise Refusal(400, f"{where}: not valid base64") from None
    if not data.startswith(_PNG):
        raise Refusal(400, f"{where}: expected a PNG image, found {len(data)} bytes that do not "
                           "start with the PNG signature")
    return data


def export_gif(obj: Any, folder: Path | None, rig_name: str) -> dict:
    """``POST /api/export``: frames the page drew -> an animated GIF in the pose folder.

    The body is ``{"frames": [PNG, ...], "fps": 30, "name": "NAME.gif", "format": "gif",
    "loop": true, "overwrite": false}``; each frame a PNG as base64 text or a
    ``data:image/png;base64,`` URL (what ``canvas.toDataURL()`` gives), all of one size.
    Needs Pillow (501 without it). Call with the server's lock held.

    Returns
    -------
    dict
        ``{"path", "name", "frames", "width", "height", "fps"}``; ``frames`` is the
        number of frames in the written file (a GIF merges a frame identical to the
        one before it into that one's delay).
    """
    obj = _object("request body", obj, ("frames", "fps", "name", "format", "loop", "overwrite"),
                  ("frames", "fps"))
    fmt = obj.get("format", "gif")
    if fmt != "gif":
        raise Refusal(400, f'"format": expected "gif" (the only export format), got {_show(fmt)}')
    fps = obj["fps"]
    if isinstance(fps, bool) or not isinstance(fps, (int, float)) or not math.isfinite(fps) \
            or not MIN_EXPORT_FPS <= fps <= 100:
        raise Refusal(400, f'"fps": expected a number in [{MIN_EXPORT_FPS:g}, 100] (a GIF frame '
                           f"lasts 10 ms to 100 s), found {_show(fps)}")
    loop = obj.get("loop", True)
    if not isinstance(loop, bool):
        raise Refusal(400, f'"loop": expected true or false, got {_show(loop)}')
    overwrite = _overwrite(obj)
    frames = obj["frames"]
    if not isinstance(frames, list) or not frames:
        got = "an empty list" if frames == [] else _show(frames)
        raise Refusal(400, f'"frames": expected a list of 1 to {MAX_EXPORT_FRAMES} PNG images, '
                           f"found {got}")
    if len(frames) > MAX_EXPORT_FRAMES:
        raise Refusal(413, f'"frames": {len(frames)} frames; the limit is {MAX_EXPORT_FRAMES} '
                           "frames an export (lower the fps)")
    pngs = [_png(f'"frames"[{k}]', x) for k, x in enumerate(frames)]
    size = _export_size([_png_size(f'"frames"[{k}]', data) for k, data in enumerate(pngs)])
    folder = _folder(folder, "exports")
    advice = _optional.missing(["PIL"], "exporting a GIF")
    if advice:
        raise Refusal(501, advice)
    target = target_in(folder, obj.get("name"), default_stem=f"{rig_name}-clip",
                       pattern=GIF_NAME, suffix=".gif", overwrite=overwrite)
    # Decoded one at a time, as the GIF writer asks for them (it keeps each frame at a
    # byte a pixel, which MAX_EXPORT_TOTAL_PIXELS bounds); a broken frame stops the
    # write and the temporary file is removed.
    first = _decode(0, pngs[0], size)
    rest = (_decode(k, data, size) for k, data in enumerate(pngs[1:], start=1))
    options = {"save_all": True, "append_images": rest,
               "duration": max(10, round(1000.0 / fps))}
    if loop:
        options["loop"] = 0          # 0: repeat for ever
    try:
        with atomic_open(target, "wb") as f:
            first.save(f, format="GIF", **options)
    except SameFileError:
        raise Refusal(409, same_file_message(target.name)) from None
    except OSError as exc:
        raise Refusal(500, f"could not write {str(target)!r}: {exc.strerror or exc}") from None
    from PIL import Image

    with Image.open(target) as back:
        count = int(getattr(back, "n_frames", 1))
    return {"path": str(target), "name": target.name, "frames": count, "width": size[0],
            "height": size[1], "fps": float(fps)}


def _png_size(where: str, data: bytes) -> tuple[int, int]:
    """(width, height) from a PNG's IHDR chunk, which must come first (PNG spec 5.6);
    nothing is decoded."""
    # signature (8 bytes), then the chunk: length 13 (4), "IHDR" (4), width, height (4
    # each, big-endian), ...
    if len(data) < 33 or data[8:16] != b"\0\0\0\x0dIHDR":
        raise Refusal(400, f"{where}: not a readable PNG image (its first chunk is not the "
                           f"13-byte IHDR header; found {len(data)} bytes)")
    w, h = int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")
    if not (w and h):
        raise Refusal(400, f"{where}: not a readable PNG image ({w} x {h} pixels)")
    if w * h > MAX_EXPORT_PIXELS:
        raise Refusal(413, f"{where}: {w} x {h} = {w * h} pixels; the limit is "
                           f"{MAX_EXPORT_PIXELS} pixels a frame")
    return w, h


def _export_size(sizes: list[tuple[int, int]]) -> tuple[int, int]:
    """The one size of every frame, within MAX_EXPORT_TOTAL_PIXELS in all."""
    w, h = sizes[0]
    for k, (wk, hk) in enumerate(sizes):
        if (wk, hk) != (w, h):
            raise Refusal(400, f'"frames"[{k}]: {wk} x {hk} pixels; every frame must have the '
                               f"size of frame 0 ({w} x {h})")
    total = len(sizes) * w * h
    if total > MAX_EXPORT_TOTAL_PIXELS:
        raise Refusal(413, f'"frames": {len(sizes)} frames of {w} x {h} = {total} pixels; the '
                           f"limit is {MAX_EXPORT_TOTAL_PIXELS} pixels an export (at most "
                           f"{MAX_EXPORT_TOTAL_PIXELS // (w * h)} frames of this size)")
    return w, h


def _decode(k: int, data: bytes, size: tuple[int, int]):
    """Frame k as an RGB image of ``size`` (400 for a PNG Pillow cannot read)."""
    from PIL import Image

    try:
        with Image.open(io.BytesIO(data)) as im:
            if im.format != "PNG" or im.size != size:
                raise ValueError(f"a {im.format} image of {im.width} x {im.height} pixels")
            return im.convert("RGB")
    except Exception as exc:    # Pillow raises many kinds for a broken image
        raise Refusal(400, f'"frames"[{k}]: not a readable PNG image ({_one_line(exc)})') \
            from None
