"""``stbs.io.read_sequence``: mesh animations as one .npz or as mesh files, and the
one-line errors for what does not fit."""

from __future__ import annotations

import numpy as np
import pytest

from stbs.io import FormatError, read_sequence, write_mesh

TRI = np.array([[0, 1, 2], [0, 2, 3]])


def _frames(f=3, n=4, d=3, seed=0):
    return np.random.default_rng(seed).standard_normal((f, n, d))


def test_npz_with_rest_and_faces(tmp_path):
    fr, rest = _frames(), _frames(1)[0] + 5
    p = tmp_path / "a.npz"
    np.savez(p, frames=fr.astype(np.float32), rest=rest, F=TRI.astype(np.int32))
    seq = read_sequence(p)
    assert seq.frames.dtype == np.float64 and seq.frames.shape == (3, 4, 3)
    np.testing.assert_array_equal(seq.frames, fr.astype(np.float32))
    np.testing.assert_array_equal(seq.rest, rest)
    assert seq.F.tolist() == TRI.tolist()


def test_npz_without_rest_takes_the_first_frame(tmp_path):
    fr = _frames(d=2)
    np.savez(tmp_path / "a.npz", frames=fr)
    seq = read_sequence(tmp_path / "a.npz")
    np.testing.assert_array_equal(seq.rest, fr[0])
    assert seq.F is None


def test_mesh_files_rest_then_frames(tmp_path):
    fr = _frames()
    paths = []
    for k, V in enumerate(fr):
        paths.append(tmp_path / f"m{k}.obj")
        write_mesh(paths[-1], V, TRI)
    seq = read_sequence(paths)
    np.testing.assert_allclose(seq.rest, fr[0])
    np.testing.assert_allclose(seq.frames, fr[1:])
    assert seq.F.tolist() == TRI.tolist()


@pytest.mark.parametrize("members, found", [
    ({"verts": np.zeros((2, 4, 3))}, "members ['verts']"),
    ({"frames": np.zeros((4, 3))}, "shape (4, 3)"),
    ({"frames": np.full((2, 4, 3), np.nan)}, "nan at index (0, 0, 0)"),
    ({"frames": np.zeros((2, 4, 3)), "rest": np.zeros((5, 3))}, "shape (5, 3)"),
    ({"frames": np.zeros((2, 4, 3)), "F": np.array([[0, 1, 9]])}, "shape (1, 3)"),
    ({"frames": np.array(["a"])}, "dtype <U1"),
])
def test_bad_npz_names_the_file_and_what_was_found(tmp_path, members, found):
    p = tmp_path / "bad.npz"
    np.savez(p, **members)
    with pytest.raises(FormatError) as exc:
        read_sequence(p)
    assert str(p) in str(exc.value) and found in str(exc.value)


def test_mesh_files_of_other_topologies_are_refused(tmp_path):
    write_mesh(tmp_path / "a.obj", _frames(1)[0], TRI)
    write_mesh(tmp_path / "b.obj", _frames(1, n=5)[0], TRI)
    with pytest.raises(FormatError, match="4 vertices in 3D.*found 5 vertices"):
        read_sequence([tmp_path / "a.obj", tmp_path / "b.obj"])
    write_mesh(tmp_path / "c.obj", _frames(1)[0], TRI[::-1])
    with pytest.raises(FormatError, match="one topology"):
        read_sequence([tmp_path / "a.obj", tmp_path / "c.obj"])


def test_one_mesh_file_or_nothing_is_refused(tmp_path):
    write_mesh(tmp_path / "a.obj", _frames(1)[0], TRI)
    with pytest.raises(ValueError, match="two or more mesh files"):
        read_sequence(tmp_path / "a.obj")
    with pytest.raises(ValueError, match="got none"):
        read_sequence([])
    with pytest.raises(FileNotFoundError):
        read_sequence(tmp_path / "missing.npz")
