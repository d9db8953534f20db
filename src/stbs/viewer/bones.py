"""A pose's per-bone arrays on the wire: JSON lists, or rows of little-endian float64.

The page's shader takes a pose as its per-bone arrays (:class:`stbs.Pose`): rotations
``R_i`` (b, d, d), posed starts ``a'_i`` (b, d), stretches ``sigma_i`` (b,) and twists
``theta_a,i``, ``theta_b,i`` (b, 2) in radians. The server sends them

- as JSON ``{"rotations", "origins", "stretch", "twist"}`` (nested lists), or
- as binary: one row per bone of ``m = d*d + d + 3`` float64 values, little-endian,
  C order: ``R_i`` row-major (d*d), ``a'_i`` (d), ``sigma_i``, ``theta_a,i``,
  ``theta_b,i``. The headers say ``X-Stbs-Dtype: float64``, ``X-Stbs-Shape: b,m``
  (``k,b,m`` for k frames of a clip) and ``X-Stbs-Byte-Order: little``. For a 3D rig
  m = 15, for a 2D rig m = 9.

The page's own world form of a pose while it drags (``{"R", "A", "S", "T"}``: 3x3
rotations, 3-vector starts, stretches, twists; a 2D rig embedded in 3D with z = 0)
is read by :func:`read_world`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from ..pose import Pose
from ..skeleton import Skeleton
from .refusal import Refusal, one_line, show

__all__ = ["row_width", "rows", "pose_rows", "pose_json", "from_rows", "read_world",
           "WORLD_KEYS"]

#: The keys of the page's world form, and those of the JSON arrays form it may use instead.
WORLD_KEYS = (("R", "A", "S", "T"), ("rotations", "origins", "stretch", "twist"))


def row_width(d: int) -> int:
    """Values per bone in a binary row: ``d*d + d + 3`` (15 in 3D, 9 in 2D)."""
    return d * d + d + 3


def rows(R, O, sigma, theta) -> np.ndarray:
    """Per-bone rows (..., b, m) from arrays batched over any leading axes.

    Examples
    --------
    >>> R = np.eye(2)[None]; O = np.array([[1.0, 2.0]])
    >>> rows(R, O, np.array([1.5]), np.zeros((1, 2))).tolist()
    [[1.0, 0.0, 0.0, 1.0, 1.0, 2.0, 1.5, 0.0, 0.0]]
    """
    R = np.asarray(R, dtype=np.float64)
    d = R.shape[-1]
    out = np.concatenate([R.reshape(R.shape[:-2] + (d * d,)), np.asarray(O, np.float64),
                          np.asarray(sigma, np.float64)[..., None],
                          np.asarray(theta, np.float64)], axis=-1)
    return np.ascontiguousarray(out, dtype=np.dtype(np.float64).newbyteorder("<"))


def pose_rows(pose: Pose) -> np.ndarray:
    """A pose as (b, m) little-endian float64 rows (the binary layout above)."""
    return rows(pose.rotations, pose.origins, pose.stretch, pose.twist)


def pose_json(pose: Pose) -> dict:
    """A pose as ``{"rotations", "origins", "stretch", "twist"}`` nested lists."""
    return {"rotations": pose.rotations.tolist(), "origins": pose.origins.tolist(),
            "stretch": pose.stretch.tolist(), "twist": pose.twist.tolist()}


def from_rows(A: np.ndarray, d: int) -> dict:
    """The arrays of (..., b, m) rows: ``{"rotations", "origins", "stretch", "twist"}``.

    Examples
    --------
    >>> back = from_rows(rows(np.eye(3)[None], [[1.0, 2, 3]], [2.0], [[0.1, 0.2]]), 3)
    >>> back["origins"].tolist(), back["stretch"].tolist(), back["twist"].tolist()
    ([[1.0, 2.0, 3.0]], [2.0], [[0.1, 0.2]])
    """
    A = np.asarray(A, dtype=np.float64)
    k = d * d
    return {"rotations": A[..., :k].reshape(A.shape[:-1] + (d, d)),
            "origins": A[..., k:k + d], "stretch": A[..., k + d],
            "twist": A[..., k + d + 1:k + d + 3]}


def _array(key: str, x: Any, shapes: tuple[tuple[int, ...], ...]) -> np.ndarray:
    """``x`` as a float64 array of one of ``shapes``, else 400 naming ``key``."""
    want = " or ".join(str(s) for s in shapes)
    try:
        A = np.array(x, dtype=np.float64) if isinstance(x, list) else None
    except (ValueError, TypeError, OverflowError):
        A = None
    if A is None:
        raise Refusal(400, f'"{key}": expected numbers of shape {want}, got {show(x)}')
    if A.shape not in shapes:
        raise Refusal(400, f'"{key}": expected shape {want}, got {A.shape}')
    if not np.isfinite(A).all():
        raise Refusal(400, f'"{key}": expected finite numbers')
    return A


def read_world(obj: Any, sk: Skeleton) -> Pose:
    """The page's world form of a pose, checked, as a :class:`stbs.Pose`.

    ``obj`` is ``{"R": (b, 3, 3), "A": (b, 3), "S": (b,), "T": (b, 2)}`` as the page
    holds it while it drags (each bone's world rotation, posed start, stretch and
    twist in radians; a 2D rig's rotations about z with z = 0), or the same under the
    names ``rotations``, ``origins``, ``stretch``, ``twist``; a 2D rig may also send
    (b, 2, 2) and (b, 2). ``T`` may be left out (no twist). Anything else is a
    :class:`Refusal` (400) naming the key.
    """
    if not isinstance(obj, Mapping):
        raise Refusal(400, 'request body: expected a JSON object {"R", "A", "S", "T"} (the '
                           f"world pose), found {show(obj)}")
    names = next((ks for ks in WORLD_KEYS if ks[0] in obj), WORLD_KEYS[0])
    extra = sorted(set(obj) - set(names))
    if extra:
        raise Refusal(400, f"request body: unexpected key {extra[0]!r}; expected "
                           f"{', '.join(names)}")
    for k in names[:3]:
        if k not in obj:
            raise Refusal(400, f'request body: missing "{k}"')
    kR, kA, kS, kT = names
    b, d = sk.n_bones, sk.dim
    R = _array(kR, obj[kR], ((b, d, d), (b, 3, 3)))
    A = _array(kA, obj[kA], ((b, d), (b, 3)))
    S = _array(kS, obj[kS], ((b,),))
    T = _array(kT, obj[kT], ((b, 2),)) if obj.get(kT) is not None else np.zeros((b, 2))
    if d == 2:
        R, A = _flat(R, A, kR, kA)
        if np.any(T != 0):
            raise Refusal(400, f'"{kT}": a 2D rig has no twist; expected zeros')
        T = np.zeros((b, 2))
    try:
        return Pose(sk, rotations=R, origins=A, stretch=S, twist=T)
    except (ValueError, TypeError) as exc:
        raise Refusal(400, one_line(exc)) from None


def _flat(R: np.ndarray, A: np.ndarray, kR: str, kA: str) -> tuple[np.ndarray, np.ndarray]:
    """A 2D rig's arrays from their 3D embedding (rotations about z, z = 0)."""
    if R.shape[1] == 3:
        off = np.abs(R[:, 2, :2]).max(initial=0) + np.abs(R[:, :2, 2]).max(initial=0)
        if off > 1e-9 or np.abs(R[:, 2, 2] - 1).max(initial=0) > 1e-9:
            raise Refusal(400, f'"{kR}": a 2D rig turns about z only; expected rows '
                               "[[c, -s, 0], [s, c, 0], [0, 0, 1]]")
        R = R[:, :2, :2]
    if A.shape[1] == 3:
        if np.abs(A[:, 2]).max(initial=0) > 0:
            raise Refusal(400, f'"{kA}": a 2D rig lies in the plane z = 0; expected z = 0')
        A = A[:, :2]
    return R, A
