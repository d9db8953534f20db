"""Rig, save_rig, load_rig: the versioned .npz rig file."""

import numpy as np
import pytest
import scipy.sparse as sp

import stbs
from stbs import Rig
from stbs.io import (
    RIG_VERSION,
    FormatError,
    load_rig,
    read_dmat,
    read_mesh,
    read_tgf,
    save_rig,
)


def small_rig(**over) -> Rig:
    """Two bones along x on a 4-vertex strip, weights computed by hand."""
    V = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [2.0, 1.0]])
    kw = dict(
        V=V,
        F=np.array([[0, 1, 3], [1, 2, 3]]),
        C=np.array([[0.0, 0.5], [1.0, 0.5], [2.0, 0.5]]),
        BE=np.array([[0, 1], [1, 2]]),
        names=["upper", "lower"],
        W=np.array([[1.0, 0.0], [0.5, 0.5], [0.0, 1.0], [0.0, 1.0]]),
        E=np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [1.0, 1.0]]),
        meta={"bone_weights": "painted", "alpha": 2},
    )
    kw.update(over)
    return Rig(**kw)


def raw_arrays(path):
    with np.load(path, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def write_raw(path, arrays):
    np.savez(path, **arrays)


# ---------------------------------------------------------------- round trips


def test_dense_round_trip(tmp_path):
    rig = small_rig()
    p = tmp_path / "r.npz"
    save_rig(p, rig)
    out = load_rig(p)
    for k in ("V", "F", "C", "BE", "W", "E"):
        np.testing.assert_array_equal(getattr(out, k), getattr(rig, k))
    assert out.T is None and out.names == ["upper", "lower"]
    assert out.meta == {"bone_weights": "painted", "alpha": 2}
    assert out.V.dtype == np.float64 and out.F.dtype == np.int64 and out.BE.dtype == np.int64
    assert [q.name for q in tmp_path.iterdir()] == ["r.npz"]


def test_documented_keys_and_version(tmp_path):
    p = tmp_path / "r.npz"
    save_rig(p, small_rig())
    raw = raw_arrays(p)
    assert set(raw) == {"stbs_rig_version", "V", "F", "C", "BE", "P", "names", "W", "E",
                        "meta_json"}
    assert raw["P"].tolist() == [-1, 0]
    assert raw["stbs_rig_version"].shape == () and int(raw["stbs_rig_version"]) == 1 == RIG_VERSION
    assert raw["names"].dtype.kind == "U"


def test_sparse_round_trip_uses_csr_keys(tmp_path):
    rig = small_rig(W=sp.csr_array(small_rig().W), E=sp.coo_matrix(small_rig().E), meta={})
    p = tmp_path / "s.npz"
    save_rig(p, rig)
    raw = raw_arrays(p)
    assert {"W_data", "W_indices", "W_indptr", "W_shape", "E_data"} <= set(raw)
    assert "W" not in raw and "meta_json" not in raw
    np.testing.assert_array_equal(raw["W_shape"], [4, 2])
    out = load_rig(p)
    assert isinstance(out.W, sp.csr_array) and isinstance(out.E, sp.csr_array)
    np.testing.assert_array_equal(out.W.toarray(), small_rig().W)
    np.testing.assert_array_equal(out.E.toarray(), small_rig().E)
    assert out.meta == {}


def test_minimal_rig_and_tets(tmp_path):
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    rig = Rig(V=V, T=[[0, 1, 2, 3]], C=[[0, 0, 0], [0, 0, 1.0]], BE=[[0, 1]], W=np.ones(4))
    p = tmp_path / "t.npz"
    save_rig(p, rig)
    out = load_rig(p)
    assert out.F is None and out.E is None and out.names is None
    np.testing.assert_array_equal(out.T, [[0, 1, 2, 3]])
    assert out.W.shape == (4, 1)
    sk = out.skeleton
    assert isinstance(sk, stbs.Skeleton) and sk.names == ["bone0"]


def test_skeleton_property_and_dim():
    rig = small_rig()
    assert rig.skeleton.names == ["upper", "lower"] and rig.dim == 2
    np.testing.assert_array_equal(rig.skeleton.parents, [-1, 0])


def test_real_arm_rig_round_trip(shared_data, tmp_path):
    d = shared_data / "libigl-tutorial-data"
    m = read_mesh(d / "arm.obj")
    C, BE = read_tgf(d / "arm.tgf")
    W = read_dmat(d / "arm-weights.dmat")
    rig = Rig(V=m.V, F=m.F, C=C, BE=BE, W=W, meta={"source": "libigl tutorial 404"})
    p = tmp_path / "arm.npz"
    save_rig(p, rig)
    out = load_rig(p)
    np.testing.assert_array_equal(out.V, m.V)
    np.testing.assert_array_equal(out.W, W)
    assert out.skeleton.n_bones == 4 and out.W.shape == (8311, 4)


# ---------------------------------------------------------------- Rig validation


@pytest.mark.parametrize("over, match", [
    (dict(W=np.ones((3, 2))), r"W must have shape \(4, 2\) \(vertices, bones\), got \(3, 2\)"),
    (dict(W=np.ones((4, 3))), r"W must have shape \(4, 2\)"),
    (dict(E=sp.csr_array(np.ones((4, 1)))), r"E must have shape \(4, 2\)"),
    (dict(C=np.zeros((3, 3)) + np.arange(3)[:, None]), r"C must have 2 columns like V"),
    (dict(F=[[0, 1, 4]]), r"F must hold vertex indices in 0..3, got 4"),
    (dict(BE=[[0, 1], [1, 1]]), r"starts and ends at the same joint"),
    (dict(names=["a"]), r"names must have 2 entries"),
    (dict(W=None), r"W must be given"),
    (dict(meta=[1]), r"meta must be a dict"),
])
def test_rig_rejects_inconsistent_input(over, match):
    with pytest.raises(ValueError, match=match):
        small_rig(**over)


def test_save_rejects_bad_path_and_meta(tmp_path):
    with pytest.raises(ValueError, match=r"supported extensions are \.npz"):
        save_rig(tmp_path / "r.rig", small_rig())
    with pytest.raises(ValueError, match="rig must be a stbs.Rig"):
        save_rig(tmp_path / "r.npz", {"V": 1})
    old = tmp_path / "keep.npz"
    save_rig(old, small_rig())
    before = old.read_bytes()
    with pytest.raises(ValueError, match="meta must be JSON-serialisable"):
        save_rig(old, small_rig(meta={"x": object()}))
    assert old.read_bytes() == before  # a failed save leaves the old file untouched
    assert [q.name for q in tmp_path.iterdir()] == ["keep.npz"]


# ---------------------------------------------------------------- broken files


@pytest.fixture
def good(tmp_path):
    p = tmp_path / "good.npz"
    save_rig(p, small_rig())
    return raw_arrays(p)


def _broken(good, **changes):
    arrays = dict(good)
    for k, v in changes.items():
        if v is None:
            arrays.pop(k)
        else:
            arrays[k] = v
    return arrays


@pytest.mark.parametrize("changes, match", [
    (dict(stbs_rig_version=np.int64(2)), r"expected stbs_rig_version 1 \(the version this "
     r"stbs reads\), found version 2"),
    (dict(stbs_rig_version=None), r"expected a stbs rig with key 'stbs_rig_version'"),
    (dict(stbs_rig_version=np.array([1, 1])), r"'stbs_rig_version' as one integer"),
    (dict(W=None), r"expected key 'W' \(dense\) or \['W_data', 'W_indices', 'W_indptr', "
     r"'W_shape'\] \(sparse\)"),
    (dict(V=None), r"expected required key 'V'"),
    (dict(BE=None), r"expected required key 'BE'"),
    (dict(W=np.ones((3, 2))), r"expected a consistent stbs rig, found W must have shape "
     r"\(4, 2\) \(vertices, bones\), got \(3, 2\)"),
    (dict(W=np.ones((4, 3))), r"W must have shape \(4, 2\)"),
    (dict(E=np.ones((4, 1))), r"E must have shape \(4, 2\)"),
    (dict(names=np.array(["a", "b", "c"])), r"names must have 2 entries"),
    (dict(names=np.array([1, 2])), r"'names' as a 1-D unicode array"),
    (dict(V=np.array(["a"])), r"expected 'V' of float dtype, found dtype <U1"),
    (dict(BE=np.array([[0.0, 1.0], [1.0, 2.0]])), r"expected 'BE' of integer dtype"),
    (dict(F=np.array([[0, 1, 9]])), r"F must hold vertex indices in 0..3, got 9"),
    (dict(meta_json=np.array("[1, 2]")), r"'meta_json' as the text of a JSON object"),
    (dict(W_data=np.ones(1)), r"expected either 'W' or the CSR keys"),
    (dict(names=np.array([None, None], dtype=object)),
     r"expected member 'names': a numeric or text array \(object arrays are never "
     r"unpickled\), found dtype object"),
])
def test_broken_rig_files(tmp_path, good, changes, match):
    p = tmp_path / "bad.npz"
    np.savez(p, **_broken(good, **changes))
    with pytest.raises(FormatError, match=match) as info:
        load_rig(p)
    assert str(info.value).startswith(str(p))


def test_broken_sparse_parts(tmp_path, good):
    base = _broken(good, W=None)
    W = sp.csr_array(small_rig().W)
    parts = dict(W_data=W.data, W_indices=W.indices.astype(np.int64),
                 W_indptr=W.indptr.astype(np.int64), W_shape=np.array([4, 2]))
    p = tmp_path / "s.npz"
    np.savez(p, **base, **{k: v for k, v in parts.items() if k != "W_indptr"})
    with pytest.raises(FormatError, match=r"expected all CSR keys .*\['W_indptr'\] missing"):
        load_rig(p)
    np.savez(p, **base, **dict(parts, W_shape=np.array([5, 2])))
    with pytest.raises(FormatError, match="consistent CSR arrays for W|W must have shape"):
        load_rig(p)
    np.savez(p, **base, **dict(parts, W_shape=np.array([4.0, 2.0])))
    with pytest.raises(FormatError, match=r"'W_shape' = \[rows, cols\]"):
        load_rig(p)


def test_object_array_is_never_unpickled(tmp_path, good):
    p = tmp_path / "o.npz"
    np.savez(p, **_broken(good, V=np.array([[0.0, 1.0]], dtype=object)))
    with pytest.raises(FormatError, match=r"expected member 'V': .* found dtype object"):
        load_rig(p)


def test_not_an_npz_empty_and_missing(tmp_path):
    p = tmp_path / "x.npz"
    p.write_text("hello")
    with pytest.raises(FormatError, match=r"expected an .npz \(zip\) archive .* found another "
                       "kind of file"):
        load_rig(p)
    p.write_text("")
    with pytest.raises(FormatError, match="found an empty file"):
        load_rig(p)
    with pytest.raises(FileNotFoundError, match="nothing.npz"):
        load_rig(tmp_path / "nothing.npz")


def test_truncated_archive(tmp_path):
    p = tmp_path / "r.npz"
    save_rig(p, small_rig())
    data = p.read_bytes()
    p.write_bytes(data[: len(data) // 2])
    with pytest.raises(FormatError, match="r.npz"):
        load_rig(p)


def test_damaged_archive_member(tmp_path):
    p = tmp_path / "r.npz"
    save_rig(p, small_rig())
    data = bytearray(p.read_bytes())
    mid = len(data) // 3
    data[mid:mid + 40] = bytes(40)
    p.write_bytes(bytes(data))
    with pytest.raises(FormatError, match="r.npz: expected"):
        load_rig(p)


def test_offset_children_round_trip(tmp_path):
    # a leg hanging off the hips' start: the parent array P is kept
    import stbs
    sk = stbs.Skeleton([[0, 0, 0], [0, 1, 0], [0.2, 0, 0], [0.2, -1, 0]], [[0, 1], [2, 3]],
                       names=["hips", "leg"], P=[-1, 0])
    rig = stbs.Rig(V=[[0, 0.5, 0], [0.2, -0.5, 0]], W=np.eye(2), skeleton=sk)
    save_rig(tmp_path / "o.npz", rig)
    back = load_rig(tmp_path / "o.npz")
    assert back.skeleton == sk and back.skeleton.parents.tolist() == [-1, 0]
    # without P the leg would be a root
    assert stbs.Skeleton(sk.C, sk.BE).parents.tolist() == [-1, -1]


def _bomb(path, rig_path, key="W", rows=50_000_000):
    """``rig_path``'s archive with member ``key`` replaced by ``rows`` x 2 zeros, deflated
    (a thousandfold smaller) and streamed, so that writing it costs no memory."""
    import io
    import zipfile

    src = np.load(rig_path)
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as out:
        for k in src.files:
            with out.open(f"{k}.npy", "w", force_zip64=True) as f:
                if k != key:
                    np.lib.format.write_array(f, src[k], allow_pickle=False)
                    continue
                head = io.BytesIO()
                np.lib.format.write_array_header_1_0(
                    head, {"descr": "<f8", "fortran_order": False, "shape": (rows, 2)})
                f.write(head.getvalue())
                zeros, left = bytes(1 << 22), rows * 16
                while left > 0:
                    f.write(zeros[:left])
                    left -= len(zeros)
    return path


def test_a_zip_bomb_is_refused_before_it_is_inflated(tmp_path):
    """A rig of a few hundred kilobytes whose weights inflate to 800 MB: refused from the
    member's header, before decompressing (not after, by the shape check)."""
    good = tmp_path / "good.npz"
    save_rig(good, small_rig())
    bomb = _bomb(tmp_path / "bomb.npz", good)
    assert bomb.stat().st_size < 2_000_000
    with pytest.raises(FormatError, match=r"member 'W' of shape \(50000000, 2\) needing "
                                          r"800000000 bytes"):
        load_rig(bomb)


def test_a_member_shorter_than_its_header_says_is_refused(tmp_path):
    import io
    import zipfile

    good = tmp_path / "good.npz"
    save_rig(good, small_rig())
    src = np.load(good)
    bad = tmp_path / "short.npz"
    with zipfile.ZipFile(bad, "w") as out:
        for k in src.files:
            data = io.BytesIO()
            np.lib.format.write_array(data, src[k], allow_pickle=False)
            raw = data.getvalue()
            out.writestr(f"{k}.npy", raw[:-8] if k == "V" else raw)
    with pytest.raises(FormatError, match=r"member 'V' of \d+ bytes .* found \d+ bytes in "
                                          r"the archive"):
        load_rig(bad)
