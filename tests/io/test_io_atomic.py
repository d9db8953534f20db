"""Atomic writes: a failed write leaves neither a partial file nor a temporary one."""

import os

import numpy as np
import pytest

from stbs.io import atomic_open, atomic_save, atomic_write


def listing(folder):
    return sorted(p.name for p in folder.iterdir())


def test_atomic_open_writes_and_replaces(tmp_path):
    p = tmp_path / "a.txt"
    with atomic_open(p, "w") as f:
        f.write("one\n")
    assert p.read_text() == "one\n"
    with atomic_open(p, "wb") as f:
        f.write(b"two\n")
    assert p.read_bytes() == b"two\n"
    assert listing(tmp_path) == ["a.txt"]


def test_atomic_open_failure_keeps_old_file_and_cleans_up(tmp_path):
    p = tmp_path / "a.txt"
    p.write_text("original")
    with pytest.raises(RuntimeError, match="boom"), atomic_open(p, "w") as f:
        f.write("half")
        raise RuntimeError("boom")
    assert p.read_text() == "original"
    assert listing(tmp_path) == ["a.txt"]


def test_atomic_open_failure_creates_nothing(tmp_path):
    with pytest.raises(KeyboardInterrupt), atomic_open(tmp_path / "new.bin") as f:
        f.write(b"x")
        raise KeyboardInterrupt
    assert listing(tmp_path) == []


def test_new_file_gets_umask_permissions(tmp_path):
    p = tmp_path / "perm.txt"
    with atomic_open(p, "w") as f:
        f.write("x")
    umask = os.umask(0)
    os.umask(umask)
    assert p.stat().st_mode & 0o777 == 0o666 & ~umask


def test_existing_file_keeps_its_mode(tmp_path):
    p = tmp_path / "perm.txt"
    p.write_text("x")
    os.chmod(p, 0o640)
    with atomic_open(p, "w") as f:
        f.write("y")
    assert p.stat().st_mode & 0o777 == 0o640


def test_bad_mode_missing_folder_and_folder_target(tmp_path):
    with pytest.raises(ValueError, match="mode must be one of"):
        with atomic_open(tmp_path / "a", "a"):
            pass
    with pytest.raises(FileNotFoundError, match="does not exist"):
        with atomic_open(tmp_path / "nope" / "a.txt"):
            pass
    with pytest.raises(IsADirectoryError):
        with atomic_open(tmp_path):
            pass


def test_atomic_save_keeps_suffix_for_np_savez(tmp_path):
    seen = []

    def save(name):
        seen.append(name)
        np.savez(name, x=np.arange(3))

    p = tmp_path / "rig.npz"
    atomic_save(p, save)
    assert seen[0].endswith(".npz") and os.path.dirname(seen[0]) == str(tmp_path)
    assert listing(tmp_path) == ["rig.npz"]  # no "rig.npz.npz", no temporary file
    with np.load(p) as z:
        np.testing.assert_array_equal(z["x"], [0, 1, 2])


def test_atomic_save_failure_keeps_old_file(tmp_path):
    p = tmp_path / "out.obj"
    p.write_text("old")

    def bad(name):
        with open(name, "w") as f:
            f.write("partial")
        raise OSError("disk full")

    with pytest.raises(OSError, match="disk full"):
        atomic_save(p, bad)
    assert p.read_text() == "old"
    assert listing(tmp_path) == ["out.obj"]


def test_atomic_write(tmp_path):
    p = tmp_path / "w.bin"
    atomic_write(p, lambda f: f.write(b"abc"))
    assert p.read_bytes() == b"abc"
    atomic_write(p, lambda f: f.write("é"), "w")
    assert p.read_text(encoding="utf-8") == "é"
