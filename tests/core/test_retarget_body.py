"""stbs.retargeting.names and .body: joint names read across conventions, and the body
parts of a hierarchy found from names or, for unnamed joints, from its shape."""

from __future__ import annotations

import humanoids as hu
import numpy as np
import pytest

import stbs
from stbs.retargeting.names import candidates, parse_name


@pytest.mark.parametrize("name, side, words", [
    ("mixamorig:LeftForeArm", "l", ("forearm",)),
    ("mixamorig1:RightUpLeg", "r", ("upleg",)),
    ("LeftUpLeg", "l", ("upleg",)),
    ("UpperArm_L", "l", ("upperarm",)),
    ("DEF-upper_arm.L", "l", ("upperarm",)),
    ("thigh.R", "r", ("thigh",)),
    ("lowerarm_l", "l", ("lowerarm",)),
    ("Bip01 R Forearm", "r", ("forearm",)),
    ("ElbowLeft", "l", ("elbow",)),
    ("lShoulder", "l", ("shoulder",)),
    ("lhand", "l", ("hand",)),
    ("LHipJoint", "l", ("hipjoint",)),
    ("lTorso_Clavicle", "l", ("torso", "clavicle")),
    ("b_LeftUpperArm_09", "l", ("upperarm",)),
    ("Spine1", "", ("spine",)),
    ("joint_Root", "", ("root",)),
    ("Hips", "", ("hips",)),
])
def test_names_read_as_a_side_and_words(name, side, words):
    p = parse_name(name)
    assert (p.side, p.words) == (side, words) and p.part


@pytest.mark.parametrize("name", ["HeadTop_End", "LeftToe_End", "LeftHandIndex1",
                                  "upperarm_twist_01_l", "PoleTarget.L", "mixamorig:LeftEye",
                                  "ik_foot_l", "b_Tail01_012", "RThumb"])
def test_names_that_are_no_body_part_have_no_role(name):
    assert candidates(parse_name(name)) == {}


def test_ambiguous_names_list_every_role_they_may_be():
    assert candidates(parse_name("LeftShoulder")) == {"collar": 2, "upperarm": 2}
    assert candidates(parse_name("LeftLeg")) == {"thigh": 1, "shin": 2}
    assert candidates(parse_name("lHip")) == {"hip": 2, "thigh": 2}
    assert candidates(parse_name("b_Hip_01")) == {"pelvis": 2}       # no side: the pelvis
    assert candidates(parse_name("pelvis_lowerback")) == {"spine": 3}  # the last part word
    assert candidates(parse_name("torso_head")) == {"head": 3}
    assert candidates(parse_name("SpineShoulder")) == {"spine": 3}     # Kinect: no side


def _roles(labels, body):
    return {labels[k]: body.side[k] + (body.role[k] or "") for k in range(len(labels))
            if body.role[k]}


def _read(sk):
    """The rig reading of retargeting (bones and leaf tails), as a dict name -> role."""
    from stbs.retargeting.core import _target

    t = _target(sk)
    return _roles(sk.names, t.body), t.body


EXPECT = {"pelvis": "pelvis", "spine1": "spine", "spine2": "spine", "chest": "spine",
          "neck": "neck", "head": "head", "l_collar": "lcollar", "l_upperarm": "lupperarm",
          "l_forearm": "lforearm", "l_hand": "lhand", "l_thigh": "lthigh", "l_shin": "lshin",
          "l_foot": "lfoot", "l_toe": "ltoe"}
for _k, _v in list(EXPECT.items()):
    if _k.startswith("l_"):
        EXPECT["r_" + _k[2:]] = "r" + _v[1:]


@pytest.mark.parametrize("scheme", ["CMU", "MIXAMO", "LAFAN", "UNITY", "UNREAL", "RIGIFY",
                                    "GAMES105", "BIPED"])
def test_every_convention_reads_as_the_same_body(scheme):
    names = getattr(hu, scheme)
    sk, parts = hu.skeleton(names)
    got, body = _read(sk)
    assert body.how == "names"
    want = {sk.names[k]: EXPECT[p] for k, p in enumerate(parts)}
    assert got == want


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("frame", ["y-up", "z-up", "turned"])
def test_unnamed_joints_read_from_the_shape(seed, frame):
    """No telling names (joint_0 ...), joints in any order, any up axis and facing: the
    parts and the sides come from the shape (the sides from where the toes point)."""
    F = {"y-up": np.eye(3),
         "z-up": np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]]),       # y -> z, z -> -y
         "turned": hu.rot([0, 1, 0], 130)[0]}[frame]
    sk, parts = hu.skeleton(frame=F, shuffle=seed)
    sk = stbs.Skeleton(sk.C, sk.BE, names=[f"joint_{k}" for k in range(sk.n_bones)],
                       P=sk.parents)
    got, body = _read(sk)
    assert body.how == "structure"
    assert got == {f"joint_{k}": EXPECT[p] for k, p in enumerate(parts)}


def _capture_roles(path):
    m = stbs.read_bvh(path)
    from stbs.retargeting.core import _source

    s = _source(m)
    return _roles(m.names, s.body)


def test_the_shared_captures_read_as_bodies(shared_data):
    bvh = shared_data / "characters" / "bvh"
    cmu = _capture_roles(bvh / "fairmotion_cmu_01_01.bvh")
    # CMU (cgspeed): LeftShoulder is the collar, LeftArm the upper arm, LHipJoint the
    # pelvis's side piece before the thigh LeftUpLeg, LeftLeg the shin
    for name, role in {"Hips": "pelvis", "LeftShoulder": "lcollar", "LeftArm": "lupperarm",
                       "LeftForeArm": "lforearm", "LeftHand": "lhand", "LHipJoint": "lhip",
                       "LeftUpLeg": "lthigh", "LeftLeg": "lshin", "LeftFoot": "lfoot",
                       "LeftToeBase": "ltoe", "RightShoulder": "rcollar", "Neck1": "neck",
                       "Head": "head", "LowerBack": "spine", "Spine1": "spine"}.items():
        assert cmu[name] == role, name
    assert "LFingers" not in cmu and "LThumb" not in cmu
    older = _capture_roles(shared_data / "bvh11-cmu" / "131_01.bvh")
    # the older CMU conversion: LeftCollar, then LeftShoulder is the upper arm; of the two
    # joints at the wrist (LeftWrist, lhand) the one whose bone has a length is the hand
    for name, role in {"LeftCollar": "lcollar", "LeftShoulder": "lupperarm",
                       "LeftElbow": "lforearm", "lhand": "lhand", "LeftHip": "lthigh",
                       "LeftKnee": "lshin", "LeftAnkle": "lfoot", "Chest2": "spine"}.items():
        assert older[name] == role, name
    assert "LeftWrist" not in older
    g = _capture_roles(bvh / "games105_walk60.bvh")
    for name, role in {"RootJoint": "pelvis", "lTorso_Clavicle": "lcollar",
                       "lShoulder": "lupperarm", "lElbow": "lforearm", "lWrist": "lhand",
                       "lHip": "lthigh", "lKnee": "lshin", "lAnkle": "lfoot",
                       "lToeJoint": "ltoe", "pelvis_lowerback": "spine",
                       "lowerback_torso": "spine", "torso_head": "head",
                       "rShoulder": "rupperarm"}.items():
        assert g[name] == role, name
    bn = _capture_roles(bvh / "dataset-1_walk_normal_002.bvh")
    for name, role in {"joint_Root": "root", "Hips": "pelvis", "Spine": "spine",
                       "Chest": "spine", "Neck": "neck", "Head": "head",
                       "Shoulder_L": "lcollar", "UpperArm_L": "lupperarm",
                       "LowerArm_L": "lforearm", "Hand_L": "lhand", "UpperLeg_L": "lthigh",
                       "LowerLeg_L": "lshin", "Foot_L": "lfoot", "Toes_L": "ltoe",
                       "Hand_R": "rhand"}.items():
        assert bn[name] == role, name


def test_tree_depths_in_one_pass_over_a_chain_ten_thousand_deep():
    """A capture's hierarchy 10,000 joints deep (a hostile BVH) gets its depths in one
    pass, not by walking up from every joint (joints x depth steps)."""
    from stbs.retargeting.body import Tree

    n = 10_000
    tree = Tree(np.arange(-1, n - 1), np.zeros((n, 3)), np.zeros(n, dtype=bool))
    np.testing.assert_array_equal(tree.depth, np.arange(n))
    forked = Tree([-1, 0, 0, 2, -1], np.zeros((5, 3)), np.zeros(5, dtype=bool))
    np.testing.assert_array_equal(forked.depth, [0, 1, 1, 2, 0])
