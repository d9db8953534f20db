"""The four methods on the array API: per-bone tables, then per-vertex blends in chunks.

Everything is 3D here; 2D rigs arrive embedded (z = 0, rotations about z). A pose
arrives as per-bone arrays with leading batch axes ``*B`` (already broadcast to one
shape); the weight layout as ``k`` slots per vertex, slot 0 the heaviest bone (the
pivot of the dual-quaternion blends).

Layout, chosen for speed and cheap gradients (``_Tables`` holds it):

- per-vertex arrays are ``(c, n, *B)``: ``c`` components (1 for scalars, 3 for points,
  4 for quaternions) first, then vertices, then the batch, so that an operation between
  a per-vertex, per-pose scalar and a c-component array runs over one contiguous stretch
  per component; per-vertex constants are ``(1, n, 1, ...)``. Under JAX they are
  ``(n, *B, c)`` instead (``_ComponentsLast``: what XLA's fusion needs);
- a method first builds its per-bone fields and packs them into one gather table; a slot
  then gathers its bones' rows for all vertices in one row gather, whose gradient is a
  scatter-add into the small table;
- the linear parts of the blends (all of ``lbs``; the rest-space stretch of ``dqs``;
  the translation, stretch and untwisted parts of ``stbs-lbs``) are one matrix product
  of dense ``(n, q b)`` weight rows with a per-pose table;
- the ``dqs`` blend is a matrix product per group of vertices sharing a pivot bone (their
  hemisphere signs then depend on the group and bone only), over vertices sorted by
  pivot;
- in eager mode on a CPU the vertices are taken in chunks small enough for their
  temporaries to stay in cache (an operation that writes a fresh multi-megabyte array
  runs at the memory's speed, several times slower); traced code (``torch.compile``,
  ``jax.jit``), JAX and GPUs take all vertices at once.

Which optional inputs are present (stretch, twist) is static: an absent one drops its
terms from the traced graph.
"""

from __future__ import annotations

import numpy as np

from . import _backend as bk
from .rotations import matrix_to_quat, quat_to_matrix

#: elements (vertices x poses) of one chunk's per-vertex arrays in eager CPU mode
CHUNK_ELEMENTS = 1 << 16

# ------------------------------------------------------------------ component algebra
# quaternions are 4-tuples (w, x, y, z) and vectors 3-tuples of equally shaped arrays


def qmul_pure(p, v):
    """``p * (0, v)``."""
    pw, px, py, pz = p
    vx, vy, vz = v
    return (-px * vx - py * vy - pz * vz,
            pw * vx + py * vz - pz * vy,
            pw * vy - px * vz + pz * vx,
            pw * vz + px * vy - py * vx)


def pure_qmul(v, q):
    """``(0, v) * q``."""
    vx, vy, vz = v
    qw, qx, qy, qz = q
    return (-vx * qx - vy * qy - vz * qz,
            vx * qw + vy * qz - vz * qy,
            -vx * qz + vy * qw + vz * qx,
            vx * qy - vy * qx + vz * qw)


def vcross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def rotate(q, x):
    """Rotate vector x by unit quaternion q."""
    w, v = q[0], q[1:]
    t = tuple(2.0 * c for c in vcross(v, x))
    c = vcross(v, t)
    return tuple(x[i] + w * t[i] + c[i] for i in range(3))


def dq_apply(xp, T, r, d, p):
    """Apply blended (not normalised) dual quaternions to points (``T``'s layout).

    ``r``, ``d`` of 4 components, ``p`` of 3 broadcasting against them. With
    ``r = (w, v)``, ``d = (dw, dv)`` and ``|r|^2 = n2`` the normalised map is
    ``p + (2 / n2) (v x (w p + v x p + dv) + w dv - dw v)``: the rotation by ``r / |r|``
    plus the translation ``2 vec(d r*) / n2``. Not defined where ``r = 0``.
    """
    w, v = T.comp(r, 0, 1), tuple(T.comp(r, i, i + 1) for i in (1, 2, 3))
    dw, dv = T.comp(d, 0, 1), tuple(T.comp(d, i, i + 1) for i in (1, 2, 3))
    pc = tuple(T.comp(p, i, i + 1) for i in range(3))
    s = 2.0 / T.csum(r * r)
    vp = vcross(v, pc)
    inner = tuple(w * pc[i] + vp[i] + dv[i] for i in range(3))
    c = vcross(v, inner)
    return p + s * T.ccat([c[i] + w * dv[i] - dw * v[i] for i in range(3)])


# ------------------------------------------------------------------ inputs
class Bones:
    """Rest bones as backend arrays: starts ``a`` (b, 3), unit axes ``u`` (b, 3),
    vectors ``vec`` (b, 3), lengths ``ell`` (b,). Differentiable when built from a
    differentiable C."""

    def __init__(self, xp, A, Bend):
        vec = Bend - A
        self.ell = xp.sqrt(xp.sum(vec * vec, axis=-1))
        self.u = vec / self.ell[:, None]
        self.a = A
        self.vec = vec


class PoseArrays:
    """A batch of world poses in 3D: R (*B, b, 3, 3) and/or q (*B, b, 4), origins
    (*B, b, 3), stretch (*B, b) or None, twist (*B, b, 2) or None."""

    def __init__(self, R, q, O, sigma, theta):
        self.R, self.q, self.O, self.sigma, self.theta = R, q, O, sigma, theta

    def matrices(self, xp):
        return self.R if self.R is not None else quat_to_matrix(self.q, xp=xp)

    def quats(self, xp):
        return self.q if self.q is not None else matrix_to_quat(self.R, xp=xp)


def _fields(x, k: int):
    """The last axis of x (length k) as k arrays."""
    return tuple(x[..., i] for i in range(k))


class Layout:
    """Per-vertex slots: ``idx`` k (n,) bone-index arrays (slot 0 the heaviest), weights
    ``w`` and endpoint weights ``e`` (n, k) (e None for lbs, dqs), rest points P (n, 3).

    ``W``, ``E``: the dense (n, b) weights where the caller has them (else scattered from
    the slots). ``cache``: keep what depends on these arrays alone between calls (they
    carry no gradient tape). ``pivots``: a concrete (n,) NumPy array of each vertex's
    pivot bone, for the grouped ``dqs`` blend.
    """

    def __init__(self, xp, P, idx, w, e, b: int, W=None, E=None, cache: bool = False,
                 pivots=None):
        self.xp, self.P, self.idx, self.w, self.e, self.b = xp, P, idx, w, e, b
        self.n = P.shape[0]
        self.W, self.E = W, E
        self.cache = cache
        self._memo: dict = {}
        self._index: dict = {}
        self.order = self.unsort = self.groups = None
        if pivots is not None:
            order = np.argsort(pivots, kind="stable")
            bounds = np.searchsorted(pivots[order], np.arange(b + 1))
            self.groups = [(g, int(bounds[g]), int(bounds[g + 1])) for g in range(b)
                           if bounds[g + 1] > bounds[g]]
            self.order = bk.index(xp, order, idx[0])
            self.unsort = bk.index(xp, np.argsort(order), idx[0])

    def memo(self, key, make):
        """``make()``, kept under ``key`` when the layout caches (never a value made while
        tracing: it would outlive its trace)."""
        if not self.cache:
            return make()
        out = self._memo.get(key)
        if out is None:
            out = make()
            if not _traced(out):
                self._memo[key] = out
        return out

    def gather_index(self, j: int, c: int, c0: int, c1: int):
        """Rows of a (c b, m) gather table for slot j's bones of vertices c0:c1, component
        by component: ``k b + idx_j[v]`` for k < c (an integer constant, kept)."""
        key = (j, c, c0, c1)
        out = self._index.get(key)
        if out is None:
            if len(self._index) > 256:     # rebuilt when the chunking changes
                self._index.clear()
            xp, i = self.xp, self.idx[j][c0:c1]
            offs = xp.arange(c, dtype=i.dtype, device=_device(i)) * self.b
            out = xp.reshape(offs[:, None] + i[None, :], (c * (c1 - c0),))
            if not bk.is_traced(out):
                self._index[key] = out
        return out

    def sorted_rows(self, key, x):
        """(n, ...) rows of x in pivot order."""
        return self.memo(("sorted", key), lambda: self.xp.take(x, self.order, axis=0))

    def affine_rows(self):
        """X = [W p_x | W p_y | W p_z | W] (n, 4b): the affine blends are ``X @ table``."""
        def make():
            P, Wd = self.P, self.dense_weights()
            return self.xp.concat([Wd * P[:, 0:1], Wd * P[:, 1:2], Wd * P[:, 2:3], Wd],
                                  axis=1)
        return self.memo("affine", make)

    def dense_weights(self):
        """(n, b) weights scattered from the slots (differentiable in ``w``)."""
        if self.W is not None:
            return self.W
        return self.memo("W", lambda: self._scatter(self.w))

    def weighted_endpoints(self):
        """(n, b) products ``w e`` (from the slots: differentiable in ``w`` and ``e``; a
        padded slot, of weight 0, adds nothing even where it repeats a bone)."""
        if self.E is not None:
            return self.dense_weights() * self.E
        return self.memo("WE", lambda: self._scatter(self.w * self.e))

    def _scatter(self, vals):
        xp = self.xp
        bones = xp.arange(self.b, dtype=self.idx[0].dtype, device=_device(self.idx[0]))
        out = None
        for j, ij in enumerate(self.idx):
            hot = xp.where(ij[:, None] == bones[None, :], vals[:, j:j + 1],
                           xp.zeros_like(vals[:, j:j + 1]))
            out = hot if out is None else out + hot
        return out


def _traced(x) -> bool:
    """Whether an array, or any array in nested lists and tuples, is being traced."""
    if isinstance(x, (list, tuple)):
        return any(_traced(y) for y in x)
    return bk.is_traced(x)


def _device(x):
    import array_api_compat

    return array_api_compat.device(x)


class _Tables:
    """Per-bone fields packed for row gathers, and per-vertex shapes for one batch.

    Per-vertex arrays are (c, nc, *B): components first, so that an operation between
    a per-vertex, per-pose scalar (1, nc, *B) and a c-component array runs over one
    contiguous stretch of nc * prod(B) values per component. The methods reach the
    component and vertex axes only through ``comp``, ``csum``, ``ccat``, ``vslice`` and
    ``vcat``, so that ``_ComponentsLast`` can lay them out the other way.
    """

    def __init__(self, xp, batch: tuple, lay: Layout):
        self.xp, self.batch, self.lay, self.b = xp, batch, lay, lay.b
        self.m = bk.prod(batch)
        self.tail = (1,) * len(batch)
        self._index_select = self._split = None
        if bk.is_torch(xp):     # the compat layer's take adds a negative-index pass
            import torch

            self._index_select, self._split = torch.index_select, torch.split

    def _comps_first(self, X):
        """(*B, b, c) fields (or anything broadcasting to them) to (c, b, m)."""
        xp, nb = self.xp, len(self.batch)
        c = X.shape[-1]
        X = xp.broadcast_to(X, self.batch + (self.b, c))
        X = xp.permute_dims(X, (nb + 1, nb) + tuple(range(nb)))          # (c, b, *B)
        return xp.reshape(X, (c, self.b, self.m))

    def pack(self, fields):
        """Groups of (*B, b, c_f) fields as one gather table (sum c_f b, m), and the c_f."""
        T = self.xp.concat([self._comps_first(f) for f in fields], axis=0)
        return self.xp.reshape(T, (T.shape[0] * self.b, self.m)), tuple(
            f.shape[-1] for f in fields)

    def gather(self, packed, j: int, c0: int, c1: int):
        """Slot j's bones' rows of a :meth:`pack` table for vertices c0:c1: one
        (c_f, nc, *B) array per group."""
        T, sizes = packed
        c = sum(sizes)
        idx = self.lay.gather_index(j, c, c0, c1)
        G = self._index_select(T, 0, idx) if self._index_select is not None else \
            self.xp.take(T, idx, axis=0)
        G = self.xp.reshape(G, (c, c1 - c0) + self.batch)
        if len(sizes) == 1:
            return [G]
        if self._split is not None:             # split's gradient is one concat
            return self._split(G, sizes, dim=0)
        out, k = [], 0
        for s in sizes:
            out.append(G[k:k + s])
            k += s
        return out

    def linear(self, fields):
        """Per-bone c-vectors (*B, b, c) of the q terms of a linear blend as the
        (c, q b, m) table multiplying dense (n, q b) rows."""
        return self.xp.concat([self._comps_first(f) for f in fields], axis=1)

    def rows(self, X, T):
        """Dense rows X (nc, q b) times a :meth:`linear` table (c, q b, m): (c, nc, *B)."""
        return self.xp.reshape(X @ T, (T.shape[0], X.shape[0]) + self.batch)

    def affine(self, M, t):
        """The linear table of ``p -> M_i p + t_i`` for :meth:`Layout.affine_rows`:
        its term c holds M_i's column c, its last term t_i."""
        return self.linear([M[..., :, :, c] for c in range(3)] + [t])

    def vertex(self, x):
        """(nc,) per-vertex values to (1, nc, 1, ...)."""
        return self.xp.reshape(x, (1, x.shape[0]) + self.tail)

    def columns(self, x):
        """The k columns of per-vertex, per-slot values x (n, k) as (1, n, 1, ...)."""
        return [self.vertex(x[:, j]) for j in range(x.shape[1])]

    def points(self, P=None):
        """The rest points (or the (n, 3) P given) as (3, n, 1, ...)."""
        P = self.lay.P if P is None else P
        return self.xp.reshape(self.xp.permute_dims(P, (1, 0)), (3, P.shape[0]) + self.tail)

    # the component and vertex axes, whatever the layout
    def comp(self, x, a: int, b: int):
        """Components a:b of a per-vertex array."""
        return x[a:b]

    def csum(self, x):
        """The sum over components, kept as one component."""
        return self.xp.sum(x, axis=0, keepdims=True)

    def ccat(self, xs):
        return self.xp.concat(xs, axis=0)

    def vslice(self, x, c0: int, c1: int):
        """Vertices c0:c1 of a per-vertex array."""
        return x[:, c0:c1]

    def vcat(self, xs):
        return xs[0] if len(xs) == 1 else self.xp.concat(xs, axis=1)

    def output(self, U, unsort=None):
        """All vertices' (3, n, *B) points, in vertex order ``unsort`` of them if given, as
        the (*B, n, 3) result."""
        xp, nb = self.xp, len(self.batch)
        if unsort is not None:
            U = xp.take(U, unsort, axis=1)
        return xp.permute_dims(U, tuple(range(2, nb + 2)) + (1, 0))


class _ComponentsLast(_Tables):
    """The same with per-vertex arrays (nc, *B, c): vertex first, components last; for
    XLA (``jax.jit``). XLA fuses the per-vertex work into the loops that consume it; with
    components first, the loop writing the (*B, n, 3) result runs through a transpose
    and recomputes each slot's gathers and trigonometry for every coordinate. Here the
    gathers' natural (nc, *B, c) output is the working layout and the result's transpose
    keeps its last axis."""

    def _bones_first(self, X):
        """(*B, b, c) fields (or anything broadcasting to them) to (b, m, c)."""
        xp, nb = self.xp, len(self.batch)
        c = X.shape[-1]
        X = xp.broadcast_to(X, self.batch + (self.b, c))
        X = xp.permute_dims(X, (nb,) + tuple(range(nb)) + (nb + 1,))      # (b, *B, c)
        return xp.reshape(X, (self.b, self.m, c))

    def pack(self, fields):
        return (self.xp.concat([self._bones_first(f) for f in fields], axis=-1),
                tuple(f.shape[-1] for f in fields))

    def gather(self, packed, j: int, c0: int, c1: int):
        T, sizes = packed
        G = self.xp.take(T, self.lay.idx[j][c0:c1], axis=0)              # (nc, m, C)
        G = self.xp.reshape(G, (c1 - c0,) + self.batch + (G.shape[-1],))
        out, k = [], 0
        for c in sizes:
            out.append(G[..., k:k + c])
            k += c
        return out

    def linear(self, fields):
        T = self.xp.concat([self._bones_first(f) for f in fields], axis=0)  # (qb, m, c)
        return self.xp.reshape(T, (T.shape[0], -1))

    def rows(self, X, T):
        return self.xp.reshape(X @ T, (X.shape[0],) + self.batch + (-1,))

    def vertex(self, x):
        return self.xp.reshape(x, (x.shape[0],) + self.tail + (1,))

    def points(self, P=None):
        P = self.lay.P if P is None else P
        return self.xp.reshape(P, (P.shape[0],) + self.tail + (3,))

    def comp(self, x, a: int, b: int):
        return x[..., a:b]

    def csum(self, x):
        return self.xp.sum(x, axis=-1, keepdims=True)

    def ccat(self, xs):
        return self.xp.concat(xs, axis=-1)

    def vslice(self, x, c0: int, c1: int):
        return x[c0:c1]

    def vcat(self, xs):
        return xs[0] if len(xs) == 1 else self.xp.concat(xs, axis=0)

    def output(self, U, unsort=None):
        xp, nb = self.xp, len(self.batch)
        if unsort is not None:
            U = xp.take(U, unsort, axis=0)
        return xp.permute_dims(U, tuple(range(1, nb + 1)) + (0, nb + 1))


def _chunk_rows(xp, lay: Layout, m: int) -> int:
    """Vertices per chunk: all of them unless eager on a CPU (NumPy or PyTorch)."""
    if bk.is_torch(xp):
        if lay.P.device.type != "cpu" or bk.is_traced(lay.P):
            return max(lay.n, 1)
    elif not bk.is_numpy(xp):
        return max(lay.n, 1)
    return max(1, CHUNK_ELEMENTS // max(m, 1))


# ------------------------------------------------------------------ methods
# Each method returns (plan, chunked): plan(c0, c1) gives vertices c0:c1 in T's layout


def lbs(xp, bones: Bones, pose: PoseArrays, lay: Layout, T: _Tables):
    """Eq. 1-3: ``sum_i w_i (a'_i + R_i S_i (p - a_i))``, one matrix product."""
    R = pose.matrices(xp)
    u, a = bones.u, bones.a
    if pose.sigma is not None:
        Ru = xp.sum(R * u[:, None, :], axis=-1)
        R = R + ((pose.sigma - 1.0)[..., None, None] * Ru[..., :, None]) * u[:, None, :]
    t = pose.O - xp.sum(R * a[:, None, :], axis=-1)
    X, tab = lay.affine_rows(), T.affine(R, t)
    return (lambda c0, c1: T.rows(X[c0:c1], tab)), False


def _stretch_table(xp, bones: Bones, pose: PoseArrays, T: _Tables):
    """The affine table of ``p -> (S_i - I)(p - a_i)`` (stretch in rest space)."""
    u = bones.u
    c = (pose.sigma - 1.0)[..., None] * u                                 # (*B, b, 3)
    return T.affine(c[..., :, None] * u[:, None, :],
                    -c * xp.sum(u * bones.a, axis=-1)[:, None])


def dqs(xp, bones: Bones, pose: PoseArrays, lay: Layout, T: _Tables):
    """Rigid parts blended as dual quaternions (pivot hemisphere), stretch linearly first.

    The per-bone dual quaternions do not vary per vertex, so a vertex's hemisphere signs
    depend only on its pivot g: ``S[g, i] = sign(q_i . q_g)``, and for the vertices of
    group g the blend is ``W_g @ (S[g] * Q)``. Vertices are taken in pivot order.
    """
    q = pose.quats(xp)
    qf = _fields(q, 4)
    a = _fields(bones.a, 3)
    t = tuple(o - r for o, r in zip(_fields(pose.O, 3), rotate(qf, a), strict=True))
    qd = xp.stack(tuple(0.5 * x for x in pure_qmul(t, qf)), axis=-1)
    stretch = pose.sigma is not None
    tab_s = _stretch_table(xp, bones, pose, T) if stretch else None
    if lay.groups is None:      # pivots not known ahead (traced weights): slot by slot
        tab = T.pack([q, qd])
        X = lay.affine_rows() if stretch else None
        Pt, W = T.points(), T.columns(lay.w)

        def slot(j, c0, c1):
            return tuple(T.gather(tab, j, c0, c1))

        def plan(c0, c1):
            p = T.vslice(Pt, c0, c1)
            if stretch:
                p = p + T.rows(X[c0:c1], tab_s)
            return dq_apply(xp, T, *_dq_blend(xp, T, W, slot, c0, c1), p)

        return plan, True
    Q = xp.concat([q, qd], axis=-1)                                       # (*B, b, 8)
    dots = xp.sum(q[..., :, None, :] * q[..., None, :, :], axis=-1)       # (*B, b, b)
    S = xp.where(dots < 0, -xp.ones_like(dots), xp.ones_like(dots))
    tabs = {g: T.linear([xp.expand_dims(S[..., g, :], axis=-1) * Q])
            for g, _, _ in lay.groups}
    Ws = lay.sorted_rows("W", lay.dense_weights())
    Pt = T.points(lay.sorted_rows("P", lay.P))
    Xs = lay.sorted_rows("affine", lay.affine_rows()) if stretch else None

    def plan_sorted(c0, c1):
        parts = [T.rows(Ws[max(s0, c0):min(s1, c1)], tabs[g]) for g, s0, s1 in lay.groups
                 if s0 < c1 and s1 > c0]
        Y = T.vcat(parts)                                                  # 8 components
        p = T.vslice(Pt, c0, c1)
        if stretch:
            p = p + T.rows(Xs[c0:c1], tab_s)
        return dq_apply(xp, T, T.comp(Y, 0, 4), T.comp(Y, 4, 8), p)

    return plan_sorted, True


def _dq_blend(xp, T: _Tables, W, slot, c0: int, c1: int):
    """Blended (real, dual) of vertices c0:c1 from ``slot(j, c0, c1)``'s dual
    quaternions, each flipped to the hemisphere of slot 0's (the pivot); ``W`` the slots'
    weights as :meth:`_Tables.columns`."""
    piv, d = slot(0, c0, c1)
    w = T.vslice(W[0], c0, c1)
    acc_r, acc_d = w * piv, w * d
    for j in range(1, len(W)):
        r, d = slot(j, c0, c1)
        w = T.vslice(W[j], c0, c1)
        # the weight with the sign of the dot product with the pivot: where(dot < 0, -w,
        # w) up to the sign of an exact zero, several times faster
        sw = xp.copysign(w, T.csum(r * piv))
        acc_r, acc_d = acc_r + sw * r, acc_d + sw * d
    return acc_r, acc_d


def _complement(xp, u):
    """Unit vectors v1, v2 (b, 3) completing the unit axes u (b, 3) to right-handed
    orthonormal frames (u, v1, v2); the helper axis is x unless u is close to it."""
    ex = xp.zeros_like(u) + xp.asarray([1.0, 0.0, 0.0], dtype=u.dtype)
    ey = xp.zeros_like(u) + xp.asarray([0.0, 1.0, 0.0], dtype=u.dtype)
    ref = xp.where(xp.abs(u[:, 0:1]) < 0.9, ex, ey)
    v1 = xp.stack(vcross(_fields(u, 3), _fields(ref, 3)), axis=-1)
    v1 = v1 / xp.sqrt(xp.sum(v1 * v1, axis=-1, keepdims=True))
    v2 = xp.stack(vcross(_fields(u, 3), _fields(v1, 3)), axis=-1)
    return v1, v2


def _frame_rows(xp, bones: Bones, lay: Layout, v1, v2, terms):
    """Dense (n, q b) rows of stbs-lbs's linear part: for each term its (n, b) block."""
    Wd, P = lay.dense_weights(), lay.P

    def coord(v):       # (p - a_i) . v_i for every vertex and bone
        return P @ xp.permute_dims(v, (1, 0)) - xp.sum(bones.a * v, axis=-1)[None, :]

    blocks = {"w": lambda: Wd, "u": lambda: Wd * coord(bones.u),
              "e": lay.weighted_endpoints,
              "v1": lambda: Wd * coord(v1), "v2": lambda: Wd * coord(v2)}
    return xp.concat([blocks[t]() for t in terms], axis=1)


def _stbs_lbs_rows(xp, bones: Bones, lay: Layout, v1, v2, terms):
    return lay.memo(("stbs-lbs",) + tuple(terms),
                    lambda: _frame_rows(xp, bones, lay, v1, v2, terms))


def _slot_coords(xp, bones: Bones, lay: Layout, v1, v2):
    """Per slot the weighted twist-plane coordinates ``w (p - a) . v1``, ``w (p - a) . v2``
    (n,) of every vertex."""
    def make():
        out = []
        for j, ij in enumerate(lay.idx):
            x = lay.P - xp.take(bones.a, ij, axis=0)
            w = lay.w[:, j]
            out.append(tuple(w * xp.sum(x * xp.take(v, ij, axis=0), axis=-1)
                             for v in (v1, v2)))
        return out

    return lay.memo("stbs-lbs-twist", make)


def stbs_lbs(xp, bones: Bones, pose: PoseArrays, lay: Layout, T: _Tables):
    """Eq. 5: ``sum_i w_i (a'_i + R_i K_i(e_i) (e_i s_i + p - a_i))``.

    In the bone's rest frame (u, v1, v2) the point ``x = p - a`` has coordinates
    ``(x_u, x_1, x_2)``; the twist by ``phi = theta_a + e (theta_b - theta_a)`` turns
    ``(x_1, x_2)`` and the stretch moves ``x_u`` by ``e (sigma - 1) l``, so the posed
    point is ``a' + (x_u + e (sigma - 1) l) R u + (c x_1 - s x_2) R v1 + (s x_1 + c x_2)
    R v2`` with ``c, s = cos(phi), sin(phi)``. Everything but the twisted terms is linear
    in per-bone tables (one matrix product over dense rows); the twisted terms are
    gathered per slot, with no rotation applied per vertex.
    """
    R = pose.matrices(xp)
    v1, v2 = _complement(xp, bones.u)
    Ru, Rv1, Rv2 = (xp.sum(R * v[:, None, :], axis=-1) for v in (bones.u, v1, v2))
    twist, stretch = pose.theta is not None, pose.sigma is not None
    terms, tabs = ["w", "u"], [pose.O, Ru]
    if stretch:
        terms.append("e")
        tabs.append(((pose.sigma - 1.0) * bones.ell)[..., None] * Ru)
    if not twist:
        terms += ["v1", "v2"]
        tabs += [Rv1, Rv2]
    X = _stbs_lbs_rows(xp, bones, lay, v1, v2, terms)
    tab = T.linear(tabs)
    if twist:
        th = pose.theta
        tab_t = T.pack([Rv1, Rv2, xp.expand_dims(th[..., 0], axis=-1),
                        xp.expand_dims(th[..., 1] - th[..., 0], axis=-1)])
        K = [(T.vertex(x1), T.vertex(x2)) for x1, x2 in _slot_coords(xp, bones, lay, v1, v2)]
        E = T.columns(lay.e)

    def plan(c0, c1):
        acc = T.rows(X[c0:c1], tab)
        if not twist:
            return acc
        for j in range(len(lay.idx)):
            G1, G2, ta, td = T.gather(tab_t, j, c0, c1)
            phi = ta + T.vslice(E[j], c0, c1) * td
            c, s = xp.cos(phi), xp.sin(phi)
            x1, x2 = T.vslice(K[j][0], c0, c1), T.vslice(K[j][1], c0, c1)
            acc = acc + (c * x1 - s * x2) * G1 + (s * x1 + c * x2) * G2
        return acc

    return plan, True


def stbs_dqs(xp, bones: Bones, pose: PoseArrays, lay: Layout, T: _Tables):
    """Eq. 6 in bilinear form.

    The map ``T(a') Rot(qR) T(e s) Rot(qK) T(-a)`` with ``qK = (cos h, sin h u)``,
    ``h = ((1 - e) theta_a + e theta_b) / 2``: since s is parallel to u, T(e s)
    commutes with qK, and it expands to real ``cos h R1 + sin h R2`` and dual
    ``cos h D1 + sin h D2 + e c (cos h R2 - sin h R1)`` with ``R1 = qR``,
    ``R2 = qR (0, u)``, ``D1 = qR alpha + Xd``, ``D2 = R2 alpha + Xd (0, u)``,
    ``alpha = -(0, a) / 2``, ``Xd = (0, a') qR / 2``, ``c = (sigma - 1) l / 2``.
    The twist enters per vertex only through the half angle's cos and sin.
    """
    R1 = _fields(pose.quats(xp), 4)
    u = _fields(bones.u, 3)
    a = _fields(bones.a, 3)
    Xd = tuple(0.5 * x for x in pure_qmul(_fields(pose.O, 3), R1))
    R2 = qmul_pure(R1, u)
    half_a = tuple(-0.5 * x for x in a)
    D1 = tuple(x + y for x, y in zip(qmul_pure(R1, half_a), Xd, strict=True))
    D2 = tuple(x + y for x, y in zip(qmul_pure(R2, half_a), qmul_pure(Xd, u), strict=True))
    twist, stretch = pose.theta is not None, pose.sigma is not None
    fields = [xp.stack(R1, axis=-1), xp.stack(D1, axis=-1)]
    if twist or stretch:
        fields.append(xp.stack(R2, axis=-1))
    if twist:
        th = pose.theta
        fields += [xp.stack(D2, axis=-1), xp.expand_dims(0.5 * th[..., 0], axis=-1),
                   xp.expand_dims(0.5 * (th[..., 1] - th[..., 0]), axis=-1)]
    if stretch:
        fields.append(xp.expand_dims(0.5 * (pose.sigma - 1.0) * bones.ell, axis=-1))
    tab = T.pack(fields)
    E, W = T.columns(lay.e), T.columns(lay.w)
    Pt = T.points()

    def slot(j, c0, c1):
        g = T.gather(tab, j, c0, c1)
        r1, d1 = g[0], g[1]
        e = T.vslice(E[j], c0, c1)
        if stretch:
            r2, ec = g[2], e * g[-1]
        if not twist:
            return r1, (d1 + ec * r2 if stretch else d1)
        r2, d2, ha, hd = g[2:6]
        h = ha + e * hd
        ch, sh = xp.cos(h), xp.sin(h)
        if stretch:     # dual = ch (D1 + e c R2) + sh (D2 - e c R1)
            d1, d2 = d1 + ec * r2, d2 - ec * r1
        return ch * r1 + sh * r2, ch * d1 + sh * d2

    def plan(c0, c1):
        return dq_apply(xp, T, *_dq_blend(xp, T, W, slot, c0, c1), T.vslice(Pt, c0, c1))

    return plan, True


def prepare(xp, method: str, bones: Bones, lay: Layout) -> None:
    """Build what a caching layout keeps for ``method`` now, outside any trace (under
    ``jax.jit`` it then enters the compiled function as constants); a full STBS pose
    (stretch and twist) is the case prepared for stbs-lbs."""
    if method == "stbs-lbs":
        v1, v2 = _complement(xp, bones.u)
        _stbs_lbs_rows(xp, bones, lay, v1, v2, ["w", "u", "e"])
        _slot_coords(xp, bones, lay, v1, v2)
    elif method in ("lbs", "dqs"):
        X = lay.affine_rows()
        if lay.groups is not None:
            lay.sorted_rows("W", lay.dense_weights())
            lay.sorted_rows("P", lay.P)
            lay.sorted_rows("affine", X)


METHOD_FUNCS = {"lbs": lbs, "dqs": dqs, "stbs-lbs": stbs_lbs, "stbs-dqs": stbs_dqs}


def deform(xp, method: str, bones: Bones, pose: PoseArrays, lay: Layout, batch: tuple):
    """(*B, n, 3) deformed points of ``lay.P`` by ``method``."""
    T = (_ComponentsLast if bk.is_jax(xp) else _Tables)(xp, batch, lay)
    plan, chunked = METHOD_FUNCS[method](xp, bones, pose, lay, T)
    n = lay.n
    rows = _chunk_rows(xp, lay, T.m) if chunked else max(n, 1)
    U = T.vcat([plan(c0, min(n, c0 + rows)) for c0 in range(0, max(n, 1), rows)])
    return T.output(U, lay.unsort)
