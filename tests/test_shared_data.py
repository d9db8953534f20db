"""data_dir(): $STBS_DATA first, then ../shared/data beside the checkout."""

from pathlib import Path

from shared_data import data_dir


def test_env_var_wins(monkeypatch, tmp_path):
    monkeypatch.setenv("STBS_DATA", str(tmp_path))
    assert data_dir() == tmp_path


def test_env_var_is_returned_even_if_missing(monkeypatch, tmp_path):
    # A wrong setting must be visible (the fixture then names it), not skipped over.
    monkeypatch.setenv("STBS_DATA", str(tmp_path / "missing"))
    assert data_dir() == tmp_path / "missing"


def test_repo_relative_default(monkeypatch):
    monkeypatch.delenv("STBS_DATA", raising=False)
    import shared_data as mod

    repo = Path(mod.__file__).resolve().parents[1]
    assert (repo / "tests" / "conftest.py").is_file()
    expected = repo.parent / "shared" / "data"
    assert data_dir() == (expected if expected.is_dir() else None)


def test_fixture_points_at_the_manifest(shared_data):
    assert (shared_data / "MANIFEST.md").is_file()
