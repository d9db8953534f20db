"""read_mesh / write_mesh: hand-made files, real shared files, broken files."""

import struct

import numpy as np
import pytest

from stbs.io import FormatError, Mesh, read_mesh, write_mesh

# ---------------------------------------------------------------- hand-made files


def test_obj_slashes_negative_indices_and_polygon_fans(tmp_path):
    p = tmp_path / "m.obj"
    p.write_text(
        "# comment\nmtllib x.mtl\no thing\n"
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0.5 1.5 1 0.2 0.3 0.4\n"
        "vt 0 0\nvn 0 0 1\n"
        "f 1/1/1 2/1/1 3/1/1\n"  # v/vt/vn
        "f -5//1 -3//1 -2//1\n"  # negative = relative to the 5 vertices so far
        "  f 1 2 3 4 5\n"  # pentagon -> fan (0,1,2) (0,2,3) (0,3,4)
        "l 1 2\n"
    )
    m = read_mesh(p)
    assert m.V.shape == (5, 3) and m.V.dtype == np.float64 and m.T is None
    np.testing.assert_array_equal(m.V[4], [0.5, 1.5, 1])  # colour columns ignored
    np.testing.assert_array_equal(
        m.F, [[0, 1, 2], [0, 2, 3], [0, 1, 2], [0, 2, 3], [0, 3, 4]])


def test_obj_quads_keep_face_order(tmp_path):
    p = tmp_path / "q.obj"
    p.write_text("v 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\nv 2 2 2\n"
                 "f 1 2 3\nf 1 2 3 4\nf 2 3 5\n")
    np.testing.assert_array_equal(read_mesh(p).F, [[0, 1, 2], [0, 1, 2], [0, 2, 3], [1, 2, 4]])


def test_planar_obj_dim_options(tmp_path):
    p = tmp_path / "flat.obj"
    p.write_text("v 0 0 0\nv 2 0 0\nv 0 3 0\nf 1 2 3\n")
    assert read_mesh(p).V.shape == (3, 2)
    assert read_mesh(p, dim=2).V.shape == (3, 2)
    V3 = read_mesh(p, dim=3).V
    assert V3.shape == (3, 3) and not V3[:, 2].any()
    q = tmp_path / "bent.obj"
    q.write_text("v 0 0 0\nv 2 0 0\nv 0 3 1e-9\nf 1 2 3\n")
    assert read_mesh(q).V.shape == (3, 3)
    with pytest.raises(ValueError, match=r"dim=2 .*max \|z\| = 1e-09"):
        read_mesh(q, dim=2)
    with pytest.raises(ValueError, match="dim must be 'auto', 2 or 3, got 4"):
        read_mesh(p, dim=4)


def test_off_comments_colours_and_quads(tmp_path):
    p = tmp_path / "c.off"
    p.write_text("COFF # coloured\n4 2 0\n# a comment line\n"
                 "0 0 1 255 0 0 255\n1 0 1 0 255 0 255\n1 1 1 0 0 255 255\n0 1 1 9 9 9 255\n"
                 "4 0 1 2 3 200 0 0\n3 3 2 1\n")
    m = read_mesh(p)
    np.testing.assert_array_equal(m.V, [[0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]])
    np.testing.assert_array_equal(m.F, [[0, 1, 2], [0, 2, 3], [3, 2, 1]])


def test_off_counts_on_header_line(tmp_path):
    p = tmp_path / "h.off"
    p.write_text("OFF 3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
    m = read_mesh(p)
    assert m.V.shape == (3, 2) and m.F.tolist() == [[0, 1, 2]]


MEDIT = """MeshVersionFormatted 1
Dimension
3
Vertices
5
0 0 0 1
1 0 0 1
0 1 0 1
0 0 1 1
0.25 0.25 0.25 0
Triangles 2
1 2 3 0
1 2 4 0
Edges
0
Tetrahedra
2
1 2 3 5 0
1 2 5 4 0
End
"""


def test_medit_tets_one_based(tmp_path):
    p = tmp_path / "t.mesh"
    p.write_text(MEDIT)
    m = read_mesh(p)
    assert m.V.shape == (5, 3)
    np.testing.assert_array_equal(m.V[4], [0.25, 0.25, 0.25])
    np.testing.assert_array_equal(m.F, [[0, 1, 2], [0, 1, 3]])
    np.testing.assert_array_equal(m.T, [[0, 1, 2, 4], [0, 1, 4, 3]])


def test_medit_planar_tets_stay_3d(tmp_path):
    # dim="auto" never drops z from a tet mesh; dim=2 is an error there.
    p = tmp_path / "flat.mesh"
    p.write_text("Dimension 3\nVertices\n4\n0 0 0 0\n1 0 0 0\n0 1 0 0\n1 1 0 0\n"
                 "Tetrahedra\n1\n1 2 3 4 0\nEnd\n")
    assert read_mesh(p).V.shape == (4, 3)
    with pytest.raises(ValueError, match="tetrahedra"):
        read_mesh(p, dim=2)


def test_medit_2d(tmp_path):
    p = tmp_path / "d2.mesh"
    p.write_text("MeshVersionFormatted 2\nDimension 2\nVertices\n3\n0 0 7\n1 0 7\n0 1 7\n"
                 "Triangles\n1\n1 2 3 0\n")
    m = read_mesh(p)
    np.testing.assert_array_equal(m.V, [[0, 0], [1, 0], [0, 1]])
    assert read_mesh(p, dim=3).V.shape == (3, 3)


GMSH_ASCII = """$MeshFormat
2.2 0 8
$EndMeshFormat
$Nodes
5
10 0 0 0
20 1 0 0
30 0 1 0
40 0 0 1
50 0.25 0.25 0.25
$EndNodes
$Elements
4
1 15 2 0 1 10
2 1 2 0 1 10 20
3 2 2 0 1 10 20 30
4 4 2 0 1 10 20 30 50
$EndElements
"""


def _gmsh_binary() -> bytes:
    out = [b"$MeshFormat\n2.2 1 8\n", struct.pack("<i", 1), b"\n$EndMeshFormat\n$Nodes\n5\n"]
    for i, x in zip([10, 20, 30, 40, 50], [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1),
                                           (0.25, 0.25, 0.25)], strict=True):
        out.append(struct.pack("<i3d", i, *x))
    out.append(b"\n$EndNodes\n$Elements\n3\n")
    out.append(struct.pack("<3i", 2, 1, 2) + struct.pack("<6i", 3, 0, 1, 10, 20, 30))
    out.append(struct.pack("<3i", 4, 2, 2) + struct.pack("<7i", 4, 0, 1, 10, 20, 30, 50)
               + struct.pack("<7i", 5, 0, 1, 10, 20, 50, 40))
    out.append(b"\n$EndElements\n")
    return b"".join(out)


def test_gmsh22_ascii_and_binary_agree(tmp_path):
    a = tmp_path / "a.msh"
    a.write_text(GMSH_ASCII)
    b = tmp_path / "b.msh"
    b.write_bytes(_gmsh_binary())
    ma, mb = read_mesh(a), read_mesh(b)
    np.testing.assert_array_equal(ma.F, [[0, 1, 2]])  # node ids 10.. -> rows 0..
    np.testing.assert_array_equal(ma.T, [[0, 1, 2, 4]])
    np.testing.assert_array_equal(ma.V, mb.V)
    np.testing.assert_array_equal(mb.F, [[0, 1, 2]])
    np.testing.assert_array_equal(mb.T, [[0, 1, 2, 4], [0, 1, 4, 3]])


@pytest.mark.parametrize("ext", [".obj", ".off", ".ply"])
def test_write_read_round_trip_is_exact(tmp_path, ext):
    rng = np.random.default_rng(7)
    V = rng.normal(size=(30, 3)) * 10.0 ** rng.integers(-8, 8, size=(30, 1))
    F = rng.integers(0, 30, size=(40, 3))
    p = tmp_path / f"r{ext}"
    write_mesh(p, V, F)
    m = read_mesh(p)
    np.testing.assert_array_equal(m.V, V)  # bit-exact: shortest repr / float64 PLY
    np.testing.assert_array_equal(m.F, F)
    assert [q.name for q in tmp_path.iterdir()] == [p.name]


def test_write_2d_writes_z0_and_reads_back_2d(tmp_path):
    V = np.array([[0.0, 0.0], [1.5, 0.0], [0.0, 2.5]])
    p = tmp_path / "t.obj"
    write_mesh(p, V, [[0, 1, 2]])
    assert "v 1.5 0.0 0.0" in p.read_text()
    np.testing.assert_array_equal(read_mesh(p).V, V)
    q = tmp_path / "t.ply"
    write_mesh(q, V, [[0, 1, 2]])
    np.testing.assert_array_equal(read_mesh(q).V, V)
    assert read_mesh(q, dim=3).V.shape == (3, 3)


def test_write_point_cloud_obj(tmp_path):
    p = tmp_path / "pts.obj"
    write_mesh(p, [[0, 0, 1], [1, 2, 3]])
    m = read_mesh(p)
    assert m.F is None and m.V.shape == (2, 3)


def test_meshio_formats_stl_vtk(tmp_path):
    import meshio

    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float)
    for ext in (".stl", ".vtk"):
        p = tmp_path / f"m{ext}"
        meshio.write(p, meshio.Mesh(pts, [("triangle", np.array([[0, 1, 2], [0, 1, 3]]))]))
        m = read_mesh(p)
        assert m.F.shape == (2, 3) and m.V.shape[1] == 3
        np.testing.assert_allclose(m.V[m.F[1]], pts[[0, 1, 3]])


def test_mesh_dataclass_validates():
    with pytest.raises(ValueError, match=r"F must hold vertex indices in 0..2, got 3"):
        Mesh(np.zeros((3, 3)), np.array([[0, 1, 3]]))
    with pytest.raises(ValueError, match=r"T must have shape \(\?, 4\)"):
        Mesh(np.zeros((3, 3)), None, np.array([[0, 1, 2]]))
    assert Mesh(np.zeros((3, 2))).dim == 2


def test_write_mesh_rejects_bad_input(tmp_path):
    with pytest.raises(ValueError, match=r"supported extensions are \.obj, \.off, \.ply"):
        write_mesh(tmp_path / "m.stl", np.zeros((3, 3)), [[0, 1, 2]])
    with pytest.raises(ValueError, match="F must hold vertex indices in 0..2, got 5"):
        write_mesh(tmp_path / "m.obj", np.zeros((3, 3)), [[0, 1, 5]])
    with pytest.raises(ValueError, match="V must be finite"):
        write_mesh(tmp_path / "m.obj", [[0, 0, np.nan]])
    assert list(tmp_path.iterdir()) == []


# ---------------------------------------------------------------- real shared files
# Expected counts copied by hand from shared/data/MANIFEST.md and COUNTS.jsonl.


def test_real_arm_obj(shared_data):
    m = read_mesh(shared_data / "libigl-tutorial-data/arm.obj")
    assert m.V.shape == (8311, 3) and m.F.shape == (16618, 3) and m.T is None
    assert m.F.min() == 0 and m.F.max() == 8310


def test_real_cylinder_obj_polygons(shared_data):
    # 200 quads + 2 twenty-gon caps (with v/vt/vn corners): 200*2 + 2*18 triangles.
    m = read_mesh(shared_data / "libigl-tutorial-data/cylinder.obj")
    assert m.V.shape == (220, 3) and m.F.shape == (436, 3)
    caps = m.F[400:]
    assert len(np.unique(caps[:18, 0])) == 1 and len(np.unique(caps[18:, 0])) == 1
    assert len(np.unique(m.F)) == 220


def test_real_cube_off_quads(shared_data):
    m = read_mesh(shared_data / "libigl-tutorial-data/cube.off")
    assert m.V.shape == (8, 3) and m.F.shape == (12, 3)
    np.testing.assert_array_equal(m.F[:2], [[0, 1, 2], [0, 2, 3]])  # "4  0 1 2 3"
    np.testing.assert_array_equal(m.V[0], [1, 0, 1])


def test_real_hand_mesh_tets(shared_data):
    m = read_mesh(shared_data / "libigl-tutorial-data/hand.mesh")
    assert m.V.shape == (7234, 3) and m.T.shape == (29998, 4) and m.F.shape == (9556, 3)
    assert m.F.max() + 1 == 4780  # boundary triangles use a prefix of the vertices
    assert m.T.min() == 0 and m.T.max() == 7233
    np.testing.assert_array_equal(m.V[0], [0.013411, -0.798051, -0.081061])


def test_real_hand_msh_matches_hand_mesh(shared_data):
    a = read_mesh(shared_data / "libigl-tutorial-data/hand.mesh")
    b = read_mesh(shared_data / "libigl-tutorial-data/hand.msh")  # gmsh 2.2 binary
    np.testing.assert_allclose(b.V, a.V, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(b.T, a.T)
    np.testing.assert_array_equal(b.F, a.F)


def test_real_knight_ply_binary_double(shared_data):
    m = read_mesh(shared_data / "computer-graphics-kinematics/knight.ply")
    assert m.V.shape == (2002, 3) and m.F.shape == (4000, 3)
    assert m.V.dtype == np.float64
    assert np.any(m.V != m.V.astype(np.float32))  # really double precision in the file


@pytest.mark.parametrize("rel, n, f", [("common-3d-test-models/woody.obj", 694, 1267),
                                       ("fast_support_reduction/woody.obj", 2863, 5478)])
def test_real_woody_obj_is_2d(shared_data, rel, n, f):
    m = read_mesh(shared_data / rel)
    assert m.V.shape == (n, 2) and m.F.shape == (f, 3)
    assert read_mesh(shared_data / rel, dim=3).V.shape == (n, 3)


# ---------------------------------------------------------------- broken files


def test_missing_file_names_path(tmp_path):
    p = tmp_path / "nope.obj"
    with pytest.raises(FileNotFoundError, match="nope.obj"):
        read_mesh(p)


def test_unknown_extension_lists_supported(tmp_path):
    p = tmp_path / "m.xyz"
    p.write_text("1 2 3\n")
    with pytest.raises(ValueError, match=r"\.obj, \.off, \.ply, \.stl, \.mesh, \.msh, \.vtk"):
        read_mesh(p)


@pytest.mark.parametrize("ext", [".obj", ".off", ".mesh", ".ply", ".msh"])
def test_empty_file(tmp_path, ext):
    p = tmp_path / f"e{ext}"
    p.write_text("")
    with pytest.raises(FormatError, match=r"e\..*: expected .*, found an empty file"):
        read_mesh(p)


@pytest.mark.parametrize("text, match", [
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", r"line 4: expected a vertex index in 1..3, found '4'"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n", r"line 4: expected a vertex index != 0"),
    ("v 0 0 0\nf -2 -1 -1\nv 1 0 0\n", r"line 2: expected a relative vertex index in -1..-1"),
    ("v 0 0 0\nv 1 zero 0\n", r"line 2: expected a number in a vertex 'v x y z', found 'zero'"),
    ("v 0 0\n", r"line 1: expected at least 3 numbers"),
    ("v 0 0 0\nv 1 0 0\nf 1 2\n", r"line 3: expected a face with at least 3 vertices, found 2"),
    ("v 0 0 0\nf 1/a x 1\n", r"line 2: expected a face corner"),
    ("# only a comment\n", r"expected at least one vertex line"),
])
def test_broken_obj(tmp_path, text, match):
    p = tmp_path / "b.obj"
    p.write_text(text)
    with pytest.raises(FormatError, match=match) as info:
        read_mesh(p)
    assert str(p) in str(info.value)


@pytest.mark.parametrize("text, match", [
    ("PLY\n3 1 0\n", r"line 1: expected an 'OFF' header"),
    ("OFF\n3 1 0\n0 0 0\n1 0 0\n", r"expected 3 vertex lines and 1 face lines"),
    ("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n", r"line 6: expected vertex indices in 0..2"),
    ("OFF\nthree 1 0\n", r"line 2: expected counts 'nV nF nE'"),
    ("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n4 0 1 2\n", r"line 6: expected a face 'k i_1 ... i_k'"),
])
def test_broken_off(tmp_path, text, match):
    p = tmp_path / "b.off"
    p.write_text(text)
    with pytest.raises(FormatError, match=match):
        read_mesh(p)


@pytest.mark.parametrize("text, match", [
    (MEDIT.replace("Tetrahedra\n2\n", "Tetrahedra\n3\n").replace("End\n", ""),
     r"expected 3 lines in the Tetrahedra block"),
    (MEDIT.replace("1 2 5 4 0", "1 2 6 4 0"), r"line 19: expected tetrahedron with vertex "
     r"indices in 1..5, found \[1, 2, 6, 4\]"),
    (MEDIT.replace("0.25 0.25 0.25 0", "0.25 0.25 x 0"), r"line 10: expected a number"),
    (MEDIT.replace("Vertices\n5", "Vertices\nfive"), r"line 5: expected a non-negative integer "
     r"after 'Vertices'"),
    ("Dimension 3\nTriangles\n0\n", r"expected a Vertices block, found none"),
    (MEDIT.replace("Edges\n0", "Hexahedra\n1\n1 2 3 4 5 1 2 3 0"), r"expected only Triangles"),
])
def test_broken_medit(tmp_path, text, match):
    p = tmp_path / "b.mesh"
    p.write_text(text)
    with pytest.raises(FormatError, match=match):
        read_mesh(p)


def test_broken_gmsh(tmp_path):
    p = tmp_path / "t.msh"
    p.write_bytes(_gmsh_binary()[:150])
    with pytest.raises(FormatError, match="t.msh: expected"):
        read_mesh(p)
    q = tmp_path / "u.msh"
    q.write_text(GMSH_ASCII.replace("10 20 30 50", "10 20 30 99"))
    with pytest.raises(FormatError, match="node id 99"):
        read_mesh(q)


def test_corrupt_ply_is_a_format_error_not_system_exit(tmp_path, capsys):
    p = tmp_path / "bad.ply"
    p.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 3\n"
                  b"property double x\nend_header\n\x00\x01")
    with pytest.raises(FormatError, match=r"bad.ply: expected a readable \.ply mesh, found "
                       r"meshio error"):
        read_mesh(p)
    out = capsys.readouterr()
    assert out.out == "" and out.err == ""  # meshio's prints are captured into the message


def test_folder_instead_of_file(tmp_path):
    d = tmp_path / "dir.obj"
    d.mkdir()
    with pytest.raises(IsADirectoryError, match="dir.obj"):
        read_mesh(d)


def test_a_ply_declaring_more_than_it_holds_is_refused_before_reading(tmp_path):
    """A 180-byte PLY declaring a trillion vertices: one error from its header, before
    meshio allocates anything."""
    p = tmp_path / "big.ply"
    p.write_text("ply\nformat binary_little_endian 1.0\nelement vertex 1000000000000\n"
                 "property float x\nproperty float y\nproperty float z\nelement face 1\n"
                 "property list uchar int vertex_indices\nend_header\n")
    with pytest.raises(FormatError, match=r"a PLY file of at least 12000000000001 bytes .* "
                                          r"\(1000000000000 vertex, 1 face\)"):
        read_mesh(p)
