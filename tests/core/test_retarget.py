"""stbs.retarget: motion (stbs.Motion) onto a rig's skeleton, twist spread along bones."""

from __future__ import annotations

import humanoids as hu
import numpy as np
import pytest

import stbs
from stbs import transforms as tf
from stbs.retargeting import joint_map, retarget


def _rx(deg):
    return tf.axis_angle_to_matrix(np.broadcast_to([1.0, 0, 0], (np.size(deg), 3)),
                                   np.radians(np.atleast_1d(deg)))


def _arm_motion(roll_deg, wrist_x=None):
    """shoulder -> elbow -> wrist -> hand end along x (3, 3, 1 long); the wrist joint
    rolls about x by ``roll_deg`` per frame (capture stores a forearm's roll there)."""
    f = len(roll_deg)
    R = np.tile(np.eye(3), (f, 4, 1, 1))
    R[:, 2] = _rx(roll_deg)
    offsets = [[0, 0, 0], [3, 0, 0], [3, 0, 0], [1, 0, 0]]
    T = None
    if wrist_x is not None:
        T = np.broadcast_to(np.array(offsets, float), (f, 4, 3)).copy()
        T[:, 2, 0] = wrist_x
    return stbs.Motion(["shoulder", "elbow", "wrist", "wrist_end"], [-1, 0, 1, 2], offsets,
                       rotations=R, translations=T, frame_time=0.04,
                       end_site=[False, False, False, True])


def test_the_motion_skeleton_rule():
    m = _arm_motion([0.0])
    sk, drive, end = m.skeleton()
    assert sk.names == ["shoulder", "elbow", "wrist"]
    np.testing.assert_array_equal(sk.C, [[0, 0, 0], [3, 0, 0], [6, 0, 0], [7, 0, 0]])
    assert drive.tolist() == [0, 1, 2] and end.tolist() == [1, 2, 3]
    # a zero offset merges joints; a joint turning two bones names the second P>K
    R = np.tile(np.eye(3), (1, 4, 1, 1))
    m2 = stbs.Motion(["hips", "zero", "l", "r"], [-1, 0, 1, 1],
                     [[0, 0, 0], [0, 0, 0], [1, 0, 0], [-1, 0, 0]], rotations=R, frame_time=1)
    sk2, drive2, _ = m2.skeleton()
    assert sk2.names == ["zero", "zero>r"] and sk2.n_joints == 3
    assert drive2.tolist() == [1, 1]


@pytest.fixture(scope="module")
def rolling():
    roll = np.linspace(0, 720, 25)           # two full turns, 30 degrees per frame
    m = _arm_motion(roll)
    sk = m.skeleton()[0]
    return m, sk, roll


def test_spread_moves_the_wrist_roll_onto_the_forearm_unwrapped(rolling):
    m, sk, roll = rolling
    spread = retarget(m, sk, twist="spread")
    joint = retarget(m, sk, twist="joint")
    assert len(spread.keys) == 25 and spread.fps == pytest.approx(25)
    np.testing.assert_allclose(spread.times, m.times)
    fore = sk.bone_index("elbow")
    th = np.array([p.twist[fore] for _, p in spread.keys])
    np.testing.assert_allclose(th[:, 0], 0, atol=1e-12)
    np.testing.assert_allclose(th[:, 1], np.radians(roll), atol=1e-9)     # 0 .. 4 pi
    assert np.abs(np.diff(th[:, 1])).max() < np.pi                          # never a full-turn jump
    for (_, ps), (_, pj), a in zip(spread.keys, joint.keys, roll, strict=True):
        assert not pj.twist.any()
        # same bone rotations and joints either way; the hand turned by the roll
        np.testing.assert_allclose(ps.rotations, pj.rotations, atol=1e-12)
        np.testing.assert_allclose(ps.joints(), pj.joints(), atol=1e-12)
        np.testing.assert_allclose(ps.rotations[sk.bone_index("wrist")], _rx(a)[0], atol=1e-12)


def test_the_spread_roll_grows_along_the_forearm(rolling):
    m, sk, roll = rolling
    k = 3                                      # 90 degrees of roll
    assert roll[k] == pytest.approx(90)
    # a tube around the forearm, all on the forearm bone, e by projection
    t = np.linspace(0.1, 0.9, 9)
    phi = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    T, P = np.meshgrid(t, phi, indexing="ij")
    V = np.column_stack([3 + 3 * T.ravel(), 0.5 * np.cos(P.ravel()), 0.5 * np.sin(P.ravel())])
    W = np.zeros((len(V), 3))
    W[:, sk.bone_index("elbow")] = 1
    E = stbs.weights.projection(V, sk)
    for twist, expect in (("spread", 90 * T.ravel()), ("joint", 0 * T.ravel())):
        pose = retarget(m, sk, twist=twist).keys[k][1]
        U = stbs.deform(V, sk, pose, W, E, method="stbs-lbs")
        turned = np.degrees(np.arctan2(U[:, 2], U[:, 1]) - np.arctan2(V[:, 2], V[:, 1]))
        turned = (turned + 180) % 360 - 180
        np.testing.assert_allclose(turned, expect, atol=1e-6)


def test_stretch_match_follows_the_source_bone_length():
    wx = np.linspace(3, 6, 5)                 # the forearm grows to twice its length
    m = _arm_motion(np.zeros(5), wrist_x=wx)
    sk = m.skeleton()[0]
    keep = retarget(m, sk)
    match = retarget(m, sk, stretch="match")
    fore = sk.bone_index("elbow")
    assert all((p.stretch == 1).all() for _, p in keep.keys)
    got = np.array([p.stretch[fore] for _, p in match.keys])
    # the total rest length is 7 in both, so the scale is 1 and sigma = length / 3
    np.testing.assert_allclose(got, wx / 3, atol=1e-12)
    np.testing.assert_allclose(match.keys[-1][1].ends[fore], [9, 0, 0], atol=1e-12)


def test_names_match_across_conventions():
    roll = np.array([0.0, 90.0])
    m = _arm_motion(roll)
    C = [[0, 0, 0], [3, 0, 0], [6, 0, 0], [7, 0, 0]]
    sk = stbs.Skeleton(C, [[0, 1], [1, 2], [2, 3]], names=["Shoulder", "ForeArm", "Hand"])
    # shoulder (before the elbow: the upper arm) = Shoulder, forearm ~ elbow, hand ~ wrist
    assert joint_map(m, sk) == {"Shoulder": "shoulder", "ForeArm": "elbow", "Hand": "wrist"}
    c = retarget(m, sk)
    np.testing.assert_allclose(c.keys[1][1].twist[1], [0, np.pi / 2], atol=1e-12)


def test_mapping_and_errors(tmp_path):
    m = _arm_motion(np.array([0.0, 90.0]))
    C = [[0, 0, 0], [3, 0, 0], [6, 0, 0], [7, 0, 0]]
    sk = stbs.Skeleton(C, [[0, 1], [1, 2], [2, 3]], names=["a", "b", "c"])
    with pytest.raises(ValueError, match=r"^no joint of the motion maps to a bone of the rig; "
                                         r"the rig's bones are a, b, c; .*give a mapping"):
        retarget(m, sk)
    mapping = {"a": "shoulder", "b": "elbow", "2": "wrist"}
    c = retarget(m, sk, mapping=mapping)
    np.testing.assert_allclose(c.keys[1][1].twist[1], [0, np.pi / 2], atol=1e-12)
    p = tmp_path / "map.json"
    p.write_text('{"a": "shoulder", "b": "elbow", "c": "wrist"}')
    c2 = retarget(m, sk, mapping=p)
    np.testing.assert_array_equal(c2.keys[1][1].twist, c.keys[1][1].twist)
    # by name, a bone without a joint is named in a warning and follows its parent
    sk4 = stbs.Skeleton(C + [[8, 0, 0]], [[0, 1], [1, 2], [2, 3], [3, 4]],
                        names=["shoulder", "elbow", "wrist", "finger"])
    c4 = retarget(m, sk4)
    assert joint_map(m, sk4)["finger"] is None
    np.testing.assert_allclose(c4.keys[1][1].rotations[3], c4.keys[1][1].rotations[2])
    # "c" follows its parent when unmapped: no roll reaches the forearm then
    c3 = retarget(m, sk, mapping={"a": "shoulder", "b": "elbow", "c": None})
    assert not c3.keys[1][1].twist.any()
    with pytest.raises(ValueError, match="the motion has no joint 'LeftWrist' .*its joints are"):
        retarget(m, sk, mapping={"c": "LeftWrist"})
    with pytest.raises(ValueError, match="the rig has no bone 'z'; its bones are a, b, c"):
        retarget(m, sk, mapping={"z": "wrist"})
    with pytest.raises(ValueError, match="twist must be one of 'spread', 'joint'"):
        retarget(m, sk, mapping=mapping, twist="rigid")
    with pytest.raises(ValueError, match="stretch must be one of"):
        retarget(m, sk, mapping=mapping, stretch="x")
    with pytest.raises(ValueError, match="3D rig"):
        retarget(m, stbs.Skeleton([[0, 0], [1, 0]], [[0, 1]]))
    with pytest.raises(TypeError, match="motion must be a stbs.Motion"):
        retarget("m", sk)


def test_the_cmu_clip_drives_its_own_skeleton(shared_data):
    """A capture on its own skeleton (Motion.skeleton: one hierarchy, offset children)
    is the capture again, moved as a whole: the skeleton starts where it stands and its
    feet are on its rest pose's ground."""
    m = stbs.read_bvh(shared_data / "bvh11-cmu" / "131_03.bvh")
    part = stbs.Motion(m.names, m.parents, m.offsets, rotations=m.rotations[::20],
                       translations=m.translations[::20], frame_time=20 * m.frame_time,
                       end_site=m.end_site)
    sk, drive, end = part.skeleton()
    assert sk.roots.size == 1
    assert joint_map(part, sk) == {n: n.split(">")[0] for n in sk.names}
    clip = retarget(part, sk)
    P = part.positions()
    th = np.array([p.twist for _, p in clip.keys])
    assert np.isfinite(th).all() and np.abs(th).max() > 0.1
    R, O, _, _ = clip.arrays(clip.times)
    ends = O + np.einsum("fbij,bj->fbi", R, sk.B - sk.A)
    shift = (P[:, end] - ends).reshape(-1, 3)
    np.testing.assert_allclose(shift, np.broadcast_to(shift[0], shift.shape), atol=1e-9)
    np.testing.assert_allclose((P[:, drive] - O).reshape(-1, 3), shift, atol=1e-9)
    # across the ground: from where it stands
    np.testing.assert_allclose(O[0, sk.roots[0], [0, 2]], sk.A[sk.roots[0], [0, 2]], atol=1e-9)


def test_a_motion_skeleton_is_one_hierarchy():
    R = np.tile(np.eye(3), (1, 6, 1, 1))
    m = stbs.Motion(["hips", "lhip", "lknee", "spine", "neck", "neck_end"],
                    [-1, 0, 1, 0, 3, 4],
                    [[0, 1, 0], [0, 0, 0], [0.2, -0.5, 0], [0, 0.3, 0], [0, 0.3, 0],
                     [0, 0.2, 0]], rotations=R, frame_time=1,
                    end_site=[False] * 5 + [True])
    sk, drive, end = m.skeleton()
    # lhip sits on the hips: its bone starts there; of the two bones at the root the
    # one heading more joints is the root bone, the other hangs from its start
    assert sk.names == ["lhip", "hips", "spine", "neck"]
    assert sk.parents.tolist() == [1, -1, 1, 2]
    assert sk.connected.tolist() == [False, False, True, True] and sk.hang[0] == 0


# ---------------------------------------------------------------- across rest postures
def _dirs(clip, sk, idx):
    R, O, _, _ = clip.arrays(clip.times)
    return np.einsum("fbij,bj->fbi", R[:, idx], sk.axes[idx])


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def test_a_t_pose_capture_puts_an_a_pose_characters_arms_where_it_has_them():
    f = 4
    # frames: the T-pose, arms lowered 45 degrees, arms raised 30, the forearm bent forward
    down = np.array([0.0, 45.0, -30.0, 0.0])
    rot = {"l_upperarm": hu.rot([0, 0, 1], -down, f), "r_upperarm": hu.rot([0, 0, 1], down, f)}
    bend = np.eye(3)[None].repeat(f, 0)
    bend[3] = hu.rot([0, 1, 0], 90)[0]
    rot["l_forearm"] = bend
    cap = hu.capture(hu.CMU, rotations=rot)
    sk, parts = hu.skeleton(hu.MIXAMO, arms_down=45.0)
    clip = retarget(cap, sk)
    P = cap.positions()
    for side in ("l", "r"):
        ua = sk.names.index(hu.MIXAMO["l_upperarm"].replace("Left", "Right") if side == "r"
                            else hu.MIXAMO["l_upperarm"])
        s0, s1 = (cap.names.index(n) for n in (
            ("LeftArm", "LeftForeArm") if side == "l" else ("RightArm", "RightForeArm")))
        want = _unit(P[:, s1] - P[:, s0])
        np.testing.assert_allclose(_dirs(clip, sk, [ua])[:, 0], want, atol=1e-9)
        # frame 0: the capture's T-pose; the character's arms stand out level
        assert abs(_dirs(clip, sk, [ua])[0, 0, 1]) < 1e-9
    # frame 1: the capture's arms are where the character's rest has them: its rest pose
    pose = clip.keys[1][1]
    arm = [i for i, p in enumerate(parts) if p.split("_")[-1] in ("upperarm", "forearm",
                                                                   "hand")]
    np.testing.assert_allclose(pose.rotations[arm], np.eye(3)[None].repeat(len(arm), 0),
                               atol=1e-9)
    # the bent forearm points forward (+z), as the capture's
    fa = sk.names.index(hu.MIXAMO["l_forearm"])
    np.testing.assert_allclose(_dirs(clip, sk, [fa])[3, 0], [0, 0, -1], atol=1e-9)


def _reorient(m: stbs.Motion, Q) -> stbs.Motion:
    """The same motion in a file whose joints' frames are turned by Q (j, 3, 3), so its
    rest pose (every rotation the identity) is no body at all (as Bandai Namco's)."""
    R = m.rotations
    P = m.parents
    Qp = np.array([Q[p] if p >= 0 else np.eye(3) for p in P])
    R2 = np.einsum("jba,fjbc,jcd->fjad", Qp, R, Q)
    O2 = np.einsum("jba,jb->ja", Qp, m.offsets)
    T2 = np.einsum("jba,fjb->fja", Qp, m.translations)
    return stbs.Motion(m.names, P, O2, rotations=R2, translations=T2, frame_time=m.frame_time,
                       end_site=m.end_site, source="turned.bvh")


def test_a_capture_whose_rest_pose_is_no_body_is_read_from_its_frames():
    f = 12
    t = np.linspace(0, 2 * np.pi, f)
    rot = {"l_thigh": hu.rot([1, 0, 0], 30 * np.sin(t), f),
           "r_thigh": hu.rot([1, 0, 0], -30 * np.sin(t), f),
           "l_upperarm": hu.rot([0, 0, 1], -70 + 10 * np.sin(t), f),
           "r_upperarm": hu.rot([0, 0, 1], 70 - 10 * np.sin(t), f),
           "l_shin": hu.rot([1, 0, 0], 20 + 20 * np.sin(t), f)}
    cap = hu.capture(hu.UNREAL, rotations=rot)
    # each joint's frame turned so that its bone lies along its own +x: the file's rest
    # pose puts every bone along x
    X = cap.rest_positions()
    Q = np.tile(np.eye(3), (cap.n_joints, 1, 1))
    for k in range(cap.n_joints):
        kids = cap.children(k)
        if kids:
            d = X[kids[0]] - X[k]
            Q[k] = stbs.transforms.rotation_between(np.array([[1.0, 0, 0]]), d[None])[0]
    odd = _reorient(cap, Q)
    np.testing.assert_allclose(odd.positions(), cap.positions(), atol=1e-9)
    sk, parts = hu.skeleton(hu.RIGIFY)
    a, b = retarget(cap, sk), retarget(odd, sk)
    for i in range(sk.n_bones):
        np.testing.assert_allclose(_dirs(b, sk, [i]), _dirs(a, sk, [i]), atol=1e-6)
    # the bones' roll too: the same rotations, up to rounding
    Ra, _, _, _ = a.arrays(a.times)
    Rb, _, _, _ = b.arrays(b.times)
    assert np.abs(Ra - Rb).max() < 1e-6


# ---------------------------------------------------------------- root travel
def test_root_travel_is_scaled_by_the_hip_heights_and_the_up_axis_found():
    """A z-up capture in centimetres glides 3 m along its forward (-y) and jumps 20 cm
    for a few frames; a y-up character half its size travels 1.5 m along its forward
    (+z), jumps 10 cm, and stands on its rest pose's ground in between."""
    f = 30
    t = np.linspace(0, 1, f)
    zup = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])
    jump = np.zeros(f)
    jump[10:14] = 20.0
    pelvis = np.column_stack([np.zeros(f), -300 * t, 100 + jump])
    cap = hu.capture(hu.CMU, scale=100.0, frame=zup, pelvis=pelvis)
    sk, parts = hu.skeleton(hu.MIXAMO, scale=0.5)
    clip = retarget(cap, sk)
    _, O, _, _ = clip.arrays(clip.times)
    hips = parts.index("pelvis")
    got = O[:, hips] - sk.A[hips]
    np.testing.assert_allclose(got[:, 0], 0, atol=1e-9)
    np.testing.assert_allclose(got[:, 2], 1.5 * t, atol=1e-9)
    # the capture's pelvis stands at its rest height over its floor: so does the rig's
    np.testing.assert_allclose(got[:, 1], jump / 200, atol=1e-9)


def test_a_capture_with_its_root_on_the_floor_and_the_pelvis_raised_by_a_channel():
    """The capture's rest pose hangs its pelvis at 0 (the root's offset) and a position
    channel lifts it to standing height: the character stays on its own ground."""
    f = 5
    X = hu.body(hu.CMU)[2]
    low = X[:, 1].min()
    cap = hu.capture(hu.CMU, pelvis=np.tile([0.0, 1.0, 0.0], (f, 1)))
    m2 = stbs.Motion(cap.names, cap.parents, cap.offsets - np.r_[[cap.offsets[0]],
                     np.zeros((cap.n_joints - 1, 3))], rotations=cap.rotations,
                     translations=cap.translations, frame_time=cap.frame_time,
                     end_site=cap.end_site)
    assert m2.rest_positions()[0].tolist() == [0, 0, 0] and low > 0
    sk, parts = hu.skeleton(hu.MIXAMO)
    _, O, _, _ = retarget(m2, sk).arrays(np.arange(f) / 30)
    np.testing.assert_allclose(O[:, parts.index("pelvis")], sk.A[parts.index("pelvis")][None]
                               .repeat(f, 0), atol=1e-9)


# ---------------------------------------------------------------- odd rigs
def test_an_ik_foot_parented_to_the_root_follows_the_shin():
    """A rig whose feet hang from a root at the ground (IK rigs): the capture's foot
    joint drives it, carried at the shin's end."""
    f = 6
    t = np.linspace(0, 1, f)
    rot = {"l_thigh": hu.rot([1, 0, 0], -60 * t, f), "l_shin": hu.rot([1, 0, 0], 80 * t, f)}
    cap = hu.capture(hu.MIXAMO, rotations=rot)
    labels, parents, X, ends, order = hu.body(hu.RIGIFY)
    # a root bone at the ground; the left foot hangs from it, not from the shin
    J = np.vstack([X, [[0, 0, 0]]])
    root = len(J) - 1
    par = np.r_[parents, -1]
    par[par == -1] = root
    par[root] = -1
    foot = order.index("l_foot")
    par[foot] = root
    names = labels + ["root"]
    from stbs.rig.joints import skeleton_from_joints

    sk = skeleton_from_joints(J, par, names)
    assert joint_map(cap, sk)[names[foot]] == "mixamorig:LeftFoot"
    clip = retarget(cap, sk)
    R, O, _, _ = clip.arrays(clip.times)
    shin = order.index("l_shin")
    # carried rigidly by the shin (whose own bone, a leaf now, ends elsewhere)
    carried = O[:, shin] + np.einsum("fij,j->fi", R[:, shin], sk.A[foot] - sk.A[shin])
    np.testing.assert_allclose(O[:, foot], carried, atol=1e-9)
    assert np.linalg.norm(O[-1, foot] - O[0, foot]) > 0.2


def test_siblings_named_alike_turn_with_the_one_that_maps():
    """Three palms off the forearm (Palm1.L, Palm2.L, Palm3.L): the one on the arm's chain
    is the hand; the others turn with it, not with the forearm."""
    f = 4
    rot = {"l_hand": hu.rot([0, 0, 1], np.linspace(0, 60, f), f)}
    cap = hu.capture(hu.CMU, rotations=rot)
    names = dict(hu.RIGIFY, l_hand="Palm2.L")
    labels, parents, X, ends, order = hu.body(names)
    hand = order.index("l_hand")
    fore = parents[hand]
    extra = [X[hand] + [0.1, 0, 0.03], X[hand] + [0.1, 0, -0.03]]
    J = np.vstack([X, [X[hand], X[hand]], extra])
    n = len(X)
    par = np.r_[parents, fore, fore, n, n + 1]
    from stbs.rig.joints import skeleton_from_joints

    sk = skeleton_from_joints(J, par, labels + ["Palm1.L", "Palm3.L", "Index.L", "Ring.L"])
    jm = joint_map(cap, sk)
    assert jm["Palm2.L"] == "LeftHand" and jm["Palm1.L"] is None and jm["Palm3.L"] is None
    R, _, _, _ = retarget(cap, sk).arrays(np.arange(f) / 30)
    for other in ("Palm1.L", "Palm3.L"):
        np.testing.assert_allclose(R[:, sk.names.index(other)], R[:, hand], atol=1e-12)
    assert np.abs(R[-1, hand] - R[-1, fore]).max() > 0.5


def test_the_no_joint_maps_error_names_the_file_on_one_line():
    cap = hu.capture(hu.CMU, source="walk.bvh")
    sk = stbs.Skeleton([[0, 0, 0], [1, 0, 0], [2, 0, 0]], [[0, 1], [1, 2]],
                       names=["Bone", "Bone.001"])
    with pytest.raises(ValueError) as e:
        retarget(cap, sk)
    msg = str(e.value)
    assert msg.startswith("no joint of 'walk.bvh' maps to a bone of the rig; the rig's bones "
                          "are Bone, Bone.001; the capture's joints are Hips, ")
    assert "\n" not in msg and msg.endswith("give a mapping {rig bone: capture joint}")


@pytest.mark.parametrize("seed", [0, 3, 6])
@pytest.mark.parametrize("names", ["MIXAMO", None])
def test_the_rigs_bone_order_does_not_matter(names, seed):
    """The same rig with its bones listed in another order (named, or unnamed and read
    from its shape) moves each bone alike."""
    f = 8
    t = np.linspace(0, 1, f)
    rot = {"spine1": hu.rot([1, 0, 0], 20 * t, f), "spine2": hu.rot([0, 0, 1], 15 * t, f),
           "chest": hu.rot([0, 1, 0], 30 * t, f), "l_upperarm": hu.rot([0, 0, 1], -50 * t, f),
           "r_thigh": hu.rot([1, 0, 0], -40 * t, f)}
    cap = hu.capture(hu.CMU, rotations=rot, pelvis=np.column_stack([t, 1 + 0 * t, 0 * t]))
    scheme = getattr(hu, names) if names else None
    a, pa = hu.skeleton(scheme)
    b, pb = hu.skeleton(scheme, shuffle=seed)
    if names is None:                # no telling names: joint_K in each order
        a = stbs.Skeleton(a.C, a.BE, names=[f"joint_{k}" for k in range(a.n_bones)], P=a.parents)
        b = stbs.Skeleton(b.C, b.BE, names=[f"joint_{k}" for k in range(b.n_bones)], P=b.parents)
    Ra, Oa, _, _ = retarget(cap, a).arrays(cap.times)
    Rb, Ob, _, _ = retarget(cap, b).arrays(cap.times)
    ib = [pb.index(p) for p in pa]
    np.testing.assert_allclose(Rb[:, ib], Ra, atol=1e-9)
    np.testing.assert_allclose(Ob[:, ib], Oa, atol=1e-9)
    assert np.abs(Ra[-1, pa.index("chest")] - np.eye(3)).max() > 0.1
