"""The fuzz harness itself: the worker answers as the ``stbs`` command does, and every
check the harness makes can fail (a stand-in for stbs that does the wrong thing)."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from fuzz_harness import Case

pytestmark = pytest.mark.slow


def _command() -> list[str]:
    """The installed ``stbs`` console script (or the same entry point via Python)."""
    script = Path(sys.executable).with_name("stbs")
    if script.is_file():
        return [str(script)]
    return [sys.executable, "-c", "import sys; from stbs.cli import main; sys.exit(main())"]


def test_the_worker_answers_as_the_command_does(fuzz_env, tmp_path):
    seeds = fuzz_env.seeds
    gltf = (seeds / "SimpleSkin.gltf").read_bytes()
    doc = json.loads(gltf)
    doc["buffers"][0]["uri"] = "../x.bin"
    outside = json.dumps(doc).encode()
    cases = [
        Case(["weights", "rig.gltf", "--endpoint", "projection", "-o", "out.gltf"],
             {"rig.gltf": gltf}),
        Case(["weights", "rig.gltf", "--endpoint", "projection", "-o", "out.gltf"],
             {"rig.gltf": outside}),
        Case(["deform", "rig.gltf", "--pose", "pose.json", "-o", "out.npz"],
             {"rig.gltf": gltf, "pose.json": b'{"rotate": {"9": {"axis": [0, 0, 1]}}}'}),
        Case(["animate", "rig.gltf", "--motion", "m.bvh", "-o", "out.npz", "--fps", "x"],
             {"rig.gltf": gltf}),
        Case(["export", "missing.glb", "-o", "out.glb"], {}),
    ]
    real = []
    for k, case in enumerate(cases):       # the command, each in a folder of its own
        d = tmp_path / str(k)
        d.mkdir()
        for name, data in case.files.items():
            (d / name).write_bytes(data)
        real.append(subprocess.Popen(_command() + case.argv, cwd=d, stdout=subprocess.PIPE,
                                     stderr=subprocess.PIPE, text=True))
    for k, (case, proc) in enumerate(zip(cases, real, strict=True)):
        out, err = proc.communicate(timeout=120)
        got = fuzz_env.run(case)
        assert (got.status, got.stdout) == (proc.returncode, out), case.argv
        if proc.returncode == 2:          # the same line, but for the folder's name
            here = got.stderr.replace(str(got.folder), "DIR")
            there = err.replace(str(tmp_path / str(k)), "DIR")
            assert here == there and len(err.splitlines()) == 1, (here, there)


def _problems(fuzz_env, code: str, *, check: str = "", files=None, timeout=None,
              out: str = "out.glb") -> str:
    case = Case(["weights", "rig.gltf", "-o", out],
                files if files is not None else {"rig.gltf": b"{}"}, check=check)
    code = (code.replace("CANARY", str(fuzz_env.canary))
            .replace("ROOT", str(fuzz_env.root)))
    return " | ".join(fuzz_env.run(case, exec_code=code, timeout=timeout).problems)


@pytest.mark.parametrize("code, problem", [
    ("rc = 0", ""),
    ("raise RuntimeError('boom')", "a traceback: .*RuntimeError: boom"),
    ("x = bytearray(3 * 2**30)", "a traceback: .*MemoryError"),
    ("rc = 3", "exit status 3"),
    ("import os, signal\nos.kill(os.getpid(), signal.SIGSEGV)", "signal 11"),
    ("import sys\nprint('stbs weights: error: a', file=sys.stderr)\n"
     "print('b', file=sys.stderr)\nrc = 2", "without exactly one line"),
    ("import sys\nprint('stbs weights: error: SVD did not converge', file=sys.stderr)\nrc = 2",
     "an error naming none of the input files"),
    ("import sys\nprint('stbs weights: error: rig.gltf: expected x, found y',"
     " file=sys.stderr)\nrc = 2", ""),
    ("open('ROOT/x.txt', 'w').write('x')", "wrote outside the case folder: .*x.txt.* "
                                           "files outside the case folder created"),
    ("import os\nos.replace('rig.gltf', 'ROOT/moved')", "wrote outside"),
    ("open('CANARY', 'rb').read()", "read .*canary"),
    ("open('out.bin', 'wb').write(open('CANARY', 'rb').read()[5:200])",
     "the canary's or /etc/passwd's bytes in the output out.bin"),
    ("import base64\nd = open('CANARY', 'rb').read()[7:300]\n"
     "open('out.txt', 'wb').write(b'x' + base64.b64encode(d))",
     "bytes in the output out.txt"),
    ("import zipfile\nz = zipfile.ZipFile('out.npz', 'w', zipfile.ZIP_DEFLATED)\n"
     "z.writestr('U.npy', open('CANARY', 'rb').read()[3:90])\nz.close()",
     "bytes in the output out.npz"),
    ("print(open('/proc/self/environ').read())",
     "read /proc/.*/environ.*|.*bytes on stdout"),
    ("import sys\nprint(open('/etc/passwd').read(), file=sys.stderr)\nrc = 2",
     "bytes on stderr"),
    ("open('rig.gltf', 'ab').write(b' ')", "input files changed"),
    ("import tempfile\ntempfile.mkstemp()", "temporary files left"),
    ("import sys\nprint('stbs: warning: RuntimeWarning: overflow', file=sys.stderr)",
     "a numeric warning"),
])
def test_each_check_can_fail(fuzz_env, code, problem):
    got = _problems(fuzz_env, code)
    if problem:
        assert re.search(problem, got), got
    else:
        assert got == ""


def test_a_run_that_reads_back_wrong_fails(fuzz_env):
    assert "exit 0 but the output does not read back" in _problems(
        fuzz_env, "rc = 0", check="deformed", out="out.npz")
    code = "import numpy as np\nnp.savez('out.npz', U=np.full((2, 3), np.nan))"
    got = _problems(fuzz_env, code, check="deformed", out="out.npz")
    assert "exit 0 but out.npz U holds NaN" in got


def test_a_case_past_its_time_is_killed_and_the_worker_restarted(fuzz_env):
    starts = fuzz_env.worker.starts
    assert "no answer within" in _problems(fuzz_env, "import time\ntime.sleep(60)",
                                           timeout=1)
    assert _problems(fuzz_env, "rc = 0") == ""
    assert fuzz_env.worker.starts == starts + 1
    assert os.listdir(fuzz_env.root / "tmp") == []
