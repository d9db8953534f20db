"""2D: triangulate an outline with the skeleton's bones as constrained segments."""

from __future__ import annotations

import math
from typing import Literal

import numpy as np

from .. import _checks
from ..skeleton import Skeleton
from . import _optional
from ._clip import Clip, clip_skeleton_2d
from ._geometry import REL_TOL, points_in_loops, scale_of, signed_area, triangle_areas
from ._pslg import PSLG, bone_distance, build_pslg, check_skeleton_inside
from ._samples import check_bone_samples
from .outline import as_outline
from .result import TriMesh

__all__ = ["triangulate_2d", "ENGINES_2D"]

#: Values of ``engine`` for :func:`triangulate_2d`.
ENGINES_2D = ("auto", "triangle", "builtin")
#: Largest ``min_angle`` accepted: Delaunay refinement is guaranteed to stop only for
#: smaller bounds (Ruppert: 20.7 degrees; Triangle in practice up to about 33.9).
MAX_MIN_ANGLE = math.radians(34.0)
#: The builtin engine's bound: beyond it batch refinement can chase its own tail.
MAX_MIN_ANGLE_BUILTIN = math.radians(30.0)


def triangulate_2d(outline, sk: Skeleton, *, max_area: float | None = None,
                   min_angle: float = math.radians(30.0), bone_samples=None,
                   engine: Literal["auto", "triangle", "builtin"] = "auto",
                   max_points: int | None = None, clip_skeleton: bool = False) -> TriMesh:
    """Quality triangle mesh of a 2D shape with the skeleton inside it.

    Every joint is a vertex and every bone is a chain of constrained segments
    through samples along it, so that no triangle straddles a bone and bounded
    biharmonic weights can be pinned exactly on the skeleton.

    Parameters
    ----------
    outline : Mesh, tuple (V, F), (k, 2) array or sequence of (k, 2) arrays
        The shape. A 2D triangle mesh (a :class:`stbs.io.Mesh` or a tuple of
        ``V`` (n, 2) float and ``F`` (f, 3) int): its boundary loops (outer boundary
        and holes) are the outline and *all* its vertices are kept, first and in
        order, so weights computed on the result map straight back
        (``W[:n]``). Or polygons (closed, without repeating the first point; a
        repeated last point is dropped), read with the even-odd rule: a polygon
        inside another is a hole. Pass ``[V[L] for L in boundary_loops(F)]`` to
        remesh a mesh's interior from scratch.
    sk : Skeleton
        A 2D skeleton lying strictly inside the shape.
    max_area : float, optional, keyword-only
        Largest triangle area (in the outline's units squared). None: only the
        angle bound, which grades the mesh from the outline's own edge lengths.
    min_angle : float, keyword-only
        Smallest triangle angle, in radians (default ``radians(30)``), at most
        ``radians(34)`` with Triangle and ``radians(30)`` with the builtin engine.
        Angles of the input (two outline edges, or two bones, meeting at a sharper
        angle) cannot be improved, so triangles in such corners keep them.
    bone_samples : int or (b,) int, optional, keyword-only
        Inner samples per bone before refinement (joints are always vertices);
        refinement may add more, all recorded in ``on_bone``. None: spaced like
        the outline's median edge (or the edge of an equilateral triangle of
        ``max_area``), at least one per bone.
    engine : {"auto", "triangle", "builtin"}, keyword-only
        ``"triangle"``: Shewchuk's Triangle through the ``triangle`` package (the
        ``triangle`` extra; free for research and private use, commercial
        distribution needs the author's permission). ``"builtin"``: Ruppert's
        Delaunay refinement on ``scipy.spatial.Delaunay`` (conforming: outline and
        bones are split until they are Delaunay edges; about 100 times slower, some
        15% more vertices). ``"auto"``: Triangle when installed, else builtin.
    max_points : int, optional, keyword-only
        Safety limit on the number of vertices for the builtin engine, which stops
        with a ``UserWarning`` (and returns the mesh so far) beyond it. None: 100
        per input point plus 8 per ``max_area`` of the shape's area.
    clip_skeleton : bool, keyword-only
        False (default): a joint outside the shape or a bone crossing the outline is
        an error. True: mesh only the bones' parts inside, for skeletons drawn past
        the edge of a traced image. Each bone is cut where it crosses the outline and
        ends a quarter of the sample spacing (at most a tenth of the part) inside,
        further where the outline runs close; joints outside are left out
        (``joint_vertex`` -1) and the cut ends are vertices on the bone (``on_bone``,
        ``t_bone``). A ``UserWarning`` says
        how many bones were cut and how far the farthest joint is outside; a bone
        with no part inside is still an error naming it.

    Returns
    -------
    TriMesh
        ``V`` (n, 2), counter-clockwise ``F`` (f, 3), ``on_bone`` / ``t_bone`` (n,),
        ``joint_vertex`` (j,), ``n_input``. Input points come first and unchanged,
        then the joints, the bone samples, and the Steiner points. Every vertex
        added on a bone satisfies ``V = a_i + t (b_i - a_i)`` to rounding; vertices
        of an input mesh within ``1e-6`` times the shape's size of a bone or joint
        are taken as on it (and kept where they are).

    Raises
    ------
    ValueError
        Bad or degenerate outline (fewer than 3 points, zero area, coincident points,
        self-intersecting or overlapping polygons, a degenerate or pinched input
        mesh, unused vertices), a 3-D outline or skeleton, a joint outside the shape
        or a bone crossing the outline (the message names the bone), bones crossing
        each other, bad options.
    ImportError
        ``engine="triangle"`` without the ``triangle`` package (names the extra).

    Examples
    --------
    >>> import numpy as np, stbs
    >>> from stbs.meshing import triangulate_2d
    >>> square = np.array([[0, 0], [4, 0], [4, 2], [0, 2]], float)
    >>> sk = stbs.Skeleton([[0.5, 1], [2, 1], [3.5, 1]], [[0, 1], [1, 2]])
    >>> m = triangulate_2d(square, sk, max_area=0.1, engine="builtin")
    >>> bool(np.all(m.V[m.joint_vertex] == sk.C))
    True
    """
    _checks.skeleton(sk)
    if sk.dim != 2:
        raise ValueError(f"sk must be a 2-D skeleton for triangulate_2d, got a {sk.dim}-D one "
                         "(C has 3 columns); use tetrahedralize for 3-D shapes")
    engine = _checks.choice("engine", engine, ENGINES_2D)
    min_angle = float(min_angle)
    if not 0.0 <= min_angle <= MAX_MIN_ANGLE:
        hint = f" (it is in radians: did you mean math.radians({min_angle:g})?)" \
            if 1.0 < min_angle <= 60.0 else ""
        raise ValueError(f"min_angle must be in [0, {MAX_MIN_ANGLE:.4f}] radians (34 degrees), "
                         f"got {min_angle}{hint}")
    if max_area is not None:
        max_area = float(max_area)
        if not (np.isfinite(max_area) and max_area > 0):
            raise ValueError(f"max_area must be a positive number or None, got {max_area}")
    if max_points is not None and (not isinstance(max_points, (int, np.integer))
                                   or max_points < 3):
        raise ValueError(f"max_points must be None or an int >= 3, got {max_points!r}")
    counts = check_bone_samples(bone_samples, sk)
    if engine == "auto":
        engine = "triangle" if _optional.available("triangle") else "builtin"
    if engine == "builtin" and min_angle > MAX_MIN_ANGLE_BUILTIN + 1e-12:
        raise ValueError(f"min_angle must be at most {MAX_MIN_ANGLE_BUILTIN:.4f} radians "
                         f"(30 degrees) with the builtin engine, got {min_angle}; install "
                         "the 'triangle' extra for up to 34 degrees")
    out = as_outline(outline)
    L = np.linalg.norm(out.P[out.segments[:, 1]] - out.P[out.segments[:, 0]], axis=1)
    spacing = float(np.median(L))
    if max_area is not None:
        spacing = min(spacing, math.sqrt(4.0 * max_area / math.sqrt(3.0)))
    clip = clip_skeleton_2d(out, sk, 0.25 * spacing) if clip_skeleton else None
    if clip is not None:     # mesh the pieces inside as the skeleton, map back after
        sk, counts = clip.sk, clip.counts(counts)
    check_skeleton_inside(out, sk)
    pslg = build_pslg(out, sk, spacing, counts)
    if engine == "triangle":
        V, F, pb, pt = _triangle(pslg, min_angle=min_angle, max_area=max_area)
    else:
        from ._ruppert import refine

        if max_points is None:
            area = sum(abs(signed_area(Q)) for Q in pslg.polygons)  # an upper bound
            max_points = 100 * pslg.P.shape[0] + (8 * area / max_area if max_area else 0)
        V, F, pb, pt = refine(pslg, min_angle=min_angle, max_area=max_area,
                              max_points=int(max_points))
    return _finish(pslg, V, F, pb, pt, engine, clip)


def _triangle(pslg: PSLG, *, min_angle: float, max_area: float | None):
    """Mesh with Shewchuk's Triangle: a CDT to find the holes, then the quality mesh."""
    tr = _optional.require("triangle")
    markers = np.where(pslg.seg_bone >= 0, pslg.seg_bone + 2, 1).astype(np.int32)
    data = {"vertices": pslg.P, "segments": pslg.S.astype(np.int32),
            "segment_markers": markers[:, None]}
    cdt = tr.triangulate(data, "p")
    T0 = cdt["triangles"]
    C0 = cdt["vertices"][T0].mean(axis=1)
    holes = C0[~points_in_loops(C0, pslg.polygons)]
    if holes.size:
        data["holes"] = holes
    opts = f"pq{math.degrees(min_angle):.6f}"
    if max_area is not None:
        opts += f"a{max_area:.17g}"
    res = tr.triangulate(data, opts)
    V = np.array(res["vertices"], dtype=np.float64)
    F = np.asarray(res["triangles"], dtype=np.int64)
    vm = np.asarray(res["vertex_markers"]).ravel()
    m = pslg.P.shape[0]
    pb = np.concatenate([pslg.point_bone, np.full(V.shape[0] - m, -1, dtype=np.int64)])
    pt = np.concatenate([pslg.point_t, np.full(V.shape[0] - m, np.nan)])
    new = np.arange(m, V.shape[0])
    on = new[vm[new] >= 2]
    if on.size:
        # Steiner points Triangle put on a bone carry its segment's marker. They are
        # left where Triangle computed them, on the segment to rounding: moving them
        # onto the line could fold a triangle next to an input vertex that is only
        # nearly on the bone.
        b = vm[on].astype(np.int64) - 2
        AB = pslg.B[b] - pslg.A[b]
        pb[on] = b
        pt[on] = np.einsum("ij,ij->i", V[on] - pslg.A[b], AB) / np.einsum("ij,ij->i", AB, AB)
    return V, F, pb, pt


def _finish(pslg: PSLG, V, F, pb, pt, engine: str, clip: Clip | None = None) -> TriMesh:
    m = pslg.P.shape[0]
    if not np.array_equal(V[:m], pslg.P):
        raise RuntimeError(f"{engine} mesher moved input points (internal error)")
    used = np.zeros(V.shape[0], dtype=bool)
    used[F.ravel()] = True
    if not used.all():
        raise RuntimeError(f"{engine} mesher left {int((~used).sum())} vertices outside every "
                           "triangle (internal error)")
    # Any other Steiner point that landed on a bone (e.g. where a bone ends) is recorded.
    free = np.flatnonzero(pb < 0)
    free = free[(free >= pslg.n_input) & ~np.isin(free, pslg.joint_vertex)]
    if free.size:
        i, t, d = bone_distance(V[free], pslg.A, pslg.B)
        on = (d <= REL_TOL * scale_of(V)) & (t > 0) & (t < 1)
        pb[free[on]], pt[free[on]] = i[on], t[on]
    area = triangle_areas(V, F)
    F = np.where((area < 0)[:, None], F[:, [0, 2, 1]], F)
    area = np.abs(area)
    if area.min() <= 1e-14 * scale_of(V) ** 2:
        raise RuntimeError(f"{engine} mesher produced a degenerate triangle (internal error)")
    pt = np.where(pb >= 0, pt, np.nan)
    joint_vertex = pslg.joint_vertex.copy()
    if clip is not None:
        pb, pt, joint_vertex = clip.to_bones(pb, pt, joint_vertex)
    arrays = dict(V=V, F=F.astype(np.int64), on_bone=pb.astype(np.int64),
                  t_bone=pt.astype(np.float64), joint_vertex=joint_vertex)
    for a in arrays.values():
        a.setflags(write=False)
    return TriMesh(**arrays, n_input=pslg.n_input, engine=engine)
