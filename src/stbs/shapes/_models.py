"""Rigged models meshed from blended primitives: :class:`Model` and :func:`arm`."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..skeleton import Skeleton
from ._fields import blend, ellipsoid, round_cone
from ._marching import mesh_primitives

__all__ = ["Model", "arm"]


@dataclass(frozen=True, eq=False)
class Model:
    """A built-in shape with its skeleton.

    Attributes
    ----------
    V : (n, 3) or (n, 2) float64
        Rest positions.
    F : (f, 3) int64
        Triangles: a closed, outward-oriented surface in 3D; counter-clockwise
        triangles of the shape in 2D, with every bone a chain of edges.
    sk : Skeleton
        Bones strictly inside the shape.
    name : str
        The model's name.
    extra : dict
        Model-specific data, listed in each model's docstring.
    """

    V: np.ndarray
    F: np.ndarray
    sk: Skeleton
    name: str
    extra: dict = field(default_factory=dict)

    @property
    def dim(self) -> int:
        """2 or 3."""
        return int(self.V.shape[1])

    def __repr__(self) -> str:
        return (f"Model({self.name!r}, {self.V.shape[0]} vertices, {self.F.shape[0]} "
                f"triangles, {self.sk.n_bones} bones, {self.dim}-D)")


def _flag(name: str, x) -> bool:
    if not isinstance(x, (bool, np.bool_)):
        raise ValueError(f"{name} must be True or False, got {x!r}")
    return bool(x)


def arm(*, quick: bool = False) -> Model:
    """An arm with a (mitten) hand along x, three bones: the paper's Figs. 1 and 5.

    Shoulder at the origin, elbow at x = 1.45, wrist at x = 2.65, hand tip at x = 3.4;
    the palm faces -y and the thumb points towards +z, so a 180 degree wrist twist
    turns the thumb to -z. One watertight surface of blended round cones (upper arm,
    biceps, forearm, palm, mitten, thumb), about 4 units long.

    Parameters
    ----------
    quick : bool, keyword-only
        A coarser mesh (about 1.8k vertices instead of 6.5k) for fast runs.

    Returns
    -------
    Model
        ``V`` (n, 3) float64, ``F`` (f, 3) int64 closed and outward. ``sk``: bones
        ``"upper"`` (shoulder -> elbow), ``"fore"`` (elbow -> wrist), ``"hand"``
        (wrist -> hand tip). ``extra``: ``"wrist"`` (3,) the wrist joint,
        ``"wrist_axis"`` (3,) the forearm's unit axis, ``"hand"`` (n,) bool, the
        vertices beyond the wrist plane (for a hand-volume measure), ``"sdf"`` the
        distance field of the shape.

    Examples
    --------
    >>> from stbs.shapes import arm
    >>> m = arm(quick=True)
    >>> m.sk.names, m.V.shape[1], m.F.shape[1]
    (['upper', 'fore', 'hand'], 3, 3)
    """
    quick = _flag("quick", quick)
    C = [[0.0, 0.0, 0.0], [1.45, 0.0, 0.0], [2.65, 0.0, 0.0], [3.4, 0.0, 0.0]]
    parts = [
        round_cone((-0.05, 0.0, 0.0), C[1], 0.26, 0.19),                   # upper arm
        ellipsoid((0.7, 0.05, 0.0), (0.5, 0.22, 0.21), k=0.2),              # biceps
        round_cone(C[1], C[2], 0.18, 0.12, k=0.1),                          # forearm
        ellipsoid((1.85, 0.02, 0.0), (0.45, 0.19, 0.2), k=0.2),             # its muscles
        ellipsoid((2.5, 0.0, 0.0), (0.25, 0.11, 0.15), k=0.1),              # flat wrist
        ellipsoid((2.95, 0.0, 0.0), (0.3, 0.1, 0.21), k=0.12),              # palm
        ellipsoid((3.33, -0.01, 0.0), (0.27, 0.08, 0.18), k=0.08),          # mitten
        round_cone((2.85, -0.02, 0.14), (3.08, -0.05, 0.31), 0.075, 0.065, k=0.1),  # thumb
    ]
    h = 0.11 if quick else 0.06
    V, F = mesh_primitives(parts, h)
    sk = Skeleton(np.asarray(C, dtype=float), np.asarray([[0, 1], [1, 2], [2, 3]],
                                                         dtype=np.int64),
                  names=["upper", "fore", "hand"])
    wrist = np.array(C[2])
    axis = np.array([1.0, 0.0, 0.0])
    return Model(V, F, sk, "arm", {"sdf": blend(parts, h), "wrist": wrist,
                                   "wrist_axis": axis, "hand": (V - wrist) @ axis > 0})
