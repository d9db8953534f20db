"""An STBS rig turned into plain linear blend skinning with helper joints ("twist bones").

Engines and glTF play linear blend skinning (LBS) of rigid joint matrices only. STBS
(DESIGN §3) moves each vertex by its bone's map *at its own endpoint weight* ``e_i``::

    x -> a'_i + R_i K_i(e_i) (e_i s_i + x - a_i)

which for a fixed ``e`` is a rigid map. :func:`helper_joints` gives every bone ``k``
helper joints beside its own (the twist bones of game rigs: a forearm with three twist
joints has ``k = 3``), so ``m = k + 1`` rigid joints per bone at parameters
``t_0 < ... < t_{m-1}`` along it: joint ``(i, j)`` is the rigid map at ``e = t_j``,
so a pose of the STBS skeleton becomes a rigid pose of the helper skeleton (stretch 1,
twist 0 everywhere: a stretch becomes the helpers' translations, a twist their
rotations about the bone), and each vertex's share ``w_i`` of bone i is split
over bone i's helpers around ``e_i``.

Choices
-------
- Spacing: ``t_j = j / (m - 1) = j / k``, both ends included (``k = 0``: ``t_0 = 0``, the
  bone itself). Every ``e`` in [0, 1] then lies between two helpers of its own bone, so convex
  weights reach the whole bone, the helper at ``t = 0`` is the bone's own rigid map and
  the one at ``t = 1`` the map at the joint it ends at (which differs from the child's
  whenever the joint bends, so a child's helpers cannot stand in for it).
- Bone totals: the weights of bone i's helpers add up to the vertex's weight on bone i
  (after the influence limit below), so a rigid pose (stretch 1, twist 0, where all
  helpers of a bone coincide) is reproduced exactly: the helper rig's LBS is the LBS of
  :attr:`HelperRig.bone_weights`, which is ``W`` itself where ``W`` has few enough bones.
- Influences: at most ``max_influences`` helpers per vertex (default 4, what glTF's
  ``JOINTS_0`` and most engines carry; 8 allowed). A bone whose ``e_i`` falls on a helper
  needs one slot, any other two (the pair around ``e_i``). Each of the vertex's heaviest
  ``max_influences`` bones first gets one slot (its nearest helper); free slots then go,
  heaviest bone first, to pairs; a bone left without its pair takes the slot of a lighter
  bone when, over the sampled poses, dropping that bone (its weight renormalised away)
  costs less than the pair gains.
- Weights: ``fit="lsq"`` (default) places each bone's share within its pair by bounded
  least squares, per vertex, over a set of sampled poses (bent, twisted and stretched),
  so that the helper rig's LBS best matches the STBS ``method`` result; ``fit="hat"``
  splits it by the hat functions in ``e`` (linear interpolation between the pair).
  Either way the weights are >= 0 and every row sums to 1.
- Accuracy: blending two rigid helpers twisted ``phi`` apart cuts the chord of the
  twist's arc, so a vertex at distance ``r`` from the axis, midway between helpers, sinks
  by ``r (1 - cos(phi / 2))`` whatever the weights; with a twist ``theta`` spread along
  the bone, ``phi = theta / k``. That bound sets ``k``: for a 180 degree twist,
  ``1 - cos(phi / 2)`` is 29 % of the radius with k = 1, 7.6 % with 2, 3.4 % with 3 and
  1.9 % with 4.

The lower-level functions (:func:`helper_params`, :func:`helper_skeleton`,
:func:`helper_arrays`) count ``m``, the joints per bone, the bone's own included.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import Literal

import numpy as np
import scipy.sparse as sp

from .. import _checks
from .. import transforms as tf
from ..clip import Clip
from ..pose import Pose, fk_arrays, joint_twists, local_arrays, pose_list
from ..rig.model import Rig
from ..skeleton import Skeleton
from ..skinning.layout import top_k

__all__ = ["helper_joints", "HelperRig", "helper_params", "helper_skeleton", "helper_arrays",
           "METHODS", "FITS"]

#: The STBS methods a helper rig can stand in for.
METHODS = ("stbs-dqs", "stbs-lbs")
#: How each bone's weight is split over its helpers.
FITS = ("lsq", "hat")
#: Sampled fitting poses: twist up to this (radians) at every joint, either way ...
TWIST_RANGE = np.pi
#: ... stretch between 1 / this and this (log-uniform) on every bone ...
STRETCH_RANGE = 2.0
#: ... and every bone turned up to this (radians) about a random axis.
BEND_RANGE = np.pi / 4
_SWEEPS = 40            # coordinate-descent sweeps of the per-vertex box QP


# --------------------------------------------------------------------------- the helper skeleton
def helper_params(m: int) -> np.ndarray:
    """(m,) parameters ``t_j`` of a bone's ``m`` joints (its own and its helpers) along it:
    ``j / (m - 1)``; ``[0]`` for m = 1.

    Examples
    --------
    >>> helper_params(3).tolist(), helper_params(1).tolist()
    ([0.0, 0.5, 1.0], [0.0])
    """
    k = _count(m, "m", 1)
    return np.zeros(1) if k == 1 else np.linspace(0.0, 1.0, k)


def _count(k, name: str = "m", low: int = 1) -> int:
    what = ("helper joints per bone, beside its own" if name == "k" else
            "joints per bone, its own included")
    if isinstance(k, bool) or not isinstance(k, (int, np.integer)):
        raise TypeError(f"{name} must be an int ({what}), got {type(k).__name__}")
    if k < low:
        raise ValueError(f"{name} must be >= {low} ({what}), got {k}")
    return int(k)


def helper_skeleton(sk: Skeleton, m: int) -> Skeleton:
    """The skeleton of ``m`` rigid bones per bone of ``sk`` (its own and ``m - 1`` helpers).

    Helper ``(i, j)`` is bone ``i * m + j``. It starts at ``a_i + t_j (b_i - a_i)``
    (:func:`helper_params`) and runs to the next helper's start; the last one (at the end
    joint ``b_i``, for m >= 2) gets a tail of half a segment past it along the bone. Each
    helper's parent is the previous helper of its bone; helper ``(i, 0)``'s parent is the
    helper of bone i's parent at or before where bone i hangs (the last one for a
    connected child). Helper ``(i, 0)`` keeps bone i's name, the others are named
    ``"<name>_twist_<j>"``. With m = 1 this is ``sk`` itself (an equal skeleton).

    Parameters
    ----------
    sk : Skeleton
    m : int
        Joints per bone, >= 1, the bone's own included.

    Returns
    -------
    Skeleton
        ``b * m`` bones; the original joints keep their indices, new joints follow.
    """
    _checks.skeleton(sk)
    k = _count(m)
    t = helper_params(k)
    b, C = sk.n_bones, sk.C
    if k == 1:
        return Skeleton(C, sk.BE, names=sk.names, P=sk.parents)
    vec = sk.B - sk.A
    pts, starts, ends = [C], np.empty((b, k), np.int64), np.empty((b, k), np.int64)
    nxt = C.shape[0]
    tail = 1.0 + 0.5 / (k - 1)
    for i in range(b):                      # loops over bones, not vertices
        inner = sk.A[i] + np.r_[t[1:-1], tail][:, None] * vec[i]
        ids = np.arange(nxt, nxt + inner.shape[0])
        pts.append(inner)
        nxt += inner.shape[0]
        starts[i] = np.r_[sk.BE[i, 0], ids[:-1], sk.BE[i, 1]]
        ends[i] = np.r_[starts[i, 1:], ids[-1]]
    names = [sk.names[i] if j == 0 else f"{sk.names[i]}_twist_{j}"
             for i in range(b) for j in range(k)]
    if len(set(names)) != len(names):
        dup = next(s for s in names if names.count(s) > 1)
        raise ValueError(f"sk: the helper bone name {dup!r} is also a bone's name; rename "
                         "that bone")
    P = np.full((b, k), -1, dtype=np.int64)
    P[:, 1:] = np.arange(b * k).reshape(b, k)[:, :-1]
    child = np.flatnonzero(sk.parents >= 0)
    p = sk.parents[child]
    j = np.searchsorted(t, sk.hang[child] + 1e-12, side="right") - 1
    P[child, 0] = p * k + j
    return Skeleton(np.vstack(pts), np.c_[starts.ravel(), ends.ravel()], names=names,
                    P=P.ravel())


def helper_arrays(sk: Skeleton, m: int, rotations, origins, stretch, twist
                  ) -> tuple[np.ndarray, np.ndarray]:
    """The helper joints' rigid maps for poses of ``sk`` given as arrays (batched).

    Helper ``(i, j)`` is bone i's STBS map at ``e = t_j``:
    ``x -> a'_i + R_i K_i(t_j) (t_j s_i + x - a_i)``, i.e. rotation ``R_i K_i(t_j)`` and
    posed start ``a'_i + t_j sigma_i R_i (b_i - a_i)`` (the twist leaves the axis alone).

    Parameters
    ----------
    sk : Skeleton
    m : int
        Joints per bone, the bone's own included.
    rotations : (..., b, d, d) float
    origins : (..., b, d) float
    stretch : (..., b) float
    twist : (..., b, 2) float

    Returns
    -------
    rotations : (..., b * m, d, d) float
    origins : (..., b * m, d) float
    """
    t = helper_params(m)
    R = np.asarray(rotations, dtype=float)
    O = np.asarray(origins, dtype=float)
    sigma = np.asarray(stretch, dtype=float)
    theta = np.asarray(twist, dtype=float)
    b, d = sk.n_bones, sk.dim
    Rh = np.repeat(R, t.size, axis=-3)                   # (..., b k, d, d)
    if d == 3:
        ang = (theta[..., :, None, 0] * (1 - t) + theta[..., :, None, 1] * t)   # (..., b, k)
        K = tf.axis_angle_to_matrix(np.repeat(sk.axes, t.size, axis=0),
                                    ang.reshape(ang.shape[:-2] + (b * t.size,)))
        Rh = Rh @ K
    end = np.einsum("...bij,bj->...bi", R, sk.B - sk.A) * sigma[..., None]   # sigma R d
    Oh = O[..., :, None, :] + t[:, None] * end[..., :, None, :]
    return Rh, Oh.reshape(Oh.shape[:-3] + (b * t.size, d))


# --------------------------------------------------------------------------- the rig
class HelperRig:
    """A rig of rigid helper joints that plays an STBS rig with plain LBS.

    Made by :func:`helper_joints`; see the module docs for the choices.

    Attributes
    ----------
    V : (n, d) float
        Rest positions.
    F : (f, 3) int or None
    T : (t, 4) int or None
    source : Skeleton
        The STBS skeleton (b bones).
    skeleton : Skeleton
        The helper skeleton (``b * (k + 1)`` bones, :func:`helper_skeleton`).
    W : (n, b * (k + 1)) scipy.sparse.csr_array
        Helper weights: >= 0, rows sum to 1, at most ``max_influences`` per row.
    bone_weights : (n, b) scipy.sparse.csr_array
        Each vertex's weight per STBS bone, the sums of its helpers' weights (``W`` kept
        to the bones that got a slot, renormalised).
    k : int
        Helper joints per bone, beside its own.
    t : (k + 1,) float
        The parameters of a bone's own joint and its helpers along it.
    bone : (b * (k + 1),) int
        The STBS bone of each helper.
    method, fit : str
    max_influences : int
    """

    def __init__(self, *, V, F, T, source: Skeleton, k: int, W, bone_weights, method: str,
                 fit: str, max_influences: int):
        self.V, self.F, self.T = V, F, T
        self.source = source
        self.k = k
        self._m = k + 1
        self.t = helper_params(self._m)
        self.skeleton = helper_skeleton(source, self._m)
        self.W = W
        self.bone_weights = bone_weights
        self.bone = np.repeat(np.arange(source.n_bones), self._m)
        self.method, self.fit, self.max_influences = method, fit, max_influences

    def _check_pose(self, pose) -> Pose:
        if not isinstance(pose, Pose):
            raise TypeError(f"pose must be a stbs.Pose, got {type(pose).__name__}")
        if pose.skeleton != self.source:
            raise ValueError(f"pose must be a pose of the STBS skeleton ({self.source!r}), "
                             f"got one of {pose.skeleton!r}")
        return pose

    def pose(self, pose: Pose) -> Pose:
        """The rigid helper pose (stretch 1, twist 0) that stands for an STBS pose.

        Parameters
        ----------
        pose : Pose
            A pose of :attr:`source`.

        Returns
        -------
        Pose
            A pose of :attr:`skeleton`.
        """
        pose = self._check_pose(pose)
        R, O = helper_arrays(self.source, self._m, pose.rotations, pose.origins,
                             pose.stretch, pose.twist)
        return Pose(self.skeleton, rotations=R, origins=O)

    def clip(self, clip: Clip, fps: float | None = None) -> Clip:
        """The rigid helper clip that stands for an STBS clip.

        The STBS clip is sampled at ``fps`` (default its own) and at its key times; the
        helper clip holds those poses as keys, interpolated linearly (``"step"`` clips:
        the keys, held). It is rigid (stretch 1, twist 0), so :func:`stbs.io.write_gltf`
        writes it key for key as node rotations and translations.

        Parameters
        ----------
        clip : Clip
            A clip of :attr:`source`.
        fps : float, optional

        Returns
        -------
        Clip
            A clip of :attr:`skeleton`.
        """
        if not isinstance(clip, Clip):
            raise TypeError(f"clip must be a stbs.Clip, got {type(clip).__name__}")
        if clip.skeleton != self.source:
            raise ValueError(f"clip must be a clip of the STBS skeleton ({self.source!r}), "
                             f"got one of {clip.skeleton!r}")
        step = (clip.interpolation == "step"
                and all(m == "step" for m in clip.rotation_interpolation)
                and all(m == "step" for m in clip.offset_interpolation))
        times = clip.times if step else np.union1d(clip.sample_times(fps), clip.times)
        R, O, sigma, theta = clip.arrays(times)
        Rh, Oh = helper_arrays(self.source, self._m, R, O, sigma, theta)
        hsk = self.skeleton
        h = hsk.n_bones
        L, D = local_arrays(hsk, Rh, Oh, np.ones((times.size, h)), np.zeros((times.size, h, 2)))
        return Clip.from_local(hsk, times, rotations=L, offsets=D, fps=clip.fps,
                               interpolation="step" if step else "linear")

    def deform(self, pose: Pose) -> np.ndarray:
        """(n, d) the helper rig's LBS for an STBS pose (what an engine plays)."""
        from ..skinning import deform

        return deform(self.V, self.skeleton, self.pose(pose), self.W, method="lbs")

    def rig(self) -> Rig:
        """The helper rig as a :class:`stbs.Rig` (no endpoint weights: its joints are rigid)."""
        meta = {"helper_joints": {"k": self.k, "method": self.method, "fit": self.fit,
                                  "source_bones": list(self.source.names)}}
        return Rig(V=self.V, F=self.F, T=self.T, skeleton=self.skeleton, W=self.W, meta=meta)

    def write_gltf(self, path: str | os.PathLike, clip: Clip | None = None) -> None:
        """Write the helper rig (and ``clip`` of the STBS skeleton, converted by
        :meth:`clip`) as a glTF 2.0 LBS skin with node animation
        (:func:`stbs.io.write_gltf`), which any glTF viewer or engine plays.

        Raises
        ------
        ValueError
            A vertex with more than 4 helpers (``max_influences=8``): the file carries
            4 a vertex (``JOINTS_0``), so it would not play as this rig does.
        """
        from ..io import write_gltf

        most = int(np.diff(self.W.indptr).max())
        if most > 4:
            raise ValueError(f"write_gltf: glTF is written with 4 joints a vertex (JOINTS_0), "
                             f"this helper rig has up to {most}; make it with "
                             "max_influences=4")
        write_gltf(path, self.rig(), None if clip is None else self.clip(clip))

    def __repr__(self) -> str:
        return (f"HelperRig(k={self.k}, {self.source.n_bones} bones -> "
                f"{self.skeleton.n_bones} helpers, V={self.V.shape}, method={self.method!r}, "
                f"fit={self.fit!r})")


# --------------------------------------------------------------------------- the fit
def _bone_map(sk: Skeleton, R, O, sigma, theta, bones, e, X) -> np.ndarray:
    """(..., n, m, d) bone ``bones`` (n, m)'s STBS map at ``e`` (n, m) applied to ``X``
    (n, d), for one pose (arrays without the batch axis)."""
    d = sk.dim
    rel = X[:, None, :] - sk.A[bones] + (e * (sigma[bones] - 1))[..., None] * (
        sk.B - sk.A)[bones]
    if d == 3:
        ang = (1 - e) * theta[bones, 0] + e * theta[bones, 1]
        rel = np.einsum("nmij,nmj->nmi", tf.axis_angle_to_matrix(sk.axes[bones], ang), rel)
    return O[bones] + np.einsum("nmij,nmj->nmi", R[bones], rel)


def _helper_map(Rh, Oh, Ah, ids, X) -> np.ndarray:
    """(n, m, d) helpers ``ids`` (n, m) applied to ``X`` (n, d)."""
    return Oh[ids] + np.einsum("nmij,nmj->nmi", Rh[ids], X[:, None, :] - Ah[ids])


class _Slots:
    """Per vertex, its top bones (heaviest first) and the helpers around their ``e``."""

    def __init__(self, W, E, t: np.ndarray, max_influences: int):
        lay = top_k(W, E, pad=())        # every bone of a vertex, heaviest first
        m = min(max_influences, lay.idx.shape[0])
        self.bone = lay.idx[:m].T.astype(np.int64)               # (n, m): the m heaviest
        w = lay.w[:m].T.astype(np.float64)
        total = w.sum(axis=1, keepdims=True)
        self.w = np.divide(w, total, out=np.zeros_like(w), where=total > 0)
        self.e = np.clip(lay.e[:m].T.astype(np.float64), 0.0, 1.0)
        k = t.size
        pos = self.e * (k - 1) if k > 1 else np.zeros_like(self.e)
        lo = np.clip(np.floor(pos), 0, max(k - 2, 0)).astype(np.int64)
        frac = pos - lo
        on = (frac <= 1e-12) | (frac >= 1 - 1e-12) | (k == 1)
        self.lo = self.bone * k + np.where(frac >= 1 - 1e-12, lo + 1, lo)
        self.hi = self.bone * k + np.minimum(lo + 1, k - 1)
        self.between = (self.w > 0) & ~on
        self.hat = np.where(self.between, frac, 0.0)             # share on hi
        self.near = np.where(frac > 0.5, self.hi, self.lo)
        self.kept = self.w > 0
        self.paired = np.zeros_like(self.kept)


def _allocate(slots: _Slots, gain: np.ndarray | None, drop: np.ndarray | None,
              max_influences: int) -> None:
    """Decide per vertex which bones keep a slot and which get their pair.

    Every bone holds one slot; heaviest first, a bone between helpers takes a second
    while one is free. With the sampled costs (``gain``: error removed by pairing a
    bone, ``drop``: error added by dropping one, both (n, m)), a bone left unpaired then
    evicts the cheapest lighter single bone when that costs less than the pair gains.
    """
    n, m = slots.w.shape
    free = max_influences - slots.kept.sum(axis=1)
    rows = np.arange(n)
    for s in range(m):                      # slots in weight order (m <= 8)
        up = slots.between[:, s] & slots.kept[:, s] & (free >= 1)
        slots.paired[up, s] = True
        free -= up
        if gain is None:
            continue
        want = slots.between[:, s] & slots.kept[:, s] & ~slots.paired[:, s]
        single = slots.kept & ~slots.paired
        single[:, : s + 1] = False
        cost = np.where(single, drop, np.inf)
        j = np.argmin(cost, axis=1)
        swap = want & (cost[rows, j] < gain[:, s])
        slots.kept[rows[swap], j[swap]] = False
        slots.paired[swap, s] = True


def _sampled_poses(sk: Skeleton, n_poses: int, seed) -> tuple[np.ndarray, ...]:
    """Arrays (R, O, sigma, theta) of seeded random bent, twisted and stretched poses."""
    rng = np.random.default_rng(seed)
    b, d = sk.n_bones, sk.dim
    if d == 3:
        L = tf.axis_angle_to_matrix(rng.normal(size=(n_poses, b, 3)),
                                    rng.uniform(0, BEND_RANGE, (n_poses, b)))
        theta = joint_twists(sk, rng.uniform(-TWIST_RANGE, TWIST_RANGE, (n_poses,
                                                                        sk.n_joints)))
    else:
        L = tf.rotation_2d(rng.uniform(-BEND_RANGE, BEND_RANGE, (n_poses, b)))
        theta = np.zeros((n_poses, b, 2))
    sigma = np.exp(rng.uniform(-np.log(STRETCH_RANGE), np.log(STRETCH_RANGE), (n_poses, b)))
    R, O = fk_arrays(sk, L, sigma, theta, np.zeros((n_poses, b, d)))
    return R, O, sigma, theta


def _pose_arrays(sk: Skeleton, poses) -> tuple[np.ndarray, ...]:
    poses = pose_list(poses, sk)
    return tuple(np.stack([getattr(p, a) for p in poses])
                 for a in ("rotations", "origins", "stretch", "twist"))


def _fit(V, sk: Skeleton, W, E, slots: _Slots, k: int, method: str, arrays,
         max_influences: int, lsq: bool, say) -> None:
    """Allocate the slots from the costs over the sampled poses and, with ``lsq``, place
    each paired bone's share (``slots.hat`` becomes the fitted share on its upper
    helper) by least squares over them."""
    from ..skinning import Deformer

    R, O, sigma, theta = arrays
    Ah = helper_skeleton(sk, k).A
    dfm = Deformer(V, sk, W, E, method=method)
    targets = [dfm(Pose(sk, rotations=R[q], origins=O[q], stretch=sigma[q], twist=theta[q]))
               for q in range(R.shape[0])]

    def maps(q):
        """Helpers lo, hi and nearest, and the exact bone maps, at pose q (n, m, d)."""
        Rh, Oh = helper_arrays(sk, k, R[q], O[q], sigma[q], theta[q])
        Xlo, Xhi = _helper_map(Rh, Oh, Ah, slots.lo, V), _helper_map(Rh, Oh, Ah, slots.hi, V)
        Xnear = np.where((slots.near == slots.hi)[..., None], Xhi, Xlo)
        return Xlo, Xhi, Xnear

    n, m = slots.w.shape
    gain, drop = np.zeros((n, m)), np.zeros((n, m))
    w2 = slots.w ** 2
    say("fitting poses", 0, len(targets))
    for q, Y in enumerate(targets):          # loops over poses, each vectorised
        Xlo, Xhi, Xnear = maps(q)
        exact = _bone_map(sk, R[q], O[q], sigma[q], theta[q], slots.bone, slots.e, V)
        hat = Xlo + slots.hat[..., None] * (Xhi - Xlo)
        gain += w2 * (np.sum((Xnear - exact) ** 2, -1) - np.sum((hat - exact) ** 2, -1))
        drop += w2 * np.sum((exact - Y[:, None, :]) ** 2, -1)
        say("fitting poses", q + 1, len(targets))
    _allocate(slots, gain, drop, max_influences)
    if lsq:
        say("least squares", 0, 1)
        _split(slots, ((Y, *maps(q)) for q, Y in enumerate(targets)))
        say("least squares", 1, 1)


def _split(slots: _Slots, cache) -> None:
    """Bounded least squares for the paired bones' shares mu (n, m) in [0, 1]:
    min sum_poses |sum_s w_s (X_lo + mu_s (X_hi - X_lo)) - Y|^2, by coordinate descent."""
    n, m = slots.w.shape
    wk = np.where(slots.kept, slots.w, 0.0)
    wk = wk / wk.sum(axis=1, keepdims=True)
    pair = slots.paired
    H = np.zeros((n, m, m))
    f = np.zeros((n, m))
    for Y, Xlo, Xhi, Xnear in cache:
        base = np.where(pair[..., None], Xlo, Xnear)
        c0 = np.einsum("nm,nmd->nd", wk, base) - Y
        D = np.where(pair[..., None], wk[..., None] * (Xhi - Xlo), 0.0)
        H += np.einsum("nad,nbd->nab", D, D)
        f += np.einsum("nad,nd->na", D, c0)
    mu = np.where(pair, slots.hat, 0.0)
    diag = np.einsum("naa->na", H)
    ok = pair & (diag > 1e-14 * max(float(diag.max(initial=0.0)), 1e-300))
    for _ in range(_SWEEPS):                # a box QP of m <= 8 unknowns per vertex
        for s in range(m):
            g = f[:, s] + np.einsum("nb,nb->n", H[:, s], mu)
            new = np.clip(mu[:, s] - g / np.where(ok[:, s], diag[:, s], 1.0), 0.0, 1.0)
            mu[:, s] = np.where(ok[:, s], new, mu[:, s])
    slots.hat = np.where(pair, mu, 0.0)


def _weights(slots: _Slots, n_helpers: int, b: int) -> tuple[sp.csr_array, sp.csr_array]:
    n, m = slots.w.shape
    wk = np.where(slots.kept, slots.w, 0.0)
    wk = wk / wk.sum(axis=1, keepdims=True)
    rows = np.repeat(np.arange(n), m)
    mu = np.where(slots.paired, slots.hat, 0.0)
    lo = np.where(slots.paired, slots.lo, slots.near)
    vals = np.r_[(wk * (1 - mu)).ravel(), (wk * mu).ravel()]
    cols = np.r_[lo.ravel(), slots.hi.ravel()]
    Wh = sp.csr_array((vals, (np.r_[rows, rows], cols)), shape=(n, n_helpers))
    Wh.sum_duplicates()
    Wh.eliminate_zeros()
    Wb = sp.csr_array((wk.ravel(), (rows, slots.bone.ravel())), shape=(n, b))
    Wb.sum_duplicates()
    Wb.eliminate_zeros()
    return Wh, Wb


# --------------------------------------------------------------------------- the entry point
def _inputs(rig_or_V, sk, W, E, F, T):
    """(V, F, T, sk, W, E) from a Rig or from arrays, checked."""
    if isinstance(rig_or_V, Rig):
        if any(x is not None for x in (sk, W, E, F, T)):
            raise TypeError("give a stbs.Rig alone, or V with sk, W and E, not both")
        rig = rig_or_V
        V, F, T, sk, W, E = rig.V, rig.F, rig.T, rig.skeleton, rig.W, rig.E
        where = "rig.E"
    else:
        if sk is None or W is None:
            raise TypeError("helper_joints needs a stbs.Rig, or V with sk, W and E")
        V = _checks.skeleton(sk, rig_or_V)
        where = "E"
    n, b = V.shape[0], sk.n_bones
    W = _checks.bone_weights(W, n, b)
    if E is None:
        raise ValueError(f"{where} is None: STBS methods need endpoint weights E (n, {b}) "
                         "(stbs.endpoint_weights makes them)")
    E = _checks.endpoint_weights(E, n, b, name=where)
    return V, F, T, sk, W, E


def helper_joints(rig_or_V, sk: Skeleton | None = None, W=None, E=None, *, k: int = 3,
                  method: Literal["stbs-dqs", "stbs-lbs"] = "stbs-dqs",
                  fit: Literal["lsq", "hat"] = "lsq", max_influences: int = 4,
                  poses: Sequence[Pose] | None = None, n_poses: int = 16, seed: int = 0,
                  F=None, T=None, progress=None) -> HelperRig:
    """Turn an STBS rig into plain LBS with ``k`` rigid helper joints per bone.

    Parameters
    ----------
    rig_or_V : Rig or (n, d) float
        A :class:`stbs.Rig` with endpoint weights, or the rest positions ``V``.
    sk : Skeleton, optional
        With ``V``: the skeleton (b bones).
    W : (n, b) float, dense or scipy.sparse, optional
        With ``V``: bone weights.
    E : (n, b) float, dense or scipy.sparse, optional
        With ``V``: endpoint weights in [0, 1] (required: the helpers sit at ``e``).
    k : int, keyword-only
        Helper joints per bone beside its own, >= 0: the bone's k + 1 rigid joints sit
        at ``t_j = j / k`` (k = 0: the bone itself).
    method : {"stbs-dqs", "stbs-lbs"}, keyword-only
        The STBS result the helper rig's LBS should match (``fit="lsq"``).
    fit : {"lsq", "hat"}, keyword-only
        How each bone's share is split over its pair of helpers: by least squares over
        the fitting poses (``"lsq"``) or by the hat functions in ``e`` (``"hat"``).
        Which bones get a pair (and which light ones are dropped) is decided from the
        fitting poses either way.
    max_influences : int, keyword-only
        Helpers per vertex, 4 (glTF ``JOINTS_0``, most engines) or 8.
    poses : sequence of Pose, keyword-only, optional
        The poses of ``sk`` to fit to (e.g. a clip's samples); default ``n_poses``
        seeded random poses, each bone bent up to 45 degrees, twisted up to 180 degrees
        either way at every joint and stretched by 1/2 to 2.
    n_poses, seed : int, keyword-only
        Number and seed of the random fitting poses.
    F : (f, 3) int, keyword-only, optional
        With ``V``: triangles (needed to write glTF).
    T : (t, 4) int, keyword-only, optional
        With ``V``: tetrahedra.
    progress : callable, keyword-only, optional
        ``progress(stage, done, total)``: stage ``"fitting poses"`` once per fitting pose,
        then ``"least squares"`` (``fit="lsq"``); raising from it cancels.

    Returns
    -------
    HelperRig

    Raises
    ------
    ValueError
        k < 0, an unknown method or fit, max_influences not 4 or 8, missing or bad
        ``E``, ``W`` of the wrong shape, poses of another skeleton, n_poses < 1.
    TypeError
        A Rig given together with arrays, or arrays without ``sk`` and ``W``.

    Examples
    --------
    >>> import numpy as np
    >>> import stbs
    >>> from stbs.fit.twist_bones import helper_joints
    >>> V, F, sk, W = stbs.shapes.cigar(8)
    >>> E = stbs.endpoint_weights(V, sk, method="projection")
    >>> helper = helper_joints(V, sk, W, E, k=3, F=F)
    >>> helper.skeleton.names
    ['bone', 'bone_twist_1', 'bone_twist_2', 'bone_twist_3']
    >>> pose = stbs.forward_kinematics(sk, stretch=[1.5], twist=[0, np.pi])
    >>> U = helper.deform(pose)                       # plain LBS of rigid helper joints
    >>> Ustbs = stbs.deform(V, sk, pose, W, E, method="stbs-dqs")
    >>> diagonal = np.linalg.norm(np.ptp(V, axis=0))
    >>> round(float(np.linalg.norm(U - Ustbs, axis=1).max() / diagonal), 3)  # 180 deg, k = 3
    0.016
    """
    k = _count(k, "k", 0) + 1            # joints per bone from here on, its own included
    _checks.progress(progress, "progress(stage, done, total)")
    say = progress or (lambda stage, done, total: None)
    method = _checks.choice("method", method, METHODS)
    fit = _checks.choice("fit", fit, FITS)
    if isinstance(max_influences, bool) or max_influences not in (4, 8):
        raise ValueError(f"max_influences must be 4 or 8, got {max_influences!r}")
    V, F, T, sk, W, E = _inputs(rig_or_V, sk, W, E, F, T)
    if poses is None:
        if isinstance(n_poses, bool) or not isinstance(n_poses, (int, np.integer)) \
                or n_poses < 1:
            raise ValueError(f"n_poses must be an int >= 1, got {n_poses!r}")
        arrays = _sampled_poses(sk, int(n_poses), seed)
    else:
        arrays = _pose_arrays(sk, poses)
    t = helper_params(k)
    slots = _Slots(W, E, t, max_influences)
    if k == 1:
        _allocate(slots, None, None, max_influences)
    else:
        _fit(V, sk, W, E, slots, k, method, arrays, max_influences, fit == "lsq", say)
    Wh, Wb = _weights(slots, sk.n_bones * k, sk.n_bones)
    return HelperRig(V=V, F=F, T=T, source=sk, k=k - 1, W=Wh, bone_weights=Wb, method=method,
                     fit=fit, max_influences=max_influences)
