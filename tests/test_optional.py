"""Optional dependencies: named with their extra, checked before a command does any work."""

import importlib.util

import pytest

from stbs import _optional
from stbs.cli import main


def test_message_names_the_extra():
    assert _optional.message("matplotlib", "the demo") == (
        "the demo needs matplotlib, which is not installed: pip install 'stbs-skinning[demo]'")
    assert "pip install 'stbs-skinning[demo]'" in _optional.message("PIL.Image", "x")
    assert _optional.message("unheard_of", "x").endswith("pip install unheard_of")


def test_require_raises_an_import_error_with_the_advice():
    with pytest.raises(_optional.OptionalDependencyError, match=r"\[embree\]") as exc:
        _optional.require("embreex.definitely_not_a_module", "ray casting")
    assert isinstance(exc.value, ImportError)
    assert _optional.require("json", "x").__name__ == "json"


def _hide(monkeypatch, *names):
    real = importlib.util.find_spec

    def find_spec(name, *a, **kw):
        if name.split(".")[0] in names:
            return None
        return real(name, *a, **kw)

    monkeypatch.setattr(importlib.util, "find_spec", find_spec)


def test_rig_from_a_picture_without_pillow_is_one_line_before_any_work(monkeypatch, tmp_path,
                                                                       capsys):
    import stbs.io

    def no_work(*a, **kw):
        raise AssertionError("the skeleton was read before the missing package was reported")

    monkeypatch.setattr(stbs.io, "read_skeleton", no_work)
    _hide(monkeypatch, "PIL")
    (tmp_path / "a.png").write_bytes(b"not read")
    code = main(["rig", str(tmp_path / "a.png"), str(tmp_path / "a.tgf"), "-o",
                 str(tmp_path / "a.npz")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert err == ["stbs rig: error: this command needs pillow, which is not installed: "
                   "pip install 'stbs-skinning[demo]'"]
    assert not (tmp_path / "a.npz").exists()
