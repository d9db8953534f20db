"""Joint motion: a hierarchy of joints and, per frame, each joint's local transform.

Motion capture (BVH, :func:`stbs.io.read_bvh`) and glTF animations describe motion on
the *joints* of a hierarchy, each with a local rotation and translation relative to
its parent, not on the bones of a :class:`stbs.Skeleton`. A :class:`Motion` holds that
data as it comes and evaluates it by forward kinematics; retargeting turns it into
poses of a rig.

Convention: a joint's local transform maps its own frame to its parent's,
``x_parent = R x + t``; a root's parent frame is the world. In the rest pose every
rotation is the identity and every translation the joint's offset.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from . import _checks

__all__ = ["Motion"]

# Joint-frames whose rotations are checked at once (bounds the check's temporaries).
_CHECK_BLOCK = 1 << 18


class Motion:
    """Per-frame local rotations and translations of a joint hierarchy.

    Parameters
    ----------
    names : sequence of j str
        Joint names, unique.
    parents : (j,) int
        Parent joint of each joint, -1 for a root; every parent comes before its
        children.
    offsets : (j, 3) float
        Each joint's rest position in its parent's frame (a root's: in the world).
    rotations : (f, j, 3, 3) float
        Local rotation of each joint in each frame (proper rotations).
    translations : (f, j, 3) float, optional
        Local translation of each joint in each frame; default: the offsets in every
        frame (only roots and joints with position channels move otherwise).
    frame_time : float
        Seconds between frames (> 0).
    end_site : (j,) bool, optional
        Joints that only mark where a chain ends (BVH ``End Site``): no channels, a
        rotation that is always the identity. Default: none.
    source : str, optional
        Where the motion comes from (a file name), for messages; kept as ``source``.

    Raises
    ------
    ValueError
        Shapes that do not fit together, non-finite values, repeated names, a parent
        out of range or after its child, rotations that are not rotations, or a
        ``frame_time`` that is not positive; the message names the argument.

    Examples
    --------
    >>> import numpy as np
    >>> R = np.tile(np.eye(3), (2, 2, 1, 1))          # 2 frames, 2 joints
    >>> R[1, 0] = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]   # frame 1: the root turns 90 deg about z
    >>> m = Motion(["hip", "knee"], [-1, 0], [[0, 0, 0], [1, 0, 0]], rotations=R,
    ...            frame_time=1 / 30)
    >>> m.n_frames, m.n_joints, m.fps
    (2, 2, 30.0)
    >>> m.positions()[:, 1].round(6)                   # the knee, per frame
    array([[1., 0., 0.],
           [0., 1., 0.]])
    """

    def __init__(self, names: Sequence[str], parents, offsets, *, rotations,
                 translations=None, frame_time: float, end_site=None,
                 source: str | None = None):
        names = [str(s) for s in names]
        j = len(names)
        if len(set(names)) != j:
            seen: set[str] = set()
            dup = next(s for s in names if s in seen or seen.add(s))
            raise ValueError(f"names must be unique, got {dup!r} twice")
        P = _checks.index_array("parents", parents, ndim=1)
        if P.shape != (j,):
            raise ValueError(f"parents must have shape ({j},) like names, got {P.shape}")
        for k, p in enumerate(P):
            if not -1 <= p < k:
                raise ValueError(f"parents[{k}] must be -1 or a joint before {k}, got {int(p)}")
        O = _checks.real_array("offsets", offsets, ndim=2, shape=(j, 3))
        R = _checks.real_array("rotations", rotations, ndim=4, shape=(None, j, 3, 3))
        f = R.shape[0]
        if f < 1:
            raise ValueError("rotations must hold at least one frame, got 0")
        # checked a slice of frames at a time: the temporaries stay small however long
        # the motion is
        err, flipped = 0.0, False
        step = max(1, _CHECK_BLOCK // max(j, 1))
        for a in range(0, f, step):
            Ra = R[a:a + step]
            err = max(err, float(np.abs(np.einsum("fjik,fjil->fjkl", Ra, Ra) - np.eye(3)).max(
                initial=0.0)))
            flipped = flipped or bool((np.linalg.det(Ra) < 0).any())
        if err > 1e-6 or flipped:
            raise ValueError(f"rotations must be proper rotations (R^T R = I, det 1), off by "
                             f"{err:.3g}")
        if translations is None:
            T = np.broadcast_to(O, (f, j, 3)).copy()
        else:
            T = _checks.real_array("translations", translations, ndim=3, shape=(f, j, 3))
        dt = float(frame_time)
        if not (np.isfinite(dt) and dt > 0):
            raise ValueError(f"frame_time must be a positive number of seconds, got {frame_time!r}")
        es = np.zeros(j, dtype=bool) if end_site is None else np.asarray(end_site, dtype=bool)
        if es.shape != (j,):
            raise ValueError(f"end_site must have shape ({j},) like names, got {es.shape}")
        self.names = names
        self.parents = P.astype(np.int64)
        self.offsets = O
        self.rotations = R
        self.translations = T
        self.frame_time = dt
        self.end_site = es
        self.source = None if source is None else str(source)

    # ------------------------------------------------------------------ sizes
    @property
    def n_frames(self) -> int:
        return int(self.rotations.shape[0])

    @property
    def n_joints(self) -> int:
        """Joints, end sites included."""
        return len(self.names)

    @property
    def fps(self) -> float:
        """Frames per second, ``1 / frame_time``."""
        return 1.0 / self.frame_time

    @property
    def times(self) -> np.ndarray:
        """(f,) seconds of each frame, from 0."""
        return np.arange(self.n_frames) * self.frame_time

    def index(self, name: str) -> int:
        """The joint called ``name``; ValueError listing the names when there is none."""
        try:
            return self.names.index(name)
        except ValueError:
            shown = ", ".join(n if len(n) <= 60 else n[:57] + "..." for n in self.names[:40])
            more = f", ... ({len(self.names)} in all)" if len(self.names) > 40 else ""
            key = name if len(str(name)) <= 60 else str(name)[:57] + "..."
            raise ValueError(f"no joint named {key!r}; the joints are {shown}{more}") from None

    def children(self, k: int) -> list[int]:
        """The joints whose parent is ``k``."""
        return [int(c) for c in np.flatnonzero(self.parents == k)]

    # ------------------------------------------------------------------ kinematics
    def _frames(self, frames) -> np.ndarray:
        if frames is None:
            return np.arange(self.n_frames)
        idx = _checks.index_array("frames", np.atleast_1d(frames), ndim=1)
        if idx.size and (idx.min() < -self.n_frames or idx.max() >= self.n_frames):
            raise ValueError(f"frames must lie in 0..{self.n_frames - 1}, got "
                             f"{int(idx.min() if idx.min() < 0 else idx.max())}")
        return idx % self.n_frames

    def global_transforms(self, frames=None) -> tuple[np.ndarray, np.ndarray]:
        """World rotation and position of every joint's frame, by forward kinematics.

        Parameters
        ----------
        frames : int or (k,) int, optional
            Frame indices (default: all).

        Returns
        -------
        R : (k, j, 3, 3) float
        t : (k, j, 3) float
            ``x_world = R[:, i] x + t[:, i]`` for a point ``x`` in joint ``i``'s frame;
            ``t`` is the joint's world position.
        """
        idx = self._frames(frames)
        Rl, Tl = self.rotations[idx], self.translations[idx]
        R, t = np.empty_like(Rl), np.empty_like(Tl)
        for k, p in enumerate(self.parents):     # parents come first: one pass
            if p < 0:
                R[:, k], t[:, k] = Rl[:, k], Tl[:, k]
            else:
                R[:, k] = R[:, p] @ Rl[:, k]
                t[:, k] = np.einsum("fab,fb->fa", R[:, p], Tl[:, k]) + t[:, p]
        return R, t

    def positions(self, frames=None) -> np.ndarray:
        """(k, j, 3) world joint positions in the given frames (default: all)."""
        return self.global_transforms(frames)[1]

    def rest_positions(self) -> np.ndarray:
        """(j, 3) world joint positions with every rotation the identity and every
        translation the offset (the hierarchy as drawn in the file)."""
        X = np.zeros_like(self.offsets)
        for k, p in enumerate(self.parents):
            X[k] = self.offsets[k] + (X[p] if p >= 0 else 0.0)
        return X

    def skeleton(self, *, tol: float = 1e-9):
        """A :class:`stbs.Skeleton` of this hierarchy's rest pose, and what drives its bones.

        Rule: every joint ``k`` whose offset is longer than ``tol`` gives a bone from its
        parent's position to its own, turned by the parent's rotation (the parent's
        frame holds the offset). Joints at the same place (a zero offset, as the CMU
        files' ``LHipJoint``) share one skeleton joint, so zero-length bones never
        arise. A bone is named after the joint that turns it; when that joint turns
        several bones, the first keeps the name and the others are named
        ``"PARENT>CHILD"``. The bones form one hierarchy, as the joints do: a bone's
        parent is the bone ending where it starts; of the bones starting at a root,
        the one heading the most joints is the root bone and the others hang from its
        start (offset children, DESIGN §2), so that forward kinematics poses the whole
        hierarchy as the motion does.

        Returns
        -------
        sk : Skeleton
            Joints at :meth:`rest_positions` (merged where they coincide), parents ``P``.
        drive : (b,) int
            For each bone, the motion joint whose rotation turns it.
        end : (b,) int
            For each bone, the motion joint at its end.

        Raises
        ------
        ValueError
            When every offset is zero (no bone at all).
        """
        from .skeleton import Skeleton

        X = self.rest_positions()
        j = self.n_joints
        moved = np.array([p >= 0 and np.linalg.norm(self.offsets[k]) > tol
                          for k, p in enumerate(self.parents)], dtype=bool)
        joint_of = np.empty(j, dtype=np.int64)      # motion joint -> skeleton joint
        owner = np.empty(j, dtype=np.int64)         # the joint that placed that one
        C: list[np.ndarray] = []
        for k, p in enumerate(self.parents):
            if p >= 0 and not moved[k]:
                joint_of[k], owner[k] = joint_of[p], owner[p]
            else:
                joint_of[k], owner[k] = len(C), k
                C.append(X[k])
        BE, names, drive, end = [], [], [], []
        taken: set[str] = set()
        for k, p in enumerate(self.parents):
            if not moved[k]:
                continue
            name = self.names[p]
            if name in taken:
                name = f"{name}>{self.names[k]}"
            taken.add(name)
            BE.append([joint_of[p], joint_of[k]])
            names.append(name)
            drive.append(p)
            end.append(k)
        if not BE:
            where = repr(self.source) if self.source else "the motion"
            raise ValueError(f"{where} has no bone: every joint's offset is zero")
        end_a = np.array(end, dtype=np.int64)
        bone_to = {int(e): i for i, e in enumerate(end_a)}     # bone ending at joint e
        size = np.zeros(j, dtype=np.int64)                     # joints below each joint
        for k in range(j - 1, -1, -1):
            if self.parents[k] >= 0:
                size[self.parents[k]] += size[k] + 1
        P = np.full(len(BE), -1, dtype=np.int64)
        at_root: dict[int, list[int]] = {}      # a root's bones, in bone order
        for i, p in enumerate(drive):
            q = int(owner[p])                   # the joint whose offset placed p
            if q in bone_to:
                P[i] = bone_to[q]
            else:                               # a root's bones: one is the root bone
                at_root.setdefault(q, []).append(i)
        for at in at_root.values():
            main = max(at, key=lambda i: (size[end_a[i]], -i))
            for i in at:
                if i != main:
                    P[i] = main
        sk = Skeleton(np.array(C), np.array(BE), names=names, P=P)
        return sk, np.array(drive, dtype=np.int64), end_a

    def __repr__(self) -> str:
        return (f"Motion({self.n_joints - int(self.end_site.sum())} joints + "
                f"{int(self.end_site.sum())} end sites, {self.n_frames} frames at "
                f"{self.fps:.6g} fps)")
