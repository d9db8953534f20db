"""Work counted, not timed: the lines of the package's own code that a call executes.

A test that guards against quadratic or unbounded work counts it here rather than
timing it, so that a loaded machine cannot fail it and a fast one cannot hide a
regression. Lines are counted in functions of ``src/stbs`` only (module bodies run at
import are left out, so the first call counts the same as the next), in this thread
and in threads started while counting (a server's request handlers); NumPy's and the
standard library's own work is not counted: bound those by memory (tracemalloc) or by
the calls they get. With a ``budget``, the call is stopped as soon as it passes it
(``TooMuchWork``, which ``except Exception`` does not catch), so a broken version fails
at once instead of running for minutes.
"""

from __future__ import annotations

import sys
import threading
from pathlib import Path

import stbs

SRC = str(Path(stbs.__file__).resolve().parent)


class TooMuchWork(BaseException):
    """The counted call passed its budget of lines."""


class Lines:
    """``with Lines(budget) as w: call()``, then ``w.count``: the package lines it ran."""

    def __init__(self, budget: int | None = None):
        self.budget = budget
        self.count = 0
        # the tracers are closures over plain locals: a bound method and attributes for
        # every line would make counting several times slower
        limit = budget if budget is not None else sys.maxsize
        n = [0]

        def line(frame, event, arg):
            if event == "line":
                n[0] += 1
                if n[0] > limit:
                    raise TooMuchWork(f"more than {budget} lines of stbs code ran")
            return line

        def call(frame, event, arg):
            code = frame.f_code
            if code.co_name == "<module>" or not code.co_filename.startswith(SRC):
                return None
            return line

        self._call, self._n = call, n

    def __enter__(self) -> Lines:
        self._before = sys.gettrace()
        threading.settrace(self._call)
        sys.settrace(self._call)
        return self

    def __exit__(self, *exc) -> None:
        sys.settrace(self._before)
        threading.settrace(None)
        self.count = self._n[0]

