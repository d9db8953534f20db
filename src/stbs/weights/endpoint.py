"""Endpoint weights e_i(p) in [0, 1]: 0 at a bone's start, 1 at its end (paper §2.2-2.3).

Methods (``endpoint_weights(..., method=...)``; details in docs/endpoint-weights.md):

==============  =================================================================
``projection``  eq. 8, the clamped position of p's projection along the bone
``idw``         eq. 9 inverse-distance joint weights (exponent ``alpha >= 2``), eq. 7
``heat``        bone heat with each joint a bone shrunk to a point (3D surface
                ``F``, or a 2D shape), joint weights, eq. 7
``bbw``         BBW solved for e_i directly: 0 at ``a_i``, 1 at ``b_i``, ``t`` at mesh
                vertices on the bone (linear along it); needs ``T`` (3D) or ``F`` (2D)
``bbw-joints``  BBW joint weights (1 at the joint, 0 at the other joints), eq. 7
==============  =================================================================

The solved methods (heat, bbw, bbw-joints) are restricted, bone by bone, to where the
bone weight ``W[:, i] > threshold`` (paper §3, 1e-7), when ``W`` is given.
"""

from __future__ import annotations

import threading
import warnings
from concurrent.futures import ThreadPoolExecutor
from typing import Literal

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from .. import _checks
from ..skeleton import Skeleton
from . import _raycast
from ._progress import Guard

__all__ = ["ENDPOINT_METHODS", "IDW_NORMALIZATIONS", "DEFAULT_THRESHOLD", "endpoint_weights",
           "projection", "idw", "idw_joint_weights", "heat_endpoint", "bbw_endpoint",
           "joints_to_endpoint", "bone_points"]

EndpointMethod = Literal["projection", "idw", "heat", "bbw", "bbw-joints"]
ENDPOINT_METHODS: tuple[str, ...] = ("projection", "idw", "heat", "bbw", "bbw-joints")
IdwNormalization = Literal["bone", "all"]
IDW_NORMALIZATIONS: tuple[str, ...] = ("bone", "all")
#: Paper §3: endpoint weights are solved only where the bone weight exceeds this.
DEFAULT_THRESHOLD = 1e-7
#: A mesh vertex within this fraction of the bounding-box diagonal of a bone (or joint)
#: counts as lying on it (skeleton samples inserted by a mesher carry only rounding
#: error); the same tolerance as :mod:`stbs.weights.boundary` uses for bone weights.
ON_BONE_TOL = 1e-6
#: KKT tolerance of the BBW solves unless one is given (BBWSolver.solve's default).
BBW_TOL = 1e-10


def _bone_params(V: np.ndarray, sk: Skeleton) -> np.ndarray:
    """(n, b) unclamped parameter of p's projection onto each bone's line."""
    A = sk.A
    D = sk.B - A
    return (V @ D.T - np.sum(A * D, axis=1)) / (sk.lengths**2)


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
    V = _checks.skeleton(sk, V)
    return np.clip(_bone_params(V, sk), 0.0, 1.0)


def joints_to_endpoint(J, sk: Skeleton) -> np.ndarray:
    """Eq. 7: ``e_i = ((1 - j_a) + j_b) / 2`` from joint weights J (n, j) in [0, 1]."""
    _checks.skeleton(sk)
    J = np.asarray(J, dtype=float)
    if J.ndim != 2 or J.shape[1] != sk.n_joints:
        raise ValueError(f"J must have shape (n, {sk.n_joints}), got {J.shape}")
    return 0.5 * ((1.0 - J[:, sk.BE[:, 0]]) + J[:, sk.BE[:, 1]])


def _check_alpha(alpha) -> float:
    if not (isinstance(alpha, (int, float, np.floating, np.integer))
            and not isinstance(alpha, bool) and np.isfinite(alpha) and alpha >= 2):
        raise ValueError(f"alpha must be a finite number >= 2 (eq. 9 weights are smooth at "
                         f"the joints only for alpha >= 2), got {alpha!r}")
    return float(alpha)


def _joint_distances(V: np.ndarray, C: np.ndarray) -> np.ndarray:
    return np.sqrt(np.maximum(
        np.sum(V**2, axis=1)[:, None] - 2.0 * V @ C.T + np.sum(C**2, axis=1)[None, :], 0.0))


def idw_joint_weights(V, sk: Skeleton, *, alpha: float = 2.0) -> np.ndarray:
    """Eq. 9 joint weights normalised over all joints (Shepard): ``d_k^-a / sum_l d_l^-a``.

    Parameters
    ----------
    V : (n, d) float
    sk : Skeleton
    alpha : float
        Exponent, >= 2.

    Returns
    -------
    J : (n, j) float64
        In [0, 1], rows sum to 1, ``J[:, k] = 1`` at joint k.
    """
    V = _checks.skeleton(sk, V)
    alpha = _check_alpha(alpha)
    Dj = _joint_distances(V, sk.C)
    dmin = Dj.min(axis=1, keepdims=True)
    # (d_min / d_k)^alpha in [0, 1] is the same ratio without overflow near a joint.
    at_joint = dmin[:, 0] == 0
    R = np.divide(dmin, Dj, out=np.zeros_like(Dj), where=Dj > 0) ** alpha
    R[at_joint] = (Dj[at_joint] == 0).astype(float)
    return R / R.sum(axis=1, keepdims=True)


def idw(V, sk: Skeleton, *, alpha: float = 2.0,
        normalize: IdwNormalization = "bone") -> np.ndarray:
    """Inverse-distance endpoint weights (eq. 9, then eq. 7).

    Parameters
    ----------
    V : (n, d) float
    sk : Skeleton
    alpha : float
        Exponent of eq. 9, >= 2 (smooth at the joints).
    normalize : {"bone", "all"}
        ``"bone"`` (default): joint weights normalised over the bone's own two
        joints, so ``j_a + j_b = 1`` and eq. 7 reduces to
        ``e_i = d_a^alpha / (d_a^alpha + d_b^alpha)``; no other joint pulls e_i.
        ``"all"``: normalised over all joints (:func:`idw_joint_weights`); near a
        neighbouring joint both ``j_a`` and ``j_b`` vanish and e_i falls back to 0.5,
        even where the bone still has weight. Either way e_i regresses to 0.5 far
        away (the fall-off the paper notes).

    Returns
    -------
    E : (n, b) float64
        In [0, 1]; exactly 0 at ``a_i`` and 1 at ``b_i``; smooth, but shape-unaware.
    """
    V = _checks.skeleton(sk, V)
    alpha = _check_alpha(alpha)
    _checks.choice("normalize", normalize, IDW_NORMALIZATIONS)
    if normalize == "all":
        return joints_to_endpoint(idw_joint_weights(V, sk, alpha=alpha), sk)
    Dj = _joint_distances(V, sk.C)
    da, db = Dj[:, sk.BE[:, 0]], Dj[:, sk.BE[:, 1]]
    r = da / (da + db)            # a != b, so the sum is positive
    ra = r**alpha
    return ra / (ra + (1.0 - r) ** alpha)


# -- restriction (paper §3) -------------------------------------------------------------
def _threshold(threshold) -> float | None:
    if threshold is None:
        return None
    if not (isinstance(threshold, (int, float, np.floating, np.integer))
            and not isinstance(threshold, bool) and 0 <= threshold < 1):
        raise ValueError(f"threshold must be a number in [0, 1) or None, got {threshold!r}")
    return float(threshold)


def _support_elements(Ele: np.ndarray, Wi: np.ndarray, threshold: float,
                      extra: np.ndarray | None = None) -> np.ndarray:
    """Elements with a vertex where ``w_i > threshold``, plus those touching ``extra``."""
    mask = (Wi[Ele] > threshold).any(axis=1)
    if extra is not None and extra.size:
        touch = np.zeros(Wi.shape[0], dtype=bool)
        touch[extra] = True
        mask |= touch[Ele].any(axis=1)
    return mask


def _column(W, i: int) -> np.ndarray:
    if sp.issparse(W):
        return np.asarray(W[:, [i]].toarray()).ravel()
    return W[:, i]


def _bone_weights(W, n: int, b: int):
    if W is None:
        return None
    return _checks.bone_weights(W, n, b)


# -- heat --------------------------------------------------------------------------------
def heat_endpoint(V, F, sk: Skeleton, *, W=None, threshold: float | None = DEFAULT_THRESHOLD,
                  backend: _raycast.RayBackend = "auto", bones=None,
                  progress=None) -> np.ndarray:
    """Bone-heat endpoint weights: joints as bones shrunk to points, then eq. 7.

    Parameters
    ----------
    V : (n, 3) or (n, 2) float
    F : (f, 3) int
        The surface (3D) or the shape's triangles (2D).
    sk : Skeleton
    W : (n, b) float, optional
        Bone weights. With ``threshold``, bone i is solved only on the triangles
        touching ``W[:, i] > threshold``; elsewhere e_i is the projection (eq. 8),
        which is never read there (``w_i`` is ~0). Without ``W``: one solve for
        all joints on the whole shape.
    threshold : float or None
        The restriction threshold (paper §3: 1e-7); None disables it.
    backend : {"auto", "embree", "numpy"}
        Visibility ray casting (3D).
    bones : sequence of int, optional
        Solve only these bones; the others keep the projection (eq. 8). None: all.
    progress : callable, optional
        ``progress(done, total)``: ``done`` of the ``total`` bones solved, after each
        one (without the restriction: one solve for all joints, reported as
        :func:`stbs.weights.bone_heat` does). Raise any exception from it to cancel:
        it propagates, and ``progress`` is not called again.

    Returns
    -------
    E : (n, b) float64
        In [0, 1]. Vertices in no triangle get the projection.

    Raises
    ------
    ValueError
        When a joint is nearest-visible from no vertex of the region solved (its
        heat weight would be 0 everywhere); the message names the joint and bone.
    """
    from .heat import BoneHeatSolver

    V = _checks.skeleton(sk, V)
    threshold = _threshold(threshold)
    n, b = V.shape[0], sk.n_bones
    W = _bone_weights(W, n, b)
    todo = _checks.bone_list(bones, b)
    guard = Guard(progress)
    solver = BoneHeatSolver(V, F, backend=backend)
    F = solver.F
    labels = [f"joint {k}" for k in range(sk.n_joints)]
    E = projection(V, sk)
    stand_in = _joints_inside(V, F, sk)
    if W is None or threshold is None:
        C = sk.C.copy()
        for (k, _), x in stand_in.items():
            if np.array_equal(C[k], sk.C[k]):  # the first bone's stand-in for a joint
                C[k] = x
        J, _ = solver.solve(C, labels=labels, progress=guard)
        used = np.unique(F)
        E[used[:, None], todo] = joints_to_endpoint(J[used], sk)[:, todo]
        return E
    for done, i in enumerate(todo, 1):
        faces = _support_elements(F, _column(W, i), threshold)
        if not faces.any():
            guard(done, len(todo))
            continue
        a, e = sk.BE[i]
        C = sk.C.copy()
        for k in (a, e):
            C[k] = stand_in.get((int(k), i), C[k])
        X, _ = solver.solve(C, faces=faces, columns=[a, e], labels=labels,
                            context=f"bone {i} ({sk.names[i]!r}), restricted to "
                                    f"w > {threshold:g}: ")
        used = np.unique(F[faces])
        E[used, i] = 0.5 * ((1.0 - X[used, 0]) + X[used, 1])
        guard(done, len(todo))
    return np.clip(E, 0.0, 1.0)


def _joints_inside(V: np.ndarray, F: np.ndarray, sk: Skeleton) -> dict:
    """Stand-ins for joints outside the shape, as heat handles: {(joint, bone): point}.

    A joint outside the surface (3D, by winding number) or the triangles' outline (2D)
    sees no vertex from inside, so its heat weight would be 0 everywhere. For each
    bone at such a joint, its stand-in is the bone's point nearest the joint that lies
    inside (a 1/128 of the bone further in), warned with the distance; a bone wholly
    outside gets none (and the solve then reports the joint).
    """
    from ..geometry import boundary_loops, points_in_loops, winding_numbers

    if V.shape[1] == 3:
        def inside(P):
            return np.abs(winding_numbers(np.ascontiguousarray(P), V, F)) >= 0.5
    else:
        loops = [V[L] for L in boundary_loops(F)]

        def inside(P):
            return points_in_loops(P, loops)

    out, said = {}, []
    for k in np.flatnonzero(~inside(sk.C)).tolist():
        for i in np.flatnonzero((sk.BE == k).any(axis=1)).tolist():
            other = sk.BE[i, 1] if sk.BE[i, 0] == k else sk.BE[i, 0]
            s = np.arange(1, 257) / 256.0           # from the joint towards the other
            P = sk.C[k] + s[:, None] * (sk.C[other] - sk.C[k])
            ins = inside(P)
            if ins.any():
                j = min(int(np.argmax(ins)) + 2, s.size - 1)
                out[(k, i)] = P[j]
                said.append(f"joint {k} (bone {i}): {100 * s[j]:.2g} % of the bone inwards")
    if said:
        warnings.warn(f"heat endpoint weights: {len({k for k, _ in out})} joint(s) lie outside "
                      "the shape, where they see no vertex; each heat handle is its bone's "
                      "nearest point inside instead: " + "; ".join(said), UserWarning,
                      stacklevel=4)
    return out


# -- BBW ---------------------------------------------------------------------------------
def _bbw_solver_class():
    try:
        from .bbw import BBWSolver
    except ImportError as exc:  # pragma: no cover - bbw ships with the package
        raise ImportError(f"BBW endpoint weights need stbs.weights.bbw: {exc}") from None
    return BBWSolver


def _elements(V: np.ndarray, F, T) -> np.ndarray:
    d = V.shape[1]
    if T is not None:
        Ele = _checks.index_array("T", T, ndim=2)
        want = 4 if d == 3 else 3
        if Ele.shape[1] != want:
            raise ValueError(f"T must have shape (t, {want}) for {d}D vertices, got {Ele.shape}")
        name = "T"
    elif d == 2 and F is not None:
        Ele = _checks.index_array("F", F, ndim=2, shape=(None, 3))
        name = "F"
    else:
        raise ValueError("BBW endpoint weights need a volume mesh: tetrahedra T (t, 4) in 3D, "
                         "or triangles F (f, 3) (or T) in 2D; got "
                         + ("F only (a surface) in 3D" if F is not None else "neither F nor T"))
    if Ele.shape[0] == 0:
        raise ValueError(f"{name} must hold at least one element, got shape {Ele.shape}")
    if Ele.min() < 0 or Ele.max() >= V.shape[0]:
        bad = int(Ele.min()) if Ele.min() < 0 else int(Ele.max())
        raise ValueError(f"{name} must hold vertex indices in 0..{V.shape[0] - 1}, got {bad}")
    return Ele


def _joint_vertices(V: np.ndarray, used: np.ndarray, sk: Skeleton, tol: float,
                    joints) -> tuple[dict[int, int], dict[int, str]]:
    """Mesh vertex (among ``used``) of each joint: the one on it, else the nearest.

    Also returns, for the joints with no vertex on them, what to say when the nearest
    is used (:func:`_warn_nearest`).
    """
    out, far = {}, {}
    joints = sorted(set(int(k) for k in joints))
    Dj = _joint_distances(V[used], sk.C[joints])
    for col, k in enumerate(joints):
        j = int(np.argmin(Dj[:, col]))
        v = int(used[j])
        out[k] = v
        if Dj[j, col] > tol:
            far[k] = f"joint {k} -> vertex {v} at distance {Dj[j, col]:.3g}"
    return out, far


def _in_elements(V: np.ndarray, Ele: np.ndarray, x: np.ndarray) -> bool:
    """Whether point ``x`` lies in one of the simplices ``V[Ele]`` (to rounding)."""
    P = V[Ele]
    D = np.swapaxes(P[:, 1:] - P[:, :1], 1, 2)          # (e, d, d) edge vectors as columns
    ok = np.abs(np.linalg.det(D)) > 0
    lam = np.linalg.solve(D[ok], (x - P[ok, 0])[..., None])[..., 0]
    return bool(np.any((lam.min(axis=1) >= -1e-12) & (lam.sum(axis=1) <= 1 + 1e-12)))


def _warn_nearest(far: dict[int, str]) -> None:
    if far:
        warnings.warn("BBW endpoint weights: no mesh vertex lies on "
                      f"{len(far)} joint(s); using the nearest vertices: "
                      + "; ".join(far[k] for k in sorted(far)), UserWarning, stacklevel=4)


def _on_bone(V: np.ndarray, used: np.ndarray, sk: Skeleton, i: int,
             tol: float) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (among ``used``) within ``tol`` of bone i's segment, and their t in [0, 1]."""
    a, d = sk.A[i], sk.B[i] - sk.A[i]
    t = np.clip(((V[used] - a) @ d) / sk.lengths[i] ** 2, 0.0, 1.0)
    dist = np.linalg.norm(V[used] - (a + t[:, None] * d), axis=1)
    on = dist <= tol
    return used[on], t[on]


def bone_points(V, sk: Skeleton, Ele) -> np.ndarray:
    """(b,) int: how many vertices of the elements ``Ele`` lie on each bone (joints
    included), within ``ON_BONE_TOL`` of the bounding-box diagonal. BBW endpoint
    weights spread e from 0 to 1 along a bone only with at least two."""
    V = _checks.skeleton(sk, V)
    used = np.unique(np.asarray(Ele))
    tol = ON_BONE_TOL * max(float(np.linalg.norm(np.ptp(V, axis=0))), 1e-300)
    return np.array([_on_bone(V, used, sk, i, tol)[0].size for i in range(sk.n_bones)],
                    dtype=np.int64)


def _solve_region(BBWSolver, V: np.ndarray, Ele: np.ndarray, mask: np.ndarray | None,
                  bidx: np.ndarray, bc: np.ndarray, cache: dict, tol: float = BBW_TOL,
                  threads: int | None = None, progress=None):
    """BBW on the elements ``Ele[mask]`` (all when None) with constraints ``bidx``/``bc``.

    Components of the region holding no constrained vertex are dropped (their
    QP would be unconstrained). Returns the solved vertices and their values.
    ``threads`` is passed to the solver when given (then the caller limits the BLAS
    threads); ``progress`` to its solve. Several threads may call this at once: the
    whole-mesh solver in ``cache`` is built and used under ``cache["lock"]``.
    """
    sub = Ele if mask is None else Ele[mask]
    verts = np.unique(sub)
    n = V.shape[0]
    s = sub.shape[1]
    adj = sp.coo_matrix((np.ones(s * len(sub)),
                         (sub.ravel(), np.roll(sub, 1, axis=1).ravel())), shape=(n, n))
    _, comp = connected_components(adj, directed=False)
    keep_comp = np.unique(comp[bidx])
    keep_v = np.zeros(n, dtype=bool)
    keep_v[verts] = np.isin(comp[verts], keep_comp)
    if not keep_v[verts].all():
        sub = sub[keep_v[sub[:, 0]]]
        verts = np.unique(sub)
    # With threads given, the caller holds the BLAS thread limit for all workers:
    # threadpoolctl's limits are process-wide, so per-thread ones would undo each other.
    kw = {} if threads is None else {"threads": threads, "blas_threads": None}
    solve_kw = {} if progress is None else {"progress": progress}
    if mask is None and verts.size == n:
        # the whole mesh: one solver (L, M, Q and the factor of a repeated b) for all
        with cache.setdefault("lock", threading.Lock()):
            if "full" not in cache:
                cache["full"] = BBWSolver(V, sub, **kw)
            X = cache["full"].solve(bidx, bc, tol=tol, **solve_kw)
        return verts, np.clip(np.asarray(X, dtype=float).reshape(n, -1), 0.0, 1.0)
    local = np.full(n, -1, dtype=np.int64)
    local[verts] = np.arange(verts.size)
    solver = BBWSolver(V[verts], local[sub], **kw)
    X = np.asarray(solver.solve(local[bidx], bc, tol=tol, **solve_kw),
                   dtype=float).reshape(verts.size, -1)
    return verts, np.clip(X, 0.0, 1.0)


def _bone_workers(BBWSolver, b: int) -> int:
    """Threads for b per-bone solves: as our solver's own (CHOLMOD through ctypes only),
    and never for a stand-in solver class."""
    from . import _cholmod
    from .bbw import BBWSolver as Ours
    from .bbw import parallel_workers

    if BBWSolver is not Ours:
        return 1
    return parallel_workers(_cholmod.default_threads(), b)


class _Mesh:
    """What the per-bone constraints of :func:`bbw_endpoint` need of the mesh."""

    def __init__(self, V: np.ndarray, Ele: np.ndarray, sk: Skeleton):
        self.V, self.Ele, self.sk = V, Ele, sk
        self.on_tol = ON_BONE_TOL * max(float(np.linalg.norm(np.ptp(V, axis=0))), 1e-300)
        self.used = np.unique(Ele)     # vertices in no element cannot carry a constraint
        self._outside: dict[int, bool] = {}

    def outside(self, k: int) -> bool:
        """Whether joint k lies outside the mesh (computed once, when asked)."""
        if k not in self._outside:
            self._outside[k] = not _in_elements(self.V, self.Ele, self.sk.C[k])
        return self._outside[k]


def _direct_constraints(mesh: _Mesh, i: int, jv: dict, far: dict, nearest: dict):
    """Bone i's constraints for e_i itself: ``t`` on the bone, 0 and 1 at its joints."""
    sk = mesh.sk
    a, e = (int(k) for k in sk.BE[i])
    on, t = _on_bone(mesh.V, mesh.used, sk, i, mesh.on_tol)
    val = dict(zip(on.tolist(), t.tolist(), strict=True))
    own = on.size >= 2 and float(np.ptp(t)) > 0.0
    held = []
    for k, value in ((a, 0.0), (e, 1.0)):
        # A joint with no vertex on it: its nearest vertex stands in, unless the joint
        # lies outside the mesh and the bone has vertices of its own (a mesh built with
        # the skeleton clipped to the shape: e = t suffices).
        if k in far and own and mesh.outside(k):
            continue
        val[jv[k]] = value
        held.append(k)
        if k in far:
            nearest[k] = far[k]
    if len(held) == 2 and jv[a] == jv[e]:
        _warn_nearest(nearest)
        raise ValueError(f"joints {a} and {e} map to the same mesh vertex {jv[a]}; "
                         f"BBW endpoint weights of bone {i} ({sk.names[i]!r}) need a "
                         "vertex per joint (refine the mesh)")
    return np.fromiter(val.keys(), dtype=np.int64), np.fromiter(val.values(), dtype=float)[:, None]


def _restricted(mesh: _Mesh, Wi, threshold: float, bidx, vals, own, joints: bool):
    """The region of a bone's solve (elements touching ``w_i > threshold`` or its own
    constrained vertices ``own``); joint weights keep only the constraints inside it."""
    mask = _support_elements(mesh.Ele, Wi, threshold, extra=own)
    if joints:
        inside = np.zeros(mesh.V.shape[0], dtype=bool)
        inside[np.unique(mesh.Ele[mask])] = True
        keep = inside[bidx]
        bidx, vals = bidx[keep], vals[keep]
    return mask, bidx, vals


def bbw_endpoint(V, sk: Skeleton, *, T=None, F=None, W=None,
                 threshold: float | None = DEFAULT_THRESHOLD, joints: bool = False,
                 tol: float = BBW_TOL, progress=None, bones=None) -> np.ndarray:
    """Bounded biharmonic endpoint weights, solved directly or as joint weights.

    Parameters
    ----------
    V : (n, d) float
    sk : Skeleton
    T : (t, 4) int, or (f, 3) in 2D
        The volume mesh BBW is solved on; in 2D the triangles ``F`` serve too.
    F : (f, 3) int, optional
        2D triangles, used when ``T`` is None.
    W : (n, b) float, optional
        Bone weights; with ``threshold`` each bone is solved only on the elements
        touching ``W[:, i] > threshold`` and its own constrained vertices. Vertices
        outside that region (and in region components holding no constraint) get the
        projection (eq. 8); ``w_i`` is ~0 there, so STBS never reads them.
    threshold : float or None
        Paper §3 restriction (1e-7); None disables it.
    joints : bool
        False (method ``"bbw"``): one BBW function per bone with ``e = 0`` at
        ``a_i``, ``1`` at ``b_i`` and ``t`` at every vertex on the bone (linear along
        it). True (``"bbw-joints"``): joint weights, 1 at the joint and 0 at the other
        joints, combined by eq. 7.
    tol : float
        KKT tolerance of each BBW solve (:meth:`stbs.weights.BBWSolver.solve`).
    progress : callable, optional
        ``progress(done, total)``: ``done`` of the ``total`` bones solved, after each
        bone (the one solve of all joints, unrestricted ``"bbw-joints"``: at every
        solver round). Raise any exception from it to cancel: the solves stop at their
        next round, the exception propagates, and ``progress`` is not called again.
    bones : sequence of int, optional
        Solve only these bones; the others keep the projection (eq. 8). None: all.

    Returns
    -------
    E : (n, b) float64 in [0, 1]

    Notes
    -----
    Joints without a mesh vertex on them use their nearest vertex, with a warning
    giving the distance (``ON_BONE_TOL`` of the bounding-box diagonal counts as on);
    a bone whose two joints would both be held at one vertex is an error naming them.
    """
    V = _checks.skeleton(sk, V)
    threshold = _threshold(threshold)
    Ele = _elements(V, F, T)
    n, b = V.shape[0], sk.n_bones
    W = _bone_weights(W, n, b)
    guard = Guard(progress)
    BBWSolver = _bbw_solver_class()
    mesh = _Mesh(V, Ele, sk)
    E = projection(V, sk)
    restrict = W is not None and threshold is not None
    todo = _checks.bone_list(bones, b)
    jv, far = _joint_vertices(V, mesh.used, sk, mesh.on_tol,
                              range(sk.n_joints) if joints
                              else np.unique(sk.BE[todo]) if todo else [])
    if joints:
        try:
            cand, ks = _unique_joint_vertices(jv)
        finally:
            _warn_nearest(far)
        if not restrict and len(todo) == b:
            return _all_joints(BBWSolver, mesh, E, cand, ks, tol, guard)
    nearest: dict[int, str] = {}
    tasks = []
    for i in todo:
        a, e = (int(k) for k in sk.BE[i])
        if joints:
            bidx, vals = cand, np.zeros((len(cand), 2))
            vals[ks == a, 0] = 1.0
            vals[ks == e, 1] = 1.0
        else:
            bidx, vals = _direct_constraints(mesh, i, jv, far, nearest)
        mask = None
        if restrict:
            own = np.array([jv[a], jv[e]]) if joints else bidx
            mask, bidx, vals = _restricted(mesh, _column(W, i), threshold, bidx, vals, own,
                                           joints)
        tasks.append((i, mask, bidx, vals))
    _warn_nearest(nearest)
    return _solve_bones(BBWSolver, mesh, E, tasks, joints, tol, guard)


def _all_joints(BBWSolver, mesh: _Mesh, E, cand, ks, tol, guard: Guard) -> np.ndarray:
    """Unrestricted joint weights of all joints: one solve on the whole mesh, eq. 7."""
    sk, b = mesh.sk, mesh.sk.n_bones
    bc = np.zeros((len(cand), sk.n_joints))
    bc[np.arange(len(cand)), ks] = 1.0
    verts, X = _solve_region(BBWSolver, mesh.V, mesh.Ele, None, cand, bc, {}, tol,
                             progress=lambda done, total: guard(done * b // total, b))
    J = np.zeros((mesh.V.shape[0], sk.n_joints))
    J[verts] = X
    E[verts] = joints_to_endpoint(J[verts], sk)
    return E


def _solve_bones(BBWSolver, mesh: _Mesh, E, tasks, joints: bool, tol, guard: Guard):
    """The per-bone solves of :func:`bbw_endpoint`, on threads when they pay."""
    cache: dict = {}
    done = [0]

    def solve(task, threads=None):
        i, mask, bidx, vals = task
        return (i, *_solve_region(BBWSolver, mesh.V, mesh.Ele, mask, bidx, vals, cache, tol,
                                  threads, progress=guard.check))

    def store(result):
        i, verts, X = result
        E[verts, i] = X[:, 0] if not joints else 0.5 * ((1.0 - X[:, 0]) + X[:, 1])
        done[0] += 1
        guard(done[0], len(tasks))

    workers = _bone_workers(BBWSolver, len(tasks))
    if workers > 1:
        # Bones on separate threads, one solver thread each: the per-bone regions are
        # independent, and whole factorizations overlap better than split solves.
        from .bbw import _blas_threads

        with _blas_threads(1), \
                ThreadPoolExecutor(workers, thread_name_prefix="stbs-endpoint") as ex:
            guard.join([ex.submit(solve, task, 1) for task in tasks], on_result=store)
    else:
        for task in tasks:
            store(solve(task))
    return np.clip(E, 0.0, 1.0)


def _unique_joint_vertices(jv: dict[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Constrained vertices and their joints; two joints on one vertex is an error."""
    seen: dict[int, int] = {}
    for k, v in jv.items():
        if v in seen:
            raise ValueError(f"joints {seen[v]} and {k} map to the same mesh vertex {v}; "
                             "BBW joint weights need a vertex per joint (refine the mesh)")
        seen[v] = k
    bidx = np.fromiter(jv.values(), dtype=np.int64)
    ks = np.fromiter(jv.keys(), dtype=np.int64)
    return bidx, ks


# -- entry point -------------------------------------------------------------------------
def endpoint_weights(V, sk: Skeleton, *, method: EndpointMethod = "projection",
                     W=None, F=None, T=None, threshold: float | None = DEFAULT_THRESHOLD,
                     alpha: float | None = None, normalize: IdwNormalization | None = None,
                     backend: _raycast.RayBackend | None = None,
                     tol: float | None = None, bones=None, progress=None) -> np.ndarray:
    """Endpoint weights E (n, b) by one of the paper's methods.

    Parameters
    ----------
    V : (n, d) float
    sk : Skeleton
    method : {"projection", "idw", "heat", "bbw", "bbw-joints"}
        ``"projection"``: eq. 8. ``"idw"``: eq. 9 joint weights -> eq. 7 (see
        :func:`idw`). ``"heat"``: bone heat with joints as points -> eq. 7, on the
        surface ``F`` (3D) or the triangles ``F`` (2D) (see :func:`heat_endpoint`).
        ``"bbw"``: BBW for e_i directly, 0 at ``a_i``, 1 at ``b_i``, linear along the
        bone; ``"bbw-joints"``: BBW joint weights -> eq. 7; both on ``T`` (3D) or
        ``F``/``T`` (2D) (see :func:`bbw_endpoint`).
    W : (n, b) float, optional
        Bone weights: the solved methods are restricted to ``W[:, i] > threshold``.
    F : (f, 3) int, optional
        Triangles: the surface for ``"heat"`` in 3D, the shape in 2D.
    T : (t, 4) int, optional
        Tetrahedra for ``"bbw"``/``"bbw-joints"`` in 3D.
    threshold : float or None
        Restriction threshold (paper §3: 1e-7); None solves on the whole mesh.
    alpha : float, optional
        ``"idw"`` only: exponent >= 2 (default 2).
    normalize : {"bone", "all"}, optional
        ``"idw"`` only: normalise joint weights over the bone's two joints (default)
        or over all joints.
    backend : {"auto", "embree", "numpy"}, optional
        ``"heat"`` only: visibility ray casting (default ``"auto"``).
    tol : float, optional
        ``"bbw"``/``"bbw-joints"`` only: KKT tolerance of the BBW solves (default
        1e-10, as :meth:`stbs.weights.BBWSolver.solve`).
    bones : sequence of int, optional
        Only these bones' columns are computed; the others hold the projection (eq. 8).
        None: all.
    progress : callable, optional
        ``progress(done, total)``: the solved methods (heat, bbw, bbw-joints) after
        each bone, and within long solves (see :func:`bbw_endpoint`,
        :func:`heat_endpoint`); the closed forms once, at the end. Raise any exception
        from it to cancel: it propagates, and ``progress`` is not called again.

    Returns
    -------
    E : (n, b) float64
        In [0, 1].

    Raises
    ------
    TypeError
        When ``sk`` is not a :class:`stbs.Skeleton`.
    ValueError
        For an unknown method, an option given to a method that does not use it, or
        a missing mesh (the message says which one the method needs).

    Examples
    --------
    One bone along the middle line of a 4 x 2 grid of squares: BBW endpoint weights
    run from 0 at the bone's start to 1 at its end, linearly along the bone.

    >>> import numpy as np
    >>> import stbs
    >>> x, y = np.meshgrid(np.arange(5.0), np.arange(3.0), indexing="ij")
    >>> V = np.c_[x.ravel(), y.ravel()]           # vertex 3 i + j at (i, j)
    >>> q = np.array([3 * i + j for i in range(4) for j in range(2)])
    >>> F = np.r_[np.c_[q, q + 3, q + 4], np.c_[q, q + 4, q + 1]]
    >>> sk = stbs.Skeleton([[0.0, 1.0], [4.0, 1.0]], [[0, 1]])
    >>> E = endpoint_weights(V, sk, method="bbw", F=F)
    >>> E[[1, 4, 7, 10, 13], 0].round(6)          # the vertices on the bone
    array([0.  , 0.25, 0.5 , 0.75, 1.  ])
    >>> endpoint_weights(V, sk)[[0, 7, 14], 0]    # eq. 8, the projection onto the bone
    array([0. , 0.5, 1. ])
    """
    _checks.choice("method", method, ENDPOINT_METHODS)
    V = _checks.skeleton(sk, V)
    for name, value, owners in (("alpha", alpha, ("idw",)), ("normalize", normalize, ("idw",)),
                                ("backend", backend, ("heat",)),
                                ("tol", tol, ("bbw", "bbw-joints"))):
        if value is not None and method not in owners:
            which = " or ".join(f"method={o!r}" for o in owners)
            raise ValueError(f"{name} applies to {which} only, got {name}={value!r} "
                             f"with method={method!r}")
    threshold = _threshold(threshold)
    if method in ("projection", "idw"):
        todo = _checks.bone_list(bones, sk.n_bones)
        guard = Guard(progress)
        E = projection(V, sk)
        if method == "idw":
            E[:, todo] = idw(V, sk, alpha=2.0 if alpha is None else alpha,
                             normalize="bone" if normalize is None else normalize)[:, todo]
        guard(len(todo), len(todo))
        return E
    if method == "heat":
        if F is None:
            raise ValueError("method='heat' needs triangles F: the surface in 3D "
                             "(visibility and diffusion live on it), the shape in 2D")
        return heat_endpoint(V, F, sk, W=W, threshold=threshold,
                             backend="auto" if backend is None else backend, bones=bones,
                             progress=progress)
    return bbw_endpoint(V, sk, T=T, F=F, W=W, threshold=threshold,
                        joints=method == "bbw-joints",
                        tol=BBW_TOL if tol is None else float(tol), progress=progress,
                        bones=bones)
