"""Rigs from joint hierarchies: the skinned characters of glTF, FBX and BVH.

A character file gives *joints*: nodes of a hierarchy, each with a bind transform,
and skinning weights over them. STBS needs *bones* (a start, an end and a direction
to stretch along and twist about), so every joint becomes one bone:

- bone ``i`` starts at joint ``i``'s bind position, so ``W``'s columns are the file's;
- it ends at one of the joint's children (the bone is *connected* to it): the only
  child, or with several the one that continues the direction from the joint's
  parent best, or, at a root, the one heading the largest subtree (the spine over
  the legs at the hips). Children at the joint's own position are passed over;
- the other children are *offset children* (DESIGN §2): shoulders hang off the chest
  and legs off the hips where they are, carried by their parent's map, so posing
  is exactly the file's node hierarchy;
- a leaf joint (a head, a finger tip) gets a tail of its own, along its parent's
  direction (a root leaf: along its bind frame's axis that best spans the vertices
  it moves), as long as the vertices it moves reach, and kept inside the mesh:
  never further than 90 % of the way to the surface along that direction.

:func:`clip_from_joint_matrices` turns a file's animation, given as the joints'
skinning matrices ``G(t) B^-1`` at key times, into a :class:`stbs.Clip` that skins
exactly as those matrices do at the keys.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence

import numpy as np

from .. import _checks
from ..clip import Clip
from ..pose import local_arrays
from ..skeleton import Skeleton, tree_depths
from .model import Rig

__all__ = ["skeleton_from_joints", "rig_from_joints", "clip_from_joint_matrices",
           "rigid_parts"]

# A leaf tail stops this far along the way from its joint to the surface.
_INSIDE = 0.9


def _first_hits(O: np.ndarray, D: np.ndarray, V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """(r,) distance along unit rays ``O + s D`` to the first triangle hit (inf: none)."""
    v0 = V[F[:, 0]]
    e1 = V[F[:, 1]] - v0
    e2 = V[F[:, 2]] - v0
    out = np.full(len(O), np.inf)
    for k, (o, d) in enumerate(zip(O, D, strict=True)):
        p = np.cross(d, e2)
        det = np.einsum("fi,fi->f", e1, p)
        ok = np.abs(det) > 1e-14
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        s = o - v0
        u = np.einsum("fi,fi->f", s, p) * inv
        q = np.cross(s, e1)
        v = (q @ d) * inv
        t = np.einsum("fi,fi->f", e2, q) * inv
        hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
        if hit.any():
            out[k] = float(t[hit].min())
    return out


def _subtree_sizes(parent: np.ndarray) -> np.ndarray:
    size = np.ones(parent.size, dtype=np.int64)
    for i in np.argsort(-tree_depths(parent), kind="stable"):
        if parent[i] >= 0:
            size[parent[i]] += size[i]
    return size


def _check_parents(parent, j: int) -> np.ndarray:
    parent = _checks.index_array("parent", parent, ndim=1, shape=(j,))
    bad = np.flatnonzero((parent < -1) | (parent >= j) | (parent == np.arange(j)))
    if bad.size:
        i = int(bad[0])
        raise ValueError(f"parent: joint {i} has parent {int(parent[i])}; expected -1 or "
                         f"another joint in 0..{j - 1}")
    lost = np.flatnonzero(tree_depths(parent) < 0)       # a cycle never reaches a root
    if lost.size:
        raise ValueError(f"parent: joint {int(lost[0])} lies on or under a cycle of joints; "
                         "the joints must form a tree (or a forest)")
    return parent


def skeleton_from_joints(J, parent, names: Sequence[str], *, V=None, F=None, W=None,
                         frames=None) -> Skeleton:
    """One bone per joint (see the module docs).

    Parameters
    ----------
    J : (j, 3) float
        Joint positions (the bind pose).
    parent : (j,) int
        Parent joint of each joint, -1 for roots; a tree or a forest.
    names : sequence of j str
        Joint names, unique; they become the bone names.
    V : (n, 3) float, optional
        The mesh, to size leaf tails and keep them inside it (with ``F``).
    F : (f, 3) int, optional
    W : (n, j) float, optional
        Weights over the joints: a leaf's tail reaches as far as the vertices it moves.
    frames : (j, 3, 3) float, optional
        Bind rotations of the joints: a root leaf points along the axis of its frame
        that best spans the vertices it moves (default: +y).

    Returns
    -------
    Skeleton
        Bone ``i`` starts at ``J[i]``; joints ``0..j-1`` are ``J``, leaf tails follow.
    """
    J, parent, names = _checked_joints(J, parent, names)
    j = J.shape[0]
    pts = J if V is None else np.vstack([J, np.asarray(V, dtype=float)])
    size = float(np.linalg.norm(np.ptp(pts, axis=0))) or 1.0
    BE = np.zeros((j, 2), dtype=np.int64)
    BE[:, 0] = np.arange(j)
    leaves, dirs, base = _bone_ends(J, parent, 1e-6 * size, size, BE)
    C = [J[i] for i in range(j)]
    if leaves:
        lengths, D = _leaf_tails(J, leaves, dirs, base, V=V, F=F, W=W, frames=frames,
                                 size=size)
        for k, i in enumerate(leaves):
            C.append(J[i] + lengths[k] * D[k])
            BE[i, 1] = len(C) - 1
    P = np.where(parent >= 0, parent, -1)
    return Skeleton(np.array(C), BE, names=names, P=P)


def _checked_joints(J, parent, names):
    J = _checks.real_array("J", J, ndim=2)
    if J.shape[1] != 3:
        raise ValueError(f"J must have shape (j, 3), got {J.shape}")
    j = J.shape[0]
    if j == 0:
        raise ValueError("J must hold at least one joint, got none")
    parent = _check_parents(parent, j)
    names = [str(s) for s in names]
    if len(names) != j:
        raise ValueError(f"names must have {j} entries (one per joint), got {len(names)}")
    return J, parent, names


def _bone_ends(J, parent, tol: float, size: float, BE):
    """Each joint's bone towards its chosen child (``BE[i, 1]``, set here); for the
    leaves (no child elsewhere): ``(leaves, dirs, base)``, their direction (None:
    unknown) and a first length."""
    j = J.shape[0]
    subtree = _subtree_sizes(parent)
    children: list[list[int]] = [[] for _ in range(j)]
    for c, q in enumerate(parent.tolist()):
        if q >= 0:
            children[q].append(c)
    # the nearest ancestor at another place than each joint (-1: none), parents first:
    # a joint at its parent's place continues its grandparent's direction
    away = np.full(j, -1, dtype=np.int64)
    for i in np.argsort(tree_depths(parent), kind="stable"):
        q = parent[i]
        if q >= 0:
            away[i] = q if np.linalg.norm(J[i] - J[q]) > tol else away[q]
    leaves, dirs, base = [], [], []
    for i in range(j):
        kids = [c for c in children[i] if np.linalg.norm(J[c] - J[i]) > tol]
        up = J[i] - J[away[i]] if away[i] >= 0 else None
        if kids:
            BE[i, 1] = _best_child(J, i, kids, up, subtree)
            continue
        leaves.append(i)
        base.append(0.5 * np.linalg.norm(up) if up is not None else 0.1 * size)
        dirs.append(up / np.linalg.norm(up) if up is not None else None)
    return leaves, dirs, base


def _best_child(J, i: int, kids: list[int], up, subtree) -> int:
    """The child a joint's bone runs to: the straightest on from ``up``, else (a root)
    the one with the largest subtree."""
    if up is None:
        return max(kids, key=lambda c: (subtree[c], -c))
    u = up / np.linalg.norm(up)
    return max(kids, key=lambda c: float((J[c] - J[i]) @ u) / np.linalg.norm(J[c] - J[i]))


def _leaf_tails(J, leaves, dirs, base, *, V, F, W, frames, size: float):
    """Leaf bones' lengths (k,) and directions (k, 3): as far as the vertices they move
    reach, kept inside the mesh."""
    Vn = None if V is None else np.asarray(V, dtype=float)
    Wd = None
    if W is not None and Vn is not None:
        Wd = W.toarray() if hasattr(W, "toarray") else np.asarray(W, dtype=float)
    for k, i in enumerate(leaves):
        moved = None
        if Wd is not None and (Wd[:, i] >= 0.5).sum() >= 3:
            moved = Vn[Wd[:, i] >= 0.5] - J[i]
        if dirs[k] is None:
            dirs[k] = _root_leaf_direction(i, moved, frames)
        if moved is not None:
            reach = float(np.quantile(moved @ dirs[k], 0.9))
            if reach > 0.05 * base[k]:
                base[k] = reach
    lengths = np.array(base)
    D = np.array(dirs)
    if V is not None and F is not None:
        Fn = _checks.index_array("F", F, ndim=2, shape=(None, 3))
        hit = _first_hits(J[leaves], D, Vn, Fn)
        inside = np.isfinite(hit)
        lengths = np.where(inside, np.minimum(lengths, _INSIDE * hit), lengths)
    return np.maximum(lengths, 1e-3 * size), D


def _root_leaf_direction(i: int, moved, frames) -> np.ndarray:
    """A lone joint's bone: along the axis of its frame that best spans the vertices it
    moves (pointing towards them), else its frame's y axis."""
    axes = np.eye(3) if frames is None else np.asarray(frames[i], dtype=float).T
    if moved is None:
        return axes[1] / np.linalg.norm(axes[1])
    spread = [np.abs(moved @ (a / np.linalg.norm(a))).sum() for a in axes]
    a = axes[int(np.argmax(spread))]
    a = a / np.linalg.norm(a)
    return a if (moved @ a).sum() >= 0 else -a


def rig_from_joints(V, F, W, bind, parent, names: Sequence[str], *,
                    meta: dict | None = None) -> Rig:
    """A rig of a skinned character: one bone per joint (see the module docs).

    Parameters
    ----------
    V : (n, 3) float
        Rest (bind pose) vertices.
    F : (f, 3) int
        Triangles.
    W : (n, j) float, dense or sparse
        Weights over the joints; each row is divided by its sum.
    bind : (j, 4, 4) float
        World bind matrix of each joint (column vectors: ``x' = M @ [x, 1]``).
    parent : (j,) int
        Parent joint, -1 for roots.
    names : sequence of j str
        Joint names (unique).
    meta : dict, optional
        The rig's metadata.

    Returns
    -------
    Rig
    """
    bind = _checks.real_array("bind", bind, ndim=3)
    if bind.shape[1:] != (4, 4):
        raise ValueError(f"bind must have shape (j, 4, 4), got {bind.shape}")
    V = _checks.vertices(V)
    if hasattr(W, "toarray"):
        W = W.toarray()
    W = _checks.real_array("W", W, shape=(V.shape[0], bind.shape[0]))
    tot = W.sum(axis=1)
    if np.any(tot <= 0):
        k = int(np.flatnonzero(tot <= 0)[0])
        raise ValueError(f"W: vertex {k} has no weight on any joint "
                         f"({int((tot <= 0).sum())} vertices have none)")
    W = W / tot[:, None]
    frames, _ = rigid_parts(bind[:, :3, :3])
    sk = skeleton_from_joints(bind[:, :3, 3], parent, names, V=V, F=F, W=W, frames=frames)
    return Rig(V=V, F=F, W=W, skeleton=sk, meta=meta)


def rigid_parts(M) -> tuple[np.ndarray, np.ndarray]:
    """The closest rotations to (..., 3, 3) matrices, and how far each was from one
    (max ``|s - 1|`` over its singular values)."""
    M = np.asarray(M, dtype=float)
    U, S, Vt = np.linalg.svd(M)
    det = np.sign(np.linalg.det(U @ Vt))
    det = np.where(det == 0, 1.0, det)
    U = U.copy()
    U[..., :, 2] *= det[..., None]
    return U @ Vt, np.abs(S - 1).max(axis=-1)


def clip_from_joint_matrices(sk: Skeleton, times, M, *, fps: float | None = None,
                             source: str = "the animation") -> Clip:
    """A clip whose keys skin as the joints' skinning matrices do.

    Parameters
    ----------
    sk : Skeleton
        A skeleton whose bone ``i`` starts at joint ``i`` (as
        :func:`skeleton_from_joints` makes).
    times : (k,) float
        Key times in seconds, increasing.
    M : (k, b, 4, 4) float
        Skinning matrix of bone ``i``'s joint at each time, ``G(t) B^-1`` (the posed
        world matrix times the inverse bind matrix).
    fps : float, optional
        The clip's frame rate; default: the key spacing when regular, else 30.
    source : str
        Names the animation in the warning about dropped scale.

    Returns
    -------
    Clip
        Bone ``i``'s rotation is the rotation of ``M_i`` (the closest one when ``M_i``
        scales: bones are rigid, so a scale is dropped with a warning), its posed start
        ``M_i a_i``; between keys the clip interpolates in the local frame.
    """
    times = _checks.real_array("times", times, ndim=1)
    b = sk.n_bones
    M = _checks.real_array("M", M, shape=(times.size, b, 4, 4))
    R, dev = rigid_parts(M[..., :3, :3])
    worst = float(dev.max(initial=0.0))
    if worst > 1e-5:
        k, i = np.unravel_index(int(np.argmax(dev)), dev.shape)
        warnings.warn(f"{source} scales joints (bone {sk.names[i]!r} by up to {worst:.3g} "
                      f"off rigid at {times[k]:g} s); bones are rigid, so the scale is "
                      "dropped", UserWarning, stacklevel=2)
    O = np.einsum("kbij,bj->kbi", M[..., :3, :3], sk.A) + M[..., :3, 3]
    sigma = np.ones((times.size, b))
    theta = np.zeros((times.size, b, 2))
    L, D = local_arrays(sk, R, O, sigma, theta)
    if fps is None:
        step = np.diff(times)
        fps = 30.0
        if step.size and np.ptp(step) <= 1e-6 * step.mean() and step.mean() > 0:
            fps = 1.0 / float(step.mean())
    return Clip.from_local(sk, times, rotations=L, offsets=D, fps=fps)
