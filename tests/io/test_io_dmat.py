"""read_dmat / write_dmat: header 'cols rows', column-major values, ASCII and binary."""

import struct

import numpy as np
import pytest
import scipy.sparse as sp

from stbs.io import FormatError, read_dmat, write_dmat

# ---------------------------------------------------------------- hand-made files


def test_ascii_is_cols_rows_then_column_major(tmp_path):
    p = tmp_path / "a.dmat"
    p.write_text("3 2\n1\n2\n3\n4\n5\n6\n")  # 3 columns, 2 rows
    X = read_dmat(p)
    np.testing.assert_array_equal(X, [[1, 3, 5], [2, 4, 6]])
    assert X.dtype == np.float64 and X.flags.c_contiguous


def test_ascii_values_may_share_lines(tmp_path):
    p = tmp_path / "a.dmat"
    p.write_text("2 2\r\n1 2\r\n  3\t4\r\n\r\n")
    np.testing.assert_array_equal(read_dmat(p), [[1, 3], [2, 4]])


def test_binary_hand_made(tmp_path):
    p = tmp_path / "b.dmat"
    p.write_bytes(b"0 0\n3 2\n" + struct.pack("<6d", 1, 2, 3, 4, 5, 6))
    np.testing.assert_array_equal(read_dmat(p), [[1, 3, 5], [2, 4, 6]])


def test_empty_matrix(tmp_path):
    p = tmp_path / "e.dmat"
    p.write_text("0 0\n")
    assert read_dmat(p).shape == (0, 0)
    q = tmp_path / "c.dmat"
    q.write_text("2 0\n")
    assert read_dmat(q).shape == (0, 2)


@pytest.mark.parametrize("binary", [False, True])
def test_round_trip_exact(tmp_path, binary):
    rng = np.random.default_rng(5)
    X = rng.normal(size=(7, 3)) * 10.0 ** rng.integers(-12, 12, size=(7, 3))
    p = tmp_path / "r.dmat"
    write_dmat(p, X, binary=binary)
    np.testing.assert_array_equal(read_dmat(p), X)
    head = p.read_bytes()[:8]
    assert head.startswith(b"0 0\n3 7\n" if binary else b"3 7\n")


def test_write_accepts_vector_and_sparse(tmp_path):
    p = tmp_path / "v.dmat"
    write_dmat(p, [1.0, 2.0])
    assert p.read_text() == "1 2\n1.0\n2.0\n"
    write_dmat(p, sp.csr_array(np.eye(2)), binary=True)
    np.testing.assert_array_equal(read_dmat(p), np.eye(2))


def test_write_rejects_bad_input(tmp_path):
    with pytest.raises(ValueError, match="X must be finite"):
        write_dmat(tmp_path / "x.dmat", [[np.inf]])
    with pytest.raises(ValueError, match=r"X must be a 1-D or 2-D array, got shape \(1, 1, 1\)"):
        write_dmat(tmp_path / "x.dmat", np.zeros((1, 1, 1)))
    with pytest.raises(ValueError, match=r"supported extensions are \.dmat"):
        write_dmat(tmp_path / "x.txt", [[1.0]])
    assert list(tmp_path.iterdir()) == []


# ---------------------------------------------------------------- real shared files


def test_real_arm_weights_ascii(shared_data):
    p = shared_data / "libigl-tutorial-data/arm-weights.dmat"
    W = read_dmat(p)
    assert W.shape == (8311, 4)  # rows == arm.obj vertices, cols == arm.tgf bones
    lines = p.read_text().split("\n", 3)
    assert lines[0] == "4 8311"
    assert W[0, 0] == float(lines[1]) and W[1, 0] == float(lines[2])  # column-major
    np.testing.assert_allclose(W.sum(1), 1, atol=1e-12)


def test_real_elephant_weights_binary(shared_data):
    p = shared_data / "libigl-tutorial-data/elephant-weights.dmat"
    W = read_dmat(p)
    assert W.shape == (6034, 24)
    raw = p.read_bytes()
    assert raw.startswith(b"0 0\n24 6034\n")
    first, second = struct.unpack_from("<2d", raw, 12)
    assert W[0, 0] == first and W[1, 0] == second
    last = struct.unpack_from("<d", raw, len(raw) - 8)[0]
    assert W[-1, -1] == last
    np.testing.assert_allclose(W.sum(1), 1, atol=1e-12)


# ---------------------------------------------------------------- broken files


def test_truncated_ascii(tmp_path):
    p = tmp_path / "t.dmat"
    p.write_text("2 3\n1\n2\n3\n4\n5\n")
    with pytest.raises(FormatError, match=r"t.dmat: expected 6 values after the header '2 3' "
                       r"\(cols rows\), found 5 values \(truncated\?\)"):
        read_dmat(p)


def test_too_many_values(tmp_path):
    p = tmp_path / "m.dmat"
    p.write_text("1 2\n1\n2\n3\n")
    with pytest.raises(FormatError, match="expected 2 values .* found 3 values"):
        read_dmat(p)


def test_non_number_names_line(tmp_path):
    p = tmp_path / "n.dmat"
    p.write_text("1 3\n1\nabc\n3\n")
    with pytest.raises(FormatError, match=r"n.dmat, line 3: expected a number, found 'abc'"):
        read_dmat(p)
    p.write_text("3 1\n1 2 3,\n")  # a bad token that is not first on its line
    with pytest.raises(FormatError, match=r"line 2: expected a number, found '3,'"):
        read_dmat(p)
    p.write_text("1 2\n1\nnan\n")
    with pytest.raises(FormatError, match=r"line 3: expected a finite number"):
        read_dmat(p)


@pytest.mark.parametrize("data, match", [
    (b"", "found an empty file"),
    (b"3\n1 2 3\n", r"line 1: expected a header 'cols rows' of two non-negative integers, "
     r"found '3'"),
    (b"a b\n", r"line 1: expected a header"),
    (b"-1 2\n1\n", r"line 1: expected a header"),
    (b"0 0\n2 2\n" + struct.pack("<3d", 1, 2, 3), r"expected 32 bytes of float64 for 2 rows x "
     r"2 cols after the binary header, found 24 bytes \(truncated\)"),
    (b"0 0\n1 1\n" + struct.pack("<2d", 1, 2), r"expected 8 bytes .* found 16 bytes"),
    (b"0 0\n1 1\n" + struct.pack("<d", np.nan), r"expected finite values, found nan at row 0"),
    (b"0 0\nx", r"line 2: expected a second header line"),
])
def test_broken_headers_and_binary(tmp_path, data, match):
    p = tmp_path / "b.dmat"
    p.write_bytes(data)
    with pytest.raises(FormatError, match=match):
        read_dmat(p)


def test_missing_file(tmp_path):
    with pytest.raises(FileNotFoundError, match="w.dmat"):
        read_dmat(tmp_path / "w.dmat")
