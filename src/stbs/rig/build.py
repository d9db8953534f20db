"""The rig pipeline: a bare mesh and skeleton in, a complete STBS rig out (paper §2.3, §3).

1. Meshing with the skeleton inside (bounded biharmonic weights need the bones in the
   mesh): a 2D triangle mesh's outline is re-triangulated with the bones as constrained
   segments; a 3D surface of any kind gets a volume mesh of its inside by winding number
   (:func:`stbs.meshing.volume_mesh`, the default) or, closed and clean, a tetrahedral
   mesh through its own vertices (:func:`stbs.tetrahedralize`); a tetrahedral mesh is
   used as it is. Bone heat works on the surface itself (a tetrahedral mesh's boundary).
2. Bone weights ``W``: bounded biharmonic weights or bone heat.
3. Endpoint weights ``E``: projection (eq. 8), inverse distance (eq. 9), heat, or
   bounded biharmonic (direct, or as joint weights), each solved only where the bone's
   weight exceeds 1e-7.
4. Back to the user's vertices: weights of the vertices meshing inserted are dropped,
   or (the winding-number volume) the volume's weights are interpolated at them, so the
   rig keeps the given ``V`` and ``F`` in their order.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np

from .. import _checks
from ..geometry import boundary_faces
from ..methods import BONE_METHODS, ENDPOINT_METHODS
from ..skeleton import Skeleton
from .model import Rig, Volume, _weights

__all__ = ["build_rig", "BONE_METHODS", "ENDPOINT_METHODS", "VOLUME_METHODS", "DEFAULT_TOL",
           "Progress"]

#: Volume meshes of a 3D surface for BBW (:func:`build_rig`'s ``volume``).
VOLUME_METHODS = ("auto", "winding", "conforming")
#: ``volume="auto"`` tries the conforming mesh on closed, clean surfaces of at most this
#: many vertices: its cost grows with them (TetGen's mesh has about 1.2 times the
#: surface's vertices: elephant.obj's 6,034 give 7,291), the winding volume's does not
#: (about 12,000 vertices); up to here the conforming mesh is no dearer.
AUTO_CONFORMING_MAX = 10_000
#: KKT tolerance of the rig's BBW solves: weights within about 1e-5 of the exact QP
#: solution (2e-7 to 3e-6 measured on 5k-50k vertex meshes), up to 1.5x faster than 1e-10.
DEFAULT_TOL = 1e-6

#: ``progress(stage, done, total)``: a stage starts with ``(stage, 0, 0)``; long stages
#: then report ``done`` of ``total`` units (weight functions, bones, meshing steps), at
#: least once per solver round or bone. An exception raised from it cancels the work.
Progress = Callable[[str, int, int], None]


def _choice(name: str, value, choices) -> str:
    if value not in choices:
        raise ValueError(f"{name} must be one of {', '.join(choices)}, got {value!r}")
    return value


def _weld(V, F, W):
    """Merge vertices at exactly the same place: (Vw, Fw, weld, Ww) with ``weld`` (n,)
    each vertex's welded index (in order of first occurrence), faces that collapse
    dropped, and each welded vertex's weights the mean of its copies'."""
    import scipy.sparse as sp

    _, first, inv = np.unique(V, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first)
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    weld = rank[np.ravel(inv)]
    Vw = V[first[order]]
    Fw = weld[F]
    Fw = Fw[(Fw[:, 0] != Fw[:, 1]) & (Fw[:, 1] != Fw[:, 2]) & (Fw[:, 0] != Fw[:, 2])]
    Wd = W.toarray() if sp.issparse(W) else np.asarray(W, dtype=float)
    Ww = np.zeros((len(Vw), Wd.shape[1]))
    np.add.at(Ww, weld, Wd)
    Ww /= np.bincount(weld, minlength=len(Vw))[:, None]
    return Vw, Fw, weld, Ww


def _extend(V, T, W, known):
    """W (n, b) given on the ``known`` vertices, extended to the others by the discrete
    Laplace equation on the tetrahedra ``T``, then clipped and rows normalised."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    from ..weights import cotmatrix

    Wd = W.toarray() if sp.issparse(W) else np.asarray(W, dtype=float)
    unknown = np.flatnonzero(~known)
    if unknown.size == 0:
        return Wd
    L = sp.csr_array(cotmatrix(V, T, degenerate="skip"))
    kn = np.flatnonzero(known)
    Lii = L[unknown][:, unknown].tocsc()
    rhs = -(L[unknown][:, kn] @ Wd[kn])
    X = spla.splu(Lii).solve(np.asarray(rhs))
    X = np.clip(X, 0.0, None)
    s = X.sum(axis=1, keepdims=True)
    X = np.where(s > 0, X / np.where(s > 0, s, 1), 1.0 / Wd.shape[1])
    out = Wd.copy()
    out[unknown] = X
    return out


def _harmonic_extension(V, T, W):
    """W (n, b) given on the first n of V's vertices, extended to the others (:func:`_extend`)."""
    known = np.zeros(len(V), dtype=bool)
    known[:W.shape[0]] = True
    Wd = np.zeros((len(V), W.shape[1]))
    Wd[:W.shape[0]] = W.toarray() if hasattr(W, "toarray") else W
    return _extend(V, T, Wd, known)


def _to_volume(vm, V, W, interp, k: int = 8):
    """Surface weights W (n, b) carried into the volume mesh ``vm`` (m, b): at each
    volume vertex the largest weight of its ``k`` nearest surface vertices, and at the
    vertices the surface interpolates from, at least the mean of what they carry. So
    wherever a surface vertex has ``w_i > 0``, so do the vertices it interpolates
    from (the endpoint solve's region covers it), and bone i's region reaches its
    bone through the inside. Rows normalised."""
    import scipy.sparse as sp
    from scipy.spatial import cKDTree

    Wd = W.toarray() if sp.issparse(W) else np.asarray(W, dtype=float)
    _, nn = cKDTree(V).query(vm.V, k=min(k, V.shape[0]))
    nn = nn.reshape(vm.V.shape[0], -1)
    Wv = Wd[nn[:, 0]].copy()
    for c in range(1, nn.shape[1]):
        np.maximum(Wv, Wd[nn[:, c]], out=Wv)
    mass = np.asarray(interp.sum(axis=0)).ravel()
    carried = np.asarray(interp.T @ Wd)
    layer = mass > 0
    Wv[layer] = np.maximum(Wv[layer], carried[layer] / mass[layer, None])
    s = Wv.sum(axis=1, keepdims=True)
    return np.where(s > 0, Wv / np.where(s > 0, s, 1.0), 1.0 / Wd.shape[1])


@dataclass
class _Job:
    """:func:`build_rig`'s checked arguments, what they call for, and the stage reporter."""

    V: np.ndarray
    sk: Skeleton
    F: np.ndarray | None
    T: np.ndarray | None
    W: object
    bone: str
    endpoint: str
    tol: float
    clip_skeleton: bool
    remesh: bool
    volume: str
    volume_size: float | None
    keep_volume: bool
    say: Callable[[str, int, int], None]

    @property
    def n(self) -> int:
        return int(self.V.shape[0])

    @property
    def d(self) -> int:
        return int(self.V.shape[1])

    @property
    def heat_on(self) -> bool:
        """Bone heat is computed (not given)."""
        return self.bone == "heat" and self.W is None

    @property
    def bbw_endpoint(self) -> bool:
        return self.endpoint in ("bbw", "bbw-joints")

    @property
    def needs_volume(self) -> bool:
        """A 3D surface's volume mesh is built: BBW needs it, or it is to be kept."""
        bbw_bone = self.bone == "bbw" and self.W is None
        return self.d == 3 and self.T is None and self.F is not None and (
            self.bbw_endpoint or bbw_bone or self.keep_volume)

    @property
    def remeshes_2d(self) -> bool:
        return self.d == 2 and self.W is None and self.bone == "bbw" and self.remesh

    def stage(self, label: str, bar: bool = False):
        """Report a stage's start; ``bar``: return its ``progress(done, total)``."""
        self.say(label, 0, 0)
        if bar:
            return lambda done, total: self.say(label, done, total)
        return None


def build_rig(V, sk: Skeleton, *, F=None, T=None, W=None,
              bone: Literal["bbw", "heat"] = "bbw",
              endpoint: Literal["bbw", "bbw-joints", "heat", "projection", "idw"] = "bbw",
              tol: float = DEFAULT_TOL, clip_skeleton: bool = False, remesh: bool = True,
              volume: Literal["auto", "winding", "conforming"] = "auto",
              volume_size: float | None = None, keep_volume: bool = False,
              progress: Progress | None = None) -> Rig:
    """A complete rig (bone and endpoint weights) of a mesh and skeleton.

    Parameters
    ----------
    V : (n, d) float
        Rest vertex positions, d = ``sk.dim`` (2 or 3).
    sk : Skeleton
        The skeleton. With a 3D surface's winding-number volume its parts outside the
        shape are left out with a ``UserWarning`` naming the bones; see
        ``clip_skeleton`` for the other meshes.
    F : (f, 3) int, optional
        Triangles: a 2D shape, or a 3D surface (any: open, in several parts,
        self-intersecting, non-manifold; closed for ``volume="conforming"``).
    T : (t, 4) int, optional
        Tetrahedra (3D), used as they are for bounded biharmonic weights; ``V`` then
        holds every vertex of the tetrahedral mesh. Bone heat then works on its
        boundary surface (``F`` if given, else the boundary of ``T``).
    W : (n, b) float, optional
        Bone weights to keep (painted, or read from a file); only ``E`` is computed.
    bone : {"bbw", "heat"}
        Bounded biharmonic weights (on a volume mesh with the skeleton inside), or
        bone heat (Baran & Popović 2007; a 3D triangle surface ``F``, or tetrahedra).
    endpoint : {"bbw", "bbw-joints", "heat", "projection", "idw"}
        Endpoint weights (paper §2.2-2.3). ``heat`` needs a 3D surface or tetrahedra.
    tol : float
        KKT tolerance of the bounded biharmonic solves, in weight units (1e-10 gives
        the exact QP solution, up to 1.5x slower).
    clip_skeleton : bool
        When stbs meshes a 2D shape, or a 3D surface with ``volume="conforming"``:
        mesh only the skeleton's parts inside it (for bone tips poking out of the
        skin); otherwise a joint outside is an error. The 3D ``"winding"`` volume
        always does so (the flag changes nothing there).
    remesh : bool
        2D: re-triangulate the outline of ``(V, F)`` with the bones inside (True), or
        solve on ``(V, F)`` as it is (False, for a mesh that already has the bones as
        vertices and edges, e.g. from :func:`stbs.triangulate_2d`).
    volume : {"auto", "winding", "conforming"}
        3D surface, BBW: the volume the weights are solved on. ``"winding"``:
        :func:`stbs.meshing.volume_mesh`, the inside by generalised winding number at
        a resolution of its own (``volume_size``), weights interpolated to the
        surface's vertices; any surface. ``"conforming"``: :func:`stbs.tetrahedralize`,
        tetrahedra through the surface's own vertices (a closed, clean surface with
        the skeleton inside, or ``clip_skeleton``; the cost grows with its vertex
        count). ``"auto"`` (default): conforming for a closed, clean surface of at
        most :data:`AUTO_CONFORMING_MAX` vertices that holds the skeleton, else
        winding (always winding when ``volume_size`` is given).
    volume_size : float, optional
        The winding-number volume's target edge length, in the mesh's units (None:
        about :data:`stbs.meshing.volume.DEFAULT_VERTICES` vertices).
    keep_volume : bool
        Keep the mesh the weights were solved on as ``rig.volume`` (a
        :class:`stbs.rig.Volume`, saved in the rig file), so that BBW endpoint weights
        can be solved again later (:func:`stbs.rig.rig_endpoint_weights`): a 3D
        surface's volume mesh (then built by ``volume`` even when the methods chosen
        need none) or a 2D shape's re-triangulation with the bones inside. None when
        the rig's own triangles (2D) or tetrahedra serve.
    progress : callable, optional
        ``progress(stage, done, total)``: each stage starts with ``(stage, 0, 0)``; the
        weight solves and meshing then report ``done`` of ``total`` units, at least once
        per solver round or bone. Raise any exception from it to cancel: the work stops
        at its next report and the exception propagates (``progress`` is not called
        again).

    Returns
    -------
    Rig
        ``V``, ``F`` and ``T`` as given (``T`` only when given), the skeleton ``sk``,
        ``W`` and ``E`` (n, b), ``meta = {"bone": ..., "endpoint": ...}`` and, with
        ``keep_volume``, ``volume``.

    Raises
    ------
    ValueError
        A method that does not fit the mesh (bone heat in 2D, a 3D rig without a
        surface or tetrahedra, ...), a skeleton outside the shape (2D, conforming 3D),
        or bad arrays; the message names the argument.

    Examples
    --------
    >>> import stbs
    >>> from stbs.shapes import cigar
    >>> V, F, sk, _ = cigar(12)
    >>> rig = stbs.build_rig(V, sk, F=F, bone="heat", endpoint="projection")
    >>> rig.W.shape == (len(V), sk.n_bones), bool(abs(rig.W.sum(axis=1) - 1).max() < 1e-9)
    (True, True)
    """
    job = _job(V, sk, F=F, T=T, W=W, bone=bone, endpoint=endpoint, tol=tol,
               clip_skeleton=clip_skeleton, remesh=remesh, volume=volume,
               volume_size=volume_size, keep_volume=keep_volume, progress=progress)
    W_surface = _surface_weights(job)
    if job.needs_volume:
        return _volume_rig(job, W_surface)
    kept = None
    if W_surface is not None:
        Vm, Fm, Tm, Wm = job.V, job.F, job.T, W_surface
    else:
        Vm, Fm, Tm, kept = _solve_mesh(job)
        Wm = _bbw_bone_weights(job, Vm, Fm, Tm)
    W_out = W_surface if W_surface is not None else Wm[:job.n]
    E = _endpoints(job, Vm, Fm, Tm, Wm, W_out, np.arange(job.n))
    return _rig(job, W_out, E, kept)


def _job(V, sk, *, F, T, W, bone, endpoint, tol, clip_skeleton, remesh, volume,
         volume_size, keep_volume, progress) -> _Job:
    """The arguments checked, before any work."""
    V = _checks.skeleton(sk, V)
    n, d = V.shape
    _choice("bone", bone, BONE_METHODS)
    _choice("endpoint", endpoint, ENDPOINT_METHODS)
    _choice("volume", volume, VOLUME_METHODS)
    tol = _positive("tol", tol)
    volume_size = None if volume_size is None else _positive("volume_size", volume_size)
    F = None if F is None else _checks.index_array("F", F, ndim=2, shape=(None, 3))
    T = None if T is None else _checks.index_array("T", T, ndim=2, shape=(None, 4))
    for name, X in (("F", F), ("T", T)):
        if X is not None and X.size and (X.min() < 0 or X.max() >= n):
            raise ValueError(f"{name} must hold vertex indices in 0..{n - 1}, got "
                             f"{int(X.min()) if X.min() < 0 else int(X.max())}")
    if T is not None and d != 3:
        raise ValueError(f"T (tetrahedra) needs 3D vertices, got V of shape {V.shape}")
    for what, method in (("bone", None if W is not None else bone), ("endpoint", endpoint)):
        if method == "heat" and (d != 3 or (F is None and T is None)):  # before any work
            raise ValueError(f"{what}='heat' needs a 3D triangle surface F"
                             + (f"; got a {d}D mesh" if d != 3 else " (or tetrahedra T)"))
    if W is not None:
        W = _weights("W", W, n, sk.n_bones)
    job = _Job(V=V, sk=sk, F=F, T=T, W=W, bone=bone, endpoint=endpoint, tol=tol,
               clip_skeleton=bool(clip_skeleton), remesh=bool(remesh), volume=volume,
               volume_size=volume_size, keep_volume=bool(keep_volume),
               say=progress or (lambda stage, done, total: None))
    if job.clip_skeleton and not (job.needs_volume or job.remeshes_2d):
        raise ValueError("clip_skeleton applies when stbs meshes the shape itself (bone='bbw' "
                         "without T: a 2D mesh, or a 3D surface)")
    if W is not None and job.bbw_endpoint and F is None and T is None:
        raise ValueError(f"endpoint={endpoint!r} needs the mesh's triangles F or tetrahedra T")
    return job


def _positive(name: str, value) -> float:
    value = float(value)
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be a positive number, got {value!r}")
    return value


def _surface_weights(job: _Job):
    """The bone weights known before any volume: given, or bone heat on the surface (a
    tetrahedral mesh's boundary, extended inside); None when BBW is to solve them."""
    from ..weights import bone_heat

    if job.W is not None:
        return job.W
    if not job.heat_on:
        return None
    V, F, T = job.V, job.F, job.T
    Fs = F if F is not None else boundary_faces(T)
    Ws = bone_heat(V, Fs, job.sk, progress=job.stage("bone heat", bar=True))
    if T is not None:
        known = np.zeros(job.n, dtype=bool)
        known[np.unique(Fs)] = True
        if not known.all():
            job.stage("extend the bone weights inside")
            Ws = _extend(V, T, Ws, known)
    return Ws


def _solve_mesh(job: _Job):
    """The mesh bone weights are solved on without a volume mesh (2D, or tetrahedra):
    ``(Vm, Fm, Tm, kept)``, the rig's vertices first; ``kept``: the 2D
    re-triangulation to keep as the rig's volume, or None."""
    from ..meshing import triangulate_2d

    V, F, T = job.V, job.F, job.T
    if job.d == 3:
        if T is None:
            raise ValueError("a 3D rig needs a closed triangle surface F or tetrahedra T")
        return V, F, T, None
    if F is None:
        raise ValueError("a 2D rig needs triangles F (the outline is taken from them)")
    if not job.remesh:
        return V, F, None, None
    job.stage("triangulate (bones inside)")
    tri = triangulate_2d((V, F), job.sk, clip_skeleton=job.clip_skeleton)
    kept = Volume.selection(tri.V, tri.F, np.arange(job.n)) if job.keep_volume else None
    return tri.V, tri.F, None, kept


def _bbw_bone_weights(job: _Job, Vm, Fm, Tm):
    from ..weights import bone_weights

    return bone_weights(Vm, job.sk, method="bbw", F=Fm if Tm is None else None, T=Tm,
                        tol=job.tol, progress=job.stage("bone weights (bbw)", bar=True))


def _volume_rig(job: _Job, W_surface) -> Rig:
    """A 3D surface's rig solved on a volume mesh of its inside: the winding-number one
    (:func:`_winding_rig`) or tetrahedra through its own vertices."""
    from ..meshing import tetrahedralize

    V, F = job.V, job.F
    index, Vw, Fw = np.arange(job.n), V, F
    if W_surface is not None:
        # Real assets split vertices at texture and normal seams: weld exact duplicates
        # for a conforming mesh, and give each copy its welded vertex's weight.
        Vw, Fw, index, Ww = _weld(V, F, W_surface)
    tet = None
    if job.volume == "auto" and job.volume_size is None:
        tet = _try_conforming(Vw, Fw, job.sk, job.clip_skeleton, job.stage)
    if job.volume == "winding" or (job.volume == "auto" and tet is None):
        return _winding_rig(job, W_surface)
    if tet is None:
        job.stage("tetrahedralize (bones inside)")
        tet = tetrahedralize(Vw, Fw, job.sk, clip_skeleton=job.clip_skeleton)
    if W_surface is not None:
        # BBW endpoint weights solve on a volume: extend the kept W harmonically to the
        # new vertices (the surface values stay exactly as given).
        job.stage("extend the bone weights inside")
        Wm = _harmonic_extension(tet.V, tet.T, Ww)
        W_out = W_surface
    else:
        Wm = _bbw_bone_weights(job, tet.V, None, tet.T)
        W_out = Wm[:job.n]
    E = _endpoints(job, tet.V, Fw, tet.T, Wm, W_out, index)
    kept = Volume.selection(tet.V, tet.T, index) if job.keep_volume else None
    return _rig(job, W_out, E, kept)


def _endpoints(job: _Job, Vm, Fm, Tm, Wm, W, index):
    """Endpoint weights (n, b) of the rig's vertices: heat on the surface, projection
    and idw on the vertices, BBW on the solve mesh ``(Vm, Fm or Tm)`` whose vertex
    ``index[k]`` is rig vertex k (``Wm``: the bone weights there, ``W``: the rig's)."""
    from ..weights import endpoint_weights

    endpoint = job.endpoint
    if endpoint == "heat":
        return _heat_endpoints(job, W)
    if endpoint in ("projection", "idw"):
        job.stage(f"endpoint weights ({endpoint})")
        return endpoint_weights(job.V, job.sk, method=endpoint)
    elem = dict(T=Tm) if Tm is not None else dict(F=Fm)
    E = endpoint_weights(Vm, job.sk, method=endpoint, W=Wm, tol=job.tol,
                         progress=job.stage(f"endpoint weights ({endpoint})", bar=True),
                         **elem)
    return E[index]


def _heat_endpoints(job: _Job, W):
    """Heat endpoint weights on the surface (a tetrahedral mesh's boundary, extended)."""
    from ..weights import endpoint_weights

    V, F, T = job.V, job.F, job.T
    bar = job.stage("endpoint weights (heat)", bar=True)
    if F is not None:
        return endpoint_weights(V, job.sk, method="heat", W=W, F=F, progress=bar)
    Fs = boundary_faces(T)
    known = np.zeros(job.n, dtype=bool)
    known[np.unique(Fs)] = True
    E = endpoint_weights(V, job.sk, method="heat", W=W, F=Fs, progress=bar)
    return E if known.all() else _extend_values(V, T, E, known)


def _rig(job: _Job, W, E, volume) -> Rig:
    meta = {"bone": "given" if job.W is not None else job.bone, "endpoint": job.endpoint}
    return Rig(V=job.V, F=job.F, T=job.T, skeleton=job.sk, W=W, E=E, meta=meta,
               volume=volume)


def _try_conforming(V, F, sk, clip_skeleton, stage):
    """``volume="auto"``: the conforming tetrahedral mesh of a small, closed, clean
    surface that holds the skeleton (or ``clip_skeleton``), else None (the
    winding-number volume is used)."""
    import warnings

    from ..meshing import check_surface, tetrahedralize

    if V.shape[0] > AUTO_CONFORMING_MAX:
        return None
    try:
        check_surface(V, F)
    except ValueError:
        return None
    stage("tetrahedralize (bones inside)")
    try:
        with warnings.catch_warnings():
            # a clipped skeleton's warning still reaches the caller; TetGen's fallback
            # to the builtin mesher is an implementation detail here
            warnings.filterwarnings("ignore", message="tetrahedralize: TetGen failed")
            return tetrahedralize(V, F, sk, self_intersections=False,
                                  clip_skeleton=clip_skeleton)
    except ValueError:
        return None


def _extend_values(V, T, X, known):
    """Values X (n, k) known on ``known`` vertices, harmonic inside (no normalisation)."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    from ..weights import cotmatrix

    unknown = np.flatnonzero(~known)
    kn = np.flatnonzero(known)
    L = sp.csr_array(cotmatrix(V, T, degenerate="skip"))
    X = np.array(X, dtype=float)
    X[unknown] = spla.splu(L[unknown][:, unknown].tocsc()).solve(
        np.asarray(-(L[unknown][:, kn] @ X[kn])))
    return np.clip(X, 0.0, 1.0)


def _winding_rig(job: _Job, W_surface) -> Rig:
    """A 3D surface's rig on its winding-number volume mesh (:func:`volume_mesh`):
    solve there, interpolate to the surface's vertices."""
    from ..meshing.volume import volume_mesh
    from ..weights import endpoint_weights
    from ..weights.endpoint import bbw_endpoint

    V, F, sk, stage = job.V, job.F, job.sk, job.stage
    vm = volume_mesh(V, F, sk, size=job.volume_size, progress=stage("volume mesh", bar=True))
    interp = vm.interpolation(V)
    if W_surface is None:
        Wv = _winding_bone_weights(job, vm)
        stage("transfer to the surface")
        W = np.asarray(interp @ Wv)
    else:
        stage("transfer into the volume")
        Wv = _to_volume(vm, V, W_surface, interp)
        W = W_surface
    if job.bbw_endpoint:
        # A bone with fewer than two points inside the shape has nothing to spread e
        # from 0 to 1 along: it keeps the projection (eq. 8), as said in the warning.
        inside = np.flatnonzero(vm.bone_points(sk) >= 2)
        Ev = bbw_endpoint(vm.V, sk, W=Wv, T=vm.T, tol=job.tol,
                          joints=job.endpoint == "bbw-joints", bones=inside,
                          progress=stage(f"endpoint weights ({job.endpoint})", bar=True))
        stage("transfer to the surface")
        E = np.clip(np.asarray(interp @ Ev), 0.0, 1.0)
    elif job.endpoint == "heat":
        E = endpoint_weights(V, sk, method="heat", W=W, F=F,
                             progress=stage("endpoint weights (heat)", bar=True))
    else:
        stage(f"endpoint weights ({job.endpoint})")
        E = endpoint_weights(V, sk, method=job.endpoint)
    kept = Volume(V=vm.V, T=vm.T, M=interp) if job.keep_volume else None
    return _rig(job, W, E, kept)


def _winding_bone_weights(job: _Job, vm):
    """BBW bone weights (m, b) on the winding-number volume, rows normalised."""
    from ..weights.bbw import BBWSolver

    b, bc, _ = vm.boundary_conditions(job.sk)
    job.stage("bone weights: Laplacian")
    solver = BBWSolver(vm.V, vm.T, degenerate="skip")
    Wv = solver.solve(b, bc, tol=job.tol, progress=job.stage("bone weights (bbw)", bar=True))
    s = Wv.sum(axis=1)
    if np.any(s <= 1e-12):
        i = int(np.argmin(s))
        raise ValueError(f"BBW left volume vertex {i} at {vm.V[i].tolist()} with all "
                         "weights 0")
    return Wv / s[:, None]
