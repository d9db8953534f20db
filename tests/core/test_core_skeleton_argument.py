"""A wrong skeleton argument reads the same everywhere (one check, stbs._checks.skeleton)."""

import numpy as np
import pytest

import stbs

V2 = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]])
F2 = np.array([[0, 1, 2]])
V3 = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
F3 = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
W2 = np.ones((3, 1))

CALLS = {
    "Pose": lambda sk: stbs.Pose(sk, rotations=np.eye(2)[None], origins=np.zeros((1, 2))),
    "Pose.rest": lambda sk: stbs.Pose.rest(sk),
    "Pose.from_joints": lambda sk: stbs.Pose.from_joints(sk, np.eye(2)),
    "forward_kinematics": lambda sk: stbs.forward_kinematics(sk),
    "deform": lambda sk: stbs.deform(V2, sk, None, W2),
    "Deformer": lambda sk: stbs.Deformer(V2, sk, W2),
    "triangulate_2d": lambda sk: stbs.triangulate_2d((V2, F2), sk),
    "tetrahedralize": lambda sk: stbs.tetrahedralize(V3, F3, sk),
    "read_pose": lambda sk: stbs.read_pose({}, sk),
    "build_rig": lambda sk: stbs.build_rig(V2, sk, F=F2),
    "Rig": lambda sk: stbs.Rig(V=V2, skeleton=sk, W=W2),
}


# Rig(skeleton=None) is not a wrong skeleton: it means C and BE are given instead.
CASES = [(name, bad) for name in sorted(CALLS) for bad in (np.eye(2), [[0, 1]], None, "x.tgf")
         if not (name == "Rig" and bad is None)]


@pytest.mark.parametrize("name, bad", CASES)
def test_not_a_skeleton_is_one_type_error(name, bad):
    with pytest.raises(TypeError, match=rf"^(sk|skeleton) must be a stbs.Skeleton, got "
                                        rf"{type(bad).__name__}$"):
        CALLS[name](bad)


@pytest.mark.parametrize("name", ["deform", "Deformer", "build_rig"])
def test_a_skeleton_of_the_other_dimension(name):
    sk3 = stbs.Skeleton([[0, 0, 0], [1, 0, 0]], [[0, 1]])
    with pytest.raises(ValueError, match=r"V must have shape \(3, 3\) to match the 3D "
                                         r"skeleton"):
        CALLS[name](sk3)
