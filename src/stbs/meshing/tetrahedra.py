"""3D: tetrahedralize a closed surface with the skeleton's joints and bone samples inside."""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import warnings
from typing import Literal

import numpy as np
from scipy.spatial import Delaunay, cKDTree

from .. import _checks
from ..skeleton import Skeleton
from . import _optional
from ._geometry import (
    REL_TOL,
    boundary_faces,
    scale_of,
    segment_hits_triangle,
    tet_volumes,
    unique_rows,
)
from ._pslg import bone_distance
from ._samples import SkeletonPoints, bone_label, check_bone_samples, fmt_point, sample_skeleton
from .result import TetMesh
from .surface import (
    _check_self_intersections,
    check_surface,
    exposed_faces,
    self_intersecting_pairs,
)

__all__ = ["tetrahedralize", "ENGINES_3D"]

#: Values of ``engine`` for :func:`tetrahedralize`.
ENGINES_3D = ("auto", "tetgen", "builtin")


def tetrahedralize(V, F, sk: Skeleton, *, max_volume: float | None = None,
                   max_radius_edge: float | None = 2.0, keep_surface: bool = True,
                   bone_samples=None, engine: Literal["auto", "tetgen", "builtin"] = "auto",
                   self_intersections: bool = True, clip_skeleton: bool = False) -> TetMesh:
    """Tetrahedral mesh of a closed surface with the skeleton's samples as vertices.

    Parameters
    ----------
    V : (n, 3) float
        Surface vertices. They are the first ``n`` vertices of the result, unchanged
        and in order, so weights computed on the tetrahedral mesh restrict to the
        surface as ``W[:n]``.
    F : (f, 3) int
        Surface triangles: a closed, manifold, consistently oriented surface
        without self-intersections (:func:`check_surface` says what is wrong
        otherwise). Several closed components are fine; one inside another makes
        a cavity.
    sk : Skeleton
        A 3D skeleton strictly inside the surface.
    max_volume : float, optional, keyword-only
        Largest tetrahedron volume. None: TetGen refines for quality only; the
        builtin engine spaces its lattice like the surface's mean edge length.
    max_radius_edge : float or None, keyword-only
        TetGen's quality bound (``-q``): the largest circumradius / shortest edge
        ratio, at least 1.0 (default 2.0, TetGen's own; 1.414 is libigl's tutorial
        choice). None: no quality refinement. Ignored by the builtin engine.
    keep_surface : bool, keyword-only
        Forbid Steiner points on the surface (TetGen ``-Y``, default), so the
        boundary of the result is the input surface. Refinement then cannot
        split surface triangles, which limits the quality next to a coarse
        surface. The builtin engine never adds surface points.
    bone_samples : int or (b,) int, optional, keyword-only
        Inner samples per bone (joints are always vertices). None: spaced like
        the mean surface edge (or the edge of a regular tetrahedron of
        ``max_volume``), at least one per bone.
    engine : {"auto", "tetgen", "builtin"}, keyword-only
        ``"tetgen"``: TetGen through pyvista's ``tetgen`` package (the ``tetgen``
        extra; TetGen is AGPL-3.0). ``"builtin"``: a body-centred cubic lattice
        inside the surface (by winding number) plus the surface and skeleton
        points, tetrahedralized by ``scipy.spatial.Delaunay``, keeping the
        tetrahedra whose centroid is inside (see Notes). ``"auto"``: TetGen when
        installed, falling back to builtin with a ``UserWarning`` when TetGen
        fails on a surface that passed the checks.
    self_intersections : bool, keyword-only
        Check the surface for self-intersections first (default True). TetGen cannot
        mesh a self-intersecting surface (it fails, or crashes its process): with
        ``engine="auto"`` or ``"builtin"`` the builtin mesher then meshes the inside,
        by winding number, with a ``UserWarning`` saying so; with ``"tetgen"`` it is
        an error. False: no check (TetGen failures still fall back under ``"auto"``).
    clip_skeleton : bool, keyword-only
        False (default): a joint or bone sample outside the surface, or a bone
        crossing it, is an error that gives the distance. True: mesh only the
        skeleton's parts inside the shape, for rigs whose bone tips poke out of the
        skin. Joints and samples outside the surface, and samples closer to it than a
        tenth of the sample spacing, are left out (with a ``UserWarning`` that counts them and
        gives the farthest distance); a left-out joint has ``joint_vertex`` -1. A bone
        with no point left inside is still an error, naming the bone.

    Returns
    -------
    TetMesh
        ``V`` (m, 3): the surface vertices, then the joints (``joint_vertex`` =
        ``n + arange(j)``), the bone samples, then Steiner points. Positively
        oriented ``T`` (t, 4); ``F``, the boundary of ``T``; ``on_bone`` /
        ``t_bone`` as for :func:`triangulate_2d` (every sample is
        ``a_i + t (b_i - a_i)`` exactly as computed).

    Raises
    ------
    ValueError
        A surface that is open, non-manifold, inconsistently oriented,
        self-intersecting, has degenerate triangles or unused or duplicate vertices;
        a 2-D ``V`` or skeleton; a joint or bone sample outside the surface or a
        bone crossing it (the message names the bone); bad options.
    ImportError
        ``engine="tetgen"`` without the ``tetgen`` package (names the extra).
    RuntimeError
        ``engine="tetgen"`` and TetGen fails on the surface.

    Notes
    -----
    The builtin engine makes good tetrahedra inside (the lattice's are all alike,
    dihedral angles 60 and 90 degrees) but does not conform to the surface: the
    tetrahedra between the surface vertices and the lattice are whatever the
    Delaunay tetrahedralization gives (slivers happen, volumes stay positive),
    the boundary of ``T`` follows the surface only approximately, and features
    thinner than the lattice spacing are bridged. Flat tetrahedra of four surface
    vertices are peeled off the boundary (measured on arm.obj: smallest dihedral
    angle 0.13 degrees, TetGen's 0.7). Every surface vertex stays in some
    tetrahedron; that is all the weights need.

    TetGen runs in a child Python process (about 0.25 s to start), so that a failure
    cannot hurt the caller: after one, the binding corrupts the heap (seen as aborts
    at exit), and TetGen may leave files in the working folder.

    Examples
    --------
    >>> import numpy as np
    >>> import stbs
    >>> V, F, sk, _ = stbs.shapes.cigar(10)
    >>> tm = stbs.tetrahedralize(V, F, sk, engine="builtin")
    >>> bool((tm.V[:len(V)] == V).all()), bool(np.all(tm.V[tm.joint_vertex] == sk.C))
    (True, True)
    """
    _checks.skeleton(sk)
    engine = _checks.choice("engine", engine, ENGINES_3D)
    if max_volume is not None:
        max_volume = float(max_volume)
        if not (np.isfinite(max_volume) and max_volume > 0):
            raise ValueError(f"max_volume must be a positive number or None, got {max_volume}")
    if max_radius_edge is not None:
        max_radius_edge = float(max_radius_edge)
        if not (np.isfinite(max_radius_edge) and max_radius_edge >= 1.0):
            raise ValueError(f"max_radius_edge must be >= 1.0 or None, got {max_radius_edge}")
    counts = check_bone_samples(bone_samples, sk)
    if engine == "tetgen":
        _optional.require("tetgen")  # before the work, not after it
    V, F = check_surface(V, F, self_intersections=False)
    boundary = None      # self-intersecting: (uncut triangles on the boundary, crossed ones)
    if self_intersections:
        pairs = self_intersecting_pairs(V, F)
        try:
            _check_self_intersections(V, F, pairs)
        except ValueError as exc:
            if engine == "tetgen":
                raise ValueError(f"{exc}; or pass engine='auto' or 'builtin', which meshes "
                                 "the inside by winding number") from None
            # The builtin mesher copes: the lattice is kept by winding number, the
            # tetrahedra by their side of the nearest triangle on the boundary.
            warnings.warn(f"tetrahedralize: {str(exc).split(' — ')[0]}; TetGen cannot mesh "
                          "it, so the builtin mesher meshes the inside by winding number",
                          UserWarning, stacklevel=2)
            engine = "builtin"
            cut = np.zeros(F.shape[0], dtype=bool)
            cut[np.concatenate(pairs)] = True
            boundary = (exposed_faces(V, F, *pairs) & ~cut, cut)
    if sk.dim != 3:
        raise ValueError(f"sk must be a 3-D skeleton for a 3-D surface, got a {sk.dim}-D one "
                         "(C has 2 columns); use triangulate_2d for 2-D shapes")
    mean_edge = float(np.linalg.norm(V[F[:, 1]] - V[F[:, 0]], axis=1).mean())
    spacing = mean_edge
    if max_volume is not None:
        spacing = min(spacing, (6.0 * np.sqrt(2.0) * max_volume) ** (1 / 3))  # regular tet
    sp = sample_skeleton(sk, spacing, counts)
    sp, joint_vertex = _skeleton_inside(V, F, sk, sp, n=V.shape[0], clip=clip_skeleton,
                                        margin=0.1 * spacing, faces=boundary is None)
    if engine == "auto":
        engine = "tetgen" if _optional.available("tetgen") else "builtin"
        if engine == "tetgen":
            try:
                return _tetgen(V, F, sk, sp, joint_vertex, max_volume, max_radius_edge,
                               keep_surface)
            except RuntimeError as exc:
                warnings.warn(f"tetrahedralize: TetGen failed ({exc}); using the builtin "
                              "mesher instead", UserWarning, stacklevel=2)
                engine = "builtin"
    if engine == "tetgen":
        return _tetgen(V, F, sk, sp, joint_vertex, max_volume, max_radius_edge,
                       keep_surface)
    return _lattice(V, F, sk, sp, joint_vertex, max_volume, mean_edge, boundary)


def _skeleton_inside(V, F, sk: Skeleton, sp: SkeletonPoints, *, n: int, clip: bool,
                     margin: float, faces: bool = True) -> tuple[SkeletonPoints, np.ndarray]:
    """The skeleton points to insert and every joint's vertex (-1: left out).

    Without ``clip``, any point outside the surface, or (``faces``) a bone crossing
    one of its triangles, is an error. A self-intersecting surface has triangles
    inside the shape, so there only the points' winding numbers count.
    """
    from ..geometry import winding_numbers
    from ._kernels import SurfaceIndex

    inside = np.abs(winding_numbers(sp.X, V, F)) >= 0.5
    size = scale_of(V)
    if clip:
        dist, _ = SurfaceIndex(V, F).closest_side(sp.X, np.inf)
        joint = np.arange(sp.X.shape[0]) < sk.n_joints
        keep = inside & ((dist >= margin) | joint)   # joints inside stay, as without clip
        lost = ~keep
        if lost.any():
            has = np.zeros(sk.n_bones, dtype=bool)
            has[sp.bone[keep & (sp.bone >= 0)]] = True
            kept_joints = np.flatnonzero(keep[:sk.n_joints])
            has[np.isin(sk.BE, kept_joints).any(axis=1)] = True
            if not has.all():
                i = int(np.argmin(has))
                raise ValueError(f"sk: {bone_label(sk, i)} lies outside the surface (none of "
                                 "its points is inside the shape); move the skeleton inside")
            far = np.where(inside, 0.0, dist)[lost].max()
            warnings.warn(f"tetrahedralize: {int(lost.sum())} skeleton point(s) outside, or "
                          f"samples within {margin:.3g} of the surface, left out "
                          f"({int((~keep[:sk.n_joints]).sum())} joint(s)); the farthest is "
                          f"{far:.3g} outside ({100 * far / size:.2g} % of the shape's size)",
                          UserWarning, stacklevel=3)
        joint_vertex = np.full(sk.n_joints, -1, dtype=np.int64)
        kj = keep[:sk.n_joints]
        joint_vertex[kj] = n + np.arange(int(kj.sum()))
        return SkeletonPoints(X=sp.X[keep], bone=sp.bone[keep], t=sp.t[keep]), joint_vertex
    out = np.flatnonzero(~inside)
    if out.size:
        k = int(out[0])
        if sp.bone[k] < 0:
            bones = np.flatnonzero((sk.BE == k).any(axis=1))
            who = (bone_label(sk, int(bones[0])) + f": its joint {k}") if bones.size \
                else f"joint {k}"
        else:
            who = f"{bone_label(sk, int(sp.bone[k]))} leaves the shape: its point at t = " \
                f"{sp.t[k]:.3g}"
        d = float(SurfaceIndex(V, F).closest_side(sp.X[k:k + 1], np.inf)[0][0])
        raise ValueError(f"sk: {who} at {fmt_point(sp.X[k])} is outside the surface by "
                         f"{d:.3g} ({100 * d / size:.2g} % of the shape's size; {out.size} "
                         "skeleton point(s) outside); the skeleton must lie inside the shape "
                         "(check that the skeleton and the mesh use the same coordinates), or "
                         "pass clip_skeleton=True (--clip-skeleton on the command line) to "
                         "mesh only its parts inside")
    A, B = sk.A, sk.B
    P = V[F]
    for i in range(sk.n_bones if faces else 0):
        hit = segment_hits_triangle(A[i], B[i], P[:, 0], P[:, 1], P[:, 2])
        if hit.any():
            f = int(np.argmax(hit))
            raise ValueError(f"sk: {bone_label(sk, i)} crosses the surface (triangle {f} at "
                             f"{fmt_point(P[f].mean(axis=0))}); every bone must lie strictly "
                             "inside the shape, or pass clip_skeleton=True (stbs rig "
                             "--clip-skeleton) to mesh only its parts inside")
    return sp, n + np.arange(sk.n_joints, dtype=np.int64)


# TetGen runs in a child process: after a failure the binding corrupts the heap (we saw
# "corrupted double-linked list" aborts and segfaults at exit), and on some failures it
# writes "tetgen-tmpfile_skipped.*" files into the working folder. A child run in a
# temporary folder contains both; it costs about a quarter second of start-up.
_WORKER = """
import sys
import numpy as np
import tetgen
d = np.load(sys.argv[1])
gen = tetgen.TetGen(d["X"], d["F"])
nodes, elems = gen.tetrahedralize(switches=sys.argv[2])[:2]
np.savez(sys.argv[3], nodes=np.asarray(nodes, dtype=np.float64),
         elems=np.asarray(elems, dtype=np.int64))
"""


def _run_tetgen(X: np.ndarray, F: np.ndarray, switches: str) -> tuple[np.ndarray, np.ndarray]:
    _optional.require("tetgen")  # a clear ImportError here, not a child's traceback
    with tempfile.TemporaryDirectory(prefix="stbs-tetgen-") as tmp:
        src, dst = os.path.join(tmp, "in.npz"), os.path.join(tmp, "out.npz")
        np.savez(src, X=X, F=F.astype(np.int32))
        proc = subprocess.run([sys.executable, "-c", _WORKER, src, switches, dst], cwd=tmp,
                              capture_output=True, text=True, errors="replace", check=False)
        if proc.returncode != 0 or not os.path.exists(dst):
            # TetGen's own words, without the child's traceback (indented lines).
            lines = (proc.stdout + "\n" + proc.stderr).splitlines()
            said = [x.strip().removeprefix("RuntimeError: ") for x in lines
                    if x.strip() and not x[0].isspace() and not x.startswith("Traceback")
                    and x.strip() not in ("parsing switches", "success")][-3:]
            how = f"exit status {proc.returncode}" if proc.returncode >= 0 else \
                f"killed by signal {-proc.returncode}"
            raise RuntimeError(f"TetGen failed with switches {switches!r}: "
                               + (" / ".join(said) if said else how))
        with np.load(dst) as out:
            return out["nodes"], out["elems"]


def _tetgen(V, F, sk, sp, joint_vertex, max_volume, max_radius_edge, keep_surface) -> TetMesh:
    n = V.shape[0]
    X = np.vstack([V, sp.X])
    switches = "pQ"
    if max_radius_edge is not None:
        switches += f"q{max_radius_edge:.6g}"
    if max_volume is not None:
        switches += f"a{max_volume:.17g}"
    if keep_surface:
        switches += "Y"
    Vt, T = _run_tetgen(X, F, switches)
    if Vt.shape[0] < X.shape[0] or not np.array_equal(Vt[:X.shape[0]], X):
        raise RuntimeError("TetGen changed or dropped input points")
    return _finish(Vt, T, V, F, sk, sp, joint_vertex, n, "tetgen")


def _lattice(V, F, sk, sp, joint_vertex, max_volume, mean_edge, boundary=None) -> TetMesh:
    from scipy.sparse import coo_array
    from scipy.sparse.csgraph import connected_components

    from ..geometry import winding_numbers
    from ._kernels import SurfaceIndex

    n = V.shape[0]
    m = n + sp.X.shape[0]
    # Body-centred cubic lattice, cube side h: its Delaunay tetrahedra (all congruent,
    # volume h^3 / 12) have edges h and h sqrt(3) / 2.
    h = (12.0 * max_volume) ** (1 / 3) if max_volume is not None else 2.0 * mean_edge
    lo, hi = V.min(axis=0), V.max(axis=0)
    shape = tuple(int(x) for x in np.floor((hi - lo) / h).astype(np.int64) + 2)
    if np.prod(shape) > 20_000_000:
        raise ValueError(f"max_volume={max_volume} asks for a lattice of {2 * np.prod(shape)} "
                         "points; pass a larger max_volume")
    ijk = np.indices(shape).reshape(3, -1).T
    # A fixed offset keeps lattice points off axis-aligned planes of the input.
    corner = lo - 0.5 * h + 0.0371 * h + ijk * h
    Lp = np.vstack([corner, corner + 0.5 * h])
    P = V[F]
    index = SurfaceIndex(V, F)
    Rf = float(np.linalg.norm(P - P.mean(axis=1)[:, None], axis=2).max())
    # Lattice points within h/2 of the surface are dropped; the others cannot be joined
    # across the surface by a lattice edge (length <= h), so each connected piece of the
    # lattice is wholly inside or outside: one winding number per piece decides.
    near = np.zeros(Lp.shape[0], dtype=bool)
    band = np.isfinite(index.tree.query(Lp, distance_upper_bound=0.5 * h + Rf)[0])
    d, _ = index.closest_side(Lp[band], 0.5 * h)
    near[band] = d <= 0.5 * h
    N = ijk.shape[0]
    edges = []
    for off in np.indices((2, 2, 2)).reshape(3, -1).T:
        # Centre (i, j, k) is a neighbour of corners (i, j, k) + off, off in {0, 1}^3.
        c = ijk + off
        ok = np.all(c < np.array(shape), axis=1)
        a = N + np.flatnonzero(ok)
        b = np.ravel_multi_index(c[ok].T, shape)
        edges.append(np.stack([a, b], axis=1))
    E = np.concatenate(edges)
    E = E[~near[E[:, 0]] & ~near[E[:, 1]]]
    G = coo_array((np.ones(E.shape[0]), (E[:, 0], E[:, 1])), shape=(Lp.shape[0],) * 2)
    _, label = connected_components(G, directed=False)
    first = np.unique(label[~near], return_index=True)[1]
    reps = np.flatnonzero(~near)[first]
    piece_in = np.zeros(label.max() + 1, dtype=bool)
    piece_in[label[reps]] = np.abs(winding_numbers(Lp[reps], V, F)) > 0.5
    keep = ~near & piece_in[label]
    keep &= cKDTree(sp.X).query(Lp)[0] > 0.5 * h  # room around the skeleton samples
    X = np.vstack([V, sp.X, Lp[keep]])
    T = Delaunay(X).simplices.astype(np.int64)
    # Flat tetrahedra (Delaunay's on coplanar points) by their own size, not the
    # shape's: a detailed surface has tetrahedra 1e-12 of the shape's size cubed.
    Pt = X[T]
    longest = np.max([np.linalg.norm(Pt[:, i] - Pt[:, j], axis=1)
                      for i, j in ((0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3))], axis=0)
    T = T[np.abs(tet_volumes(X, T)) > 1e-12 * longest ** 3]
    # Inside or out by the centroid: its side of the nearest surface point.
    Q = X[T]
    cen = Q.mean(axis=1)
    reach = np.linalg.norm(Q - cen[:, None], axis=2).max(axis=1)
    near_cut = near_inner = np.zeros(T.shape[0], dtype=bool)
    if boundary is not None:
        # A self-intersecting surface: an inner triangle (a sheet inside another) has
        # the inside on both sides, and a crossed one says nothing by its side; only
        # the boundary's uncut triangles are asked, the winding number near crossings.
        on, cut = boundary

        def near(mask):
            return np.isfinite(SurfaceIndex(V, F[mask]).closest_side(cen, reach)[0]) \
                if mask.any() else np.zeros(T.shape[0], dtype=bool)

        near_cut, near_inner = near(cut), near(~on & ~cut)
        index = SurfaceIndex(V, F[on]) if on.any() else None
    if index is not None:
        dist, side = index.closest_side(cen, reach)
    else:
        dist, side = np.full(T.shape[0], np.inf), np.zeros(T.shape[0], dtype=np.int64)
    interior = (T >= n).any(axis=1)
    # No surface within reach: the tetrahedron does not meet it, and has an interior
    # vertex (a surface vertex would be within reach) so it is inside.
    inside = (side < 0) | (np.isinf(dist) & interior) | ((side == 0) & interior)
    inside[near_inner & np.isinf(dist)] = True
    inside[near_cut] = np.abs(winding_numbers(cen[near_cut], V, F)) > 0.5
    depth = np.full(dist.shape, np.inf)
    fin = np.isfinite(dist)
    depth[fin] = -side[fin] * dist[fin]
    # A surface vertex all of whose tetrahedra poke out (a sharp concave spot) keeps its
    # most-inside one.
    used = np.zeros(X.shape[0], dtype=bool)
    used[T[inside].ravel()] = True
    orphan = np.flatnonzero(~used[:m])
    if orphan.size:
        t_of = np.repeat(np.arange(T.shape[0]), 4)
        v_of = T.ravel()
        sel = np.isin(v_of, orphan)
        cand_t, cand_v = t_of[sel], v_of[sel]
        order = np.lexsort((-depth[cand_t], cand_v))
        first = np.unique(cand_v[order], return_index=True)[1]
        inside[cand_t[order][first]] = True
    T = _peel_slivers(X, T[inside], n)
    used = np.zeros(X.shape[0], dtype=bool)
    used[T.ravel()] = True
    used[:m] = True  # checked in _finish
    # Drop lattice points no kept tetrahedron uses (they all come after the fixed ones).
    remap = np.cumsum(used) - 1
    return _finish(X[used], remap[T], V, F, sk, sp, joint_vertex, n, "builtin")


def _peel_slivers(X, T, n, *, min_dihedral_deg: float = 5.0, rounds: int = 8):
    """Remove flat tetrahedra made of four surface vertices from the boundary.

    Delaunay tetrahedralization of nearly coplanar surface vertices leaves slivers
    lying in the surface (dihedral angles near 0 or 180 degrees); on the boundary they
    add nothing but terrible cotangent weights. One is kept if removing it would leave
    a vertex in no tetrahedron.
    """
    for _ in range(rounds):
        surf = (T < n).all(axis=1)
        if not surf.any():
            break
        faces = np.concatenate([T[:, [1, 2, 3]], T[:, [0, 3, 2]], T[:, [0, 1, 3]],
                                T[:, [0, 2, 1]]])
        key = np.sort(faces, axis=1)
        _, _, inv, cnt = unique_rows(key)
        on_boundary = (cnt[inv.ravel()] == 1).reshape(4, -1).any(axis=0)
        cand = np.flatnonzero(surf & on_boundary)
        cand = cand[_min_dihedral(X, T[cand]) < np.radians(min_dihedral_deg)]
        if cand.size == 0:
            break
        keep = np.ones(T.shape[0], dtype=bool)
        keep[cand] = False
        used = np.bincount(T[keep].ravel(), minlength=X.shape[0]) > 0
        lost = np.isin(T[cand], np.flatnonzero(~used)).any(axis=1)
        if lost.all():
            break
        keep[cand[lost]] = True
        T = T[keep]
    return T


def _min_dihedral(X, T) -> np.ndarray:
    """Smallest dihedral angle (radians) of each tetrahedron."""
    P = X[T]
    out = np.full(T.shape[0], np.pi)
    for i, j, k, l in ((0, 1, 2, 3), (0, 2, 1, 3), (0, 3, 1, 2), (1, 2, 0, 3), (1, 3, 0, 2),
                       (2, 3, 0, 1)):
        e = P[:, j] - P[:, i]
        n1 = np.cross(e, P[:, k] - P[:, i])
        n2 = np.cross(e, P[:, l] - P[:, i])
        c = np.einsum("ij,ij->i", n1, n2) / (np.linalg.norm(n1, axis=1)
                                             * np.linalg.norm(n2, axis=1))
        out = np.minimum(out, np.arccos(np.clip(c, -1.0, 1.0)))
    return out


def _finish(X, T, V, F, sk, sp: SkeletonPoints, joint_vertex: np.ndarray, n: int,
            engine: str) -> TetMesh:
    from ..geometry import winding_numbers

    m = n + sp.X.shape[0]
    if engine == "tetgen" and _components(F) > 1:
        # A surface inside another bounds a cavity, which TetGen fills: drop it.
        w = np.abs(winding_numbers(X[T].mean(axis=1), V, F))
        T = T[w > 0.5]
        used = np.zeros(X.shape[0], dtype=bool)
        used[T.ravel()] = True
        used[:m] = True
        remap = np.cumsum(used) - 1
        T, X = remap[T], X[used]
    used = np.zeros(X.shape[0], dtype=bool)
    used[T.ravel()] = True
    if not used[:m].all():
        k = int(np.argmin(used[:m]))
        what = "surface vertex" if k < n else "skeleton point"
        raise RuntimeError(f"{engine}: {what} {k} at {fmt_point(X[k])} is in no tetrahedron")
    vol = tet_volumes(X, T)
    T = np.where((vol < 0)[:, None], T[:, [0, 1, 3, 2]], T)
    if np.abs(vol).min() <= 0:
        raise RuntimeError(f"{engine} produced a tetrahedron of zero volume (internal error)")
    on_bone = np.full(X.shape[0], -1, dtype=np.int64)
    t_bone = np.full(X.shape[0], np.nan)
    on_bone[n:m] = sp.bone
    t_bone[n:m] = sp.t
    steiner = np.arange(m, X.shape[0])
    if steiner.size:
        i, t, d = bone_distance(X[steiner], sk.A, sk.B)
        on = (d <= REL_TOL * scale_of(X)) & (t > 0) & (t < 1)
        on_bone[steiner[on]], t_bone[steiner[on]] = i[on], t[on]
    arrays = dict(V=X, T=T.astype(np.int64), F=boundary_faces(T).astype(np.int64),
                  on_bone=on_bone, t_bone=t_bone,
                  joint_vertex=joint_vertex)
    for a in arrays.values():
        a.setflags(write=False)
    return TetMesh(**arrays, n_input=n, engine=engine)


def _components(F) -> int:
    from scipy.sparse import coo_array
    from scipy.sparse.csgraph import connected_components

    n = int(F.max()) + 1
    E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]]])
    G = coo_array((np.ones(E.shape[0]), (E[:, 0], E[:, 1])), shape=(n, n))
    return int(connected_components(G, directed=False)[0])
