"""Weights of a rig fitted to example meshes in known poses.

Given the rest mesh ``V``, its skeleton, m example poses and the m meshes ``frames``
those poses should produce, find the weights that reproduce them best in the least
squares sense, summed over all frames and vertices:

- :func:`fit_endpoint_weights`: endpoint weights E for fixed bone weights W;
- :func:`fit_weights`: W (bounded, summing to one, at most k bones per vertex, smooth
  across the surface) and E together, by alternating the two solves.

The endpoint solve (stbs-lbs, DESIGN eq. 5)
-------------------------------------------
At a vertex p, bone i contributes ``w_i x_i(e)`` with
``x_i(e) = a'_i + R_i K_i(e) (e s_i + p - a_i)``. Because ``s_i`` lies along the bone's
rest axis ``u_i`` and ``K_i`` turns about that axis, only the axial part of
``q = e s_i + p - a_i`` depends on e, and ``||q||`` does not depend on the twist. With
the other bones' contributions fixed, the squared residual summed over frames is
therefore, as a function of the one unknown ``e = e_i``::

    h(e) = c1 e + c2 e^2 + sum_f 2 [P_f cos(theta_f(e)) + Q_f sin(theta_f(e))] + const,
    theta_f(e) = (1 - e) theta_a,f + e theta_b,f

a quadratic plus one sinusoid per frame whose twist varies along the bone. Without such
frames its minimiser over [0, 1] is the clamped vertex of the parabola. Otherwise ``h``
is sampled on a grid fine enough that each interval spans at most an eighth of the
fastest sinusoid's period, and the best sample's two intervals are searched for the
root of ``h'`` by safeguarded Newton (bisection when Newton leaves the bracket); the
best of that root and the bracket's ends is kept. Each step is the exact minimiser of
the residual over ``e_i`` in [0, 1] (up to rounding), never increases the residual,
and is computed for all vertices of the bone at once.

Block coordinate descent sweeps the bones (in a seeded random order per sweep); after
each sweep one Gauss-Newton step on all of a vertex's e together (kept only where it
lowers that vertex's residual) speeds up vertices whose bones are coupled, where
coordinate descent alone converges only linearly. It stops once a sweep changes no
``w_i e_i`` by more than ``tol``. The residual is not convex in E jointly, so the
descent finds a local minimum; from projection endpoint weights and with a few frames
that stretch and twist each bone it finds the true E of noise-free examples.

``method="stbs-dqs"`` (eq. 6) uses the same descent on the dual-quaternion model: the
1D residual is evaluated exactly (blend, normalise, apply) on the same grid and refined
by golden-section search; the Gauss-Newton step takes a forward-difference Jacobian;
whenever the descent settles, a joint grid search over each pair of bones sharing
vertices (one of which twists) looks for a better minimum and the descent resumes from
it. It is a local method: where two bones at a vertex turn more than 180 degrees apart
in some frame, a quaternion crosses its pivot's hemisphere as e moves, the residual
jumps there, and the true E can lie in a narrow valley between such jumps that
coordinate and grid moves miss. Below that (bends and twists that keep the bones within
180 degrees of each other) the residual is smooth in E and noise-free E is recovered.

Bone weights (fit_weights)
--------------------------
Each round solves (a) W given E exactly (stbs-lbs is linear in W; a k-sparse bounded
least-squares problem per vertex, :func:`stbs.fit._lsq.simplex_qp`), then (b) E given W
by a few sweeps of the descent above, then up to a few Gauss-Newton steps on W and E
together on the current supports (w >= 0 and summing to one, e in [0, 1]; each kept
only where it lowers the vertex's objective). Alternating (a) and (b) alone converges
linearly where W and E are coupled; with the joint steps noise-free examples are fitted
to rounding in a few rounds.

Which entries are fitted
------------------------
``e_i`` at a vertex is fitted where ``w_i > 0`` there and bone i stretches
(``sigma != 1``) or twists non-uniformly (``theta_a != theta_b``) in at least one
frame. Elsewhere e_i has no effect on any frame and keeps its starting value (``E0``,
by default projection endpoint weights, eq. 8), so the result stays a usable rig.

Progress and cancelling
-----------------------
``progress(stage, done, total)`` is called with ``(stage, 0, 0)`` when a stage starts,
then with ``done`` of ``total`` once per bone update (stage ``"endpoint weights"``) or
per round (stage ``"fit weights"``); raise any exception from it to cancel (it
propagates unchanged and ``progress`` is not called again).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Literal

import numpy as np
import scipy.sparse as sp

from .. import _checks
from .. import transforms as tf
from ..pose import Pose, pose_list
from ..skeleton import Skeleton
from ._lsq import simplex_objective, simplex_qp

__all__ = ["fit_endpoint_weights", "fit_weights", "FIT_METHODS", "Progress"]

Progress = Callable[[str, int, int], None]
#: Skinning models the fits support.
FIT_METHODS = ("stbs-lbs", "stbs-dqs")
#: Grid samples per radian of the fastest twist rate (an eighth of a period per interval).
_GRID_PER_RADIAN = 8 / (2 * np.pi)
_GRID_MIN = 17
_NEWTON_STEPS = 40
_GOLDEN_STEPS = 32
#: Entries of (frames x vertices x bones x 4 or 6) arrays held at once.
_CHUNK = 1 << 22
#: Endpoint sweeps and joint Gauss-Newton steps per round of fit_weights.
_INNER_SWEEPS = 3
_JOINT_STEPS = 4
#: Jacobi steps of the smoothness prior per W step.
_PRIOR_STEPS = 5
#: Most joint pair searches of the stbs-dqs descent.
_PAIR_ROUNDS = 2


# ============================================================================ inputs
def _inputs(V, sk, poses, frames):
    """Checked ``V`` (n, d) and ``frames`` (m, n, d) float64, poses as a list."""
    V = _checks.skeleton(sk, V)
    n, d = V.shape
    poses = pose_list(poses, sk)
    try:
        Y = np.asarray(frames, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        shapes = [np.shape(x) for x in frames] if isinstance(frames, Sequence) else "?"
        raise ValueError(f"frames must be example meshes of shape (m, {n}, {d}) like V "
                         f"{V.shape}; got shapes {shapes}: {exc}") from None
    if Y.ndim == 2 and Y.shape == V.shape:
        raise ValueError(f"frames must be a stack of example meshes, shape (m, {n}, {d}); got "
                         f"one mesh of shape {Y.shape}; wrap it in a list")
    if Y.ndim != 3 or Y.shape[1:] != V.shape:
        raise ValueError(f"frames must have shape (m, {n}, {d}): each frame shaped like V "
                         f"{V.shape}; got frames of shape {Y.shape}")
    if Y.shape[0] == 0:
        raise ValueError("frames must hold at least one example mesh, got 0 frames")
    if Y.shape[0] != len(poses):
        raise ValueError(f"poses and frames must have one pose per frame, got {len(poses)} "
                         f"poses and {Y.shape[0]} frames")
    if not np.all(np.isfinite(Y)):
        f, v, c = (int(i) for i in np.argwhere(~np.isfinite(Y))[0])
        raise ValueError(f"frames must be finite, got {Y[f, v, c]} at frame {f}, vertex {v}, "
                         f"coordinate {c}")
    return V, Y, poses


def _dense(X) -> np.ndarray:
    return np.asarray(X.toarray() if sp.issparse(X) else X, dtype=np.float64).copy()


def _start_E(V, sk, E0, n: int, b: int) -> np.ndarray:
    if E0 is None:
        from ..weights.endpoint import endpoint_weights
        return _dense(endpoint_weights(V, sk, method="projection"))
    return _dense(_checks.endpoint_weights(E0, n, b, name="E0"))


def _positive_int(name: str, value) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ValueError(f"{name} must be a positive integer, got {value!r}")
    return int(value)


def _nonneg(name: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.number)) \
            or not np.isfinite(value) or value < 0:
        raise ValueError(f"{name} must be a finite number >= 0, got {value!r}")
    return float(value)


# ============================================================================ the poses
class _Rig:
    """The rest mesh and the per-frame bone constants, in 3D (2D embedded at z = 0)."""

    def __init__(self, V: np.ndarray, sk: Skeleton, poses: list[Pose], Y: np.ndarray):
        d = sk.dim
        pad = (lambda X: np.concatenate([X, np.zeros(X.shape[:-1] + (1,))], axis=-1)) \
            if d == 2 else (lambda X: X)
        self.d = d
        self.P = pad(V)
        self.Y = pad(Y)                                              # (m, n, 3)
        self.A, self.U = pad(sk.A), pad(sk.axes)                     # (b, 3)
        self.L = sk.lengths
        R = np.stack([p.rotations for p in poses])                   # (m, b, d, d)
        self.R = tf.embed_rotation_2d(R) if d == 2 else R
        self.Ap = pad(np.stack([p.origins for p in poses]))          # (m, b, 3)
        self.sigma = np.stack([p.stretch for p in poses])            # (m, b)
        th = np.stack([p.twist for p in poses])                      # (m, b, 2)
        self.ta, self.dt = th[..., 0], th[..., 1] - th[..., 0]
        self.k = (self.sigma - 1.0) * self.L                         # axial stretch length
        self.qR = tf.matrix_to_quat(self.R)                          # (m, b, 4)

    def active(self, i: int) -> bool:
        """Whether e_i has any effect: bone i stretches or twists non-uniformly."""
        return bool(np.any(self.k[:, i] != 0) or np.any(self.dt[:, i] != 0))

    def bone_points(self, i: int, idx: np.ndarray, e: np.ndarray, slope: bool = False):
        """``x_i(e)`` (m, r, 3) of eq. 5 at the vertices ``idx`` with their e (r,), and
        with ``slope`` its derivative in e too.

        With ``g = p - a_i`` split into its axial length ``g.u`` and the part ``g_perp``
        across the axis, ``K(phi) (e s + g) = (g.u + e k) u + cos(phi) g_perp +
        sin(phi) u x g_perp``, so ``x = a' + (g.u + e k) R u + cos(phi) R g_perp +
        sin(phi) R (u x g_perp)`` and ``dx/de = k R u + dtheta (cos(phi) R (u x g_perp)
        - sin(phi) R g_perp)``.
        """
        u = self.U[i]
        g = self.P[idx] - self.A[i]
        gu = g @ u
        perp = g - gu[:, None] * u
        Rt = np.swapaxes(self.R[:, i], 1, 2)                          # (m, 3, 3)
        Rp = perp @ Rt                                                # (m, r, 3)
        Rc = np.cross(u, perp) @ Rt
        Ru = self.R[:, i] @ u                                         # (m, 3)
        phi = self.ta[:, i, None] + e[None, :] * self.dt[:, i, None]
        c, s = np.cos(phi)[..., None], np.sin(phi)[..., None]
        k = self.k[:, i, None, None]
        x = self.Ap[:, i, None, :] + (gu[None, :, None] + e[None, :, None] * k) \
            * Ru[:, None, :] + c * Rp + s * Rc
        if not slope:
            return x
        return x, k * Ru[:, None, :] + self.dt[:, i, None, None] * (c * Rc - s * Rp)

    def predict(self, W: np.ndarray, E: np.ndarray) -> np.ndarray:
        """stbs-lbs positions (m, n, 3) of every frame."""
        out = np.zeros_like(self.Y)
        for i in range(W.shape[1]):
            idx = np.flatnonzero(W[:, i] > 0)
            if idx.size:
                out[:, idx] += W[idx, i, None] * self.bone_points(i, idx, E[idx, i])
        return out

    def dq_constants(self):
        """Per frame and bone, what eq. 6's dual quaternion of bone i at e is built from.

        ``R_i K_i(e)`` has quaternion ``cos(phi/2) qR + sin(phi/2) qR (0, u)`` and the map's
        translation ``a' + R K (e s - a)`` is ``T0 + e T1 + cos(phi) T2 + sin(phi) T3``
        (K fixes the axis and turns the part of ``a`` across it).
        """
        if not hasattr(self, "_dq"):
            m, b = self.sigma.shape
            u0 = np.concatenate([np.zeros((b, 1)), self.U], axis=1)
            qRu = tf.quat_mul(self.qR, np.broadcast_to(u0, (m, b, 4)))
            Ru = np.einsum("fbij,bj->fbi", self.R, self.U)
            au = np.sum(self.A * self.U, axis=1)
            a_perp = self.A - au[:, None] * self.U
            T0 = self.Ap - au[None, :, None] * Ru
            T1 = self.k[..., None] * Ru
            T2 = -np.einsum("fbij,bj->fbi", self.R, a_perp)
            T3 = -np.einsum("fbij,bj->fbi", self.R, np.cross(self.U, a_perp))
            # component-first (4 or 3, m, b) for fast per-vertex arithmetic
            self._dq = tuple(np.moveaxis(X, -1, 0).copy() for X in (self.qR, qRu, T0, T1,
                                                                     T2, T3))
        return self._dq

    def bone_dq(self, i: int, e: np.ndarray):
        """Unit dual quaternions (4, m, r) x 2 of eq. 6's rigid map of bone i at e (r,)."""
        qR, qRu, T0, T1, T2, T3 = (X[:, :, i, None] for X in self.dq_constants())
        phi = self.ta[:, i, None] + e[None, :] * self.dt[:, i, None]           # (m, r)
        q = np.cos(0.5 * phi) * qR + np.sin(0.5 * phi) * qRu
        t = T0 + e * T1 + np.cos(phi) * T2 + np.sin(phi) * T3
        # dual part 0.5 (0, t) q
        qd = 0.5 * np.stack([
            -(t[0] * q[1] + t[1] * q[2] + t[2] * q[3]),
            t[0] * q[0] + t[1] * q[3] - t[2] * q[2],
            -t[0] * q[3] + t[1] * q[0] + t[2] * q[1],
            t[0] * q[2] - t[1] * q[1] + t[2] * q[0]])
        return q, qd


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product of component-first (3, ...) arrays."""
    return np.stack([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                     a[0] * b[1] - a[1] * b[0]])


# ============================================================================ 1D minimisers
def _grid(dt_max: float, *, per_radian: float = _GRID_PER_RADIAN,
          least: int = _GRID_MIN) -> np.ndarray:
    """Samples of [0, 1], each interval at most an eighth of the fastest period (by
    default; the pair search takes a quarter)."""
    return np.linspace(0.0, 1.0, max(least, int(np.ceil(dt_max * per_radian)) + 1))


class _TrigQuadratic:
    """``h(e) = c1 e + c2 e^2 + 2 sum_f [P_f cos(ta_f + e dt_f) + Q_f sin(ta_f + e dt_f)]``
    per row r: c1, c2 (r,), P, Q (mt, r), ta, dt (mt,)."""

    def __init__(self, c1, c2, P, Q, ta, dt):
        self.c1, self.c2, self.P, self.Q, self.ta, self.dt = c1, c2, P, Q, ta, dt

    def _cs(self, e):
        phi = self.ta[:, None] + self.dt[:, None] * e[None, :]
        return np.cos(phi), np.sin(phi)

    def value(self, e):
        c, s = self._cs(e)
        return self.c1 * e + self.c2 * e * e + 2 * np.sum(self.P * c + self.Q * s, axis=0)

    def grid_values(self, grid):
        """h at every grid point for every row: (g, r)."""
        phi = self.ta[None, :] + grid[:, None] * self.dt[None, :]               # (g, mt)
        return (grid[:, None] * self.c1 + (grid * grid)[:, None] * self.c2
                + 2 * (np.cos(phi) @ self.P + np.sin(phi) @ self.Q))

    def slopes(self, e):
        """h' and h'' at e (r,)."""
        c, s = self._cs(e)
        dt = self.dt[:, None]
        d1 = self.c1 + 2 * self.c2 * e + 2 * np.sum(dt * (self.Q * c - self.P * s), axis=0)
        d2 = 2 * self.c2 - 2 * np.sum(dt * dt * (self.P * c + self.Q * s), axis=0)
        return d1, d2

    def root(self, lo, hi, x):
        """Root of h' in [lo, hi] where h'(lo) < 0 < h'(hi): safeguarded Newton from x,
        each row until its step or its bracket falls below 1e-11 (about the precision
        of h' near its root: it sums terms much larger than itself)."""
        out = x.copy()
        rows = np.arange(x.size)
        h = self
        for _ in range(_NEWTON_STEPS):
            d1, d2 = h.slopes(x)
            lo = np.where(d1 < 0, x, lo)
            hi = np.where(d1 > 0, x, hi)
            with np.errstate(divide="ignore", invalid="ignore"):
                xn = x - d1 / d2
            newton = (d2 > 0) & (xn >= lo) & (xn <= hi)
            done = newton & (np.abs(xn - x) <= 1e-11) | (hi - lo <= 1e-11) | (d1 == 0)
            xn = np.where(newton, xn, 0.5 * (lo + hi))
            out[rows] = np.where(done, x, xn)
            if done.all():
                break
            go = ~done
            rows, lo, hi, x = rows[go], lo[go], hi[go], xn[go]
            h = h.subset(go)
        return out

    def subset(self, keep: np.ndarray) -> _TrigQuadratic:
        return _TrigQuadratic(self.c1[keep], self.c2[keep], self.P[:, keep], self.Q[:, keep],
                              self.ta, self.dt)


def _minimise_trig(h: _TrigQuadratic, e_old: np.ndarray) -> np.ndarray:
    """The minimiser over [0, 1] of h per row (the previous value where none is better)."""
    if h.dt.size == 0:                       # no twist: a parabola, its clamped vertex
        with np.errstate(divide="ignore", invalid="ignore"):
            e = np.clip(-h.c1 / (2 * h.c2), 0.0, 1.0)
        return np.where(h.c2 > 0, e, e_old)
    grid = _grid(float(np.abs(h.dt).max()))
    kb = np.argmin(h.grid_values(grid), axis=0)
    lo, hi = grid[np.maximum(kb - 1, 0)], grid[np.minimum(kb + 1, grid.size - 1)]
    d_lo, d_hi = h.slopes(lo)[0], h.slopes(hi)[0]
    inside = (d_lo < 0) & (d_hi > 0)
    root = grid[kb].copy()
    if inside.any():
        root[inside] = h.subset(inside).root(lo[inside], hi[inside], root[inside])
    cand = np.stack([e_old, lo, hi, root])
    vals = np.stack([h.value(c) for c in cand])
    return cand[np.argmin(vals, axis=0), np.arange(e_old.size)]


def _minimise_sampled(f, e_old: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """Minimiser over [0, 1] of a 1D function per row ``f(e (r,)) -> (r,)``: the best
    grid sample, refined by golden-section search over its two intervals."""
    r = e_old.size
    vals = np.stack([f(np.full(r, t)) for t in grid])
    kb = np.argmin(vals, axis=0)
    lo, hi = grid[np.maximum(kb - 1, 0)], grid[np.minimum(kb + 1, grid.size - 1)]
    g = (np.sqrt(5.0) - 1) / 2
    x1, x2 = hi - g * (hi - lo), lo + g * (hi - lo)
    f1, f2 = f(x1), f(x2)
    for _ in range(_GOLDEN_STEPS):
        left = f1 <= f2                      # the minimum lies in [lo, x2]
        hi = np.where(left, x2, hi)
        lo = np.where(left, lo, x1)
        x1n = np.where(left, hi - g * (hi - lo), x2)
        x2n = np.where(left, x1, lo + g * (hi - lo))
        fn = f(np.where(left, x1n, x2n))
        f1, f2 = np.where(left, fn, f2), np.where(left, f1, fn)
        x1, x2 = x1n, x2n
    cand = np.stack([e_old, grid[kb], 0.5 * (lo + hi)])
    vals = np.stack([f(c) for c in cand])
    return cand[np.argmin(vals, axis=0), np.arange(r)]


# ============================================================================ bone steps
def _lbs_step(rig: _Rig, i: int, idx, W, E, pred) -> float:
    """Exact update of e_i at the vertices ``idx`` (stbs-lbs); updates E and pred."""
    w, e_old = W[idx, i], E[idx, i]
    u = rig.U[i]
    x_old = rig.bone_points(i, idx, e_old)
    # alpha = (other bones - target) + w a'_i, turned back by R_i; the residual is
    # ||alpha + w R_i K_i(e) q(e)||^2 = const + w (2 alpha . K q + w ||q||^2)
    alpha = pred[:, idx] - w[:, None] * x_old - rig.Y[:, idx] + w[:, None] * rig.Ap[:, i, None]
    alpha = alpha @ rig.R[:, i]
    gam = rig.P[idx] - rig.A[i]
    gu = gam @ u
    perp = gam - gu[:, None] * u
    k = rig.k[:, i]
    c1 = 2 * (k @ (alpha @ u)) + 2 * w * gu * k.sum()
    c2 = w * (k @ k)
    tw = np.flatnonzero(rig.dt[:, i] != 0)
    P = np.einsum("fri,ri->fr", alpha[tw], perp)
    Q = np.einsum("fri,ri->fr", alpha[tw], np.cross(u, perp))
    h = _TrigQuadratic(c1, c2, P, Q, rig.ta[tw, i], rig.dt[tw, i])
    e_new = _minimise_trig(h, e_old)
    pred[:, idx] += w[:, None] * (rig.bone_points(i, idx, e_new) - x_old)
    E[idx, i] = e_new
    return float(np.abs(w * (e_new - e_old)).max(initial=0.0))


def _dq_points(cr: np.ndarray, cd: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Blended dual quaternions (4, m, r) x 2, normalised, applied to P (3, 1, r)."""
    nrm = np.sqrt(np.sum(cr * cr, axis=0))
    cr, cd = cr / nrm, cd / nrm
    w0, v0, we, ve = cr[0], cr[1:], cd[0], cd[1:]
    t = 2.0 * (w0 * ve - we * v0 + _cross(v0, ve))          # translation of a unit DQ
    c = 2.0 * _cross(v0, np.broadcast_to(P, v0.shape))
    return P + w0 * c + _cross(v0, c) + t


class _DqsResidual:
    """The stbs-dqs residual of the vertices ``c`` (r,) as a function of the endpoint
    weights of the bones ``vary`` alone (eq. 6); the other bones' dual quaternions are
    computed once. Called with one (r,) array of e per bone in ``vary``."""

    def __init__(self, rig: _Rig, vary: Sequence[int], c: np.ndarray, W: np.ndarray,
                 E: np.ndarray):
        m = rig.Y.shape[0]
        Wc = W[c]
        J = np.flatnonzero(np.any(Wc > 0, axis=0))
        others = J[~np.isin(J, vary)]
        self.rig, self.vary = rig, list(vary)
        self.P = rig.P[c].T[:, None, :]                                   # (3, 1, r)
        self.Y = np.moveaxis(rig.Y[:, c], -1, 0)                          # (3, m, r)
        self.wv = [Wc[:, i] for i in self.vary]
        self.wo = Wc[:, others].T[:, None, :]                             # (o, 1, r)
        self.QR = np.empty((4, others.size, m, c.size))
        self.QD = np.empty_like(self.QR)
        for jj, j in enumerate(others):
            self.QR[:, jj], self.QD[:, jj] = rig.bone_dq(j, E[c, j])
        # the pivot: the heaviest bone at the vertex (DESIGN §3), as the Deformer picks it
        piv = J[np.argmax(Wc[:, J], axis=1)]
        self.piv_vary = [piv == i for i in self.vary]
        jo = np.clip(np.searchsorted(others, piv), 0, max(others.size - 1, 0))
        self.qp = self.QR[:, jo, :, np.arange(c.size)].transpose(1, 2, 0) \
            if others.size else None                                        # (4, m, r)

    def __call__(self, *es: np.ndarray) -> np.ndarray:
        return np.sum((self.points(*es) - self.Y) ** 2, axis=(0, 1))

    def points(self, *es: np.ndarray) -> np.ndarray:
        """Blended positions (3, m, r)."""
        qs = [self.rig.bone_dq(i, e) for i, e in zip(self.vary, es, strict=True)]
        qp = self.qp
        for (qr, _), mine in zip(qs, self.piv_vary, strict=True):
            qp = qr if qp is None else np.where(mine, qr, qp)
        so = np.where(np.einsum("kjfr,kfr->jfr", self.QR, qp) < 0, -1.0, 1.0) * self.wo
        cr = np.einsum("jfr,kjfr->kfr", so, self.QR)
        cd = np.einsum("jfr,kjfr->kfr", so, self.QD)
        for (qr, qd), w in zip(qs, self.wv, strict=True):
            si = np.where(np.sum(qr * qp, axis=0) < 0, -1.0, 1.0) * w
            cr = cr + si * qr
            cd = cd + si * qd
        return _dq_points(cr, cd, self.P)


def _chunks(rig: _Rig, idx: np.ndarray, b: int):
    step = max(1, _CHUNK // (rig.Y.shape[0] * b * 4))
    return (idx[s:s + step] for s in range(0, idx.size, step))


def _dqs_step(rig: _Rig, i: int, idx, W, E, pred) -> float:
    """Update of e_i at the vertices ``idx`` on the stbs-dqs model (pred unused)."""
    grid = _grid(float(np.abs(rig.dt[:, i]).max()))
    change = 0.0
    for c in _chunks(rig, idx, W.shape[1]):
        e_new = _minimise_sampled(_DqsResidual(rig, [i], c, W, E), E[c, i], grid)
        change = max(change, float(np.abs(W[c, i] * (e_new - E[c, i])).max(initial=0.0)))
        E[c, i] = e_new
    return change


def _dqs_polish(rig: _Rig, bones: list[int], W, E) -> int:
    """One Gauss-Newton step on all of a vertex's e together on the stbs-dqs model, with
    a forward-difference Jacobian (steps of 1e-7, taken inwards at the bounds); e
    pushed past a bound is held there; kept only where it lowers the vertex's residual.
    Returns how many vertices improved."""
    improved = 0
    h = 1e-7
    for c in _chunks(rig, np.flatnonzero(np.any(W[:, bones] > 0, axis=1)), W.shape[1]):
        vary = [i for i in bones if np.any(W[c, i] > 0)]
        f = _DqsResidual(rig, vary, c, W, E)
        es = [E[c, i] for i in vary]
        base = f.points(*es)
        cols = []
        for t in range(len(vary)):
            step = np.where(es[t] > 0.5, -h, h)
            moved = list(es)
            moved[t] = es[t] + step
            cols.append((f.points(*moved) - base) / step)
        Jc = np.stack(cols, axis=-1)                                  # (3, m, r, v)
        H = np.einsum("kfra,kfrb->rab", Jc, Jc)
        g = -np.einsum("kfra,kfr->ra", Jc, base - f.Y)
        Ec = E[c][:, vary]
        free = W[c][:, vary] > 0
        delta = _masked_solve(H, g, free)
        out = free & (((Ec <= 0) & (delta < 0)) | ((Ec >= 1) & (delta > 0)))
        if out.any():
            delta = _masked_solve(H, g, free & ~out)
        before = f(*es)
        for shrink in (1.0, 0.25):
            Et = np.clip(Ec + shrink * delta, 0.0, 1.0)
            better = f(*Et.T) < before
            rows = c[better]
            E[rows[:, None], np.array(vary)[None, :]] = Et[better]
            improved += int(better.sum())
            if better.all():
                break
            before = np.where(better, -np.inf, before)
            Ec = np.where(better[:, None], Et, Ec)
            delta = np.where(better[:, None], 0.0, delta)
    return improved


def _masked_solve(H: np.ndarray, g: np.ndarray, free: np.ndarray) -> np.ndarray:
    """``H d = g`` per row on the ``free`` unknowns (the others 0), with a tiny ridge."""
    a = g.shape[1]
    d = np.arange(a)
    M = np.where(free[:, :, None] & free[:, None, :], H, 0.0)
    M[:, d, d] += np.where(free, 1e-12 * np.abs(H[:, d, d]).max(axis=1, keepdims=True)
                           + 1e-300, 1.0)
    return np.linalg.solve(M, np.where(free, g, 0.0)[..., None])[..., 0]


def _dqs_pairs(rig: _Rig, bones: list[int], W, E) -> int:
    """Joint grid search over (e_i, e_j) for every pair of bones sharing vertices, to
    leave minima of the coordinate descent that a pair of bones holds (the dual
    quaternions' hemisphere flips make them common). Returns how many vertices moved."""
    moved = np.zeros(W.shape[0], bool)
    twists = [i for i in bones if np.any(rig.dt[:, i] != 0)]
    for i, j in ((i, j) for i in bones for j in bones if i < j):
        if i not in twists and j not in twists:
            continue             # no e moves a rotation: no hemisphere jumps, no traps
        idx = np.flatnonzero((W[:, i] > 0) & (W[:, j] > 0))
        gi, gj = (_grid(float(np.abs(rig.dt[:, x]).max()), per_radian=_GRID_PER_RADIAN / 2,
                        least=9) for x in (i, j))
        for c in _chunks(rig, idx, W.shape[1]):
            f = _DqsResidual(rig, [i, j], c, W, E)
            best = f(E[c, i], E[c, j])
            bi, bj = E[c, i].copy(), E[c, j].copy()
            for ei in gi:
                for ej in gj:
                    v = f(np.full(c.size, ei), np.full(c.size, ej))
                    better = v < best * (1 - 1e-9)
                    best = np.where(better, v, best)
                    bi, bj = np.where(better, ei, bi), np.where(better, ej, bj)
            moved[c] |= (bi != E[c, i]) | (bj != E[c, j])
            E[c, i], E[c, j] = bi, bj
    return int(moved.sum())


def _descend(rig: _Rig, W, E, *, method, iterations, tol, rng, say) -> tuple[np.ndarray, int]:
    """Block coordinate descent on E over the bones; returns E and the sweeps run.

    stbs-dqs: whenever the descent settles, a joint grid search over each pair of bones
    (:func:`_dqs_pairs`) looks for a better minimum; the descent resumes from what it
    finds, until it finds nothing (at most ``_PAIR_ROUNDS`` times).
    """
    b = W.shape[1]
    bones = [i for i in range(b) if rig.active(i)]
    pred = rig.predict(W, E) if method == "stbs-lbs" else None
    step = _lbs_step if method == "stbs-lbs" else _dqs_step
    supports = {i: np.flatnonzero(W[:, i] > 0) for i in bones}
    pair_rounds = _PAIR_ROUNDS if method == "stbs-dqs" else 0
    total = iterations * len(bones)
    say(0, 0)
    active = np.isin(np.arange(b), bones)
    for sweep in range(iterations):
        change = 0.0
        for t, i in enumerate(rng.permutation(bones)):
            if supports[i].size:
                change = max(change, step(rig, int(i), supports[i], W, E, pred))
            say(sweep * len(bones) + t + 1, total)
        if change > tol:
            # Gauss-Newton polish on E (module docs): coordinate descent alone converges
            # linearly where a vertex's bones are coupled
            E_before = E.copy()
            if pred is None:
                _dqs_polish(rig, bones, W, E)
            elif _joint_step(rig, W, E, None, None, active, fix_w=True):
                pred[...] = rig.predict(W, E)
            change = max(change, float(np.abs(W * (E - E_before)).max()))
        if change <= tol:
            if pair_rounds == 0 or _dqs_pairs(rig, bones, W, E) == 0:
                return E, sweep + 1
            pair_rounds -= 1
    return E, iterations


def _reporter(progress, stage: str):
    def say(done: int, total: int) -> None:
        if progress is not None:
            progress(stage, done, total)
    return say


# ============================================================================ public
def fit_endpoint_weights(V, sk: Skeleton, W, poses: Sequence[Pose], frames, *,
                         method: Literal["stbs-lbs", "stbs-dqs"] = "stbs-lbs", E0=None,
                         iterations: int = 100, tol: float = 1e-9, seed: int = 0,
                         progress: Progress | None = None) -> np.ndarray:
    """Endpoint weights E that best reproduce example meshes in known poses.

    Minimises ``sum_f ||deform(V, poses[f], W, E) - frames[f]||^2`` over E in [0, 1]
    by block coordinate descent over the bones, each step an exact 1D minimisation for
    all vertices at once (module docs). Entries that affect no frame keep ``E0``.

    Parameters
    ----------
    V : (n, d) float
        Rest positions.
    sk : Skeleton
    W : (n, b) ndarray or scipy.sparse
        Bone weights (>= 0, rows summing to 1), held fixed.
    poses : sequence of m Pose
        The known poses of the examples, poses of ``sk``.
    frames : (m, n, d) float
        The example meshes, vertex for vertex like ``V``.
    method : {"stbs-lbs", "stbs-dqs"}
        The skinning model the examples follow (DESIGN eq. 5 or eq. 6).
    E0 : (n, b) ndarray or scipy.sparse, optional
        Starting endpoint weights in [0, 1], kept where e has no effect; default
        projection endpoint weights (eq. 8).
    iterations : int
        Most sweeps over the bones.
    tol : float
        Stop once a sweep changes no ``w_i e_i`` by more than this (an e whose weight
        is tiny moves points by little, so its change is weighed by ``w_i``).
    seed : int
        Seeds the random order in which each sweep visits the bones.
    progress : callable, optional
        ``progress(stage, done, total)``, stage ``"endpoint weights"``, one report per
        bone update; raise from it to cancel.

    Returns
    -------
    E : (n, b) float64 ndarray
        Endpoint weights in [0, 1].

    Raises
    ------
    ValueError
        Frames not shaped (m, n, d) like V, a pose count different from the frame
        count, no frames, non-finite frames, W or E0 of the wrong shape or range, an
        unknown method.
    """
    method = _checks.choice("method", method, FIT_METHODS)
    _checks.progress(progress, "progress(stage, done, total)")
    V, Y, poses = _inputs(V, sk, poses, frames)
    n, b = V.shape[0], sk.n_bones
    W = _dense(_checks.bone_weights(W, n, b))
    iterations = _positive_int("iterations", iterations)
    tol = _nonneg("tol", tol)
    E = _start_E(V, sk, E0, n, b)
    rig = _Rig(V, sk, poses, Y)
    E, _ = _descend(rig, W, E, method=method, iterations=iterations, tol=tol,
                    rng=np.random.default_rng(seed), say=_reporter(progress, "endpoint weights"))
    return np.clip(E, 0.0, 1.0)


def _neighbour_average(F, n: int):
    """Row-normalised vertex adjacency (n, n) of the triangles F and each vertex's
    neighbour count, for the smoothness prior."""
    F = _checks.index_array("F", F, ndim=2)
    if F.shape[1] != 3:
        raise ValueError(f"F must have shape (f, 3), got {F.shape}")
    if F.size and (F.min() < 0 or F.max() >= n):
        raise ValueError(f"F must hold vertex indices in 0..{n - 1}, got values in "
                         f"{F.min()}..{F.max()}")
    i = np.concatenate([F[:, 0], F[:, 1], F[:, 2], F[:, 1], F[:, 2], F[:, 0]])
    j = np.concatenate([F[:, 1], F[:, 2], F[:, 0], F[:, 0], F[:, 1], F[:, 2]])
    adj = sp.csr_array((np.ones(i.size), (i, j)), shape=(n, n))
    adj.data[:] = 1.0                                   # an edge shared by two faces: once
    deg = np.asarray(adj.sum(axis=1)).ravel()
    return sp.diags_array(1.0 / np.maximum(deg, 1)) @ adj, deg


def _weights_step(rig: _Rig, E, k: int, avg, lam, W_prev=None):
    """W given E (stbs-lbs is linear in W): the normal equations of every vertex
    accumulated over the frames, then k-sparse simplex solves per vertex. With the
    smoothness term (``avg``, the neighbour average), the solve is repeated
    ``_PRIOR_STEPS`` times, each with the neighbours' weights of the one before as the
    prior (Jacobi steps; the normal equations are reused). Where the k-sparse support
    rule does worse than the weights before (k < b), that row keeps them, so no solve
    raises the objective. Returns W and the last prior (None without smoothing)."""
    n, b = E.shape
    X = np.stack([rig.bone_points(i, np.arange(n), E[:, i]) for i in range(b)], axis=2)
    H0, g0 = _normal_equations(X, rig.Y)
    W, prior = W_prev, None
    d = np.arange(b)
    for _ in range(_PRIOR_STEPS if avg is not None else 1):
        H, g = H0, g0
        if avg is not None and W is not None:
            prior = avg @ W
            H = H0.copy()
            H[:, d, d] += lam[:, None]
            g = g0 + lam[:, None] * prior
        W_new = simplex_qp(H, g, k=k)
        if W is not None:
            worse = simplex_objective(H, g, W_new) > simplex_objective(H, g, W)
            W_new[worse] = W[worse]
        W = W_new
    return W, prior


def _normal_equations(X: np.ndarray, y: np.ndarray):
    """``X^T X`` (r, a, a) and ``X^T y`` (r, a) per vertex of X (m, r, a, 3), y (m, r, 3)."""
    m, r, a, _ = X.shape
    Xt = np.ascontiguousarray(np.moveaxis(X, 1, 0).transpose(0, 2, 1, 3)).reshape(r, a, 3 * m)
    yt = np.ascontiguousarray(np.moveaxis(y, 1, 0)).reshape(r, 3 * m, 1)
    return Xt @ np.swapaxes(Xt, 1, 2), (Xt @ yt)[..., 0]


def _objective(rig: _Rig, c, Wc, Ec, prior, lam) -> np.ndarray:
    """Data term (and smoothness term) of the vertices c (r,) with their weights
    Wc, Ec (r, b); ``prior`` and ``lam`` are the whole mesh's (or None)."""
    r = -rig.Y[:, c]
    for i in range(Wc.shape[1]):
        r = r + Wc[:, i, None] * rig.bone_points(i, c, Ec[:, i])
    out = np.sum(r * r, axis=(0, 2))
    if prior is not None:
        out += lam[c] * np.sum((Wc - prior[c]) ** 2, axis=1)
    return out


def _kkt_step(H: np.ndarray, g: np.ndarray, free: np.ndarray,
              held: np.ndarray | None = None) -> np.ndarray:
    """Gauss-Newton step (r, 2b) of (w, e): the unknowns off ``free`` move by ``held``
    (default 0), the free ones solve ``H d = g`` with all w's changes summing to zero."""
    r, a = g.shape
    b = a // 2
    held = np.zeros((r, a)) if held is None else held
    M = np.zeros((r, a + 1, a + 1))
    M[:, :a, :a] = np.where(free[:, :, None] & free[:, None, :], H, 0.0)
    d = np.arange(a)
    M[:, d, d] += np.where(free, 1e-12 * np.abs(H[:, d, d]).max(axis=1, keepdims=True), 1.0)
    M[:, a, :b] = M[:, :b, a] = free[:, :b]                           # sum of dw = 0
    M[:, a, a] = ~free[:, :b].any(axis=1)
    coupled = np.einsum("rab,rb->ra", H, held)
    rhs = np.concatenate([np.where(free, g - coupled, held),
                          -held[:, :b].sum(axis=1, keepdims=True)], axis=1)
    return np.linalg.solve(M, rhs[..., None])[:, :a, 0]


def _joint_step(rig: _Rig, W, E, prior, lam, active: np.ndarray, *,
                fix_w: bool = False) -> int:
    """One Gauss-Newton step on W and E together at every vertex, on the current
    supports (w stays >= 0 and sums to 1, e is clamped to [0, 1]); kept only where it
    lowers the vertex's objective. Alternating (a) and (b) converges linearly where the
    two are coupled; this step converges fast once the supports are right. With
    ``fix_w`` only E moves (the endpoint descent's polish). Updates W and E in place;
    returns how many vertices improved."""
    n, b = W.shape
    m = rig.Y.shape[0]
    step = max(1, _CHUNK // (m * 3 * 2 * b))
    improved = 0
    for s0 in range(0, n, step):
        c = np.arange(s0, min(n, s0 + step))
        X = np.empty((m, c.size, 2 * b, 3))
        for i in range(b):
            X[:, :, i], D = rig.bone_points(i, c, E[c, i], slope=True)
            X[:, :, b + i] = W[c, i, None] * D
        S = W[c] > 0
        free = np.concatenate([S & (not fix_w), S & active], axis=1)
        res = np.einsum("frbk,rb->frk", X[:, :, :b], W[c]) - rig.Y[:, c]
        H, g = _normal_equations(X, -res)
        if prior is not None:
            H[:, np.arange(b), np.arange(b)] += lam[c, None]
            g[:, :b] -= lam[c, None] * (W[c] - prior[c])
        delta = _kkt_step(H, g, free)
        # unknowns the step would push past a bound are held there (e at 0 or 1, w set
        # to 0) and the others solved again: an active-set pass that keeps the step
        # whole where an e sits at its bound or a tiny w is on its way out
        E_c, W_c = E[c], W[c]
        de, dw = delta[:, b:], delta[:, :b]
        out = np.concatenate([(W_c + dw < 0), ((E_c <= 0) & (de < 0)) | ((E_c >= 1) & (de > 0))],
                             axis=1) & free
        if out.any():
            free &= ~out
            held = np.zeros_like(delta)
            held[:, :b] = np.where(out[:, :b], -W_c, 0.0)               # those w drop to 0
            delta = _kkt_step(H, g, free, held)
        dw, de = delta[:, :b], delta[:, b:]
        with np.errstate(divide="ignore", invalid="ignore"):
            reach = np.where(S & (dw < 0), W[c] / -dw, np.inf).min(axis=1)
        before = np.sum(res * res, axis=(0, 2))
        if prior is not None:
            before += lam[c] * np.sum((W[c] - prior[c]) ** 2, axis=1)
        for shrink in (1.0, 0.25):
            a = (np.minimum(1.0, reach) * shrink)[:, None]
            Wt = np.where(S, np.maximum(W[c] + a * dw, 0.0), 0.0)
            Wt /= Wt.sum(axis=1, keepdims=True)
            Et = np.clip(E[c] + a * de, 0.0, 1.0)
            better = _objective(rig, c, Wt, Et, prior, lam) < before
            W[c[better]], E[c[better]] = Wt[better], Et[better]
            improved += int(better.sum())
            c, before = c[~better], before[~better]
            S, dw, de, reach = S[~better], dw[~better], de[~better], reach[~better]
            if c.size == 0:
                break
    return improved


def fit_weights(V, sk: Skeleton, poses: Sequence[Pose], frames, *, F=None,
                max_influences: int | None = 4, smoothness: float = 1e-3,
                method: Literal["stbs-lbs"] = "stbs-lbs", E0=None, iterations: int = 30,
                tol: float = 1e-7, seed: int = 0,
                progress: Progress | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Bone weights W and endpoint weights E that best reproduce example meshes.

    Each round runs, for all vertices at once (module docs):

    (a) W given E: stbs-lbs is linear in W, so each vertex's weights solve a bounded,
        sum-to-one, at most ``max_influences``-sparse least-squares problem over all
        frames (:func:`stbs.fit._lsq.simplex_qp`: an exact active-set solve on the
        support an active-set rule picks), plus ``smoothness`` times the squared
        distance to the average of the vertex's neighbours' weights (from the previous
        round) across the edges of ``F``;
    (b) E given W: a few sweeps of the coordinate descent of
        :func:`fit_endpoint_weights`;
    (c) a few Gauss-Newton steps on W and E together on the supports of (a), each kept
        only where it lowers the vertex's objective.

    The objective never rises within a round; the result is a local minimum (the
    problem is not convex in W and E jointly), reached from projection E.

    The data term is divided by ``m L^2`` (m frames, L the diagonal of V's bounding
    box), so ``smoothness`` does not depend on the number of frames or on the units.

    Parameters
    ----------
    V : (n, d) float
    sk : Skeleton
    poses : sequence of m Pose
    frames : (m, n, d) float
        As for :func:`fit_endpoint_weights`.
    F : (f, 3) int, optional
        Triangles whose edges define the neighbours of the smoothness term; without
        them there is no smoothness term.
    max_influences : int or None
        Most bones per vertex (None: no limit).
    smoothness : float
        Weight of the smoothness term, ``>= 0`` (0 turns it off).
    method : {"stbs-lbs"}
        The skinning model of the examples (the W step needs a model linear in W).
    E0 : (n, b) ndarray or scipy.sparse, optional
        Starting endpoint weights; default projection endpoint weights (eq. 8).
        Entries that affect no frame keep these values.
    iterations : int
        Most rounds of (a) and (b).
    tol : float
        Stop once a round changes no ``w_i`` and no ``w_i e_i`` by more than this, or
        lowers the objective by less than this fraction of it (or the examples are
        matched to rounding).
    seed : int
        Seeds the random bone order of the endpoint sweeps.
    progress : callable, optional
        ``progress(stage, done, total)``: stage ``"fit weights"`` once per round, and
        the ``"endpoint weights"`` reports of each (b); raise from it to cancel.

    Returns
    -------
    W : (n, b) float64 ndarray
        Dense bone weights, ``>= 0``, rows summing to 1, at most ``max_influences``
        non-zeros per row.
    E : (n, b) float64 ndarray
        Endpoint weights in [0, 1].
    """
    method = _checks.choice("method", method, ("stbs-lbs",))
    _checks.progress(progress, "progress(stage, done, total)")
    V, Y, poses = _inputs(V, sk, poses, frames)
    n, b = V.shape[0], sk.n_bones
    k = None if max_influences is None else _positive_int("max_influences", max_influences)
    smoothness = _nonneg("smoothness", smoothness)
    iterations = _positive_int("iterations", iterations)
    tol = _nonneg("tol", tol)
    avg, deg = _neighbour_average(F, n) if F is not None else (None, np.zeros(n))
    scale = Y.shape[0] * max(float(np.sum(np.ptp(V, axis=0) ** 2)), 1e-300)
    lam = smoothness * scale * (deg > 0)
    E = _start_E(V, sk, E0, n, b)
    rig = _Rig(V, sk, poses, Y)
    rng = np.random.default_rng(seed)
    say = _reporter(progress, "fit weights")
    inner = _reporter(progress, "endpoint weights")
    W = np.zeros((n, b))
    exact = 1e-24 * float(np.sum(rig.Y ** 2))     # fitted to rounding: nothing left to do
    say(0, 0)
    active = np.array([rig.active(i) for i in range(b)])
    for it in range(iterations):
        W_old, E_old = W, E.copy()
        W, prior = _weights_step(rig, E, k, avg if smoothness > 0 else None, lam,
                                 W_prev=W if it > 0 else None)
        E, _ = _descend(rig, W, E, method=method, iterations=_INNER_SWEEPS, tol=tol, rng=rng,
                        say=inner)
        for _ in range(_JOINT_STEPS):
            if _joint_step(rig, W, E, prior, lam, active) == 0:
                break
        say(it + 1, iterations)
        everything = np.arange(n)
        obj = float(np.sum(_objective(rig, everything, W, E, prior, lam)))
        obj_old = np.inf if it == 0 else float(np.sum(_objective(rig, everything, W_old,
                                                                 E_old, prior, lam)))
        if obj <= exact or it > 0 and (obj_old - obj <= tol * obj_old or (
                float(np.abs(W - W_old).max()) <= tol
                and float(np.abs(W * (E - E_old)).max()) <= tol)):
            break
    return W, np.clip(E, 0.0, 1.0)
