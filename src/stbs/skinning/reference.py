"""Plain NumPy implementations of the four skinning methods, written for reading, not speed.

They follow the equations term by term (dense weights, one (n, 3, 3) twist matrix
per bone), share nothing with the compiled kernels but the transforms module, and
serve as the oracle in tests and as the NumPy baseline in benchmarks.
"""

from __future__ import annotations

import numpy as np

from .. import transforms as tf
from ..pose import Pose


def _dense(X) -> np.ndarray:
    return np.asarray(X.toarray() if hasattr(X, "toarray") else X, dtype=np.float64)


def _bone_frames(pose: Pose):
    sk = pose.skeleton
    d = sk.dim
    pad = (lambda X: np.hstack([X, np.zeros((X.shape[0], 1))])) if d == 2 else (lambda X: X)
    R = tf.embed_rotation_2d(pose.rotations) if d == 2 else pose.rotations
    return pad(sk.A), pad(sk.B), pad(sk.axes), R, pad(pose.origins)


def reference_deform(V, pose: Pose, W, E=None, method: str = "stbs-dqs") -> np.ndarray:
    """Deformed positions (n, d) by ``method``; E is required for the STBS methods."""
    sk = pose.skeleton
    V = np.asarray(V, dtype=np.float64)
    n, d = V.shape
    P = np.hstack([V, np.zeros((n, 1))]) if d == 2 else V
    W = _dense(W)
    E = None if E is None else _dense(E)
    A, B, U, R, Ap = _bone_frames(pose)
    sigma, th = pose.stretch, pose.twist
    b = sk.n_bones
    if method == "lbs":
        out = np.zeros_like(P)
        for i in range(b):
            S = np.eye(3) + (sigma[i] - 1) * np.outer(U[i], U[i])
            out += W[:, i:i + 1] * (Ap[i] + (P - A[i]) @ (R[i] @ S).T)
    elif method == "stbs-lbs":
        out = np.zeros_like(P)
        for i in range(b):
            e = E[:, i]
            s = (sigma[i] - 1) * (B[i] - A[i])
            K = tf.axis_angle_to_matrix(np.broadcast_to(U[i], (n, 3)),
                                        (1 - e) * th[i, 0] + e * th[i, 1])
            y = e[:, None] * s + P - A[i]                      # eq. 5, inner bracket
            out += W[:, i:i + 1] * (Ap[i] + np.einsum("ij,njk,nk->ni", R[i], K, y))
    elif method == "dqs":
        # stretches blended linearly in rest space first, then rigid parts as DQs
        Ps = np.zeros_like(P)
        for i in range(b):
            S = np.eye(3) + (sigma[i] - 1) * np.outer(U[i], U[i])
            Ps += W[:, i:i + 1] * (A[i] + (P - A[i]) @ S.T)
        q = tf.matrix_to_quat(R)
        qr, qd = tf.dq_from_rt(q, Ap - np.einsum("bij,bj->bi", R, A))
        br, bd = tf.dq_blend(W, np.broadcast_to(qr, (n, b, 4)), np.broadcast_to(qd, (n, b, 4)))
        out = tf.dq_apply(br, bd, Ps)
    elif method == "stbs-dqs":
        qr = np.empty((n, b, 4))
        qd = np.empty((n, b, 4))
        for i in range(b):
            e = E[:, i]
            s = (sigma[i] - 1) * (B[i] - A[i])
            K = tf.axis_angle_to_matrix(np.broadcast_to(U[i], (n, 3)),
                                        (1 - e) * th[i, 0] + e * th[i, 1])
            M = np.einsum("ij,njk->nik", R[i], K)               # R_i K_i(e_i)
            t = Ap[i] + np.einsum("nij,nj->ni", M, e[:, None] * s - A[i])   # eq. 6, T_i(e_i)
            qr[:, i], qd[:, i] = tf.dq_from_rt(tf.matrix_to_quat(M), t)
        br, bd = tf.dq_blend(W, qr, qd)
        out = tf.dq_apply(br, bd, P)
    else:
        raise ValueError(f"method must be one of 'lbs', 'dqs', 'stbs-lbs', 'stbs-dqs', "
                         f"got {method!r}")
    return out[:, :d]
