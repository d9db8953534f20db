"""Synthetic humanoids for the retargeting tests: one body, any naming, rest posture,
up axis, facing and size; as a capture (a stbs.Motion with end sites) or as a rig's
skeleton (one bone per joint, as the character readers make)."""

from __future__ import annotations

import numpy as np

import stbs
from stbs import transforms as tf
from stbs.rig.joints import skeleton_from_joints

#: The body's joints: (part, parent part, position in a y-up body facing +z, left = +x).
PARTS = [
    ("pelvis", None, (0.0, 1.00, 0.0)),
    ("spine1", "pelvis", (0.0, 1.10, -0.01)),
    ("spine2", "spine1", (0.0, 1.25, -0.02)),
    ("chest", "spine2", (0.0, 1.40, -0.02)),
    ("neck", "chest", (0.0, 1.55, -0.01)),
    ("head", "neck", (0.0, 1.65, 0.0)),
    ("l_collar", "chest", (0.03, 1.50, 0.0)),
    ("l_upperarm", "l_collar", (0.18, 1.50, 0.0)),
    ("l_forearm", "l_upperarm", (0.48, 1.50, 0.0)),
    ("l_hand", "l_forearm", (0.73, 1.50, 0.0)),
    ("l_thigh", "pelvis", (0.10, 0.95, 0.0)),
    ("l_shin", "l_thigh", (0.10, 0.52, 0.0)),
    ("l_foot", "l_shin", (0.10, 0.10, 0.0)),
    ("l_toe", "l_foot", (0.10, 0.02, 0.12)),
]
#: Where each leaf's chain ends (BVH end sites; the rig's leaf tails).
ENDS = {"head": (0.0, 1.85, 0.0), "l_hand": (0.91, 1.50, 0.0), "l_toe": (0.10, 0.02, 0.20)}

CMU = {"pelvis": "Hips", "spine1": "LowerBack", "spine2": "Spine", "chest": "Spine1",
       "neck": "Neck1", "head": "Head", "l_collar": "LeftShoulder", "l_upperarm": "LeftArm",
       "l_forearm": "LeftForeArm", "l_hand": "LeftHand", "l_thigh": "LeftUpLeg",
       "l_shin": "LeftLeg", "l_foot": "LeftFoot", "l_toe": "LeftToeBase"}
MIXAMO = {k: f"mixamorig:{v}" for k, v in {**CMU, "spine1": "Spine", "spine2": "Spine1",
                                             "chest": "Spine2", "neck": "Neck"}.items()}
UNREAL = {"pelvis": "pelvis", "spine1": "spine_01", "spine2": "spine_02", "chest": "spine_03",
          "neck": "neck_01", "head": "head", "l_collar": "clavicle_l",
          "l_upperarm": "upperarm_l", "l_forearm": "lowerarm_l", "l_hand": "hand_l",
          "l_thigh": "thigh_l", "l_shin": "calf_l", "l_foot": "foot_l", "l_toe": "ball_l"}
RIGIFY = {"pelvis": "DEF-hips", "spine1": "DEF-spine", "spine2": "DEF-spine.001",
          "chest": "DEF-chest", "neck": "DEF-neck", "head": "DEF-head",
          "l_collar": "DEF-shoulder.L", "l_upperarm": "DEF-upper_arm.L",
          "l_forearm": "DEF-forearm.L", "l_hand": "DEF-hand.L", "l_thigh": "DEF-thigh.L",
          "l_shin": "DEF-shin.L", "l_foot": "DEF-foot.L", "l_toe": "DEF-toe.L"}
LAFAN = {**CMU, "spine1": "Spine", "spine2": "Spine1", "chest": "Spine2", "neck": "Neck",
         "l_toe": "LeftToe"}
UNITY = {"pelvis": "Hips", "spine1": "Spine", "spine2": "Chest", "chest": "UpperChest",
         "neck": "Neck", "head": "Head", "l_collar": "LeftShoulder",
         "l_upperarm": "LeftUpperArm", "l_forearm": "LeftLowerArm", "l_hand": "LeftHand",
         "l_thigh": "LeftUpperLeg", "l_shin": "LeftLowerLeg", "l_foot": "LeftFoot",
         "l_toe": "LeftToes"}
# games105-like: a clavicle before "Shoulder", which is then the upper arm
GAMES105 = {"pelvis": "RootJoint", "spine1": "pelvis_lowerback", "spine2": "lowerback_mid",
            "chest": "lowerback_torso", "neck": "torso_neck", "head": "torso_head",
            "l_collar": "lTorso_Clavicle", "l_upperarm": "lShoulder", "l_forearm": "lElbow",
            "l_hand": "lWrist", "l_thigh": "lHip", "l_shin": "lKnee", "l_foot": "lAnkle",
            "l_toe": "lToeJoint"}
BIPED = {"pelvis": "Bip01 Pelvis", "spine1": "Bip01 Spine", "spine2": "Bip01 Spine1",
         "chest": "Bip01 Spine2", "neck": "Bip01 Neck", "head": "Bip01 Head",
         "l_collar": "Bip01 L Clavicle", "l_upperarm": "Bip01 L UpperArm",
         "l_forearm": "Bip01 L Forearm", "l_hand": "Bip01 L Hand", "l_thigh": "Bip01 L Thigh",
         "l_shin": "Bip01 L Calf", "l_foot": "Bip01 L Foot", "l_toe": "Bip01 L Toe0"}


def _mirror(name: str) -> str:
    """The right side's name of a left side's name, in each convention above."""
    swaps = [("Left", "Right"), ("_l", "_r"), (".L", ".R"), (" L ", " R "), ("lT", "rT"),
             ("lS", "rS"), ("lE", "rE"), ("lW", "rW"), ("lH", "rH"), ("lK", "rK"),
             ("lA", "rA")]
    for a, c in swaps:
        if a in name:
            return name.replace(a, c, 1)
    raise ValueError(name)


def body(names: dict[str, str] | None = None, *, arms_down: float = 0.0, scale: float = 1.0):
    """(names, parents, X): the humanoid's joints, left and right, in a y-up body facing +z,
    the arms lowered by ``arms_down`` degrees from a T-pose (45: an A-pose)."""
    parts = []
    for part, parent, x in PARTS:
        parts.append((part, parent, np.array(x)))
        if part.startswith("l_"):
            r = "r_" + part[2:]
            rp = parent if not parent.startswith("l_") else "r_" + parent[2:]
            parts.append((r, rp, np.array(x) * [-1, 1, 1]))
    order = [p for p, _, _ in parts]
    X = {p: x for p, _, x in parts}
    a = np.radians(arms_down)
    for side, sign in (("l_", 1.0), ("r_", -1.0)):
        s = X[side + "upperarm"]
        R = tf.axis_angle_to_matrix(np.array([[0, 0, 1.0]]), np.array([-sign * a]))[0]
        for p in ("forearm", "hand"):
            X[side + p] = s + R @ (X[side + p] - s)
    ends = {}
    for part, x in ENDS.items():
        for side, sign in (("", 1.0), ("r_", -1.0)):
            key = part if side == "" else "r_" + part[2:]
            if side and not part.startswith("l_"):
                continue
            e = np.array(x) * [sign, 1, 1]
            if "hand" in key:
                s = X[key[:2] + "upperarm"]
                R = tf.axis_angle_to_matrix(np.array([[0, 0, 1.0]]), np.array([-sign * a]))[0]
                e = s + R @ (e - s)
            ends[key] = e
    label = {}
    for p in order:
        if names is None:
            label[p] = p
        elif p.startswith("r_"):
            label[p] = _mirror(names["l_" + p[2:]])
        else:
            label[p] = names[p]
    parents = [-1 if par is None else order.index(par) for _, par, _ in parts]
    return ([label[p] for p in order], np.array(parents), scale * np.array([X[p] for p in order]),
            {order.index(k): scale * v for k, v in ends.items()}, order)


def world(frame_R, X):
    """X (n, 3) turned by the 3x3 frame_R (rows are points)."""
    return X @ np.asarray(frame_R).T


_I = np.eye(3)


def capture(names=None, *, arms_down=0.0, scale=1.0, frame=_I, rotations=None,
            pelvis=None, frame_time=1 / 30, source="synthetic.bvh"):
    """A capture of the humanoid: rest pose as :func:`body` turned by ``frame`` (3x3,
    e.g. to make z the up axis), end sites at the leaves, ``rotations`` ``{part:
    (f, 3, 3) local rotations}`` (in the rest frame's axes), ``pelvis`` (f, 3) the
    pelvis's world positions (default: its rest position)."""
    labels, parents, X, ends, order = body(names, arms_down=arms_down, scale=scale)
    X = world(frame, X)
    n = len(labels)
    names_all, par_all, pos, end_site = list(labels), list(parents), list(X), [False] * n
    for k, e in ends.items():
        names_all.append(f"{labels[k]}_end")
        par_all.append(k)
        pos.append(world(frame, e[None])[0])
        end_site.append(True)
    pos = np.array(pos)
    offsets = np.array([pos[k] - (pos[p] if p >= 0 else 0) for k, p in enumerate(par_all)])
    f = 1
    if rotations:
        f = len(next(iter(rotations.values())))
    if pelvis is not None:
        f = max(f, len(pelvis))
    R = np.tile(np.eye(3), (f, len(names_all), 1, 1))
    for part, Rk in (rotations or {}).items():
        k = order.index(part)
        R[:, k] = np.asarray(frame) @ Rk @ np.asarray(frame).T
    T = np.broadcast_to(offsets, (f, len(names_all), 3)).copy()
    if pelvis is not None:
        T[:, 0] = pelvis
    return stbs.Motion(names_all, par_all, offsets, rotations=R, translations=T,
                       frame_time=frame_time, end_site=end_site, source=source)


def skeleton(names=None, *, arms_down=0.0, scale=1.0, frame=_I, shuffle=None):
    """The humanoid as a rig's skeleton: one bone per joint (stbs.rig.joints), leaf tails
    at the body's chain ends; ``shuffle`` (a seed) lists the joints in a random order."""
    labels, parents, X, ends, order = body(names, arms_down=arms_down, scale=scale)
    X = world(frame, X)
    n = len(labels)
    perm = np.arange(n)
    if shuffle is not None:
        perm = np.random.default_rng(shuffle).permutation(n)
    inv = np.argsort(perm)
    par = np.array([-1 if parents[perm[i]] < 0 else inv[parents[perm[i]]] for i in range(n)])
    sk = skeleton_from_joints(X[perm], par, [labels[k] for k in perm])
    # the leaves' tails where the capture's chains end (its end sites)
    C = sk.C.copy()
    for k, e in ends.items():
        i = int(inv[k])
        C[sk.BE[i, 1]] = world(frame, e[None])[0]
    sk = stbs.Skeleton(C, sk.BE, names=sk.names, P=sk.parents)
    return sk, [order[k] for k in perm]


def rot(axis, deg, f=1):
    """(f, 3, 3) rotations about ``axis`` by ``deg`` (scalar or (f,)) degrees."""
    deg = np.broadcast_to(np.asarray(deg, dtype=float), (f,))
    return tf.axis_angle_to_matrix(np.broadcast_to(np.asarray(axis, float), (f, 3)),
                                   np.radians(deg))
