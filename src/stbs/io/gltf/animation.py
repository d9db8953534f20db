"""glTF animations as clips that equal the file's node hierarchy at any time.

A glTF animation keys each node's translation ``t``, rotation ``r`` and scale ``s``
(LINEAR, STEP or CUBICSPLINE); a node's local matrix is ``N = T(t) R(r) S(s)`` and the
skin of joint ``j`` at time ``τ`` is ``M_j = G_j(τ) IBM_j``. The clip's bone ``i``
(joint ``i``, bind ``B_i = IBM_i^-1``) takes the rigid part of ``M_i``: rotation
``R_i = rot(G_i) rot(B_i)^T``, posed start ``a'_i = trans(G_i)``. In the clip's local
frame (:meth:`stbs.Pose.local`, no stretch or twist) that is, for a child ``i`` of
bone ``p`` with the nodes ``C = N_m1 ... N_mk N_i`` between them,

- ``L_i = R_p^T R_i = rot(IBM_p)^T rot(N_m1 ... N_x-1) r_x(τ) rot(S_x ... N_i IBM_i)``:
  a constant left and right product around the one animated rotation ``r_x`` in ``C``
  (the joint's own, usually), so slerp, STEP and the cubic Hermite of ``r_x`` map
  exactly onto the bone's rotation channel (the tangents by the same products);
- ``D_i = K_p trans(C) - (a_i - a_p)`` with the constant ``K_p = R_p^T lin(G_p)``
  (the parent's world scale in the bind frame): affine in the one animated
  translation in ``C``, so LINEAR, STEP and CUBICSPLINE carry over as they are.

A root bone is the same with ``C`` running from the top of its node tree, so the
motion of non-joint ancestors (an ``Armature`` node) is folded into the roots.

Every channel of the animation that moves the skeleton is put on the union of their
key times, each bone keeping its channel's interpolation: a linear channel re-keyed
at extra times is still exact, a STEP one too, and a Hermite piece split at an inner
time is exact with the derivative there as both tangents (and its value there, off
the unit sphere: the clip normalises after interpolating, as glTF does).

Where that structure does not hold -- two animated rotations (or translations) in one
bone's chain, a turning node between a bone and the joint it hangs from (or above a
root: its start moves on an arc), an animated scale above it, a non-uniform scale that
shears -- the channel takes the exact skinning-matrix values at the union times and
slerps (lerps) between them: exact at every key time of the animation, an
approximation between keys. Each
analytic channel is checked against those exact values at the union times before it
is used. A joint whose scale changes over time cannot be a rigid bone: its own
scaling is dropped with a warning naming it (its children still move as in the
file); constant scales are part of the bind.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from ... import transforms as tf
from ...clip import Clip
from ...pose import local_arrays
from ...skeleton import Skeleton
from .accessors import FLOAT_ONLY, SIGNED_UNIT, read_accessor
from .container import GltfFile
from .scene import Scene, polar, trs_matrices

__all__ = ["Channel", "Joints", "decode_clip", "animation_names"]

_PATHS = ("translation", "rotation", "scale")
_MODES = {"LINEAR": "linear", "STEP": "step", "CUBICSPLINE": "cubic"}
#: Scale changing by more than this (relative) over an animation is warned about.
SCALE_TOL = 1e-4
#: An analytic channel must match the skinning matrices to this (rotation entries;
#: offsets: times the skeleton's size) at every union time.
CHECK_TOL = 1e-6


@dataclass
class Joints:
    """What the clips need of the rig read: its joints and their binds.

    Attributes
    ----------
    nodes : list of int
        The joint node of each bone.
    ibm : (b, 4, 4) float
        Inverse bind matrices.
    skeleton : Skeleton
        Bone ``i`` starts at joint ``i``'s bind position; parent bones are parent joints.
    carried : dict of int to (int, int)
        The nodes that hang a rigid part below its joint (those between the joint and the
        mesh node, and the mesh node): node -> (mesh node, bone of the joint).
    """

    nodes: list[int]
    ibm: np.ndarray
    skeleton: Skeleton
    carried: dict[int, tuple[int, int]] = field(default_factory=dict)


def animation_names(f: GltfFile) -> list[str]:
    """The animations' names in file order: their own, else ``animation_K``; a repeated
    name gets ``_K`` appended."""
    out: list[str] = []
    for a, anim in enumerate(f.items("animations")):
        nm = anim.get("name") if isinstance(anim, dict) else None
        name = nm if isinstance(nm, str) and nm else f"animation_{a}"
        while name in out:
            name = f"{name}_{a}"
        out.append(name)
    return out


def _qmul(p, q):
    return tf.quat_mul(p, q)


class Channel:
    """One sampler driving one node's translation, rotation or scale.

    Rotations are held as ``(w, x, y, z)``; LINEAR and STEP keys normalised (files
    round them), CUBICSPLINE values and tangents as written.
    """

    def __init__(self, f: GltfFile, a: int, s: int, sampler: dict, path: str):
        what = f"animation {a} sampler {s}"
        self.path = path
        mode = f.get(sampler, "interpolation", "string", f"animations[{a}].samplers[{s}]",
                     "LINEAR")
        if mode not in _MODES:
            raise f.error(f"{what}: interpolation LINEAR, STEP or CUBICSPLINE", repr(mode))
        self.mode = _MODES[mode]
        T = read_accessor(f, f.get(sampler, "input", "index", what), f"{what} input",
                          types=("SCALAR",), components=FLOAT_ONLY)[:, 0]
        if np.any(np.diff(T) <= 0):
            k = int(np.flatnonzero(np.diff(T) <= 0)[0])
            raise f.error(f"{what} input: increasing key times",
                          f"{T[k]:g} then {T[k + 1]:g}")
        m = 4 if path == "rotation" else 3
        out = read_accessor(f, f.get(sampler, "output", "index", what), f"{what} output",
                            types=("VEC4",) if m == 4 else ("VEC3",),
                            components=SIGNED_UNIT if m == 4 else FLOAT_ONLY)
        per = 3 if self.mode == "cubic" else 1
        if len(out) != per * len(T):
            raise f.error(f"{what} output: {per * len(T)} values ({len(T)} keys"
                          f"{', 3 per key for CUBICSPLINE' if per == 3 else ''})",
                          str(len(out)))
        out = np.asarray(out, dtype=float).reshape(len(T), per, m)
        if m == 4:
            out = out[..., [3, 0, 1, 2]]
        if self.mode == "cubic" and len(T) == 1:       # one key: a constant
            self.mode = "linear"
            out = out[:, 1:2]
        if self.mode == "cubic":
            self.tin, self.v, self.tout = out[:, 0], out[:, 1], out[:, 2]
        else:
            self.v = out[:, 0]
            self.tin = self.tout = None
        if m == 4:
            n = np.linalg.norm(self.v, axis=-1)
            if np.any(n <= 1e-12):
                raise f.error(f"{what} output: non-zero rotation quaternions",
                              f"a zero one at key {int(np.argmin(n))}")
            if self.mode != "cubic":
                self.v = self.v / n[:, None]
        self.t = T

    @property
    def constant(self) -> bool:
        """True when the channel holds one value all along."""
        same = bool(np.all(self.v == self.v[:1]))
        if self.mode == "cubic":
            same = same and not self.tin.any() and not self.tout.any()
        return same

    def rest_value(self) -> np.ndarray:
        """The value it holds (for a constant channel), unit for a rotation."""
        v = self.v[0]
        return v / np.linalg.norm(v) if self.path == "rotation" else v

    def rekey(self, U: np.ndarray) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
        """Values (and for cubic channels in- and out-tangents per second) at times ``U``
        such that interpolating them piece by piece with this channel's mode gives
        exactly this channel (before its first key and after its last it holds)."""
        T, v = self.t, self.v
        K = T.size
        i = np.searchsorted(T, U, side="right") - 1            # -1 .. K-1
        before = i < 0
        ic = np.clip(i, 0, K - 1)
        on = ~before & (T[ic] == U)
        after = (i == K - 1) & ~on
        inner = ~before & ~on & ~after
        j = np.minimum(ic + 1, K - 1)
        dt = np.where(inner, T[j] - T[ic], 1.0)
        s = np.where(inner, (U - T[ic]) / dt, 0.0)
        val = v[ic].copy()
        val[before] = v[0]
        tin = tout = None
        if self.mode == "linear" and inner.any():
            if self.path == "rotation":
                val[inner] = tf.quat_slerp(v[ic[inner]], v[j[inner]], s[inner])
            else:
                val[inner] = v[ic[inner]] + s[inner, None] * (v[j[inner]] - v[ic[inner]])
        elif self.mode == "cubic":
            tin = np.zeros_like(val)
            tout = np.zeros_like(val)
            # at a key: its own tangents, but 0 on a side where the channel holds
            tin[on & (ic > 0)] = self.tin[ic[on & (ic > 0)]]
            tout[on & (ic < K - 1)] = self.tout[ic[on & (ic < K - 1)]]
            if inner.any():
                k, k1, ss, d = ic[inner], j[inner], s[inner, None], dt[inner, None]
                p0, m0, p1, m1 = v[k], self.tout[k], v[k1], self.tin[k1]
                s2, s3 = ss * ss, ss * ss * ss
                val[inner] = ((2 * s3 - 3 * s2 + 1) * p0 + (s3 - 2 * s2 + ss) * d * m0
                              + (-2 * s3 + 3 * s2) * p1 + (s3 - s2) * d * m1)
                der = ((6 * s2 - 6 * ss) * p0 / d + (3 * s2 - 4 * ss + 1) * m0
                       + (-6 * s2 + 6 * ss) * p1 / d + (3 * s2 - 2 * ss) * m1)
                tin[inner] = der
                tout[inner] = der
        return val, tin, tout

    def sample(self, U: np.ndarray) -> np.ndarray:
        """The channel's value at times ``U`` (unit rotations)."""
        val = self.rekey(U)[0]
        if self.path == "rotation":
            val = val / np.linalg.norm(val, axis=-1, keepdims=True)
        return val


def _channels(f: GltfFile, a: int, relevant: set[int], n_nodes: int
              ) -> dict[tuple[int, str], Channel]:
    """The translation, rotation and scale channels of animation ``a`` on ``relevant``
    nodes (the others are not decoded)."""
    anim = f.item("animations", a, f"animation {a}")
    where = f"animations[{a}]"
    samplers = f.get(anim, "samplers", "array", where)
    chans = f.get(anim, "channels", "array", where)
    out: dict[tuple[int, str], Channel] = {}
    made: dict[tuple[int, str], Channel] = {}
    for c, ch in enumerate(chans):
        cw = f"{where}.channels[{c}]"
        if not isinstance(ch, dict):
            raise f.error(f"{cw}: a JSON object", repr(ch)[:40])
        s = f.get(ch, "sampler", "index", cw, below=len(samplers))
        tgt = f.get(ch, "target", "object", cw)
        node = f.get(tgt, "node", "index", cw + ".target", None, below=n_nodes)
        path = f.get(tgt, "path", "string", cw + ".target")
        if node is None or path not in _PATHS or node not in relevant:
            continue             # morph weights, pointers, nodes off the skeleton
        if (node, path) in out:
            raise f.error(f"{where}: one channel per node and path",
                          f"two for node {node}'s {path}")
        sampler = samplers[s]
        if not isinstance(sampler, dict):
            raise f.error(f"{where}.samplers[{s}]: a JSON object", repr(sampler)[:40])
        key = (s, path)
        if key not in made:
            made[key] = Channel(f, a, s, sampler, path)
        out[(node, path)] = made[key]
    return out


def _chain(scene: Scene, node: int, stop: int | None) -> list[int]:
    """Nodes from just below ``stop`` (None: the top of the tree) down to ``node``."""
    out = [node]
    p = int(scene.parent[node])
    while p >= 0 and p != stop:
        out.append(p)
        p = int(scene.parent[p])
    return out[::-1]


def _product(M: np.ndarray, nodes: list[int]) -> np.ndarray:
    out = np.eye(4)
    for k in nodes:
        out = out @ M[k]
    return out


def _warn_carried(f: GltfFile, scene: Scene, J: Joints, chans: dict, label: str) -> None:
    """Warn when the animation moves a node between a rigid part and its joint: the rig
    carries the part with the joint alone."""
    moved: dict[int, int] = {}
    for (node, path), ch in chans.items():
        if node not in J.carried:
            continue
        rest = {"translation": scene.T, "rotation": scene.Q, "scale": scene.S}[path][node]
        off = not ch.constant
        if not off:
            v = ch.rest_value()
            gap = (min(np.abs(v - rest).max(), np.abs(v + rest).max())
                   if path == "rotation" else np.abs(v - rest).max())
            off = gap > 1e-6 * max(1.0, float(np.abs(rest).max()))
        if off:
            moved.setdefault(node, J.carried[node][0])
    if moved:
        who = ", ".join(f"node {scene.name(k)!r} (carrying {scene.name(m)!r} on joint "
                        f"{J.skeleton.names[J.carried[k][1]]!r})"
                        for k, m in list(moved.items())[:6])
        warnings.warn(f"{str(f.path)!r}: {label} moves {who}; a rigid part moves with its "
                      "joint only, so that motion is not in the rig", UserWarning,
                      stacklevel=4)


def _rest_and_moving(scene: Scene, chans: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                         dict[tuple[int, str], Channel]]:
    """Each node's rest T, Q, S with the constant channels in (they are part of the
    rest), and the channels that move."""
    T0, Q0, S0 = scene.T.copy(), scene.Q.copy(), scene.S.copy()
    moving: dict[tuple[int, str], Channel] = {}
    for (node, path), ch in chans.items():
        if ch.constant:
            {"translation": T0, "rotation": Q0, "scale": S0}[path][node] = ch.rest_value()
        else:
            moving[(node, path)] = ch
    return T0, Q0, S0, moving


def _check_no_shear(f: GltfFile, scene: Scene, moving: dict, a: int) -> None:
    """Refuse a moving channel on a node given by a matrix that is no T R S."""
    for (node, _path) in moving:
        if scene.matrix[node] and not np.allclose(
                trs_matrices(scene.T[node], scene.Q[node], scene.S[node]),
                scene.local[node], atol=1e-6 * max(1.0, np.abs(scene.local[node]).max())):
            raise f.error(f"animation {a}: channels on nodes given by translation, rotation "
                          "and scale", f"node {node} given by a matrix with shear")


def _union_times(chans: dict, moving: dict) -> np.ndarray:
    """The union of the moving channels' keys, and the first and last key of any
    channel on the skeleton (the animation's extent); [0] for none."""
    times = {float(t) for ch in moving.values() for t in ch.t}
    times.update(float(t) for ch in chans.values() for t in (ch.t[0], ch.t[-1]))
    return np.array(sorted(times) or [0.0])


def _warn_scale_changes(f: GltfFile, scene: Scene, J: Joints, moving: dict,
                        label: str) -> list[tuple[int, float]]:
    """Warn, once per animation, about the joints and nodes whose scale changes; they
    (node, by how much) are returned."""
    sk = J.skeleton
    bone_of = {node: i for i, node in enumerate(J.nodes)}
    grow = [(node, float(np.abs(ch.v / np.where(ch.v[:1] == 0, 1, ch.v[:1]) - 1).max()))
            for (node, path), ch in moving.items() if path == "scale"]
    loud = [(node, d) for node, d in grow if d > SCALE_TOL]
    if loud:
        who = ", ".join(f"{'joint' if node in bone_of else 'node'} "
                        f"{(sk.names[bone_of[node]] if node in bone_of else scene.name(node))!r}"
                        f" (by up to {d:.3g})" for node, d in loud[:6])
        # stacklevel: this, decode_clip, GltfAnimations.__getitem__, its caller
        warnings.warn(f"{str(f.path)!r}: {label} changes the scale of {who}; bones are "
                      "rigid, so that scaling is dropped (the children still move as in "
                      "the file)", UserWarning, stacklevel=4)
    return loud


def _local_keys(scene: Scene, order: list[int], moving: dict, static: np.ndarray,
                rest: tuple[np.ndarray, np.ndarray, np.ndarray], U: np.ndarray) -> dict:
    """Node -> its local matrices at the times ``U`` (k, 4, 4): sampled where a channel
    moves it, else its static matrix."""
    T0, Q0, S0 = rest
    k = U.size
    Nloc = {}
    for node in order:
        if not any((node, p) in moving for p in _PATHS):
            Nloc[node] = np.broadcast_to(static[node], (k, 4, 4))
            continue
        t = moving[(node, "translation")].sample(U) if (node, "translation") in moving \
            else np.broadcast_to(T0[node], (k, 3))
        q = moving[(node, "rotation")].sample(U) if (node, "rotation") in moving \
            else np.broadcast_to(Q0[node], (k, 4))
        s = moving[(node, "scale")].sample(U) if (node, "scale") in moving \
            else np.broadcast_to(S0[node], (k, 3))
        Nloc[node] = trs_matrices(np.asarray(t), np.asarray(q), np.asarray(s))
    return Nloc


def _skin_matrices(f: GltfFile, scene: Scene, J: Joints, order: list[int], Nloc: dict,
                   U: np.ndarray, label: str) -> tuple[np.ndarray, np.ndarray]:
    """The joints' world matrices ``G_j`` (k, b, 4, 4) at the times ``U``, the node
    hierarchy evaluated, and their skin matrices ``G_j IBM_j``, checked finite."""
    G = {}
    with np.errstate(over="ignore", invalid="ignore"):
        for node in order:
            p = int(scene.parent[node])
            G[node] = Nloc[node] if p < 0 else G[p] @ Nloc[node]
        Gj = np.stack([G[j] for j in J.nodes], axis=1)                 # (k, b, 4, 4)
        M = Gj @ J.ibm
    if not np.isfinite(M).all():
        kk = int(np.flatnonzero(~np.isfinite(M).all(axis=(1, 2, 3)))[0])
        raise f.error(f"{label}: skin matrices that are finite at every key",
                      f"an overflow at {U[kk]:g} s (transforms too large)")
    return Gj, M


@dataclass
class _Bones:
    """Each bone's channels while they are made: the exact local rotations ``Lg`` and
    offsets ``Dg`` at the union times ``U`` to start from (interpolated linearly), replaced
    by a file's channel re-keyed where one reproduces them (its interpolation and cubic
    tangents kept)."""

    scene: Scene
    J: Joints
    order: list[int]
    U: np.ndarray
    moving: dict
    static: np.ndarray
    Q0: np.ndarray
    S0: np.ndarray
    Lg: np.ndarray
    Dg: np.ndarray

    def __post_init__(self) -> None:
        k, b = self.Dg.shape[:2]
        self.quats = tf.matrix_to_quat(self.Lg)
        self.offs = self.Dg.copy()
        self.rmode, self.dmode = ["linear"] * b, ["linear"] * b
        self.rtan = [np.zeros((k, b, 4)), np.zeros((k, b, 4))]
        self.dtan = [np.zeros((k, b, 3)), np.zeros((k, b, 3))]
        sk = self.J.skeleton
        self.size = float(np.linalg.norm(np.ptp(sk.C, axis=0))) or 1.0
        self.world0 = self.static.copy()
        for node in self.order:
            p = int(self.scene.parent[node])
            if p >= 0:
                self.world0[node] = self.world0[p] @ self.static[node]

    def rotation(self, i: int, chain: list[int], pb: int) -> None:
        """Bone ``i``'s rotation from the one animated rotation in its chain of nodes, if
        there is one (an animated scale on the way that shears or changes the frame
        fails the check against the exact values)."""
        rot = [x for x in chain if (x, "rotation") in self.moving]
        if len(rot) != 1:
            return
        x = rot[0]
        c = chain.index(x)
        pre = _product(self.static, chain[:c])
        post = np.diag([*self.S0[x], 1.0]) @ _product(self.static, chain[c + 1:])
        left = polar(pre[:3, :3])[0]
        if pb >= 0:
            left = polar(self.J.ibm[pb, :3, :3])[0].T @ left
        right = polar(post[:3, :3] @ self.J.ibm[i, :3, :3])[0]
        qa, qb = tf.matrix_to_quat(left), tf.matrix_to_quat(right)
        ch = self.moving[(x, "rotation")]
        val, tin, tout = ch.rekey(self.U)
        q = _qmul(_qmul(qa, val), qb)
        if np.abs(tf.quat_to_matrix(q) - self.Lg[:, i]).max() <= CHECK_TOL:
            self.quats[:, i] = q
            self.rmode[i] = ch.mode
            if ch.mode == "cubic":
                self.rtan[0][:, i] = _qmul(_qmul(qa, tin), qb)
                self.rtan[1][:, i] = _qmul(_qmul(qa, tout), qb)

    def offset(self, i: int, chain: list[int], pb: int, pnode: int | None) -> None:
        """Bone ``i``'s offset from the one animated translation in its chain of nodes,
        if there is one and nothing else moves above it."""
        below = chain[:-1]
        moved = [x for x in chain if (x, "translation") in self.moving]
        still = not any((x, "rotation") in self.moving or (x, "scale") in self.moving
                        for x in below)
        if len(moved) != 1 or not still:
            return
        A = self.J.skeleton.A
        x = moved[0]
        c = chain.index(x)
        pre = _product(self.static, chain[:c])
        post = _product(self.static, chain[c + 1:])
        K = np.eye(3)
        base = A[i].copy()
        if pb >= 0:
            Rp = polar(self.world0[pnode][:3, :3] @ self.J.ibm[pb, :3, :3])[0]
            K = Rp.T @ self.world0[pnode][:3, :3]
            base = A[i] - A[pb]
        Lx = trs_matrices(np.zeros(3), self.Q0[x], self.S0[x])[:3, :3]
        Amat = K @ pre[:3, :3]
        cvec = K @ (pre[:3, 3] + pre[:3, :3] @ Lx @ post[:3, 3]) - base
        ch = self.moving[(x, "translation")]
        val, tin, tout = ch.rekey(self.U)
        d = val @ Amat.T + cvec
        if np.abs(d - self.Dg[:, i]).max() <= CHECK_TOL * self.size:
            self.offs[:, i] = d
            self.dmode[i] = ch.mode
            if ch.mode == "cubic":
                self.dtan[0][:, i] = tin @ Amat.T
                self.dtan[1][:, i] = tout @ Amat.T

    def clip(self, f: GltfFile, label: str) -> Clip:
        """The clip of these channels, at the key spacing's frame rate when it is
        regular (else 30)."""
        U = self.U
        step = np.diff(U)
        fps = 30.0
        if step.size and np.ptp(step) <= 1e-6 * step.mean() and step.mean() > 0:
            fps = 1.0 / float(step.mean())
        cubic_r = "cubic" in self.rmode
        cubic_d = "cubic" in self.dmode
        try:
            return Clip.from_local(self.J.skeleton, U, rotations=self.quats,
                                   offsets=self.offs, fps=fps,
                                   rotation_interpolation=self.rmode,
                                   offset_interpolation=self.dmode,
                                   rotation_tangents=tuple(self.rtan) if cubic_r else None,
                                   offset_tangents=tuple(self.dtan) if cubic_d else None)
        except ValueError as exc:
            raise f.error(f"{label}: keys that make a clip",
                          " ".join(str(exc).split())) from None


def decode_clip(f: GltfFile, scene: Scene, J: Joints, a: int, name: str) -> Clip:
    """Animation ``a`` of ``f`` as a clip of ``J.skeleton`` (see the module docs)."""
    sk = J.skeleton
    b = sk.n_bones
    nodes = J.nodes
    label = f"animation {a} ({name!r})"
    relevant = scene.upward(nodes)
    chans = _channels(f, a, relevant | set(J.carried), scene.n)
    _warn_carried(f, scene, J, chans, label)
    chans = {key: ch for key, ch in chans.items() if key[0] in relevant}
    T0, Q0, S0, moving = _rest_and_moving(scene, chans)
    _check_no_shear(f, scene, moving, a)
    static = scene.local.copy()
    for node in {node for node, _ in chans}:
        static[node] = trs_matrices(T0[node], Q0[node], S0[node])
    U = _union_times(chans, moving)
    k = U.size
    loud = _warn_scale_changes(f, scene, J, moving, label)

    # ---- the exact values at the union times: the node hierarchy, evaluated
    order = [int(x) for x in scene.order if int(x) in relevant]
    # the clip keeps about 200 bytes per key and bone; the hierarchy's matrices and the
    # skin matrices live while it is made
    f.reserve(k * b * 200, f"{label}: {k} keys over {b} bones")
    f.reserve(k * (len(order) + 3 * b) * 16 * 8, f"{label}: {k} keys over {len(order)} nodes",
              keep=False)
    Nloc = _local_keys(scene, order, moving, static, (T0, Q0, S0), U)
    Gj, M = _skin_matrices(f, scene, J, order, Nloc, U, label)
    R, dev = polar(M[..., :3, :3])
    O = Gj[..., :3, 3]
    ones, zeros = np.ones((k, b)), np.zeros((k, b, 2))
    Lg, Dg = local_arrays(sk, R, O, ones, zeros)
    worst = float(dev.max(initial=0.0))
    if worst > SCALE_TOL and not loud:
        kk, i = np.unravel_index(int(np.argmax(dev)), dev.shape)
        warnings.warn(f"{str(f.path)!r}: {label} scales or shears joint {sk.names[i]!r} (its "
                      f"skin matrix is up to {worst:.3g} off rigid at {U[kk]:g} s); bones are "
                      "rigid, so that is dropped", UserWarning, stacklevel=3)

    # ---- each bone's channels: analytic where the structure allows, checked
    bones = _Bones(scene, J, order, U, moving, static, Q0, S0, Lg, Dg)
    for i, node in enumerate(nodes):
        pb = int(sk.parents[i])
        pnode = nodes[pb] if pb >= 0 else None
        chain = _chain(scene, node, pnode)
        bones.rotation(i, chain, pb)
        bones.offset(i, chain, pb, pnode)
    return bones.clip(f, label)
