"""3D: a volume mesh for the weights of any surface, by generalised winding numbers.

Real characters are rarely closed, manifold surfaces: they come in parts (body, eyes,
teeth, clothes), with holes (a neck without a head, open sleeves), self-intersections
(clothes through skin) and non-manifold edges, and their skeletons poke out (leaf-bone
tails, a root joint on the floor). :func:`volume_mesh` meshes the *inside* of such a
surface, defined by its generalised winding number (Jacobson et al. 2013: > 1/2
inside), at a resolution of its own:

1. a spacing: cubes of side ``size`` over the shape, halved (up to ``refine`` times)
   where bones lie close together or the shape is thin, graded 2:1;
2. points: the skeleton's joints and bone samples that lie inside, the surface sampled
   at the local spacing (its vertices and points on its large triangles, one per
   voxel), and a body-centred cubic lattice inside at the local spacing;
3. their Delaunay tetrahedralization (:class:`scipy.spatial.Delaunay`);
4. the tetrahedra whose centroid has winding number > 1/2 are kept (fast winding
   numbers, :class:`stbs.geometry.WindingTree`), slivers (a dihedral angle under 5
   degrees) left out, every skeleton point kept in some tetrahedron, and parts that
   hold no skeleton point dropped.

The surface's own vertices are *not* vertices of the volume mesh: its cost is set by
``size`` (by default chosen for about :data:`DEFAULT_VERTICES` vertices), not by the
surface's resolution, and weights reach the surface by interpolation
(:meth:`VolumeMesh.interpolation`). The skeleton's points are vertices, so the
weights' boundary conditions are exact where the skeleton is inside the shape.
docs/bbw.md ("Real surfaces") says why each step is as it is, with measurements.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.spatial import Delaunay, cKDTree

from .. import _checks
from ..skeleton import Skeleton
from ._geometry import scale_of, tet_volumes
from ._samples import MAX_AUTO_SAMPLES, bone_label, sample_skeleton
from .tetrahedra import _min_dihedral

__all__ = ["volume_mesh", "VolumeMesh", "DEFAULT_VERTICES"]

#: Vertices the volume mesh gets by default (``size`` is chosen for about this many).
DEFAULT_VERTICES = 12_000
#: Most halvings of the spacing where the skeleton is dense or the shape thin.
MAX_REFINE = 2
#: Winding number above which a point is inside.
INSIDE = 0.5
#: A bone wholly outside the shape but within this many times the spacing of it holds
#: the volume vertices nearest it (a toe bone on the sole); farther (an IK pole target)
#: it gets no bone weight.
REACH = 2.0
#: Tetrahedra with a dihedral angle below this (degrees) are slivers, left out.
SLIVER_DEGREES = 5.0
#: Bones named in one warning; the rest are counted.
_NAMED = 8


@dataclass(frozen=True, eq=False)
class VolumeMesh:
    """A tetrahedral mesh of the inside of a surface, with the skeleton's points inside.

    Attributes
    ----------
    V : (m, 3) float64
        Vertices: the skeleton points inside the shape, the surface samples, then the
        lattice points.
    T : (t, 4) int64
        Tetrahedra, positively oriented.
    on_bone : (m,) int64
        The bone a vertex lies on (0 < t < 1), -1 elsewhere (joints included).
    t_bone : (m,) float64
        Its parameter along that bone; NaN where ``on_bone`` is -1.
    joint_vertex : (j,) int64
        Each joint's vertex, -1 for a joint outside the shape.
    size : float
        The target edge length the mesh was made with.
    kind : (m,) int8
        Where each vertex comes from: 0 the skeleton, 1 the surface, 2 the lattice.
    bones_outside : dict
        ``{bone: (share, farthest, nearest)}`` for the bones with points outside the
        shape: the share of their points left out, and how far outside the farthest
        and the nearest of those are.
    """

    V: np.ndarray
    T: np.ndarray
    on_bone: np.ndarray
    t_bone: np.ndarray
    joint_vertex: np.ndarray
    size: float
    kind: np.ndarray
    bones_outside: dict = field(default_factory=dict)

    def __repr__(self) -> str:
        return (f"VolumeMesh({self.V.shape[0]} vertices, {self.T.shape[0]} tetrahedra, "
                f"size {self.size:.3g}, {int((self.on_bone >= 0).sum())} bone samples, "
                f"{int((self.joint_vertex >= 0).sum())} of {self.joint_vertex.size} joints)")

    def interpolation(self, P) -> sp.csr_array:
        """Linear interpolation from the mesh's vertices to points ``P`` (p, 3).

        A point in a tetrahedron gets its barycentric coordinates; a point outside the
        mesh (a surface vertex just outside the meshed inside, a part left out) those
        of the nearest point of the nearest tetrahedron. Rows are >= 0 and sum to 1, so
        interpolated weights keep their bounds and partition of unity.

        Returns
        -------
        (p, m) sparse array, 4 entries per row.
        """
        P = _checks.real_array("P", P, ndim=2, shape=(None, 3))
        return _interpolation(self.V, self.T, P)

    def bone_points(self, sk: Skeleton) -> np.ndarray:
        """(b,) int: how many of the mesh's vertices lie on each bone (joints included)."""
        count = np.bincount(self.on_bone[self.on_bone >= 0], minlength=sk.n_bones)
        has = (self.joint_vertex >= 0)[sk.BE]
        return count + has.sum(axis=1)

    def boundary_conditions(self, sk: Skeleton) -> tuple[np.ndarray, np.ndarray, dict]:
        """Bone weights' constraints: ``b`` (k,), ``bc`` (k, #bones), and the stand-ins.

        The skeleton's vertices hold their bones (``1/k`` each at a joint of k bones,
        as :func:`stbs.weights.boundary_conditions`). A bone with no point inside the
        shape is held at the free vertices nearest to points along it when it lies
        within :data:`REACH` times the spacing of the surface; farther, it is held
        nowhere (its weights are 0). The third value maps the bones held so to the
        distance of their nearest vertex, in the shape's units.

        Raises
        ------
        ValueError
            A bone that nothing can hold (the mesh has no free vertex), naming it.
        """
        from ..weights.boundary import segment_distances

        m, nb = self.V.shape[0], sk.n_bones
        sk_v = np.flatnonzero((self.on_bone >= 0) | np.isin(np.arange(m), self.joint_vertex))
        D = segment_distances(self.V[sk_v], sk.A, sk.B)
        tol = 1e-9 * scale_of(self.V)
        hold = np.zeros((m, nb))
        hold[sk_v] = D <= tol
        # A skeleton vertex always holds its own bone (rounding in the sample's position).
        inner = np.flatnonzero(self.on_bone >= 0)
        hold[inner, self.on_bone[inner]] = 1.0
        stand_in = {}
        empty = np.flatnonzero(~hold.any(axis=0))
        if empty.size:
            free = np.flatnonzero(~hold.any(axis=1))
            if free.size == 0:
                raise ValueError(f"sk: {bone_label(sk, int(empty[0]))} lies outside the shape "
                                 "and the volume mesh has no free vertex to hold it")
            tree = cKDTree(self.V[free])
            for i in empty.tolist():
                if self.bones_outside.get(i, (1.0, 0.0, 0.0))[2] > REACH * self.size:
                    continue            # far outside (an IK target): no weight
                k = max(2, min(16, int(np.ceil(sk.lengths[i] / self.size)) + 1))
                S = sk.A[i] + np.linspace(0.0, 1.0, k)[:, None] * (sk.B[i] - sk.A[i])
                d, j = tree.query(S)
                best = np.flatnonzero(d <= d.min() + 0.5 * self.size)
                hold[free[j[best]], i] = 1.0
                stand_in[i] = float(d.min())
        b = np.flatnonzero(hold.any(axis=1))
        bc = hold[b] / hold[b].sum(axis=1, keepdims=True)
        return b.astype(np.int64), bc, stand_in


# --------------------------------------------------------------------------------------
def volume_mesh(V, F, sk: Skeleton, *, size: float | None = None,
                vertices: int = DEFAULT_VERTICES, refine: int = MAX_REFINE,
                progress=None) -> VolumeMesh:
    """Tetrahedral mesh of the inside of any triangle surface, skeleton points inside.

    Parameters
    ----------
    V : (n, 3) float
        Surface vertices.
    F : (f, 3) int
        Triangles: open, several parts, self-intersecting and non-manifold are all fine.
        Each connected part is oriented outwards by its signed volume first.
    sk : Skeleton
        A 3D skeleton. Its parts outside the shape are left out, with a
        ``UserWarning`` naming the bones.
    size : float, optional, keyword-only
        Target edge length, in the surface's units. None: chosen so that the mesh
        has about ``vertices`` vertices (from the shape's volume and area, not from
        its vertex count).
    vertices : int, keyword-only
        The vertex budget ``size`` is chosen for (ignored when ``size`` is given).
    refine : int, keyword-only
        Most times the spacing is halved where the skeleton's bones lie close together
        (hands, face) or the shape is thin (fingers, ears), 0 for a uniform mesh.
    progress : callable, optional, keyword-only
        ``progress(done, total)`` as each of the ``total`` steps (size, grading,
        samples, lattice, Delaunay, tetrahedra inside) starts, and ``(total, total)``
        at the end. Raise any exception from it to cancel: it propagates.

    Returns
    -------
    VolumeMesh

    Raises
    ------
    ValueError
        Bad arrays or options; a skeleton with no point inside the shape (winding
        number above 1/2), e.g. a surface that encloses nothing or a skeleton in other
        coordinates.

    Examples
    --------
    >>> import stbs
    >>> from stbs.meshing import volume_mesh
    >>> V, F, sk, _ = stbs.shapes.cigar(12)
    >>> vm = volume_mesh(V, F, sk, vertices=2000)
    >>> 1500 < vm.V.shape[0] < 2500, bool((vm.V[vm.joint_vertex] == sk.C).all())
    (True, True)
    >>> P = vm.interpolation(V)          # the surface's vertices from the volume's
    >>> bool(abs(P.sum(axis=1) - 1).max() < 1e-12 and abs(P @ vm.V - V).max() < vm.size)
    True
    """
    _checks.skeleton(sk)
    if sk.dim != 3:
        raise ValueError(f"sk must be a 3-D skeleton, got a {sk.dim}-D one")
    V = _checks.real_array("V", V, ndim=2, shape=(None, 3))
    F = _checks.index_array("F", F, ndim=2, shape=(None, 3))
    if F.size and (F.min() < 0 or F.max() >= V.shape[0]):
        bad = int(F.min()) if F.min() < 0 else int(F.max())
        raise ValueError(f"F must hold vertex indices in 0..{V.shape[0] - 1}, got {bad}")
    F = F[(F[:, 0] != F[:, 1]) & (F[:, 1] != F[:, 2]) & (F[:, 2] != F[:, 0])]
    if F.shape[0] == 0:
        raise ValueError("F must hold at least one non-degenerate triangle")
    if vertices is None or int(vertices) < 100:
        raise ValueError(f"vertices must be an int >= 100, got {vertices!r}")
    if not (isinstance(refine, (int, np.integer)) and 0 <= refine <= 5):
        raise ValueError(f"refine must be an int in 0..5, got {refine!r}")
    from ..geometry import WindingTree

    steps = 6
    say = progress or (lambda done, total: None)
    say(0, steps)
    F = _oriented(V, F)
    wind = WindingTree(V, F)
    lo, hi = V[np.unique(F)].min(axis=0), V[np.unique(F)].max(axis=0)
    if size is None:
        size = _default_size(V, F, wind, sk, lo, hi, int(vertices), int(refine))
    else:
        size = float(size)
        if not (np.isfinite(size) and size > 0):
            raise ValueError(f"size must be a positive number, got {size!r}")
    h = size
    if np.prod(np.floor((hi - lo) / h) + 2) > 30_000_000:
        raise ValueError(f"size={size:.6g} asks for a lattice of over 60 million points for "
                         f"a shape of extent {np.round(hi - lo, 6).tolist()}; pass a larger size")

    # 1. the grading: cubes of side h over the shape, each refined 2^level times where
    # the skeleton is dense (hands, face) or the shape thin (fingers, ears)
    say(1, steps)
    grid, _, _ = _graded(wind, sk, lo, hi, h, int(refine))
    say(2, steps)
    # 2. the skeleton's points, spaced like the cubes they are in; those inside kept
    skp = sample_skeleton(sk, h, _counts(sk.lengths, _bone_spacing(sk, grid)))
    inside_sk = wind(skp.X) > INSIDE
    # exact duplicates (an offset child starting on a parent's sample) are one vertex
    _, once = np.unique(skp.X, axis=0, return_index=True)
    dup = np.ones(skp.X.shape[0], dtype=bool)
    dup[once] = False
    keep_sk = inside_sk & ~dup
    outside = _outside_report(sk, skp, inside_sk, V, F, h)
    if not keep_sk.any():
        raise ValueError("sk: no joint or bone of the skeleton lies inside the shape (winding "
                         "number > 1/2); check that the skeleton and the mesh use the same "
                         "coordinates")
    K = skp.X[keep_sk]
    sk_tree = cKDTree(K)
    # 3. the surface, one sample per voxel of its cube's spacing; none closer than a
    # third of the spacing to a skeleton point
    S = _surface_samples(V, F, grid)
    S = S[sk_tree.query(S)[0] > grid.spacing(S) / 3]
    # 4. the cubes' body-centred cubic lattices inside, away from the surface and the
    # skeleton (by half their spacing)
    say(3, steps)
    L = grid.lattice()
    hL = grid.spacing(L)
    far = sk_tree.query(L, distance_upper_bound=h)[0] > 0.5 * hL
    L, hL = L[far], hL[far]
    dense = _surface_samples(V, F, grid, finer=3)
    d = cKDTree(dense).query(L, distance_upper_bound=0.45 * h)[0]
    L = L[d > 0.45 * hL]
    L = L[wind(L) > INSIDE]
    ns, nk = S.shape[0], K.shape[0]
    X = np.vstack([K, S, L])

    # 5. Delaunay, and the tetrahedra inside
    say(4, steps)
    T = Delaunay(X).simplices.astype(np.int64)
    say(5, steps)
    w = wind(X[T].mean(axis=1))
    keep = (w > INSIDE) & ~_flat(X, T)
    # Slivers (nearly flat tetrahedra, common in Delaunay meshes of surface samples)
    # are left out: their cotangent weights are huge and of both signs, and would
    # spoil the conditioning of the bilaplacian (it squares the Laplacian's); their
    # volume is nearly 0, so the mesh loses nothing.
    quality = np.zeros(T.shape[0])
    cand = np.flatnonzero(keep | ((T < nk).any(axis=1) & ~_flat(X, T)))
    quality[cand] = _min_dihedral(X, T[cand])
    keep &= quality >= np.radians(SLIVER_DEGREES)
    # every skeleton point in some tetrahedron: the best of its most-inside ones
    used = np.zeros(X.shape[0], dtype=bool)
    used[T[keep].ravel()] = True
    orphan = np.flatnonzero(~used[:nk])
    if orphan.size:
        t_of = np.repeat(np.arange(T.shape[0]), 4)
        v_of = T.ravel()
        sel = np.isin(v_of, orphan) & (quality[t_of] > 0)
        ct, cv = t_of[sel], v_of[sel]
        score = np.minimum(w[ct], 1.0) + quality[ct]     # inside first, then the best shape
        order = np.lexsort((-score, cv))
        firsts = np.unique(cv[order], return_index=True)[1]
        keep[ct[order][firsts]] = True
    kept = np.flatnonzero(keep)
    # 6. parts without a skeleton point are left out (their surface interpolates from
    # the nearest part that has one)
    kept = kept[_with_skeleton(T[kept], X.shape[0], nk)]
    Tk = T[kept]
    used = np.zeros(X.shape[0], dtype=bool)
    used[Tk.ravel()] = True
    remap = np.cumsum(used) - 1
    Xm, Tm = X[used], remap[Tk]
    vol = tet_volumes(Xm, Tm)
    Tm = np.where((vol < 0)[:, None], Tm[:, [0, 1, 3, 2]], Tm)
    m = Xm.shape[0]
    # the skeleton's record
    on_bone = np.full(m, -1, dtype=np.int64)
    t_bone = np.full(m, np.nan)
    kidx = np.flatnonzero(keep_sk)
    in_mesh = used[:nk]
    inner = skp.bone[kidx] >= 0
    sel = in_mesh & inner
    on_bone[remap[np.flatnonzero(sel)]] = skp.bone[kidx[sel]]
    t_bone[remap[np.flatnonzero(sel)]] = skp.t[kidx[sel]]
    joint_vertex = np.full(sk.n_joints, -1, dtype=np.int64)
    sel = in_mesh & ~inner
    joint_vertex[kidx[sel]] = remap[np.flatnonzero(sel)]
    kind = np.repeat(np.array([0, 1, 2], dtype=np.int8), [nk, ns, X.shape[0] - nk - ns])[used]
    for a in (Xm, Tm, on_bone, t_bone, joint_vertex, kind):
        a.setflags(write=False)
    say(steps, steps)
    return VolumeMesh(V=Xm, T=Tm, on_bone=on_bone, t_bone=t_bone,
                      joint_vertex=joint_vertex, size=float(h), kind=kind,
                      bones_outside=outside)


# --------------------------------------------------------------------------------------
def _oriented(V, F):
    """Each connected part of the surface turned to face outwards.

    Parts are found after merging vertices at the same position (assets split them at
    texture seams). A part whose signed volume, about its own centroid, is clearly
    negative (below -0.2 of the sum of the absolute volumes: inward-facing) is
    reversed; open sheets, whose volume says nothing, are left as they are.
    """
    from scipy.sparse.csgraph import connected_components

    _, weld = np.unique(V, axis=0, return_inverse=True)
    Fw = np.ravel(weld)[F]
    n = int(Fw.max()) + 1
    adj = sp.coo_array((np.ones(3 * F.shape[0]), (Fw.ravel(), np.roll(Fw, 1, axis=1).ravel())),
                       shape=(n, n))
    k, comp = connected_components(adj, directed=False)
    part = comp[Fw[:, 0]]
    P = V[F]
    centre = np.zeros((k, 3))
    for d in range(3):
        centre[:, d] = np.bincount(part, weights=P[:, :, d].mean(axis=1), minlength=k)
    centre /= np.maximum(np.bincount(part, minlength=k), 1)[:, None]
    P = P - centre[part][:, None, :]
    six = np.einsum("ij,ij->i", P[:, 0], np.cross(P[:, 1], P[:, 2]))
    vol = np.bincount(part, weights=six, minlength=k)
    mag = np.bincount(part, weights=np.abs(six), minlength=k)
    flip = (vol < -0.2 * mag)[part]
    return np.where(flip[:, None], F[:, ::-1], F)


def _default_size(V, F, wind, sk: Skeleton, lo, hi, budget: int, refine: int) -> float:
    """The coarsest spacing h whose graded mesh has about ``budget`` vertices.

    Measured on real characters, the lattice inside has about 2 points per cube of the
    local spacing s less a shell of 0.45 s under the surface, the surface about 1.1
    samples per s^2 (both within 15 %); the volume is found by winding numbers on a
    48^3 grid, and s by the grading h gives (:func:`_graded`), so the cost follows the
    shape and its skeleton, not the surface's vertex count.
    """
    ext = np.maximum(hi - lo, 1e-12 * scale_of(V))
    g = 48
    axes = [lo[d] + (np.arange(g) + 0.5) / g * ext[d] for d in range(3)]
    G = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    G = G[wind(G) > INSIDE]
    dv = float(np.prod(ext)) / g ** 3
    P = V[F]
    At = 0.5 * np.linalg.norm(np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]), axis=1)
    Ct = P.mean(axis=1)
    volume, area = dv * G.shape[0], float(At.sum())

    def count(h, graded: bool):
        if graded:
            grid, skp, inside = _graded(wind, sk, lo, hi, h, refine)
            sG, sT = grid.spacing(G), grid.spacing(Ct)
            n_sk = int(_counts(sk.lengths, _bone_spacing(sk, grid)).sum()) + sk.n_joints
        else:
            sG, sT, n_sk = h, h, int(_counts(sk.lengths, h).sum()) + sk.n_joints
        lattice = float(np.sum(2.0 * dv / np.broadcast_to(sG, (G.shape[0],)) ** 3))
        shell = float(np.sum(0.9 * At / sT ** 2))
        return max(lattice - shell, 0.1 * lattice) + 1.1 / 0.9 * shell + n_sk

    def solve(a, b, graded, steps):
        for _ in range(steps):
            mid = np.sqrt(a * b)
            a, b = (mid, b) if count(mid, graded) > budget else (a, mid)
        return float(b)

    # uniform first (a lower bound: refinement only adds points), then graded
    big = 2.0 * float(np.linalg.norm(ext))
    h0 = solve(max(((volume + area * big) / budget) ** (1 / 3) * 1e-3, 1e-12 * big), big,
               False, 60)
    return solve(h0, 2 ** refine * h0, True, 6) if refine else h0


def _graded(wind, sk: Skeleton, lo, hi, h, refine):
    """The cubes of side h over the box, graded by the skeleton (:func:`_desired_size`);
    with the first skeleton samples and which of them are inside."""
    grid = _Grid(lo, hi, h)
    first = sample_skeleton(sk, h, _counts(sk.lengths, h))
    inside = wind(first.X) > INSIDE
    grid.grade(_desired_size(sk, first, inside, wind, h), first.X[inside], refine)
    return grid, first, inside


def _counts(lengths, spacing) -> np.ndarray:
    """Inner samples per bone at most ``spacing`` apart; at least 3, so that a bone
    partly outside the shape keeps two points inside."""
    return np.clip(np.ceil(lengths / spacing).astype(np.int64) - 1, 3, MAX_AUTO_SAMPLES)


def _desired_size(sk: Skeleton, skp, inside, wind, h) -> np.ndarray:
    """The spacing wanted at each skeleton point inside the shape: a third of the
    distance to the nearest bone that is not its own, its parent or its child, nor
    shares a joint with it (fingers side by side), and the shape's thickness there
    (the nearest of 14 probes, at h/8 ... h, found outside); at most ``h``."""
    from ..weights.boundary import segment_distances

    X = skp.X[inside]
    if X.shape[0] == 0:
        return np.zeros(0)
    j, b = sk.n_joints, sk.n_bones
    # the bones a point belongs to (a joint: all bones meeting there)
    bone = skp.bone[inside]
    own = np.zeros((X.shape[0], b), dtype=bool)
    own[np.flatnonzero(bone >= 0), bone[bone >= 0]] = True
    joint = np.flatnonzero(inside[:j])
    own[np.flatnonzero(bone < 0)] = (sk.BE[None, :, :] == joint[:, None, None]).any(axis=2)
    near = (sk.BE[:, None, :, None] == sk.BE[None, :, None, :]).any(axis=(2, 3))
    has = np.flatnonzero(sk.parents >= 0)
    near[has, sk.parents[has]] = near[sk.parents[has], has] = True
    mine = (own.astype(np.int64) @ near.astype(np.int64)) > 0
    D = segment_distances(X, sk.A, sk.B)
    D[mine] = np.inf
    apart = D.min(axis=1) / 3.0
    dirs = np.vstack([np.eye(3), -np.eye(3),
                      np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1).T
                      / np.sqrt(3.0)])
    radii = h * np.array([0.125, 0.25, 0.5, 1.0])
    Q = X[:, None, None, :] + radii[None, :, None, None] * dirs[None, None, :, :]
    out = (wind(Q.reshape(-1, 3)) <= INSIDE).reshape(X.shape[0], radii.size, -1).any(axis=2)
    thick = np.where(out.any(axis=1), radii[np.argmax(out, axis=1)], h)
    return np.minimum(np.minimum(apart, thick), h)


class _Grid:
    """Cubes of side ``h`` over the box ``[lo, hi]``, each with a refinement level
    (its spacing is ``h / 2^level``); neighbouring cubes differ by one level at most."""

    def __init__(self, lo, hi, h):
        # a fixed offset keeps lattice points off the axis-aligned planes of the input
        self.origin = lo - 0.5 * h + 0.0371 * h
        self.h = h
        self.shape = tuple(int(x) for x in np.floor((hi - self.origin) / h).astype(np.int64) + 2)
        self.level = np.zeros(self.shape, dtype=np.int64)

    def grade(self, size, P, refine: int) -> None:
        """Refine the cubes holding (or within reach of) points ``P`` that want
        ``size``; then balance the levels."""
        if refine == 0 or P.shape[0] == 0:
            return
        want = np.clip(np.ceil(np.log2(self.h / np.maximum(size, 1e-300))), 0, refine)
        want = want.astype(np.int64)
        cell = self.cell(P)
        np.maximum.at(self.level, tuple(cell.T), want)
        # 2:1 balance, and the fine cubes reach a cube beyond the points' own
        from scipy.ndimage import grey_dilation

        for _ in range(refine + 1):
            grown = grey_dilation(self.level, size=(3, 3, 3)) - 1
            if np.all(grown <= self.level):
                break
            np.maximum(self.level, grown, out=self.level)

    def cell(self, P) -> np.ndarray:
        c = np.floor((P - self.origin) / self.h).astype(np.int64)
        return np.clip(c, 0, np.array(self.shape) - 1)

    def spacing(self, P) -> np.ndarray:
        """(p,) the spacing of the cube each point lies in."""
        return self.h / 2.0 ** self.level[tuple(self.cell(P).T)]

    def lattice(self) -> np.ndarray:
        """The body-centred cubic lattice of every cube at its spacing (each cube holds
        its corner and centre points on its lower faces, not on its upper ones)."""
        out = []
        for lv in np.unique(self.level).tolist():
            cubes = np.argwhere(self.level == lv)
            k = 2 ** lv
            a = np.indices((k, k, k)).reshape(3, -1).T
            offs = np.vstack([a, a + 0.5]) * (self.h / k)
            corner = self.origin + cubes * self.h
            out.append((corner[:, None, :] + offs[None]).reshape(-1, 3))
        return np.vstack(out)


def _bone_spacing(sk: Skeleton, grid: _Grid) -> np.ndarray:
    """(b,) the finest spacing of the cubes each bone passes through."""
    t = np.linspace(0.0, 1.0, 33)
    P = sk.A[:, None, :] + t[None, :, None] * (sk.B - sk.A)[:, None, :]
    return grid.spacing(P.reshape(-1, 3)).reshape(sk.n_bones, -1).min(axis=1)


def _surface_samples(V, F, grid: _Grid, finer: int = 1) -> np.ndarray:
    """Points on the surface about the local spacing (over ``finer``) apart: its
    vertices and barycentric grids on its longer triangles, then one per voxel of
    that spacing (the one nearest the voxel's centre)."""
    used = np.unique(F)
    pts = [V[used]]
    P = V[F]
    longest = np.max([np.linalg.norm(P[:, i] - P[:, (i + 1) % 3], axis=1)
                      for i in range(3)], axis=0)
    m = np.ceil(finer * longest / grid.spacing(P.mean(axis=1))).astype(np.int64)
    for k in np.unique(m[m >= 2]).tolist():
        ij = np.array([(i, j) for i in range(k + 1) for j in range(k + 1 - i)
                       if not ((i == 0 and j in (0, k)) or (i == k and j == 0))], float) / k
        bary = np.c_[1.0 - ij.sum(axis=1), ij]
        pts.append(np.einsum("pc,tcd->tpd", bary, P[m == k]).reshape(-1, 3))
    X = np.vstack(pts)
    s = grid.spacing(X) / finer
    cell = np.floor((X - grid.origin) / s[:, None]).astype(np.int64)
    centre = grid.origin + (cell + 0.5) * s[:, None]
    d = np.sum((X - centre) ** 2, axis=1)
    lv = np.round(np.log2(grid.h / (finer * s))).astype(np.int64)
    cell -= cell.min(axis=0)
    key = np.ravel_multi_index(np.c_[lv, cell].T, tuple(np.c_[lv, cell].max(axis=0) + 1))
    order = np.lexsort((d, key))
    first = np.ones(order.size, dtype=bool)
    first[1:] = key[order][1:] != key[order][:-1]
    return X[order[first]]


def _flat(X, T) -> np.ndarray:
    """Tetrahedra of (nearly) zero volume for their size: Delaunay's on coplanar points."""
    Pt = X[T]
    longest = np.max([np.linalg.norm(Pt[:, i] - Pt[:, j], axis=1)
                      for i, j in ((0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3))], axis=0)
    return np.abs(tet_volumes(X, T)) <= 1e-9 * longest ** 3


def _with_skeleton(T, n, nk) -> np.ndarray:
    """(t,) bool: tetrahedra in a connected part holding one of the first ``nk`` points."""
    from scipy.sparse.csgraph import connected_components

    adj = sp.coo_array((np.ones(3 * T.shape[0]), (T[:, :3].ravel(), T[:, 1:].ravel())),
                       shape=(n, n))
    _, comp = connected_components(adj, directed=False)
    used = np.zeros(n, dtype=bool)
    used[T.ravel()] = True
    good = np.zeros(int(comp.max()) + 1, dtype=bool)
    good[comp[np.flatnonzero(used[:nk])]] = True
    return good[comp[T[:, 0]]]


def _outside_report(sk: Skeleton, skp, inside: np.ndarray, V, F, h) -> dict:
    """Warn about the bones with points outside the shape; return them as
    ``{bone: (share of its points outside, farthest distance, nearest distance)}``
    (distances of the points outside from the surface)."""
    if inside.all():
        return {}
    from ._kernels import SurfaceIndex

    j = sk.n_joints
    out: dict[int, tuple[float, float, float]] = {}
    dist = np.zeros(skp.X.shape[0])
    bad = np.flatnonzero(~inside)
    dist[bad] = SurfaceIndex(V, F).closest_side(skp.X[bad], np.inf)[0]
    for i in range(sk.n_bones):
        pts = np.concatenate([sk.BE[i], j + np.flatnonzero(skp.bone[j:] == i)])
        lost = ~inside[pts]
        if lost.any():
            d = dist[pts][lost]
            out[i] = (float(lost.mean()), float(d.max()), float(d.min()))
    near = [i for i, (s, _, d) in out.items() if s == 1.0 and d <= REACH * h]
    far = [i for i, (s, _, d) in out.items() if s == 1.0 and d > REACH * h]
    parts = [f"{bone_label(sk, i)}: {100 * s:.0f} % outside, up to {d:.3g}"
             for i, (s, d, _) in list(out.items())[:_NAMED]]
    more = f"; and {len(out) - _NAMED} more" if len(out) > _NAMED else ""
    warnings.warn(f"volume mesh: {len(out)} bone(s) leave the shape ({'; '.join(parts)}{more};"
                  f" distances in the mesh's units, shape size {scale_of(V):.3g}); the "
                  "weights are held by their parts inside"
                  + (f"; the {len(near)} wholly outside but near it hold the volume's vertices "
                     "nearest them" if near else "")
                  + (f"; the {len(far)} farther than {REACH:g} times the spacing ({h:.3g}) get "
                     "no bone weight (" + ", ".join(bone_label(sk, i) for i in far[:_NAMED])
                     + (", ..." if len(far) > _NAMED else "") + ")" if far else "")
                  + ("; wholly outside, they keep the projection (eq. 8) as endpoint weights"
                     if near or far else ""), UserWarning, stacklevel=_stacklevel())
    return out


def _stacklevel() -> int:
    """The stack level of the first frame outside stbs (a warning names the user's
    call, not ours)."""
    import sys

    f, level = sys._getframe(1), 1
    while f is not None and f.f_globals.get("__name__", "").startswith("stbs."):
        f, level = f.f_back, level + 1
    return level


def _interpolation(Vm, Tm, P, chunk: int = 20_000) -> sp.csr_array:
    """(p, m): each point's barycentric coordinates in the tetrahedron holding it, or
    the clamped ones of the nearest point of the nearest tetrahedron (see
    :func:`_nearest_tets`), four per row, >= 0 and summing to 1."""
    p, m = P.shape[0], Vm.shape[0]
    cen = Vm[Tm].mean(axis=1)
    tree = cKDTree(cen)
    # columns: the edges from the fourth corner, so b = Ainv (x - v3)
    Ainv = np.linalg.inv(np.swapaxes(Vm[Tm[:, :3]] - Vm[Tm[:, 3]][:, None, :], 1, 2))
    tet = np.zeros(p, dtype=np.int64)
    bary = np.zeros((p, 4))
    tol = 1e-12 * scale_of(Vm)
    for s in range(0, p, chunk):
        Q = P[s:s + chunk]
        t, b, d = _nearest_tets(Vm, Tm, Q, tree, Ainv, k=16)
        # not inside one of the 16 nearest: look wider (long thin tetrahedra)
        wide = np.flatnonzero(d > tol)
        if wide.size:
            t2, b2, d2 = _nearest_tets(Vm, Tm, Q[wide], tree, Ainv, k=64)
            better = d2 < d[wide]
            t[wide[better]], b[wide[better]] = t2[better], b2[better]
        tet[s:s + chunk], bary[s:s + chunk] = t, b
    rows = np.repeat(np.arange(p), 4)
    return sp.csr_array((bary.ravel(), (rows, Tm[tet].ravel())), shape=(p, m))


def _nearest_tets(Vm, Tm, P, tree, Ainv, k: int):
    """Among the ``k`` tetrahedra with the nearest centroids: the one whose nearest
    point to each of ``P`` (approximated by clamping the barycentric coordinates) is
    nearest. Returns (tetrahedra, coordinates, distances); a point inside one of
    them gets it, with its exact coordinates and distance 0."""
    k = min(k, Tm.shape[0])
    _, cand = tree.query(P, k=k)
    cand = cand.reshape(P.shape[0], k)
    best_d = np.full(P.shape[0], np.inf)
    best_t = np.zeros(P.shape[0], dtype=np.int64)
    best_b = np.zeros((P.shape[0], 4))
    for c in range(k):
        t = cand[:, c]
        b3 = np.einsum("pij,pj->pi", Ainv[t], P - Vm[Tm[t, 3]])
        b = np.clip(np.c_[b3, 1.0 - b3.sum(axis=1)], 0.0, None)
        b /= b.sum(axis=1, keepdims=True)
        d = np.linalg.norm(np.einsum("pc,pcd->pd", b, Vm[Tm[t]]) - P, axis=1)
        better = d < best_d
        best_d[better], best_t[better], best_b[better] = d[better], t[better], b[better]
    return best_t, best_b, best_d
