"""stbs.io.read_pose and write_pose: both JSON forms, names and indices, degrees, bad input."""

import json
import math

import numpy as np
import pytest

import stbs
from stbs import transforms as tf
from stbs.io import read_pose

D = math.pi / 180


@pytest.fixture
def sk3():
    # A chain upper -> forearm -> hand from joint 0, plus a second root bone "other"
    # that also starts at joint 0.
    C = [[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0], [0, 1, 0]]
    BE = [[0, 1], [1, 2], [2, 3], [0, 4]]
    return stbs.Skeleton(C, BE, names=["upper", "forearm", "hand", "other"])


@pytest.fixture
def sk2():
    return stbs.Skeleton([[0, 0], [1, 0], [2, 0]], [[0, 1], [1, 2]], names=["a", "b"])


def assert_pose_equal(p, q):
    for name in ("rotations", "origins", "stretch", "twist"):
        np.testing.assert_allclose(getattr(p, name), getattr(q, name), atol=1e-12,
                                   err_msg=name)


def rot(axis, deg):
    return tf.axis_angle_to_matrix(np.asarray(axis, float), deg * D)


# ---------------------------------------------------------------- forward kinematics form
def test_empty_object_is_rest_pose(sk3):
    assert read_pose({}, sk3).is_rest(tol=1e-15)


def test_rotate_by_index_string_int_and_name(sk3):
    L = np.tile(np.eye(3), (4, 1, 1))
    L[1] = rot([0, 0, 1], 90)
    want = stbs.forward_kinematics(sk3, rotations=L)
    for key in ("1", 1, "forearm"):
        got = read_pose({"rotate": {key: {"axis": [0, 0, 1], "angle": 90}}}, sk3)
        assert_pose_equal(got, want)
    # The child starts at the parent's end and inherits its rotation.
    np.testing.assert_allclose(got.origins[2], [1, 1, 0], atol=1e-12)


def test_axis_need_not_be_unit(sk3):
    a = read_pose({"rotate": {"0": {"axis": [0, 3, 0], "angle": 45}}}, sk3)
    b = read_pose({"rotate": {"0": {"axis": [0, 1, 0], "angle": 45}}}, sk3)
    assert_pose_equal(a, b)


def test_degrees_default_true_and_radians(sk3):
    deg = read_pose({"rotate": {"0": {"axis": [0, 1, 0], "angle": 90}},
                     "twist": {"forearm": [0, 180]}}, sk3)
    deg2 = read_pose({"rotate": {"0": {"axis": [0, 1, 0], "angle": 90}},
                      "twist": {"forearm": [0, 180]}, "degrees": True}, sk3)
    rad = read_pose({"rotate": {"0": {"axis": [0, 1, 0], "angle": math.pi / 2}},
                     "twist": {"forearm": [0, math.pi]}, "degrees": False}, sk3)
    assert_pose_equal(deg, deg2)
    assert_pose_equal(deg, rad)
    np.testing.assert_allclose(deg.rotations[0], rot([0, 1, 0], 90), atol=1e-12)


def test_stretch_and_translate(sk3):
    got = read_pose({"stretch": {"upper": 2, "2": 0.5}, "translate": [1, 2, 3]}, sk3)
    want = stbs.forward_kinematics(sk3, stretch=[2, 1, 0.5, 1], translation=[1, 2, 3])
    assert_pose_equal(got, want)
    np.testing.assert_allclose(got.origins[1], [3, 2, 3])


def test_end_twist_spreads_along_bone_and_turns_children(sk3):
    # Fig. 5: {"forearm": [0, 180]} spreads 180 deg along the forearm, hand turned by 180.
    got = read_pose({"twist": {"forearm": [0, 180]}}, sk3)
    tau = np.zeros(5)
    tau[2] = math.pi
    assert_pose_equal(got, stbs.forward_kinematics(sk3, twist=tau))
    np.testing.assert_allclose(got.twist[1], [0, math.pi])
    np.testing.assert_allclose(got.twist[2], [0, 0])
    np.testing.assert_allclose(got.rotations[2], rot([1, 0, 0], 180), atol=1e-12)


def test_root_start_twist(sk3):
    got = read_pose({"twist": {"upper": [30, 90], "other": [30, 0]}}, sk3)
    np.testing.assert_allclose(got.twist[0], [30 * D, 90 * D])
    np.testing.assert_allclose(got.twist[3], [30 * D, 0], atol=1e-15)
    # The forearm inherits the upper bone's full end twist (90 deg) rigidly.
    np.testing.assert_allclose(got.rotations[1], rot([1, 0, 0], 90), atol=1e-12)


def test_a_start_twist_is_the_bone_own_twist(sk3):
    # a start twist on a root turns that root only; on a child it turns the child about
    # its axis on top of the frame it inherits
    got = read_pose({"twist": {"upper": [30, 90], "hand": [10, 20]}}, sk3)
    np.testing.assert_allclose(got.twist[0], [30 * D, 90 * D], atol=1e-15)
    np.testing.assert_allclose(got.twist[2], [10 * D, 20 * D], atol=1e-15)
    np.testing.assert_allclose(got.twist[3], [0, 0], atol=1e-15)
    want = stbs.Pose.from_local(sk3, twist=got.twist)
    assert_pose_equal(got, want)


def test_2d_rotation_angle_only(sk2):
    got = read_pose({"rotate": {"b": {"angle": 30}}, "stretch": {"a": 1.5}}, sk2)
    want = stbs.forward_kinematics(sk2, rotations=[0, 30 * D], stretch=[1.5, 1])
    assert_pose_equal(got, want)
    # Zero twists are allowed in 2D.
    read_pose({"twist": {"a": [0, 0]}}, sk2)


# ---------------------------------------------------------------- joints form
def test_joints_form(sk3):
    Cp = [[0, 0, 0], [0, 1, 0], [0, 3, 0], [0, 4, 0], [-1, 0, 0]]
    got = read_pose({"joints": Cp, "twist": {"3": [0, 180], "hand": [10, 20]}}, sk3)
    th = np.zeros((4, 2))
    th[3] = (0, math.pi)
    th[2] = (10 * D, 20 * D)  # absolute per-bone twists, also on a non-root bone
    want = stbs.Pose.from_joints(sk3, Cp, twist=th)
    assert_pose_equal(got, want)
    np.testing.assert_allclose(got.stretch, [1, 2, 1, 1])


def test_joints_form_2d_radians(sk2):
    got = read_pose({"joints": [[0, 0], [0, 1], [0, 2]], "degrees": False}, sk2)
    np.testing.assert_allclose(got.ends, [[0, 1], [0, 2]], atol=1e-12)


# ---------------------------------------------------------------- files
def test_read_from_file(tmp_path, sk3):
    p = tmp_path / "pose.json"
    p.write_text(json.dumps({"stretch": {"forearm": 1.5}}))
    for src in (p, str(p)):
        np.testing.assert_allclose(read_pose(src, sk3).stretch, [1, 1.5, 1, 1])


def test_missing_file(tmp_path, sk3):
    with pytest.raises(FileNotFoundError):
        read_pose(tmp_path / "nope.json", sk3)


def test_malformed_json_names_file_and_line(tmp_path, sk3):
    p = tmp_path / "bad.json"
    p.write_text('{"stretch": {"0": 1.5},\n "rotate": }\n')
    with pytest.raises(ValueError, match=r"bad\.json, line 2.*not valid pose JSON"):
        read_pose(p, sk3)


def test_nan_literal_in_file(tmp_path, sk3):
    p = tmp_path / "nan.json"
    p.write_text('{"stretch": {"0": NaN}}')
    with pytest.raises(ValueError, match=r"nan\.json: expected pose JSON with finite numbers, "
                                        r"found NaN"):
        read_pose(p, sk3)


# ---------------------------------------------------------------- bad input
BAD_3D = [
    ({"rotate": {}, "foo": 1}, r"key 'foo': unknown key"),
    ({"joints": [], "rotate": {}}, r"key 'rotate': not allowed with \"joints\""),
    ({"joints": [[0, 0, 0]] * 5, "stretch": {}}, r"key 'stretch'"),
    ({"rotate": {"7": {"axis": [0, 0, 1], "angle": 1}}}, r"\"rotate\": bone '7' does not exist"),
    ({"stretch": {"-1": 2}}, r"\"stretch\": bone '-1' does not exist"),
    ({"twist": {"elbow": [0, 1]}}, r"\"twist\": bone 'elbow' does not exist"),
    ({"stretch": {"1": 2, "forearm": 3}}, r"bone 'forearm'.*given twice \(also as '1'\)"),
    ({"rotate": {"0": {"axis": [0, 1], "angle": 1}}}, r"'0' \"axis\": expected a 3D axis.*2 "),
    ({"rotate": {"0": {"axis": [0, 0, 0], "angle": 1}}}, r"non-zero axis"),
    ({"rotate": {"0": {"angle": 1}}}, r"bone '0': missing \"axis\""),
    ({"rotate": {"0": {"axis": [0, 0, 1]}}}, r"bone '0': missing \"angle\""),
    ({"rotate": {"0": {"axis": [0, 0, 1], "angle": 1, "x": 2}}}, r"unexpected key 'x'"),
    ({"rotate": {"0": 90}}, r"bone '0': expected \{\"axis\""),
    ({"rotate": [1, 2]}, r"\"rotate\": expected an object \{bone: value\}"),
    ({"rotate": {"0": {"axis": [0, 0, 1], "angle": "90"}}}, r"\"angle\": expected a number"),
    ({"rotate": {"0": {"axis": [0, 0, 1], "angle": True}}}, r"\"angle\": expected a number"),
    ({"rotate": {"0": {"axis": [0, float("nan"), 1], "angle": 1}}}, r"\"axis\"\[1\]: "
                                                                     r"expected a finite"),
    ({"rotate": {"0": {"axis": [0, 0, 1], "angle": float("inf")}}}, r"expected a finite"),
    ({"stretch": {"hand": 0}}, r"bone 'hand': stretch must be > 0"),
    ({"stretch": {"hand": -1.5}}, r"bone 'hand': stretch must be > 0"),
    ({"stretch": {"hand": None}}, r"bone 'hand': expected a number"),
    ({"twist": {"hand": [0, 1, 2]}}, r"bone 'hand': expected \[start, end\].*3 values"),
    ({"twist": {"hand": 180}}, r"bone 'hand': expected \[start, end\]"),
    ({"translate": [0, 0]}, r"\"translate\": expected a 3D offset.*2 values"),
    ({"translate": [0, 0, float("nan")]}, r"\"translate\"\[2\]: expected a finite"),
    ({"degrees": "yes"}, r"\"degrees\": expected true or false"),
    ({"joints": [[0, 0, 0]] * 4}, r"\"joints\": expected 5 posed joint positions.*4 rows"),
    ({"joints": [[0, 0, 0]] * 4 + [[0, 0]]}, r"\"joints\"\[4\]: expected a 3D position"),
    ({"joints": [[0, 0, 0]] * 4 + [[0, float("nan"), 0]]}, r"\"joints\"\[4\]\[1\]: "
                                                          r"expected a finite"),
    ({"joints": [[0, 0, 0]] * 5}, r"\"joints\": C_posed: bone 0 .*zero posed length"),
    ({"joints": [[0, 0, 0]] * 4 + [[0, 1, 0]], "twist": {"9": [0, 1]}}, r"bone '9' does not"),
]


@pytest.mark.parametrize("obj, match", BAD_3D)
def test_bad_input_3d(sk3, obj, match):
    with pytest.raises(ValueError, match=r"^pose: .*" + match):
        read_pose(obj, sk3)


BAD_2D = [
    ({"twist": {"a": [0, 90]}}, r"\"twist\" bone 'a': twist must be 0 for a 2D skeleton"),
    ({"joints": [[0, 0], [1, 0], [2, 0]], "twist": {"b": [0, 1]}}, r"bone 'b': twist must be 0"),
    ({"rotate": {"a": {"axis": [0, 0, 1], "angle": 3}}}, r"unexpected key 'axis' \(a 2D "
                                                         r"rotation has no axis\)"),
    ({"rotate": {"a": {}}}, r"missing \"angle\"; expected \{\"angle\": a\}"),
    ({"translate": [0, 0, 0]}, r"expected a 2D offset"),
    ({"joints": [[0, 0, 0], [1, 0, 0], [2, 0, 0]]}, r"\"joints\"\[0\]: expected a 2D position"),
]


@pytest.mark.parametrize("obj, match", BAD_2D)
def test_bad_input_2d(sk2, obj, match):
    with pytest.raises(ValueError, match=r"^pose: .*" + match):
        read_pose(obj, sk2)


def test_top_level_must_be_an_object(tmp_path, sk3):
    p = tmp_path / "list.json"
    p.write_text("[1, 2]")
    with pytest.raises(ValueError, match=r"list\.json: expected a JSON object"):
        read_pose(p, sk3)


def test_type_errors(sk3):
    with pytest.raises(TypeError, match="sk must be a stbs.Skeleton"):
        read_pose({}, "skeleton")
    with pytest.raises(TypeError, match="path_or_dict"):
        read_pose(42, sk3)


# ----------------------------------------------------------------------------- write_pose


def _chain3d():
    C = [[0, 0, 0], [1, 0, 0], [2, 0.5, 0], [3, 0.5, 0.5], [1, 1, 0]]
    BE = [[0, 1], [1, 2], [2, 3], [1, 4]]
    return stbs.Skeleton(C, BE, names=["upper", "fore", "hand", "side"])


def _same(p, q, atol=1e-12):
    for a in ("rotations", "origins", "stretch", "twist"):
        np.testing.assert_allclose(getattr(p, a), getattr(q, a), atol=atol, err_msg=a)


@pytest.mark.parametrize("degrees", [True, False])
def test_write_pose_fk_round_trip(tmp_path, degrees):
    from stbs.io import write_pose

    sk = _chain3d()
    rng = np.random.default_rng(3)
    L = stbs.transforms.axis_angle_to_matrix(rng.normal(size=(4, 3)), rng.uniform(-3, 3, 4))
    pose = stbs.forward_kinematics(sk, rotations=L, stretch=[1.2, 0.7, 1.0, 2.0],
                                   twist=np.radians([30, 0, 400, -90, 10]),
                                   translation=[0.5, -1, 2])
    path = tmp_path / "p.json"
    write_pose(path, pose, degrees=degrees)
    obj = json.loads(path.read_text())
    assert set(obj) <= {"rotate", "stretch", "twist", "translate", "degrees"}
    assert obj["degrees"] is degrees and "hand" not in obj.get("stretch", {})
    _same(read_pose(path, sk), pose)


def test_write_pose_fk_form_describes_every_pose(tmp_path):
    from stbs.io import pose_to_dict, write_pose

    sk = _chain3d()
    Cp = np.array(sk.C) + np.random.default_rng(1).normal(scale=0.2, size=sk.C.shape)
    theta = np.zeros((4, 2))
    theta[2] = np.radians([45, 200])        # a non-root start twist
    pose = stbs.Pose.from_joints(sk, Cp, twist=theta)
    obj = pose_to_dict(pose)
    assert "rotate" in obj and obj["twist"] == {"hand": [pytest.approx(45), pytest.approx(200)]}
    write_pose(tmp_path / "j.json", pose)
    _same(read_pose(tmp_path / "j.json", sk), pose)
    obj = pose_to_dict(pose, form="joints")
    assert "joints" in obj
    write_pose(tmp_path / "k.json", pose, form="joints")
    _same(read_pose(tmp_path / "k.json", sk), pose)


def test_write_pose_2d_and_rest(tmp_path):
    from stbs.io import pose_to_dict, write_pose

    sk = stbs.Skeleton([[0, 0], [1, 0], [2, 0]], [[0, 1], [1, 2]])
    assert pose_to_dict(stbs.Pose.rest(sk)) == {"degrees": True}
    pose = stbs.forward_kinematics(sk, rotations=[0.4, -1.1], stretch=[1.5, 1.0])
    write_pose(tmp_path / "p.json", pose, form="fk")
    _same(read_pose(tmp_path / "p.json", sk), pose)
    write_pose(tmp_path / "q.json", pose, form="joints")
    _same(read_pose(tmp_path / "q.json", sk), pose)


def test_write_pose_parted_and_rolled_poses_and_leaves_files_alone(tmp_path):
    from stbs.io import pose_to_dict, write_pose

    sk = _chain3d()
    rest = stbs.Pose.rest(sk)
    origins = np.array(rest.origins)
    origins[1] += [0, 0, 0.3]               # the forearm leaves the elbow
    rolled = stbs.transforms.axis_angle_to_matrix(np.array(sk.axes), np.full(4, 0.5))
    pose = stbs.Pose(sk, rotations=rolled, origins=origins)
    obj = pose_to_dict(pose)
    # the forearm's offset from the elbow, in the frame the upper bone carries it in
    assert sk.names[1] in obj["translate"] and sk.names[0] not in obj["translate"]
    write_pose(tmp_path / "p.json", pose)
    _same(read_pose(tmp_path / "p.json", sk), pose)
    # the joints form cannot say it, and a failed write leaves the file alone
    with pytest.raises(ValueError, match="joints form"):
        pose_to_dict(pose, form="joints")
    target = tmp_path / "keep.json"
    target.write_text("{}")
    with pytest.raises(ValueError):
        write_pose(target, pose, form="joints")
    assert target.read_text() == "{}"
    with pytest.raises(ValueError, match="form must be one of auto, fk, joints"):
        pose_to_dict(rest, form="bvh")
    with pytest.raises(TypeError, match="pose must be a stbs.Pose"):
        pose_to_dict(sk)
