"""The planar straight-line graph (PSLG) handed to a 2D mesher: outline + skeleton."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..skeleton import Skeleton
from ._geometry import (
    REL_TOL,
    orient2d,
    point_segment_distance,
    points_in_loops,
    project_on_segment,
    scale_of,
    segments_intersect,
)
from ._samples import bone_label, fmt_point, sample_skeleton
from .outline import Outline

#: Input vertices this close to a joint or a bone (relative to the size of the shape)
#: are taken to be on it.
ON_BONE_TOL = 1e-6


@dataclass
class PSLG:
    """Points, constrained segments and what lies on the skeleton.

    ``P[:n_input]`` are the outline's input points. Segment k joins ``S[k]``; it is an
    outline segment when ``seg_bone[k] == -1``, else a piece of bone ``seg_bone[k]``
    running from parameter ``seg_t[k, 0]`` to ``seg_t[k, 1]``. ``apex`` marks the
    points where segments may meet at an angle (outline vertices and joints).
    """

    P: np.ndarray
    S: np.ndarray
    seg_bone: np.ndarray
    seg_t: np.ndarray
    point_bone: np.ndarray
    point_t: np.ndarray
    joint_vertex: np.ndarray
    apex: np.ndarray
    n_input: int
    polygons: list[np.ndarray]
    A: np.ndarray
    B: np.ndarray


def check_skeleton_inside(out: Outline, sk: Skeleton) -> None:
    """ValueError naming the bone when the skeleton is not strictly inside the outline."""
    P, S = out.P, out.segments
    scale = scale_of(np.vstack([P, sk.C]))
    tol = REL_TOL * scale
    close = cKDTree(sk.C).query_pairs(tol, output_type="ndarray")
    if close.size:
        a, b = close[0]
        raise ValueError(f"sk: joints {a} and {b} coincide at {fmt_point(sk.C[a])}; a 2-D "
                         "skeleton needs distinct joint positions")
    inside = points_in_loops(sk.C, out.polygons())
    if not inside.all():
        j = int(np.argmin(inside))
        bones = np.flatnonzero((sk.BE == j).any(axis=1))
        who = (bone_label(sk, int(bones[0])) + f" has joint {j}") if bones.size else f"joint {j}"
        raise ValueError(f"sk: {who} at {fmt_point(sk.C[j])} outside the outline; the skeleton "
                         "must lie inside the shape (move the joint inside, or check that "
                         "the skeleton and the outline use the same coordinates), or pass "
                         "clip_skeleton=True (--clip-skeleton on the command line) to mesh "
                         "only its parts inside")
    A, B = sk.A, sk.B
    Q0, Q1 = P[S[:, 0]], P[S[:, 1]]
    step = max(1, 2_000_000 // max(S.shape[0], 1))
    for s in range(0, sk.n_bones, step):
        hit = segments_intersect(A[s:s + step, None], B[s:s + step, None], Q0[None], Q1[None],
                                 tol=tol)
        if hit.any():
            i, k = np.argwhere(hit)[0]
            i += s
            raise ValueError(f"sk: {bone_label(sk, int(i))} crosses the outline (boundary "
                             f"segment {S[k].tolist()} near {fmt_point((Q0[k] + Q1[k]) / 2)}); "
                             "every bone must lie strictly inside the shape, or pass "
                             "clip_skeleton=True (--clip-skeleton on the command line) to "
                             "mesh only its parts inside")
    # Bones may meet only at shared joints (and not run along each other there).
    i, k = np.triu_indices(sk.n_bones, 1)
    share = (sk.BE[i, :, None] == sk.BE[k, None, :]).any(axis=(1, 2))
    cross = np.zeros(i.size, dtype=bool)
    ns = ~share
    cross[ns] = segments_intersect(A[i[ns]], B[i[ns]], A[k[ns]], B[k[ns]], tol=tol)
    sh = np.flatnonzero(share)
    if sh.size:
        bi, bk = sk.BE[i[sh]], sk.BE[k[sh]]
        c = np.where((bi[:, 0] == bk[:, 0]) | (bi[:, 0] == bk[:, 1]), bi[:, 0], bi[:, 1])
        u = np.where(bi[:, 0] == c, bi[:, 1], bi[:, 0])
        w = np.where(bk[:, 0] == c, bk[:, 1], bk[:, 0])
        du, dw = sk.C[u] - sk.C[c], sk.C[w] - sk.C[c]
        flat = np.abs(orient2d(sk.C[c], sk.C[u], sk.C[w])) <= \
            REL_TOL * np.linalg.norm(du, axis=1) * np.linalg.norm(dw, axis=1)
        cross[sh] = flat & (np.einsum("ij,ij->i", du, dw) > 0)
    if cross.any():
        m = int(np.argmax(cross))
        raise ValueError(f"sk: {bone_label(sk, int(i[m]))} and {bone_label(sk, int(k[m]))} "
                         "cross or overlap; in 2-D, bones may meet only at a shared joint")


def build_pslg(out: Outline, sk: Skeleton, spacing: float, counts: np.ndarray | None) -> PSLG:
    """Outline points, then joints and bone samples, with the constrained segments."""
    P0 = out.P
    n = P0.shape[0]
    sp = sample_skeleton(sk, spacing, counts)
    j = sk.n_joints
    A, B = sk.A, sk.B
    joint_vertex = np.full(j, -1, dtype=np.int64)
    in_bone, in_point, in_t = [], [], []  # input points on bones
    if out.mesh:
        # Interior vertices of an input mesh may already sit on a joint or a bone: a
        # mesh built around a skeleton and saved with few digits (woody.obj: 4
        # decimals) has them within ON_BONE_TOL of it. They are used as they are.
        tol = ON_BONE_TOL * scale_of(np.vstack([P0, sk.C]))
        d, nearest = cKDTree(P0).query(sk.C)
        joint_vertex[d <= tol] = nearest[d <= tol]
        for i in range(sk.n_bones):
            lo, hi = np.minimum(A[i], B[i]) - tol, np.maximum(A[i], B[i]) + tol
            cand = np.flatnonzero(np.all((P0 >= lo) & (P0 <= hi), axis=1))
            t, dist = project_on_segment(P0[cand], A[i], B[i])
            ok = (dist <= tol) & (t > 0) & (t < 1) & ~np.isin(cand, joint_vertex)
            in_bone.append(np.full(int(ok.sum()), i))
            in_point.append(cand[ok])
            in_t.append(t[ok])
    in_bone = np.concatenate(in_bone).astype(np.int64) if in_bone else np.zeros(0, np.int64)
    in_point = np.concatenate(in_point).astype(np.int64) if in_point else np.zeros(0, np.int64)
    in_t = np.concatenate(in_t) if in_t else np.zeros(0)
    new_joints = np.flatnonzero(joint_vertex < 0)
    joint_vertex[new_joints] = n + np.arange(new_joints.size)
    # Regular samples, minus those within half a sample gap of an input point on the bone.
    sb, st, sx = sp.bone[j:], sp.t[j:], sp.X[j:]
    gap = 0.5 / (np.bincount(sb, minlength=sk.n_bones) + 1.0)
    close = (sb[:, None] == in_bone[None]) & (np.abs(st[:, None] - in_t[None]) < gap[sb, None])
    keep = ~close.any(axis=1)
    sb, st, sx = sb[keep], st[keep], sx[keep]
    P = np.vstack([P0, sk.C[new_joints], sx])
    pb = np.concatenate([np.full(n + new_joints.size, -1, dtype=np.int64), sb])
    pt = np.concatenate([np.full(n + new_joints.size, np.nan), st])
    pb[in_point], pt[in_point] = in_bone, in_t
    # Bone chains: start joint, samples by t, end joint.
    segs, seg_bone, seg_t = [out.segments], [np.full(out.segments.shape[0], -1)], \
        [np.full((out.segments.shape[0], 2), np.nan)]
    ids = np.arange(P.shape[0])
    for i in range(sk.n_bones):
        on = ids[pb == i]
        on = on[np.argsort(pt[on], kind="stable")]
        chain = np.concatenate([[joint_vertex[sk.BE[i, 0]]], on, [joint_vertex[sk.BE[i, 1]]]])
        tt = np.concatenate([[0.0], pt[on], [1.0]])
        segs.append(np.stack([chain[:-1], chain[1:]], axis=1))
        seg_bone.append(np.full(chain.size - 1, i))
        seg_t.append(np.stack([tt[:-1], tt[1:]], axis=1))
    apex = np.zeros(P.shape[0], dtype=bool)
    for L in out.loops:
        apex[L] = True
    apex[joint_vertex] = True
    return PSLG(P=P, S=np.concatenate(segs).astype(np.int64),
                seg_bone=np.concatenate(seg_bone).astype(np.int64),
                seg_t=np.concatenate(seg_t), point_bone=pb, point_t=pt,
                joint_vertex=joint_vertex, apex=apex, n_input=n, polygons=out.polygons(),
                A=A, B=B)


def bone_distance(X: np.ndarray, A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, np.ndarray,
                                                                          np.ndarray]:
    """For points ``X``: nearest bone, parameter along it and distance."""
    d = point_segment_distance(X[:, None, :], A[None], B[None])
    i = np.argmin(d, axis=1)
    t, dist = project_on_segment(X, A[i], B[i])
    return i, t, dist
