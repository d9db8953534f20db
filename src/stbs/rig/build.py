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
from typing import Literal

import numpy as np

from .. import _checks
from ..geometry import boundary_faces
from ..methods import BONE_METHODS, ENDPOINT_METHODS
from ..skeleton import Skeleton
from .model import Rig, _weights

__all__ = ["build_rig", "BONE_METHODS", "ENDPOINT_METHODS", "VOLUME_METHODS", "DEFAULT_TOL"]

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
#: then report ``done`` of ``total`` units (weight functions).
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


def build_rig(V, sk: Skeleton, *, F=None, T=None, W=None,
              bone: Literal["bbw", "heat"] = "bbw",
              endpoint: Literal["bbw", "bbw-joints", "heat", "projection", "idw"] = "bbw",
              tol: float = DEFAULT_TOL, clip_skeleton: bool = False, remesh: bool = True,
              volume: Literal["auto", "winding", "conforming"] = "auto",
              volume_size: float | None = None,
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
    progress : callable, optional
        ``progress(stage, done, total)``: each stage starts with ``(stage, 0, 0)``; the
        weight solves then report how many of their functions are done.

    Returns
    -------
    Rig
        ``V``, ``F`` and ``T`` as given (``T`` only when given), the skeleton ``sk``,
        ``W`` and ``E`` (n, b), and ``meta = {"bone": ..., "endpoint": ...}``.

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
    from ..meshing import tetrahedralize, triangulate_2d
    from ..weights import bone_heat, bone_weights, endpoint_weights

    V = _checks.skeleton(sk, V)
    n, d = V.shape
    _choice("bone", bone, BONE_METHODS)
    _choice("endpoint", endpoint, ENDPOINT_METHODS)
    _choice("volume", volume, VOLUME_METHODS)
    tol = float(tol)
    if not (math.isfinite(tol) and tol > 0):
        raise ValueError(f"tol must be a positive number, got {tol!r}")
    if volume_size is not None:
        volume_size = float(volume_size)
        if not (math.isfinite(volume_size) and volume_size > 0):
            raise ValueError(f"volume_size must be a positive number, got {volume_size!r}")
    F = None if F is None else _checks.index_array("F", F, ndim=2, shape=(None, 3))
    T = None if T is None else _checks.index_array("T", T, ndim=2, shape=(None, 4))
    for name, X in (("F", F), ("T", T)):
        if X is not None and X.size and (X.min() < 0 or X.max() >= n):
            raise ValueError(f"{name} must hold vertex indices in 0..{n - 1}, got "
                             f"{int(X.min()) if X.min() < 0 else int(X.max())}")
    if T is not None and d != 3:
        raise ValueError(f"T (tetrahedra) needs 3D vertices, got V of shape {V.shape}")
    say = progress or (lambda stage, done, total: None)

    def stage(label: str, bar: bool = False):
        say(label, 0, 0)
        if bar:
            return lambda done, total: say(label, done, total)
        return None

    keep_W = W is not None
    heat_on = bone == "heat" and not keep_W
    for what, method in (("bone", None if keep_W else bone), ("endpoint", endpoint)):
        if method == "heat" and (d != 3 or (F is None and T is None)):  # before any work
            raise ValueError(f"{what}='heat' needs a 3D triangle surface F"
                             + (f"; got a {d}D mesh" if d != 3 else " (or tetrahedra T)"))
    if keep_W:
        W = _weights("W", W, n, sk.n_bones)
    bbw_endpoint = endpoint in ("bbw", "bbw-joints")
    surface_3d = d == 3 and T is None
    known_W = keep_W or heat_on
    needs_volume = surface_3d and F is not None and (bbw_endpoint
                                                     or (bone == "bbw" and not known_W))
    winding = needs_volume and volume == "winding"
    conforming = needs_volume and volume == "conforming"
    meshes_itself = needs_volume or (d == 2 and not keep_W and bone == "bbw" and remesh)
    if clip_skeleton and not meshes_itself:
        raise ValueError("clip_skeleton applies when stbs meshes the shape itself (bone='bbw' "
                         "without T: a 2D mesh, or a 3D surface)")
    if keep_W and bbw_endpoint and F is None and T is None:
        raise ValueError(f"endpoint={endpoint!r} needs the mesh's triangles F or tetrahedra T")
    if heat_on and T is not None:
        # Bone heat lives on the surface: the tetrahedra's boundary, extended inside.
        Fs = F if F is not None else boundary_faces(T)
        stage("bone heat")
        Ws = bone_heat(V, Fs, sk)
        known = np.zeros(n, dtype=bool)
        known[np.unique(Fs)] = True
        if not known.all():
            stage("extend the bone weights inside")
            Ws = _extend(V, T, Ws, known)
        W_surface = Ws
    elif heat_on:
        stage("bone heat")
        W_surface = bone_heat(V, F, sk)
    else:
        W_surface = W if keep_W else None
    weld = tet = None
    if W_surface is not None and needs_volume:
        # Real assets split vertices at texture and normal seams: weld exact duplicates
        # for a conforming mesh, and give each copy its welded vertex's weight.
        Vw, Fw, weld, Ww = _weld(V, F, W_surface)
    if needs_volume and volume == "auto" and volume_size is not None:
        volume, winding = "winding", True      # a size is the winding volume's
    if needs_volume and volume == "auto":
        tet = _try_conforming(Vw if weld is not None else V, Fw if weld is not None else F,
                              sk, clip_skeleton, stage)
        conforming, winding = tet is not None, tet is None
    if winding:
        return _winding_rig(V, F, sk, W_surface, keep_W, bone, endpoint, tol, volume_size,
                            stage)
    if W_surface is not None and conforming:
        # BBW endpoint weights solve on a volume: mesh the surface with the bones inside
        # as for bone weights, and extend the kept W harmonically to the new vertices
        # (the surface values stay exactly as given).
        if tet is None:
            stage("tetrahedralize (bones inside)")
            tet = tetrahedralize(Vw, Fw, sk, clip_skeleton=clip_skeleton)
        Vm, Fm, Tm = tet.V, Fw, tet.T
        stage("extend the bone weights inside")
        Wm = _harmonic_extension(Vm, Tm, Ww)
    elif W_surface is not None:
        Vm, Fm, Tm = V, F, T
        Wm = W_surface
        weld = None
    else:
        if d == 2:
            if F is None:
                raise ValueError("a 2D rig needs triangles F (the outline is taken from them)")
            if remesh:
                stage("triangulate (bones inside)")
                tri = triangulate_2d((V, F), sk, clip_skeleton=clip_skeleton)
                Vm, Fm, Tm = tri.V, tri.F, None
            else:
                Vm, Fm, Tm = V, F, None
        elif T is not None:
            Vm, Fm, Tm = V, F, T
        else:
            if F is None:
                raise ValueError("a 3D rig needs a closed triangle surface F or tetrahedra T")
            if tet is None:
                stage("tetrahedralize (bones inside)")
                tet = tetrahedralize(V, F, sk, clip_skeleton=clip_skeleton)
            Vm, Fm, Tm = tet.V, F, tet.T
        Wm = bone_weights(Vm, sk, method="bbw", F=Fm if Tm is None else None, T=Tm, tol=tol,
                          progress=stage("bone weights (bbw)", bar=True))
    if endpoint == "heat":
        stage("endpoint weights (heat)")
        if F is None:                      # a tetrahedral mesh: on its boundary, extended
            Fs = boundary_faces(T)
            known = np.zeros(n, dtype=bool)
            known[np.unique(Fs)] = True
            E = endpoint_weights(V, sk, method="heat", W=Wm[:n], F=Fs)
            if not known.all():
                E = _extend_values(V, T, E, known)
        else:
            E = endpoint_weights(V, sk, method="heat", W=Wm[:n], F=F)
    elif endpoint in ("projection", "idw"):
        stage(f"endpoint weights ({endpoint})")
        E = endpoint_weights(V, sk, method=endpoint)
    else:
        elem = dict(T=Tm) if Tm is not None else dict(F=Fm)
        E = endpoint_weights(Vm, sk, method=endpoint, W=Wm, tol=tol,
                             progress=stage(f"endpoint weights ({endpoint})", bar=True),
                             **elem)
        E = E[weld] if weld is not None else E[:n]
    meta = {"bone": "given" if keep_W else bone, "endpoint": endpoint}
    W_out = W_surface if W_surface is not None else Wm[:n]
    return Rig(V=V, F=F, T=T, skeleton=sk, W=W_out, E=E, meta=meta)


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


def _winding_rig(V, F, sk, W_surface, keep_W, bone, endpoint, tol, volume_size, stage) -> Rig:
    """A 3D surface's rig on its winding-number volume mesh (:func:`volume_mesh`):
    solve there, interpolate to the surface's vertices."""
    from ..meshing.volume import volume_mesh
    from ..weights import endpoint_weights
    from ..weights.bbw import BBWSolver
    from ..weights.endpoint import bbw_endpoint

    stage("volume mesh")
    vm = volume_mesh(V, F, sk, size=volume_size)
    interp = vm.interpolation(V)
    if W_surface is None:
        b, bc, _ = vm.boundary_conditions(sk)
        stage("bone weights: Laplacian")
        solver = BBWSolver(vm.V, vm.T, degenerate="skip")
        Wv = solver.solve(b, bc, tol=tol, progress=stage("bone weights (bbw)", bar=True))
        s = Wv.sum(axis=1)
        if np.any(s <= 1e-12):
            i = int(np.argmin(s))
            raise ValueError(f"BBW left volume vertex {i} at {vm.V[i].tolist()} with all "
                             "weights 0")
        Wv /= s[:, None]
        stage("transfer to the surface")
        W = np.asarray(interp @ Wv)
    else:
        stage("transfer into the volume")
        Wv = _to_volume(vm, V, W_surface, interp)
        W = W_surface
    if endpoint in ("bbw", "bbw-joints"):
        # A bone with fewer than two points inside the shape has nothing to spread e
        # from 0 to 1 along: it keeps the projection (eq. 8), as said in the warning.
        inside = np.flatnonzero(vm.bone_points(sk) >= 2)
        Ev = bbw_endpoint(vm.V, sk, W=Wv, T=vm.T, tol=tol, joints=endpoint == "bbw-joints",
                          bones=inside,
                          progress=stage(f"endpoint weights ({endpoint})", bar=True))
        stage("transfer to the surface")
        E = np.clip(np.asarray(interp @ Ev), 0.0, 1.0)
    else:
        stage(f"endpoint weights ({endpoint})")
        E = endpoint_weights(V, sk, method=endpoint, **(
            dict(W=W, F=F) if endpoint == "heat" else {}))
    meta = {"bone": "given" if keep_W else bone, "endpoint": endpoint}
    return Rig(V=V, F=F, T=None, skeleton=sk, W=W, E=E, meta=meta)
