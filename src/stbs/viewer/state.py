"""What one viewer server holds: the rig and its payload, the current pose, the clips.

:class:`ViewerState` is the server's one piece of mutable state. The routes
(:mod:`stbs.viewer.routes`) read and change it only through its methods, each of
which takes its lock for as long as it touches what it holds; the HTTP handler never
sees it.
"""

from __future__ import annotations

import contextlib
import os
import threading
from pathlib import Path

from .._inputs import note_input, tracking
from ..clip import Clip
from ..io import pose_to_dict
from ..pose import Pose
from ..rig import Rig
from . import clips
from .payload import RigPayload
from .refusal import Refusal

__all__ = ["ViewerState", "RIG_TARGETS", "same_file"]

#: Rig files the page's rig may be saved as.
RIG_TARGETS = (".npz", ".glb", ".gltf")


def same_file(a: Path, b: Path) -> bool:
    """Whether two paths name one file (the same real path, or a hard link)."""
    if os.path.realpath(a) == os.path.realpath(b):
        return True
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


class ViewerState:
    """The rig served, its payload, the current pose, the clips and the capture.

    Parameters
    ----------
    rig : Rig
        Checked as :class:`stbs.viewer.payload.RigPayload` checks it.
    extras : mapping, optional
        Further arrays for the payload.
    name : str
        The rig's name (default file names).
    rig_target, rig_source, pose_folder : Path or None
        Where the rig is saved, the glTF file it came from, the folder of pose, clip
        and GIF files (see :class:`stbs.viewer.ViewerServer`).
    inputs : iterable of paths
        Files the server reads, which no save writes over.
    clip : Clip, optional
        The capture: the clip the server was started with, kept for good.

    Raises
    ------
    ValueError
        A bad target or folder, a clip of another skeleton, weights the viewer
        cannot use.
    """

    def __init__(self, rig: Rig, *, extras=None, name: str = "rig", rig_target=None,
                 rig_source=None, pose_folder=None, inputs=(), clip: Clip | None = None):
        self.payload = RigPayload(rig, extras=extras)
        self.name = str(name)
        self.rig_target = None if rig_target is None else Path(rig_target)
        if self.rig_target is not None and (self.rig_target.suffix.lower() not in RIG_TARGETS
                                            or not self.rig_target.parent.is_dir()):
            raise ValueError(f"rig_target must be a {', '.join(RIG_TARGETS)} file in an "
                             f"existing folder, got {str(self.rig_target)!r}")
        self.rig_source = None if rig_source is None else Path(rig_source)
        self.inputs = _paths(inputs)
        if self.rig_source is not None:
            self.inputs.insert(0, self.rig_source)
        if self.rig_target is not None:
            same = next((p for p in self.inputs if same_file(p, self.rig_target)), None)
            if same is not None:
                raise ValueError(f"rig_target {str(self.rig_target)!r} is a file this viewer "
                                 f"reads ({str(same)!r}); choose another path")
        self.pose_folder = None if pose_folder is None else Path(pose_folder)
        if self.pose_folder is not None and not self.pose_folder.is_dir():
            raise ValueError(f"pose_folder must be an existing folder, got "
                             f"{str(self.pose_folder)!r}")
        self.clips = clips.ClipStore(rig.skeleton, clip)
        self.lock = threading.Lock()
        self._pose = Pose.rest(rig.skeleton)
        self._pose_obj: dict | None = None

    # ------------------------------------------------------------------ the rig
    @property
    def rig(self) -> Rig:
        """The rig served now (replaced by a save with new weights)."""
        return self.payload.rig

    @property
    def capture(self) -> str | None:
        """The id of the clip the server was started with, or None."""
        return self.clips.started

    def info(self) -> dict:
        """``GET /api/rig``: the payload's summary, the name, which saves are on, the
        capture, and the endpoint methods this rig can compute."""
        from .jobs import endpoint_methods

        info = self.payload.info()
        info.update(name=self.name, save={"rig": self.rig_target is not None,
                                          "pose": self.pose_folder is not None},
                    clip=self.capture is not None, endpoint_methods=endpoint_methods(self.rig))
        return info

    # ------------------------------------------------------------------ the pose
    @property
    def pose(self) -> Pose:
        """The current pose."""
        with self.lock:
            return self._pose

    def set_pose(self, pose: Pose) -> None:
        """Make ``pose`` (of the rig's skeleton, checked by the caller) the current pose.
        Its pose file object is made only when asked for (:meth:`pose_object`), so a
        seek costs the clip's evaluation and nothing more."""
        with self.lock:
            self._pose = pose
            self._pose_obj = None

    def pose_object(self) -> dict:
        """The current pose as pose JSON (:func:`stbs.io.pose_to_dict`), made once."""
        with self.lock:
            if self._pose_obj is None:
                self._pose_obj = pose_to_dict(self._pose)
            return dict(self._pose_obj)

    # ------------------------------------------------------------------ clips
    def add_clip(self, clip: Clip) -> dict:
        """Hold ``clip``; its summary with its new id."""
        with self.lock:
            return clips.summary(self.clips.add(clip), clip)

    def clip(self, cid: str) -> Clip:
        """The clip of id ``cid`` (404 for an unknown or dropped id)."""
        with self.lock:
            return self.clips.get(cid)

    def clip_summary(self, cid: str | None = None) -> dict:
        """The summary of clip ``cid``; None: of the capture (404 without one)."""
        with self.lock:
            if cid is None:
                cid = self.capture
                if cid is None:
                    raise Refusal(404, "/api/clip: this viewer was started without a clip "
                                       "(stbs view RIG --motion FILE)")
            return clips.summary(cid, self.clips.get(cid))

    def clip_file(self, cid: str) -> dict:
        """The clip file object of clip ``cid``."""
        with self.lock:
            return self.clips.file(cid)

    # ------------------------------------------------------------------ saves
    @contextlib.contextmanager
    def writing(self):
        """Hold the lock and run inside :func:`stbs._inputs.tracking` with this server's
        inputs noted, so the atomic writers refuse to write over one of them (and over
        a file the writer itself reads, such as a glTF ``rig_source``'s buffers).

        Per save rather than for the server's whole life: a run tracked for its life
        would also record every file the rest of the process reads meanwhile (a script
        loading the rig the page just saved), and refuse the next save over it.
        """
        with self.lock, tracking():
            for p in self.inputs:
                note_input(p)
            yield


def _paths(inputs) -> list[Path]:
    if isinstance(inputs, (str, os.PathLike)):
        inputs = [inputs]
    try:
        return [Path(os.fspath(p)) for p in inputs]
    except TypeError:
        raise ValueError(f"inputs must be paths (str or os.PathLike), got "
                         f"{inputs!r}") from None
