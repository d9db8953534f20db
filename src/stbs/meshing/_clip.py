"""2D ``clip_skeleton``: the parts of the bones inside the outline, as a skeleton of pieces.

Each bone is cut where it crosses the outline; every inside interval becomes a *piece*,
a bone of its own from a kept joint or a *clip point* (pulled inside by a margin) to
another. The 2D mesher meshes the pieces as it would a skeleton; :meth:`Clip.to_bones`
maps its record (piece, parameter) back to (bone, parameter) afterwards.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from ..skeleton import Skeleton
from ._geometry import point_segment_distance, points_in_loops, scale_of
from ._samples import bone_label
from .outline import Outline


@dataclass
class Clip:
    """Pieces of the bones inside the outline.

    ``sk`` has one bone per piece: piece ``p`` is the part ``t0[p] <= t <= t1[p]`` of
    bone ``bone[p]``. Its joint ``q`` is joint ``joint[q]`` of the input skeleton, or a
    clip point (``joint[q] == -1``) at parameter ``joint_t[q]`` of bone ``joint_bone[q]``.
    """

    sk: Skeleton
    bone: np.ndarray
    t0: np.ndarray
    t1: np.ndarray
    joint: np.ndarray
    joint_bone: np.ndarray
    joint_t: np.ndarray
    n_joints: int

    def counts(self, counts: np.ndarray | None) -> np.ndarray | None:
        """Per-bone sample counts shared out among the pieces by their length."""
        if counts is None:
            return None
        return np.round(counts[self.bone] * (self.t1 - self.t0)).astype(np.int64)

    def to_bones(self, pb: np.ndarray, pt: np.ndarray, joint_vertex: np.ndarray):
        """The mesher's (piece, parameter) record and piece joints' vertices, for bones."""
        on = pb >= 0
        bone = np.full(pb.shape, -1, dtype=np.int64)
        t = np.full(pt.shape, np.nan)
        p = pb[on]
        bone[on] = self.bone[p]
        t[on] = self.t0[p] + pt[on] * (self.t1[p] - self.t0[p])
        cp = self.joint < 0
        bone[joint_vertex[cp]] = self.joint_bone[cp]
        t[joint_vertex[cp]] = self.joint_t[cp]
        jv = np.full(self.n_joints, -1, dtype=np.int64)
        jv[self.joint[~cp]] = joint_vertex[~cp]
        return bone, t, jv


def clip_skeleton_2d(out: Outline, sk: Skeleton, margin: float) -> Clip | None:
    """The bones' parts inside ``out``, or None when the whole skeleton is inside.

    A clip point is placed ``margin`` (at most a tenth of the inside part) inside the
    crossing along the bone, and further until it is at least half that from the
    outline; a part that vanishes so is dropped. A bone with no piece left is a
    ValueError naming it.
    """
    polys = out.polygons()
    S = out.segments
    Q0, Q1 = out.P[S[:, 0]], out.P[S[:, 1]]
    inside_j = points_in_loops(sk.C, polys)
    A, B = sk.A, sk.B
    pieces: list[tuple[int, float, float]] = []
    crossed = False
    for i in range(sk.n_bones):
        d = B[i] - A[i]
        e = Q1 - Q0
        den = d[0] * e[:, 1] - d[1] * e[:, 0]
        w = Q0 - A[i]
        ok = den != 0
        t = np.where(ok, (w[:, 0] * e[:, 1] - w[:, 1] * e[:, 0]) / np.where(ok, den, 1), -1)
        u = np.where(ok, (w[:, 0] * d[1] - w[:, 1] * d[0]) / np.where(ok, den, 1), -1)
        cut = np.unique(t[ok & (t > 0) & (t < 1) & (u >= 0) & (u <= 1)])
        crossed |= cut.size > 0
        knots = np.concatenate([[0.0], cut, [1.0]])
        mid = A[i] + 0.5 * (knots[:-1] + knots[1:])[:, None] * d
        ins = points_in_loops(mid, polys)
        length = float(np.linalg.norm(d))
        k = 0
        while k < ins.size:
            if not ins[k]:
                k += 1
                continue
            s = k
            while k + 1 < ins.size and ins[k + 1]:
                k += 1
            lo, hi = float(knots[s]), float(knots[k + 1])
            # The margin: at most a tenth of the inside part, so short parts stay.
            mg = min(margin, 0.1 * (hi - lo) * length)
            lo = lo if lo == 0.0 and inside_j[sk.BE[i, 0]] else \
                _pull_inside(A[i], d, length, lo, +1, mg, Q0, Q1)
            hi = hi if hi == 1.0 and inside_j[sk.BE[i, 1]] else \
                _pull_inside(A[i], d, length, hi, -1, mg, Q0, Q1)
            if hi - lo > 0.5 * mg / length:
                pieces.append((i, lo, hi))
            k += 1
    if not crossed and inside_j.all():
        return None
    have = np.zeros(sk.n_bones, dtype=bool)
    have[[p[0] for p in pieces]] = True
    if not have.all():
        i = int(np.argmin(have))
        raise ValueError(f"sk: {bone_label(sk, i)} lies outside the outline (no part of it "
                         "is inside the shape); move the skeleton inside")
    # Joints of the pieces: kept input joints once each, then the clip points.
    keyed: dict = {}
    C, joint, jb, jt, BE, names = [], [], [], [], [], []

    def vertex(i: int, t: float, end: int) -> int:
        j = int(sk.BE[i, end])
        key = ("joint", j) if (t == float(end) and inside_j[j]) else ("clip", i, t)
        if key not in keyed:
            keyed[key] = len(C)
            C.append(A[i] + t * (B[i] - A[i]) if key[0] == "clip" else sk.C[j])
            joint.append(j if key[0] == "joint" else -1)
            jb.append(-1 if key[0] == "joint" else i)
            jt.append(np.nan if key[0] == "joint" else t)
        return keyed[key]

    for k, (i, lo, hi) in enumerate(pieces):
        BE.append((vertex(i, lo, 0), vertex(i, hi, 1)))
        names.append(f"{sk.names[i]} [inside part {k}]")
    bone = np.array([p[0] for p in pieces], dtype=np.int64)
    left_j = np.flatnonzero(~inside_j)
    far = 0.0
    if left_j.size:
        far = float(point_segment_distance(sk.C[left_j, None], Q0[None], Q1[None]).min(axis=1)
                    .max())
    whole = [(i, lo, hi) for i, lo, hi in pieces if lo == 0.0 and hi == 1.0]
    n_clipped = sk.n_bones - len(whole)
    size = scale_of(np.vstack([out.P, sk.C]))
    gone = (f"{left_j.size} joint(s) outside left out, the farthest {far:.3g} outside "
            f"({100 * far / size:.2g} % of the shape's size)") if left_j.size \
        else "no joint outside"
    warnings.warn(f"triangulate_2d: {n_clipped} bone(s) cross the outline and are meshed only "
                  f"inside it ({gone})", UserWarning, stacklevel=3)
    return Clip(sk=Skeleton(np.array(C), np.array(BE, dtype=np.int64), names=names),
                bone=bone, t0=np.array([p[1] for p in pieces]),
                t1=np.array([p[2] for p in pieces]), joint=np.array(joint, dtype=np.int64),
                joint_bone=np.array(jb, dtype=np.int64), joint_t=np.array(jt),
                n_joints=sk.n_joints)


def _pull_inside(a, d, length: float, t: float, sign: int, margin: float, Q0, Q1) -> float:
    """Parameter ``margin`` (then 2, 4, ... times it) inside the crossing at ``t`` along
    the bone, until the point is at least ``margin / 2`` from the outline."""
    step = margin / length
    for _ in range(8):
        s = t + sign * step
        if not 0.0 < s < 1.0:
            return s
        if point_segment_distance(a + s * d, Q0, Q1).min() >= 0.5 * margin:
            return s
        step *= 2.0
    return t + sign * step
