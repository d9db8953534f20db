"""Boundary conditions for bone weights: which vertices a bone holds at weight 1.

Two cases (boundary conditions never silently give empty weights):

* **Meshes with bone samples** (the ones :mod:`stbs.meshing` builds, libigl's
  ``hand.mesh``): every vertex within ``tol`` of bone i's segment gets the bc row
  ``e_i``. A vertex on several bones -- a joint shared by a parent and its children --
  gets ``1/k`` for each of its k bones, exactly as libigl's ``boundary_conditions``
  does (it collects a 1 per bone and normalises the row). Rows of ``bc`` therefore
  always sum to 1, so the constraints are compatible with a partition of unity, and no
  bone is favoured at a joint.
* **A user's mesh without bone samples**: a bone with no vertex of its own on it is
  constrained at the vertices nearest to ``samples`` points spread along it
  (joints excluded), with a ``UserWarning`` naming the bones and the largest
  distance. A vertex chosen by several bones goes to the bone whose segment is
  nearest (ties are split); a bone left with no vertex at all is a ``ValueError``
  naming it.
"""

from __future__ import annotations

import warnings

import numpy as np

from .. import _checks
from ..skeleton import Skeleton

__all__ = ["boundary_conditions", "segment_distances"]

#: Default distance tolerance, relative to the bounding-box diagonal of V.
ON_BONE_TOL = 1e-6


def segment_distances(P, A, B) -> np.ndarray:
    """Euclidean distances from points to segments.

    Parameters
    ----------
    P : (n, d) float
        Points.
    A, B : (b, d) float
        Segment end points.

    Returns
    -------
    D : (n, b) float64
        ``D[p, i]`` is the distance from ``P[p]`` to the segment ``A[i] B[i]``.
    """
    P, A, B = (np.asarray(x, dtype=float) for x in (P, A, B))
    AB = B - A
    ll = np.einsum("bd,bd->b", AB, AB)
    D = np.empty((P.shape[0], A.shape[0]))
    step = max(1, 2**22 // max(1, A.shape[0] * P.shape[1]))   # bound the temporaries
    for s in range(0, P.shape[0], step):
        AP = P[s:s + step, None, :] - A[None, :, :]
        t = np.clip(np.einsum("nbd,bd->nb", AP, AB) / np.where(ll > 0, ll, 1.0), 0.0, 1.0)
        D[s:s + step] = np.linalg.norm(AP - t[..., None] * AB[None], axis=2)
    return D


def _label(sk: Skeleton, i: int) -> str:
    return f"bone {i} ({sk.names[i]!r})"


def boundary_conditions(V, sk: Skeleton, *, T=None, F=None, samples: int | None = None,
                        tol: float = ON_BONE_TOL) -> tuple[np.ndarray, np.ndarray]:
    """Constrained vertices ``b`` and their values ``bc`` for the bone weights of ``sk``.

    Parameters
    ----------
    V : (n, d) float
        Vertex positions, d = ``sk.dim``.
    sk : Skeleton
    T : (t, 4) int, optional
        Tetrahedra. When ``T`` or ``F`` is given, only vertices of the elements can be
        constrained (an unreferenced vertex would not be part of the solve).
    F : (f, 3) int, optional
        Triangles.
    samples : int, optional
        Points per bone for the nearest-vertex fallback; default: one per mean edge
        length along the bone (with ``F``/``T``), at least 4, else 16.
    tol : float
        A vertex lies on a bone when its distance to the segment is at most ``tol``
        times the bounding-box diagonal of ``V``.

    Returns
    -------
    b : (k,) int64
        Sorted vertex indices.
    bc : (k, b) float64
        Rows sum to 1: ``e_i`` on bone i alone, ``1/k`` on each of k bones meeting at a
        vertex.

    Warns
    -----
    UserWarning
        When some bone has no vertex on it and nearest vertices are used instead.

    Raises
    ------
    ValueError
        For mismatched shapes, or a bone that no vertex can be attached to.
    """
    V = _checks.skeleton(sk, V)
    n = V.shape[0]
    tol = float(tol)
    if not tol >= 0:
        raise ValueError(f"tol must be >= 0, got {tol}")
    if samples is not None and int(samples) < 1:
        raise ValueError(f"samples must be >= 1, got {samples}")
    usable = np.ones(n, dtype=bool)
    edge = None
    elems = []
    for name, X, k in (("T", T, 4), ("F", F, 3)):
        if X is None:
            continue
        X = _checks.index_array(name, X, ndim=2, shape=(None, k))
        if X.size and (X.min() < 0 or X.max() >= n):
            bad = int(X.min()) if X.min() < 0 else int(X.max())
            raise ValueError(f"{name} must hold vertex indices in 0..{n - 1}, got {bad}")
        elems.append(X)
    if elems:
        usable[:] = False
        for X in elems:
            usable[X.ravel()] = True
        X = elems[0]
        e = np.concatenate([X[:, [a, c]] for a in range(X.shape[1])
                            for c in range(a + 1, X.shape[1])])
        edge = float(np.mean(np.linalg.norm(V[e[:, 0]] - V[e[:, 1]], axis=1))) if e.size else None
    scale = float(np.linalg.norm(np.ptp(np.vstack([V, sk.C]), axis=0))) or 1.0
    D = segment_distances(V, sk.A, sk.B)
    D[~usable] = np.inf
    on = D <= tol * scale
    own = on & (on.sum(axis=1) == 1)[:, None]           # on this bone only
    missing = np.flatnonzero(~own.any(axis=0))
    hold = on.astype(float)
    if missing.size:
        cand = np.flatnonzero(usable)
        far = 0.0
        for i in missing.tolist():
            if samples is not None:
                k = int(samples)
            elif edge:
                k = max(4, int(np.ceil(sk.lengths[i] / edge)))
            else:
                k = 16
            t = (np.arange(k) + 0.5) / k
            S = sk.A[i] + t[:, None] * (sk.B[i] - sk.A[i])
            # nearest usable vertex to each sample
            d2 = np.full(k, np.inf)
            near = np.zeros(k, dtype=np.int64)
            step = max(1, 2**22 // max(1, k * V.shape[1]))
            for s in range(0, cand.size, step):
                c = cand[s:s + step]
                dd = np.sum((V[c, None, :] - S[None]) ** 2, axis=2)
                j = np.argmin(dd, axis=0)
                better = dd[j, np.arange(k)] < d2
                d2[better] = dd[j, np.arange(k)][better]
                near[better] = c[j[better]]
            near = np.unique(near)
            far = max(far, float(np.sqrt(d2.max())) / sk.lengths[i])
            hold[near, i] = 1.0
        # a vertex claimed by several bones goes to the nearest segment(s)
        multi = np.flatnonzero((hold > 0).sum(axis=1) > 1)
        if multi.size:
            Dm = np.where(hold[multi] > 0, D[multi], np.inf)
            best = Dm <= Dm.min(axis=1, keepdims=True) * (1 + 1e-9) + tol * scale
            hold[multi] = best.astype(float)
        names = ", ".join(_label(sk, i) for i in missing[:6].tolist())
        more = f" and {missing.size - 6} more" if missing.size > 6 else ""
        warnings.warn(
            f"boundary_conditions: no mesh vertex lies on {names}{more}; constrained the "
            f"vertices nearest to points along each instead (farthest at {far:.3g} bone "
            "lengths). Insert bone samples into the mesh (stbs.meshing) for exact "
            "constraints.", UserWarning, stacklevel=2)
    empty = np.flatnonzero(~(hold > 0).any(axis=0))
    if empty.size:
        i = int(empty[0])
        raise ValueError(f"boundary_conditions: no vertex can be attached to {_label(sk, i)}: "
                         "every vertex near it is closer to another bone. Refine the mesh "
                         "near that bone or insert bone samples into it")
    b = np.flatnonzero(hold.any(axis=1))
    bc = hold[b] / hold[b].sum(axis=1, keepdims=True)
    return b.astype(np.int64), bc
