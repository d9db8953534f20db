"""OpenUSD out (``usd-core``, the ``usd`` extra): :func:`write_usd` writes a UsdSkel rig,
its clip as a ``SkelAnimation``, and the STBS animation baked as a points cache.

Layout of the stage (``upAxis`` Y, ``metersPerUnit`` 1)::

    /Rig            SkelRoot
    /Rig/Skeleton   Skeleton: one joint per bone (paths follow the bone hierarchy),
                    bind transforms at the bones' starts, rest transforms relative
                    to the parent joint; skel:animationSource -> Anim with a clip
    /Rig/Skeleton/Anim  SkelAnimation: each joint's rotation and translation per frame
    /Rig/Mesh       Mesh bound to the skeleton: skel:jointIndices / jointWeights
                    (the four heaviest bones, elementSize 4), skel:skinningMethod
                    (classicLinear, or dualQuaternion when asked), and the endpoint
                    weights as primvars:stbs:endpointWeights (elementSize 4, aligned)
    /Baked          Mesh with time-sampled points: the frames ``bake=METHOD`` computed,
                    stretch and twist included (with a clip, ``bake`` and ``frames``;
                    :func:`stbs.bake.export` skins the clip and writes them)

Time codes are frames at the clip's rate (``timeCodesPerSecond`` = ``clip.fps``),
frame 0 at the clip's start.
"""

from __future__ import annotations

import os
import re

import numpy as np

from .. import transforms as tf
from .._optional import require
from ..clip import Clip
from ..geometry import boundary_faces
from ..methods import SKINNING_METHODS
from ..pose import local_transforms
from ..rig.model import Rig
from ..skinning.layout import four_heaviest
from ._atomic import atomic_save
from ._frames import skinned_frames
from ._parse import suffix

__all__ = ["write_usd", "USD_EXTENSIONS"]

USD_EXTENSIONS = (".usda", ".usdc", ".usd")


def _joint_paths(names: list[str], parents: np.ndarray) -> list[str]:
    safe, seen = [], set()
    for i, n in enumerate(names):
        s = re.sub(r"[^A-Za-z0-9_]", "_", str(n)) or f"bone{i}"
        if s[0].isdigit():
            s = f"bone_{s}"
        while s in seen:
            s = f"{s}_{i}"
        seen.add(s)
        safe.append(s)
    out = [""] * len(names)
    for i in range(len(names)):         # iteratively: a chain may be thousands deep
        chain = [i]
        while not out[chain[-1]] and parents[chain[-1]] >= 0 and not out[parents[chain[-1]]]:
            chain.append(parents[chain[-1]])
        for k in reversed(chain):
            if not out[k]:
                p = parents[k]
                out[k] = safe[k] if p < 0 else f"{out[p]}/{safe[k]}"
    return out


def write_usd(path: str | os.PathLike, rig: Rig, clip: Clip | None = None, *,
              bake: str | None = None, skinning: str = "lbs", frames=None) -> None:
    """Write a 3D rig as OpenUSD (UsdSkel); see the module docs for the layout.

    Parameters
    ----------
    path : str or os.PathLike
        ``.usda`` (text), ``.usdc`` (binary) or ``.usd``; written atomically.
    rig : Rig
    clip : Clip, optional
        Written as the skeleton's ``SkelAnimation`` (rotations and posed starts: what
        linear or dual-quaternion skinning of rigid joints shows), sampled at its rate.
    bake : {"lbs", "dqs", "stbs-lbs", "stbs-dqs"}, optional
        With ``clip``: the method that computed ``frames`` (or that skins the clip
        at ``clip.sample_times()`` when ``frames`` is not given), written per frame as
        ``/Baked``.
    skinning : {"lbs", "dqs"}
        The mesh's ``skel:skinningMethod``: ``classicLinear`` or ``dualQuaternion``.
    frames : sequence of (n, 3) float, optional
        With ``bake``: the deformed positions at each of ``clip.sample_times()``.
    """
    suffix(path, USD_EXTENSIONS, "write_usd")
    if not isinstance(rig, Rig):
        raise TypeError(f"rig must be a stbs.Rig, got {type(rig).__name__}")
    if rig.dim != 3:
        raise ValueError(f"USD skeletons are 3D; got a {rig.dim}D rig")
    if skinning not in ("lbs", "dqs"):
        raise ValueError(f"skinning must be 'lbs' or 'dqs', got {skinning!r}")
    if clip is not None and (not isinstance(clip, Clip) or clip.skeleton != rig.skeleton):
        raise ValueError("clip must be a stbs.Clip of the rig's skeleton")
    frames = _check_frames(rig, clip, bake, frames)
    F = rig.F if rig.F is not None else (boundary_faces(rig.T, rig.V)
                                         if rig.T is not None else None)
    if F is None or len(F) == 0:
        raise ValueError("write_usd needs triangles (rig.F) or tetrahedra (rig.T)")
    require("pxr", "writing OpenUSD")
    atomic_save(path, lambda tmp: _write(tmp, rig, np.asarray(F), clip, bake, skinning,
                                                 frames))


def _check_frames(rig: Rig, clip, bake, frames) -> list[np.ndarray] | None:
    """The frames as float32 (n, 3) arrays, one per ``clip.sample_times()``."""
    if bake is None and frames is None:
        return None
    if bake not in SKINNING_METHODS:
        raise ValueError("frames need bake=: the method that computed them" if bake is None
                         else f"bake must be one of {', '.join(SKINNING_METHODS)}, "
                              f"got {bake!r}")
    if clip is None:
        raise ValueError("bake needs a clip: the animation to bake")
    if frames is None:
        frames = skinned_frames(rig, clip, clip.sample_times(), bake)
    k = len(clip.sample_times())
    if len(frames) != k:
        raise ValueError(f"frames must hold one mesh per sampled time ({k}), got {len(frames)}")
    out = [np.asarray(U, dtype=np.float32) for U in frames]
    for U in out:
        if U.shape != rig.V.shape:
            raise ValueError(f"frames: each must have shape {rig.V.shape}, got {U.shape}")
    return out


def _write(tmp: str, rig: Rig, F: np.ndarray, clip, bake, skinning, frames) -> None:
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdSkel, Vt

    sk = rig.skeleton
    b = sk.n_bones
    V = np.asarray(rig.V, dtype=np.float64)
    if os.path.exists(tmp):          # the atomic writer's placeholder: USD makes its own
        os.remove(tmp)
    stage = Usd.Stage.CreateNew(tmp)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    root = UsdSkel.Root.Define(stage, "/Rig")
    stage.SetDefaultPrim(root.GetPrim())
    skel = UsdSkel.Skeleton.Define(stage, "/Rig/Skeleton")
    joints = _joint_paths(list(sk.names), sk.parents)
    skel.CreateJointsAttr(Vt.TokenArray(joints))
    A = sk.A

    def translate(t):
        return Gf.Matrix4d(1.0).SetTranslate(Gf.Vec3d(*map(float, t)))

    skel.CreateBindTransformsAttr(Vt.Matrix4dArray([translate(A[i]) for i in range(b)]))
    rest = [A[i] - (A[sk.parents[i]] if sk.parents[i] >= 0 else 0.0) for i in range(b)]
    skel.CreateRestTransformsAttr(Vt.Matrix4dArray([translate(t) for t in rest]))

    mesh = UsdGeom.Mesh.Define(stage, "/Rig/Mesh")
    mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(V.astype(np.float32)))
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray([3] * len(F)))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray(F.ravel().astype(int).tolist()))
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    mesh.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(*map(float, V.min(0))),
                                         Gf.Vec3f(*map(float, V.max(0)))]))
    binding = UsdSkel.BindingAPI.Apply(mesh.GetPrim())
    binding.CreateSkeletonRel().SetTargets([skel.GetPath()])
    idx, w, e = four_heaviest(rig.W, rig.E)
    idx = idx.astype(np.int32)
    binding.CreateJointIndicesPrimvar(False, 4).Set(Vt.IntArray(idx.ravel().tolist()))
    binding.CreateJointWeightsPrimvar(False, 4).Set(
        Vt.FloatArray.FromNumpy(w.ravel().astype(np.float32)))
    binding.CreateGeomBindTransformAttr(Gf.Matrix4d(1.0))
    binding.CreateSkinningMethodAttr(UsdSkel.Tokens.dualQuaternion if skinning == "dqs"
                                     else UsdSkel.Tokens.classicLinear)
    if rig.E is not None:
        pv = UsdGeom.PrimvarsAPI(mesh).CreatePrimvar("stbs:endpointWeights",
                                                     Sdf.ValueTypeNames.FloatArray,
                                                     UsdGeom.Tokens.vertex, 4)
        pv.Set(Vt.FloatArray.FromNumpy(e.ravel().astype(np.float32)))
    if clip is not None:
        times = clip.sample_times()
        poses = [clip.pose(float(t)) for t in times]
        stage.SetTimeCodesPerSecond(clip.fps)
        stage.SetFramesPerSecond(clip.fps)
        stage.SetStartTimeCode(0)
        stage.SetEndTimeCode(len(times) - 1)
        anim = UsdSkel.Animation.Define(stage, "/Rig/Skeleton/Anim")
        anim.CreateJointsAttr(Vt.TokenArray(joints))
        R = np.array([p.rotations for p in poses])
        O = np.array([p.origins for p in poses])
        LR, LT = local_transforms(sk, R, O)
        q = tf.matrix_to_quat(LR)                        # (w, x, y, z)
        rot, tra, sca = (anim.CreateRotationsAttr(), anim.CreateTranslationsAttr(),
                         anim.CreateScalesAttr())
        sca.Set(Vt.Vec3hArray([Gf.Vec3h(1, 1, 1)] * b))
        for k in range(len(times)):
            rot.Set(Vt.QuatfArray([Gf.Quatf(float(q[k, i, 0]),
                                            Gf.Vec3f(*map(float, q[k, i, 1:])))
                                   for i in range(b)]), k)
            tra.Set(Vt.Vec3fArray.FromNumpy(LT[k].astype(np.float32)), k)
        UsdSkel.BindingAPI.Apply(skel.GetPrim()).CreateAnimationSourceRel().SetTargets(
            [anim.GetPath()])
        if frames is not None:
            baked = UsdGeom.Mesh.Define(stage, "/Baked")
            baked.CreateFaceVertexCountsAttr(Vt.IntArray([3] * len(F)))
            baked.CreateFaceVertexIndicesAttr(Vt.IntArray(F.ravel().astype(int).tolist()))
            baked.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
            pts, ext = baked.CreatePointsAttr(), baked.CreateExtentAttr()
            for k, U in enumerate(frames):
                pts.Set(Vt.Vec3fArray.FromNumpy(U), k)
                ext.Set(Vt.Vec3fArray([Gf.Vec3f(*map(float, U.min(0))),
                                       Gf.Vec3f(*map(float, U.max(0)))]), k)
            baked.GetPrim().SetCustomDataByKey("stbs:method", bake)
    stage.GetRootLayer().Save()
