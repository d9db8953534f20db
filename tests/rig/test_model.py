"""stbs.Rig: one skeleton, built once; checks at construction; replace()."""

import numpy as np
import pytest
import scipy.sparse as sp

import stbs


def strip_rig(**over):
    kw = dict(V=[[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [2.0, 1.0]], F=[[0, 1, 3], [1, 2, 3]],
              C=[[0.0, 0.5], [1.0, 0.5], [2.0, 0.5]], BE=[[0, 1], [1, 2]],
              names=["upper", "lower"],
              W=[[1.0, 0.0], [0.5, 0.5], [0.0, 1.0], [0.0, 1.0]])
    kw.update(over)
    return stbs.Rig(**kw)


def test_the_rig_holds_one_skeleton_and_its_poses_compose():
    rig = strip_rig()
    assert rig.skeleton is rig.skeleton
    a = stbs.forward_kinematics(rig.skeleton, rotations=[0.3, -0.2])
    b = stbs.Pose.from_joints(rig.skeleton, rig.C + [0.0, 0.25])
    ab = a.compose(b)                      # failed when each access built a new Skeleton
    np.testing.assert_allclose(ab.origins, b.origins + np.einsum(
        "bij,bj->bi", b.rotations, a.origins - rig.skeleton.A))
    mid = a.interpolate(b, 0.5)
    assert mid.skeleton is rig.skeleton


def test_poses_of_a_saved_and_loaded_rig_compose_with_the_original(tmp_path):
    rig = strip_rig()
    stbs.save_rig(tmp_path / "r.npz", rig)
    back = stbs.load_rig(tmp_path / "r.npz")
    assert back.skeleton == rig.skeleton and back.skeleton is not rig.skeleton
    p = stbs.Pose.rest(back.skeleton).compose(stbs.forward_kinematics(rig.skeleton,
                                                                      rotations=[0.5, 0.0]))
    np.testing.assert_allclose(p.rotations[0], stbs.transforms.rotation_2d(0.5))


def test_skeleton_given_as_an_object():
    sk = stbs.Skeleton([[0, 0, 0], [0, 0, 1.0]], [[0, 1]], names=["spine"])
    rig = stbs.Rig(V=np.zeros((4, 3)) + [0, 0, 0.5], T=[[0, 1, 2, 3]], skeleton=sk,
                   W=np.ones((4, 1)))
    assert rig.skeleton is sk and rig.names == ["spine"] and rig.dim == 3
    assert np.shares_memory(rig.C, sk.C)
    with pytest.raises(TypeError, match="not both"):
        stbs.Rig(V=rig.V, skeleton=sk, C=sk.C, BE=sk.BE, W=rig.W)
    with pytest.raises(TypeError, match="skeleton must be a stbs.Skeleton"):
        stbs.Rig(V=rig.V, skeleton=sk.C, W=rig.W)
    with pytest.raises(TypeError, match="needs its skeleton"):
        stbs.Rig(V=rig.V, W=rig.W)
    with pytest.raises(ValueError, match="C must have 3 columns"):
        stbs.Rig(V=rig.V, C=[[0, 0], [1, 0]], BE=[[0, 1]], W=rig.W)


def test_skeleton_arrays_are_read_only():
    rig = strip_rig()
    with pytest.raises(AttributeError):
        rig.C = np.zeros((3, 2))
    with pytest.raises(ValueError):
        rig.C[0, 0] = 5.0


@pytest.mark.parametrize("over, match", [
    (dict(W=np.ones((3, 2))), r"W must have shape \(4, 2\)"),
    (dict(E=np.ones((4, 3))), r"E must have shape \(4, 2\)"),
    (dict(F=[[0, 1, 9]]), r"F must hold vertex indices in 0..3, got 9"),
    (dict(W=sp.csr_array(np.full((4, 2), np.nan))), "W must be finite"),
    (dict(meta=[1]), "meta must be a dict"),
])
def test_bad_fields_name_the_argument(over, match):
    with pytest.raises(ValueError, match=match):
        strip_rig(**over)


def test_replace_keeps_the_skeleton_and_checks_again():
    rig = strip_rig()
    E = np.full((4, 2), 0.5)
    new = rig.replace(E=E, meta={"endpoint": "painted"})
    assert new.skeleton is rig.skeleton and new.names == ["upper", "lower"]
    np.testing.assert_array_equal(new.E, E)
    assert rig.E is None and new.meta == {"endpoint": "painted"}
    assert rig.replace(names=["a", "b"]).names == ["a", "b"]
    with pytest.raises(ValueError, match="W must have shape"):
        rig.replace(W=np.ones((4, 3)))
    unnamed = strip_rig(names=None)
    assert unnamed.names is None and unnamed.replace(E=E).names is None
