"""Clips: keyed poses of one skeleton, interpolated in time (an animation).

A :class:`Clip` holds its keys as arrays in the local (forward-kinematics) frame,
as glTF, BVH and USD animation do: at each key time each bone's rotation relative to
the frame its parent carries it in (a unit quaternion), its stretch, its twist at
both ends and its offset from where it hangs (:meth:`stbs.Pose.local`). Between keys
rotations are slerped along the shortest arc and the rest is interpolated linearly
(twists past 360 degrees kept), then forward kinematics builds the pose, so chains
never tear or shrink between keys. ``interpolation="step"`` holds each key instead.
A clip read from glTF may also hold per-bone STEP or cubic (Hermite) channels, so
that it equals the file's node hierarchy at any time. Before the first key and after
the last the clip holds that key's pose. The JSON clip file is read and written by
:func:`stbs.io.read_clip` and :func:`stbs.io.write_clip`.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Literal

import numpy as np

from . import _checks
from . import transforms as tf
from .pose import Pose, fk_arrays, local_arrays
from .skeleton import Skeleton

__all__ = ["Clip", "INTERPOLATIONS", "CHANNEL_INTERPOLATIONS", "MAX_SAMPLES", "MAX_TIME"]

#: Ways to go from one key to the next (the whole clip).
INTERPOLATIONS = ("linear", "step")
#: Ways one bone's rotation or offset channel may go from key to key.
CHANNEL_INTERPOLATIONS = ("linear", "step", "cubic")
#: Most poses :meth:`Clip.sample` makes (a guard against a huge fps or a long clip).
MAX_SAMPLES = 100_000
#: Largest magnitude of a key time, in seconds (about 11.6 days).
MAX_TIME = 1e6

# A time within this many frames of the grid counts as on it (k / fps in floating point).
_GRID_TOL = 1e-9
_MODE = {m: k for k, m in enumerate(CHANNEL_INTERPOLATIONS)}


def _real(name: str, x, *, positive: bool = False, bound: float | None = None) -> float:
    if isinstance(x, bool) or not isinstance(x, (int, float, np.integer, np.floating)):
        raise TypeError(f"{name} must be a real number, got {type(x).__name__} {x!r}")
    try:
        v = float(x)
    except OverflowError:       # a Python int beyond the float range
        raise ValueError(f"{name} must be finite, got an integer of about "
                         f"{int(x.bit_length() * 0.30103) + 1} digits") from None
    if not math.isfinite(v):
        raise ValueError(f"{name} must be finite, got {v}")
    if bound is not None and abs(v) > bound:
        raise ValueError(f"{name} must lie within ±{bound:g}, got {v:.6g}")
    if positive and v <= 0:
        raise ValueError(f"{name} must be > 0, got {v:g}")
    return v


def _to_quats(R: np.ndarray, d: int) -> np.ndarray:
    """(..., d, d) rotations as (..., 4) unit quaternions (2D: about z)."""
    if d == 2:
        half = 0.5 * tf.angle_2d(R)
        q = np.zeros(R.shape[:-2] + (4,))
        q[..., 0], q[..., 3] = np.cos(half), np.sin(half)
        return q
    return tf.matrix_to_quat(R)


def _from_quats(q: np.ndarray, d: int) -> np.ndarray:
    if d == 2:
        return tf.rotation_2d(2.0 * np.arctan2(q[..., 3], q[..., 0]))
    return tf.quat_to_matrix(q)


def _channel_modes(name: str, modes, b: int, default: str) -> np.ndarray:
    if modes is None:
        modes = default
    if isinstance(modes, str):
        modes = [modes] * b
    modes = list(modes)
    if len(modes) != b:
        raise ValueError(f"{name} must be one interpolation or {b} (one per bone), got "
                         f"{len(modes)}")
    bad = [m for m in modes if m not in _MODE]
    if bad:
        raise ValueError(f"{name} must hold {', '.join(CHANNEL_INTERPOLATIONS)}, got {bad[0]!r}")
    return np.array([_MODE[m] for m in modes], dtype=np.int8)


def _hermite(p0, m0, p1, m1, s, dt):
    """Cubic Hermite between p0 and p1 with slopes m0, m1 (per second) over dt."""
    s = s[..., None]
    s2, s3 = s * s, s * s * s
    dt = dt[..., None]
    return ((2 * s3 - 3 * s2 + 1) * p0 + (s3 - 2 * s2 + s) * dt * m0
            + (-2 * s3 + 3 * s2) * p1 + (s3 - s2) * dt * m1)


class Clip:
    """Keyed poses of one skeleton.

    Parameters
    ----------
    keys : iterable of (float, Pose)
        At least one ``(time, pose)`` pair; times in seconds, finite, of magnitude at
        most :data:`MAX_TIME` and distinct (they are sorted); every pose of an equal
        skeleton (same joints, bones and names).
    fps : float, keyword-only
        Frames per second of :meth:`sample` by default (> 0); default 30.
    interpolation : {"linear", "step"}, keyword-only
        ``"linear"``: :meth:`stbs.Pose.interpolate` between neighbouring keys (the
        local-frame interpolation of the module docs); ``"step"``: each key's pose
        held until the next key.

    Keys are converted to the local frame once; :meth:`from_local` makes a clip from
    local-frame arrays directly (per-bone STEP and cubic channels included).

    Attributes
    ----------
    keys : tuple of (float, Pose)
        Sorted by time.
    times : (k,) float
        The key times, increasing (read-only).
    quaternions : (k, b, 4) float
        Local rotations at the keys, unit quaternions ``(w, x, y, z)`` (2D: about z);
        a cubic channel's keys are its Hermite control values, normalised after
        interpolation.
    stretch : (k, b) float
    twist : (k, b, 2) float
        Twist angles at each bone's start and end (radians).
    offsets : (k, b, d) float
        Bone offsets in the local frame (:meth:`stbs.Pose.local`).
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
            t = _real(f"keys[{k}] time", t, bound=MAX_TIME)
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
        poses = [p for _, _, p in pairs]
        R = np.stack([p.rotations for p in poses])
        sigma = np.stack([p.stretch for p in poses])
        theta = np.stack([p.twist for p in poses])
        L, D = local_arrays(sk, R, np.stack([p.origins for p in poses]), sigma, theta)
        self._setup(sk, np.array([t for t, _, _ in pairs]), _to_quats(L, sk.dim), sigma,
                    theta, D, fps=fps, interpolation=interpolation)
        self._key_poses = tuple(poses)

    @classmethod
    def from_local(cls, sk: Skeleton, times, *, rotations=None, stretch=None, twist=None,
                   offsets=None, fps: float = 30,
                   interpolation: Literal["linear", "step"] = "linear",
                   rotation_interpolation=None, offset_interpolation=None,
                   rotation_tangents=None, offset_tangents=None) -> Clip:
        """A clip from keys in the local (forward-kinematics) frame, as arrays.

        Parameters
        ----------
        sk : Skeleton
        times : (k,) float
            Key times in seconds, increasing, of magnitude at most :data:`MAX_TIME`.
        rotations : (k, b, 4) or (k, b, d, d) float, optional
            Local rotations (see :meth:`stbs.Pose.local`) as unit quaternions
            ``(w, x, y, z)`` (2D: about z) or matrices; identity by default. The keys of
            a cubic channel are its Hermite control values, kept as given (non-zero,
            not necessarily unit: the interpolated value is normalised).
        stretch : (k, b) float, optional
            Stretches, default 1.
        twist : (k, b, 2) float, optional
            Twist angles (radians) at each bone's start and end, default 0.
        offsets : (k, b, d) float, optional
            Bone offsets (see :meth:`stbs.Pose.local`), default 0.
        fps : float, keyword-only
            Frames per second of :meth:`sample` by default.
        interpolation : {"linear", "step"}, keyword-only
            The clip's interpolation: of stretch and twist, and of every channel
            not given below.
        rotation_interpolation, offset_interpolation : str or sequence of b str, optional
            Per bone, ``"linear"`` (slerp; lerp for offsets), ``"step"`` or ``"cubic"``
            (cubic Hermite of the quaternion components, then normalised, as glTF's
            CUBICSPLINE; needs the tangents).
        rotation_tangents : pair of (k, b, 4) float, optional
            In- and out-tangents (per second) of the cubic rotation channels.
        offset_tangents : pair of (k, b, d) float, optional
            Likewise for the cubic offset channels.
        """
        if not isinstance(sk, Skeleton):
            raise TypeError(f"sk must be a stbs.Skeleton, got {type(sk).__name__}")
        b, d = sk.n_bones, sk.dim
        times = _checks.real_array("times", times, ndim=1)
        k = times.size
        if k == 0:
            raise ValueError("times must hold at least one key time, got none")
        if np.abs(times).max() > MAX_TIME:
            raise ValueError(f"times must lie within ±{MAX_TIME:g} s, got "
                             f"{times[np.argmax(np.abs(times))]:.6g}")
        if np.any(np.diff(times) <= 0):
            i = int(np.flatnonzero(np.diff(times) <= 0)[0])
            raise ValueError(f"times must increase, got {times[i]:g} then {times[i + 1]:g}")
        if rotations is None:
            q = np.zeros((k, b, 4))
            q[..., 0] = 1.0
        else:
            rot = np.asarray(rotations, dtype=float)
            if rot.shape == (k, b, 4):
                q = _checks.real_array("rotations", rot, shape=(k, b, 4))
                n = np.linalg.norm(q, axis=-1)
                # a cubic channel's keys are Hermite control values, normalised after
                # interpolation as glTF's CUBICSPLINE does (a key inside a glTF piece
                # is off the unit sphere); the others must be unit quaternions
                cubic = _channel_modes("rotation_interpolation", rotation_interpolation,
                                       b, interpolation) == _MODE["cubic"]
                unit = np.broadcast_to(~cubic, n.shape)
                if np.any(np.abs(n[unit] - 1) > 1e-6) or np.any(n <= 1e-12):
                    raise ValueError(f"rotations must be unit quaternions (non-zero for cubic "
                                     f"channels), got norms in [{n.min():.6g}, {n.max():.6g}]")
                q = np.where(unit[..., None], q / n[..., None], q)
            elif rot.shape == (k, b, d, d):
                q = _to_quats(_checks.real_array("rotations", rot, shape=(k, b, d, d)), d)
            else:
                raise ValueError(f"rotations must have shape ({k}, {b}, 4) or ({k}, {b}, {d}, "
                                 f"{d}), got {rot.shape}")
        sigma = np.ones((k, b)) if stretch is None else _checks.real_array(
            "stretch", stretch, shape=(k, b))
        if np.any(sigma <= 0):
            raise ValueError(f"stretch must be > 0, got {sigma.min():.6g}")
        theta = np.zeros((k, b, 2)) if twist is None else _checks.real_array(
            "twist", twist, shape=(k, b, 2))
        if d == 2 and np.any(theta != 0):
            raise ValueError("twist must be 0 in 2D")
        D = np.zeros((k, b, d)) if offsets is None else _checks.real_array(
            "offsets", offsets, shape=(k, b, d))
        clip = cls.__new__(cls)
        clip._setup(sk, times, q, sigma, theta, D, fps=fps, interpolation=interpolation,
                    rmode=rotation_interpolation, dmode=offset_interpolation,
                    rtan=rotation_tangents, dtan=offset_tangents)
        clip._key_poses = None
        return clip

    def _setup(self, sk, times, q, sigma, theta, D, *, fps, interpolation, rmode=None,
               dmode=None, rtan=None, dtan=None) -> None:
        if interpolation not in INTERPOLATIONS:
            raise ValueError(f"interpolation must be one of {', '.join(INTERPOLATIONS)}, got "
                             f"{interpolation!r}")
        self.fps = _real("fps", fps, positive=True)
        self.interpolation = str(interpolation)
        self.skeleton = sk
        b, d = sk.n_bones, sk.dim
        k = len(times)
        self._rmode = _channel_modes("rotation_interpolation", rmode, b, interpolation)
        self._dmode = _channel_modes("offset_interpolation", dmode, b, interpolation)
        self._rtan = self._dtan = None
        for name, modes, tan, m in (("rotation_tangents", self._rmode, rtan, 4),
                                    ("offset_tangents", self._dmode, dtan, d)):
            if tan is None:
                if np.any(modes == _MODE["cubic"]):
                    raise ValueError(f"{name} must be given for cubic channels")
                continue
            if not isinstance(tan, (tuple, list)) or len(tan) != 2:
                raise ValueError(f"{name} must be an (in, out) pair of ({k}, {b}, {m}) arrays")
            pair = tuple(_checks.real_array(name, x, shape=(k, b, m)) for x in tan)
            if name == "rotation_tangents":
                self._rtan = pair
            else:
                self._dtan = pair
        self.times = np.asarray(times, dtype=np.float64).copy()
        # keys of the linear rotation channels in one hemisphere with their predecessor,
        # so slerp between neighbours takes the shortest arc
        q = np.array(q, dtype=float)
        if k > 1:
            # key i is flipped when its dot with key i-1, as flipped, is negative: the
            # flips multiply along the keys (a parity of negative dots), starting afresh
            # (unflipped) after a dot of exactly 0; vectorised, as a clip may hold 100 000
            # keys
            dots = np.sum(q[1:] * q[:-1], axis=-1)                     # (k-1, b)
            neg = np.cumsum(dots < 0, axis=0)
            base = np.maximum.accumulate(np.where(dots == 0, neg, 0), axis=0)
            flip = ((neg - base) % 2 == 1) & (self._rmode != _MODE["cubic"])
            q[1:][flip] *= -1
        self.quaternions, self.stretch, self.twist, self.offsets = q, sigma, theta, D
        for a in (self.times, self.quaternions, self.stretch, self.twist, self.offsets):
            a.setflags(write=False)

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

    @property
    def keys(self) -> tuple[tuple[float, Pose], ...]:
        """The keys as ``(time, Pose)`` pairs, sorted by time."""
        if self._key_poses is None:
            self._key_poses = tuple(self.poses(self.times))
        return tuple(zip(self.times.tolist(), self._key_poses, strict=True))

    def __len__(self) -> int:
        return int(self.times.size)

    @property
    def rotation_interpolation(self) -> list[str]:
        """Each bone's rotation channel: ``"linear"``, ``"step"`` or ``"cubic"``."""
        return [CHANNEL_INTERPOLATIONS[m] for m in self._rmode]

    @property
    def offset_interpolation(self) -> list[str]:
        """Each bone's offset channel: ``"linear"``, ``"step"`` or ``"cubic"``."""
        return [CHANNEL_INTERPOLATIONS[m] for m in self._dmode]

    @property
    def rotation_tangents(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(in, out) tangents (k, b, 4) of the cubic rotation channels, or None."""
        return self._rtan

    @property
    def offset_tangents(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(in, out) tangents (k, b, d) of the cubic offset channels, or None."""
        return self._dtan

    # ------------------------------------------------------------------ poses
    def local(self, t) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The local-frame arrays at times ``t`` (any shape ``s``), vectorised.

        Returns
        -------
        rotations : s + (b, d, d); stretch : s + (b,); twist : s + (b, 2);
        offsets : s + (b, d)
        """
        t = np.asarray(t, dtype=float)
        if not np.all(np.isfinite(t)):
            raise ValueError("t must be finite")
        T = self.times
        K = T.size
        if K == 1:
            i = np.zeros(t.shape, dtype=np.int64)
            s = np.zeros(t.shape)
            dt = np.ones(t.shape)
        else:
            i = np.clip(np.searchsorted(T, t, side="right") - 1, 0, K - 2)
            dt = T[i + 1] - T[i]
            # far outside a very short piece the ratio may overflow: it is clipped to 1
            with np.errstate(over="ignore"):
                s = np.clip((t - T[i]) / dt, 0.0, 1.0)
            # on a key up to rounding (a grid k / fps against keys at k * dt): that key
            s = np.where(s <= 1e-9, 0.0, np.where(s >= 1 - 1e-9, 1.0, s))
        j = np.minimum(i + 1, K - 1)
        step = self.interpolation == "step"
        sl = np.zeros_like(s) if step else s
        q0, q1 = self.quaternions[i], self.quaternions[j]
        q = tf.quat_slerp(q0, q1, np.broadcast_to(s[..., None], q0.shape[:-1]))
        rm = self._rmode
        if np.any(rm == _MODE["step"]):
            q[..., rm == _MODE["step"], :] = np.where(s[..., None, None] >= 1.0,
                                                      q1, q0)[..., rm == _MODE["step"], :]
        if np.any(rm == _MODE["cubic"]):
            c = rm == _MODE["cubic"]
            h = _hermite(q0[..., c, :], self._rtan[1][i][..., c, :], q1[..., c, :],
                         self._rtan[0][j][..., c, :], s[..., None], dt[..., None])
            q[..., c, :] = h / np.linalg.norm(h, axis=-1, keepdims=True)
        D0, D1 = self.offsets[i], self.offsets[j]
        D = D0 + s[..., None, None] * (D1 - D0)
        dm = self._dmode
        if np.any(dm == _MODE["step"]):
            D[..., dm == _MODE["step"], :] = np.where(s[..., None, None] >= 1.0,
                                                      D1, D0)[..., dm == _MODE["step"], :]
        if np.any(dm == _MODE["cubic"]):
            c = dm == _MODE["cubic"]
            D[..., c, :] = _hermite(D0[..., c, :], self._dtan[1][i][..., c, :], D1[..., c, :],
                                    self._dtan[0][j][..., c, :], s[..., None], dt[..., None])
        w = np.where(step, np.where(s >= 1.0, 1.0, 0.0), sl)
        sigma = self.stretch[i] + w[..., None] * (self.stretch[j] - self.stretch[i])
        theta = self.twist[i] + w[..., None, None] * (self.twist[j] - self.twist[i])
        return _from_quats(q, self.skeleton.dim), sigma, theta, D

    def arrays(self, t) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The poses at times ``t`` (any shape ``s``) as arrays, vectorised.

        Returns
        -------
        rotations : s + (b, d, d)
            World rotations ``R_i``.
        origins : s + (b, d)
            Posed starts ``a'_i``.
        stretch : s + (b,)
        twist : s + (b, 2)
        """
        L, sigma, theta, D = self.local(t)
        R, O = fk_arrays(self.skeleton, L, sigma, theta, D)
        return R, O, sigma, theta

    def poses(self, t) -> list[Pose]:
        """The poses at the times ``t`` (a 1-D array), evaluated in one batch."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        if t.ndim != 1:
            raise ValueError(f"t must be a 1-D array of times, got shape {t.shape}")
        R, O, sigma, theta = self.arrays(t)
        sk = self.skeleton
        return [Pose(sk, rotations=R[k], origins=O[k], stretch=sigma[k], twist=theta[k])
                for k in range(t.size)]

    def pose(self, t: float) -> Pose:
        """The pose at time ``t`` (seconds).

        At a key's time that key's pose; between keys the local-frame interpolation
        of the module docs (``"step"``: the earlier key held); before the first key
        the first pose, after the last key the last pose. For many times at once use
        :meth:`poses` or :meth:`arrays`.
        """
        t = _real("t", t)
        if self._key_poses is not None:
            T = self.times
            if t <= T[0]:
                return self._key_poses[0]
            if t >= T[-1]:
                return self._key_poses[-1]
            i = int(np.searchsorted(T, t, side="right")) - 1
            near = 1e-9 * (T[i + 1] - T[i])
            if t - T[i] <= near or self.interpolation == "step":
                return self._key_poses[i]
            if T[i + 1] - t <= near:
                return self._key_poses[i + 1]
        return self.poses([t])[0]

    def sample_times(self, fps: float | None = None, *, limit: int | None = None
                     ) -> np.ndarray:
        """The times :meth:`sample` poses: ``start + k / fps`` for k = 0, 1, ...

        The grid runs from the first key's time up to the last key's; the last key's
        time is included when it falls on the grid (to 1e-9 of a frame), else the
        grid stops at the last step before it. A clip of one key gives one time.

        Parameters
        ----------
        fps : float, optional
            Frames per second (> 0); default the clip's ``fps``.
        limit : int, optional
            Most times made (default :data:`MAX_SAMPLES`); more is an error, raised
            before anything is allocated.

        Returns
        -------
        (m,) float
        """
        fps = self.fps if fps is None else _real("fps", fps, positive=True)
        limit = MAX_SAMPLES if limit is None else int(limit)
        steps = self.duration * fps
        if not math.isfinite(steps) or steps + _GRID_TOL >= limit:
            raise ValueError(f"fps: {fps:g} frames a second over {self.duration:g} s makes "
                             f"{steps + 1:.0f} poses; at most {limit} are sampled")
        m = int(math.floor(steps + _GRID_TOL)) + 1
        return self.start + np.arange(m) / fps

    def sample(self, fps: float | None = None) -> list[Pose]:
        """The poses at :meth:`sample_times` (``fps`` default: the clip's)."""
        return self.poses(self.sample_times(fps))

    def __repr__(self) -> str:
        return (f"Clip({len(self)} keys, {self.start:g}..{self.end:g} s, fps={self.fps:g}, "
                f"interpolation={self.interpolation!r}, {self.skeleton!r})")
