"""The fuzz suite's worker: imports stbs once, then runs ``stbs.cli.main(argv)`` per case
in a forked child, as the ``stbs`` command would run it.

Run as ``python fuzz_worker.py`` by :mod:`fuzz_harness`; it reads one JSON request per
line on stdin and answers one JSON line on its original stdout (fd 1 is pointed at
/dev/null, so nothing stbs prints can garble the answers).

Requests:

``{"op": "warm", "argv": [...], "cwd": DIR}``
    Run a case in this process (no fork, no limits): it loads what later cases need
    (numba's compiled kernels, lazily imported modules), so that the forked children
    inherit it and each case costs its own work only. Answer ``{"rc": N}``.
``{"op": "case", "argv": [...], "cwd": DIR, "io": DIR, "memory": BYTES,
"forbidden": [PATH, ...], "allowed_writes": [PREFIX, ...], "check": KIND}``
    Fork a child that caps its address space (RLIMIT_AS) at what the worker holds
    plus ``memory`` bytes, changes to ``cwd``, sends fd 1 and 2 to files in ``io``,
    records every file it opens (an audit hook), runs ``main(argv)`` with an uncaught
    exception printed as Python prints it (exit status 1), checks the outputs of a
    successful run (``check``) and exits with main's status. Answer ``{"status":
    N or None, "signal": N or None, "stdout": TEXT, "stderr": TEXT, "opened":
    [[PATH, FLAGS], ...], "check": PROBLEM or None}``. With ``"exec": CODE`` the
    child runs that Python code in place of ``main`` (its ``rc`` the status): the
    harness's own tests use it to see that each of its checks can fail.

The harness starts the worker with ``NUMBA_THREADING_LAYER=workqueue``: numba's
default layer here, GNU OpenMP, aborts a child forked after its threads started.

The parent enforces the per-case timeout: it kills the worker's process group (the
worker and its child) when no answer comes in time, and starts a new worker.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import resource
import sys
import traceback


def _vm_size() -> int:
    """Bytes of address space this process holds (VmSize)."""
    with open("/proc/self/status", encoding="ascii") as fh:
        for line in fh:
            if line.startswith("VmSize:"):
                return int(line.split()[1]) * 1024
    return 0


def _warm(main, req: dict) -> dict:
    cwd = os.getcwd()
    try:
        os.chdir(req["cwd"])
        with contextlib.redirect_stdout(io.StringIO()), \
                contextlib.redirect_stderr(io.StringIO()) as err:
            rc = main(req["argv"])
    finally:
        os.chdir(cwd)
    return {"rc": rc, "stderr": err.getvalue()[-2000:]}


def _audit(opened: list):
    """An audit hook recording (path, flags) of every file opened and of every rename,
    removal and folder made (flags -1, -2, -3)."""
    def hook(event: str, args) -> None:
        if event == "open":
            path, _, flags = args
            if isinstance(path, (str, bytes)):
                opened.append((os.fsdecode(path), flags if isinstance(flags, int) else 0))
        elif event in ("os.rename", "os.replace"):
            opened.append((os.fsdecode(args[1]), -1))
        elif event in ("os.remove", "os.rmdir", "shutil.rmtree"):
            opened.append((os.fsdecode(args[0]), -2))
        elif event == "os.mkdir":
            opened.append((os.fsdecode(args[0]), -3))
    return hook


def _finite(name: str, x) -> str | None:
    """What is wrong with ``x`` if it holds NaN or infinity (None: nothing)."""
    import numpy as np

    x = np.asarray(x)
    if x.size and not np.isfinite(x).all():
        return f"{name} holds NaN or infinity"
    return None


def _check_gltf_copy(out: str) -> str | None:
    """A glTF copy is self-contained: its buffer is its own; an image it could not embed
    (not PNG or JPEG) keeps a relative name, never one leading out."""
    from stbs.io.gltf import GltfFile

    doc = GltfFile(out).doc
    bad = [b.get("uri") for b in doc.get("buffers", [])
           if not str(b.get("uri", "data:")).startswith("data:")]
    bad += [u for m in doc.get("images", []) if isinstance(m, dict)
            and isinstance(u := m.get("uri"), str) and not u.startswith("data:")
            and (":" in u or u.startswith("/") or ".." in u or "\\" in u
                 or "%" in u)]
    if bad:
        return f"{out}: a buffer or image naming a file ({bad[0][:80]!r})"
    return None


def _check_rig(kind: str, out: str) -> str | None:
    """A rig written (``rig-e``: with endpoint weights) reads back finite, its endpoint
    weights in [0, 1]."""
    import numpy as np

    from stbs.io import read_rig

    rig = read_rig(out)
    if rig.E is None and kind == "rig-e":
        return f"{out}: no endpoint weights"
    for name, x in (("V", rig.V), ("W", rig.W), ("E", rig.E)):
        if x is not None and (bad := _finite(f"{out} {name}", x)):
            return bad
    if rig.E is not None and not (np.min(rig.E) >= 0 and np.max(rig.E) <= 1):
        return f"{out}: endpoint weights outside [0, 1]"
    if out.lower().endswith((".gltf", ".glb")):
        return _check_gltf_copy(out)
    return None


def _check_deformed(kind: str, out: str) -> str | None:
    """One deformed mesh: U (n, 3), not empty, finite."""
    import numpy as np

    z = np.load(out)
    U = z["U"] if hasattr(z, "files") else z
    if U.ndim != 2 or U.shape[0] == 0:
        return f"{out}: U of shape {U.shape}"
    return _finite(f"{out} U", U)


def _check_frames(kind: str, out: str) -> str | None:
    """Frames: an .npz of U (frames, n, 3) and times, finite; a glTF that reads back
    finite (a .json is not looked into)."""
    import numpy as np

    if out.lower().endswith(".npz"):
        z = np.load(out)
        if z["U"].ndim != 3 or z["U"].shape[0] == 0:
            return f"{out}: U of shape {z['U'].shape}"
        return _finite(f"{out} U", z["U"]) or _finite(f"{out} times", z["times"])
    if out.lower().endswith(".json"):
        return None
    from stbs.io import read_gltf

    rig, _ = read_gltf(out)
    return _finite(f"{out} V", rig.V)


def _check_manifest(kind: str, out: str | None) -> str | None:
    """Every .npz a manifest's jobs wrote (in the case folder) is finite."""
    import numpy as np

    found = [f for f in os.listdir(".") if f.endswith(".npz")]
    for name in found:
        z = np.load(name)
        if bad := _finite(f"{name} U", z["U"]):
            return bad
    return None


_CHECKS = {"rig": _check_rig, "rig-e": _check_rig, "deformed": _check_deformed,
           "frames": _check_frames, "manifest": _check_manifest}


def _check_output(kind: str, argv: list[str]) -> str | None:
    """What is wrong with the outputs of a run that exited 0 (None: they look right)."""
    out = argv[argv.index("-o") + 1] if "-o" in argv else None
    check = _CHECKS.get(kind)
    return None if check is None else check(kind, out)


def _case(main, req: dict, base: int) -> dict:
    out_path = os.path.join(req["io"], "stdout")
    err_path = os.path.join(req["io"], "stderr")
    res_path = os.path.join(req["io"], "result.json")
    for p in (out_path, err_path, res_path):
        with contextlib.suppress(FileNotFoundError):
            os.unlink(p)
    sys.stdout.flush()
    sys.stderr.flush()
    pid = os.fork()
    if pid == 0:                                    # the case
        code = 1
        try:
            cap = base + int(req["memory"])
            resource.setrlimit(resource.RLIMIT_AS, (cap, cap))
            for fd in _PIPES:                   # the worker's own
                os.close(fd)
            for fd, p in ((1, out_path), (2, err_path)):
                f = os.open(p, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
                os.dup2(f, fd)
                os.close(f)
            os.chdir(req["cwd"])
            opened: list = []
            sys.addaudithook(_audit(opened))
            try:
                if req.get("exec"):             # the harness's own tests: a stand-in
                    ns = {"argv": req["argv"]}
                    exec(req["exec"], ns)
                    code = ns.get("rc", 0)
                else:
                    code = main(req["argv"])
            except SystemExit as exc:           # as the interpreter would exit
                code = exc.code if isinstance(exc.code, int) else 1
            except BaseException:               # as the interpreter prints it
                traceback.print_exc()
                code = 1
            problem = None
            if code == 0 and req.get("check"):
                try:
                    problem = _check_output(req["check"], req["argv"])
                except Exception as exc:        # an output that does not read back
                    problem = f"the output does not read back: {type(exc).__name__}: {exc}"
            sys.stdout.flush()
            sys.stderr.flush()
            fd = os.open(res_path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
            os.write(fd, json.dumps({"opened": opened, "check": problem}).encode())
            os.close(fd)
        except BaseException:
            with contextlib.suppress(BaseException):
                traceback.print_exc()
        finally:
            os._exit(code if isinstance(code, int) and 0 <= code < 256 else 1)
    _, status = os.waitpid(pid, 0)
    ans: dict = {"status": os.WEXITSTATUS(status) if os.WIFEXITED(status) else None,
                 "signal": os.WTERMSIG(status) if os.WIFSIGNALED(status) else None}
    for key, p in (("stdout", out_path), ("stderr", err_path)):
        try:
            with open(p, "rb") as fh:
                ans[key] = fh.read(1 << 20).decode("utf-8", "replace")
        except FileNotFoundError:
            ans[key] = ""
    try:
        with open(res_path, encoding="utf-8") as fh:
            ans.update(json.load(fh))
    except (FileNotFoundError, ValueError):
        ans.update(opened=[], check=None, no_result=True)
    return ans


#: The file descriptors the worker reads requests from and answers on.
_PIPES: list[int] = []


def serve() -> None:
    # requests and answers on their own descriptors; stdin reads nothing, stdout goes
    # nowhere (what stbs prints in a warm-up run is captured anyway)
    _PIPES[:] = [os.dup(0), os.dup(1)]
    requests = os.fdopen(_PIPES[0], "r", encoding="utf-8")
    answers = os.fdopen(_PIPES[1], "w", buffering=1, encoding="utf-8")
    for fd, mode in ((0, os.O_RDONLY), (1, os.O_WRONLY)):
        null = os.open(os.devnull, mode)
        os.dup2(null, fd)
        os.close(null)
    from stbs.cli import main

    for line in requests:
        req = json.loads(line)
        if req["op"] == "warm":
            ans = _warm(main, req)
        elif req["op"] == "case":
            ans = _case(main, req, _vm_size())
        else:
            ans = {"error": f"unknown op {req['op']!r}"}
        answers.write(json.dumps(ans) + "\n")


if __name__ == "__main__":
    serve()
