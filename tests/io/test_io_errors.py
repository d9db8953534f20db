"""stbs.io.FormatError: message layout, attributes, pickling."""

import pickle

import pytest

from stbs.io import FormatError


def test_message_names_path_line_expected_found():
    e = FormatError("/x/arm.tgf", "a joint index in 1..5", "'7'", line=9)
    assert str(e) == "/x/arm.tgf, line 9: expected a joint index in 1..5, found '7'"
    assert (e.path, e.line, e.expected, e.found) == ("/x/arm.tgf", 9, "a joint index in 1..5",
                                                     "'7'")


def test_without_line():
    e = FormatError("w.dmat", "12 values", "11 values")
    assert str(e) == "w.dmat: expected 12 values, found 11 values"
    assert e.line is None


def test_is_a_value_error_and_pickles():
    e = FormatError("a.obj", "x", "y", line=3)
    assert isinstance(e, ValueError)
    with pytest.raises(ValueError, match="a.obj, line 3"):
        raise e
    e2 = pickle.loads(pickle.dumps(e))
    assert str(e2) == str(e) and e2.line == 3
