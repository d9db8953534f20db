"""Motion onto a rig: :func:`retarget` and :func:`joint_map` (see the package docs)."""

from __future__ import annotations

import os
import warnings
from collections.abc import Mapping
from typing import Any, Literal

import numpy as np

from .. import transforms as tf
from .._json import load_json
from ..clip import Clip
from ..motion import Motion
from ..pose import local_arrays
from ..skeleton import Skeleton
from .body import Body, Tree, read_body
from .names import parse_name

__all__ = ["retarget", "joint_map"]

# The capture's rest pose is its reference unless its bones stray further than this
# (root mean square, radians) from the rig's rest directions and a frame of the
# capture lies much closer (a file whose rest pose is not a body: Bandai Namco's).
_REST_OK = np.radians(25.0)
# Frames of the capture tried as the reference pose.
_CANDIDATES = 48
# A torso bone further than this from the capture's in the reference is not swung.
_ACROSS = np.radians(60.0)
# An up direction this close (radians) to a coordinate axis is that axis.
_SNAP = np.radians(25.0)


# ------------------------------------------------------------------ the two hierarchies
class _Side:
    """One side of a retargeting: a hierarchy as a :class:`Tree`, its :class:`Body`."""

    def __init__(self, names, tree: Tree, body: Body, n: int):
        self.names = names
        self.tree = tree
        self.body = body
        self.n = n                    # joints (bones) that can be mapped: 0..n-1


def _target(sk: Skeleton) -> _Side:
    """The rig: a node per bone at its start, a tip at each bone end no child starts at."""
    b = sk.n_bones
    has_conn = np.zeros(b, dtype=bool)
    kids = sk.parents >= 0
    has_conn[sk.parents[kids & sk.connected]] = True
    leaf = np.flatnonzero(~has_conn)
    parents = np.concatenate([sk.parents, leaf])
    X = np.vstack([sk.A, sk.B[leaf]])
    tips = np.concatenate([np.zeros(b, dtype=bool), np.ones(leaf.size, dtype=bool)])
    names = [nm.split(">")[0] for nm in sk.names] + [None] * leaf.size
    tree = Tree(parents, X, tips)
    return _Side(sk.names, tree, read_body(names, parents, X, tips), b)


def _source(motion: Motion) -> _Side:
    names = [None if e else nm for nm, e in zip(motion.names, motion.end_site, strict=True)]
    tree = Tree(motion.parents, motion.rest_positions(), motion.end_site)
    body = read_body(names, motion.parents, tree.X, motion.end_site)
    if body.pelvis < 0:
        # a rest pose that is not a body (every bone along one axis): the first frame
        X = motion.positions(0)[0]
        again = read_body(names, motion.parents, X, motion.end_site)
        if again.count() > body.count():
            body = again
    return _Side(motion.names, tree, body, motion.n_joints)


# ------------------------------------------------------------------ the mapping
def _map_repeated_roles(out: np.ndarray, tb: Body, sb: Body, s_chest: int, b: int) -> None:
    """Map the rig's unmapped spine and neck bones: one to one in order when the counts
    agree, else each to the capture joint whose place along the spine overlaps its own
    most (the capture's chest left out)."""
    for role in ("spine", "neck"):
        ts = [i for i in tb.find(role) if i < b and out[i] < 0]
        ss = [k for k in sb.find(role) if k != s_chest]
        if not ts or not ss:
            continue
        if len(ts) == len(ss):
            out[ts] = ss
            continue
        for i in ts:
            a, e = tb.span[i]

            def overlap(k, a=a, e=e):
                s0, s1 = sb.span[k]
                return (min(e, s1) - max(a, s0), -abs((a + e) - (s0 + s1)))
            out[i] = max(ss, key=overlap)


def _map_by_roles(out: np.ndarray, used: set, tb: Body, sb: Body, b: int) -> None:
    """Map each unmapped bone with a limb or head role to a capture joint of that role
    and side (the first not used yet)."""
    for i in range(b):
        role, side = tb.role[i], tb.side[i]
        if out[i] >= 0 or role in (None, "root", "spine", "neck"):
            continue
        cands = sb.find(role, side)
        if not cands:
            continue
        k = next((c for c in cands if c not in used), cands[0])
        out[i] = k
        used.add(k)


def _map_by_name_keys(out: np.ndarray, used: set, tgt: _Side, src: _Side, motion: Motion,
                      joints: list[int], base: list[str]) -> None:
    """Map the bones without a part (fingers, eyes, props) to the capture joint of the
    same name across conventions, shallow bones first, one bone each."""
    b = tgt.n
    tb, sb = tgt.body, src.body
    keys: dict[str, int] = {}
    for k in joints:
        if sb.role[k] is None:
            keys.setdefault(parse_name(motion.names[k]).key, k)
    for i in np.argsort(tgt.tree.depth[:b], kind="stable"):
        if out[i] < 0 and tb.role[i] is None:
            p = parse_name(base[i])
            k = keys.get(p.key, -1) if p.words else -1
            if k >= 0 and k not in used:        # one bone each: Thumb2 follows Thumb
                out[i] = k
                used.add(k)


def _auto_mapping(tgt: _Side, src: _Side, motion: Motion) -> np.ndarray:
    """Rig bone -> capture joint: by name when the rig is named as the capture (two
    thirds of its bones), else by body part, then by name across conventions."""
    b = tgt.n
    out = np.full(b, -1, dtype=np.int64)
    joints = [k for k in range(src.n) if not motion.end_site[k]]
    index = {motion.names[k]: k for k in joints}
    base = [nm.split(">")[0] for nm in tgt.names]
    if sum(nm in index for nm in base) >= max(1.0, 2.0 * b / 3.0):
        for i, nm in enumerate(base):
            out[i] = index.get(nm, -1)
    used = set(out[out >= 0].tolist())
    tb, sb = tgt.body, src.body
    t_chest, s_chest = _chest(tb, tgt.tree), _chest(sb, src.tree)
    if 0 <= t_chest < b and s_chest >= 0 and out[t_chest] < 0:
        out[t_chest] = s_chest
        used.add(s_chest)
    _map_repeated_roles(out, tb, sb, s_chest, b)
    _map_by_roles(out, used, tb, sb, b)
    _map_by_name_keys(out, used, tgt, src, motion, joints, base)
    return out


def _chest(body: Body, tree: Tree) -> int:
    """The spine joint the arms hang from (-1: none)."""
    tops = []
    for roles in body.limbs("arm").values():
        first = min(roles.values(), key=lambda k: tree.depth[k])
        up = next((a for a in tree.ancestors(first) if body.role[a] is not None), -1)
        if up >= 0 and body.role[up] == "spine":
            tops.append(up)
    return tops[0] if tops and all(t == tops[0] for t in tops) else -1


#: A mapping file larger than this is refused unread (a real one is a few kilobytes).
MAPPING_MAX_BYTES = 16 * 2**20


def _short(x: Any) -> str:
    """A name or value for a one-line message, at most about 60 characters."""
    if isinstance(x, str):
        return repr(x if len(x) <= 60 else x[:57] + "...")
    if x is None or isinstance(x, (bool, int, float)) and abs(x) < 1e20:
        return repr(x)
    if isinstance(x, Mapping):
        return "an object"
    return "a list" if isinstance(x, (list, tuple)) else f"a {type(x).__name__}"


def _read_mapping(path: str | os.PathLike) -> tuple[str, Any]:
    """A mapping file's JSON, read safely (:func:`stbs._json.load_json`): its size
    bounded, nesting, long integers, ``NaN`` and repeated keys refused. Errors name the
    file."""
    where = os.fspath(path)
    try:
        with open(where, "rb") as f:
            size = os.fstat(f.fileno()).st_size
            if size > MAPPING_MAX_BYTES:
                raise ValueError(f"{where}: expected a mapping file of at most "
                                 f"{MAPPING_MAX_BYTES >> 20} MiB, found {size >> 20} MiB")
            data = f.read()
    except FileNotFoundError:
        raise FileNotFoundError(f"mapping file not found: {where!r}") from None
    return where, load_json(data, where, what="mapping JSON {rig bone: capture joint}",
                            unique_keys=True)


def _given_mapping(mapping: Any, sk: Skeleton, motion: Motion) -> np.ndarray:
    if isinstance(mapping, (str, os.PathLike)):
        where, mapping = _read_mapping(mapping)
        src = f"{where}: mapping"
        if not isinstance(mapping, Mapping):
            raise ValueError(f"{src}: expected a JSON object {{rig bone: capture joint}}, got "
                             f"a JSON {type(mapping).__name__}")
    elif isinstance(mapping, Mapping):
        src = "mapping"
    else:
        raise TypeError(f"mapping must be a dict {{rig bone: motion joint}}, a JSON file of "
                        f"one, or None, got {type(mapping).__name__}")
    bones = {n: i for i, n in enumerate(sk.names)}
    joints = {n: k for k, n in enumerate(motion.names) if not motion.end_site[k]}
    out = np.full(sk.n_bones, -1, dtype=np.int64)
    given: dict[int, Any] = {}
    for bone, joint in mapping.items():
        i = bones.get(bone) if isinstance(bone, str) else None
        if i is None:
            if isinstance(bone, str) and bone.isascii() and bone.isdigit() and len(bone) <= 20:
                i = int(bone)
            elif isinstance(bone, (int, np.integer)) and not isinstance(bone, bool):
                i = int(bone)
            if i is None or not 0 <= i < sk.n_bones:
                raise ValueError(f"{src}: the rig has no bone {_short(bone)}; its bones are "
                                 f"{_listed(sk.names)}")
        if i in given:
            raise ValueError(f"{src}: bone {i} ({_short(sk.names[i])}) is given twice (as "
                             f"{_short(given[i])} and {_short(bone)})")
        given[i] = bone
        if joint is None:
            continue
        if not isinstance(joint, str) or joint not in joints:
            raise ValueError(f"{src}: the motion has no joint {_short(joint)} (for bone "
                             f"{_short(bone)}); its joints are {_listed(_joint_names(motion))}")
        out[i] = joints[joint]
    if not (out >= 0).any():
        raise ValueError(f"{src}: expected a capture joint for some bone, found none (every "
                         f"bone null or left out); the rig's bones are {_listed(sk.names, 20)}; "
                         f"the joints of {_where(motion)} are "
                         f"{_listed(_joint_names(motion), 20)}")
    return out


def _joint_names(motion: Motion) -> list[str]:
    """The motion's joints that turn something (its end sites left out)."""
    return [n for n, e in zip(motion.names, motion.end_site, strict=True) if not e]


def _listed(names, most: int = 40) -> str:
    # names cut to 60 characters: a message stays one readable line
    names = [n if len(n) <= 60 else n[:57] + "..." for n in names]
    if len(names) <= most:
        return ", ".join(names)
    return ", ".join(names[:most]) + f", ... ({len(names)} in all)"


def _where(motion: Motion) -> str:
    src = getattr(motion, "source", None)
    return repr(src) if src else "the motion"


def _check(motion, rig, twist, stretch) -> Skeleton:
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
    return sk


def _mapping(motion: Motion, sk: Skeleton, mapping, tgt: _Side, src: _Side) -> np.ndarray:
    m = _auto_mapping(tgt, src, motion) if mapping is None else _given_mapping(mapping, sk, motion)
    if not (m >= 0).any():
        raise ValueError(f"no joint of {_where(motion)} maps to a bone of the rig; the rig's "
                         f"bones are {_listed(sk.names, 20)}; the capture's joints are "
                         f"{_listed(_joint_names(motion), 20)}; give a mapping "
                         f"{{rig bone: capture joint}}")
    return m


def joint_map(motion: Motion, rig, *, mapping=None) -> dict[str, str | None]:
    """The capture joint that drives each bone of the rig in :func:`retarget`.

    Parameters
    ----------
    motion : Motion
    rig : Rig or Skeleton
    mapping : dict or str or os.PathLike, optional
        As in :func:`retarget`.

    Returns
    -------
    dict
        ``{rig bone: capture joint, or None for a bone that turns with its parent}``,
        in the rig's bone order; written as JSON it is a mapping file to edit.
    """
    sk = _check(motion, rig, "spread", "keep")
    tgt, src = _target(sk), _source(motion)
    m = _mapping(motion, sk, mapping, tgt, src)
    return {sk.names[i]: (motion.names[m[i]] if m[i] >= 0 else None) for i in range(sk.n_bones)}


# ------------------------------------------------------------------ frames and scale
def _snap(v: np.ndarray | None) -> np.ndarray | None:
    if v is None:
        return None
    n = np.linalg.norm(v)
    if n <= 1e-12:
        return None
    v = v / n
    ax = int(np.argmax(np.abs(v)))
    if np.arccos(min(1.0, abs(v[ax]))) <= _SNAP:
        e = np.zeros(3)
        e[ax] = np.sign(v[ax])
        return e
    return v


def _legs(body: Body, tree: Tree) -> list[tuple[int, int]]:
    """(first joint, lowest point) of each leg: the lowest point is where the leg's
    last joint's bone ends (a toe's tip)."""
    out = []
    for roles in body.limbs("leg").values():
        if not roles:
            continue
        first = min(roles.values(), key=lambda k: tree.depth[k])
        last = max(roles.values(), key=lambda k: tree.depth[k])
        e = tree.segment_end(last)
        out.append((first, e if e >= 0 else last))
    return out


def _up_vectors(body: Body, tree: Tree, X: np.ndarray) -> np.ndarray | None:
    """(..., 3) the body's up in poses X (..., n, 3): from the feet to the pelvis, else
    from the pelvis up the torso; None when neither is known."""
    p = body.pelvis
    if p < 0:
        return None
    legs = _legs(body, tree)
    if legs:
        v = sum(X[..., p, :] - X[..., low, :] for _, low in legs)
    else:
        top = next((body.find(r)[-1] for r in ("head", "neck", "spine") if body.find(r)), -1)
        if top < 0:
            return None
        v = X[..., top, :] - X[..., p, :]
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.where(n > 1e-12, v / np.maximum(n, 1e-300), 0.0)


def _hip_height(body: Body, tree: Tree, X: np.ndarray, up: np.ndarray) -> float | None:
    """How high the pelvis stands over the soles with straight legs: the pelvis above
    the hip joint, thigh and shin lengths, the ankle above the sole (mean of the legs)."""
    p = body.pelvis
    got = []
    for roles in body.limbs("leg").values():
        if not {"thigh", "shin", "foot"} <= set(roles):
            continue
        th, sh, ft = roles["thigh"], roles["shin"], roles["foot"]
        chain = [k for k in tree.path(ft)]
        low = min(float(X[k] @ up) for k in chain)
        got.append(float((X[p] - X[th]) @ up) + np.linalg.norm(X[sh] - X[th])
                   + np.linalg.norm(X[ft] - X[sh]) + float(X[ft] @ up) - low)
    return float(np.mean(got)) if got and np.mean(got) > 0 else None


def _heading(up: np.ndarray, a: np.ndarray, b: np.ndarray, w: np.ndarray) -> np.ndarray:
    """The turn about ``up`` that best takes directions a onto b (weighted, across up)."""
    a = a - (a @ up)[:, None] * up
    b = b - (b @ up)[:, None] * up
    s = float(np.sum(w * (np.cross(a, b) @ up)))
    c = float(np.sum(w * np.einsum("ij,ij->i", a, b)))
    ang = np.arctan2(s, c) if abs(s) + abs(c) > 1e-12 else 0.0
    return tf.axis_angle_to_matrix(up[None], np.array([ang]))[0]


# ------------------------------------------------------------------ retarget
def retarget(motion: Motion, rig, *, mapping=None,
             twist: Literal["spread", "joint"] = "spread",
             stretch: Literal["keep", "match"] = "keep") -> Clip:
    """A motion as a clip of poses of a rig's skeleton (see the package docs).

    Parameters
    ----------
    motion : Motion
        The source, e.g. from :func:`stbs.io.read_bvh`.
    rig : Rig or Skeleton
        The target (3D); a :class:`stbs.Rig` gives its ``skeleton``.
    mapping : dict or str or os.PathLike, optional
        ``{rig bone (name or index): motion joint name (or None: follow the parent)}``,
        or a JSON file holding one; it gives every bone's joint (bones it leaves out
        follow their parents). Default: by body part, read from the names of both
        (CMU, Mixamo, LAFAN, Bandai Namco, Blender, Unreal, ``RootJoint``/``lHip`` ... conventions)
        or, for unnamed joints, from the skeleton's shape (:func:`joint_map` shows
        the result).
    twist : {"spread", "joint"}
        Spread each joint's twist along the bone ending there, unwrapped over time,
        or keep it rigid at the joint.
    stretch : {"keep", "match"}
        ``"keep"``: every stretch 1. ``"match"``: each bone's stretch is the source
        bone's length in that frame over the target's rest length, after scaling the
        source as the root's travel is scaled (so a source in other units, or another
        build, changes proportions only).

    Returns
    -------
    Clip
        One key per motion frame at its time, ``fps`` the motion's.

    Raises
    ------
    ValueError
        A 2D rig, a bad choice, no joint that maps to a bone, or a mapping naming a
        bone or joint that does not exist (the message lists the names there are).

    Warns
    -----
    UserWarning
        Rig bones that are body parts (an arm, a leg, the spine) but found no joint of
        the motion; they follow their parents.
    """
    sk = _check(motion, rig, twist, stretch)
    tgt, src_side = _target(sk), _source(motion)
    src = _mapping(motion, sk, mapping, tgt, src_side)
    b, f = sk.n_bones, motion.n_frames
    if mapping is None:
        lost = [sk.names[i] for i in range(b) if src[i] < 0 and tgt.body.role[i]
                not in (None, "root")]
        if lost:
            warnings.warn(f"retarget: {len(lost)} rig bones that are body parts match no "
                          f"joint of {_where(motion)} and follow their parents: "
                          f"{_listed(lost, 12)} (a mapping names their joints)",
                          UserWarning, stacklevel=2)
    s_tree = src_side.tree
    Rg, tg = motion.global_transforms()
    end = _source_ends(sk, src, s_tree)
    up_t, up_s = _ups(tgt, src_side, tg)
    ref = _Reference(sk, src, end, s_tree.X, tg, up_t, up_s, tol=1e-6 * s_tree.size)
    C = ref.constants(Rg, tgt.body)
    ok = ref.ok
    scale = _scale(sk, tgt, src_side, ref, up_t, up_s)

    sigma = np.ones((f, b))
    if stretch == "match" and ok.size:
        cur = np.linalg.norm(tg[:, end[ok]] - tg[:, src[ok]], axis=2)
        sigma[:, ok] = np.maximum(scale * cur / sk.lengths[ok], 1e-6)

    follow = _siblings(sk, src) if mapping is None else np.full(b, -1, dtype=np.int64)
    R, O = _world(sk, src, follow, _carriers(sk, src, s_tree), ref.G, Rg, C, sigma)
    O += _travel(sk, tgt, src_side, src, tg, ref, up_t, up_s, scale, O)[:, None]
    theta = _spread(sk, src, R) if twist == "spread" else np.zeros((f, b, 2))
    L, D = local_arrays(sk, R, O, sigma, theta)
    return Clip.from_local(sk, motion.times, rotations=L, stretch=sigma, twist=theta,
                           offsets=D, fps=motion.fps)


def _source_ends(sk: Skeleton, src: np.ndarray, s_tree: Tree) -> np.ndarray:
    """For each mapped bone, the capture joint where its source bone ends: the joint of
    the rig bone that continues it (past a joint at the same place, as CMU's LowerBack
    at the Hips), else the next joint along the capture's main chain; -1: none."""
    end = np.full(sk.n_bones, -1, dtype=np.int64)
    X0, tol = s_tree.X, 1e-6 * s_tree.size
    for i in np.flatnonzero(src >= 0):
        s = src[i]
        for c in np.flatnonzero((sk.parents == i) & sk.connected):
            k = src[c]
            if k >= 0 and k != s and s_tree.is_below(k, s):
                end[i] = k if np.linalg.norm(X0[k] - X0[s]) > tol else s_tree.segment_end(k)
                if end[i] >= 0:
                    break
        else:
            end[i] = s_tree.segment_end(s)
    return end


def _ups(tgt: _Side, src_side: _Side, tg: np.ndarray):
    """(up of the rig in its rest pose, up of the capture's world over its frames), each
    snapped to an axis near it; (None, None) unless both are known."""
    up_t = _snap(_up_vectors(tgt.body, tgt.tree, tgt.tree.X))
    f = tg.shape[0]
    sample = np.unique(np.linspace(0, f - 1, min(f, 200)).astype(int))
    v = _up_vectors(src_side.body, src_side.tree, tg[sample])
    up_s = None if v is None else _snap(v.mean(axis=0))
    if up_t is None or up_s is None:
        return None, None
    return up_t, up_s


class _Reference:
    """The capture's reference pose and the turn ``G`` between the two worlds.

    The reference is the capture's rest pose, or, when its bones stray far from the
    rig's rest directions (root mean square over the mapped bones, weighted by the rig's
    bone lengths) and a frame of the capture lies much nearer, that frame. ``G`` takes
    the rig's up to the capture's and turns about it to fit the mapped bones'
    directions (identity when the up axes are unknown).
    """

    def __init__(self, sk, src, end, X0, tg, up_t, up_s, *, tol):
        self.sk, self.src, self.end, self.tol = sk, src, end, tol
        self.up_t, self.up_s = up_t, up_s
        mapped = np.flatnonzero(src >= 0)
        self.ok = mapped[end[mapped] >= 0]
        self.frame = -1
        self.G, self.d, self.good, cost = self._fit(X0)
        self.X = X0
        if self.ok.size and cost > _REST_OK ** 2:
            f = tg.shape[0]
            cand = np.unique(np.linspace(0, f - 1, min(f, _CANDIDATES)).astype(int))
            fits = [(self._fit(tg[k]), k) for k in cand]
            (G, d, good, c), k = min(fits, key=lambda x: x[0][3])
            if c < cost / 1.5:
                self.G, self.d, self.good, self.frame, self.X = G, d, good, k, tg[k]

    def _fit(self, X):
        ok, sk = self.ok, self.sk
        u = sk.axes[ok]
        w = sk.lengths[ok] / max(sk.lengths[ok].sum(), 1e-300)
        d = X[self.end[ok]] - X[self.src[ok]]
        n = np.linalg.norm(d, axis=1)
        d = d / np.maximum(n, 1e-300)[:, None]
        good = n > self.tol
        if self.up_t is None:
            G = np.eye(3)
        else:
            R1 = tf.rotation_between(self.up_t[None], self.up_s[None])[0]
            G = _heading(self.up_s, u[good] @ R1.T, d[good], w[good]) @ R1 \
                if good.any() else R1
        c = np.clip(np.einsum("ij,ij->i", u @ G.T, d), -1, 1)
        cost = float(np.sum(w * good * np.arccos(c) ** 2) / max(np.sum(w * good), 1e-300))
        return G, d, good, cost

    def constants(self, Rg: np.ndarray, t_body: Body) -> np.ndarray:
        """(b, 3, 3) ``C_i = F_s(ref)^T M_i^T G`` so that ``R_i(t) = G^T F_s(t) C_i``: the
        source joint's turn from the reference, its bone first swung (``M_i``, the
        smallest rotation) from its direction there onto the rig bone's rest direction.
        A torso bone lying across the capture's (a quadruped's under a biped's) is not
        swung: it keeps its rest direction and turns as the capture's does (swung
        upright it would fold the body in two)."""
        sk, src, ok, G = self.sk, self.src, self.ok, self.G
        b = sk.n_bones
        mapped = np.flatnonzero(src >= 0)
        F = np.tile(np.eye(3), (b, 1, 1)) if self.frame < 0 else Rg[self.frame,
                                                                       np.maximum(src, 0)]
        M = np.tile(np.eye(3), (b, 1, 1))
        if ok.size:
            target = sk.axes[ok] @ G.T
            across = np.einsum("ij,ij->i", self.d, target) < np.cos(_ACROSS)
            torso = np.array([t_body.role[i] in ("pelvis", "spine", "neck", "head")
                              for i in ok])
            swing = self.good & ~(across & torso)
            M[ok[swing]] = tf.rotation_between(self.d[swing], target[swing])
        C = np.tile(np.eye(3), (b, 1, 1))
        C[mapped] = np.einsum("bji,bkj,kl->bil", F[mapped], M[mapped], G)
        return C


def _scale(sk, tgt: _Side, src_side: _Side, ref: _Reference, up_t, up_s) -> float:
    """Capture units to rig units: the ratio of the hip heights (the capture's in its
    reference pose), else of the mapped bones' lengths."""
    if up_t is not None:
        h_t = _hip_height(tgt.body, tgt.tree, tgt.tree.X, up_t)
        h_s = _hip_height(src_side.body, src_side.tree, ref.X, up_s)
        if h_t and h_s:
            return h_t / h_s
    ok = ref.ok
    ls = np.linalg.norm(ref.X[ref.end[ok]] - ref.X[ref.src[ok]], axis=1).sum() if ok.size else 0
    return float(sk.lengths[ok].sum() / ls) if ls > 0 else 1.0


def _world(sk, src, follow, carrier, G, Rg, C, sigma):
    """World rotations (f, b, 3, 3) and starts (f, b, 3) of every bone, parents first: a
    mapped bone turns as ``G^T F_s(t) C_i``, a bone that follows a sibling or its
    parent as that bone; a bone hangs where its parent carries it (DESIGN §2, no
    twist), or where the bone its joint hangs from in the capture carries it."""
    f, b = sigma.shape
    R = np.empty((f, b, 3, 3))
    O = np.empty((f, b, 3))
    vec = sk.B - sk.A
    for i in _order(sk, carrier, follow):
        p = sk.parents[i]
        if src[i] >= 0:
            R[:, i] = np.einsum("ji,fjk,kl->fil", G, Rg[:, src[i]], C[i])
        elif follow[i] >= 0:
            R[:, i] = R[:, follow[i]]
        elif p >= 0:
            R[:, i] = R[:, p]
        else:
            R[:, i] = np.eye(3)
        k = carrier[i]
        if k >= 0:
            O[:, i] = O[:, k] + R[:, k] @ (sk.A[i] - sk.A[k])
        elif p >= 0:
            rel = sk.hang[i] * (sigma[:, p, None] - 1) * vec[p] + (sk.A[i] - sk.A[p])
            O[:, i] = O[:, p] + np.einsum("fij,fj->fi", R[:, p], rel)
        else:
            O[:, i] = sk.A[i]
    return R, O


def _spread(sk, src, R) -> np.ndarray:
    """(f, b, 2) twists: each mapped connected child's twist about its parent's axis,
    unwrapped over time, as the parent's end twist; only where the parent has this one
    child and no other bone starts at the joint."""
    f, b = R.shape[:2]
    theta = np.zeros((f, b, 2))
    starts = np.bincount(sk.BE[:, 0], minlength=sk.n_joints)
    nkids = np.bincount(sk.parents[sk.parents >= 0], minlength=b)
    for i in np.flatnonzero(src >= 0):
        p = sk.parents[i]
        if p < 0 or not sk.connected[i] or nkids[p] != 1 or starts[sk.BE[i, 0]] != 1:
            continue
        Lr = np.einsum("fji,fjk->fik", R[:, p], R[:, i])
        theta[:, p, 1] = np.unwrap(_twist_about(Lr, sk.axes[p]))
    return theta


def _carriers(sk: Skeleton, src: np.ndarray, s_tree: Tree) -> np.ndarray:
    """For a mapped bone whose joint, in the capture, hangs below the joint of a bone that
    is not its ancestor in the rig (an IK-driven foot parented to the rig's root), that
    bone; -1 for every other bone (placed by its own parent)."""
    b = sk.n_bones
    out = np.full(b, -1, dtype=np.int64)
    anc = [set() for _ in range(b)]
    for i in sk.order:
        p = sk.parents[i]
        if p >= 0:
            anc[i] = anc[p] | {int(p)}
    by_joint: dict[int, list[int]] = {}
    for i in np.flatnonzero(src >= 0):
        by_joint.setdefault(int(src[i]), []).append(int(i))
    for i in np.flatnonzero(src >= 0):
        for a in s_tree.ancestors(int(src[i])):
            bones = [k for k in by_joint.get(a, []) if k != i]
            if not bones:
                continue
            if not any(k in anc[i] for k in bones):
                # the nearest such bone carries it; none of them may lie below it
                k = min(bones, key=lambda k: np.linalg.norm(sk.B[k] - sk.A[i]))
                if i not in anc[k]:
                    out[i] = k
            break
    return out


def _siblings(sk: Skeleton, src: np.ndarray) -> np.ndarray:
    """For an unmapped bone, a mapped sibling it turns with: one starting at the same
    place and named alike but for digits (``Palm1.L``, ``Palm3.L`` beside ``Palm2.L``,
    the hand); -1 for every other bone."""
    out = np.full(sk.n_bones, -1, dtype=np.int64)
    tol = 1e-6 * max(float(np.ptp(sk.C, axis=0).max()), 1e-300)
    key = [parse_name(n.split(">")[0]) for n in sk.names]
    for i in np.flatnonzero(src < 0):
        if not key[i].words:
            continue
        for k in np.flatnonzero((sk.parents == sk.parents[i]) & (src >= 0)):
            if key[k] == key[i] and np.linalg.norm(sk.A[k] - sk.A[i]) <= tol:
                out[i] = k
                break
    return out


def _order(sk: Skeleton, carrier: np.ndarray, follow: np.ndarray) -> list[int]:
    """The bones with every parent, carrier and bone followed before the bones that
    depend on them; a carrier that would come after its bone (a loop) is dropped."""
    done = np.zeros(sk.n_bones, dtype=bool)
    out: list[int] = []
    for i in sk.order:
        stack = [int(i)]
        seen = set()
        while stack:
            k = stack[-1]
            if done[k]:
                stack.pop()
                continue
            need = [d for d in (sk.parents[k], carrier[k], follow[k]) if d >= 0 and not done[d]]
            if not need:
                done[k] = True
                out.append(k)
                stack.pop()
                continue
            if k in seen:              # a loop: place the bone by its parent
                carrier[k] = follow[k] = -1
                continue
            seen.add(k)
            stack.extend(int(d) for d in need)
    return out


def _travel(sk, tgt: _Side, src_side: _Side, src, tg, ref, up_t, up_s, scale, O):
    """(f, 3) the translation that puts the rig's pelvis where the capture's goes:
    across the ground from where the rig stands, scaled; up and down as high over the
    rig's ground as the capture's pelvis over its floor, scaled."""
    t_body, s_body, s_tree = tgt.body, src_side.body, src_side.tree
    G = ref.G
    tp = t_body.pelvis if 0 <= t_body.pelvis < sk.n_bones else int(sk.roots[0])
    sp = s_body.pelvis
    if sp < 0:
        sp = int(src[tp]) if src[tp] >= 0 else int(np.flatnonzero(s_tree.parents < 0)[0])
    p = tg[:, sp]
    h_t = None if up_t is None else _hip_height(t_body, tgt.tree, tgt.tree.X, up_t)
    legs = _legs(s_body, s_tree)
    if h_t is not None and legs:
        # the capture's floor: low points of the legs (a foot is down most of the time)
        idx = sorted({k for first, low in legs for k in s_tree.path(first)})
        floor = float(np.quantile((tg[:, idx] @ up_s).min(axis=1), 0.1))
        across = p - p[:1]
        across = across - (across @ up_s)[:, None] * up_s
        disp = scale * across @ G + (scale * (p @ up_s - floor) - h_t)[:, None] * up_t
    else:
        disp = scale * (p - ref.X[sp]) @ G
    return sk.A[tp] + disp - O[:, tp]


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
