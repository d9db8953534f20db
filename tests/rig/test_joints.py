"""Rigs from joint hierarchies (stbs.rig.joints): one bone per joint, offset children,
leaf tails inside the mesh, clips that skin as the joints' matrices do."""

from __future__ import annotations

import numpy as np
import pytest

import stbs
from stbs import transforms as tf
from stbs.rig.joints import clip_from_joint_matrices, rig_from_joints, skeleton_from_joints


def _box(lo, hi):
    """A closed, outward-oriented box surface."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    V = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                  for z in (lo[2], hi[2])])
    F = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                  [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    return V, F


# A small humanoid as a node hierarchy: (name, parent, local translation)
_NODES = [("hips", -1, [0, 1, 0]), ("spine", 0, [0, 0.3, 0]), ("head", 1, [0, 0.4, 0]),
          ("l_arm", 1, [0.2, 0.3, 0]), ("l_fore", 3, [0.3, 0, 0]),
          ("r_arm", 1, [-0.2, 0.3, 0]), ("l_leg", 0, [0.1, -0.05, 0]),
          ("l_shin", 6, [0, -0.45, 0]), ("r_leg", 0, [-0.1, -0.05, 0])]


def _rand_quats(rng, n):
    q = rng.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def _world(local_R, local_t, parent):
    """World 4x4 matrices of a node hierarchy (the glTF/FBX rule G = G_parent N)."""
    n = len(parent)
    G = np.zeros((n, 4, 4))
    for i in range(n):
        N = np.eye(4)
        N[:3, :3] = local_R[i]
        N[:3, 3] = local_t[i]
        G[i] = N if parent[i] < 0 else G[parent[i]] @ N
    return G


def _humanoid(rng):
    parent = np.array([p for _, p, _ in _NODES])
    t_rest = np.array([t for _, _, t in _NODES], dtype=float)
    R_rest = tf.quat_to_matrix(_rand_quats(rng, len(_NODES)) * [40, 1, 1, 1])  # near identity
    bind = _world(R_rest, t_rest, parent)
    return parent, t_rest, R_rest, bind


def test_one_bone_per_joint_with_offset_children():
    parent, _, _, bind = _humanoid(np.random.default_rng(0))
    names = [n for n, _, _ in _NODES]
    sk = skeleton_from_joints(bind[:, :3, 3], parent, names)
    assert sk.n_bones == len(_NODES) and sk.names == names
    np.testing.assert_allclose(sk.A, bind[:, :3, 3])
    par = dict(zip(names, sk.parents.tolist(), strict=True))
    assert par["spine"] == names.index("hips") and par["l_leg"] == names.index("hips")
    # the hips continue into the spine (the largest subtree), the spine into the head
    assert sk.BE[0, 1] == names.index("spine") and sk.BE[1, 1] == names.index("head")
    assert sk.connected[names.index("spine")] and not sk.connected[names.index("l_leg")]
    assert not sk.connected[names.index("l_arm")]
    assert len(sk.roots) == 1


def test_a_clip_skins_as_the_node_hierarchy_and_a_turned_hip_carries_the_legs():
    rng = np.random.default_rng(1)
    parent, t_rest, R_rest, bind = _humanoid(rng)
    names = [n for n, _, _ in _NODES]
    n = 400
    V = rng.uniform([-0.5, 0.2, -0.2], [0.5, 2.2, 0.2], size=(n, 3))
    W = rng.uniform(size=(n, len(names))) ** 4
    W /= W.sum(1, keepdims=True)
    rig = rig_from_joints(V, np.zeros((0, 3), dtype=int), W, bind, parent, names)
    times = np.array([0.0, 0.5, 1.25])
    Rs = [tf.quat_to_matrix(_rand_quats(rng, len(names))) for _ in times]
    ts = [t_rest + rng.normal(scale=0.05, size=t_rest.shape) * (parent < 0)[:, None]
          for _ in times]
    M = np.stack([_world(R, t, parent) @ np.linalg.inv(bind) for R, t in zip(Rs, ts,
                                                                          strict=True)])
    clip = clip_from_joint_matrices(rig.skeleton, times, M)
    Vh = np.column_stack([V, np.ones(n)])
    for k, t in enumerate(times):
        want = np.einsum("nb,bin->ni", W, np.einsum("bij,nj->bin", M[k, :, :3], Vh))
        got = stbs.deform(V, rig.skeleton, clip.pose(float(t)), rig.W, method="lbs")
        np.testing.assert_allclose(got, want, atol=1e-10)
    # between keys the clip is the node hierarchy with its local rotations slerped:
    # the local rotation of a node relative to its bind orientation, as glTF slerps it
    s = 0.3
    Rmid = np.stack([tf.quat_to_matrix(tf.quat_slerp(tf.matrix_to_quat(a), tf.matrix_to_quat(b),
                                                     s)) for a, b in zip(Rs[0], Rs[1],
                                                                         strict=True)])
    Mmid = _world(Rmid, (1 - s) * ts[0] + s * ts[1], parent) @ np.linalg.inv(bind)
    want = np.einsum("nb,bin->ni", W, np.einsum("bij,nj->bin", Mmid[:, :3], Vh))
    got = stbs.deform(V, rig.skeleton, clip.pose(s * 0.5), rig.W, method="lbs")
    np.testing.assert_allclose(got, want, atol=1e-10)
    # turning the hips 40 degrees by hand turns the legs, spine and arms with them
    L = np.tile(np.eye(3), (len(names), 1, 1))
    L[0] = tf.axis_angle_to_matrix(np.array([0, 0, 1.0]), np.radians(40))
    pose = stbs.forward_kinematics(rig.skeleton, rotations=L)
    a0 = bind[0, :3, 3]
    np.testing.assert_allclose(pose.origins, (rig.skeleton.A - a0) @ L[0].T + a0, atol=1e-12)


def test_leaf_tails_stay_inside_the_mesh():
    V, F = _box([-1, -1, -1], [1, 1, 1])
    J = np.array([[0, -0.5, 0], [0, 0.8, 0]])
    W = np.zeros((8, 2))
    W[:, 1] = 1
    sk = skeleton_from_joints(J, [-1, 0], ["neck", "head"], V=V, F=F, W=W)
    tail = sk.C[sk.BE[1, 1]]
    # along the parent's direction (+y), never past 90 % of the way to the top (y = 1)
    np.testing.assert_allclose(tail[[0, 2]], [0, 0], atol=1e-12)
    assert 0.8 < tail[1] <= 0.8 + 0.9 * 0.2 + 1e-12
    assert stbs.geometry.winding_numbers(tail[None], V, F)[0] > 0.5


def test_bad_hierarchies_are_named():
    J = np.zeros((3, 3)) + np.arange(3)[:, None]
    with pytest.raises(ValueError, match="cycle"):
        skeleton_from_joints(J, [2, 0, 1], ["a", "b", "c"])
    with pytest.raises(ValueError, match="joint 1 has parent 7"):
        skeleton_from_joints(J, [-1, 7, 1], ["a", "b", "c"])


def test_scaled_joints_warn_and_are_dropped():
    sk = skeleton_from_joints(np.array([[0, 0, 0.0], [1, 0, 0]]), [-1, 0], ["a", "b"])
    M = np.tile(np.eye(4), (1, 2, 1, 1))
    M[0, 1, :3, :3] *= 1.5
    with pytest.warns(UserWarning, match="scales joints"):
        clip = clip_from_joint_matrices(sk, [0.0], M)
    np.testing.assert_allclose(clip.pose(0.0).rotations, np.tile(np.eye(3), (2, 1, 1)),
                               atol=1e-12)


def test_tree_depths_and_cycles():
    from stbs.skeleton import tree_depths

    np.testing.assert_array_equal(tree_depths([-1, 0, 0, 2, -1, 4]), [0, 1, 1, 2, 0, 1])
    np.testing.assert_array_equal(tree_depths(np.arange(-1, 9999)), np.arange(10_000))
    # a cycle (1 -> 2 -> 1) and a node under it are reached from no root
    np.testing.assert_array_equal(tree_depths([-1, 2, 1, 2]), [0, -1, -1, -1])
    with pytest.raises(ValueError, match=r"P: bone [01] \(.*\) lies on a cycle of bones"):
        stbs.Skeleton(np.eye(3) * [1, 2, 3], [[0, 1], [1, 2]], P=[1, 0])


def test_a_chain_of_thousands_of_joints_at_one_place():
    """5000 joints stacked at one place above a root (a hostile file's chain): each
    continues the direction from the last joint elsewhere, found in one pass (it was a
    walk up from every joint, joints x depth steps), and the tree is checked in one
    pass too."""
    j = 5000
    J = np.zeros((j, 3))
    J[1:, 1] = 1.0
    sk = skeleton_from_joints(J, np.arange(-1, j - 1), [f"j{i}" for i in range(j)])
    assert sk.n_bones == j
    np.testing.assert_allclose(sk.axes[1:], np.tile([0, 1.0, 0], (j - 1, 1)), atol=1e-12)
    np.testing.assert_array_equal(sk.depth, np.arange(j))
    parent = np.arange(-1, j - 1)
    parent[0] = j - 1                                     # the chain closed on itself
    with pytest.raises(ValueError, match="lies on or under a cycle of joints"):
        skeleton_from_joints(J, parent, [f"j{i}" for i in range(j)])
