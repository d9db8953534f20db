"""read_bf: libigl 5-column and FAST 27-column bone forests."""

import numpy as np
import pytest

from stbs.io import FormatError, read_bf, read_dmat, read_mesh

# ---------------------------------------------------------------- hand-made files


def test_offsets_accumulate_from_parents(tmp_path):
    # node 0: unweighted root at (1, 0, 0); 1: child of 0; 2: child of 1 (listed before 1);
    # 3: unweighted child of 0; 4: weighted root = point handle.
    p = tmp_path / "f.bf"
    p.write_text("-1 -1 1 0 0\n"
                 "0 0 0 1 0\n"
                 "2 1 0 0 2\n"
                 "-1 0 0 0 -1\n"
                 "1 -1 5 5 5\n")
    bf = read_bf(p)
    np.testing.assert_array_equal(bf.C, [[1, 0, 0], [1, 1, 0], [1, 1, 2], [1, 0, -1], [5, 5, 5]])
    np.testing.assert_array_equal(bf.BE, [[0, 1], [1, 2], [0, 3]])
    np.testing.assert_array_equal(bf.weight_index, [0, 2, -1])
    np.testing.assert_array_equal(bf.node_parent, [-1, 0, 1, 0, -1])
    np.testing.assert_array_equal(bf.handles, [4])
    np.testing.assert_array_equal(bf.handle_weight_index, [1])
    assert bf.extra is None
    # bones sorted by weight column, the unweighted one last
    np.testing.assert_array_equal(bf.bone_order, [0, 1, 2])
    sk = bf.skeleton()
    assert sk.n_bones == 3 and sk.n_joints == 5


def test_child_listed_before_parent(tmp_path):
    p = tmp_path / "o.bf"
    p.write_text("1 2 0 0 1\n-1 -1 0 0 0\n0 1 1 0 0\n")
    bf = read_bf(p)
    np.testing.assert_array_equal(bf.C, [[1, 0, 1], [0, 0, 0], [1, 0, 0]])
    np.testing.assert_array_equal(bf.BE, [[2, 0], [1, 2]])
    np.testing.assert_array_equal(bf.weight_index, [1, 0])
    np.testing.assert_array_equal(bf.bone_order, [1, 0])
    np.testing.assert_array_equal(bf.skeleton().BE, [[1, 2], [2, 0]])


def test_negative_weight_indices_mean_unweighted(tmp_path):
    p = tmp_path / "n.bf"
    p.write_text("-3 -1 0 0 1\n0 0 0 1 0\n")
    bf = read_bf(p)
    np.testing.assert_array_equal(bf.node_weight_index, [-1, 0])
    assert bf.handles.size == 0


def test_fast_27_columns(tmp_path):
    tail = " 1 0 0 0 0 0 0 1 0 1 0 0 0 0 1 0 0 0 0 1 0 1"
    p = tmp_path / "fast.bf"
    p.write_text(f"-1 -1 0 0 1{tail}\n0 0 0 1 0{tail}\n")
    bf = read_bf(p)
    np.testing.assert_array_equal(bf.C, [[0, 0, 1], [0, 1, 1]])
    assert bf.extra.shape == (2, 22)
    np.testing.assert_array_equal(bf.extra[0, :4], [1, 0, 0, 0])  # quaternion w x y z
    assert bf.extra[0, 7] == 1 and bf.extra[0, 8] == 0  # stretch, twist


def test_dim_options(tmp_path):
    p = tmp_path / "flat.bf"
    p.write_text("-1 -1 0 0 0\n0 0 0 1 0\n")
    assert read_bf(p).C.shape == (2, 2)
    assert read_bf(p, dim=3).C.shape == (2, 3)


# ---------------------------------------------------------------- real shared files


def test_real_robot_arm_is_planar_unless_dim_3(shared_data):
    # robot-arm.bf lies in z = 0 but rigs a 3-D mesh: dim="auto" gives 2-D, dim=3 3-D.
    path = shared_data / "computer-graphics-kinematics/robot-arm.bf"
    bf = read_bf(path, dim=3)
    assert bf.C.shape == (7, 3) and bf.BE.shape == (6, 2)
    np.testing.assert_array_equal(bf.BE, [[0, 1], [1, 2], [2, 3], [3, 4], [4, 5], [5, 6]])
    np.testing.assert_array_equal(bf.weight_index, np.arange(6))
    np.testing.assert_allclose(bf.C[-1], [0, 0.04142 + 0.0752467 + 0.161533 + 0.2241
                                          + 0.1586 + 0.0748, 0], atol=1e-15)
    assert read_bf(path).C.shape == (7, 2)


def test_real_knight_bf_equals_knight_tgf(shared_data):
    from stbs.io import read_tgf

    d = shared_data / "computer-graphics-kinematics"
    bf = read_bf(d / "knight.bf")
    C, BE = read_tgf(d / "knight.tgf")
    assert bf.C.shape == (19, 3) and bf.BE.shape == (18, 2)
    np.testing.assert_allclose(bf.C, C, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(bf.BE, BE)
    np.testing.assert_array_equal(bf.weight_index, np.arange(18))


def test_real_fast_male_27_columns_and_weight_order(shared_data):
    d = shared_data / "FAST/male"
    bf = read_bf(d / "bone_roots.bf")
    assert bf.C.shape == (18, 3) and bf.BE.shape == (17, 2) and bf.extra.shape == (18, 22)
    np.testing.assert_array_equal(bf.extra[:, 7], 1)  # stretch
    np.testing.assert_array_equal(bf.extra[:, 8], 0)  # twist
    assert sorted(bf.weight_index.tolist()) == list(range(17))
    assert bf.weight_index.tolist() != list(range(17))  # the file lists them out of order
    # With bones sorted by weight column, the heaviest column is the nearest bone for
    # most vertices (MANIFEST: 0.93); in file order it would be about 0.29.
    sk = bf.skeleton()
    V = read_mesh(d / "mesh.mesh").V
    W = read_dmat(d / "weights.dmat")
    assert W.shape == (V.shape[0], sk.n_bones)
    A, B = sk.A, sk.B
    t = np.clip(np.einsum("nbd,bd->nb", V[:, None] - A, B - A) / sk.lengths**2, 0, 1)
    dist = np.linalg.norm(V[:, None] - (A + t[..., None] * (B - A)), axis=-1)
    assert np.mean(W.argmax(1) == dist.argmin(1)) > 0.9


def test_real_basset_point_handles(shared_data):
    bf = read_bf(shared_data / "FAST/Basset/bone_roots.bf")
    assert bf.C.shape == (6, 3)
    np.testing.assert_array_equal(bf.handles, [1, 2])
    np.testing.assert_array_equal(bf.handle_weight_index, [0, 1])
    np.testing.assert_array_equal(bf.weight_index, [2, 3, 4])
    np.testing.assert_array_equal(bf.node_weight_index[0], -1)  # "-3" in the file


def test_real_cactus_only_point_handles(shared_data):
    bf = read_bf(shared_data / "FAST/cactus_3d/bone_roots.bf")
    assert bf.BE.shape == (0, 2)
    np.testing.assert_array_equal(bf.handles, [0, 1])
    np.testing.assert_array_equal(bf.C[0], [0.527285, 0.521143, 0.069041])


# ---------------------------------------------------------------- broken files


@pytest.mark.parametrize("text, match", [
    ("", r"expected node lines 'wi parent x y z', found an empty file"),
    ("-1 -1 0 0 0 1 2\n", r"line 1: expected 5 columns 'wi parent x y z' or 27 \(FAST\), "
     r"found 7 columns"),
    ("-1 -1 0 0 0\n" + "0 0 0 1 0" + " 0" * 22 + "\n", r"line 2: expected 5 columns like line 1"),
    ("-1 -1 0 0 0\n0 2 0 1 0\n", r"line 2: expected a parent node index in -1..1"),
    ("-1 -1 0 0 0\n0 -2 0 1 0\n", r"line 2: expected a parent node index"),
    ("0 1 0 0 1\n1 0 0 1 0\n", r"line 1: expected a forest \(no node its own ancestor\), "
     r"found a cycle"),
    ("0 -1 0 0 1\n0 0 0 1 0\n", r"line 2: expected each weight index used once, found weight "
     r"index 0 again \(first on line 1\)"),
    ("-1 -1 0 0 0\n0 0.5 0 1 0\n", r"line 2: expected an integer parent index, found '0.5'"),
    ("-1 -1 0 0 0\n0 0 0 y 0\n", r"line 2: expected a number in column 4, found 'y'"),
    ("-1 -1 0 0 0\n0 0 0 inf 0\n", r"line 2: expected finite numbers"),
])
def test_broken_bf(tmp_path, text, match):
    p = tmp_path / "b.bf"
    p.write_text(text)
    with pytest.raises(FormatError, match=match) as info:
        read_bf(p)
    assert str(info.value).startswith(str(p))
