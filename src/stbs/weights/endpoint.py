"""Endpoint weights e_i(p) in [0, 1]: 0 at a bone's start, 1 at its end (paper §2.2-2.3)."""

from __future__ import annotations

from typing import Literal

import numpy as np

from .. import _checks
from ..skeleton import Skeleton

ENDPOINT_METHODS: tuple[str, ...] = ("projection",)


def projection(V, sk: Skeleton) -> np.ndarray:
    """Eq. 8: relative position of p's projection onto bone i's segment.

    ``e_i(p) = clamp(((p - a_i) . (b_i - a_i)) / l_i^2, 0, 1)``, which equals
    ``|proj_i(p) - a_i| / |b_i - a_i|`` for the closest point ``proj_i(p)`` on the segment.

    Parameters
    ----------
    V : (n, d) float
    sk : Skeleton

    Returns
    -------
    E : (n, b) float64
        Only C0 where the projection leaves the segment (paper Fig. 7).
    """
    V = _checks.vertices(V)
    if V.shape[1] != sk.dim:
        raise ValueError(f"V must have shape ({V.shape[0]}, {sk.dim}) to match the skeleton, "
                         f"got {V.shape}")
    A = sk.A
    D = sk.B - A
    t = (V @ D.T - np.sum(A * D, axis=1)) / (sk.lengths**2)
    return np.clip(t, 0.0, 1.0)


def joints_to_endpoint(J, sk: Skeleton) -> np.ndarray:
    """Eq. 7: ``e_i = ((1 - j_a) + j_b) / 2`` from joint weights J (n, j) in [0, 1]."""
    J = np.asarray(J, dtype=float)
    if J.ndim != 2 or J.shape[1] != sk.n_joints:
        raise ValueError(f"J must have shape (n, {sk.n_joints}), got {J.shape}")
    return 0.5 * ((1.0 - J[:, sk.BE[:, 0]]) + J[:, sk.BE[:, 1]])


def endpoint_weights(V, sk: Skeleton, method: Literal["projection"] = "projection", *,
                     W=None, F=None, T=None) -> np.ndarray:
    """Endpoint weights E (n, b) by one of the paper's methods.

    Parameters
    ----------
    V : (n, d) float
    sk : Skeleton
    method : {"projection"}
        ``"projection"``: eq. 8. (The shape-aware methods of §2.3 arrive with the
        weights solvers.)
    W, F, T : optional
        Bone weights and mesh elements, used by the shape-aware methods.
    """
    _checks.choice("method", method, ENDPOINT_METHODS)
    return projection(V, sk)
