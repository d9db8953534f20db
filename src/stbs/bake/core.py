"""Baking an animation: a rig and a motion in, one deformed mesh per frame out.

The rig's :class:`stbs.Deformer` is built once, so each frame costs the skinning only;
the frames are written as one ``.npz`` (``U`` (k, n, d) float32), a folder of meshes,
or a ``.glb``/``.gltf`` whose morph targets play them in any glTF viewer. Baking lives
here alone: the file writers of :mod:`stbs.io` take frames already computed
(:func:`bake_frames`), and :func:`export` writes a rig with its clip baked.
"""

from __future__ import annotations

import os
import re
import shutil
import tempfile
import time
import zipfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._optional import require
from ..clip import MAX_SAMPLES, Clip
from ..io import (
    GLTF_EXTENSIONS,
    USD_EXTENSIONS,
    atomic_open,
    read_bvh,
    read_clip,
    read_fbx,
    read_gltf,
    write_gltf,
    write_mesh,
    write_usd,
)
from ..methods import SKINNING_METHODS as METHODS
from ..retargeting import retarget
from ..rig import Rig
from ..skinning import Deformer

__all__ = ["load_motion", "frame_times", "frame_limit", "MAX_BAKE_BYTES", "MAX_BAKE_FRAMES",
           "clip_frames",
           "bake", "bake_frames", "export", "Baked", "MOTION_EXTENSIONS",
           "MESH_FOLDER_FORMATS", "write_frames", "output_kind"]

MOTION_EXTENSIONS = (".bvh", ".gltf", ".glb", ".fbx", ".json")
MESH_FOLDER_FORMATS = (".obj", ".ply", ".off")


def load_motion(path: str | os.PathLike, rig: Rig, *, mapping=None, twist: str = "spread",
                stretch: str = "keep", animation: str | None = None) -> Clip:
    """A motion file as a clip of the rig's skeleton.

    ``.json``: a clip file (:func:`stbs.io.read_clip`). ``.bvh``: retargeted onto the rig
    (:func:`stbs.retarget` with ``mapping``, ``twist``, ``stretch``). ``.gltf``/``.glb``:
    an animation of that file (``animation`` by name; default the first), whose
    skeleton must be the rig's (e.g. the character's own file). ``.fbx``: likewise an
    animation stack, by default the first that moves (Mixamo files open with a
    motionless "Take 001").
    """
    p = Path(os.fspath(path))
    ext = p.suffix.lower()
    if ext not in MOTION_EXTENSIONS:
        raise ValueError(f"motion {str(p)!r}: expected one of {', '.join(MOTION_EXTENSIONS)}")
    if ext == ".json":
        return read_clip(p, rig.skeleton)
    if ext == ".bvh":
        return retarget(read_bvh(p), rig, mapping=mapping, twist=twist, stretch=stretch)
    _, clips = read_fbx(p) if ext == ".fbx" else read_gltf(p, **_gltf_selection(rig, p))
    if not clips:
        raise ValueError(f"motion {str(p)!r}: the file has no animation")
    if animation is None:
        clip = next(iter(clips.values()))
        if ext == ".fbx":
            clip = next((c for c in clips.values() if _moves(c)), clip)
    elif animation in clips:
        clip = clips[animation]
    else:
        raise ValueError(f"motion {str(p)!r}: no animation {animation!r}; it has "
                         f"{', '.join(map(repr, clips))}")
    if clip.skeleton != rig.skeleton:
        raise ValueError(f"motion {str(p)!r}: its skeleton ({clip.skeleton!r}) is not the "
                         f"rig's ({rig.skeleton!r}); bake a glTF or FBX character with its "
                         f"own animations, or give a .bvh or a clip .json")
    return clip


def _gltf_selection(rig: Rig, p: Path) -> dict:
    """The skin=/mesh=/rigid= the rig was read with, when the motion is the rig's own
    file (the rigid parts shape the leaf bones, so the clips' skeleton is the rig's)."""
    info = (rig.meta or {}).get("gltf")
    if not isinstance(info, dict) or info.get("file") != p.name:
        return {}
    sel = dict(info.get("select") or {})
    if "rigid" not in info:
        sel["rigid"] = False            # read by an stbs that read skinned meshes only
    return {k: v for k, v in sel.items() if k in ("skin", "mesh", "rigid") and v is not None}


def _moves(clip: Clip) -> bool:
    """Whether the clip's keys differ (beyond rounding) from its first."""
    size = float(np.ptp(clip.skeleton.C, axis=0).max()) or 1.0
    return len(clip.times) > 1 and bool(
        np.ptp(clip.quaternions, axis=0).max() > 1e-9
        or np.ptp(clip.offsets, axis=0).max() > 1e-9 * size
        or np.ptp(clip.stretch, axis=0).max() > 1e-9
        or np.ptp(clip.twist, axis=0).max() > 1e-9)


_SLICE = re.compile(r"^\s*(-?\d*)\s*(?::\s*(-?\d*)\s*(?::\s*(-?\d*)\s*)?)?$")


#: Poses evaluated in one vectorised call while baking.
_POSE_BATCH = 256
#: Most frames one bake makes unless a frame limit is given (``--max-frames``): 20 minutes
#: at 30 fps, 5 at 120 fps; a longer take is baked in parts with ``--frames A:B``.
MAX_BAKE_FRAMES = 36_000
#: Baked frames held in memory at once (float32 x, y, z of every vertex in every frame)
#: may take at most this many bytes unless a frame limit is given (``--max-frames``).
MAX_BAKE_BYTES = 2 * 2**30


def frame_limit(n_vertices: int, max_frames: int | None = None) -> int:
    """The most frames :func:`bake` makes of a rig of ``n_vertices``: ``max_frames`` when
    given, else as many as fit in :data:`MAX_BAKE_BYTES`, at most
    :data:`MAX_BAKE_FRAMES`."""
    if max_frames is not None:
        if isinstance(max_frames, bool) or not isinstance(max_frames, (int, np.integer)) \
                or max_frames < 1:
            raise ValueError(f"max_frames: expected an integer >= 1, got {max_frames!r}")
        return int(max_frames)
    return int(max(1, min(MAX_BAKE_FRAMES, MAX_BAKE_BYTES // (12 * max(int(n_vertices), 1)))))


def frame_times(clip: Clip, *, fps: float | None = None, frames: str | None = None,
                limit: int | None = None, n_vertices: int | None = None) -> np.ndarray:
    """The times to bake: the clip sampled at ``fps`` (default its own), then the
    frames ``"A:B:STEP"`` of that grid (Python slice rules, ``"A"`` alone is one frame).

    ``limit`` is the most frames selected (default :data:`stbs.clip.MAX_SAMPLES`);
    more is a ValueError before anything is baked, naming ``n_vertices`` when given.
    """
    cap = MAX_SAMPLES if limit is None else int(limit)
    times = clip.sample_times(fps, limit=max(cap, MAX_SAMPLES))
    if frames is not None:
        times = _select(times, frames)
    if len(times) > cap:
        size = (f" of {n_vertices} vertices ({len(times) * 12 * n_vertices / 2**30:.1f} GiB "
                "in memory)" if n_vertices else "")
        raise ValueError(f"{len(times)} frames to bake{size}; at most {cap} are baked "
                         f"at once: bake fewer with --frames A:B:STEP or a lower --fps, or "
                         f"raise the limit with --max-frames N (max_frames=N)")
    return times


def _select(times: np.ndarray, frames: str) -> np.ndarray:
    """The frames ``"A:B:STEP"`` of the grid ``times``."""
    m = _SLICE.match(str(frames))
    if m is None or not any(m.groups()):
        raise ValueError(f"frames must look like A:B:STEP (e.g. 0:100:2), got {frames!r}")
    a, b, c = (int(g) if g not in (None, "") else None for g in m.groups())
    if ":" not in str(frames):
        if not -len(times) <= a < len(times):
            raise ValueError(f"frames: frame {a} is outside the clip's {len(times)} frames")
        return times[[a]]
    if c == 0:
        raise ValueError("frames: STEP must not be 0")
    out = times[slice(a, b, c)]
    if out.size == 0:
        raise ValueError(f"frames {frames!r} selects none of the clip's {len(times)} frames")
    return out


def clip_frames(clip: Clip, *, fps: float | None = None, frames: str | None = None) -> Clip:
    """The clip keyed at the frames :func:`bake` would bake (``fps``, ``frames`` as in
    :func:`frame_times`), interpolated as the clip plays; the clip itself when neither
    is given."""
    if fps is None and frames is None:
        return clip
    times = frame_times(clip, fps=fps, frames=frames)
    L, sigma, theta, D = clip.local(times)
    return Clip.from_local(clip.skeleton, times, rotations=L, stretch=sigma, twist=theta,
                           offsets=D, fps=clip.fps if fps is None else fps)


def output_kind(out: str | os.PathLike) -> str:
    """``"npz"``, ``"gltf"`` or ``"folder:.obj"`` (``.ply``, ``.off``) for an output path:
    a folder is a path ending in ``/``, an existing folder, or a name without extension
    (then ``.obj`` meshes)."""
    s = os.fspath(out)
    p = Path(s)
    ext = p.suffix.lower()
    if s.endswith(("/", os.sep)) or p.is_dir() or ext == "":
        return "folder:.obj"
    if ext == ".npz":
        return "npz"
    if ext in (".glb", ".gltf"):
        return "gltf"
    raise ValueError(f"output {s!r}: expected .npz, .glb, .gltf or a folder (of .obj meshes)")


def _npz_bytes(arrays: dict[str, np.ndarray]) -> bytes:
    """A deterministic .npz (fixed member dates), so equal frames make equal files;
    stored, not deflated: float frames barely compress, and deflating them costs more
    than baking them."""
    import io

    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_STORED) as z:
        for name, a in arrays.items():
            member = io.BytesIO()
            np.lib.format.write_array(member, np.asanyarray(a), allow_pickle=False)
            info = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_STORED
            z.writestr(info, member.getvalue())
    return buf.getvalue()


def write_frames(out: str | os.PathLike, rig: Rig, clip: Clip, times: np.ndarray,
                 frames: np.ndarray, method: str, *, mesh_format: str = ".obj") -> Path:
    """Write baked frames (k, n, d) at ``times`` to ``out`` (see :func:`output_kind`),
    atomically: a folder is filled under a temporary name and renamed when complete."""
    kind = output_kind(out)
    p = Path(os.fspath(out).rstrip("/" + os.sep))
    frames = np.asarray(frames, dtype=np.float32)
    if kind == "npz":
        arrays = {"U": frames, "times": np.asarray(times, dtype=np.float64),
                  "method": np.asarray(method)}
        if rig.F is not None:
            arrays["F"] = np.asarray(rig.F, dtype=np.int64)
        if rig.T is not None:
            arrays["T"] = np.asarray(rig.T, dtype=np.int64)
        data = _npz_bytes(arrays)
        with atomic_open(p, "wb") as f:
            f.write(data)
        return p
    if kind == "gltf":
        write_gltf(p, rig, bake=method, frames=frames, times=times)
        return p
    ext = mesh_format if mesh_format.startswith(".") else f".{mesh_format}"
    if ext not in MESH_FOLDER_FORMATS:
        raise ValueError(f"mesh format must be one of {', '.join(MESH_FOLDER_FORMATS)}, "
                         f"got {mesh_format!r}")
    if p.exists() and any(p.iterdir()):
        raise ValueError(f"output folder {str(p)!r} exists and is not empty")
    parent = p.parent if str(p.parent) else Path(".")
    tmp = Path(tempfile.mkdtemp(prefix=f".{p.name}.", dir=parent))
    try:
        F = rig.F
        width = max(5, len(str(len(frames))))
        for k, U in enumerate(frames):
            write_mesh(tmp / f"frame_{k:0{width}d}{ext}", U.astype(np.float64), F)
        if p.exists():
            p.rmdir()
        os.replace(tmp, p)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return p


@dataclass
class Baked:
    """What :func:`bake` did: the output, the frame count, and the seconds spent
    skinning alone and in all (reading and writing excluded: ``total`` is the frame
    loop, pose evaluation included)."""

    path: Path
    frames: int
    skinning_s: float
    total_s: float

    @property
    def fps(self) -> float:
        return self.frames / self.total_s if self.total_s > 0 else float("inf")


def bake(rig: Rig, clip: Clip, out: str | os.PathLike, *, method: str = "stbs-dqs",
         fps: float | None = None, frames: str | None = None, mesh_format: str = ".obj",
         progress: Callable[[int, int], None] | None = None, dtype=np.float32,
         max_frames: int | None = None) -> Baked:
    """Bake ``clip`` on ``rig`` with ``method`` and write the frames to ``out``.

    Parameters
    ----------
    rig : Rig
    clip : Clip
        Of the rig's skeleton (e.g. :func:`load_motion`).
    out : str or os.PathLike
        ``.npz``, ``.glb``/``.gltf`` or a folder (see :func:`output_kind`).
    method : {"lbs", "dqs", "stbs-lbs", "stbs-dqs"}
    fps : float, optional
        Sampling rate (default the clip's).
    frames : str, optional
        ``"A:B:STEP"`` of the sampled frames.
    progress : callable, optional
        ``progress(done, total)`` after each frame.
    max_frames : int, optional
        The most frames baked (default: as many as fit in :data:`MAX_BAKE_BYTES`, at
        most :data:`MAX_BAKE_FRAMES`); more is a ValueError before any work.
    """
    _check_method(method)
    if clip.skeleton != rig.skeleton:
        raise ValueError("clip must be of the rig's skeleton")
    output_kind(out)                                  # fail before any work
    n = len(rig.V)
    times = frame_times(clip, fps=fps, frames=frames, limit=frame_limit(n, max_frames),
                        n_vertices=n)
    t0 = time.perf_counter()
    U, skin = _skin(rig, clip, times, method=method, dtype=dtype, progress=progress)
    total = time.perf_counter() - t0
    path = write_frames(out, rig, clip, times, U, method, mesh_format=mesh_format)
    return Baked(path, len(times), skin, total)


def _check_method(method) -> str:
    if method not in METHODS:
        raise ValueError(f"method must be one of {', '.join(METHODS)}, got {method!r}")
    return method


def _skin(rig: Rig, clip: Clip, times: np.ndarray, *, method: str, dtype=None,
          progress: Callable[[int, int], None] | None = None) -> tuple[np.ndarray, float]:
    """The frames (k, n, d) of ``clip`` at ``times`` skinned by ``method`` (float32, or
    ``dtype`` when it is float64), and the seconds spent in the skinning alone."""
    dfm = Deformer(rig.V, rig.skeleton, rig.W, rig.E, method=method, dtype=dtype)
    n, d = rig.V.shape
    out = np.float64 if dfm.dtype == np.float64 else np.float32
    U = np.empty((len(times), n, 3), dtype=out)    # 3 columns: the kernels' layout
    U.fill(0)        # commit the output's pages now: writing them is the output's cost
    skin = 0.0
    for a in range(0, len(times), _POSE_BATCH):     # poses evaluated a batch at a time
        for k, pose in enumerate(clip.poses(times[a:a + _POSE_BATCH]), start=a):
            s = time.perf_counter()
            dfm(pose, out=U[k])
            skin += time.perf_counter() - s
            if progress is not None:
                progress(k + 1, len(times))
    return U[:, :, :d], skin


def bake_frames(rig: Rig, clip: Clip, times=None, *, method: str = "stbs-dqs",
                dtype=None) -> np.ndarray:
    """The rig's mesh skinned by ``method`` at each of ``times`` of ``clip``.

    Parameters
    ----------
    rig : Rig
    clip : Clip
        Of the rig's skeleton.
    times : (k,) float, optional
        Default ``clip.sample_times()``.
    method : {"lbs", "dqs", "stbs-lbs", "stbs-dqs"}
    dtype : float32 or float64, optional
        The :class:`stbs.Deformer`'s (default: float32 for a float32 mesh, else float64).

    Returns
    -------
    (k, n, d) float
        The deformed positions, frame by frame.
    """
    _check_method(method)
    if not isinstance(clip, Clip) or clip.skeleton != rig.skeleton:
        raise ValueError("clip must be a stbs.Clip of the rig's skeleton")
    times = clip.sample_times() if times is None else np.asarray(times, dtype=np.float64)
    return _skin(rig, clip, times, method=method, dtype=dtype)[0]


def export(path: str | os.PathLike, rig: Rig, clip: Clip | None = None, *,
           bake: str | None = None, skinning: str = "lbs") -> None:
    """Write a rig (and its clip) as glTF (``.glb``, ``.gltf``) or OpenUSD (``.usda``,
    ``.usdc``, ``.usd``), with the clip baked by ``bake`` at ``clip.sample_times()``
    (:func:`stbs.io.write_gltf`'s morph targets, :func:`stbs.io.write_usd`'s points cache).

    ``skinning`` is the OpenUSD mesh's ``skel:skinningMethod`` (``"lbs"`` or ``"dqs"``).
    """
    ext = Path(os.fspath(path)).suffix.lower()
    usd = ext in USD_EXTENSIONS
    if not usd and ext not in GLTF_EXTENSIONS:         # fail before any work
        raise ValueError(f"export: expected a path ending in "
                         f"{', '.join(GLTF_EXTENSIONS + USD_EXTENSIONS)}, got "
                         f"{os.fspath(path)!r}")
    if usd:
        require("pxr", "writing OpenUSD")
    if bake is not None and clip is None:
        raise ValueError("bake needs a clip: the animation to bake")
    frames = None
    if bake is not None:
        frames = bake_frames(rig, clip, method=_check_method(bake))
    if usd:
        write_usd(path, rig, clip, bake=bake, skinning=skinning, frames=frames)
    else:
        write_gltf(path, rig, clip, bake, frames=frames)
