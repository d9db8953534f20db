"""Progress callbacks that threads share and that cancel the work when they raise.

The long computations take ``progress(done, total)``. Raising any exception from it
cancels: the computation stops at its next report and the exception propagates. With
worker threads that needs care: the callback must not run on two threads at once, a
worker that reports after the callback raised must stop without calling it again,
and the caller must get the callback's own exception, not a worker's. :class:`Guard`
does all three.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterable
from concurrent.futures import Future, as_completed

from .. import _checks

__all__ = ["Guard", "Cancelled", "check_callable"]


class Cancelled(Exception):
    """Raised in a worker that reports after the progress callback raised."""


def check_callable(progress, form: str = "progress(done, total)") -> None:
    """A ``TypeError`` unless ``progress`` is None or callable (:func:`stbs._checks.progress`)."""
    _checks.progress(progress, form)


class Guard:
    """``progress(done, total)`` made safe for threads and for cancelling.

    Calls are serialised; once the callback raised, every later report (and
    :meth:`check`) raises :class:`Cancelled` without calling it again. ``error`` is the
    callback's exception; :meth:`join` waits for futures and re-raises it.
    """

    def __init__(self, progress: Callable[[int, int], None] | None):
        check_callable(progress)
        self.progress = progress
        self.error: BaseException | None = None
        self._lock = threading.Lock()

    def __call__(self, done: int, total: int) -> None:
        with self._lock:
            if self.error is not None:
                raise Cancelled("the progress callback raised")
            if self.progress is None:
                return
            try:
                self.progress(done, total)
            except BaseException as exc:
                self.error = exc
                raise

    def check(self, done: int = 0, total: int = 0) -> None:
        """Raise :class:`Cancelled` once the callback has raised; never calls it."""
        if self.error is not None:
            raise Cancelled("the progress callback raised")

    def join(self, futures: Iterable[Future], on_result=None) -> list:
        """Results of ``futures`` in their order (``on_result(result)`` for each as it
        completes). On a failure the futures not started are cancelled, those running
        stop at their next report, and the callback's exception (else the failure)
        is raised."""
        futures = list(futures)
        slot = {f: i for i, f in enumerate(futures)}
        out: list = [None] * len(futures)
        try:
            for f in as_completed(futures):
                out[slot[f]] = f.result()
                if on_result is not None:
                    on_result(out[slot[f]])
        except BaseException as exc:
            for f in futures:
                f.cancel()
            if self.error is None:
                self.error = exc          # workers still running stop at their next report
            for f in futures:
                if not f.cancelled():
                    f.exception()         # wait: nothing runs on after the caller returns
            if self.error is not exc and isinstance(exc, Cancelled):
                raise self.error from None
            raise
        return out
