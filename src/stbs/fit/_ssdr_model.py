"""The STBS-SSDR model and its block updates (private to :mod:`stbs.fit.ssdr`).

Bone i of the decomposition maps a rest vertex p with endpoint weight e (eq. 5) to

    T_i(p, e) = a'_i + R_i K_i(e) (e s_i + p - a_i),   s_i = (sigma_i - 1) (b_i - a_i),

and since ``K_i`` turns about the rest axis ``u_i`` and ``s_i`` lies along it, with
``q = p - a_i = z u_i + r`` (``z`` axial, ``r`` radial) this is

    T_i = a'_i + R_i [ (z + e (sigma_i - 1) l_i) u_i + cos(th) r + sin(th) u_i x r ],
    th  = (1 - e) theta_a,i + e theta_b,i.

A frame is ``sum_i w_i T_i``. Every update below is a block of a coordinate descent on
``sum_f sum_v |sum_i w_vi T_fi(v) - y_fv|^2``: one bone's transforms in all frames with
the other bones held (weighted Procrustes for ``R, a'``, a linear solve for ``sigma``,
a Gauss-Newton step for the twists), or one bone's endpoint weights at its vertices.
Arrays: frames ``Y`` (F, n, 3), per-frame bone parameters ``R`` (F, b, 3, 3), ``O``
(posed starts, F, b, 3), ``sig`` (F, b), ``th`` (F, b, 2).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Stretches are kept in this range (posed length / rest length): a bone whose vertices
#: barely feel its stretch would otherwise collapse or grow without bound.
SIGMA_RANGE = (0.25, 4.0)
#: Largest twist difference along one bone, |theta_b - theta_a| (a half turn each way).
TWIST_SPAN = np.pi
#: Candidate endpoint weights tried per vertex in the E step (plus the current one).
E_GRID = 21


@dataclass
class Bones:
    """Rest segments: starts ``a`` (b, 3), unit axes ``u`` (b, 3), lengths ``ell`` (b,)."""

    a: np.ndarray
    u: np.ndarray
    ell: np.ndarray

    @property
    def ends(self) -> np.ndarray:
        return self.a + self.ell[:, None] * self.u


@dataclass
class State:
    """Everything the alternation updates; ``P`` (F, n, 3) is the current fit of ``Y``."""

    W: np.ndarray        # (n, b)
    E: np.ndarray        # (n, b)
    R: np.ndarray        # (F, b, 3, 3)
    O: np.ndarray        # (F, b, 3)
    sig: np.ndarray      # (F, b)
    th: np.ndarray       # (F, b, 2)
    P: np.ndarray | None = None


# --------------------------------------------------------------------------- evaluation
def local_points(X, e, a, u, ell, sig, th) -> np.ndarray:
    """``K(e)(e s + p - a)`` (F, m, 3) for rest points ``X`` (m, 3) of one bone.

    ``e`` (m,), ``a``, ``u`` (3,), ``ell`` float, ``sig`` (F,), ``th`` (F, 2).
    """
    q = X - a
    z = q @ u
    r = q - z[:, None] * u
    ur = np.cross(u, r)
    ang = th[:, :1] * (1.0 - e) + th[:, 1:] * e                      # (F, m)
    axial = z + e * ((sig[:, None] - 1.0) * ell)                     # (F, m)
    return (axial[..., None] * u + np.cos(ang)[..., None] * r
            + np.sin(ang)[..., None] * ur)


def bone_points(X, e, bones: Bones, i: int, st: State) -> np.ndarray:
    """``T_i`` (F, m, 3) of rest points ``X`` (m, 3) with endpoint weights ``e`` (m,)."""
    M = local_points(X, e, bones.a[i], bones.u[i], bones.ell[i], st.sig[:, i], st.th[:, i])
    return st.O[:, i, None, :] + M @ st.R[:, i].transpose(0, 2, 1)


def reconstruct(X, bones: Bones, st: State) -> np.ndarray:
    """``sum_i w_i T_i`` (F, n, 3) over every bone's support."""
    F = st.R.shape[0]
    P = np.zeros((F,) + X.shape)
    for i in range(st.W.shape[1]):
        idx = np.flatnonzero(st.W[:, i] > 0)
        if idx.size:
            P[:, idx] += st.W[idx, i, None] * bone_points(X[idx], st.E[idx, i], bones, i, st)
    return P


def sq_error(P, Y) -> float:
    return float(np.einsum("fni,fni->", P - Y, P - Y))


# --------------------------------------------------------------------------- rotations
def procrustes(H: np.ndarray) -> np.ndarray:
    """Rotations (..., 3, 3) maximising ``tr(R H)``-style fits: ``H = sum M (x) Y``."""
    U, _, Vt = np.linalg.svd(H)
    d = np.sign(np.linalg.det(np.einsum("...ij,...jk->...ik", U, Vt)))
    d = np.where(d == 0, 1.0, d)
    Vt = Vt.copy()
    Vt[..., 2, :] *= d[..., None]
    return np.einsum("...ji,...kj->...ik", Vt, U)        # V diag(1, 1, d) U^T


def axis_rotation(u: np.ndarray, ang: np.ndarray) -> np.ndarray:
    """Rotations (F, 3, 3) by ``ang`` (F,) about the unit axis ``u`` (3,) (Rodrigues)."""
    K = np.array([[0.0, -u[2], u[1]], [u[2], 0.0, -u[0]], [-u[1], u[0], 0.0]])
    s, c = np.sin(ang)[:, None, None], np.cos(ang)[:, None, None]
    return np.eye(3) + s * K + (1.0 - c) * (K @ K)


# --------------------------------------------------------------------------- bone step
def _fit_rigid(M, w, Z):
    """Per frame ``R, O`` minimising ``sum_m |w_m (O + R M_m) - Z_m|^2`` (F, m, 3)."""
    w2 = w * w
    S = w2.sum()
    Mbar = np.einsum("m,fmi->fi", w2, M) / S
    Zbar = np.einsum("m,fmi->fi", w, Z) / S
    H = (w[:, None] * M).transpose(0, 2, 1) @ Z - S * Mbar[:, :, None] * Zbar[:, None, :]
    R = procrustes(H)
    return R, Zbar - np.einsum("fij,fj->fi", R, Mbar)


def _fit_stretch(L, w, e, z, ell, sig_old):
    """Least-squares ``sigma`` (F,) from the axial residual ``L.u`` (F, m)."""
    we = w * e * ell
    den = float(we @ we)
    if den <= 1e-12 * max(float((w * z) @ (w * z)), 1e-300):
        return sig_old                      # no vertex feels this bone's stretch
    num = (L - w * z) @ we
    return np.clip(1.0 + num / den, *SIGMA_RANGE)


def _fit_twist(c, s, w, e, th_old):
    """Twists (F, 2) and a common turn (F,) from the radial fit angles.

    The radial residual is ``const - 2 w rho cos(th_m - phi_m)``; one Gauss-Newton step
    on ``th_m = alpha + e_m beta`` (the quadratic model ``w rho (th - phi)^2 / 2``)
    gives alpha and beta per frame. Returns the twist pair with the common turn taken
    out (``theta_a = -beta/2, theta_b = beta/2``) and that turn.
    """
    kap = w * np.hypot(c, s)                                   # (F, m)
    phi = np.arctan2(s, c)
    cur = th_old[:, :1] * (1.0 - e) + th_old[:, 1:] * e
    phi = cur + np.angle(np.exp(1j * (phi - cur)))             # nearest branch
    # normal equations of sum kap (alpha + e beta - phi)^2, beta gently held
    s0 = kap.sum(axis=1)
    s1 = kap @ e
    s2 = kap @ (e * e)
    t0 = (kap * phi).sum(axis=1)
    t1 = (kap * phi) @ e
    ridge = 1e-9 * (s0 + 1e-300)
    beta_old = th_old[:, 1] - th_old[:, 0]
    s2r = s2 + ridge
    t1r = t1 + ridge * beta_old
    det = s0 * s2r - s1 * s1
    ok = det > 1e-12 * np.maximum(s0 * s2r, 1e-300)
    safe = np.where(ok, det, 1.0)
    alpha = np.where(ok, (s2r * t0 - s1 * t1r) / safe, t0 / np.maximum(s0, 1e-300))
    beta = np.where(ok, (s0 * t1r - s1 * t0) / safe, beta_old)
    clipped = np.clip(beta, -TWIST_SPAN, TWIST_SPAN)
    alpha = alpha + (beta - clipped) * (s1 / np.maximum(s0, 1e-300))   # best alpha for it
    beta = clipped
    turn = alpha + 0.5 * beta
    return np.stack([-0.5 * beta, 0.5 * beta], axis=1), turn


def fit_bone(X, Y, bones: Bones, i: int, st: State, *, stbs: bool, rounds: int = 2) -> None:
    """Refit bone i's transforms in every frame with the other bones held; updates
    ``st`` (``R, O, sig, th`` of bone i and ``P``) in place, never raising the error."""
    idx = np.flatnonzero(st.W[:, i] > 0)
    if idx.size == 0:
        return
    w = st.W[idx, i]
    e = st.E[idx, i]
    Xi = X[idx]
    T_old = bone_points(Xi, e, bones, i, st)
    Z = Y[:, idx] - (st.P[:, idx] - w[:, None] * T_old)        # what bone i should make
    best = float(np.einsum("fmi,fmi->", w[:, None] * T_old - Z, w[:, None] * T_old - Z))
    a, u, ell = bones.a[i], bones.u[i], bones.ell[i]
    q = Xi - a
    z = q @ u
    r = q - z[:, None] * u
    ur = np.cross(u, r)
    keep = (st.R[:, i].copy(), st.O[:, i].copy(), st.sig[:, i].copy(), st.th[:, i].copy())
    for _ in range(rounds):
        M = local_points(Xi, e, a, u, ell, st.sig[:, i], st.th[:, i])
        st.R[:, i], st.O[:, i] = _fit_rigid(M, w, Z)
        if not stbs:
            break
        # the residual in the bone's rest frame: R^T (Z - w O)
        L = (Z - w[:, None] * st.O[:, i, None, :]) @ st.R[:, i]
        st.sig[:, i] = _fit_stretch(L @ u, w, e, z, ell, st.sig[:, i])
        Lr = L - (L @ u)[..., None] * u
        th, turn = _fit_twist(np.einsum("fmi,mi->fm", Lr, r), np.einsum("fmi,mi->fm", Lr, ur),
                              w, e, st.th[:, i])
        st.R[:, i] = st.R[:, i] @ axis_rotation(u, turn)
        st.th[:, i] = th
        # O for the new twist and stretch (the rigid optimum given R)
        M = local_points(Xi, e, a, u, ell, st.sig[:, i], st.th[:, i])
        w2 = w * w
        Mw = np.einsum("m,fmi->fi", w2, M)
        st.O[:, i] = (np.einsum("m,fmi->fi", w, Z)
                      - np.einsum("fij,fj->fi", st.R[:, i], Mw)) / w2.sum()
    T_new = bone_points(Xi, e, bones, i, st)
    D = w[:, None] * T_new - Z
    if float(np.einsum("fmi,fmi->", D, D)) > best:        # a step that did not help
        st.R[:, i], st.O[:, i], st.sig[:, i], st.th[:, i] = keep
        return
    st.P[:, idx] += w[:, None] * (T_new - T_old)


# --------------------------------------------------------------------------- E step
def fit_endpoints(X, Y, bones: Bones, i: int, st: State, E0: np.ndarray, lam: float) -> None:
    """Endpoint weights of bone i at its vertices, one 1D search each, others held:
    ``min_e sum_f |w T_fi(p, e) - z_f|^2 + lam (e - e0)^2`` over ``e`` in [0, 1]
    (a grid, then a parabola through the best grid point and its neighbours)."""
    idx = np.flatnonzero(st.W[:, i] > 0)
    if idx.size == 0:
        return
    w = st.W[idx, i]
    Xi = X[idx]
    e_old = st.E[idx, i]
    e0 = E0[idx, i]
    T_old = bone_points(Xi, e_old, bones, i, st)
    Z = Y[:, idx] - (st.P[:, idx] - w[:, None] * T_old)

    # |w M(e) - G|^2 with G = R^T (z - w O) (the residual in the bone's rest frame),
    # M(e) = (z + e ds) u + cos(th(e)) r + sin(th(e)) u x r: scalars per frame and vertex
    a, u, ell = bones.a[i], bones.u[i], bones.ell[i]
    q = Xi - a
    z = q @ u
    r = q - z[:, None] * u
    G = (Z - w[:, None] * st.O[:, i, None, :]) @ st.R[:, i]
    gu, gc, gs = G @ u, np.einsum("fmi,mi->fm", G, r), np.einsum("fmi,mi->fm", G, np.cross(u, r))
    ds = ((st.sig[:, i] - 1.0) * ell)[:, None]                      # (F, 1)
    ta, tb = st.th[:, i, :1], st.th[:, i, 1:]

    def cost(e):
        ang = ta + e * (tb - ta)
        ax = z + e * ds
        f = w * w * ax * ax - 2 * w * (ax * gu + np.cos(ang) * gc + np.sin(ang) * gs)
        return f.sum(axis=0) + lam * (e - e0) ** 2

    grid = np.linspace(0.0, 1.0, E_GRID)
    C = np.stack([cost(np.full(idx.size, g)) for g in grid])           # (G, m)
    j = np.argmin(C, axis=0)
    jl, jr = np.maximum(j - 1, 0), np.minimum(j + 1, E_GRID - 1)
    cols = np.arange(idx.size)
    cl, cm, cr = C[jl, cols], C[j, cols], C[jr, cols]
    h = grid[1] - grid[0]
    curv = cl - 2 * cm + cr
    inner = (j > 0) & (j < E_GRID - 1) & (curv > 0)
    step = np.where(inner, 0.5 * h * (cl - cr) / np.where(inner, curv, 1.0), 0.0)
    cand = np.clip(grid[j] + step, 0.0, 1.0)
    c_cand = cost(cand)
    c_old = cost(e_old)
    e_new = np.where(c_cand < cm, cand, grid[j])
    c_new = np.minimum(c_cand, cm)
    e_new = np.where(c_new < c_old, e_new, e_old)
    st.E[idx, i] = e_new
    T_new = bone_points(Xi, e_new, bones, i, st)
    st.P[:, idx] += w[:, None] * (T_new - T_old)
