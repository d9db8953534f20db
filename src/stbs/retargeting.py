"""Motion onto a rig: joint rotations of a capture (a :class:`stbs.Motion`) as a
:class:`stbs.Clip` of poses of the rig's skeleton, with twist spread along the bones.

Each bone of the target skeleton is matched to a *source joint*, the joint of the
motion that turns it (by name, or by a mapping). The source joint's world rotation,
relative to the motion's rest pose, becomes the bone's world rotation relative to the
rig's rest pose (``R_t = R_s R_s0^-1 R_t0`` with the rest orientations ``R_s0``, ``R_t0``
taken as the frames the two rest poses are drawn in). A bone with no source joint
turns with its parent.

``twist="spread"`` (the paper's twistable bones, applied to motion): each bone's rotation
relative to its parent is split into a *twist* about the parent bone's axis and a
*swing*; the twist is moved to the joint between them, where it becomes the parent's end
twist ``theta_b`` and so grows from 0 to its full angle along the parent bone (a
forearm's roll, stored at the wrist by capture, turns the forearm progressively instead
of the wrist alone). The child's final orientation is unchanged: it inherits the full
twist (see :func:`stbs.forward_kinematics`). Twist angles are unwrapped over time, so a roll
that keeps turning never jumps back by a full turn. ``twist="joint"`` keeps the rigid
roll at the joint, for comparison. Joints where several bones start keep their twist
rigid too (one twist per joint cannot serve two children).
"""

from __future__ import annotations

import json
import os
import re
import warnings
from collections.abc import Mapping
from typing import Any, Literal

import numpy as np

from . import transforms as tf
from .clip import Clip
from .motion import Motion
from .pose import forward_kinematics, local_transforms
from .skeleton import Skeleton

__all__ = ["retarget", "ALIASES"]

#: Usual names of the same joint in capture files and rigs (normalised: lower case,
#: letters and digits only, side prefixes "l"/"r"/"left"/"right" removed first).
ALIASES: tuple[tuple[str, ...], ...] = (
    ("hips", "hip", "pelvis", "root"),
    ("spine", "lowerback", "spine1", "abdomen"),
    ("chest", "spine2", "upperchest", "thorax"),
    ("neck", "lowerneck", "neck1"),
    ("head",),
    ("collar", "clavicle", "shoulder"),
    ("upperarm", "arm", "humerus"),
    ("elbow", "forearm", "lowerarm", "radius"),
    ("wrist", "hand"),
    ("upleg", "upperleg", "thigh", "femur"),
    ("knee", "leg", "lowerleg", "shin", "calf", "tibia"),
    ("ankle", "foot"),
    ("toe", "toes", "toebase"),
)

_PREFIXES = ("mixamorig", "bip01", "bip001", "def", "bone", "jnt", "joint")


def _normalise(name: str) -> tuple[str, str]:
    """(side, stem) of a joint or bone name: "LeftForeArm" -> ("l", "forearm")."""
    s = re.sub(r"[^a-z0-9]", "", name.lower())
    for p in _PREFIXES:
        if s.startswith(p) and len(s) > len(p):
            s = s[len(p):]
    side = ""
    for pre, tag in (("left", "l"), ("right", "r")):
        if s.startswith(pre) and len(s) > len(pre):
            return tag, s[len(pre):]
        if s.endswith(pre) and len(s) > len(pre):
            return tag, s[:-len(pre)]
    m = re.fullmatch(r"([lr])([a-z].*)", s) or re.fullmatch(r"(.*[a-z])([lr])", s)
    if m and len(s) > 3:
        a, b = m.groups()
        side, s = (a, b) if a in "lr" and len(a) == 1 else (b, a)
    return side, s


def _alias(stem: str) -> str:
    for group in ALIASES:
        if stem in group:
            return group[0]
    return stem


def _auto_mapping(sk: Skeleton, motion: Motion) -> np.ndarray:
    """Target bone -> source joint by name: exact, then case and punctuation blind, then
    aliases. A bone named ``"P>K"`` (see :meth:`stbs.Motion.skeleton`) matches joint P."""
    joints = [k for k in range(motion.n_joints) if not motion.end_site[k]]
    exact = {motion.names[k]: k for k in joints}
    loose: dict[tuple[str, str], int] = {}
    alias: dict[tuple[str, str], int] = {}
    for k in joints:
        side, stem = _normalise(motion.names[k])
        loose.setdefault((side, stem), k)
        alias.setdefault((side, _alias(stem)), k)
    out = np.full(sk.n_bones, -1, dtype=np.int64)
    for i, name in enumerate(sk.names):
        base = name.split(">")[0]
        if base in exact:
            out[i] = exact[base]
            continue
        side, stem = _normalise(base)
        k = loose.get((side, stem), alias.get((side, _alias(stem)), -1))
        out[i] = k
    return out


def _given_mapping(mapping: Any, sk: Skeleton, motion: Motion) -> np.ndarray:
    if isinstance(mapping, (str, os.PathLike)):
        try:
            with open(mapping, encoding="utf-8") as f:
                mapping = json.load(f)
        except FileNotFoundError:
            raise FileNotFoundError(f"mapping file not found: {os.fspath(mapping)!r}") from None
        except json.JSONDecodeError as exc:
            raise ValueError(f"mapping {os.fspath(mapping)!r}: not JSON ({exc})") from None
    if not isinstance(mapping, Mapping):
        raise TypeError(f"mapping must be a dict {{rig bone: motion joint}}, a JSON file of "
                        f"one, or None, got {type(mapping).__name__}")
    out = np.full(sk.n_bones, -1, dtype=np.int64)
    for bone, joint in mapping.items():
        try:
            i = sk.bone_index(int(bone) if isinstance(bone, str) and bone.isdigit() else bone)
        except (KeyError, IndexError, ValueError):
            raise ValueError(f"mapping: the rig has no bone {bone!r}; its bones are "
                             f"{', '.join(sk.names)}") from None
        if joint is None:
            continue
        if not isinstance(joint, str) or joint not in motion.names:
            raise ValueError(f"mapping: the motion has no joint {joint!r} (for bone {bone!r}); "
                             f"its joints are {', '.join(motion.names)}")
        out[i] = motion.names.index(joint)
    return out


def _end_joints(sk: Skeleton, motion: Motion, src: np.ndarray) -> np.ndarray:
    """For each mapped bone, the child of its source joint whose rest direction is
    closest to the bone's (the source bone's end); -1 where there is none."""
    X = motion.rest_positions()
    out = np.full(sk.n_bones, -1, dtype=np.int64)
    for i in np.flatnonzero(src >= 0):
        s = src[i]
        best, score = -1, -np.inf
        stack = motion.children(s)
        while stack:             # children at the same place: look through to theirs
            k = stack.pop(0)
            d = X[k] - X[s]
            n = np.linalg.norm(d)
            if n <= 1e-12:
                stack.extend(motion.children(k))
                continue
            c = float(d @ sk.axes[i]) / n
            if c > score:
                best, score = k, c
        out[i] = best
    return out


def _twist_about(Rl: np.ndarray, u: np.ndarray) -> np.ndarray:
    """(f,) angle of the twist part of rotations (f, 3, 3) about the unit axis u, in
    (-pi, pi] (swing-twist split: ``R = T(u, angle) S`` with ``S`` turning u off itself
    the least)."""
    q = tf.matrix_to_quat(Rl)
    w, p = q[:, 0], q[:, 1:] @ u
    small = np.hypot(w, p) < 1e-9             # a half-turn swing: no twist defined
    ang = 2.0 * np.arctan2(p, w)
    ang = (ang + np.pi) % (2 * np.pi) - np.pi
    ang[small] = 0.0
    return ang


def retarget(motion: Motion, rig, *, mapping=None,
             twist: Literal["spread", "joint"] = "spread",
             stretch: Literal["keep", "match"] = "keep") -> Clip:
    """A motion as a clip of poses of a rig's skeleton.

    Parameters
    ----------
    motion : Motion
        The source, e.g. from :func:`stbs.io.read_bvh`; its rest pose is every
        rotation the identity.
    rig : Rig or Skeleton
        The target (3D); a :class:`stbs.Rig` gives its ``skeleton``.
    mapping : dict or str or os.PathLike, optional
        ``{rig bone (name or index): motion joint name (or None: follow the parent)}``,
        or a JSON file holding one. Default: by name (exact, then ignoring case,
        punctuation and prefixes such as ``mixamorig:``, then :data:`ALIASES`, sides
        from ``Left``/``L``/``_l``); a bone named ``"P>K"`` matches joint ``P``.
    twist : {"spread", "joint"}
        See the module docs: spread each joint's twist along the bone ending there,
        unwrapped over time, or keep it rigid at the joint.
    stretch : {"keep", "match"}
        ``"keep"``: every stretch 1. ``"match"``: each bone's stretch is the source
        bone's length in that frame over the target's rest length, after scaling the
        source by the ratio of the total rest lengths of the matched bones (so a
        source in other units, or another build, changes proportions only).

    Returns
    -------
    Clip
        One key per motion frame at its time, ``fps`` the motion's. The root moves by
        its source joint's translation (scaled as for ``stretch="match"``).

    Raises
    ------
    ValueError
        A 2D rig, a bad choice, no bone matched, or a mapping naming a bone or joint
        that does not exist (the message lists the names there are).

    Warns
    -----
    UserWarning
        Matching by name left some rig bones without a joint (they follow their
        parents); the warning names them.
    """
    if not isinstance(motion, Motion):
        raise TypeError(f"motion must be a stbs.Motion, got {type(motion).__name__}")
    sk = rig if isinstance(rig, Skeleton) else getattr(rig, "skeleton", None)
    if not isinstance(sk, Skeleton):
        raise TypeError(f"rig must be a stbs.Rig or stbs.Skeleton, got {type(rig).__name__}")
    if sk.dim != 3:
        raise ValueError(f"retarget needs a 3D rig, got a {sk.dim}D skeleton")
    if twist not in ("spread", "joint"):
        raise ValueError(f"twist must be one of 'spread', 'joint', got {twist!r}")
    if stretch not in ("keep", "match"):
        raise ValueError(f"stretch must be one of 'keep', 'match', got {stretch!r}")
    src = _auto_mapping(sk, motion) if mapping is None else _given_mapping(mapping, sk, motion)
    if not (src >= 0).any():
        raise ValueError(f"no bone of the rig matches a joint of the motion by name; rig "
                         f"bones: {', '.join(sk.names)}; motion joints: "
                         f"{', '.join(motion.names)} (give a mapping)")
    if mapping is None and (src < 0).any():
        lost = [sk.names[i] for i in np.flatnonzero(src < 0)]
        warnings.warn(f"retarget: {len(lost)} rig bones match no joint of the motion by "
                      f"name and follow their parents: {', '.join(lost)} (a mapping names "
                      f"their joints)", UserWarning, stacklevel=2)
    f, b = motion.n_frames, sk.n_bones
    Rg, tg = motion.global_transforms()
    # world rotation of each bone relative to the rest pose (motion rest: identity)
    D = np.empty((f, b, 3, 3))
    for i in sk.order:
        p = sk.parents[i]
        if src[i] >= 0:
            D[:, i] = Rg[:, src[i]]
        elif p >= 0:
            D[:, i] = D[:, p]
        else:
            D[:, i] = np.eye(3)
    L = local_transforms(sk, D)
    has_p = sk.parents >= 0
    tau = np.zeros((f, sk.n_joints))
    if twist == "spread":
        starts = np.bincount(sk.BE[:, 0], minlength=sk.n_joints)
        for i in np.flatnonzero(has_p):
            J, p = sk.BE[i, 0], sk.parents[i]
            if starts[J] != 1 or src[i] < 0:
                continue
            u = sk.axes[p]
            ang = np.unwrap(_twist_about(L[:, i], u))
            T = tf.axis_angle_to_matrix(np.broadcast_to(u, (f, 3)), ang)
            L[:, i] = np.einsum("fji,fjk->fik", T, L[:, i])       # S = T^-1 L
            tau[:, J] = ang
    # scale between the two rest poses, for stretch and the root's travel
    X0 = motion.rest_positions()
    end = _end_joints(sk, motion, src)
    ok = (src >= 0) & (end >= 0)
    ls = np.linalg.norm(X0[end[ok]] - X0[src[ok]], axis=1)
    scale = float(sk.lengths[ok].sum() / ls.sum()) if ok.any() and ls.sum() > 0 else 1.0
    sigma = np.ones((f, b))
    if stretch == "match" and ok.any():
        cur = np.linalg.norm(tg[:, end[ok]] - tg[:, src[ok]], axis=2)
        sigma[:, ok] = np.maximum(scale * cur / sk.lengths[ok], 1e-6)
    root = sk.roots[0]
    r = src[root] if src[root] >= 0 else int(np.flatnonzero(motion.parents < 0)[0])
    shift = scale * (tg[:, r] - X0[r])
    keys = [(float(t), forward_kinematics(sk, rotations=L[k], stretch=sigma[k], twist=tau[k],
                                          translation=shift[k]))
            for k, t in enumerate(motion.times)]
    return Clip(keys, fps=motion.fps)
