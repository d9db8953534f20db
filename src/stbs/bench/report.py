"""What both benchmarks share: the machine they ran on, option parsing, JSON output.

Public so that the peer scripts in ``benchmarks/`` report the same way.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np

from ..io import atomic_open

__all__ = ["quiet", "cpu_model", "platform_name", "load_average", "peak_rss_bytes",
           "machine_lines", "positive_int", "int_at_least", "positive_float",
           "check_json_path", "jsonable", "write_json"]

Log = Callable[[str], None]


def quiet(msg: str) -> None:
    """A log that says nothing."""


# --------------------------------------------------------------------------- machine
def cpu_model() -> str:
    """The CPU's model name (``/proc/cpuinfo``), else the machine type."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    # not platform.processor(): on Linux it runs ``uname -p`` in a subprocess
    return platform.machine()


def platform_name() -> str:
    """Operating system, release and machine type, e.g. ``Linux-6.1.0-x86_64``.

    Not :func:`platform.platform`: it asks for the processor, which on Linux runs
    ``uname -p`` in a subprocess, and a benchmark starts no process unless asked.
    """
    u = platform.uname()
    return "-".join(x for x in (u.system, u.release, u.machine) if x)


def load_average() -> list[float] | None:
    """1, 5 and 15 minute load averages: other work on the CPUs inflates every figure."""
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except (AttributeError, OSError):
        return None


def peak_rss_bytes() -> int | None:
    """Peak resident memory of this process in bytes (None where unknown)."""
    try:
        import resource
    except ImportError:  # not on Windows
        return None
    r = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return int(r) if sys.platform == "darwin" else int(r) * 1024


def machine_lines(machine: dict, versions: str, what: str) -> list[str]:
    """The report's first lines: CPU and ``versions``, then the load at the start
    (with a note that ``what`` may be inflated when other work was running)."""
    lines = [f"machine: {machine.get('cpu')}, {machine.get('cpus')} CPUs; {versions}"]
    load = machine.get("load_average")
    if load:
        busy = f" (other work was running: {what} may be inflated)" if load[0] > 0.5 else ""
        lines.append(f"load average at start: {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}{busy}")
    return lines


# --------------------------------------------------------------------------- options
def int_at_least(low: int) -> Callable[[str], int]:
    """An argparse type: a whole number >= ``low``."""
    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            v = None
        if v is None or v < low:
            raise argparse.ArgumentTypeError(f"expected a whole number >= {low}, got {text!r}")
        return v
    return parse


positive_int = int_at_least(1)


def positive_float(text: str) -> float:
    """An argparse type: a finite number > 0."""
    try:
        v = float(text)
    except ValueError:
        v = float("nan")
    if not (np.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"expected a number > 0, got {text!r}")
    return v


# --------------------------------------------------------------------------- JSON
def check_json_path(path: str | os.PathLike | None) -> Path | None:
    """``--json``'s path, checked before anything is timed.

    Raises
    ------
    ValueError
        The path is a folder, or its folder is missing or not writable.
    """
    if path is None:
        return None
    out = Path(path)
    if out.is_dir():
        raise ValueError(f"--json: {out} is a folder, expected a file path")
    parent = out.parent if str(out.parent) else Path(".")
    if not parent.is_dir():
        raise ValueError(f"--json: folder {parent} does not exist")
    if not os.access(parent, os.W_OK):
        raise ValueError(f"--json: folder {parent} is not writable")
    return out


def jsonable(x):
    """``x`` with NumPy scalars made Python numbers and non-finite floats None."""
    if isinstance(x, dict):
        return {k: jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, (np.floating, float)):
        return float(x) if np.isfinite(x) else None
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


def write_json(path: str | os.PathLike, doc: dict) -> None:
    """Write ``doc`` as JSON to a temporary file in ``path``'s folder, then rename it."""
    with atomic_open(Path(path), "w") as f:
        f.write(json.dumps(jsonable(doc), indent=1, allow_nan=False))
