"""The error the command line raises for a problem with a command's inputs."""

from __future__ import annotations

__all__ = ["CommandError"]


class CommandError(ValueError):
    """A problem with a command's inputs found by the command line itself.

    Reported, like every ``ValueError`` from the inputs, as one line
    ``stbs <cmd>: error: <message>`` with exit status 2.
    """
