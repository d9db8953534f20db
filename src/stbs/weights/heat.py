"""Bone heat weights (Baran & Popović 2007, §4), for bones and for joints shrunk to points.

For handles ``h`` (bone segments, or points for the joint weights of the STBS
paper §2.3) and each vertex ``j`` of the shape, let ``d(j)`` be the distance to the
nearest handle *visible* from ``j`` (the segment from ``j`` to its closest point on
the handle stays inside the shape). Handle ``i``'s weights solve::

    (-Δ + H) w_i = H p_i,        H_jj = k c / d(j)^2,   p_i(j) = 1/k

where the ``k`` handles within a relative ``TIE_TOL`` of ``d(j)`` are the nearest
(``k = 1`` almost everywhere; at a joint shared by two bones ``k = 2``), and
``p_i(j) = 0``, ``H_jj = 0`` for the others and for vertices that see no handle (they
get their weights by diffusion). ``Δ = M^-1 L`` with the cotangent Laplacian ``L``
and the mixed Voronoi areas ``M`` of :mod:`stbs.weights.laplacian`, so the system
solved is the symmetric positive definite ``(-L + M H) w_i = M H p_i``: one
factorization serves every handle. The weights of all handles sum to 1 wherever
some handle is nearest.

Shapes: a 3D surface ``(V, F)``, where visibility is ray casting against its
triangles (:mod:`stbs.weights._raycast`: Embree when ``embreex`` is installed, else
a NumPy BVH), or a 2D triangle mesh, where the boundary edges block visibility.

Every connected component is solved on its own (the matrix is block diagonal). A
component from which no handle is visible would get all-zero weights; instead
its vertices use the Euclidean-nearest handles, ignoring visibility, and a
:class:`BoneHeatWarning` names the component. A handle that is nearest-visible for
no vertex has all-zero weights: by default that is a ``ValueError`` naming it, and
:class:`HeatReport` says which handles lost their vertices to occlusion.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from .. import _checks
from ..skeleton import Skeleton
from . import _raycast
from ._progress import check_callable
from .laplacian import cotmatrix, massmatrix

__all__ = ["BoneHeatSolver", "BoneHeatWarning", "HeatReport", "bone_heat",
           "heat_joint_weights", "TIE_TOL"]

#: Handles whose distance is within this relative tolerance of the nearest visible
#: one count as equally near (Baran & Popović's tie rule: ``p = 1/k``, ``H = k c / d^2``).
TIE_TOL = 1e-4
#: Inward offset of the visibility segments' start, in mean edge lengths: the start
#: must leave the vertex's own triangles behind, yet stay inside thin parts.
OFFSET_EDGES = 1e-2

OnEmpty = Literal["raise", "warn"]
_ON_EMPTY = ("raise", "warn")


class BoneHeatWarning(UserWarning):
    """A bone-heat fallback was taken (a blind component, a handle with no weight)."""


@dataclass(frozen=True)
class HeatReport:
    """What the visibility pass found, per handle (bone or joint).

    Attributes
    ----------
    labels : tuple of str
        One per handle, e.g. ``"bone 2 ('forearm')"`` or ``"joint 3"``.
    n_nearest : (h,) int
        Vertices of the solved (sub)mesh whose nearest visible handle this is (ties
        count for each; blind components count their Euclidean-nearest handles).
    n_occluded : (h,) int
        Vertices for which this is the Euclidean-nearest handle but the segment to it
        leaves the shape. Large counts with ``n_nearest == 0`` mean the handle lies
        (partly) outside the shape.
    n_blind : int
        Vertices that see no handle at all; they get weights by diffusion.
    n_components : int
        Connected components of the (sub)mesh solved on.
    blind_components : tuple of int
        Components that see no handle; they used the Euclidean-nearest handles.
    empty : tuple of int
        Handles whose weights are zero everywhere.
    backend : str
        Visibility backend: ``"embree"``, ``"numpy"`` or ``"numpy-2d"``.
    """

    labels: tuple[str, ...]
    n_nearest: np.ndarray
    n_occluded: np.ndarray
    n_blind: int
    n_components: int
    blind_components: tuple[int, ...] = ()
    empty: tuple[int, ...] = ()
    backend: str = field(default="numpy")

    def __str__(self) -> str:
        w = max((len(s) for s in self.labels), default=6)
        lines = [f"{'handle':<{w}}  nearest  occluded"]
        for s, a, b in zip(self.labels, self.n_nearest, self.n_occluded, strict=True):
            flag = "  <- no weight" if a == 0 else ""
            lines.append(f"{s:<{w}}  {a:7d}  {b:8d}{flag}")
        lines.append(f"{self.n_blind} vertices see no handle; {self.n_components} components"
                     + (f", blind: {list(self.blind_components)}" if self.blind_components
                        else "") + f"; visibility backend {self.backend}")
        return "\n".join(lines)


@dataclass
class _Nearest:
    D: np.ndarray        # (n, h) distance to each handle's closest point
    near: np.ndarray     # (n, h) bool: among the nearest visible handles
    dstar: np.ndarray    # (n,) distance to the nearest visible handle, inf if none
    n_occluded: np.ndarray


def _factorize(A):
    """A solve function for the sparse SPD matrix A (:mod:`._cholesky`: CHOLMOD if
    installed, else SciPy's SuperLU in symmetric mode)."""
    from ._cholesky import factorize
    return factorize(A).solve


class BoneHeatSolver:
    """Bone heat on one shape: Laplacian, normals and ray caster built once.

    Parameters
    ----------
    V : (n, 3) or (n, 2) float
        A 3D surface's vertices, or a 2D shape's.
    F : (f, 3) int
        Triangles.
    backend : {"auto", "embree", "numpy"}
        Visibility ray casting in 3D (see :class:`stbs.weights._raycast.SegmentCaster`).
    offset : float, optional
        How far inside the shape, along the vertex normal, visibility segments start.
        Default: ``OFFSET_EDGES`` mean edge lengths.

    Examples
    --------
    Two bones along the middle of a 4 x 2 grid of squares (a 2D shape):

    >>> import numpy as np
    >>> import stbs
    >>> x, y = np.meshgrid(np.arange(5.0), np.arange(3.0), indexing="ij")
    >>> V = np.c_[x.ravel(), y.ravel()]           # vertex 3 i + j at (i, j)
    >>> q = np.array([3 * i + j for i in range(4) for j in range(2)])
    >>> F = np.r_[np.c_[q, q + 3, q + 4], np.c_[q, q + 4, q + 1]]
    >>> sk = stbs.Skeleton([[0.5, 1.0], [2.0, 1.0], [3.5, 1.0]], [[0, 1], [1, 2]])
    >>> solver = BoneHeatSolver(V, F)
    >>> W, report = solver.solve(sk.A, sk.B, labels=[f"bone {i}" for i in range(sk.n_bones)])
    >>> W[[4, 7, 10]].round(6)                    # on bone 0, at the joint, on bone 1
    array([[1. , 0. ],
           [0.5, 0.5],
           [0. , 1. ]])
    """

    def __init__(self, V, F, *, backend: _raycast.RayBackend = "auto",
                 offset: float | None = None):
        V = _checks.vertices(V)
        F = _faces(F, V.shape[0])
        _checks.choice("backend", backend, _raycast.RAY_BACKENDS)
        self.V, self.F = V, F
        self.dim = V.shape[1]
        edges = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
        mean_edge = float(np.mean(np.linalg.norm(V[edges[:, 0]] - V[edges[:, 1]], axis=1)))
        if offset is None:
            offset = OFFSET_EDGES * mean_edge
        elif not (np.isfinite(offset) and offset >= 0):
            raise ValueError(f"offset must be a finite number >= 0, got {offset!r}")
        self.offset = float(offset)
        self._used = np.unique(F)
        self._caster = _raycast.SegmentCaster(V, F, backend=backend)
        self.backend = self._caster.backend
        N = _inward_normals(V, F)
        self._origins = V + self.offset * N
        self._scale = max(float(np.ptp(V, axis=0).max()), 1e-300)
        self._cache: tuple[bytes, _Nearest] | None = None

    # -- visibility -------------------------------------------------------------------
    def _nearest(self, P0: np.ndarray, P1: np.ndarray, report=None) -> _Nearest:
        """The nearest visible handles; ``report(r, h + 1)`` before each ray-casting round."""
        key = P0.tobytes() + P1.tobytes()
        if self._cache is not None and self._cache[0] == key:
            return self._cache[1]
        V = self.V
        n, h = V.shape[0], P0.shape[0]
        seg = P1 - P0
        len2 = np.sum(seg**2, axis=1)
        safe = np.where(len2 > 0, len2, 1.0)
        # Closest point on each handle: parameter t (n, h), zero for point handles.
        T = np.clip(((V @ seg.T) - np.sum(P0 * seg, axis=1)) / safe, 0.0, 1.0)
        T[:, len2 == 0] = 0.0
        D = _distances(V, P0, seg, T)
        order = np.argsort(D, axis=1, kind="stable")
        near = np.zeros((n, h), dtype=bool)
        dstar = np.full(n, np.inf)
        first_occluded = np.zeros(n, dtype=bool)
        active = self._used      # vertices in no triangle (e.g. a tet mesh's inside) skip
        for r in range(h):
            if report is not None:
                report(r, h + 1)
            hnd = order[active, r]
            test = D[active, hnd] <= dstar[active] * (1 + TIE_TOL)
            active, hnd = active[test], hnd[test]
            if active.size == 0:
                break
            Q = P0[hnd] + T[active, hnd, None] * seg[hnd]
            O = self._origins[active]
            occ = self._caster.occluded(O, Q - O)
            if r == 0:
                first_occluded[active] = occ
            seen = ~occ
            near[active[seen], hnd[seen]] = True
            fresh = seen & ~np.isfinite(dstar[active])
            dstar[active[fresh]] = D[active[fresh], hnd[fresh]]
        n_occ = np.bincount(order[first_occluded, 0], minlength=h)
        out = _Nearest(D=D, near=near, dstar=dstar, n_occluded=n_occ)
        self._cache = (key, out)
        return out

    # -- solve ------------------------------------------------------------------------
    def solve(self, P0, P1=None, *, c: float = 1.0, faces=None, columns=None,
              labels: Sequence[str] | None = None, on_empty: OnEmpty = "raise",
              context: str = "", progress=None) -> tuple[np.ndarray, HeatReport]:
        """Heat weights of handles (segments ``P0[i] -> P1[i]``, or points ``P0[i]``).

        Parameters
        ----------
        P0 : (h, d) float
            Handle starts (or the points, when ``P1`` is None).
        P1 : (h, d) float, optional
            Handle ends; a row equal to its ``P0`` row is a point handle.
        c : float
            Heat constant (1 in Baran & Popović).
        faces : (f,) bool or int array, optional
            Solve on this subset of the triangles only (the STBS §3 restriction);
            vertices outside it get 0. Visibility still uses the whole shape.
        columns : sequence of int, optional
            Which handles' weights to return (default all). All handles still
            compete for the nearest-visible role.
        labels : sequence of h str, optional
            Names for messages and the report (default ``"handle i"``).
        on_empty : {"raise", "warn"}
            A requested handle that is nearest-visible for no vertex of the (sub)mesh
            has all-zero weights: raise a ``ValueError`` naming it, or warn.
        context : str
            Prefix for messages (e.g. which bone's restricted solve this is).
        progress : callable, optional
            ``progress(done, h + 1)`` before each round of visibility ray casting
            (``done`` < h), then ``(h + 1, h + 1)`` once solved. Raise from it to cancel.

        Returns
        -------
        X : (n, len(columns)) float64
            In [0, 1]; rows over all handles sum to 1 on the solved vertices.
        report : HeatReport
        """
        P0 = _checks.real_array("P0", P0, ndim=2, shape=(None, self.dim))
        P1 = P0 if P1 is None else _checks.real_array("P1", P1, shape=P0.shape)
        if P0.shape[0] == 0:
            raise ValueError("P0 must hold at least one handle, got shape "
                             f"{P0.shape}")
        h = P0.shape[0]
        if not (np.isfinite(c) and c > 0):
            raise ValueError(f"c must be a finite number > 0, got {c!r}")
        _checks.choice("on_empty", on_empty, _ON_EMPTY)
        labels = tuple(labels) if labels is not None else tuple(f"handle {i}" for i in range(h))
        if len(labels) != h:
            raise ValueError(f"labels must have {h} entries, got {len(labels)}")
        cols = np.arange(h) if columns is None else np.asarray(columns, dtype=np.int64)
        if cols.size and (cols.min() < 0 or cols.max() >= h):
            raise ValueError(f"columns must lie in 0..{h - 1}, got {cols.tolist()}")
        F = self.F
        if faces is not None:
            faces = np.asarray(faces)
            F = F[faces]
        V = self.V
        n = V.shape[0]
        X = np.zeros((n, cols.size))
        nv = self._nearest(P0, P1, progress)
        if F.shape[0] == 0:
            report = HeatReport(labels, np.zeros(h, np.int64), nv.n_occluded, 0, 0,
                                (), tuple(int(i) for i in cols), self.backend)
            _empty(report, cols, on_empty, context)
            return X, report
        used = np.unique(F)
        # Components of the (sub)mesh; unreferenced vertices are left out.
        adj = sp.coo_matrix((np.ones(3 * len(F)),
                             (F.ravel(), np.roll(F, 1, axis=1).ravel())), shape=(n, n))
        _, comp = connected_components(adj, directed=False)
        _, comp_used = np.unique(comp[used], return_inverse=True)
        comp_used = comp_used.ravel()
        n_comp = int(comp_used.max()) + 1
        near = nv.near[used]
        dstar = nv.dstar[used]
        D = nv.D[used]
        seen = np.isfinite(dstar)
        comp_sees = np.bincount(comp_used, weights=seen, minlength=n_comp) > 0
        blind_comps = np.flatnonzero(~comp_sees)
        if blind_comps.size:
            # A component seeing no handle would get all-zero weights: use the
            # Euclidean-nearest handles there instead (visibility ignored).
            rows = np.isin(comp_used, blind_comps)
            dmin = D[rows].min(axis=1)
            near = near.copy()
            dstar = dstar.copy()
            near[rows] = D[rows] <= dmin[:, None] * (1 + TIE_TOL)
            dstar[rows] = dmin
            for k in blind_comps.tolist():
                members = used[comp_used == k]
                warnings.warn(
                    f"{context}bone heat: component {k} ({members.size} vertices, e.g. vertex "
                    f"{int(members[0])}) sees no handle from inside the shape; its weights "
                    "come from the Euclidean-nearest handles, ignoring visibility",
                    BoneHeatWarning, stacklevel=3)
        n_blind = int(np.count_nonzero(~np.isfinite(dstar)))
        k = near.sum(axis=1)
        floor = 1e-6 * self._scale
        d2 = np.maximum(np.where(np.isfinite(dstar), dstar, 1.0), floor) ** 2
        # H_jj = k c / d^2 and p_i(j) = 1/k, so M H p_i = M c / d^2 on the k nearest.
        heat = np.where(k > 0, c / d2, 0.0)
        L = cotmatrix(V, F, degenerate="skip")
        m = massmatrix(V, F, degenerate="skip").diagonal()
        A = (-L)[used][:, used] + sp.diags(m[used] * heat * k)
        rhs = (m[used] * heat)[:, None] * near[:, cols]
        counts = near.sum(axis=0)
        empty = tuple(int(i) for i in cols if counts[i] == 0)
        report = HeatReport(labels, counts.astype(np.int64), nv.n_occluded, n_blind, n_comp,
                            tuple(int(i) for i in blind_comps), empty, self.backend)
        _empty(report, cols, on_empty, context)
        if rhs.any():
            sol = _factorize(sp.csc_matrix(A))(np.asarray(rhs, dtype=float))
            X[used] = np.clip(sol.reshape(used.size, cols.size), 0.0, 1.0)
        if progress is not None:
            progress(h + 1, h + 1)
        return X, report


def _distances(V: np.ndarray, P0: np.ndarray, seg: np.ndarray, T: np.ndarray) -> np.ndarray:
    """(n, h) distance from each vertex to ``P0 + T seg`` (its closest point on handle)."""
    D = np.empty(T.shape)
    for i in range(P0.shape[0]):  # loop over handles, vectorised over vertices
        D[:, i] = np.linalg.norm(V - (P0[i] + T[:, i, None] * seg[i]), axis=1)
    return D


def _empty(report: HeatReport, cols: np.ndarray, on_empty: str, context: str) -> None:
    if not report.empty:
        return
    parts = []
    for i in report.empty:
        why = (f"it is the Euclidean-nearest handle of {report.n_occluded[i]} vertices, all of "
               "which it is hidden from (does it lie outside the shape?)"
               if report.n_occluded[i] else "no vertex has it as nearest handle")
        parts.append(f"{report.labels[i]} ({why})")
    msg = (f"{context}bone heat: {len(parts)} handle(s) get zero weight everywhere: "
           + "; ".join(parts))
    if on_empty == "raise":
        raise ValueError(msg)
    warnings.warn(msg, BoneHeatWarning, stacklevel=4)


def _faces(F, n: int) -> np.ndarray:
    F = _checks.index_array("F", F, ndim=2, shape=(None, 3))
    if F.shape[0] == 0:
        raise ValueError("F must hold at least one triangle, got shape (0, 3)")
    if F.min() < 0 or F.max() >= n:
        bad = int(F.min()) if F.min() < 0 else int(F.max())
        raise ValueError(f"F must hold vertex indices in 0..{n - 1}, got {bad}")
    return F


def _inward_normals(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Unit vectors pointing into the shape at boundary vertices (0 elsewhere).

    3D: minus the area-weighted vertex normals, flipped per connected component when
    its signed volume is negative (an inside-out surface). 2D: the inward normals of
    the boundary edges, oriented by each triangle's winding.
    """
    n = V.shape[0]
    if V.shape[1] == 3:
        fn = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
        N = np.zeros((n, 3))
        for j in range(3):
            np.add.at(N, F[:, j], fn)
        adj = sp.coo_matrix((np.ones(3 * len(F)),
                             (F.ravel(), np.roll(F, 1, axis=1).ravel())), shape=(n, n))
        _, comp = connected_components(adj, directed=False)
        vol = np.bincount(comp[F[:, 0]], weights=np.einsum("ij,ij->i", V[F[:, 0]], fn),
                          minlength=int(comp.max()) + 1)
        sign = np.where(vol[comp] < 0, 1.0, -1.0)
        N *= sign[:, None]
    else:
        signed = ((V[F[:, 1], 0] - V[F[:, 0], 0]) * (V[F[:, 2], 1] - V[F[:, 0], 1])
                  - (V[F[:, 1], 1] - V[F[:, 0], 1]) * (V[F[:, 2], 0] - V[F[:, 0], 0]))
        Fo = np.where((signed < 0)[:, None], F[:, ::-1], F)
        edges = _raycast._boundary_edges(Fo)
        d = V[edges[:, 1]] - V[edges[:, 0]]
        inward = np.stack([-d[:, 1], d[:, 0]], axis=1)   # left of a CCW edge
        N = np.zeros((n, 2))
        np.add.at(N, edges[:, 0], inward)
        np.add.at(N, edges[:, 1], inward)
    norm = np.linalg.norm(N, axis=1)
    return np.divide(N, norm[:, None], out=np.zeros_like(N), where=norm[:, None] > 0)


def _bone_labels(sk: Skeleton) -> list[str]:
    return [f"bone {i} ({sk.names[i]!r})" for i in range(sk.n_bones)]


def bone_heat(V, F, sk: Skeleton, *, c: float = 1.0,
              backend: _raycast.RayBackend = "auto", on_empty: OnEmpty = "raise",
              return_report: bool = False, progress=None):
    """Bone heat weights W (Baran & Popović 2007) of a 3D surface or a 2D shape.

    Parameters
    ----------
    V : (n, 3) or (n, 2) float
    F : (f, 3) int
        Surface triangles (3D) or the shape's triangles (2D).
    sk : Skeleton
    c : float
        Heat constant (1 in the original).
    backend : {"auto", "embree", "numpy"}
        Visibility ray casting (3D).
    on_empty : {"raise", "warn"}
        A bone visible as nearest from no vertex: ``ValueError`` naming it, or a
        :class:`BoneHeatWarning` (its column is then zero).
    return_report : bool
        Also return the :class:`HeatReport`.
    progress : callable, optional
        ``progress(done, total)``, ``total = b + 1``: before each round of visibility
        ray casting (one per rank of nearness, at most b), then ``(b + 1, b + 1)``
        once solved. Raise any exception from it to cancel: it propagates, and
        ``progress`` is not called again.

    Returns
    -------
    W : (n, b) float64
        Non-negative, rows sum to 1 (to solver precision).
    report : HeatReport
        Only with ``return_report=True``.
    """
    V = _checks.skeleton(sk, V)
    check_callable(progress)
    solver = BoneHeatSolver(V, F, backend=backend)
    W, report = solver.solve(sk.A, sk.B, c=c, labels=_bone_labels(sk), on_empty=on_empty,
                             progress=progress)
    W = _normalise_rows(W)
    return (W, report) if return_report else W


def heat_joint_weights(V, F, sk: Skeleton, *, c: float = 1.0,
                       backend: _raycast.RayBackend = "auto", on_empty: OnEmpty = "raise",
                       return_report: bool = False):
    """Joint weights J by bone heat with every joint a bone shrunk to a point (paper §2.3).

    Parameters are those of :func:`bone_heat`.

    Returns
    -------
    J : (n, j) float64
        In [0, 1], rows sum to 1. Combine with :func:`stbs.weights.joints_to_endpoint`
        (eq. 7) for endpoint weights.
    report : HeatReport
        Only with ``return_report=True``.
    """
    V = _checks.skeleton(sk, V)
    solver = BoneHeatSolver(V, F, backend=backend)
    J, report = solver.solve(sk.C, None, c=c,
                             labels=[f"joint {k}" for k in range(sk.n_joints)],
                             on_empty=on_empty)
    J = _normalise_rows(J)
    return (J, report) if return_report else J


def _normalise_rows(W: np.ndarray) -> np.ndarray:
    """Remove solver round-off from the partition of unity (rows are ~1 already)."""
    s = W.sum(axis=1, keepdims=True)
    return np.divide(W, s, out=np.zeros_like(W), where=s > 0)
