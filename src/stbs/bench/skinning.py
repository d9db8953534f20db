"""Throughput of the four skinning methods beside NumPy and SciPy peers (``stbs bench``).

For each vertex count and storage dtype the benchmark builds a random rig (a
``bones``-bone forest, vertices scattered around it, ``influences`` non-zero bone
weights per vertex on random bones, random endpoint weights) and a pose with a
rotation, a stretch and a twist at both ends on *every* bone. It then times one
frame, ``Deformer(...)(pose, out=buf)``, per method, and in the same run:

- ``numpy-lbs``: LBS in plain NumPy over the top-k weights (per-vertex blended
  3x4 matrices by ``einsum``, then applied);
- ``scipy-lbs``: LBS as one sparse product ``L @ T`` (the LBS matrix of libigl's
  ``lbs_matrix``, sparse).

More peers can be timed in the same run through ``run_bench(extra_peers=...)``:
``benchmarks/skinning_vs_igl.py`` in the source tree adds libigl's.

Times are nanoseconds per vertex, the **median** of ``repeats`` frames after two
warm-up frames (so JIT compilation is never timed); the minimum is kept in the
rows too. Each row also gives the bytes the method must move per vertex, the
bandwidth-bound time for those bytes at the memory bandwidth measured in the same
run, and the ratio of the measured time to that bound. Rows for our methods add
the memory held by the ``Deformer`` against the input and the peak memory
allocated while building it and per frame (``tracemalloc``).

Nothing here touches the network or starts a process. Docs: ``docs/benchmarks.md``.
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import re
import statistics
import sys
import time
import tracemalloc
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .. import transforms as tf
from ..pose import Pose
from ..skeleton import Skeleton
from ..skinning import METHODS, Deformer
from .report import (
    check_json_path,
    cpu_model,
    load_average,
    machine_lines,
    peak_rss_bytes,
    platform_name,
    positive_int,
    quiet,
    write_json,
)

__all__ = ["PEERS", "DTYPES", "DEFAULT_SIZES", "WARMUP", "Peer", "BenchRig", "make_rig",
           "make_pose", "lbs_affines", "numpy_lbs", "lbs_matrix_sparse", "stacked_transforms",
           "measure_bandwidth", "machine_info", "time_frames", "auto_repeats", "csr_bytes",
           "make_row", "run_bench", "format_table", "add_arguments", "collect", "print_report",
           "run", "main"]

#: The peers ``stbs bench`` times beside our methods.
PEERS: tuple[str, ...] = ("numpy-lbs", "scipy-lbs")
DTYPES: tuple[str, ...] = ("float64", "float32")
DEFAULT_SIZES: tuple[int, ...] = (10_000, 100_000, 1_000_000)
#: Untimed frames before the timed ones.
WARMUP = 2

Log = Callable[[str], None]
#: An extra peer for :func:`run_bench`: ``peer(rig, V, repeats, bandwidth, log)`` returns
#: one row (:func:`make_row`) for the rig's vertices stored as ``V`` (its dtype is the row's).
Peer = Callable[["BenchRig", np.ndarray, int, dict, Log], dict]


# --------------------------------------------------------------------------- rig and pose
@dataclass
class BenchRig:
    """A random rig in top-k form.

    Attributes
    ----------
    sk : Skeleton
        3D forest of b bones.
    V : (n, 3) float64
        Rest positions.
    idx : (n, k) int64
        Distinct bones per vertex (column 0 is the bone the vertex was placed around).
    w : (n, k) float64
        Bone weights, all > 0, rows summing to 1.
    e : (n, k) float64
        Endpoint weights in [0, 1] of the same (vertex, bone) pairs.
    pose : Pose
        Rotation, stretch != 1 and both twist angles != 0 on every bone.
    """

    sk: Skeleton
    V: np.ndarray
    idx: np.ndarray
    w: np.ndarray
    e: np.ndarray
    pose: Pose

    @property
    def n(self) -> int:
        return int(self.V.shape[0])

    def _sparse(self, X: np.ndarray) -> sp.csr_array:
        n, k = self.idx.shape
        indptr = np.arange(0, n * k + 1, k, dtype=np.int64)
        return sp.csr_array((X.ravel(), self.idx.ravel(), indptr),
                            shape=(n, self.sk.n_bones))

    @property
    def W(self) -> sp.csr_array:
        """(n, b) bone weights, CSR with k entries per row."""
        return self._sparse(self.w)

    @property
    def E(self) -> sp.csr_array:
        """(n, b) endpoint weights, CSR with the sparsity of ``W``."""
        return self._sparse(self.e)

    def W_dense(self) -> np.ndarray:
        """(n, b) float64 dense bone weights."""
        Wd = np.zeros((self.n, self.sk.n_bones))
        np.put_along_axis(Wd, self.idx, self.w, axis=1)
        return Wd


def _unit(rng: np.random.Generator, m: int) -> np.ndarray:
    x = rng.standard_normal((m, 3))
    return x / np.linalg.norm(x, axis=1, keepdims=True)


def _random_skeleton(rng: np.random.Generator, bones: int) -> Skeleton:
    """A forest: bone 0 and (for b >= 4) bone b//2 start new trees; every other
    bone continues the previous bone (a chain) or branches off an earlier end."""
    C = [np.zeros(3)]
    BE, ends = [], []
    for i in range(bones):
        if i == 0:
            start = 0
        elif bones >= 4 and i == bones // 2:
            C.append(rng.normal(scale=3.0, size=3))
            start = len(C) - 1
        elif rng.random() < 0.6:
            start = ends[i - 1]
        else:
            start = ends[int(rng.integers(i))]
        C.append(C[start] + rng.uniform(0.5, 1.5) * _unit(rng, 1)[0])
        ends.append(len(C) - 1)
        BE.append((start, len(C) - 1))
    return Skeleton(np.array(C), np.array(BE))


def make_pose(sk: Skeleton, seed: int = 0, *, stretch: bool = True, twist: bool = True,
              max_angle: float = 1.2) -> Pose:
    """A random pose: every bone rotated by 0.3..``max_angle`` rad about a random axis,
    its start moved, and (by default) stretched by 0.6..0.9 or 1.1..1.4 and twisted by
    0.2..pi rad (either sign) at *both* ends, so no bone takes a shortcut."""
    rng = np.random.default_rng([seed, 1])
    b = sk.n_bones
    R = tf.axis_angle_to_matrix(_unit(rng, b), rng.uniform(0.3, max_angle, b))
    origins = sk.A + 0.2 * rng.standard_normal((b, 3))
    sigma = 1.0 + rng.choice([-1.0, 1.0], b) * rng.uniform(0.1, 0.4, b) if stretch else None
    theta = (rng.choice([-1.0, 1.0], (b, 2)) * rng.uniform(0.2, np.pi, (b, 2))
             if twist else None)
    return Pose(sk, rotations=R, origins=origins, stretch=sigma, twist=theta)


def make_rig(n: int, bones: int = 20, influences: int = 4, seed: int = 0) -> BenchRig:
    """Random rig with ``n`` vertices; see :class:`BenchRig`."""
    n, bones, influences = int(n), int(bones), int(influences)
    if n < 1:
        raise ValueError(f"n must be >= 1, got {n}")
    if bones < 1:
        raise ValueError(f"bones must be >= 1, got {bones}")
    if not 1 <= influences <= bones:
        raise ValueError(f"influences must be in 1..bones={bones}, got {influences}")
    rng = np.random.default_rng([seed, 0])
    sk = _random_skeleton(rng, bones)
    k = influences
    # k distinct random bones per vertex, vectorised (no loop over vertices)
    idx = np.argpartition(rng.random((n, bones), dtype=np.float32), k - 1, axis=1)[:, :k]
    idx = np.ascontiguousarray(idx, dtype=np.int64)
    home = idx[:, 0]
    t = rng.random((n, 1))
    V = sk.A[home] + t * (sk.B - sk.A)[home] + 0.3 * rng.standard_normal((n, 3))
    w = rng.uniform(0.05, 1.0, (n, k))
    w[:, 0] += 1.0  # the bone a vertex sits around weighs most
    w /= w.sum(axis=1, keepdims=True)
    e = rng.random((n, k))
    return BenchRig(sk=sk, V=V, idx=idx, w=w, e=e, pose=make_pose(sk, seed))


# --------------------------------------------------------------------------- LBS peers
def lbs_affines(pose: Pose) -> np.ndarray:
    """(b, 3, 4) float64 ``[R_i S_i | a'_i - R_i S_i a_i]``: bone i's LBS map (eq. 1-3)."""
    sk = pose.skeleton
    U = sk.axes
    S = np.eye(3) + (pose.stretch - 1)[:, None, None] * np.einsum("bi,bj->bij", U, U)
    M = np.einsum("bij,bjk->bik", pose.rotations, S)
    t = pose.origins - np.einsum("bij,bj->bi", M, sk.A)
    return np.concatenate([M, t[:, :, None]], axis=2)


def numpy_lbs(V: np.ndarray, idx: np.ndarray, w: np.ndarray, A: np.ndarray) -> np.ndarray:
    """LBS in NumPy over top-k weights: blend each vertex's 3x4 matrix, then apply it.

    Parameters
    ----------
    V : (n, 3) float
    idx : (n, k) int
    w : (n, k) float, same dtype as V
    A : (b, 3, 4) float64
        From :func:`lbs_affines`; cast to V's dtype.

    Returns
    -------
    (n, 3) array of V's dtype.
    """
    n = V.shape[0]
    A12 = A.reshape(A.shape[0], 12).astype(V.dtype, copy=False)
    M = np.einsum("nk,nkj->nj", w, A12[idx]).reshape(n, 3, 4)
    return np.einsum("nij,nj->ni", M[:, :, :3], V) + M[:, :, 3]


def lbs_matrix_sparse(V: np.ndarray, idx: np.ndarray, w: np.ndarray,
                      b: int | None = None) -> sp.csr_array:
    """(n, 4b) CSR LBS matrix, columns ordered as libigl's ``lbs_matrix``.

    Row v holds ``w_vi * [x, y, z, 1]`` in columns ``4i .. 4i+3`` for each bone i of v,
    so that ``L @ stacked_transforms(A)`` is LBS. ``b`` defaults to ``idx.max() + 1``.
    """
    n, k = idx.shape
    Vh = np.concatenate([V, np.ones((n, 1), dtype=V.dtype)], axis=1)
    data = (w[:, :, None] * Vh[:, None, :]).reshape(-1)
    cols = (4 * idx[:, :, None] + np.arange(4)).reshape(-1)
    indptr = np.arange(0, 4 * n * k + 1, 4 * k, dtype=np.int64)
    if b is None:
        b = int(idx.max()) + 1 if idx.size else 1
    L = sp.csr_array((data, cols, indptr), shape=(n, 4 * int(b)))
    L.sort_indices()
    return L


def stacked_transforms(A: np.ndarray) -> np.ndarray:
    """(4b, 3) ``T`` with ``T[4i:4i+4] = A_i^T``: the right factor of ``M @ T`` LBS."""
    return np.ascontiguousarray(A.transpose(0, 2, 1).reshape(-1, 3))


# --------------------------------------------------------------------------- bandwidth
def measure_bandwidth(nbytes: int = 128 * 2**20, repeats: int = 5) -> dict:
    """Memory bandwidth in GB/s: a multi-threaded triad, and a NumPy copy for reference.

    ``triad``: ``a = b + s c`` compiled with numba over all its threads, 3 * nbytes
    moved. It streams like the skinning kernels do (same threads, loads plus
    ordinary stores), so it is the figure the bounds use (``gbs``). ``copy``:
    ``np.copyto(b, a)`` on one thread, 2 * nbytes moved (memcpy may use streaming
    stores). Both count bytes read plus bytes written; the write-allocate read of a
    destination line is not counted (the STREAM convention, and the one used for
    the skinning methods' bytes). Each figure is the best of ``repeats``.
    """
    import numba as nb

    @nb.njit(parallel=True, nogil=True, cache=False)
    def _triad(a, b, c, s):  # pragma: no cover - compiled
        for i in nb.prange(a.shape[0]):
            a[i] = b[i] + s * c[i]

    m = max(int(nbytes) // 8, 1)
    a = np.ones(m)
    b = np.full(m, 2.0)
    c = np.full(m, 3.0)
    _triad(a[:1024], b[:1024], c[:1024], 0.5)  # compile outside the timing

    def best(fn) -> float:
        fn()
        ts = []
        for _ in range(max(int(repeats), 1)):
            t0 = time.perf_counter()
            fn()
            ts.append(time.perf_counter() - t0)
        return min(ts)

    t_copy = best(lambda: np.copyto(b, a))
    t_triad = best(lambda: _triad(a, b, c, 0.5))
    copy_gbs = 2 * m * 8 / t_copy / 1e9
    triad_gbs = 3 * m * 8 / t_triad / 1e9
    return {"gbs": triad_gbs, "copy_gbs": copy_gbs, "triad_gbs": triad_gbs,
            "triad_threads": int(nb.get_num_threads()), "array_bytes": m * 8,
            "counted": "bytes read + bytes written; write-allocate reads not counted"}


# --------------------------------------------------------------------------- machine
def machine_info() -> dict:
    """CPU model, core count, thread counts and library versions."""
    import numba as nb

    return {"cpu": cpu_model(), "cpus": os.cpu_count(), "numba_threads": nb.get_num_threads(),
            "python": platform.python_version(), "numpy": np.__version__,
            "numba": nb.__version__, "platform": platform_name(),
            "load_average": load_average()}


# --------------------------------------------------------------------------- timing
def time_frames(fn: Callable[[], object], repeats: int) -> tuple[float, float]:
    """(median, min) seconds per call of ``fn`` over ``repeats`` calls after
    :data:`WARMUP` untimed calls."""
    for _ in range(WARMUP):
        fn()
    ts = []
    for _ in range(int(repeats)):
        t0 = time.perf_counter_ns()
        fn()
        ts.append(time.perf_counter_ns() - t0)
    return statistics.median(ts) * 1e-9, min(ts) * 1e-9


def auto_repeats(n: int) -> int:
    """Timed frames for ``n`` vertices when none are given: 5e7 / n, within 10..300."""
    return int(min(300, max(10, 5e7 // max(n, 1))))


def _traced_peak(fn: Callable[[], object]) -> tuple[object, int, float]:
    """(result, peak bytes newly allocated while running fn, seconds)."""
    tracemalloc.start()
    try:
        t0 = time.perf_counter()
        res = fn()
        dt = time.perf_counter() - t0
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    return res, int(peak), dt


def csr_bytes(X: sp.csr_array) -> int:
    """Bytes held by a CSR matrix's data, indices and row pointers."""
    return int(X.data.nbytes + X.indices.nbytes + X.indptr.nbytes)


def make_row(size: int, dtype: str, method: str, kind: str, bandwidth: dict, *,
             med: float | None = None, mn: float | None = None, repeats: int | None = None,
             threads=None, bytes_per_vertex: float | None = None, note: str = "",
             reason: str = "") -> dict:
    """One row of the report.

    Parameters
    ----------
    size : int
        Vertices.
    dtype : str
        Storage dtype.
    method : str
        One of ours, or a peer's name.
    kind : {"stbs", "peer"}
    bandwidth : dict
        From :func:`measure_bandwidth` (its ``gbs`` gives the bound).
    med, mn : float, optional
        Median and minimum seconds per frame (from :func:`time_frames`).
    repeats : int, optional
        Timed frames.
    threads : int or str, optional
    bytes_per_vertex : float, optional
        What the method must move per vertex and frame.
    note : str
        One phrase for the table.
    reason : str
        Non-empty: the row was skipped, and why (one line).
    """
    row = {"size": int(size), "dtype": dtype, "method": method, "kind": kind,
           "status": "skipped" if reason else "ok", "reason": reason, "repeats": repeats,
           "ns_per_vertex": None, "min_ns_per_vertex": None, "threads": threads,
           "bytes_per_vertex": bytes_per_vertex, "bandwidth_gbs": bandwidth["gbs"],
           "bound_ns_per_vertex": None, "ratio_to_bound": None, "stat": "median",
           "note": note}
    if med is not None:
        row["ns_per_vertex"] = med * 1e9 / size
        row["min_ns_per_vertex"] = mn * 1e9 / size
    if bytes_per_vertex is not None:
        row["bound_ns_per_vertex"] = bytes_per_vertex / bandwidth["gbs"]   # B / (GB/s) = ns
        if row["ns_per_vertex"] is not None:
            row["ratio_to_bound"] = row["ns_per_vertex"] / row["bound_ns_per_vertex"]
    return row


def _dtype_name(d) -> str:
    try:
        return np.dtype(d).name
    except TypeError:
        return str(d)


def _check_choices(sizes, bones, influences, dtypes, repeats, methods) -> tuple:
    sizes = tuple(int(s) for s in sizes)
    if not sizes or min(sizes) < 1:
        raise ValueError(f"sizes must be positive vertex counts, got {list(sizes)}")
    if int(bones) < 1:
        raise ValueError(f"bones must be >= 1, got {bones}")
    if not 1 <= int(influences) <= int(bones):
        raise ValueError(f"influences must be in 1..bones ({bones}), got {influences}")
    dtypes = tuple(_dtype_name(d) for d in dtypes)
    bad = [d for d in dtypes if d not in DTYPES]
    if bad or not dtypes:
        raise ValueError(f"dtypes must be among {list(DTYPES)}, got {list(dtypes)}")
    if repeats is not None and int(repeats) < 1:
        raise ValueError(f"repeats must be >= 1, got {repeats}")
    bad = [m for m in methods if m not in METHODS]
    if bad:
        raise ValueError(f"methods must be among {list(METHODS)}, got {bad}")
    return sizes, int(bones), int(influences), dtypes


def run_bench(sizes: Sequence[int] = DEFAULT_SIZES, bones: int = 20, influences: int = 4,
              dtypes: Sequence[str] = DTYPES, repeats: int | None = None, peers: bool = True,
              seed: int = 0, *, methods: Sequence[str] = METHODS, bandwidth: dict | None = None,
              extra_peers: Sequence[Peer] = (), log: Log = quiet) -> list[dict]:
    """Time every method (and peers) per vertex count and dtype.

    Parameters
    ----------
    sizes : sequence of int
        Vertex counts.
    bones, influences : int
        Bones in the random forest; non-zero weights per vertex.
    dtypes : sequence of {"float64", "float32"}
        Storage dtypes (our kernels compute in float64 either way).
    repeats : int, optional
        Timed frames per row after 2 warm-up frames; default :func:`auto_repeats`.
    peers : bool
        Also time the NumPy and SciPy peers (:data:`PEERS`).
    seed : int
        Rig and pose seed.
    methods : sequence of str
        Subset of ``METHODS``.
    bandwidth : dict, optional
        From :func:`measure_bandwidth`; measured here when omitted.
    extra_peers : sequence of Peer
        More peers, each called once per (size, dtype) after the others (see :data:`Peer`).
    log : callable
        Progress messages.

    Returns
    -------
    list of dict, one per (size, dtype, method or peer) (:func:`make_row`). Keys:
    ``size``, ``dtype``, ``method``, ``kind`` ("stbs" or "peer"), ``status`` ("ok" or
    "skipped") and ``reason``, ``ns_per_vertex`` (median) and ``min_ns_per_vertex``,
    ``repeats``, ``threads``, ``bytes_per_vertex``, ``bandwidth_gbs``,
    ``bound_ns_per_vertex``, ``ratio_to_bound``, ``note``; for our methods also
    ``input_bytes``, ``deformer_nbytes``, ``nbytes_over_input``, ``build_s``,
    ``build_peak_bytes`` and ``frame_peak_bytes``.

    Raises
    ------
    ValueError
        For an empty or non-positive size, influences outside 1..bones, an unknown
        dtype or method, before anything is timed.
    """
    import numba as nb

    sizes, bones, influences, dtypes = _check_choices(sizes, bones, influences, dtypes,
                                                      repeats, methods)
    bw = bandwidth if bandwidth is not None else measure_bandwidth()
    threads = int(nb.get_num_threads())
    rows: list[dict] = []
    for n in sizes:
        reps = int(repeats) if repeats is not None else auto_repeats(n)
        log(f"{n:,} vertices: building the rig")
        rig = make_rig(n, bones, influences, seed)
        for dtype in dtypes:
            dt = np.dtype(dtype)
            V_in = rig.V if dt == np.float64 else rig.V.astype(dt)
            for method in methods:
                log(f"{n:,} {dtype} {method}")
                rows.append(_method_row(rig, V_in, method, reps, bw, threads))
            if peers:
                rows.append(_numpy_lbs_row(rig, V_in, reps, bw, log))
                rows.append(_scipy_lbs_row(rig, V_in, reps, bw, log))
            for peer in extra_peers:
                rows.append(peer(rig, V_in, reps, bw, log))
    return rows


def _method_row(rig: BenchRig, V_in: np.ndarray, method: str, reps: int, bw: dict,
                threads: int) -> dict:
    """One of our methods: memory while building, per frame, and the frame time."""
    n, dt = rig.n, V_in.dtype
    isz = dt.itemsize
    uses_e = method.startswith("stbs")
    W, E = rig.W, (rig.E if uses_e else None)
    dfm, build_peak, build_s = _traced_peak(
        lambda: Deformer(V_in, rig.sk, W, E, method=method, dtype=dt))
    lay, pose = dfm.layout, rig.pose
    buf = np.empty((n, 3), dtype=dt)
    dfm(pose, out=buf)  # compile (or load) the kernel before tracing
    _, frame_peak, _ = _traced_peak(lambda: dfm(pose, out=buf))
    med, mn = time_frames(lambda: dfm(pose, out=buf), reps)
    k = lay.k
    # per vertex: V (3 values), idx, w, e where used, the output written (3 values)
    bpv = (3 * isz + k * (lay.idx.itemsize + lay.w.itemsize)
           + (k * lay.e.itemsize if uses_e and lay.e is not None else 0) + 3 * isz)
    inp = V_in.nbytes + csr_bytes(W) + (csr_bytes(E) if uses_e else 0)
    row = make_row(n, str(dt), method, "stbs", bw, med=med, mn=mn, repeats=reps,
                   threads=threads, bytes_per_vertex=bpv, note=f"k={k}, idx {lay.idx.dtype}")
    row.update(input_bytes=int(inp), deformer_nbytes=int(dfm.nbytes),
               nbytes_over_input=dfm.nbytes / inp, build_s=build_s,
               build_peak_bytes=build_peak, frame_peak_bytes=frame_peak)
    return row


def _numpy_lbs_row(rig: BenchRig, V_in: np.ndarray, reps: int, bw: dict, log: Log) -> dict:
    n, k, dt = rig.n, rig.idx.shape[1], V_in.dtype
    log(f"{n:,} {dt} numpy-lbs")
    w = rig.w.astype(dt)
    med, mn = time_frames(lambda: numpy_lbs(V_in, rig.idx, w, lbs_affines(rig.pose)), reps)
    return make_row(n, str(dt), "numpy-lbs", "peer", bw, med=med, mn=mn, repeats=reps,
                    threads=1,
                    bytes_per_vertex=3 * dt.itemsize + k * (8 + dt.itemsize) + 3 * dt.itemsize,
                    note="einsum over top-k (int64 idx); temporaries not counted")


def _scipy_lbs_row(rig: BenchRig, V_in: np.ndarray, reps: int, bw: dict, log: Log) -> dict:
    n, dt = rig.n, V_in.dtype
    log(f"{n:,} {dt} scipy-lbs")
    L = lbs_matrix_sparse(V_in, rig.idx, rig.w.astype(dt), rig.sk.n_bones)
    med, mn = time_frames(lambda: L @ stacked_transforms(lbs_affines(rig.pose)).astype(dt),
                          reps)
    return make_row(n, str(dt), "scipy-lbs", "peer", bw, med=med, mn=mn, repeats=reps,
                    threads=1, bytes_per_vertex=csr_bytes(L) / n + 3 * dt.itemsize,
                    note="sparse (n, 4b) CSR LBS matrix @ T")


# --------------------------------------------------------------------------- report
def _fmt(x, spec: str) -> str:
    return "-" if x is None else format(x, spec)


def _mb(x) -> str:
    return "-" if x is None else f"{x / 1e6:.1f}"


def format_table(rows: Sequence[dict], machine: dict | None = None,
                 bandwidth: dict | None = None) -> str:
    """A plain-text report: timings (ours and peers), then our methods' memory.

    Rows with a ``detail`` (how a peer was built) add one line each under the table.
    """
    lines = machine_lines(machine, f"numba {machine.get('numba_threads')} threads; "
                          f"Python {machine.get('python')}, NumPy {machine.get('numpy')}, "
                          f"numba {machine.get('numba')}" + "".join(
                              f", {k} {v}" for k, v in machine.get("peer_versions", {}).items()),
                          "figures") if machine else []
    if bandwidth:
        lines.append(f"memory bandwidth: {bandwidth['gbs']:.1f} GB/s, triad a = b + s c on "
                     f"{bandwidth['triad_threads']} threads, {bandwidth['array_bytes'] / 2**20:.0f}"
                     f" MiB arrays (NumPy copy on 1 thread: {bandwidth['copy_gbs']:.1f} GB/s); "
                     f"{bandwidth['counted']}")
    elif rows:
        lines.append(f"memory bandwidth: {rows[0]['bandwidth_gbs']:.1f} GB/s")
    lines.append("ns/vertex: median over the timed frames after warm-up (JIT excluded); "
                 "bound = bytes per vertex / bandwidth; x bound = ns/vertex / bound")
    lines.append("")
    head = (f"{'size':>10}  {'dtype':<8} {'method':<10} {'ns/vertex':>9} {'min':>7} "
            f"{'x bound':>7} {'B/vertex':>8} {'bound':>6} {'reps':>4}  {'threads':<12} note")
    lines += [head, "-" * len(head)]
    last = None
    for r in rows:
        key = (r["size"], r["dtype"])
        if last is not None and key != last:
            lines.append("")
        last = key
        if r["status"] != "ok":
            lines.append(f"{r['size']:>10,}  {r['dtype']:<8} {r['method']:<10} "
                         f"skipped: {r['reason']}")
            continue
        lines.append(
            f"{r['size']:>10,}  {r['dtype']:<8} {r['method']:<10} "
            f"{_fmt(r['ns_per_vertex'], '9.2f')} {_fmt(r['min_ns_per_vertex'], '7.2f')} "
            f"{_fmt(r['ratio_to_bound'], '7.2f')} {_fmt(r['bytes_per_vertex'], '8.0f')} "
            f"{_fmt(r['bound_ns_per_vertex'], '6.2f')} {_fmt(r['repeats'], '4d')}  "
            f"{r['threads']!s:<12} {r['note']}")
    details = dict.fromkeys(f"{r['method']}: {r['detail']}" for r in rows if r.get("detail"))
    if details:
        lines += [""] + list(details)
    mem = [r for r in rows if r["kind"] == "stbs" and r["status"] == "ok"]
    if mem:
        lines += ["", "memory (MB; tracemalloc peaks are new allocations while running):"]
        head = (f"{'size':>10}  {'dtype':<8} {'method':<10} {'input':>8} {'Deformer':>9} "
                f"{'ratio':>6} {'build peak':>10} {'build s':>8} {'frame peak':>10}")
        lines += [head, "-" * len(head)]
        for r in mem:
            lines.append(
                f"{r['size']:>10,}  {r['dtype']:<8} {r['method']:<10} {_mb(r['input_bytes']):>8} "
                f"{_mb(r['deformer_nbytes']):>9} {r['nbytes_over_input']:6.2f} "
                f"{_mb(r['build_peak_bytes']):>10} {r['build_s']:8.2f} "
                f"{_mb(r['frame_peak_bytes']):>10}")
        lines.append("input = V + W (CSR) + E (CSR, stbs methods); ratio = Deformer / input")
    return "\n".join(lines)


# --------------------------------------------------------------------------- command line
_SIZE = re.compile(r"^\s*(\d+(?:\.\d+)?)\s*([kKmM]?)\s*$")


def _parse_sizes(text: str) -> tuple[int, ...]:
    out = []
    for part in str(text).split(","):
        m = _SIZE.match(part)
        if not m:
            raise argparse.ArgumentTypeError(
                f"sizes must be a comma-separated list of vertex counts such as "
                f"10k,100k,1M, got {part.strip()!r}")
        val = float(m.group(1)) * {"": 1, "k": 1e3, "m": 1e6}[m.group(2).lower()]
        if val < 1 or val != math.floor(val):
            raise argparse.ArgumentTypeError(
                f"sizes must be whole vertex counts >= 1, got {part.strip()!r}")
        out.append(int(val))
    return tuple(out)


def _choice_list(name: str, choices: tuple[str, ...]):
    """An argparse type: a comma-separated list of ``choices``."""
    def parse(text: str) -> tuple[str, ...]:
        out = tuple(s.strip() for s in str(text).split(","))
        bad = [s for s in out if s not in choices]
        if bad:
            raise argparse.ArgumentTypeError(f"{name} must be a comma-separated list from "
                                             f"{', '.join(choices)}, got {bad[0]!r}")
        return out
    return parse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add ``stbs bench``'s options to ``parser``."""
    parser.add_argument("--sizes", type=_parse_sizes, default=DEFAULT_SIZES,
                        help="vertex counts, k and M suffixes allowed (default 10k,100k,1M)")
    parser.add_argument("--bones", type=positive_int, default=20,
                        help="bones in the random skeleton (default 20)")
    parser.add_argument("--influences", type=positive_int, default=4,
                        help="non-zero bone weights per vertex (default 4)")
    parser.add_argument("--dtype", type=_choice_list("dtype", DTYPES), default=DTYPES,
                        help="storage dtypes: float64,float32 (default both)")
    parser.add_argument("--methods", type=_choice_list("methods", METHODS), default=METHODS,
                        help="methods to time (default lbs,dqs,stbs-lbs,stbs-dqs)")
    parser.add_argument("--repeats", type=positive_int, default=None,
                        help="timed frames per row after 2 warm-up frames "
                             "(default 10..300 by size)")
    parser.add_argument("--seed", type=int, default=0, help="rig and pose seed (default 0)")
    parser.add_argument("--no-peers", action="store_true",
                        help="skip the NumPy and SciPy peers")
    parser.add_argument("--json", metavar="OUT.json", default=None,
                        help="also write the machine, bandwidth, settings and rows as JSON "
                             "(written to a temporary file, then renamed)")


def collect(args: argparse.Namespace, *, extra_peers: Sequence[Peer] = (),
            log: Log = quiet) -> dict:
    """Run the benchmark for parsed ``args`` (:func:`add_arguments`).

    Returns
    -------
    dict
        The JSON document: ``schema``, ``benchmark`` ("skinning"), ``machine``,
        ``bandwidth``, ``settings``, ``rows``.

    Raises
    ------
    ValueError
        For inconsistent options (influences > bones), before anything is timed.
    """
    sizes, bones, influences, dtypes = _check_choices(args.sizes, args.bones, args.influences,
                                                      args.dtype, args.repeats, args.methods)
    machine = machine_info()
    log("measuring memory bandwidth")
    bw = measure_bandwidth()
    rows = run_bench(sizes, bones, influences, dtypes, args.repeats,
                     peers=not args.no_peers, seed=args.seed, methods=args.methods,
                     bandwidth=bw, extra_peers=extra_peers, log=log)
    machine["peak_rss_bytes"] = peak_rss_bytes()
    return {"schema": 1, "benchmark": "skinning", "machine": machine, "bandwidth": bw,
            "settings": {"sizes": list(sizes), "bones": bones, "influences": influences,
                         "dtypes": list(dtypes), "methods": list(args.methods),
                         "repeats": args.repeats, "seed": args.seed, "warmup": WARMUP,
                         "stat": "median"},
            "rows": rows}


def print_report(doc: dict) -> None:
    """Print the table of a :func:`collect` document and the process's peak memory."""
    print(format_table(doc["rows"], doc["machine"], doc["bandwidth"]))
    rss = doc["machine"].get("peak_rss_bytes")
    if rss:
        print(f"\npeak resident memory of this process: {rss / 1e6:.0f} MB")


def run(args: argparse.Namespace) -> int:
    """Run the benchmark for parsed ``args``; print the table; return 0.

    Raises
    ------
    ValueError
        For inconsistent options (influences > bones) or an unusable ``--json`` path,
        before anything is timed.
    """
    out = check_json_path(args.json)

    def log(msg: str) -> None:
        print(f"stbs bench: {msg}", file=sys.stderr, flush=True)

    doc = collect(args, log=log)
    print_report(doc)
    if out is not None:
        write_json(out, doc)
        log(f"wrote {out}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m stbs.bench [options]``: the same as ``stbs bench``; returns the exit
    status (2 and one line on stderr for a bad option)."""
    p = argparse.ArgumentParser(prog="stbs bench", description=__doc__.splitlines()[0])
    add_arguments(p)
    args = p.parse_args(argv)
    try:
        return run(args)
    except ValueError as exc:
        print(f"stbs bench: error: {exc}", file=sys.stderr)
        return 2
