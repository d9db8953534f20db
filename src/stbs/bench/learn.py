"""Differentiable skinning throughput (``stbs bench --learn``): poses × vertices per second
of :class:`stbs.skin.Skinner`'s forward and backward passes on PyTorch (and JAX when
installed), beside the compiled NumPy kernels (:class:`stbs.Deformer`, one pose a call)
and an LBS written the usual PyTorch way (smplx's ``lbs``: a dense ``W @ A`` blend of
4×4 bone matrices, then one matrix per vertex applied to homogeneous points), all in one
run on the same rig and poses.

The rig is :func:`stbs.bench.make_rig`'s (``--vertices`` vertices around ``--bones``
bones, ``--influences`` bones per vertex, endpoint weights in [0, 1]); the batch is
``--batch`` random poses, each bone turned, moved, stretched and twisted at both ends.

- ``forward``: one batched call without a gradient tape (``torch.no_grad``; JAX: the
  jitted function);
- ``backward``: PyTorch: ``loss.backward()`` alone, after a forward that records the tape
  (untimed), ``loss = U.square().sum()``, gradients to every pose input; JAX: the jitted
  ``value_and_grad`` minus the jitted forward;
- ``numba``: the :class:`stbs.Deformer` of the same method called once per pose into a
  reused buffer (the NumPy path ``stbs.skin`` dispatches to for arrays without a tape).

Medians of ``--repeat`` calls after warm-up calls. The kernels' rows are timed first,
before PyTorch or JAX run anything: their thread pools keep spinning between operations
and would slow the kernels' own threads. ``--compile`` adds ``torch.compile``'s
forward (its compile time reported apart); ``--device cuda`` runs the PyTorch rows on a
GPU where one is present.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
import warnings

import numpy as np
import scipy.sparse as sp

from ..methods import SKINNING_METHODS as METHODS
from .report import (
    check_json_path,
    cpu_model,
    int_at_least,
    load_average,
    machine_lines,
    platform_name,
    write_json,
)
from .skinning import BenchRig, make_pose, make_rig

__all__ = ["add_arguments", "requires", "collect", "format_table", "run", "smplx_lbs"]

WARMUP = 2


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--learn", action="store_true", required=True,
                        help="time differentiable skinning (this benchmark)")
    parser.add_argument("--vertices", type=int_at_least(10), default=20_000,
                        help="vertices of the rig (default 20000)")
    parser.add_argument("--bones", type=int_at_least(1), default=24,
                        help="bones of the rig (default 24)")
    parser.add_argument("--influences", type=int_at_least(1), default=4,
                        help="bones per vertex (default 4)")
    parser.add_argument("--batch", type=int_at_least(1), default=32,
                        help="poses per batched call (default 32)")
    parser.add_argument("--methods", default=",".join(METHODS),
                        help=f"comma-separated, of {', '.join(METHODS)} (default: all)")
    parser.add_argument("--dtype", choices=("float32", "float64"), default="float32",
                        help="(default float32)")
    parser.add_argument("--repeat", type=int_at_least(1), default=7,
                        help="timed calls per row (default 7)")
    parser.add_argument("--backends", default="torch,jax",
                        help="comma-separated, of torch, jax (default torch,jax; a backend "
                             "that is not installed is left out with a note)")
    parser.add_argument("--device", default="cpu",
                        help="PyTorch device for its rows, e.g. cuda (default cpu)")
    parser.add_argument("--compile", action="store_true",
                        help="also time torch.compile's forward (compiles each method once)")
    parser.add_argument("--json", metavar="OUT.json", default=None,
                        help='also write {"learn": [{"method", "backend", "pass", '
                             '"seconds", "poses_vertices_per_s"}, ...], "machine": {...}}')


def _names(text: str, allowed, what: str) -> list[str]:
    names = [t.strip() for t in str(text).split(",") if t.strip()]
    bad = [t for t in names if t not in allowed]
    if not names or bad:
        raise ValueError(f"--{what} must be comma-separated names of {', '.join(allowed)}, "
                         f"got {text!r}")
    return names


def requires(args: argparse.Namespace) -> list[str]:
    return ["torch"] if "torch" in _names(args.backends, ("torch", "jax"), "backends") else []


# --------------------------------------------------------------------------- the peer
def smplx_lbs(V, W, A):
    """LBS the usual PyTorch way (as smplx's ``lbs`` blends its joints' transforms).

    Parameters
    ----------
    V : (n, 3) tensor
        Rest positions.
    W : (n, b) tensor
        Dense bone weights.
    A : (B, b, 4, 4) tensor
        Each bone's rest-to-posed transform.

    Returns
    -------
    (B, n, 3) tensor
    """
    import torch

    B, b = A.shape[:2]
    T = torch.matmul(W, A.reshape(B, b, 16)).reshape(B, -1, 4, 4)
    Vh = torch.cat([V, torch.ones_like(V[:, :1])], dim=1)
    return torch.matmul(T, Vh[None, :, :, None])[:, :, :3, 0]


def _affines(R: np.ndarray, O: np.ndarray, A0: np.ndarray) -> np.ndarray:
    """(B, b, 4, 4) rigid maps x -> R (x - a) + a' (the peer's transforms)."""
    T = np.zeros(R.shape[:-2] + (4, 4))
    T[..., :3, :3] = R
    T[..., :3, 3] = O - np.einsum("...ij,...j->...i", R, A0)
    T[..., 3, 3] = 1.0
    return T


# --------------------------------------------------------------------------- timing
def _median(fn, repeat: int) -> float:
    for _ in range(WARMUP):
        fn()
    ts = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t0)
    return statistics.median(ts)


class _Case:
    """The rig, its dense weights and a batch of poses as stacked arrays."""

    def __init__(self, args: argparse.Namespace):
        rig: BenchRig = make_rig(args.vertices, args.bones, args.influences, seed=0)
        self.rig = rig
        n, b = len(rig.V), rig.sk.n_bones
        rows = np.repeat(np.arange(n), rig.idx.shape[1])
        self.W = sp.csr_array((rig.w.ravel(), (rows, rig.idx.ravel())), shape=(n, b))
        self.E = sp.csr_array((rig.e.ravel(), (rows, rig.idx.ravel())), shape=(n, b))
        self.poses = [make_pose(rig.sk, seed=s + 1) for s in range(args.batch)]
        self.R = np.stack([p.rotations for p in self.poses])
        self.O = np.stack([p.origins for p in self.poses])
        self.sigma = np.stack([p.stretch for p in self.poses])
        self.theta = np.stack([p.twist for p in self.poses])
        self.dtype = np.dtype(args.dtype)


def _numba_rows(case: _Case, methods, repeat: int) -> dict:
    from ..skinning import Deformer

    out = {}
    buf = np.empty((len(case.rig.V), 3), dtype=case.dtype)
    for m in methods:
        dfm = Deformer(case.rig.V, case.rig.sk, case.W, case.E, method=m, dtype=case.dtype)

        def call(dfm=dfm):
            for p in case.poses:
                dfm(p, out=buf)

        out[(m, "numba", "forward")] = lambda call=call: _median(call, repeat)
    return out


def _torch_rows(case: _Case, methods, args) -> dict:
    import torch

    from ..skin import Skinner

    dev = torch.device(args.device)
    dt = torch.float32 if case.dtype == np.float32 else torch.float64

    def tensor(x, grad=False):
        return torch.tensor(np.asarray(x), dtype=dt, device=dev, requires_grad=grad)

    sync = torch.cuda.synchronize if dev.type == "cuda" else (lambda: None)
    R, O, s, th = (tensor(x) for x in (case.R, case.O, case.sigma, case.theta))
    leaves = [tensor(x, True) for x in (case.R, case.O, case.sigma, case.theta)]
    rows = {}
    for m in methods:
        sk = Skinner(case.rig.V, case.rig.sk, case.W, case.E, method=m, backend="torch",
                     dtype=dt, device=dev)

        def fwd(sk=sk):
            with torch.no_grad():
                sk(rotations=R, origins=O, stretch=s, twist=th)
            sync()

        def bwd(sk=sk):
            for x in leaves:
                x.grad = None
            loss = sk(rotations=leaves[0], origins=leaves[1], stretch=leaves[2],
                      twist=leaves[3]).square().sum()
            sync()
            t0 = time.perf_counter()
            loss.backward()
            sync()
            return time.perf_counter() - t0

        rows[(m, "torch", "forward")] = lambda f=fwd: _median(f, args.repeat)
        rows[(m, "torch", "backward")] = lambda f=bwd: _median_inner(f, args.repeat)
        if args.compile:
            rows[(m, "torch.compile", "forward")] = _compiled(sk, (R, O, s, th), args.repeat,
                                                              sync)
    Wd = tensor(case.W.toarray())
    V = tensor(case.rig.V)
    A = tensor(_affines(case.R, case.O, case.rig.sk.A))
    Ag = tensor(_affines(case.R, case.O, case.rig.sk.A), True)

    def peer_fwd():
        with torch.no_grad():
            smplx_lbs(V, Wd, A)
        sync()

    def peer_bwd():
        Ag.grad = None
        loss = smplx_lbs(V, Wd, Ag).square().sum()
        sync()
        t0 = time.perf_counter()
        loss.backward()
        sync()
        return time.perf_counter() - t0

    rows[("lbs", "smplx-style", "forward")] = lambda: _median(peer_fwd, args.repeat)
    rows[("lbs", "smplx-style", "backward")] = lambda: _median_inner(peer_bwd, args.repeat)
    return rows


def _median_inner(fn, repeat: int) -> float:
    """Median of the seconds ``fn`` itself reports (it times only its inner part)."""
    for _ in range(WARMUP):
        fn()
    return statistics.median(fn() for _ in range(repeat))


def _compiled(sk, inputs, repeat: int, sync):
    """A row timing torch.compile's forward; its compile time is kept on the function."""
    import torch

    state: dict = {}

    def row():
        if "fn" not in state:
            fn = torch.compile(lambda R, O, s, th: sk(rotations=R, origins=O, stretch=s,
                                                      twist=th), fullgraph=True)
            t0 = time.perf_counter()
            with torch.no_grad(), warnings.catch_warnings():
                # Dynamo's notes on the array-API layer's lru_cache'd type checks
                warnings.filterwarnings("ignore", message="Dynamo detected a call to")
                fn(*inputs)
            sync()
            state["fn"], state["compile_s"] = fn, time.perf_counter() - t0
            row.compile_s = state["compile_s"]

        def call():
            with torch.no_grad():
                state["fn"](*inputs)
            sync()

        return _median(call, repeat)

    return row


def _jax_rows(case: _Case, methods, args) -> dict:
    import jax
    import jax.numpy as jnp

    from ..skin import Skinner

    if case.dtype == np.float64:
        jax.config.update("jax_enable_x64", True)
    R, O, s, th = (jnp.asarray(x, dtype=case.dtype)
                   for x in (case.R, case.O, case.sigma, case.theta))
    rows = {}
    for m in methods:
        sk = Skinner(case.rig.V, case.rig.sk, case.W, case.E, method=m, backend="jax",
                     dtype=case.dtype)

        def f(R, O, s, th, sk=sk):
            return sk(rotations=R, origins=O, stretch=s, twist=th)

        fwd = jax.jit(f)
        vg = jax.jit(jax.value_and_grad(lambda *a, f=f: jnp.sum(f(*a) ** 2),
                                        argnums=(0, 1, 2, 3)))
        rows[(m, "jax", "forward")] = lambda fwd=fwd: _median(
            lambda: fwd(R, O, s, th).block_until_ready(), args.repeat)
        rows[(m, "jax", "forward+backward")] = lambda vg=vg: _median(
            lambda: jax.block_until_ready(vg(R, O, s, th)), args.repeat)
    return rows


def collect(args: argparse.Namespace, *, log=lambda msg: None) -> dict:
    """Time every row; ``{"learn": rows, "machine": {...}, "notes": [...]}``."""
    methods = _names(args.methods, METHODS, "methods")
    backends = _names(args.backends, ("torch", "jax"), "backends")
    case = _Case(args)
    # the kernels first, before PyTorch or JAX run anything: their OpenMP threads keep
    # spinning after each operation and would slow numba's threads several times over
    timers = _numba_rows(case, methods, args.repeat)
    log("timing the compiled kernels")
    seconds = {key: fn() for key, fn in timers.items()}
    notes = []
    versions = [f"numpy {np.__version__}"]
    for name, make in (("torch", _torch_rows), ("jax", _jax_rows)):
        if name not in backends:
            continue
        try:
            mod = __import__(name)
        except ImportError:
            notes.append(f"{name} is not installed: its rows are left out (stbs-skinning's "
                         f"{name} extra brings it)")
            continue
        versions.append(f"{name} {mod.__version__}")
        timers.update(make(case, methods, args))
    log(f"{len(timers) - len(seconds)} more rows, {args.repeat} timed calls each")
    seconds.update({key: fn() for key, fn in timers.items() if key not in seconds})
    n, B = len(case.rig.V), args.batch
    rows = []
    for (m, backend, kind), t in seconds.items():
        row = {"method": m, "backend": backend, "pass": kind, "seconds": t,
               "poses_vertices_per_s": B * n / t}
        comp = getattr(timers[(m, backend, kind)], "compile_s", None)
        if comp is not None:
            row["compile_s"] = comp
        rows.append(row)
    machine = {"cpu": cpu_model(), "cpus": os.cpu_count(), "platform": platform_name(),
               "load_average": load_average(),
               "vertices": n, "bones": case.rig.sk.n_bones, "influences": args.influences,
               "batch": B, "dtype": args.dtype, "device": args.device,
               "versions": ", ".join(versions)}
    return {"learn": rows, "machine": machine, "notes": notes}


def _ratios(rows: list[dict]) -> dict:
    """(method, backend, pass) -> (this row's time / numba's forward, / own forward)."""
    t = {(r["method"], r["backend"], r["pass"]): r["seconds"] for r in rows}
    out = {}
    for (m, be, kind), s in t.items():
        numba = t.get((m, "numba", "forward"))
        own = t.get((m, be, "forward"))
        out[(m, be, kind)] = (None if numba is None else s / numba,
                              None if own is None or kind == "forward" else s / own)
    return out


def format_table(doc: dict) -> list[str]:
    rows = doc["learn"]
    ratios = _ratios(rows)
    head = (f"{'method':<9} {'backend':<14} {'pass':<17} {'ms/batch':>9} "
            f"{'poses*verts/s':>14} {'÷ numba fwd':>11} {'÷ own fwd':>9}")
    lines = [head, "-" * len(head)]
    for r in rows:
        vs_numba, vs_own = ratios[(r["method"], r["backend"], r["pass"])]
        lines.append(
            f"{r['method']:<9} {r['backend']:<14} {r['pass']:<17} {1e3 * r['seconds']:>9.2f} "
            f"{r['poses_vertices_per_s']:>14.3e} "
            f"{'' if vs_numba is None else f'{vs_numba:.2f}×':>11} "
            f"{'' if vs_own is None else f'{vs_own:.2f}×':>9}"
            + (f"  (compiled in {r['compile_s']:.1f} s)" if "compile_s" in r else ""))
    return lines


def run(args: argparse.Namespace) -> int:
    path = check_json_path(args.json)

    def log(msg: str) -> None:
        print(f"stbs bench: {msg}", file=sys.stderr, flush=True)

    doc = collect(args, log=log)
    m = doc["machine"]
    for line in machine_lines(m, m["versions"], "the times"):
        print(line)
    print(f"rig: {m['vertices']} vertices, {m['bones']} bones, {m['influences']} per vertex; "
          f"batches of {m['batch']} poses, {m['dtype']}, PyTorch on {m['device']}")
    for note in doc["notes"]:
        print(f"note: {note}")
    print()
    for line in format_table(doc):
        print(line)
    if path is not None:
        write_json(path, doc)
        print(f"\nwrote {path}")
    return 0
