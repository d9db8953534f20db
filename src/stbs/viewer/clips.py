"""The viewer server's clip routes: sample a clip, pose the rig at a time, save, export a GIF.

:class:`ViewerServer` answers ``POST /api/clip/sample``, ``POST /api/clip/pose``,
``POST /api/save-clip`` and ``POST /api/export`` with these functions; they check the
request, raise :class:`Refusal` (an HTTP status and one line) for a bad one, and leave
the locking and the token and Host rules to the server. Clips are read by
:func:`stbs.io.read_clip`, so the page plays exactly :meth:`stbs.Clip.pose`.
"""

from __future__ import annotations

import base64
import binascii
import io
import json
import math
import os
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from .. import _optional
from ..clip import Clip
from ..io import atomic_open, pose_to_dict, read_clip, write_clip
from ..pose import Pose
from ..skeleton import Skeleton

__all__ = ["Refusal", "MAX_FRAMES", "MAX_EXPORT_FRAMES", "MAX_EXPORT_PIXELS", "CLIP_NAME",
           "GIF_NAME", "read_request_clip", "sample", "clip_pose", "pose_object",
           "target_in", "save_clip", "export_gif"]

#: Most frames ``/api/clip/sample`` answers (the clip's fps grid, or explicit times).
MAX_FRAMES = 2000
#: Most frames ``/api/export`` takes.
MAX_EXPORT_FRAMES = 600
#: Largest frame ``/api/export`` takes, in pixels (width x height).
MAX_EXPORT_PIXELS = 2048 * 2048
#: A clip file name the client may give ``/api/save-clip``: a bare ``.json`` name.
CLIP_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]{0,99}\.json\Z")
#: A GIF file name the client may give ``/api/export``: a bare ``.gif`` name.
GIF_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]{0,99}\.gif\Z")

_PNG = b"\x89PNG\r\n\x1a\n"


class Refusal(Exception):
    """A request the clip routes refuse: the HTTP status and a one-line message."""

    def __init__(self, status: int, message: str):
        super().__init__(message)
        self.status = int(status)
        self.message = " ".join(str(message).split())


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
    try:
        return read_clip(obj, sk)
    except (ValueError, TypeError) as exc:
        raise Refusal(400, str(exc)) from None


def _bones(pose: Pose) -> dict:
    return {"rotations": pose.rotations.tolist(), "origins": pose.origins.tolist(),
            "stretch": pose.stretch.tolist(), "twist": pose.twist.tolist()}


def sample(obj: Any, sk: Skeleton) -> dict:
    """``POST /api/clip/sample``: a clip (plus optional ``"times"``) -> per-frame bone arrays.

    The body is a clip file's object; an extra key ``"times": [t, ...]`` asks for the
    poses at those times instead of the clip's fps grid (:meth:`stbs.Clip.sample_times`).
    Each frame is the pose's arrays as ``GET /api/pose/bones`` gives them.
    """
    if isinstance(obj, Mapping) and "times" in obj:
        obj = dict(obj)
        given = obj.pop("times")
        if not isinstance(given, list) or not given or len(given) > MAX_FRAMES:
            got = f"{len(given)} times" if isinstance(given, list) else _show(given)
            raise Refusal(400, f'"times": expected a list of 1 to {MAX_FRAMES} times in seconds, '
                               f"found {got}")
        times = [_time(f'"times"[{k}]', t) for k, t in enumerate(given)]
        clip = read_request_clip(obj, sk)
    else:
        clip = read_request_clip(obj, sk)
        try:
            grid = clip.sample_times()
        except ValueError as exc:
            raise Refusal(400, f"clip: {exc}") from None
        if len(grid) > MAX_FRAMES:
            raise Refusal(400, f"clip: {clip.duration:g} s at {clip.fps:g} fps is {len(grid)} "
                               f"frames; at most {MAX_FRAMES} are sampled (lower the fps)")
        times = grid.tolist()
    return {"fps": clip.fps, "interpolation": clip.interpolation, "start": clip.start,
            "end": clip.end, "duration": clip.duration, "keys": clip.times.tolist(),
            "times": times, "frames": [_bones(clip.pose(t)) for t in times]}


def pose_object(pose: Pose) -> tuple[dict, bool]:
    """A pose file object for ``pose`` and whether it gives ``pose`` exactly.

    Between keys a clip's joints may part (origins are interpolated linearly), and
    then neither pose-file form holds the pose; the joints form of its mean joints
    (:meth:`stbs.Pose.joints`) and its twists stands in for it.
    """
    try:
        return pose_to_dict(pose), True
    except ValueError:
        pass
    sk, scale = pose.skeleton, 180.0 / math.pi
    obj: dict = {"joints": pose.joints().tolist()}
    if sk.dim == 3:
        twist = {sk.names[i]: [float(s * scale), float(e * scale)]
                 for i, (s, e) in enumerate(pose.twist.tolist()) if s != 0 or e != 0}
        if twist:
            obj["twist"] = twist
    obj["degrees"] = True
    return obj, False


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
    if os.path.islink(target) or (os.path.lexists(target) and not target.is_file()):
        raise Refusal(403, f"{name!r}: exists and is not a plain file; not replaced")
    if target.exists() and not overwrite:
        raise Refusal(409, f"{name!r} exists in {str(folder)!r}; send \"overwrite\": true to "
                           "replace it")
    return target


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


def save_clip(obj: Any, sk: Skeleton, folder: Path | None, rig_name: str) -> dict:
    """``POST /api/save-clip``: ``{"clip", "name"?, "overwrite"?}`` -> the clip file written.

    Call with the server's lock held (the name is chosen and written in one step).
    """
    obj = _object("request body", obj, ("clip", "name", "overwrite"), ("clip",))
    overwrite = _overwrite(obj)
    clip = read_request_clip(obj["clip"], sk)
    folder = _folder(folder, "clips")
    target = target_in(folder, obj.get("name"), default_stem=f"{rig_name}-clip",
                       pattern=CLIP_NAME, suffix=".json", overwrite=overwrite)
    try:
        write_clip(target, clip)
    except ValueError as exc:      # a key's pose that no pose-file form holds
        raise Refusal(400, str(exc)) from None
    except OSError as exc:
        raise Refusal(500, f"could not write {str(target)!r}: "
                           f"{exc.strerror or exc}") from None
    return {"path": str(target), "name": target.name, "keys": len(clip)}


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
            or not 0 < fps <= 100:
        raise Refusal(400, f'"fps": expected a number in (0, 100] (a GIF delay is at least '
                           f"10 ms), found {_show(fps)}")
    loop = obj.get("loop", True)
    if not isinstance(loop, bool):
        raise Refusal(400, f'"loop": expected true or false, got {_show(loop)}')
    overwrite = _overwrite(obj)
    frames = obj["frames"]
    if not isinstance(frames, list) or not 1 <= len(frames) <= MAX_EXPORT_FRAMES:
        got = f"{len(frames)} frames" if isinstance(frames, list) else _show(frames)
        raise Refusal(400, f'"frames": expected a list of 1 to {MAX_EXPORT_FRAMES} PNG images, '
                           f"found {got}")
    pngs = [_png(f'"frames"[{k}]', x) for k, x in enumerate(frames)]
    folder = _folder(folder, "exports")
    advice = _optional.missing(["PIL"], "exporting a GIF")
    if advice:
        raise Refusal(501, advice)
    from PIL import Image

    images = []
    size = None
    for k, data in enumerate(pngs):
        try:
            im = Image.open(io.BytesIO(data))
            if im.format != "PNG":
                raise ValueError(f"a {im.format} image")
            if im.width * im.height > MAX_EXPORT_PIXELS:
                raise Refusal(400, f'"frames"[{k}]: {im.width} x {im.height} pixels; at most '
                                   f"{MAX_EXPORT_PIXELS} pixels a frame")
            im = im.convert("RGB")
        except Refusal:
            raise
        except Exception as exc:    # Pillow raises many kinds for a broken image
            raise Refusal(400, f'"frames"[{k}]: not a readable PNG image ({exc})') from None
        if size is None:
            size = im.size
        elif im.size != size:
            raise Refusal(400, f'"frames"[{k}]: {im.width} x {im.height} pixels; every frame '
                               f"must have the size of frame 0 ({size[0]} x {size[1]})")
        images.append(im)
    target = target_in(folder, obj.get("name"), default_stem=f"{rig_name}-clip",
                       pattern=GIF_NAME, suffix=".gif", overwrite=overwrite)
    options = {"save_all": True, "append_images": images[1:],
               "duration": max(10, round(1000.0 / fps))}
    if loop:
        options["loop"] = 0          # 0: repeat for ever
    try:
        with atomic_open(target, "wb") as f:
            images[0].save(f, format="GIF", **options)
    except OSError as exc:
        raise Refusal(500, f"could not write {str(target)!r}: {exc.strerror or exc}") from None
    with Image.open(target) as back:
        count = int(getattr(back, "n_frames", 1))
    return {"path": str(target), "name": target.name, "frames": count, "width": size[0],
            "height": size[1], "fps": float(fps)}
