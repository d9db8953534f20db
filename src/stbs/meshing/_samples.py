"""Points along the skeleton: every joint and samples inside every bone."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..skeleton import Skeleton

#: Most samples one bone gets by default (an explicit ``bone_samples`` may ask for more).
MAX_AUTO_SAMPLES = 200


@dataclass
class SkeletonPoints:
    """Joints first, then the inner samples of bone 0, bone 1, ...

    ``X[:j] == sk.C``; inner sample k lies on bone ``bone[k]`` at parameter ``t[k]``
    (``bone`` and ``t`` are -1 / NaN for the joints).
    """

    X: np.ndarray
    bone: np.ndarray
    t: np.ndarray

    @property
    def n_joints(self) -> int:
        return int(np.count_nonzero(self.bone < 0))


def check_bone_samples(bone_samples, sk: Skeleton) -> np.ndarray | None:
    """``bone_samples``: None (automatic), an int for every bone, or one int per bone."""
    if bone_samples is None:
        return None
    a = np.asarray(bone_samples)
    if a.dtype.kind not in "iu" or a.ndim > 1 or (a.ndim == 1 and a.size != sk.n_bones):
        raise ValueError(f"bone_samples must be None, an int or {sk.n_bones} ints (one per "
                         f"bone), got {bone_samples!r}")
    a = np.broadcast_to(a, (sk.n_bones,)).astype(np.int64)
    if a.min() < 0:
        raise ValueError(f"bone_samples must be >= 0, got {int(a.min())}")
    return a


def sample_skeleton(sk: Skeleton, spacing: float, counts: np.ndarray | None) -> SkeletonPoints:
    """Joints plus evenly spaced inner samples on every bone.

    ``counts[i]`` inner samples on bone i, or (``counts`` None) as many as keep
    neighbouring samples at most ``spacing`` apart (at least one per bone, so every
    bone has a vertex of its own for the boundary conditions, at most
    ``MAX_AUTO_SAMPLES``).
    """
    if counts is None:
        counts = np.clip(np.ceil(sk.lengths / spacing).astype(np.int64) - 1, 1,
                         MAX_AUTO_SAMPLES)
    A, B = sk.A, sk.B
    bones = np.repeat(np.arange(sk.n_bones), counts)
    # t = k / (m + 1), k = 1..m for each bone: exact a + t (b - a) positions.
    k = np.arange(bones.size) - np.repeat(np.cumsum(counts) - counts, counts) + 1
    t = k / (counts[bones] + 1.0)
    X = A[bones] + t[:, None] * (B[bones] - A[bones])
    j = sk.n_joints
    return SkeletonPoints(
        X=np.vstack([sk.C, X]),
        bone=np.concatenate([np.full(j, -1, dtype=np.int64), bones]),
        t=np.concatenate([np.full(j, np.nan), t]),
    )


def bone_label(sk: Skeleton, i: int) -> str:
    """``bone 3 ('forearm', joints 2->3)``, as :class:`stbs.Skeleton` names bones."""
    return f"bone {i} ({sk.names[i]!r}, joints {sk.BE[i, 0]}->{sk.BE[i, 1]})"


def fmt_point(x) -> str:
    return "(" + ", ".join(f"{v:.6g}" for v in np.asarray(x, dtype=float)) + ")"
