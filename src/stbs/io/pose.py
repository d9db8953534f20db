"""Pose files: a :class:`stbs.Pose` described in JSON.

A pose file is one JSON object in one of two forms. Bones are named by index
(a JSON number, or a string of digits, since JSON object keys are strings) or by
name (:meth:`stbs.Skeleton.bone_index`; a name wins over a digit string that is
also a name). Angles are in **degrees unless** ``"degrees": false`` is given, in
which case they are radians. Every other key is an error.

Joints form (dragging joints, as :meth:`stbs.Pose.from_joints`)::

    {"joints": [[x, y, z], ...], "twist": {"3": [0, 180]}, "degrees": true}

``joints``
    The posed position of every joint, (j, d), in the skeleton's joint order.
    Each bone's rotation is the smallest rotation from its rest to its posed
    direction and its stretch the length ratio (:meth:`stbs.Pose.from_joints`).
``twist`` (3D only)
    ``{bone: [start, end]}``: the twist angles theta_a, theta_b of that bone at
    its start and end joint, about its own axis. These are *absolute* per-bone
    values (nothing is inherited in this form); unlisted bones get ``[0, 0]``.

Forward-kinematics form (local rotations, as :func:`stbs.forward_kinematics`)::

    {"rotate": {"2": {"axis": [0, 1, 0], "angle": 90}}, "stretch": {"4": 1.5},
     "twist": {"forearm": [0, 180]}, "translate": [0, 0, 0], "degrees": true}

All keys are optional; ``{}`` is the rest pose. The pose is forward kinematics
(:meth:`stbs.Pose.from_local`): a child hangs in its parent's posed frame (at its
parent's end, or where it hangs on its parent for an offset child) and inherits the
parent's rotation and twist there. Every pose has this form exactly
(:meth:`stbs.Pose.local`).

``rotate``
    ``{bone: {"axis": [x, y, z], "angle": a}}`` in 3D (axis non-zero, any
    length), ``{bone: {"angle": a}}`` in 2D (counter-clockwise; no axis). The
    bone's *local* rotation about its start joint, in its parent's frame (the
    world frame for a root bone). Unlisted bones: identity.
``stretch``
    ``{bone: sigma}`` with sigma > 0, posed length / rest length. Unlisted: 1.
``twist`` (3D only)
    ``{bone: [start, end]}``: the bone's own twist angles theta_a, theta_b about its
    axis, on top of the frame it inherits. The twist grows from ``start`` to ``end``
    along the bone, and every bone hanging below is turned rigidly by the twist
    where it hangs (the paper's Fig. 5: ``{"forearm": [0, 180]}`` spreads 180
    degrees along the forearm and turns the hand by 180 degrees). A ``start`` turns
    the whole bone about its axis first.
``translate``
    ``[x, y, z]`` (d values): added to every root bone's start. Or
    ``{bone: [x, y, z]}``: each listed bone's start moved by that offset, in the
    frame its parent carries it in (world for a root), as an animated joint
    translation does. Default 0.

Errors are :class:`ValueError` naming the file (or ``pose`` for a dict), the
key and the bone, what was expected and what was found: unknown keys, a
mixture of both forms, a bone that does not exist or is listed twice, wrong
vector lengths, non-numbers, NaN or infinity, a stretch <= 0, a zero axis, a
non-zero twist on a 2D skeleton.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from .. import _checks
from .. import transforms as tf
from ..pose import Pose
from ..skeleton import Skeleton

__all__ = ["read_pose", "write_pose", "pose_to_dict", "POSE_FORMS", "JOINTS_KEYS", "FK_KEYS"]

#: Keys of the joints form.
JOINTS_KEYS = ("joints", "twist", "degrees")
#: Keys of the forward-kinematics form.
FK_KEYS = ("rotate", "stretch", "twist", "translate", "degrees")


def read_pose(path_or_dict: str | os.PathLike | Mapping[str, Any], sk: Skeleton) -> Pose:
    """Read a pose of ``sk`` from a JSON file or an already parsed dict.

    Parameters
    ----------
    path_or_dict : str, os.PathLike or Mapping
        A ``.json`` file (any extension is accepted), or the parsed object.
    sk : Skeleton
        The skeleton the pose is for; bone names and indices refer to it.

    Returns
    -------
    Pose

    Raises
    ------
    FileNotFoundError
        The file does not exist.
    ValueError
        The file is not valid JSON, or the pose is invalid (see the module docs);
        the message names the file, the key and the bone.
    TypeError
        ``sk`` is not a :class:`stbs.Skeleton`, or ``path_or_dict`` is neither a
        path nor a mapping.
    """
    _checks.skeleton(sk)
    if isinstance(path_or_dict, Mapping):
        src, obj = "pose", path_or_dict
    elif isinstance(path_or_dict, (str, os.PathLike)):
        src, obj = _load(Path(os.fspath(path_or_dict)))
    else:
        raise TypeError("path_or_dict must be a path or a dict, got "
                        f"{type(path_or_dict).__name__}")
    return _Reader(src, sk).pose(obj)


def _load(p: Path) -> tuple[str, Any]:
    if not p.exists():
        raise FileNotFoundError(2, "pose file not found", str(p))
    if p.is_dir():
        raise IsADirectoryError(21, "pose path is a folder, expected a file", str(p))
    src = str(p)
    try:
        text = p.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise ValueError(f"{src}: expected UTF-8 JSON text, found an undecodable byte at "
                         f"offset {exc.start}") from None
    try:
        return src, json.loads(text)
    except json.JSONDecodeError as exc:
        raise ValueError(f"{src}, line {exc.lineno}, column {exc.colno}: not valid JSON "
                         f"({exc.msg})") from None


def _show(x: Any) -> str:
    """A short JSON rendering of a value for error messages."""
    try:
        s = json.dumps(x)
    except (TypeError, ValueError):
        s = repr(x)
    return s if len(s) <= 60 else s[:57] + "..."


class _Reader:
    """Validates one pose object; ``src`` prefixes every message."""

    def __init__(self, src: str, sk: Skeleton):
        self.src = src
        self.sk = sk
        self.scale = 1.0

    def fail(self, where: str, msg: str) -> ValueError:
        return ValueError(f"{self.src}: {where}: {msg}")

    # ------------------------------------------------------------------ scalars
    def number(self, where: str, x: Any) -> float:
        # bool is an int in Python but never a number in a pose file.
        if isinstance(x, bool) or not isinstance(x, (int, float)):
            raise self.fail(where, f"expected a number, found {_show(x)}")
        v = float(x)
        if not math.isfinite(v):
            raise self.fail(where, f"expected a finite number, found {_show(x)}")
        return v

    def vector(self, where: str, x: Any, d: int, what: str) -> np.ndarray:
        if not isinstance(x, list) or len(x) != d:
            got = f"{len(x)} values" if isinstance(x, list) else _show(x)
            raise self.fail(where, f"expected {what} (a list of {d} numbers), found {got}")
        return np.array([self.number(f"{where}[{k}]", v) for k, v in enumerate(x)])

    def table(self, key: str, x: Any) -> dict[int, tuple[str, Any]]:
        """``{bone: value}`` -> ``{bone index: (label, value)}``; each bone at most once."""
        if not isinstance(x, Mapping):
            raise self.fail(f'"{key}"', f"expected an object {{bone: value}}, found {_show(x)}")
        out: dict[int, tuple[str, Any]] = {}
        given: dict[int, Any] = {}
        for name, value in x.items():
            try:
                i = self.sk.bone_index(name)
            except ValueError as exc:
                raise self.fail(f'"{key}"', str(exc)) from None
            label = f'"{key}" bone {name!r}'
            if i in out:
                raise self.fail(label, f"bone {i} ({self.sk.names[i]!r}) is given twice "
                                       f"(also as {given[i]!r})")
            out[i] = (label, value)
            given[i] = name
        return out

    def twist_pairs(self, x: Any) -> dict[int, tuple[str, float, float]]:
        out = {}
        for i, (label, v) in self.table("twist", x).items():
            s, e = self.vector(label, v, 2, "[start, end] twist angles") * self.scale
            out[i] = (label, float(s), float(e))
        if self.sk.dim == 2 and any(s != 0 or e != 0 for _, s, e in out.values()):
            label = next(lb for lb, s, e in out.values() if s != 0 or e != 0)
            raise self.fail(label, "twist must be 0 for a 2D skeleton (bones twist about "
                                   "their own axis, which needs 3D)")
        return out

    # ------------------------------------------------------------------ forms
    def pose(self, obj: Any) -> Pose:
        if not isinstance(obj, Mapping):
            raise ValueError(f"{self.src}: expected a JSON object with keys "
                             f"{', '.join(JOINTS_KEYS)} or {', '.join(FK_KEYS)}, "
                             f"found {_show(obj)}")
        keys = set(obj)
        deg = obj.get("degrees", True)
        if not isinstance(deg, bool):
            raise self.fail('"degrees"', f"expected true or false, found {_show(deg)}")
        self.scale = math.pi / 180.0 if deg else 1.0
        if "joints" in keys:
            unknown = sorted(keys - set(JOINTS_KEYS))
            if unknown:
                raise self.fail(f"key {unknown[0]!r}", "not allowed with \"joints\"; the "
                                f"joints form takes {', '.join(JOINTS_KEYS)} (the "
                                f"forward-kinematics form takes {', '.join(FK_KEYS)})")
            return self.joints_form(obj)
        unknown = sorted(keys - set(FK_KEYS))
        if unknown:
            raise self.fail(f"key {unknown[0]!r}", "unknown key; expected "
                            f"{', '.join(FK_KEYS)} (forward kinematics) or "
                            f"{', '.join(JOINTS_KEYS)} (posed joints)")
        return self.fk_form(obj)

    def joints_form(self, obj: Mapping) -> Pose:
        sk = self.sk
        j, d = sk.n_joints, sk.dim
        J = obj["joints"]
        if not isinstance(J, list) or len(J) != j:
            got = f"{len(J)} rows" if isinstance(J, list) else _show(J)
            raise self.fail('"joints"', f"expected {j} posed joint positions (one per joint "
                                        f"of the skeleton), found {got}")
        C = np.array([self.vector(f'"joints"[{k}]', row, d, f"a {d}D position")
                      for k, row in enumerate(J)])
        theta = np.zeros((sk.n_bones, 2))
        for i, (_, s, e) in self.twist_pairs(obj.get("twist", {})).items():
            theta[i] = (s, e)
        try:
            return Pose.from_joints(sk, C, twist=theta)
        except ValueError as exc:
            raise self.fail('"joints"', str(exc)) from None

    def fk_form(self, obj: Mapping) -> Pose:
        sk = self.sk
        b, d = sk.n_bones, sk.dim
        L = np.tile(np.eye(d), (b, 1, 1))
        for i, (label, spec) in self.table("rotate", obj.get("rotate", {})).items():
            L[i] = self.rotation(label, spec)
        sigma = np.ones(b)
        for i, (label, v) in self.table("stretch", obj.get("stretch", {})).items():
            sigma[i] = self.number(label, v)
            if sigma[i] <= 0:
                raise self.fail(label, f"stretch must be > 0 (posed length / rest length), "
                                       f"found {_show(v)}")
        theta = np.zeros((b, 2))
        for i, (_, s, e) in self.twist_pairs(obj.get("twist", {})).items():
            theta[i] = (s, e)
        D = np.zeros((b, d))
        if "translate" in obj:
            tr = obj["translate"]
            if isinstance(tr, Mapping):
                for i, (label, v) in self.table("translate", tr).items():
                    D[i] = self.vector(label, v, d, f"a {d}D offset")
            else:
                D[sk.roots] = self.vector('"translate"', tr, d,
                                          f"a {d}D offset or {{bone: offset}}")
        return Pose.from_local(sk, L, stretch=sigma, twist=theta, offsets=D)

    def rotation(self, label: str, spec: Any) -> np.ndarray:
        d = self.sk.dim
        want = '{"axis": [x, y, z], "angle": a}' if d == 3 else '{"angle": a}'
        if not isinstance(spec, Mapping):
            raise self.fail(label, f"expected {want}, found {_show(spec)}")
        extra = sorted(set(spec) - ({"axis", "angle"} if d == 3 else {"angle"}))
        if extra:
            why = " (a 2D rotation has no axis)" if d == 2 and extra == ["axis"] else ""
            raise self.fail(label, f"unexpected key {extra[0]!r}{why}; expected {want}")
        if "angle" not in spec:
            raise self.fail(label, f'missing "angle"; expected {want}')
        angle = self.number(f'{label} "angle"', spec["angle"]) * self.scale
        if d == 2:
            return tf.rotation_2d(angle)
        if "axis" not in spec:
            raise self.fail(label, f'missing "axis"; expected {want}')
        axis = self.vector(f'{label} "axis"', spec["axis"], 3, "a 3D axis")
        if not np.any(axis):
            raise self.fail(f'{label} "axis"', "expected a non-zero axis, found [0, 0, 0]")
        return tf.axis_angle_to_matrix(axis, angle)


# ----------------------------------------------------------------------------- writing

#: Forms :func:`write_pose` can write.
POSE_FORMS = ("auto", "fk", "joints")


def pose_to_dict(pose: Pose, *, form: str = "auto", degrees: bool = True) -> dict:
    """The JSON object of a pose file describing ``pose`` (the inverse of :func:`read_pose`).

    Parameters
    ----------
    pose : Pose
    form : {"auto", "fk", "joints"}
        ``"fk"``: the forward-kinematics form (local rotations, stretch, twists,
        translations), which describes every pose exactly. ``"joints"``: the posed
        joints and absolute twists, which exists when shared joints agree and every
        rotation is the smallest one from the rest to the posed direction (no roll
        about the bone). ``"auto"``: the forward-kinematics form.
    degrees : bool
        Angles in degrees (``"degrees": true``) or radians.

    Returns
    -------
    dict
        Bones are named by name; entries equal to their default are left out.

    Raises
    ------
    ValueError
        ``form`` is unknown, or the pose cannot be written in it (the message says
        which bone breaks which condition).
    """
    if not isinstance(pose, Pose):
        raise TypeError(f"pose must be a stbs.Pose, got {type(pose).__name__}")
    if form not in POSE_FORMS:
        raise ValueError(f"form must be one of {', '.join(POSE_FORMS)}, got {form!r}")
    scale = 180.0 / math.pi if degrees else 1.0
    if form in ("auto", "fk"):
        fk, why = _fk_dict(pose, scale)
        if fk is not None:
            return {**fk, "degrees": degrees}
        if form == "fk":
            raise ValueError(f"pose: not expressible in the forward-kinematics form: {why}")
    joints, why_j = _joints_dict(pose, scale)
    if joints is not None:
        return {**joints, "degrees": degrees}
    if form == "joints":
        raise ValueError(f"pose: not expressible in the joints form: {why_j}")
    raise ValueError(f"pose: expressible in neither pose-file form (forward kinematics: {why}; "
                     f"joints: {why_j})")


def write_pose(path: str | os.PathLike, pose: Pose, *, form: str = "auto",
               degrees: bool = True) -> None:
    """Write ``pose`` as a JSON pose file that :func:`read_pose` reads back (atomically).

    Parameters
    ----------
    path : str or os.PathLike
        Destination file (its folder must exist); written to a temporary file and
        renamed, so a failure leaves an existing file untouched.
    pose : Pose
    form, degrees
        As in :func:`pose_to_dict`.

    Examples
    --------
    >>> import os, tempfile
    >>> import numpy as np
    >>> import stbs
    >>> sk = stbs.Skeleton([[0, 0, 0], [1, 0, 0], [2, 0, 0]], [[0, 1], [1, 2]],
    ...                    names=["upper", "fore"])
    >>> pose = stbs.forward_kinematics(sk, stretch=[1.0, 1.5], twist=np.radians([0, 0, 90]))
    >>> path = os.path.join(tempfile.mkdtemp(), "pose.json")
    >>> stbs.io.write_pose(path, pose)
    >>> back = stbs.io.read_pose(path, sk)
    >>> bool(np.allclose(back.twist, pose.twist) and np.allclose(back.stretch, pose.stretch))
    True
    """
    from ._atomic import atomic_open

    obj = pose_to_dict(pose, form=form, degrees=degrees)
    text = json.dumps(obj, indent=1)
    with atomic_open(path, "w") as f:
        f.write(text + "\n")


def _tol(pose: Pose) -> float:
    sk = pose.skeleton
    return 1e-9 * max(float(np.abs(sk.C).max()), float(np.abs(pose.origins).max()), 1.0)


def _num(x: float) -> float:
    x = float(x)
    return 0.0 if x == 0 else x


def _fk_dict(pose: Pose, scale: float) -> tuple[dict | None, str]:
    sk = pose.skeleton
    b, d = sk.n_bones, sk.dim
    tol = _tol(pose)
    L, D = pose.local()
    sig, th = pose.stretch, pose.twist
    obj: dict[str, Any] = {}
    rotate = {}
    for i in range(b):
        if np.abs(L[i] - np.eye(d)).max() <= 1e-15:
            continue
        if d == 2:
            rotate[sk.names[i]] = {"angle": _num(tf.angle_2d(L[i]) * scale)}
        else:
            axis, angle = tf.quat_to_axis_angle(tf.matrix_to_quat(L[i]))
            rotate[sk.names[i]] = {"axis": [_num(a) for a in axis],
                                   "angle": _num(angle * scale)}
    if rotate:
        obj["rotate"] = rotate
    stretch = {sk.names[i]: _num(sig[i]) for i in range(b) if sig[i] != 1.0}
    if stretch:
        obj["stretch"] = stretch
    twist = {sk.names[i]: [_num(th[i, 0] * scale), _num(th[i, 1] * scale)]
             for i in range(b) if np.any(th[i] != 0)}
    if twist:
        obj["twist"] = twist
    moved = np.flatnonzero(np.abs(D).max(axis=1) > tol)
    roots = sk.roots
    if moved.size and np.isin(moved, roots).all() and np.abs(
            D[roots] - D[roots[0]]).max() <= tol:
        obj["translate"] = [_num(x) for x in D[roots[0]]]
    elif moved.size:
        obj["translate"] = {sk.names[i]: [_num(x) for x in D[i]] for i in moved.tolist()}
    return obj, ""


def _joints_dict(pose: Pose, scale: float) -> tuple[dict | None, str]:
    sk = pose.skeleton
    tol = _tol(pose)
    R, O, sig, th = pose.rotations, pose.origins, pose.stretch, pose.twist
    vec = sk.B - sk.A
    posed = sig[:, None] * np.einsum("bij,bj->bi", R, vec)
    C = np.array(sk.C, dtype=np.float64)
    seen = np.zeros(sk.n_joints, dtype=bool)
    for i in range(sk.n_bones):
        for k, x in ((sk.BE[i, 0], O[i]), (sk.BE[i, 1], O[i] + posed[i])):
            if seen[k] and np.abs(C[k] - x).max() > tol:
                return None, f"bones meeting at joint {k} put it at different places"
            C[k], seen[k] = x, True
    smallest = tf.rotation_between(vec, posed)
    roll = np.abs(smallest - R).max(axis=(1, 2))
    if roll.max() > 1e-9:
        i = int(np.argmax(roll))
        return None, (f"bone {i} ({sk.names[i]!r}) is rolled about its own axis (use the "
                      "twist or the forward-kinematics form)")
    obj: dict[str, Any] = {"joints": [[_num(x) for x in row] for row in C]}
    twist = {sk.names[i]: [_num(th[i, 0] * scale), _num(th[i, 1] * scale)]
             for i in range(sk.n_bones) if np.any(th[i] != 0)}
    if twist:
        obj["twist"] = twist
    return obj, ""
