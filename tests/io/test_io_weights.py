"""read_weights: .dmat, .npy, .npz (dense, key W, scipy sparse), .csv."""

import numpy as np
import pytest
import scipy.sparse as sp

from stbs.io import FormatError, read_dmat, read_weights, write_dmat

W0 = np.array([[1.0, 0.0], [0.25, 0.75], [0.5, 0.5]])


def test_dmat(tmp_path):
    p = tmp_path / "w.dmat"
    write_dmat(p, W0)
    np.testing.assert_array_equal(read_weights(p), W0)


def test_npy_and_vector(tmp_path):
    p = tmp_path / "w.npy"
    np.save(p, W0.astype(np.float32))
    W = read_weights(p)
    assert W.dtype == np.float64
    np.testing.assert_array_equal(W, W0)
    np.save(p, np.array([1, 2, 3]))
    np.testing.assert_array_equal(read_weights(p), [[1], [2], [3]])


def test_npz_single_array_or_key_w(tmp_path):
    p = tmp_path / "a.npz"
    np.savez(p, anything=W0)
    np.testing.assert_array_equal(read_weights(p), W0)
    q = tmp_path / "b.npz"
    np.savez(q, W=W0, E=np.zeros_like(W0))
    np.testing.assert_array_equal(read_weights(q), W0)


def test_npz_scipy_sparse(tmp_path):
    p = tmp_path / "s.npz"
    sp.save_npz(p, sp.csr_matrix(W0))
    W = read_weights(p)
    assert sp.issparse(W) and isinstance(W, sp.csr_array)
    np.testing.assert_array_equal(W.toarray(), W0)


def test_csv(tmp_path):
    p = tmp_path / "w.csv"
    p.write_text("# weights\n1,0\n0.25, 0.75\n0.5,0.5\n")
    np.testing.assert_array_equal(read_weights(p), W0)


def test_real_arm_weights(shared_data):
    p = shared_data / "libigl-tutorial-data/arm-weights.dmat"
    np.testing.assert_array_equal(read_weights(p), read_dmat(p))


@pytest.mark.parametrize("setup, match", [
    (lambda p: np.savez(p, A=W0, B=W0), r"expected an .npz with a single array or the key "
     r"'W', found keys \['A', 'B'\]"),
    (lambda p: np.savez(p, W=np.array([{"a": 1}], dtype=object)),
     r"object arrays are never unpickled\), found dtype object"),
    (lambda p: np.savez(p, W=np.array([[1.0, np.nan]])), r"expected finite weights in key "
     r"'W', found nan at \(row, col\) = \(0, 1\)"),
    (lambda p: np.savez(p, W=np.zeros((2, 2, 2))), r"expected a 1-D or 2-D array"),
    (lambda p: np.savez(p, W=np.array(["a", "b"])), r"expected a numeric array"),
    (lambda p: p.write_bytes(b"PK\x03\x04 broken"), r"expected a NumPy .npz file"),
    (lambda p: np.savez(p), r"found no arrays"),
])
def test_broken_npz(tmp_path, setup, match):
    p = tmp_path / "bad.npz"
    setup(p)
    with pytest.raises(FormatError, match=match):
        read_weights(p)


def test_object_npy_is_never_unpickled(tmp_path):
    p = tmp_path / "o.npy"
    np.save(p, np.array([None, 1], dtype=object), allow_pickle=True)
    with pytest.raises(FormatError, match=r"never unpickled\), found dtype object"):
        read_weights(p)


def test_broken_csv_and_empty(tmp_path):
    p = tmp_path / "w.csv"
    p.write_text("1,0\n0.5\n")
    with pytest.raises(FormatError, match=r"w.csv, line 2: expected exactly 2 numbers"):
        read_weights(p)
    p.write_text("")
    with pytest.raises(FormatError, match="found an empty file"):
        read_weights(p)


def test_unknown_extension_and_missing(tmp_path):
    p = tmp_path / "w.txt"
    p.write_text("1 2\n")
    with pytest.raises(ValueError, match=r"supported extensions are \.dmat, \.npy, \.npz, \.csv"):
        read_weights(p)
    with pytest.raises(FileNotFoundError, match="gone.npy"):
        read_weights(tmp_path / "gone.npy")


def test_an_npy_header_larger_than_the_file_is_refused_unread(tmp_path):
    """A 200-byte .npy whose header declares 16 GB of weights: refused from the header,
    before NumPy allocates the array."""
    import io

    head = io.BytesIO()
    np.lib.format.write_array_header_1_0(
        head, {"descr": "<f8", "fortran_order": False, "shape": (10**9, 2)})
    p = tmp_path / "W.npy"
    p.write_bytes(head.getvalue() + bytes(64))
    with pytest.raises(FormatError, match=r"an \.npy file of 16000000128 bytes .* found "
                                          r"192 bytes"):
        read_weights(p)
