"""Saves of the viewer: a pose file into the pose folder, the rig to its target.

Every save writes a temporary file then renames it (:mod:`stbs.io`'s atomic writers),
under the state's lock and inside :meth:`ViewerState.writing` (so no save writes
over a file the viewer reads, ``"overwrite"`` or not), and never replaces an existing
file unless the request says ``"overwrite": true``. Clip files and GIF exports are
saved by :mod:`stbs.viewer.clips` by the same rules.
"""

from __future__ import annotations

import json
import os
from typing import Any

from .._inputs import SameFileError
from ..io import read_pose, write_pose, write_rig
from ..pose import Pose
from . import clips
from .payload import RigPayload
from .refusal import Refusal, one_line
from .state import ViewerState

__all__ = ["save_pose", "save_rig", "read_request_pose", "POSE_NAME"]

#: A pose file name the client may give ``/api/save-pose``: a bare ``.json`` name.
POSE_NAME = clips.CLIP_NAME


def read_request_pose(obj: Any, state: ViewerState) -> Pose:
    """A pose object (either form of the pose files) read for the rig's skeleton."""
    if not isinstance(obj, dict):
        raise Refusal(400, f"pose: expected a JSON object (a pose in either form of the pose "
                           f"files), found {type(obj).__name__}")
    try:
        return read_pose(obj, state.rig.skeleton)
    except (ValueError, TypeError) as exc:
        raise Refusal(400, one_line(exc)) from None


def _overwrite(x: Any) -> bool:
    if not isinstance(x, bool):
        raise Refusal(400, f'"overwrite": expected true or false, got {x!r}')
    return x


def save_pose(state: ViewerState, obj: Any) -> dict:
    """``POST /api/save-pose``: a pose, or ``{"pose", "name"?, "overwrite"?}`` -> the file
    written, ``{"path", "name"}``."""
    if not isinstance(obj, dict):
        raise Refusal(400, "request body: expected a JSON object (a pose, or "
                           '{"pose": ..., "name": "NAME.json", "overwrite": false})')
    name, overwrite = None, False
    if "pose" in obj:
        extra = sorted(set(obj) - {"pose", "name", "overwrite"})
        if extra:
            raise Refusal(400, f"request body: unexpected key {extra[0]!r}; expected pose, "
                               "name, overwrite")
        name, overwrite = obj.get("name"), _overwrite(obj.get("overwrite", False))
        obj = obj["pose"]
        if name is not None and not (isinstance(name, str) and POSE_NAME.match(name)):
            raise Refusal(400, f'"name": expected a bare file name ending in .json (letters, '
                               f"digits, _ - and dots, no folder), got {json.dumps(name)[:80]}")
    pose = read_request_pose(obj, state)
    if state.pose_folder is None:
        raise Refusal(409, "saving poses is off: this rig has no folder of its own (start "
                           "stbs view with --save-as PATH)")
    with state.writing():
        target = clips.target_in(state.pose_folder, name, default_stem=f"{state.name}-pose",
                                 pattern=POSE_NAME, suffix=".json", overwrite=overwrite)
        try:
            write_pose(target, pose)
        except SameFileError:
            raise Refusal(409, clips.same_file_message(target.name)) from None
        except OSError as exc:
            raise Refusal(500, f"could not write {str(target)!r}: "
                               f"{exc.strerror or one_line(exc)}") from None
    return {"path": str(target), "name": target.name}


def save_rig(state: ViewerState, W=None, E=None, *, overwrite: bool = False) -> dict:
    """``POST /api/save-rig``: write the rig (with new weights when given) to the rig
    target; new weights also become the rig served. 409 when the target exists and
    ``overwrite`` is false. Returns ``{"path", "vertices", "bones", "has_E"}``."""
    target = state.rig_target
    if target is None:
        raise Refusal(409, "saving the rig is off: start stbs view with --save-as PATH")
    from .bodies import with_weights

    with state.writing():
        rig, payload = state.payload.rig, None
        if W is not None or E is not None:
            rig = with_weights(rig, W, E)
            try:
                payload = RigPayload(rig, extras=state.payload.extras)
            except (ValueError, TypeError) as exc:
                raise Refusal(400, one_line(exc)) from None
        if os.path.islink(target) or (os.path.lexists(target) and not target.is_file()):
            raise Refusal(403, f"{target.name!r}: exists and is not a plain file; not "
                               "replaced")
        if target.exists() and not overwrite:
            raise Refusal(409, f"{target.name!r} exists in {str(target.parent)!r}; send "
                               '"overwrite": true (raw weights: the header X-Stbs-Overwrite: '
                               "true) to replace it")
        try:
            write_rig(target, rig, source=state.rig_source)
        except SameFileError:
            raise Refusal(409, clips.same_file_message(target.name)) from None
        except ValueError as exc:   # e.g. no endpoint weights to add to a glTF file
            raise Refusal(409, f"could not write {target.name}: {one_line(exc)}") from None
        except OSError as exc:
            raise Refusal(500, f"could not write {str(target)!r}: "
                               f"{exc.strerror or one_line(exc)}") from None
        if payload is not None:
            state.payload = payload
    return {"path": str(target), "vertices": int(len(rig.V)),
            "bones": int(rig.skeleton.n_bones), "has_E": rig.E is not None}
