"""Fuzzing the command line: mutated glTF characters, BVH captures, clips, poses and
batch manifests, each run through the real ``stbs`` command (see fuzz_harness for what
is checked).

Two profiles:

- short (the default, run by ``make test``): a fixed number of cases per target,
  derandomized (the same cases on every run), under a minute in all;
- long (``make fuzz``; ``STBS_FUZZ_SECONDS=N`` sets it): each target draws cases for
  its share of N seconds, from seeds ``STBS_FUZZ_SEED`` (default 0), 1, 2, ...

A target collects every distinct problem (the same problem seen again only counts)
and fails at the end with one example of each, so one run shows all it found. In the
short profile a case past its time ends the target's run (each costs the time limit
and a new worker), so that a hang found never holds ``make test`` up for long.
"""

from __future__ import annotations

import json
import os
import re
import time

import pytest
from fuzz_harness import Case, FuzzEnv
from fuzz_mutations import (
    Gltf,
    apply_bvh,
    apply_bytes,
    apply_gltf,
    apply_json,
    bvh_ops,
    byte_ops,
    dumps,
    gltf_ops,
    hostile_values,
    json_ops,
)
from fuzz_seeds import manifest
from hypothesis import HealthCheck, Phase, given, seed, settings
from hypothesis import strategies as st

pytestmark = pytest.mark.slow

#: The long profile's seconds (unset or 0: the short profile) and first seed.
SECONDS = float(os.environ.get("STBS_FUZZ_SECONDS") or 0)
SEED = int(os.environ.get("STBS_FUZZ_SEED") or 0)
#: A file to append every case's outcome to (one JSON line each), for looking into
#: what the cases reach.
LOG = os.environ.get("STBS_FUZZ_LOG")
#: Cases per target in the short profile.
SHORT = {"gltf": 240, "bvh": 60, "clip": 50, "pose": 50, "manifest": 30}
#: Each target's share of the long profile's time.
SHARE = {"gltf": 0.45, "bvh": 0.15, "clip": 0.12, "pose": 0.1, "manifest": 0.18}


def _sometimes(ops):
    """Now and then (one case in four), byte-level edits on top of the others."""
    return st.one_of(st.none(), st.none(), st.none(), ops)


def _signature(problem: str) -> str:
    """A problem with its numbers, paths and quoted text blurred: the same bug twice is
    one finding."""
    s = re.sub(r"'[^']*'|\"[^\"]*\"", "'…'", problem)
    s = re.sub(r"/\S+", "PATH", s)
    s = re.sub(r"\d+(\.\d+)?(e[-+]?\d+)?", "N", s)
    return s[:160]


def _run(fuzz_env: FuzzEnv, target: str, strategy, make_case) -> None:
    found: dict[str, list] = {}
    stats = {"cases": 0, "seconds": 0.0, "ok": 0, "refused": 0, "making": 0.0,
             "timeouts": 0}

    def one(x):
        if stats["timeouts"] and not SECONDS:
            return          # the short profile reports one case past its time, not all
        t = time.perf_counter()
        case = make_case(fuzz_env, x)
        stats["making"] += time.perf_counter() - t
        out = fuzz_env.run(case)
        stats["cases"] += 1
        stats["seconds"] += out.seconds
        stats["ok"] += out.status == 0
        stats["refused"] += out.status == 2
        stats["timeouts"] += out.timed_out
        if LOG:
            with open(LOG, "a", encoding="utf-8") as fh:
                fh.write(json.dumps({"target": target, "case": repr(x)[:2000],
                                     "status": out.status, "seconds": round(out.seconds, 3),
                                     "stderr": out.stderr[-1000:],
                                     "problems": out.problems}) + "\n")
        for prob in out.problems:
            entry = found.setdefault(_signature(prob), [0, case.label, x, prob, case.argv])
            entry[0] += 1

    common = dict(database=None, deadline=None, phases=[Phase.explicit, Phase.generate],
                  suppress_health_check=list(HealthCheck), print_blob=False)
    if SECONDS:
        end = time.monotonic() + SECONDS * SHARE[target]
        k = SEED
        while time.monotonic() < end:
            test = settings(max_examples=25, derandomize=False, **common)(
                seed(k)(given(strategy)(one)))
            test()
            k += 1
    else:
        settings(max_examples=SHORT[target], derandomize=True, **common)(
            given(strategy)(one))()
    print(f"\nfuzz {target}: {stats['cases']} cases in {stats['seconds']:.1f} s "
          f"({stats['ok']} exit 0, {stats['refused']} exit 2; {stats['making']:.1f} s making "
          f"them), {len(found)} distinct problems")
    if found:
        lines = [f"{n}x {label}: {prob}\n    case: {x!r}\n    stbs {' '.join(argv)}"
                 for n, label, x, prob, argv in found.values()]
        pytest.fail(f"fuzz {target}: {len(found)} distinct problems "
                    f"(cases kept in {fuzz_env.root / 'failures'}):\n" + "\n".join(lines),
                    pytrace=False)


# ----------------------------------------------------------------------------- glTF
GLTF_SEEDS = ["SimpleSkin.gltf", "SimpleSkin.gltf", "RiggedSimple.glb", "CesiumMan.glb",
              "SimpleSkin-stbs.gltf", "exported.glb"]
#: --skin and --mesh (which skeleton or mesh of a character to read), now and then
PICK = [[], [], [], ["--skin", "0"], ["--skin", "1"], ["--mesh", "0"], ["--mesh", "2"],
        ["--skin", "stbs"], ["--mesh", "mesh"]]
GLTF_COMMANDS = ["weights", "weights-gltf", "deform", "export", "animate"]
_PARSED: dict[str, Gltf] = {}


def _canary(env: FuzzEnv) -> dict:
    return {"canary": str(env.canary), "secret": env.canary.name, "up": "../..",
            "canary_dir": str(env.root)}


def _gltf_case(env: FuzzEnv, x) -> Case:
    name, cmd, ops, raw, pick = x
    if name not in _PARSED:
        _PARSED[name] = Gltf.parse((env.seeds / name).read_bytes())
    g = apply_gltf(_PARSED[name], ops, _canary(env))
    data, files = g.pack()
    if raw:
        data = apply_bytes(data, raw)
    rig = "rig" + os.path.splitext(name)[1]
    files[rig] = data
    argv, check = {
        "weights": (["weights", rig, "--endpoint", "projection", "-o", "out.glb"], "rig-e"),
        "weights-gltf": (["weights", rig, "--endpoint", "projection", "-o", "out.gltf"],
                         "rig-e"),
        "deform": (["deform", rig, "--pose", "pose.json", "-o", "out.npz"], "deformed"),
        "export": (["export", rig, "-o", "out.glb"], "rig"),
        "animate": (["animate", rig, "--motion", rig, "-o", "out.npz"], "frames"),
    }[cmd]
    if cmd == "deform":
        files["pose.json"] = (env.seeds / "any-pose.json").read_bytes()
        if pick[:1] == ["--mesh"]:       # deform's --mesh is a rest mesh file
            pick = []
    argv = argv + pick
    return Case(argv, files, g.links, check=check, confined=True, label=f"glTF {name} {cmd}")


def test_fuzz_gltf(fuzz_env):
    strategy = st.tuples(st.sampled_from(GLTF_SEEDS), st.sampled_from(GLTF_COMMANDS),
                         gltf_ops(), _sometimes(byte_ops(2)), st.sampled_from(PICK))
    _run(fuzz_env, "gltf", strategy, _gltf_case)


# ----------------------------------------------------------------------------- BVH
def _bvh_case(env: FuzzEnv, x) -> Case:
    name, ops, raw, out, opts = x
    text = apply_bvh((env.seeds / name).read_text(), ops)
    data = text.encode("utf-8", "surrogatepass")
    if raw:
        data = apply_bytes(data, raw)
    argv = ["animate", "{seeds}/RiggedFigure.glb", "--motion", "m.bvh", "-o", out, *opts]
    return Case(argv, {"m.bvh": data}, check="frames", label=f"BVH {name}")


def test_fuzz_bvh(fuzz_env):
    opts = st.sampled_from([[], ["--stretch", "match"], ["--twist", "joint"],
                            ["--method", "lbs"]])
    strategy = st.tuples(st.sampled_from(["cmu.bvh", "walk.bvh", "walk60.bvh"]), bvh_ops(),
                         _sometimes(byte_ops(2)), st.sampled_from(["out.npz", "out.json"]),
                         opts)
    _run(fuzz_env, "bvh", strategy, _bvh_case)


# ----------------------------------------------------------------------------- clips
CLIP_VALUES = st.one_of(
    hostile_values(),
    st.sampled_from(["linear", "step", "cubic", "node1", "node2", "0", "1", "7", "-1"]),
    st.sampled_from([{"time": 1e308, "pose": {}}, {"time": 0, "pose": {}}, {"pose": {}},
                     {"rotate": {"node1": {"axis": [0, 0, 0], "angle": 1}}},
                     {"rotate": {"0": {"axis": [1e308, 1e308, 0], "angle": 1e308}}},
                     {"rotate": {"0": {"quaternion": [0, 0, 0, 0]}}},
                     {"rotate": {"0": {"matrix": [[1e308] * 3] * 3}}},
                     {"joints": [[0, 0, 0]]}, {"joints": [[0, 0, 0]] * 3},
                     {"translate": [1e308, 0, 0]}, {"stretch": {"0": 0}},
                     {"stretch": {"0": -1}}, {"stretch": {"0": 1e308}},
                     {"twist": {"0": [1e308, -1e308]}}, {"degrees": "yes"}]))


def _json_case(seed_name: str, file_name: str, argv, check: str):
    def make(env: FuzzEnv, x) -> Case:
        ops, raw = x
        doc = apply_json(json.loads((env.seeds / seed_name).read_bytes()), ops)
        data = dumps(doc).encode("utf-8", "surrogatepass")
        if raw:
            data = apply_bytes(data, raw)
        return Case(list(argv), {file_name: data}, check=check,
                    label=f"{seed_name} {argv[0]}")
    return make


def test_fuzz_clip(fuzz_env):
    strategy = st.tuples(json_ops(3, CLIP_VALUES), _sometimes(byte_ops(1)))
    argv = ["animate", "{seeds}/SimpleSkin.gltf", "--motion", "clip.json", "-o", "out.npz"]
    _run(fuzz_env, "clip", strategy, _json_case("clip.json", "clip.json", argv, "frames"))


def test_fuzz_pose(fuzz_env):
    makers = {s: _json_case(s, "pose.json", ["deform", "{seeds}/SimpleSkin.gltf", "--pose",
                                              "pose.json", "-o", "out.npz"], "deformed")
              for s in ("pose.json", "pose-joints.json", "any-pose.json")}

    def make(env, x):
        name, ops, raw = x
        return makers[name](env, (ops, raw))

    strategy = st.tuples(st.sampled_from(sorted(makers)), json_ops(3, CLIP_VALUES),
                         _sometimes(byte_ops(1)))
    _run(fuzz_env, "pose", strategy, make)


# ----------------------------------------------------------------------------- manifests
MANIFEST_VALUES = st.one_of(
    hostile_values(),
    st.sampled_from(["SimpleSkin.gltf", "RiggedFigure.glb", "clip.json", "walk.bvh",
                     "SimpleSkin.gltf/", "missing.npz", "out.glb", "out.gltf", "out/", "out",
                     "x.npz", "clip.npz", "manifest.json", "/etc/passwd", "CANARY",
                     "../../SECRET", "lbs", "dqs", "stbs", "spread", "joint", "keep",
                     "match", "0:3", "0:1000000000", "::", "a:b", "5:2", "-1:", "0:3:0",
                     "0:3:-1", "1e9", "0:2:1000000000", "animation_0"]))
_MANIFEST_FILES = ("SimpleSkin.gltf", "RiggedFigure.glb", "clip.json", "walk.bvh")


def _manifest_case(env: FuzzEnv, x) -> Case:
    ops, raw = x
    doc = apply_json(manifest(), ops)
    canary = _canary(env)
    # A manifest names where its outputs go (anywhere, by design): outputs that would
    # leave the case folder are kept in it, so that writing outside still means a bug.
    for job in doc if isinstance(doc, list) else []:
        if isinstance(job, dict):
            for key, v in list(job.items()):
                if isinstance(v, str):
                    v = (v.replace("CANARY", canary["canary"])
                         .replace("SECRET", canary["secret"]))
                    if key == "output" and (".." in v or v.startswith("/")):
                        v = "escaped.npz"
                    job[key] = v
    data = dumps(doc).encode("utf-8", "surrogatepass")
    if raw:
        data = apply_bytes(data, raw)
    files = {n: (env.seeds / n).read_bytes() for n in _MANIFEST_FILES}
    files["manifest.json"] = data
    return Case(["animate", "--manifest", "manifest.json"], files, check="manifest",
                confined=False, outputs_named=True, label="manifest")


def test_fuzz_manifest(fuzz_env):
    strategy = st.tuples(json_ops(3, MANIFEST_VALUES), _sometimes(byte_ops(1)))
    _run(fuzz_env, "manifest", strategy, _manifest_case)
