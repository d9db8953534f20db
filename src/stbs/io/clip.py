"""Clip files: a :class:`stbs.Clip` (keyed poses, an animation) described in JSON.

A clip file is one JSON object::

    {"fps": 30, "interpolation": "linear",
     "keys": [{"time": 0.0, "pose": {"rotate": {}}},
              {"time": 1.5, "pose": {"stretch": {"neck": 1.6}}}]}

``keys``
    A non-empty list of at most :data:`MAX_KEYS` (100 000; and keys × bones of the
    skeleton at most :data:`MAX_KEY_BONES`, 5 000 000) ``{"time": seconds, "pose":
    POSE}``; the times finite, of magnitude at most :data:`stbs.clip.MAX_TIME` (1e6 s)
    and distinct (any order: they are sorted), each pose in either form of a pose file
    (:mod:`stbs.io.pose`: the joints form or the forward-kinematics form, bones by
    index or name, degrees unless the pose says ``"degrees": false``, numbers within
    the pose files' limits). The forms may be mixed from key to key.
``fps`` (optional, default 30)
    Frames per second of :meth:`stbs.Clip.sample`; a number > 0 and at most
    :data:`MAX_FPS` (1000).
``interpolation`` (optional, default ``"linear"``)
    ``"linear"`` (:meth:`stbs.Pose.interpolate` between keys) or ``"step"`` (each
    key held until the next).

Every other key is an error, and so is a key given twice in one object. A file is
read as JSON of bounded size and nesting with finite numbers. Errors are one
:class:`ValueError` naming the file (or ``clip`` for a dict), the key's index
(``keys[2]``), what was expected and what was found; an invalid pose gives the pose
reader's message behind ``keys[2].pose``.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from .. import _checks
from ..clip import INTERPOLATIONS, MAX_TIME, Clip
from ..skeleton import Skeleton
from .pose import POSE_FORMS, _key, _load, _Reader, _show, pose_to_dict

__all__ = ["read_clip", "write_clip", "clip_to_dict", "CLIP_KEYS", "MAX_KEYS", "MAX_FPS",
           "MAX_KEY_BONES"]

#: Keys of a clip object.
CLIP_KEYS = ("fps", "interpolation", "keys")
#: Most keys in a clip file.
MAX_KEYS = 100_000
#: Largest ``fps`` of a clip file.
MAX_FPS = 1000.0
#: Most keys × bones of the skeleton in a clip file: the clip's arrays take 80 bytes
#: each (400 MB at this limit; reading peaks at about twice that). 100 000 keys of a
#: 50-bone rig, 10 minutes at 120 fps of a 65-bone character.
MAX_KEY_BONES = 5_000_000


def read_clip(path_or_dict: str | os.PathLike | Mapping[str, Any], sk: Skeleton) -> Clip:
    """Read a clip of ``sk`` from a JSON file or an already parsed dict.

    Parameters
    ----------
    path_or_dict : str, os.PathLike or Mapping
        A ``.json`` clip file (any extension is accepted), or the parsed object.
    sk : Skeleton
        The skeleton the clip poses; bone names and indices refer to it.

    Returns
    -------
    Clip

    Raises
    ------
    FileNotFoundError
        The file does not exist.
    ValueError
        The file is not valid JSON or the clip is invalid (see the module docs);
        the message names the file and the key's index.
    TypeError
        ``sk`` is not a :class:`stbs.Skeleton`, or ``path_or_dict`` is neither a
        path nor a mapping.
    """
    _checks.skeleton(sk)
    if isinstance(path_or_dict, Mapping):
        src, obj = "clip", path_or_dict
    elif isinstance(path_or_dict, (str, os.PathLike)):
        src, obj = _load(Path(os.fspath(path_or_dict)), "clip")
    else:
        raise TypeError("path_or_dict must be a path or a dict, got "
                        f"{type(path_or_dict).__name__}")
    return _clip(src, obj, sk)


def _number(src: str, where: str, x: Any, low: float, high: float, what: str) -> float:
    """A number from ``low`` to ``high`` (``low`` excluded when it is 0)."""
    if isinstance(x, bool) or not isinstance(x, (int, float)):
        raise ValueError(f"{src}: {where}: expected {what}, found {_show(x)}")
    # compared before float(): an integer of any length, without OverflowError
    if not (low < x if low == 0 else low <= x) or not x <= high:
        raise ValueError(f"{src}: {where}: expected {what}, found {_show(x)}")
    return float(x)


def _clip(src: str, obj: Any, sk: Skeleton) -> Clip:
    if not isinstance(obj, Mapping):
        raise ValueError(f'{src}: expected a JSON object {{"fps": 30, "interpolation": '
                         f'"linear", "keys": [{{"time": t, "pose": {{...}}}}, ...]}}, found '
                         f"{_show(obj)}")
    unknown = sorted(set(obj) - set(CLIP_KEYS), key=str)
    if unknown:
        raise ValueError(f"{src}: key {_key(unknown[0])}: unknown key; a clip has "
                         f"{', '.join(CLIP_KEYS)}")
    fps = _number(src, '"fps"', obj.get("fps", 30), 0.0, MAX_FPS,
                  f"a finite number > 0 and <= {MAX_FPS:g} (frames a second)")
    interp = obj.get("interpolation", "linear")
    if not isinstance(interp, str) or interp not in INTERPOLATIONS:
        raise ValueError(f'{src}: "interpolation": expected one of '
                         f"{', '.join(json.dumps(s) for s in INTERPOLATIONS)}, found "
                         f"{_show(interp)}")
    if "keys" not in obj:
        raise ValueError(f'{src}: missing "keys": expected a list of {{"time": t, "pose": '
                         f"{{...}}}}")
    keys = obj["keys"]
    if not isinstance(keys, (list, tuple)) or not keys:
        raise ValueError(f'{src}: "keys": expected a non-empty list of {{"time": t, "pose": '
                         f"{{...}}}}, found {_show(keys)}")
    if len(keys) > MAX_KEYS:
        raise ValueError(f'{src}: "keys": expected at most {MAX_KEYS} keys, found '
                         f"{len(keys)}")
    b = sk.n_bones
    if len(keys) * b > MAX_KEY_BONES:
        raise ValueError(f'{src}: "keys": expected at most {MAX_KEY_BONES} keys × bones, '
                         f"found {len(keys)} keys × {b} bones")
    # the keys in the local frame, as the clip holds them, written in place (no pose of
    # its own for each key, rotations made in one batch: a long clip reads quickly)
    reader = _Reader(src, sk)
    Q, sigma, theta, D = reader.defaults(len(keys), quats=True)
    times = np.empty(len(keys))
    seen: dict[float, int] = {}
    for k, key in enumerate(keys):
        where = f"keys[{k}]"
        if not isinstance(key, Mapping):
            raise ValueError(f'{src}: {where}: expected an object {{"time": t, "pose": '
                             f"{{...}}}}, found {_show(key)}")
        extra = sorted(set(key) - {"time", "pose"}, key=str)
        if extra:
            raise ValueError(f"{src}: {where}: unexpected key {_key(extra[0])}; a key has "
                             "time and pose")
        for need in ("time", "pose"):
            if need not in key:
                raise ValueError(f'{src}: {where}: missing "{need}"')
        t = _number(src, f'{where}."time"', key["time"], -MAX_TIME, MAX_TIME,
                    f"a finite number (seconds) of magnitude at most {MAX_TIME:g}")
        if t in seen:
            raise ValueError(f"{src}: {where}: time {t:g} is also the time of "
                             f"keys[{seen[t]}]; key times must be distinct")
        seen[t] = k
        times[k] = t
        reader.src = f"{src}: {where}.pose"
        reader.into(key["pose"], k, sigma, theta, D, Q)
    reader.turn(Q)
    if np.any(np.diff(times) < 0):      # keys in any order: sorted by time
        order = np.argsort(times, kind="stable")
        times, Q, sigma, theta, D = times[order], Q[order], sigma[order], theta[order], D[order]
    return Clip.from_local(sk, times, rotations=Q, stretch=sigma, twist=theta, offsets=D,
                           fps=fps, interpolation=interp)


def clip_to_dict(clip: Clip, *, form: str = "auto", degrees: bool = True) -> dict:
    """The JSON object of a clip file describing ``clip`` (the inverse of :func:`read_clip`).

    Parameters
    ----------
    clip : Clip
    form : {"auto", "fk", "joints"}
        The form of every key's pose, as in :func:`stbs.io.pose_to_dict`.
    degrees : bool
        Angles in degrees or radians.

    Returns
    -------
    dict
        ``{"fps", "interpolation", "keys": [{"time", "pose"}, ...]}``, keys by time.

    Raises
    ------
    ValueError
        A key's pose cannot be written in ``form`` (the message names the key).
    """
    if not isinstance(clip, Clip):
        raise TypeError(f"clip must be a stbs.Clip, got {type(clip).__name__}")
    if form not in POSE_FORMS:
        raise ValueError(f"form must be one of {', '.join(POSE_FORMS)}, got {form!r}")
    keys = []
    for k, (t, pose) in enumerate(clip.keys):
        try:
            obj = pose_to_dict(pose, form=form, degrees=degrees)
        except ValueError as exc:
            raise ValueError(f"clip keys[{k}] (time {t:g}): {exc}") from None
        keys.append({"time": float(t), "pose": obj})
    return {"fps": clip.fps, "interpolation": clip.interpolation, "keys": keys}


def write_clip(path: str | os.PathLike, clip: Clip, *, form: str = "auto",
               degrees: bool = True) -> None:
    """Write ``clip`` as a JSON clip file that :func:`read_clip` reads back (atomically).

    Parameters
    ----------
    path : str or os.PathLike
        Destination file (its folder must exist); written to a temporary file and
        renamed, so a failure leaves an existing file untouched.
    clip : Clip
    form, degrees
        As in :func:`clip_to_dict`.

    Examples
    --------
    >>> import os, tempfile
    >>> import numpy as np
    >>> import stbs
    >>> sk = stbs.Skeleton([[0, 0, 0], [1, 0, 0]], [[0, 1]], names=["arm"])
    >>> twisted = stbs.Pose(sk, rotations=np.eye(3)[None], origins=[[0, 0, 0]],
    ...                     twist=[[0.0, 4 * np.pi]])
    >>> clip = stbs.Clip([(0.0, stbs.Pose.rest(sk)), (2.0, twisted)], fps=24)
    >>> path = os.path.join(tempfile.mkdtemp(), "clip.json")
    >>> stbs.io.write_clip(path, clip)
    >>> back = stbs.io.read_clip(path, sk)
    >>> back.times.tolist(), back.fps, float(np.degrees(back.pose(1.0).twist[0, 1]))
    ([0.0, 2.0], 24.0, 360.0)
    """
    from ._atomic import atomic_open

    text = json.dumps(clip_to_dict(clip, form=form, degrees=degrees), indent=1)
    with atomic_open(path, "w") as f:
        f.write(text + "\n")
