"""The rig pipeline: a bare mesh and skeleton in, a complete STBS rig out (paper §2.3, §3).

1. Meshing with the skeleton inside (bounded biharmonic weights need the bones in the
   mesh): a 2D triangle mesh's outline is re-triangulated with the bones as constrained
   segments, a closed 3D surface is tetrahedralized with the joints and bone samples
   inserted; a tetrahedral mesh is used as it is. Bone heat works on the surface itself.
2. Bone weights ``W``: bounded biharmonic weights or bone heat.
3. Endpoint weights ``E``: projection (eq. 8), inverse distance (eq. 9), heat, or
   bounded biharmonic (direct, or as joint weights), each solved only where the bone's
   weight exceeds 1e-7.
4. Restriction to the user's vertices: weights of the vertices meshing inserted are
   dropped, so the rig keeps the given ``V`` and ``F`` in their order.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Literal

import numpy as np

from .. import _checks
from ..skeleton import Skeleton
from .model import Rig, _weights

__all__ = ["build_rig", "BONE_METHODS", "ENDPOINT_METHODS", "DEFAULT_TOL"]

#: Bone weight methods of :func:`build_rig`.
BONE_METHODS = ("bbw", "heat")
#: Endpoint weight methods of :func:`build_rig`.
ENDPOINT_METHODS = ("bbw", "bbw-joints", "heat", "projection", "idw")
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


def _harmonic_extension(V, T, W):
    """W (n, b) given on the first n of V's vertices, extended to the others by the
    discrete Laplace equation on the tetrahedra, then clipped and rows normalised."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    from ..weights import cotmatrix

    n = W.shape[0]
    Wd = W.toarray() if sp.issparse(W) else np.asarray(W, dtype=float)
    if len(V) == n:
        return Wd
    L = sp.csr_array(cotmatrix(V, T))
    Lii = L[n:][:, n:].tocsc()
    rhs = -(L[n:][:, :n] @ Wd)
    X = spla.splu(Lii).solve(np.asarray(rhs))
    X = np.clip(X, 0.0, None)
    s = X.sum(axis=1, keepdims=True)
    X = np.where(s > 0, X / np.where(s > 0, s, 1), 1.0 / Wd.shape[1])
    return np.vstack([Wd, X])


def build_rig(V, sk: Skeleton, *, F=None, T=None, W=None,
              bone: Literal["bbw", "heat"] = "bbw",
              endpoint: Literal["bbw", "bbw-joints", "heat", "projection", "idw"] = "bbw",
              tol: float = DEFAULT_TOL, clip_skeleton: bool = False, remesh: bool = True,
              progress: Progress | None = None) -> Rig:
    """A complete rig (bone and endpoint weights) of a mesh and skeleton.

    Parameters
    ----------
    V : (n, d) float
        Rest vertex positions, d = ``sk.dim`` (2 or 3).
    sk : Skeleton
        The skeleton, inside the shape (see ``clip_skeleton``).
    F : (f, 3) int, optional
        Triangles: a 2D shape, or a closed 3D surface.
    T : (t, 4) int, optional
        Tetrahedra (3D), used as they are for bounded biharmonic weights; ``V`` then
        holds every vertex of the tetrahedral mesh.
    W : (n, b) float, optional
        Bone weights to keep (painted, or read from a file); only ``E`` is computed.
    bone : {"bbw", "heat"}
        Bounded biharmonic weights (on a mesh with the skeleton inside), or bone heat
        (Baran & Popović 2007; a 3D triangle surface ``F``).
    endpoint : {"bbw", "bbw-joints", "heat", "projection", "idw"}
        Endpoint weights (paper §2.2-2.3). ``heat`` needs a 3D triangle surface.
    tol : float
        KKT tolerance of the bounded biharmonic solves, in weight units (1e-10 gives
        the exact QP solution, up to 1.5x slower).
    clip_skeleton : bool
        When stbs meshes the shape (bbw without ``T``): mesh only the skeleton's parts
        inside it (for bone tips poking out of the skin); otherwise a joint outside is
        an error.
    remesh : bool
        2D: re-triangulate the outline of ``(V, F)`` with the bones inside (True), or
        solve on ``(V, F)`` as it is (False, for a mesh that already has the bones as
        vertices and edges, e.g. from :func:`stbs.triangulate_2d`).
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
        surface or tetrahedra, ...), a skeleton outside the shape, or bad arrays; the
        message names the argument.

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
    tol = float(tol)
    if not (math.isfinite(tol) and tol > 0):
        raise ValueError(f"tol must be a positive number, got {tol!r}")
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

    if endpoint == "heat" and (d != 3 or F is None):    # checked before any work is done
        raise ValueError("endpoint='heat' needs a 3D triangle surface F")
    keep_W = W is not None
    if keep_W:
        W = _weights("W", W, n, sk.n_bones)
    meshes_itself = ((not keep_W and bone == "bbw" and T is None and (d == 3 or remesh))
                     or (keep_W and d == 3 and T is None and endpoint in ("bbw", "bbw-joints")))
    if clip_skeleton and not meshes_itself:
        raise ValueError("clip_skeleton applies when stbs meshes the shape itself (bone='bbw' "
                         "without T: a 2D mesh, or a 3D surface)")
    if keep_W and endpoint in ("bbw", "bbw-joints") and F is None and T is None:
        raise ValueError(f"endpoint={endpoint!r} needs the mesh's triangles F or tetrahedra T")
    weld = None
    if keep_W and d == 3 and T is None and endpoint in ("bbw", "bbw-joints"):
        # BBW endpoint weights solve on a volume: mesh the surface with the bones inside
        # as for bone weights, and extend the kept W harmonically to the new vertices
        # (the surface values stay exactly as given).
        if F is None:
            raise ValueError(f"endpoint={endpoint!r} in 3D needs a closed triangle surface F "
                             "or tetrahedra T")
        # Real assets split vertices at texture and normal seams: weld exact duplicates
        # for the volume mesh, and give each copy its welded vertex's weight.
        Vw, Fw, weld, Ww = _weld(V, F, W)
        stage("tetrahedralize (bones inside)")
        tet = tetrahedralize(Vw, Fw, sk, clip_skeleton=clip_skeleton)
        Vm, Fm, Tm = tet.V, Fw, tet.T
        stage("extend the bone weights inside")
        Wm = _harmonic_extension(Vm, Tm, Ww)
    elif keep_W:
        Vm, Fm, Tm = V, F, T
        Wm = W
    elif bone == "heat":
        if d != 3 or F is None:
            raise ValueError(f"bone='heat' needs a 3D triangle surface F; got a {d}D mesh"
                             + ("" if F is not None else " without triangles"))
        stage("bone heat")
        Wm = bone_heat(V, F, sk)
        Vm, Fm, Tm = V, F, None
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
            stage("tetrahedralize (bones inside)")
            tet = tetrahedralize(V, F, sk, clip_skeleton=clip_skeleton)
            Vm, Fm, Tm = tet.V, F, tet.T
        Wm = bone_weights(Vm, sk, method="bbw", F=Fm if Tm is None else None, T=Tm, tol=tol,
                          progress=stage("bone weights (bbw)", bar=True))
    if endpoint == "heat":
        stage("endpoint weights (heat)")
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
    return Rig(V=V, F=F, T=T, skeleton=sk, W=W if keep_W else Wm[:n], E=E, meta=meta)
