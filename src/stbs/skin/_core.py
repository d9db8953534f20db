"""The four methods on the array API: per-bone tables, then one gather-and-blend pass.

Everything is 3D here; 2D rigs arrive embedded (z = 0, rotations about z). A pose
arrives as per-bone arrays with leading batch axes ``*B`` (already broadcast to one
shape); the weight layout as ``k`` slots per vertex, slot 0 the heaviest bone (the
pivot of the dual-quaternion blends).

Layout, chosen for speed under autograd: a method builds its per-bone constants as a
list of scalar *fields* (each (*B, b)), stacked into one (m, b, *B) table. Each slot
gathers the table's rows for all vertices at once (``take`` along the bone axis, a copy
of contiguous batch rows) and splits it back into m fields of shape (n, *B) by
iterating over the first axis (PyTorch's ``unbind``, whose backward is one ``stack``:
slicing a packed table instead costs a zero-filled full-size gradient per slice). All
per-vertex algebra is then written component by component on those fields: closed-form
quaternion products, no (n, k, 4, 4) matrices and no per-vertex 3x3 twist matrices.
The linear blends (``lbs``, and the rest-space stretch of ``dqs``) are one matrix
product ``[W p_x | W p_y | W p_z | W] @ table`` instead.

Which optional inputs are present (stretch, twist) is static: an absent one drops its
terms from the traced graph.
"""

from __future__ import annotations

from .rotations import matrix_to_quat, quat_to_matrix

# ------------------------------------------------------------------ component algebra
# quaternions are 4-tuples (w, x, y, z) and vectors 3-tuples of equally shaped arrays


def qmul(p, q):
    pw, px, py, pz = p
    qw, qx, qy, qz = q
    return (pw * qw - px * qx - py * qy - pz * qz,
            pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw)


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


def vdot(a, b):
    out = a[0] * b[0]
    for x, y in zip(a[1:], b[1:], strict=True):
        out = out + x * y
    return out


def rotate(q, x):
    """Rotate vector x by unit quaternion q."""
    w, v = q[0], q[1:]
    t = tuple(2.0 * c for c in vcross(v, x))
    c = vcross(v, t)
    return tuple(x[i] + w * t[i] + c[i] for i in range(3))


def dq_apply(r, d, p):
    """Apply blended (not normalised) dual quaternions ``(r, d)`` to points p.

    With ``r = (w, v)``, ``d = (dw, dv)`` and ``|r|^2 = n2`` the normalised map is
    ``p + (2 / n2) (v x (w p + v x p + dv) + w dv - dw v)``: the rotation by ``r / |r|``
    plus the translation ``2 vec(d r*) / n2``. Not defined where ``r = 0``.
    """
    w, v = r[0], r[1:]
    dw, dv = d[0], d[1:]
    s = 2.0 / vdot(r, r)
    vp = vcross(v, p)
    inner = tuple(w * p[i] + vp[i] + dv[i] for i in range(3))
    c = vcross(v, inner)
    return tuple(p[i] + s * (c[i] + w * dv[i] - dw * v[i]) for i in range(3))


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
    ``w`` and endpoint weights ``e`` (n, k) (e None for lbs, dqs), rest points P (n, 3)."""

    def __init__(self, xp, P, idx, w, e, b: int, W=None, cache: bool = False, pivots=None):
        self.xp, self.P, self.idx, self.w, self.e, self.b = xp, P, idx, w, e, b
        self.W = W
        self._X = self.affine_rows() if cache else None
        self.groups = None
        if pivots is not None:
            self._group(pivots, cache)

    def _group(self, pivots, cache: bool):
        """Vertices grouped by their pivot bone (a concrete (n,) NumPy array): for the
        ``dqs`` blend, whose hemisphere signs then depend on the group and bone only."""
        import numpy as np

        xp = self.xp
        order = np.argsort(pivots, kind="stable")
        bounds = np.searchsorted(pivots[order], np.arange(self.b + 1))
        like = self.idx[0]
        self.groups = [(g, _index(xp, order[bounds[g]:bounds[g + 1]], like))
                       for g in range(self.b) if bounds[g + 1] > bounds[g]]
        self.unsort = _index(xp, np.argsort(order), like)
        self._Wg = self.group_weights() if cache else None

    def group_weights(self):
        """Per pivot group its rows of the dense weights, (n_g, b) each."""
        if getattr(self, "_Wg", None) is not None:
            return self._Wg
        Wd = self.dense_weights()
        return [self.xp.take(Wd, rows, axis=0) for _, rows in self.groups]

    def affine_rows(self):
        """X = [W p_x | W p_y | W p_z | W] (n, 4b): the linear blends are ``X @ table``."""
        if getattr(self, "_X", None) is not None:
            return self._X
        xp, P = self.xp, self.P
        Wd = self.dense_weights()
        return xp.concat([Wd * P[:, 0:1], Wd * P[:, 1:2], Wd * P[:, 2:3], Wd], axis=1)

    def dense_weights(self):
        """(n, b) weights scattered from the slots (differentiable in ``w``)."""
        xp = self.xp
        if self.W is not None:
            return self.W
        bones = xp.arange(self.b, dtype=self.idx[0].dtype, device=_device(self.idx[0]))
        out = None
        for j, ij in enumerate(self.idx):
            hot = xp.where(ij[:, None] == bones[None, :], self.w[:, j:j + 1],
                           xp.zeros_like(self.w[:, j:j + 1]))
            out = hot if out is None else out + hot
        return out


def _device(x):
    import array_api_compat

    return array_api_compat.device(x)


def _index(xp, x, like):
    import numpy as np

    return xp.asarray(np.array(x, dtype=np.int64), device=_device(like))


class _Fields:
    """Gather per-bone fields for one slot and shape per-vertex arrays for the batch."""

    def __init__(self, xp, fields, batch: tuple, lay: Layout):
        self.xp, self.batch, self.lay = xp, batch, lay
        shape = batch + (lay.b,)
        T = xp.stack([xp.broadcast_to(f, shape) for f in fields], axis=0)   # (m, *B, b)
        nd = T.ndim
        self.T = xp.permute_dims(T, (0, nd - 1) + tuple(range(1, nd - 1)))  # (m, b, *B)
        self.tail = (1,) * len(batch)

    def slot(self, j: int):
        """The m fields of slot j, each (n, *B)."""
        return tuple(self.xp.take(self.T, self.lay.idx[j], axis=1))

    def vertex(self, x):
        """(n,) per-vertex array to (n, 1, ..., 1) to broadcast against the batch."""
        return self.xp.reshape(x, (x.shape[0],) + self.tail)

    def output(self, comps):
        """Three (n, *B) fields to (*B, n, 3)."""
        xp = self.xp
        U = xp.stack(comps, axis=-1)                                     # (n, *B, 3)
        nd = U.ndim
        return xp.permute_dims(U, tuple(range(1, nd - 1)) + (0, nd - 1))

    def points(self):
        return tuple(self.vertex(self.lay.P[:, i]) for i in range(3))


def _affine_blend(xp, lay: Layout, M, t, batch: tuple):
    """``sum_i w_i (M_i p + t_i)`` for all vertices as one matrix product: (*B, n, 3).

    M (*B, b, 3, 3) and t (*B, b, 3); X = [W p_x | W p_y | W p_z | W] (n, 4b).
    """
    X = lay.affine_rows()
    # rows c*b + i hold M_i[:, c] (the column multiplying p_c), rows 3b + i hold t_i
    T = xp.concat([M[..., :, :, 0], M[..., :, :, 1], M[..., :, :, 2], t], axis=-2)
    nb = len(batch)
    if nb == 0:
        return X @ T
    T2 = xp.permute_dims(T, (nb,) + tuple(range(nb)) + (nb + 1,))        # (4b, *B, 3)
    m = 1
    for s in batch:
        m *= s
    Y = X @ xp.reshape(T2, (T2.shape[0], m * 3))                          # (n, B*3)
    Y = xp.reshape(Y, (X.shape[0],) + batch + (3,))
    return xp.permute_dims(Y, tuple(range(1, nb + 1)) + (0, nb + 1))


# ------------------------------------------------------------------ methods
def lbs(xp, bones: Bones, pose: PoseArrays, lay: Layout, batch: tuple):
    """Eq. 1-3: ``sum_i w_i (a'_i + R_i S_i (p - a_i))``."""
    R = pose.matrices(xp)
    u, a = bones.u, bones.a
    if pose.sigma is not None:
        Ru = xp.sum(R * u[:, None, :], axis=-1)
        R = R + ((pose.sigma - 1.0)[..., None, None] * Ru[..., :, None]) * u[:, None, :]
    t = pose.O - xp.sum(R * a[:, None, :], axis=-1)
    return _affine_blend(xp, lay, R, t, batch)


def _stretch_offsets(xp, bones: Bones, pose: PoseArrays, lay: Layout, batch: tuple):
    """``sum_i w_i (S_i - I)(p - a_i)``, S_i blended linearly in rest space: (*B, n, 3)."""
    u = bones.u
    c = (pose.sigma - 1.0)[..., None] * u                                 # (*B, b, 3)
    M = c[..., :, None] * u[:, None, :]
    t = -c * xp.sum(u * bones.a, axis=-1)[:, None]
    return _affine_blend(xp, lay, M, t, batch)


def dqs(xp, bones: Bones, pose: PoseArrays, lay: Layout, batch: tuple):
    """Rigid parts blended as dual quaternions (pivot hemisphere), stretch linearly first."""
    q = pose.quats(xp)
    qf = _fields(q, 4)
    a = _fields(bones.a, 3)
    t = tuple(o - r for o, r in zip(_fields(pose.O, 3), rotate(qf, a), strict=True))
    qd = tuple(0.5 * x for x in pure_qmul(t, qf))
    F = _Fields(xp, qf + qd, batch, lay)
    P = F.points()
    if pose.sigma is not None:
        off = _stretch_offsets(xp, bones, pose, lay, batch)               # (*B, n, 3)
        nb = len(batch)
        off = xp.permute_dims(off, (nb,) + tuple(range(nb)) + (nb + 1,))  # (n, *B, 3)
        P = tuple(P[i] + off[..., i] for i in range(3))
    if lay.groups is not None:
        blend = _grouped_dq_blend(xp, q, qd, lay, batch)
    else:
        blend = _slot_dq_blend(xp, F, lay)
    return F.output(dq_apply(blend[0:4], blend[4:8], P))


def _blend_add(xp, acc, real, dual, wj):
    """``acc`` (blended real, blended dual, pivot) with one more slot's dual quaternion,
    weighted by ``wj`` and flipped to the hemisphere of the first slot's (the pivot)."""
    if acc is None:
        return tuple(wj * x for x in real), tuple(wj * x for x in dual), real
    r, d, piv = acc
    s = xp.where(vdot(real, piv) < 0, -wj, wj)
    return (tuple(y + s * x for y, x in zip(r, real, strict=True)),
            tuple(y + s * x for y, x in zip(d, dual, strict=True)), piv)


def _slot_dq_blend(xp, F, lay: Layout):
    """Blend slot by slot, each flipped to the hemisphere of slot 0 (the pivot)."""
    acc = None
    for j in range(len(lay.idx)):
        f = F.slot(j)
        acc = _blend_add(xp, acc, f[0:4], f[4:8], F.vertex(lay.w[:, j]))
    return acc[0] + acc[1]


def _grouped_dq_blend(xp, q, qd, lay: Layout, batch: tuple):
    """The same blend as one matrix product per pivot group.

    The per-bone dual quaternions do not vary per vertex, so a vertex's hemisphere
    signs depend only on its pivot g: ``S[g, i] = sign(q_i . q_g)``. For the vertices
    of group g the blend is ``W_g @ (S[g] * Q)``, (n_g, b) @ (b, 8 B).
    """
    m = 1
    for x in batch:
        m *= x
    b = lay.b
    Q = xp.reshape(xp.stack(tuple(q[..., i] for i in range(4)) + qd, axis=-1), (m, b, 8))
    qm = Q[..., 0:4]
    dots = xp.sum(qm[:, :, None, :] * qm[:, None, :, :], axis=-1)                 # (m, b, b)
    S = xp.where(dots < 0, -xp.ones_like(dots), xp.ones_like(dots))
    Y = []
    for (g, _), Wg in zip(lay.groups, lay.group_weights(), strict=True):
        Qg = S[:, g, :, None] * Q                                                   # (m, b, 8)
        Qg = xp.reshape(xp.permute_dims(Qg, (1, 0, 2)), (b, m * 8))
        Y.append(Wg @ Qg)
    Y = xp.take(xp.concat(Y, axis=0), lay.unsort, axis=0)                           # (n, m*8)
    n = Y.shape[0]
    Y = xp.permute_dims(xp.reshape(Y, (n, m, 8)), (2, 0, 1))
    return tuple(xp.reshape(Y, (8, n) + batch))


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


def stbs_lbs(xp, bones: Bones, pose: PoseArrays, lay: Layout, batch: tuple):
    """Eq. 5: ``sum_i w_i (a'_i + R_i K_i(e_i) (e_i s_i + p - a_i))``.

    In the bone's rest frame (u, v1, v2) the point ``x = p - a`` has coordinates
    ``(x_u, x_1, x_2)``, fixed per vertex and slot; the twist by
    ``phi = theta_a + e (theta_b - theta_a)`` turns ``(x_1, x_2)`` and the stretch moves
    ``x_u`` by ``e (sigma - 1) l``, so the posed point is
    ``a' + (x_u + e (sigma - 1) l) R u + (c x_1 - s x_2) R v1 + (s x_1 + c x_2) R v2``
    with ``c, s = cos(phi), sin(phi)``: per vertex only two scalars per slot depend on the
    twist, and no rotation is applied per vertex.
    """
    R = pose.matrices(xp)
    u = bones.u
    v1, v2 = _complement(xp, u)
    twist, stretch = pose.theta is not None, pose.sigma is not None
    fields = list(_fields(pose.O, 3))
    for v in (u, v1, v2):
        fields += list(_fields(xp.sum(R * v[:, None, :], axis=-1), 3))      # R v
    if stretch:
        fields.append((pose.sigma - 1.0) * bones.ell)
    if twist:
        th = pose.theta
        fields += [th[..., 0], th[..., 1] - th[..., 0]]
    F = _Fields(xp, fields, batch, lay)
    acc = None
    for j, ij in enumerate(lay.idx):
        f = F.slot(j)
        x = lay.P - xp.take(bones.a, ij, axis=0)                            # (n, 3), rest
        xu, x1, x2 = (F.vertex(xp.sum(x * xp.take(v, ij, axis=0), axis=-1))
                      for v in (u, v1, v2))
        ej = F.vertex(lay.e[:, j])
        if stretch:
            xu = xu + ej * f[12]
        if twist:
            k = 13 if stretch else 12
            phi = f[k] + ej * f[k + 1]
            cs, sn = xp.cos(phi), xp.sin(phi)
            x1, x2 = cs * x1 - sn * x2, sn * x1 + cs * x2
        y = [f[i] + xu * f[3 + i] + x1 * f[6 + i] + x2 * f[9 + i] for i in range(3)]
        wj = F.vertex(lay.w[:, j])
        acc = [wj * v for v in y] if acc is None else [acc[i] + wj * y[i] for i in range(3)]
    return F.output(tuple(acc))


def stbs_dqs(xp, bones: Bones, pose: PoseArrays, lay: Layout, batch: tuple):
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
    fields = list(R1 + D1 + R2 + D2)
    if stretch:
        fields.append(0.5 * (pose.sigma - 1.0) * bones.ell)
    if twist:
        th = pose.theta
        fields += [0.5 * th[..., 0], 0.5 * (th[..., 1] - th[..., 0])]
    F = _Fields(xp, fields, batch, lay)
    acc = None
    for j in range(len(lay.idx)):
        f = F.slot(j)
        ej = F.vertex(lay.e[:, j])
        r1, d1, r2, d2 = f[0:4], f[4:8], f[8:12], f[12:16]
        k = 17 if stretch else 16
        if twist:
            h = f[k] + ej * f[k + 1]
            ch, sh = xp.cos(h), xp.sin(h)
            real = tuple(ch * x + sh * y for x, y in zip(r1, r2, strict=True))
            if stretch:     # dual = ch (D1 + e c R2) + sh (D2 - e c R1)
                ec = ej * f[16]
                d1 = tuple(x + ec * y for x, y in zip(d1, r2, strict=True))
                d2 = tuple(x - ec * y for x, y in zip(d2, r1, strict=True))
            dual = tuple(ch * x + sh * y for x, y in zip(d1, d2, strict=True))
        else:
            real, dual = r1, d1
            if stretch:
                ec = ej * f[16]
                dual = tuple(z + ec * y for z, y in zip(dual, r2, strict=True))
        acc = _blend_add(xp, acc, real, dual, F.vertex(lay.w[:, j]))
    return F.output(dq_apply(acc[0], acc[1], F.points()))


METHOD_FUNCS = {"lbs": lbs, "dqs": dqs, "stbs-lbs": stbs_lbs, "stbs-dqs": stbs_dqs}


def deform(xp, method: str, bones: Bones, pose: PoseArrays, lay: Layout, batch: tuple):
    """(*B, n, 3) deformed points of ``lay.P`` by ``method``."""
    return METHOD_FUNCS[method](xp, bones, pose, lay, batch)
