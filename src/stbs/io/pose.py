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

Limits: every number (coordinate, offset, angle, twist, axis component) has a
magnitude of at most :data:`MAX_VALUE` (1e6; twists past 360 degrees are kept), and a
stretch lies from :data:`MIN_STRETCH` to :data:`MAX_STRETCH` (1e-6 to 1e6), given or
(joints form) implied by the posed joints. A file is read as JSON of at most 256 MiB,
nested at most 64 deep, with finite numbers and integers of at most 20 digits, each key
at most once in an object.

Errors are one :class:`ValueError` naming the file (or ``pose`` for a dict), the
key and the bone, what was expected and what was found: a file that is not such
JSON, unknown keys, a key given twice, a mixture of both forms, a bone that does not
exist or is listed twice, wrong vector lengths, non-numbers (``true`` and strings
included), NaN or infinity, numbers beyond the limits, a stretch <= 0, a zero axis, a
zero-length posed bone, a non-zero twist on a 2D skeleton.
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
from .._json import read_json
from ..pose import Pose
from ..skeleton import Skeleton

__all__ = ["read_pose", "write_pose", "pose_to_dict", "POSE_FORMS", "JOINTS_KEYS", "FK_KEYS",
           "MAX_VALUE", "MIN_STRETCH", "MAX_STRETCH"]

#: Keys of the joints form.
JOINTS_KEYS = ("joints", "twist", "degrees")
#: Keys of the forward-kinematics form.
FK_KEYS = ("rotate", "stretch", "twist", "translate", "degrees")
#: Largest magnitude of a number in a pose: a coordinate, an offset, an angle (in the
#: pose's unit), a twist or an axis component.
MAX_VALUE = 1e6
#: Smallest and largest stretch (posed length / rest length).
MIN_STRETCH = 1e-6
MAX_STRETCH = 1e6


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


def _load(p: Path, what: str = "pose") -> tuple[str, Any]:
    """A JSON file read safely (:func:`stbs._json.read_json`: bounded size and
    nesting, finite numbers, integers of bounded length), each key at most once in an
    object."""
    path, obj = read_json(p, what, unique_keys=True)
    return str(path), obj


def _show(x: Any, budget: int = 60) -> str:
    """A short JSON-like rendering of a value for error messages: never longer than
    about ``budget`` characters, whatever the value's size or nesting."""
    out = _render(x, budget, 3)
    return out if len(out) <= budget else out[:budget - 3] + "..."


def _key(x: Any) -> str:
    """A key or bone name for messages: Python's quoting, cut to 60 characters."""
    if isinstance(x, str):
        return repr(x if len(x) <= 60 else x[:57] + "...")
    return _show(x)


def _render(x: Any, budget: int, depth: int) -> str:
    if x is None or isinstance(x, bool):
        return json.dumps(x)
    if isinstance(x, int):
        if abs(x) < 10 ** 20:
            return str(x)
        return f"<an integer of about {int(x.bit_length() * 0.30103) + 1} digits>"
    if isinstance(x, float):
        return json.dumps(x)
    if isinstance(x, str):
        return json.dumps(x[:budget])
    if isinstance(x, (list, tuple, Mapping)):
        mapping = isinstance(x, Mapping)
        if depth <= 0:
            return "{...}" if mapping else "[...]"
        parts, used = [], 2
        for item in (x.items() if mapping else x):
            if used > budget:
                parts.append("...")
                break
            part = (f"{_render(item[0], budget, 0)}: {_render(item[1], budget, depth - 1)}"
                    if mapping else _render(item, budget, depth - 1))
            parts.append(part)
            used += len(part) + 2
        body = ", ".join(parts)
        return "{" + body + "}" if mapping else "[" + body + "]"
    return f"<{type(x).__name__}>"


def _quats(R: np.ndarray, d: int) -> np.ndarray:
    """(..., d, d) rotations as (..., 4) unit quaternions (2D: about z)."""
    if d == 3:
        return tf.matrix_to_quat(R)
    half = 0.5 * tf.angle_2d(R)
    q = np.zeros(R.shape[:-2] + (4,))
    q[..., 0], q[..., 3] = np.cos(half), np.sin(half)
    return q


class _Reader:
    """Validates one pose object; ``src`` prefixes every message."""

    def __init__(self, src: str, sk: Skeleton):
        self.src = src
        self.sk = sk
        self.scale = 1.0
        # rotations of the forward-kinematics form noted until turn(): (slot, bone,
        # axis, angle in radians)
        self._turns: list[tuple[int, int, list[float], float]] = []

    def fail(self, where: str, msg: str) -> ValueError:
        return ValueError(f"{self.src}: {where}: {msg}")

    # ------------------------------------------------------------------ scalars
    def number(self, where: str, x: Any, *, bound: float = MAX_VALUE) -> float:
        # bool is an int in Python but never a number in a pose file.
        if isinstance(x, bool) or not isinstance(x, (int, float)):
            raise self.fail(where, f"expected a number, found {_show(x)}")
        # compared before float(): an integer of any length, without OverflowError
        if not abs(x) <= bound:
            what = "a finite number" if isinstance(x, float) and not math.isfinite(x) else \
                f"a number of magnitude at most {bound:g}"
            raise self.fail(where, f"expected {what}, found {_show(x)}")
        return float(x)

    def vector(self, where: str, x: Any, d: int, what: str) -> np.ndarray:
        if not isinstance(x, (list, tuple)) or len(x) != d:
            got = f"{len(x)} values" if isinstance(x, (list, tuple)) else _show(x)
            raise self.fail(where, f"expected {what} (a list of {d} numbers), found {got}")
        return np.array([self.number(f"{where}[{k}]", v) for k, v in enumerate(x)])

    def bone(self, key: str, name: Any) -> int:
        """The bone ``name`` names (a name, an index, or a string of digits)."""
        sk = self.sk
        if isinstance(name, str) and name in sk.names:
            return sk.names.index(name)
        i = None
        if isinstance(name, int) and not isinstance(name, bool):
            i = name
        elif isinstance(name, str) and name.isascii() and name.isdigit() and len(name) <= 20:
            i = int(name)
        if i is not None and 0 <= i < sk.n_bones:
            return i
        names = ", ".join(_key(n) for n in sk.names[:8]) + (", ..." if sk.n_bones > 8 else "")
        raise self.fail(f'"{key}"', f"bone {_key(name)} does not exist; bones are "
                                    f"0..{sk.n_bones - 1} or names {names}")

    def table(self, key: str, x: Any) -> dict[int, tuple[str, Any]]:
        """``{bone: value}`` -> ``{bone index: (label, value)}``; each bone at most once."""
        if not isinstance(x, Mapping):
            raise self.fail(f'"{key}"', f"expected an object {{bone: value}}, found {_show(x)}")
        out: dict[int, tuple[str, Any]] = {}
        given: dict[int, Any] = {}
        for name, value in x.items():
            i = self.bone(key, name)
            label = f'"{key}" bone {_key(name)}'
            if i in out:
                raise self.fail(label, f"bone {i} ({_key(self.sk.names[i])}) is given twice "
                                       f"(also as {_key(given[i])})")
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
        L, sigma, theta, D = self.defaults(1)
        joints = self.into(obj, 0, sigma, theta, D, L)
        if joints is not None:
            return joints
        self.turn(L)
        return Pose.from_local(self.sk, L[0], stretch=sigma[0], twist=theta[0], offsets=D[0])

    def defaults(self, n: int, *, quats: bool = False
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Local-frame arrays of ``n`` rest poses: rotations (n, b, d, d) (``quats``: unit
        quaternions (n, b, 4), ``(w, x, y, z)``, 2D about z), stretch (n, b), twist
        (n, b, 2), offsets (n, b, d)."""
        b, d = self.sk.n_bones, self.sk.dim
        if quats:
            L = np.zeros((n, b, 4))
            L[..., 0] = 1.0
        else:
            L = np.tile(np.eye(d), (n, b, 1, 1))
        return L, np.ones((n, b)), np.zeros((n, b, 2)), np.zeros((n, b, d))

    def into(self, obj: Any, k: int, sigma: np.ndarray, theta: np.ndarray, D: np.ndarray,
             L: np.ndarray) -> Pose | None:
        """Write the pose ``obj`` describes, in the local frame (:meth:`stbs.Pose.local`),
        into slot ``k`` of the arrays of :meth:`defaults`. The rotations of the
        forward-kinematics form are only noted, all turned into matrices at once by
        :meth:`turn`; a pose of the joints form is made, written whole, and returned."""
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
            unknown = sorted(keys - set(JOINTS_KEYS), key=str)
            if unknown:
                raise self.fail(f"key {_key(unknown[0])}", "not allowed with \"joints\"; the "
                                f"joints form takes {', '.join(JOINTS_KEYS)} (the "
                                f"forward-kinematics form takes {', '.join(FK_KEYS)})")
            pose = self.joints_form(obj)
            Lk, D[k] = pose.local()
            L[k] = Lk if L.ndim == 4 else _quats(Lk, self.sk.dim)
            sigma[k], theta[k] = pose.stretch, pose.twist
            return pose
        unknown = sorted(keys - set(FK_KEYS), key=str)
        if unknown:
            raise self.fail(f"key {_key(unknown[0])}", "unknown key; expected "
                            f"{', '.join(FK_KEYS)} (forward kinematics) or "
                            f"{', '.join(JOINTS_KEYS)} (posed joints)")
        self.fk_form(obj, k, sigma[k], theta[k], D[k])
        return None

    def turn(self, L: np.ndarray) -> None:
        """The noted rotations, in one batch, into ``L``: matrices (n, b, d, d) or
        quaternions (n, b, 4), as :meth:`defaults` made it."""
        if not self._turns:
            return
        k, i, axes, angles = (np.array(x) for x in zip(*self._turns, strict=True))
        self._turns = []
        if self.sk.dim == 2:
            if L.ndim == 4:
                L[k, i] = tf.rotation_2d(angles)
            else:
                L[k, i] = 0.0
                L[k, i, 0], L[k, i, 3] = np.cos(0.5 * angles), np.sin(0.5 * angles)
            return
        # each axis scaled to a largest component of 1 first: a tiny axis (1e-200) has a
        # norm
        axes = axes / np.abs(axes).max(axis=1, keepdims=True)
        q = tf.axis_angle_to_quat(axes, angles)
        L[k, i] = tf.quat_to_matrix(q) if L.ndim == 4 else q

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
            pose = Pose.from_joints(sk, C, twist=theta)
        except ValueError as exc:
            raise self.fail('"joints"', str(exc)) from None
        bad = np.flatnonzero(~((pose.stretch >= MIN_STRETCH) & (pose.stretch <= MAX_STRETCH)))
        if bad.size:
            i = int(bad[0])
            raise self.fail('"joints"', f"bone {i} ({_key(sk.names[i])}): expected a posed "
                                        f"length from {MIN_STRETCH:g} to {MAX_STRETCH:g} times "
                                        f"its rest length, found {pose.stretch[i]:.6g} times")
        return pose

    def fk_form(self, obj: Mapping, k: int, sigma: np.ndarray, theta: np.ndarray,
                D: np.ndarray) -> None:
        """Stretch (b,), twist (b, 2) and offsets (b, d) of slot ``k`` from ``obj``;
        its rotations noted for :meth:`turn`."""
        sk = self.sk
        d = sk.dim
        for i, (label, spec) in self.table("rotate", obj.get("rotate", {})).items():
            axis, angle = self.rotation(label, spec)
            self._turns.append((k, i, axis, angle))
        for i, (label, v) in self.table("stretch", obj.get("stretch", {})).items():
            sigma[i] = self.number(label, v)
            if sigma[i] <= 0:
                raise self.fail(label, f"stretch must be > 0 (posed length / rest length), "
                                       f"found {_show(v)}")
            if not MIN_STRETCH <= sigma[i] <= MAX_STRETCH:
                raise self.fail(label, f"expected a stretch from {MIN_STRETCH:g} to "
                                       f"{MAX_STRETCH:g} (posed length / rest length), found "
                                       f"{_show(v)}")
        if "twist" in obj:
            for i, (_, s, e) in self.twist_pairs(obj["twist"]).items():
                theta[i] = (s, e)
        if "translate" in obj:
            tr = obj["translate"]
            if isinstance(tr, Mapping):
                for i, (label, v) in self.table("translate", tr).items():
                    D[i] = self.vector(label, v, d, f"a {d}D offset")
            else:
                D[sk.roots] = self.vector('"translate"', tr, d,
                                          f"a {d}D offset or {{bone: offset}}")

    def rotation(self, label: str, spec: Any) -> tuple[list[float], float]:
        """The axis (3 numbers, not all 0; 2D: none) and angle (radians) of a rotation."""
        d = self.sk.dim
        want = '{"axis": [x, y, z], "angle": a}' if d == 3 else '{"angle": a}'
        if not isinstance(spec, Mapping):
            raise self.fail(label, f"expected {want}, found {_show(spec)}")
        extra = sorted(set(spec) - ({"axis", "angle"} if d == 3 else {"angle"}), key=str)
        if extra:
            why = " (a 2D rotation has no axis)" if d == 2 and extra == ["axis"] else ""
            raise self.fail(label, f"unexpected key {_key(extra[0])}{why}; expected {want}")
        if "angle" not in spec:
            raise self.fail(label, f'missing "angle"; expected {want}')
        angle = self.number(f'{label} "angle"', spec["angle"]) * self.scale
        if d == 2:
            return [0.0, 0.0, 1.0], angle
        if "axis" not in spec:
            raise self.fail(label, f'missing "axis"; expected {want}')
        axis = self.vector(f'{label} "axis"', spec["axis"], 3, "a 3D axis")
        if not np.any(axis):
            raise self.fail(f'{label} "axis"', "expected a non-zero axis, found [0, 0, 0]")
        return axis.tolist(), angle


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
    turned = np.flatnonzero(np.abs(L - np.eye(d)).reshape(b, -1).max(axis=1, initial=0)
                            > 1e-15)
    if d == 3 and turned.size:      # every turned bone's axis and angle at once
        axes, angles = tf.quat_to_axis_angle(tf.matrix_to_quat(L[turned]))
    for k, i in enumerate(turned):
        if d == 2:
            rotate[sk.names[i]] = {"angle": _num(tf.angle_2d(L[i]) * scale)}
        else:
            rotate[sk.names[i]] = {"axis": [_num(a) for a in axes[k]],
                                   "angle": _num(angles[k] * scale)}
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
