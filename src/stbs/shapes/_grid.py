"""Rigged shapes on grids: a cigar (an ellipsoid with one bone), a box, a two-bone bar.

:func:`cigar`, :func:`box` and :func:`bar` return ``(V, F, sk, W)``: rest positions
(n, 3) float64, outward oriented triangles (f, 3) int64, the :class:`stbs.Skeleton`
and bone weights (n, b) float64 (rows sum to 1). :func:`box_tets` gives a box as
tetrahedra, :func:`sections` the cross-sections of a grid shape.
"""

from __future__ import annotations

import numpy as np

from .. import _checks
from ..geometry import tet_volumes, unique_rows
from ..skeleton import Skeleton

__all__ = ["cigar", "box", "bar", "sections", "box_tets"]


def _positive_int(name: str, x, minimum: int = 1) -> int:
    if isinstance(x, bool) or not isinstance(x, (int, np.integer)) or x < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {x!r}")
    return int(x)


def cigar(n: int = 24, *, half_length: float = 2.0, radius: float = 0.5,
          bone_half_length: float = 1.0):
    """An ellipsoid along x with one bone inside it (the paper's Fig. 2).

    The bone runs from ``(-bone_half_length, 0, 0)`` to ``(bone_half_length, 0, 0)``;
    the shape reaches ``half_length`` past the centre on both sides, so with the
    defaults a part of length 1 lies beyond each end of the bone.

    Parameters
    ----------
    n : int
        Number of rings from pole to pole (>= 3); ``2 n`` vertices around each ring.
    half_length, radius : float
        Semi-axes of the ellipsoid along x and across.
    bone_half_length : float
        Half the bone's length; must be less than ``half_length``.

    Returns
    -------
    V : (2 + (n - 1) 2n, 3) float64
    F : (4 n (n - 1), 3) int64
    sk : Skeleton
        Joints ``[-bone_half_length, 0, 0]`` and ``[bone_half_length, 0, 0]``, one bone
        named ``"bone"``.
    W : (n_V, 1) float64
        All ones: with a single bone, every skinning method needs w = 1 everywhere.

    Examples
    --------
    >>> from stbs.shapes import cigar
    >>> V, F, sk, W = cigar(8)
    >>> V.shape, F.shape, sk.n_bones, float(V[:, 0].max())
    ((114, 3), (224, 3), 1, 2.0)
    """
    n = _positive_int("n", n, 3)
    if not 0 < bone_half_length < half_length or radius <= 0:
        raise ValueError("need 0 < bone_half_length < half_length and radius > 0, got "
                         f"{bone_half_length}, {half_length}, {radius}")
    m = 2 * n
    phi = np.pi * np.arange(1, n) / n
    t = 2 * np.pi * np.arange(m) / m
    P, T = np.meshgrid(phi, t, indexing="ij")
    ring = np.stack([-half_length * np.cos(P), radius * np.sin(P) * np.cos(T),
                     radius * np.sin(P) * np.sin(T)], axis=-1).reshape(-1, 3)
    V = np.vstack([[-half_length, 0.0, 0.0], ring, [half_length, 0.0, 0.0]])
    last = V.shape[0] - 1

    def vid(i, j):  # ring i in 1..n-1, segment j (wrapped)
        return 1 + (i - 1) * m + (j % m)

    j = np.arange(m)
    # Quads (i, j) -> (i, j+1) -> (i+1, j+1) -> (i+1, j): edge along t first, then
    # along phi, which is outward for this parametrisation.
    faces = [np.stack([np.zeros(m, int), vid(1, j + 1), vid(1, j)], axis=1)]
    for i in range(1, n - 1):
        q0, q1, q2, q3 = vid(i, j), vid(i, j + 1), vid(i + 1, j + 1), vid(i + 1, j)
        faces += [np.stack([q0, q1, q2], axis=1), np.stack([q0, q2, q3], axis=1)]
    faces.append(np.stack([vid(n - 1, j), vid(n - 1, j + 1), np.full(m, last)], axis=1))
    F = np.vstack(faces).astype(np.int64)
    sk = Skeleton([[-bone_half_length, 0.0, 0.0], [bone_half_length, 0.0, 0.0]], [[0, 1]],
                  names=["bone"])
    return V, F, sk, np.ones((V.shape[0], 1))


def _box_surface(nx: int, ny: int, nz: int, size) -> tuple[np.ndarray, np.ndarray]:
    """Surface of the box [0, Lx] x [-Ly/2, Ly/2] x [-Lz/2, Lz/2] on an nx x ny x nz grid."""
    N = (nx, ny, nz)
    ii, jj, kk = np.meshgrid(*(np.arange(s + 1) for s in N), indexing="ij")
    on = (ii == 0) | (ii == nx) | (jj == 0) | (jj == ny) | (kk == 0) | (kk == nz)
    ids = np.full(on.shape, -1, dtype=np.int64)
    ids[on] = np.arange(int(on.sum()))
    grid = np.stack([ii[on] / nx, jj[on] / ny - 0.5, kk[on] / nz - 0.5], axis=1)
    V = grid * np.asarray(size, dtype=float)
    tris = []
    for ax in range(3):
        u, v = (ax + 1) % 3, (ax + 2) % 3  # (u, v, ax) right-handed: e_u x e_v = e_ax
        for side in (0, N[ax]):
            a, b = np.meshgrid(np.arange(N[u]), np.arange(N[v]), indexing="ij")
            a, b = a.ravel(), b.ravel()

            def at(du, dv, a=a, b=b, ax=ax, u=u, v=v, side=side):
                idx = [None, None, None]
                idx[ax], idx[u], idx[v] = np.full_like(a, side), a + du, b + dv
                return ids[idx[0], idx[1], idx[2]]

            q = [at(0, 0), at(1, 0), at(1, 1), at(0, 1)]
            if side == 0:  # normal -e_ax: reverse the quad
                q = q[::-1]
            tris += [np.stack([q[0], q[1], q[2]], axis=1), np.stack([q[0], q[2], q[3]], axis=1)]
    return V, np.vstack(tris)


def box(nx: int = 32, ny: int = 6, nz: int = 6, *, size=(4.0, 1.0, 1.0)):
    """A box along x with one bone along its whole length (the paper's Fig. 3, left).

    Parameters
    ----------
    nx, ny, nz : int
        Grid cells along x, y, z; ``nx`` must be even so that there is a cross-section
        at the middle of the bone.
    size : (3,) float
        Edge lengths; the box spans ``[0, Lx] x [-Ly/2, Ly/2] x [-Lz/2, Lz/2]``.

    Returns
    -------
    V : (n, 3) float64
        Grid points on the surface.
    F : (f, 3) int64
        Two triangles per grid cell on each face, oriented outward.
    sk : Skeleton
        One bone ``"bone"`` from ``(0, 0, 0)`` to ``(Lx, 0, 0)``.
    W : (n, 1) float64
        All ones.

    Examples
    --------
    >>> from stbs.shapes import box
    >>> V, F, sk, W = box(4, 2, 2, size=(2.0, 1.0, 1.0))
    >>> V.shape, F.shape, sk.C.tolist()
    ((42, 3), (80, 3), [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0]])
    """
    nx = _positive_int("nx", nx, 2)
    ny, nz = _positive_int("ny", ny), _positive_int("nz", nz)
    if nx % 2:
        raise ValueError(f"nx must be even (a cross-section at the middle), got {nx}")
    V, F = _box_surface(nx, ny, nz, size)
    L = float(size[0])
    sk = Skeleton([[0.0, 0.0, 0.0], [L, 0.0, 0.0]], [[0, 1]], names=["bone"])
    return V, F, sk, np.ones((V.shape[0], 1))


def bar(nx: int = 32, ny: int = 6, nz: int = 6, *, size=(4.0, 1.0, 1.0), blend: float = 0.5):
    """A box along x with two bones meeting at its middle (the paper's Fig. 3, right).

    Parameters
    ----------
    nx, ny, nz : int
        Grid cells along x, y, z (``nx`` even: a cross-section at the joint).
    size : (3,) float
        Edge lengths, as in :func:`box`.
    blend : float
        Half-width of the region around the joint where the two bone weights
        overlap; outside it each point follows one bone only, as in a typical
        LBS/DQS rig that bends well.

    Returns
    -------
    V, F
        As :func:`box`.
    sk : Skeleton
        Bones ``"upper"`` (0, 0, 0) -> (Lx/2, 0, 0) and ``"lower"`` (Lx/2, 0, 0) -> (Lx, 0, 0).
    W : (n, 2) float64
        A smoothstep from bone 0 to bone 1 over ``|x - Lx/2| < blend``.

    Examples
    --------
    >>> from stbs.shapes import bar
    >>> V, F, sk, W = bar()
    >>> sk.names, W[V[:, 0] == 0.0].max(axis=0).tolist(), bool(abs(W.sum(axis=1) - 1).max() < 1e-15)
    (['upper', 'lower'], [1.0, 0.0], True)
    """
    V, F, _, _ = box(nx, ny, nz, size=size)
    L = float(size[0])
    if not 0 < blend < L / 2:
        raise ValueError(f"blend must lie in (0, {L / 2}), got {blend}")
    t = np.clip((V[:, 0] - (L / 2 - blend)) / (2 * blend), 0.0, 1.0)
    w1 = t * t * (3 - 2 * t)
    W = np.stack([1.0 - w1, w1], axis=1)
    sk = Skeleton([[0.0, 0.0, 0.0], [L / 2, 0.0, 0.0], [L, 0.0, 0.0]], [[0, 1], [1, 2]],
                  names=["upper", "lower"])
    return V, F, sk, W


def sections(V) -> list[tuple[float, np.ndarray]]:
    """Cross-sections of a grid shape across x.

    Parameters
    ----------
    V : (n, d) float
        Vertex positions; x values equal to 9 decimals are one section.

    Returns
    -------
    list of (float, (k,) int64)
        ``(x, vertex indices)`` per distinct x, by increasing x.

    Examples
    --------
    >>> from stbs.shapes import sections
    >>> [(x, i.tolist()) for x, i in sections([[1.0, 0.0], [0.0, 1.0], [1.0, 2.0]])]
    [(0.0, [1]), (1.0, [0, 2])]
    """
    V = np.asarray(V, dtype=float)
    xs, inv = np.unique(np.round(V[:, 0], 9), return_inverse=True)
    return [(float(x), np.flatnonzero(inv == k)) for k, x in enumerate(xs)]


def box_tets(lo=(0.0, 0.0, 0.0), hi=(4.0, 1.0, 1.0), h: float = 0.25):
    """A box as a Kuhn-subdivided voxel grid: tetrahedra and their outward surface.

    Each cube of side ``h`` is split into 6 tetrahedra along its main diagonal, so
    neighbouring cubes match (no cracks).

    Parameters
    ----------
    lo, hi : (3,) float
        Opposite corners of the box.
    h : float
        Cube size; the box's sides are rounded to whole numbers of cubes.

    Returns
    -------
    V : (n, 3) float64
        Grid points.
    T : (t, 4) int64
        Positively oriented tetrahedra.
    F : (f, 3) int64
        The boundary triangles, oriented outwards.

    Examples
    --------
    >>> from stbs.shapes import box_tets
    >>> V, T, F = box_tets(hi=(2.0, 1.0, 1.0), h=0.5)
    >>> V.shape, T.shape, F.shape
    ((45, 3), (96, 4), (80, 3))
    """
    import itertools

    lo = _checks.real_array("lo", lo, shape=(3,))
    hi = _checks.real_array("hi", hi, shape=(3,))
    if not h > 0 or np.any(hi - lo < h):
        raise ValueError(f"box_tets needs h > 0 and hi - lo >= h, got h={h}, lo={lo}, hi={hi}")
    m = np.round((hi - lo) / h).astype(int)
    axes = [np.linspace(lo[k], hi[k], m[k] + 1) for k in range(3)]
    V = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    vid = np.arange(V.shape[0]).reshape(m + 1)
    i, j, k = (g.ravel() for g in np.meshgrid(*[np.arange(s) for s in m], indexing="ij"))
    corner = {c: vid[i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1)] for c in range(8)}
    T = []
    for perm in itertools.permutations(range(3)):      # path 0 -> ... -> 7 along the axes
        c1 = 1 << perm[0]
        c2 = c1 | (1 << perm[1])
        T.append(np.stack([corner[0], corner[c1], corner[c2], corner[7]], axis=1))
    T = np.concatenate(T).astype(np.int64)
    neg = tet_volumes(V, T) < 0
    T[neg] = T[neg][:, [1, 0, 2, 3]]
    # The outward faces of positive tetrahedra; the boundary keeps their order.
    faces = np.concatenate([T[:, [1, 2, 3]], T[:, [0, 3, 2]], T[:, [0, 1, 3]], T[:, [0, 2, 1]]])
    _, _, inv, cnt = unique_rows(np.sort(faces, axis=1))
    F = faces[cnt[inv] == 1]
    return V, T, F
