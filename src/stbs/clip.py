"""Clips: keyed poses of one skeleton, interpolated in time (an animation).

A :class:`Clip` holds keys ``(time, Pose)`` sorted by time. Between two keys the
pose is :meth:`stbs.Pose.interpolate` (slerped rotations; linear origins, stretch
and twist, so twists past 360 degrees are kept), or the earlier key held
(``interpolation="step"``). Before the first key and after the last one the clip
holds that key's pose. The JSON clip file is read and written by
:func:`stbs.io.read_clip` and :func:`stbs.io.write_clip`.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Literal

import numpy as np

from .pose import Pose
from .skeleton import Skeleton

__all__ = ["Clip", "INTERPOLATIONS", "MAX_SAMPLES"]

#: Ways to go from one key to the next.
INTERPOLATIONS = ("linear", "step")
#: Most poses :meth:`Clip.sample` makes (a guard against a huge fps or a long clip).
MAX_SAMPLES = 100_000

# A time within this many frames of the grid counts as on it (k / fps in floating point).
_GRID_TOL = 1e-9


def _real(name: str, x, *, positive: bool = False) -> float:
    if isinstance(x, bool) or not isinstance(x, (int, float, np.integer, np.floating)):
        raise TypeError(f"{name} must be a real number, got {type(x).__name__} {x!r}")
    v = float(x)
    if not math.isfinite(v):
        raise ValueError(f"{name} must be finite, got {v}")
    if positive and v <= 0:
        raise ValueError(f"{name} must be > 0, got {v:g}")
    return v


class Clip:
    """Keyed poses of one skeleton.

    Parameters
    ----------
    keys : iterable of (float, Pose)
        At least one ``(time, pose)`` pair; times in seconds, finite and distinct
        (they are sorted); every pose of an equal skeleton (same joints, bones and
        names).
    fps : float, keyword-only
        Frames per second of :meth:`sample` by default (> 0); default 30.
    interpolation : {"linear", "step"}, keyword-only
        ``"linear"``: :meth:`stbs.Pose.interpolate` between neighbouring keys;
        ``"step"``: each key's pose held until the next key.

    Attributes
    ----------
    keys : tuple of (float, Pose)
        Sorted by time.
    times : (k,) float
        The key times, increasing (read-only).
    skeleton : Skeleton
    fps : float
    interpolation : str

    Raises
    ------
    ValueError
        No keys, a non-finite or repeated time, poses of different skeletons, a bad
        ``fps`` or an unknown ``interpolation``.
    TypeError
        A key that is not a ``(time, Pose)`` pair.

    Examples
    --------
    A 2D bone turned from 0 to 90 degrees and stretched from 1 to 2 over one second:

    >>> import numpy as np
    >>> import stbs
    >>> sk = stbs.Skeleton([[0, 0], [1, 0]], [[0, 1]])
    >>> bent = stbs.forward_kinematics(sk, rotations=[np.pi / 2], stretch=[2.0])
    >>> clip = stbs.Clip([(0.0, stbs.Pose.rest(sk)), (1.0, bent)], fps=4)
    >>> mid = clip.pose(0.5)
    >>> float(np.degrees(np.arctan2(mid.rotations[0, 1, 0], mid.rotations[0, 0, 0])))
    45.0
    >>> float(mid.stretch[0])
    1.5
    >>> clip.sample_times().tolist()
    [0.0, 0.25, 0.5, 0.75, 1.0]
    >>> clip.pose(7.0).stretch.tolist()   # after the last key: the last key's pose
    [2.0]
    """

    def __init__(self, keys: Iterable[tuple[float, Pose]], *, fps: float = 30,
                 interpolation: Literal["linear", "step"] = "linear"):
        if isinstance(keys, (str, bytes)) or not isinstance(keys, Iterable):
            raise TypeError(f"keys must be a list of (time, Pose) pairs, got "
                            f"{type(keys).__name__}")
        pairs = []
        for k, key in enumerate(keys):
            if not isinstance(key, (tuple, list)) or len(key) != 2:
                raise TypeError(f"keys[{k}] must be a (time, Pose) pair, got "
                                f"{type(key).__name__}")
            t, pose = key
            t = _real(f"keys[{k}] time", t)
            if not isinstance(pose, Pose):
                raise TypeError(f"keys[{k}] pose must be a stbs.Pose, got "
                                f"{type(pose).__name__}")
            pairs.append((t, k, pose))
        if not pairs:
            raise ValueError("keys must hold at least one (time, Pose) pair, got none")
        sk: Skeleton = pairs[0][2].skeleton
        for _, k, pose in pairs:
            if pose.skeleton != sk:
                raise ValueError(f"keys[{k}] pose is of another skeleton ({pose.skeleton!r}); "
                                 f"every key must pose a skeleton equal to keys[0]'s ({sk!r})")
        pairs.sort(key=lambda p: p[0])
        for (t0, k0, _), (t1, k1, _) in zip(pairs, pairs[1:], strict=False):
            if t1 == t0:
                raise ValueError(f"keys[{k0}] and keys[{k1}] have the same time {t0:g}; key "
                                 "times must be distinct")
        if interpolation not in INTERPOLATIONS:
            raise ValueError(f"interpolation must be one of {', '.join(INTERPOLATIONS)}, got "
                             f"{interpolation!r}")
        self.fps = _real("fps", fps, positive=True)
        self.interpolation = str(interpolation)
        self.skeleton = sk
        self.keys = tuple((t, pose) for t, _, pose in pairs)
        self.times = np.array([t for t, _ in self.keys], dtype=np.float64)
        self.times.setflags(write=False)

    # ------------------------------------------------------------------ time
    @property
    def start(self) -> float:
        """The first key's time (seconds)."""
        return float(self.times[0])

    @property
    def end(self) -> float:
        """The last key's time (seconds)."""
        return float(self.times[-1])

    @property
    def duration(self) -> float:
        """``end - start`` in seconds; 0 for a clip of one key."""
        return self.end - self.start

    def __len__(self) -> int:
        return len(self.keys)

    # ------------------------------------------------------------------ poses
    def pose(self, t: float) -> Pose:
        """The pose at time ``t`` (seconds).

        At a key's time that key's pose; between keys ``i`` and ``i + 1``
        ``keys[i].interpolate(keys[i + 1], (t - t_i) / (t_{i+1} - t_i))`` (linear) or
        ``keys[i]`` (step); before the first key the first pose, after the last key
        the last pose.
        """
        t = _real("t", t)
        T = self.times
        if t <= T[0]:
            return self.keys[0][1]
        if t >= T[-1]:
            return self.keys[-1][1]
        i = int(np.searchsorted(T, t, side="right")) - 1      # T[i] <= t < T[i + 1]
        t0, p0 = self.keys[i]
        t1, p1 = self.keys[i + 1]
        # on a key up to rounding (a grid k / fps against keys at k * dt): that key
        near = 1e-9 * (t1 - t0)
        if t - t0 <= near or self.interpolation == "step":
            return p0
        if t1 - t <= near:
            return p1
        return p0.interpolate(p1, (t - t0) / (t1 - t0))

    def sample_times(self, fps: float | None = None) -> np.ndarray:
        """The times :meth:`sample` poses: ``start + k / fps`` for k = 0, 1, ...

        The grid runs from the first key's time up to the last key's; the last key's
        time is included when it falls on the grid (to 1e-9 of a frame), else the
        grid stops at the last step before it. A clip of one key gives one time.

        Parameters
        ----------
        fps : float, optional
            Frames per second (> 0); default the clip's ``fps``.

        Returns
        -------
        (m,) float
        """
        fps = self.fps if fps is None else _real("fps", fps, positive=True)
        steps = self.duration * fps
        m = int(math.floor(steps + _GRID_TOL)) + 1
        if m > MAX_SAMPLES:
            raise ValueError(f"fps: {fps:g} frames a second over {self.duration:g} s makes "
                             f"{m} poses; at most {MAX_SAMPLES} are sampled")
        return self.start + np.arange(m) / fps

    def sample(self, fps: float | None = None) -> list[Pose]:
        """The poses at :meth:`sample_times` (``fps`` default: the clip's)."""
        return [self.pose(float(t)) for t in self.sample_times(fps)]

    def __repr__(self) -> str:
        return (f"Clip({len(self.keys)} keys, {self.start:g}..{self.end:g} s, fps={self.fps:g}, "
                f"interpolation={self.interpolation!r}, {self.skeleton!r})")
