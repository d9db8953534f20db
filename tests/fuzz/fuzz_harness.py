"""Runs fuzz cases through the real command line and judges what happened.

:class:`FuzzEnv` owns a folder for a whole session::

    ROOT/canary-<hex>.bin      the canary: a unique random marker, repeated
    ROOT/seeds/                valid files to mutate (made with the library)
    ROOT/cases/<k>/            one case: its input files, and where it writes
    ROOT/io/                   the worker's capture files
    ROOT/tmp/                  the worker's TMPDIR

and a :class:`Worker` (``fuzz_worker.py``: stbs imported once, a forked child per case
under an address-space cap, a per-case timeout enforced here). :meth:`FuzzEnv.run`
writes a :class:`Case` into a fresh folder, runs its command there and returns what
went wrong, judged by the contract of ``stbs``:

- exit status 0 with outputs that read back and look right (finite, in range) and no
  numeric warning (overflow, invalid value) on stderr, or
  exit status 2 with exactly one line on stderr, ``stbs CMD: error: ...``, naming one
  of the case's input files; never a traceback, another status, a signal, a timeout;
- no file created, changed or removed outside the case folder (the rest of ROOT is
  compared before and after, the TMPDIR must stay empty, and every file the command
  opens for writing, renames or removes is recorded by an audit hook); the case's
  input files unchanged (hashed before and after);
- the canary never read (audit hook) where the case's inputs are files from
  elsewhere (a glTF's buffer URIs), nor ``/etc/passwd`` or ``/proc/*/environ``; its
  marker in no output file (raw, base64-encoded, or inside a ``.npz``), nor on stdout
  or stderr; the marker is also in the worker's environment, so a leak of
  ``/proc/self/environ`` shows too.
"""

from __future__ import annotations

import base64
import hashlib
import json
import os
import re
import secrets
import select
import shutil
import signal
import subprocess
import sys
import time
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

HERE = Path(__file__).resolve().parent
#: Seconds a case may take before its worker is killed (and the case fails).
TIMEOUT = float(os.environ.get("STBS_FUZZ_TIMEOUT", "20"))
#: Bytes of address space a case may take beyond what the worker holds.
MEMORY = int(float(os.environ.get("STBS_FUZZ_MEMORY_GB", "2")) * 2**30)
_WRITE = os.O_WRONLY | os.O_RDWR | os.O_CREAT | os.O_TRUNC | os.O_APPEND
_ENVIRON = re.compile(r"^/proc/(self|thread-self|\d+)(/task/\d+)?/environ$")
#: Bytes that /etc/passwd holds on any Linux and no stbs output would.
_PASSWD = b"root:x:0:0:"


@dataclass
class Case:
    """One run of one command on files written for it.

    Attributes
    ----------
    argv : list of str
        The command line after ``stbs``; file names are relative to the case folder,
        ``{seeds}`` names the seed folder.
    files : dict of str to bytes
        The case's input files, written into its folder.
    links : dict of str to str
        Symbolic links made in its folder (name -> target).
    check : str
        How the worker checks a successful run's output (see ``fuzz_worker``).
    confined : bool
        True when the inputs come from elsewhere and may name no file outside their
        folder (a glTF's buffers): reading the canary is then a failure.
    outputs_named : bool
        True when the inputs name the outputs (a manifest's jobs): an error may then
        name an output path in the case folder rather than an input file.
    label : str
        What the case is, for reports.
    """

    argv: list[str]
    files: dict[str, bytes]
    links: dict[str, str] = field(default_factory=dict)
    check: str = ""
    confined: bool = True
    outputs_named: bool = False
    label: str = ""


@dataclass
class Outcome:
    status: int | None
    signal: int | None
    stdout: str
    stderr: str
    seconds: float
    timed_out: bool = False
    opened: list = field(default_factory=list)
    check: str | None = None
    problems: list[str] = field(default_factory=list)
    folder: Path | None = None


class Worker:
    """The worker process (``fuzz_worker.py``), restarted after a timeout or a crash."""

    def __init__(self, root: Path, env: dict[str, str], warmups: list[tuple[list[str], str]]):
        self.root = root
        self.env = env
        self.warmups = warmups
        self.proc: subprocess.Popen | None = None
        self.starts = 0
        self.warm_failures: list[str] = []

    def start(self) -> None:
        log = open(self.root / "io" / "worker.log", "ab")  # noqa: SIM115 (kept by Popen)
        self.proc = subprocess.Popen(
            [sys.executable, str(HERE / "fuzz_worker.py")], stdin=subprocess.PIPE,
            stdout=subprocess.PIPE, stderr=log, env=self.env, cwd=self.root,
            start_new_session=True)
        log.close()
        self.starts += 1
        for argv, cwd in self.warmups:
            ans = self.request({"op": "warm", "argv": argv, "cwd": cwd}, 600)
            if ans is None or ans.get("rc") != 0:
                self.warm_failures.append(f"{argv}: {ans}")

    def request(self, req: dict, timeout: float) -> dict | None:
        """The worker's answer, or None when none came within ``timeout`` seconds (the
        worker is then killed) or the worker died."""
        if self.proc is None or self.proc.poll() is not None:
            self.start()
        assert self.proc is not None and self.proc.stdin and self.proc.stdout
        self.proc.stdin.write((json.dumps(req) + "\n").encode())
        self.proc.stdin.flush()
        ready, _, _ = select.select([self.proc.stdout], [], [], timeout)
        line = self.proc.stdout.readline() if ready else b""
        if not line:
            self.kill()
            return None
        return json.loads(line)

    def kill(self) -> None:
        if self.proc is None:
            return
        try:
            os.killpg(self.proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        self.proc.wait()
        for f in (self.proc.stdin, self.proc.stdout):
            if f:
                f.close()
        self.proc = None


def _tree(folder: Path, skip: tuple[str, ...] = ()) -> dict[str, tuple]:
    """Every entry under ``folder`` but the top-level ones in ``skip``: relative path ->
    (kind, size, mtime_ns)."""
    out = {}
    for dirpath, dirs, files in os.walk(folder):
        if dirpath == str(folder):
            dirs[:] = [d for d in dirs if d not in skip]
            files = [f for f in files if f not in skip]
        for name in dirs + files:
            p = os.path.join(dirpath, name)
            st = os.lstat(p)
            out[os.path.relpath(p, folder)] = (st.st_mode >> 12, st.st_size, st.st_mtime_ns)
    return out


def _digest(p: Path) -> str:
    return hashlib.sha256(p.read_bytes()).hexdigest()


def _error_line_problems(case: Case, argv: list[str], folder: Path, cmd: str,
                         lines: list[str]) -> list[str]:
    """An exit 2 must leave exactly one line ``stbs CMD: error: ...`` on stderr, naming
    one of the case's input files."""
    if len(lines) != 1 or not lines[0].startswith(f"stbs {cmd}: error: "):
        return [f"exit 2 without exactly one line 'stbs {cmd}: error: ...' on "
                f"stderr: {' | '.join(lines)[-600:]!r}"]
    names = set(case.files) | {os.path.basename(a) for a in argv[1:] if not a.startswith("-")}
    if case.outputs_named:
        names.add(str(folder))
    if not any(n and n in lines[0] for n in names):
        return [f"an error naming none of the input files: {lines[0][:400]!r}"]
    return []


class FuzzEnv:
    """The session's folder, canary, seeds and worker (see the module docs)."""

    def __init__(self, root: Path, seeds: dict[str, bytes],
                 warmups: list[tuple[list[str], dict[str, bytes]]]):
        self.root = root.resolve()
        self.marker = "CANARY" + secrets.token_hex(9).upper()     # 24 ASCII bytes
        self.canary = self.root / f"canary-{self.marker[6:14]}.bin"
        self.canary.write_bytes(self.marker.encode() * 2731)
        self._needles = self._encodings(self.marker.encode())
        for sub in ("seeds", "cases", "io", "tmp"):
            (self.root / sub).mkdir(exist_ok=True)
        self.seeds = self.root / "seeds"
        for name, data in seeds.items():
            (self.seeds / name).write_bytes(data)
            os.chmod(self.seeds / name, 0o444)
        self.seed_hashes = {n: _digest(self.seeds / n) for n in seeds}
        self.count = 0
        env = dict(os.environ, TMPDIR=str(self.root / "tmp"), STBS_FUZZ_SECRET=self.marker,
                   OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1",
                   NUMBA_NUM_THREADS="1", NUMBA_THREADING_LAYER="workqueue",
                   PYTHONDONTWRITEBYTECODE="1", PYTHONHASHSEED="0")
        env.pop("STBS_DATA", None)
        warm = []
        for k, (argv, files) in enumerate(warmups):
            d = self.root / "io" / f"warm{k}"
            d.mkdir()
            for name, data in files.items():
                (d / name).write_bytes(data.replace(b"{seeds}", str(self.seeds).encode()))
            warm.append(([a.replace("{seeds}", str(self.seeds)) for a in argv], str(d)))
        self.worker = Worker(self.root, env, warm)
        self.worker.start()
        self.allowed_writes = [str(self.root / "io") + os.sep, str(self.root / "tmp") + os.sep,
                               "/dev/"]
        cache = os.environ.get("NUMBA_CACHE_DIR")
        if cache:
            self.allowed_writes.append(os.path.realpath(cache) + os.sep)

    @staticmethod
    def _encodings(marker: bytes) -> list[bytes]:
        """The marker as it shows in a stream copied raw or base64-encoded (at any of
        its alignments against base64's 3-byte groups)."""
        out = [marker]
        run = marker * 4
        for r in range(len(marker)):
            out.append(base64.b64encode(run[r:r + 2 * len(marker)])[:32])
        return out

    def close(self) -> None:
        self.worker.kill()

    # ------------------------------------------------------------------ one case
    def run(self, case: Case, *, exec_code: str | None = None,
            timeout: float | None = None) -> Outcome:
        """Run ``case`` (``exec_code``: Python code run in place of ``stbs``, for the
        harness's own tests; ``timeout``: seconds, default :data:`TIMEOUT`) and judge
        it."""
        timeout = TIMEOUT if timeout is None else timeout
        self.count += 1
        folder = self.root / "cases" / str(self.count)
        folder.mkdir()
        for name, data in case.files.items():
            (folder / name).write_bytes(data)
        for name, target in case.links.items():
            os.symlink(target, folder / name)
        argv = [a.replace("{seeds}", str(self.seeds)) for a in case.argv]
        inputs = {n: _digest(folder / n) for n in case.files}
        outside = self._outside()
        t = time.perf_counter()
        ans = self.worker.request({"op": "case", "argv": argv, "cwd": str(folder),
                                   "io": str(self.root / "io"), "memory": MEMORY,
                                   "check": case.check, "exec": exec_code}, timeout)
        dt = time.perf_counter() - t
        if ans is None:
            out = Outcome(None, None, "", "", dt, timed_out=True)
        else:
            out = Outcome(ans["status"], ans["signal"], ans["stdout"], ans["stderr"], dt,
                          opened=ans.get("opened", []), check=ans.get("check"))
            if ans.get("no_result"):
                out.problems.append("the case's process died before reporting")
        out.folder = folder
        out.problems += self._judge(case, argv, folder, out, inputs, outside, timeout)
        if not out.problems:
            shutil.rmtree(folder)
        else:
            self._keep(folder, case, out)
        return out

    def _outside(self) -> dict:
        # the case's own folder, the worker's capture files, TMPDIR (checked empty
        # apart) and the failures kept are not "outside"
        snap = _tree(self.root, skip=("cases", "io", "tmp", "failures"))
        snap["#canary"] = _digest(self.canary)
        snap["#seeds"] = tuple(sorted(self.seed_hashes.items()))
        return snap

    def _keep(self, folder: Path, case: Case, out: Outcome) -> None:
        """Keep a failing case's folder as it was left, with what happened."""
        keep = self.root / "failures" / folder.name
        keep.parent.mkdir(exist_ok=True)
        shutil.move(str(folder), keep)
        (keep.parent / f"{folder.name}.json").write_text(json.dumps(
            {"label": case.label, "argv": case.argv, "status": out.status,
             "signal": out.signal, "problems": out.problems, "stderr": out.stderr[-4000:]},
            indent=1))

    def _judge(self, case: Case, argv: list[str], folder: Path, out: Outcome,
               inputs: dict[str, str], outside: dict, timeout: float) -> list[str]:
        """What went wrong in a case's run (see the module docs); empty when nothing."""
        return (self._exit_problems(case, argv, folder, out, timeout)
                + self._leak_problems(case, folder, out, inputs)
                + self._file_problems(case, folder, out, inputs, outside))

    @staticmethod
    def _exit_problems(case: Case, argv: list[str], folder: Path, out: Outcome,
                       timeout: float) -> list[str]:
        """How the command ended: exit 0 with good outputs, or exit 2 with one error line
        naming an input; never a timeout, signal, traceback or numeric warning."""
        p: list[str] = []
        cmd = argv[0]
        err = out.stderr
        lines = [s for s in err.splitlines() if s.strip()]
        if out.timed_out:
            p.append(f"no answer within {timeout:g} s (killed)")
        elif out.signal is not None:
            p.append(f"killed by signal {out.signal} ({signal.Signals(out.signal).name})")
        elif "Traceback (most recent call last)" in err or out.status == 1:
            p.append("a traceback: " + " | ".join(lines[-3:])[-600:])
        elif out.status == 2:
            p += _error_line_problems(case, argv, folder, cmd, lines)
        elif out.status != 0:
            p.append(f"exit status {out.status}: {' | '.join(lines[-3:])[-600:]}")
        if out.status == 0 and out.check:
            p.append(f"exit 0 but {out.check}")
        numeric = [s for s in lines if "RuntimeWarning:" in s]
        if numeric:            # an overflow or a NaN met on the way: a check missing
            p.append(f"a numeric warning: {numeric[0][:300]}")
        return p

    def _leak_problems(self, case: Case, folder: Path, out: Outcome,
                       inputs: dict[str, str]) -> list[str]:
        """The canary's or /etc/passwd's bytes on stdout, stderr or in an output file."""
        p: list[str] = []
        for stream, text in (("stdout", out.stdout), ("stderr", out.stderr)):
            if self.marker in text or _PASSWD.decode() in text:
                p.append(f"the canary's or /etc/passwd's bytes on {stream}")
        for name in sorted(os.listdir(folder)):
            f = folder / name
            if name in inputs or name in case.links or not f.is_file() or f.is_symlink():
                continue
            if self._leaks(f):
                p.append(f"the canary's or /etc/passwd's bytes in the output {name}")
        return p

    def _file_problems(self, case: Case, folder: Path, out: Outcome, inputs: dict[str, str],
                       outside: dict) -> list[str]:
        """Files opened where they must not be, inputs changed, files outside the case
        folder created or changed, temporary files left (which are removed)."""
        p = self._files_touched(case, folder, out.opened)
        changed = [n for n, h in inputs.items()
                   if not (folder / n).is_file() or _digest(folder / n) != h]
        if changed:
            p.append(f"input files changed or removed: {changed}")
        now = self._outside()
        if now != outside:
            diff = sorted(set(now.items()) ^ set(outside.items()), key=str)[:4]
            p.append(f"files outside the case folder created or changed: {diff}")
        left = os.listdir(self.root / "tmp")
        if left:
            p.append(f"temporary files left in TMPDIR: {left[:4]}")
            for name in left:
                q = self.root / "tmp" / name
                shutil.rmtree(q) if q.is_dir() else q.unlink()
        return p

    def _leaks(self, f: Path) -> bool:
        with open(f, "rb") as fh:
            data = fh.read(256 * 2**20)
        blobs = [data]
        if data[:4] == b"PK\x03\x04":
            try:
                with zipfile.ZipFile(f) as z:
                    blobs += [z.read(i) for i in z.namelist()]
            except (zipfile.BadZipFile, OSError, ValueError):
                pass
        return any(n in b for b in blobs for n in self._needles + [_PASSWD])

    def _files_touched(self, case: Case, folder: Path, opened: list) -> list[str]:
        p = []
        case_dir = str(folder.resolve()) + os.sep
        canary = str(self.canary.resolve())
        for path, flags in opened:
            full = os.path.normpath(os.path.join(folder, path))
            if flags < 0 or flags & _WRITE:
                # a file written, renamed over, removed or a folder made
                real = os.path.join(os.path.realpath(os.path.dirname(full)),
                                    os.path.basename(full))
                if not (real + os.sep).startswith(case_dir) and \
                        not real.startswith(tuple(self.allowed_writes)) and \
                        "/__pycache__/" not in real:
                    p.append(f"wrote outside the case folder: {real}")
                continue
            real = os.path.realpath(full)
            if real == "/etc/passwd" or _ENVIRON.match(real) or \
                    (case.confined and real == canary):
                p.append(f"read {real} (named by {path!r})")
        return sorted(set(p))[:6]
