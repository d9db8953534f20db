"""Skinning throughput beside libigl's: ``stbs bench`` plus two libigl peers, one run.

Builds the same random rigs and times them the same way as ``stbs bench`` (it
imports :mod:`stbs.bench`), adding, per size and dtype:

- ``igl-lbs``: libigl's ``igl.lbs_matrix(V, W)`` (dense, precomputed) times the
  stacked transforms, ``M @ T`` (only the product is per frame); needs libigl's
  Python binding (``pip install 'stbs-skinning[bench]'``);
- ``igl-dqs``: libigl's C++ ``igl::dqs`` through our harness ``igl_dqs/bench_dqs.cpp``,
  compiled here (once, cached) against header-only libigl and Eigen (rigid DQS only:
  libigl has no stretch or twist). Needs a C++17 compiler and the headers:
  ``--libigl-include`` / ``LIBIGL_INCLUDE`` (the ``include/`` folder of a libigl
  checkout) and ``--eigen-include`` / ``EIGEN_INCLUDE`` (else the usual system
  folders, e.g. Debian's ``libeigen3-dev``). Without them it says so in one line and
  is skipped.

Before timing, each peer that runs is checked against ``stbs.deform`` on a small
rig (``--no-check`` skips this). The report ends with the project's speed targets
(``speed_targets.py``). Nothing is downloaded unless ``--download-libigl`` is given
(it looks for libigl's headers in the installed libigl version's sdist on PyPI, once).

Usage::

    python benchmarks/skinning_vs_igl.py --sizes 1M --dtype float64
    LIBIGL_INCLUDE=~/src/libigl/include python benchmarks/skinning_vs_igl.py --json out.json

Every ``stbs bench`` option applies (``--help``). Docs: ``docs/benchmarks.md``.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import re
import shutil
import subprocess
import sys
import tarfile
import tempfile
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

import stbs
from speed_targets import format_targets, skinning_targets
from stbs import bench
from stbs import transforms as tf
from stbs.bench.report import check_json_path, write_json

PROG = "skinning_vs_igl"
HARNESS = Path(__file__).resolve().parent / "igl_dqs" / "bench_dqs.cpp"
#: Where Eigen (``include/eigen3``) and libigl (``include/igl``) are looked for after the
#: given folders and the environment variables.
SYSTEM_PREFIXES = ["/usr/local", "/usr", "/opt/homebrew"]
FLAGS = ("-O3", "-march=native", "-DNDEBUG", "-std=c++17", "-pthread")
NEEDS = ("needs libigl's C++ headers (--libigl-include or LIBIGL_INCLUDE: the include/ "
         "folder of a libigl checkout) and Eigen's (--eigen-include or EIGEN_INCLUDE; "
         "Debian: apt-get install libeigen3-dev)")

Log = Callable[[str], None]


def _quiet(msg: str) -> None:
    pass


def cache_dir() -> Path:
    """Where the compiled harness (and headers fetched by --download-libigl) are kept."""
    if os.environ.get("STBS_CACHE"):
        return Path(os.environ["STBS_CACHE"])
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "stbs"


def libigl_version() -> str | None:
    """The installed libigl Python binding's version, or None."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("libigl")
    except PackageNotFoundError:
        return None


# --------------------------------------------------------------------------- headers
def _safe_members(tar: tarfile.TarFile, prefix: str) -> list[tarfile.TarInfo]:
    out = []
    for m in tar.getmembers():
        if not m.name.startswith(prefix) or not (m.isfile() or m.isdir()):
            continue
        if m.name.startswith("/") or ".." in Path(m.name).parts:
            continue
        out.append(m)
    return out


def headers_from_sdist(cache: Path, log: Log = _quiet) -> tuple[Path | None, Path | None, str]:
    """libigl (and Eigen) headers from the installed libigl version's sdist on PyPI.

    Only with ``--download-libigl``. Downloaded once with pip; the outcome is
    remembered in ``cache`` so a sdist without headers is not fetched again (libigl
    2.6.3's holds only the binding's sources). Returns (libigl include, Eigen include,
    note).
    """
    ver = libigl_version()
    if ver is None:
        return None, None, ("libigl is not installed (pip install 'stbs-skinning[bench]'), "
                            "so there is no libigl sdist version to look in")
    marker = cache / f"libigl-{ver}-sdist.json"
    if marker.exists():
        info = json.loads(marker.read_text())
        igl = Path(info["libigl"]) if info.get("libigl") else None
        eig = Path(info["eigen"]) if info.get("eigen") else None
        if (igl is None or (igl / "igl" / "dqs.h").exists()) and (
                eig is None or (eig / "Eigen" / "Core").exists()):
            return igl, eig, info["note"]
    log(f"looking for libigl's C++ headers in the libigl {ver} sdist on PyPI "
        f"(once; result kept in {marker})")
    cache.mkdir(parents=True, exist_ok=True)
    igl = eig = None
    with tempfile.TemporaryDirectory(dir=cache) as tmp:
        cmd = [sys.executable, "-m", "pip", "download", "--disable-pip-version-check", "-q",
               "--no-deps", "--no-binary", "libigl", f"libigl=={ver}", "-d", tmp]
        try:
            proc = subprocess.run(cmd, capture_output=True, text=True, timeout=900)
        except (OSError, subprocess.TimeoutExpired) as exc:
            return None, None, f"pip download of the libigl {ver} sdist failed: {exc}"
        tars = sorted(Path(tmp).glob("libigl-*.tar.gz"))
        if proc.returncode != 0 or not tars:
            last = (proc.stderr.strip().splitlines() or ["no sdist"])[-1]
            return None, None, f"pip download of the libigl {ver} sdist failed: {last}"
        with tarfile.open(tars[0]) as tar:
            names = tar.getnames()
            dqs = [s for s in names if s.endswith("include/igl/dqs.h")]
            core = [s for s in names if s.endswith("Eigen/Core")]
            dest = cache / f"libigl-{ver}-sdist"
            for found, depth, kind in ((dqs, len("igl/dqs.h"), "libigl"),
                                       (core, len("Eigen/Core"), "eigen")):
                if not found:
                    continue
                prefix = found[0][: -depth]
                members = _safe_members(tar, prefix)
                if sys.version_info >= (3, 12) or hasattr(tarfile, "data_filter"):
                    tar.extractall(dest, members=members, filter="data")
                else:  # old Pythons; members were vetted above
                    tar.extractall(dest, members=members)  # noqa: S202
                if kind == "libigl":
                    igl = dest / prefix
                else:
                    eig = dest / prefix
    parts = [f"libigl headers from the libigl {ver} sdist: {igl}" if igl else
             f"the libigl {ver} sdist on PyPI has no include/igl/dqs.h (it holds the "
             "Python binding sources; its CMake build fetches libigl's C++ from git)"]
    if eig:
        parts.append(f"Eigen from the sdist: {eig}")
    note = "; ".join(parts)
    marker.write_text(json.dumps({"libigl": str(igl) if igl else None,
                                  "eigen": str(eig) if eig else None, "note": note}))
    return igl, eig, note


def find_headers(libigl: str | None = None, eigen: str | None = None, *,
                 download: bool = False, log: Log = _quiet) -> dict:
    """Locate Eigen's and libigl's include folders for the C++ DQS harness.

    Order: the given folder, else ``EIGEN_INCLUDE`` / ``LIBIGL_INCLUDE``; common system
    folders (``/usr/include/eigen3``, ...); an unpacked copy under the cache
    (``~/.cache/stbs/libigl*/include``); last, only with ``download``, the installed
    libigl version's sdist from PyPI (:func:`headers_from_sdist`).

    Returns
    -------
    dict with ``eigen`` and ``libigl`` (str or None) and ``notes`` (list of str).
    """
    cache = cache_dir()
    notes: list[str] = []

    def first(given: str | None, env: str, cands: Sequence[Path], probe: str) -> Path | None:
        explicit = given or os.environ.get(env)
        if explicit:
            p = Path(explicit).expanduser()
            if (p / probe).exists():
                return p
            notes.append(f"{'the given folder' if given else env} {p} has no {probe}")
        return next((c for c in cands if (c / probe).exists()), None)

    prefixes = [Path(p) for p in (os.environ.get("CONDA_PREFIX"), *SYSTEM_PREFIXES) if p]
    cached = sorted([*cache.glob("libigl*/include"), *cache.glob("libigl*/*/include")],
                    key=lambda p: p.stat().st_mtime, reverse=True)
    eig = first(eigen, "EIGEN_INCLUDE", [p / "include" / "eigen3" for p in prefixes]
                + sorted(cache.glob("eigen*")), "Eigen/Core")
    igl = first(libigl, "LIBIGL_INCLUDE", [p / "include" for p in prefixes] + cached,
                "igl/dqs.h")
    if (igl is None or eig is None) and download:
        igl2, eig2, note = headers_from_sdist(cache, log)
        notes.append(note)
        igl = igl or igl2
        eig = eig or eig2
    return {"eigen": str(eig) if eig else None, "libigl": str(igl) if igl else None,
            "notes": notes}


# --------------------------------------------------------------------------- the harness
def _compiler() -> str | None:
    cxx = os.environ.get("CXX")
    if cxx:
        return shutil.which(cxx)
    return next((p for p in map(shutil.which, ("g++", "c++", "clang++")) if p), None)


def _dqs_variant(libigl_include: Path) -> str:
    """Which igl::dqs these headers hold. Since May 2025 (libigl #2390) it flips each
    bone's quaternion by the sign of its dot product with the running sum, a chain
    of dependent dot products per vertex; before, it summed them unflipped."""
    try:
        text = (libigl_include / "igl" / "dqs.cpp").read_text(errors="replace")
    except OSError:
        return "igl::dqs (dqs.cpp not found)"
    if re.search(r"\.dot\(\s*vQ\[", text):
        return "igl::dqs with the per-bone hemisphere test (libigl from May 2025)"
    return "igl::dqs without a hemisphere test (libigl before May 2025)"


def build_igl_dqs(libigl: str | None = None, eigen: str | None = None, *,
                  download: bool = False, log: Log = _quiet) -> tuple[Path | None, str]:
    """Compile (once, cached by source, flags, compiler and libigl's dqs.cpp) the harness.

    Returns
    -------
    (path to the executable, what it was built from) or (None, why not, one line).
    """
    if not HARNESS.exists():
        return None, f"the harness source {HARNESS} is missing"
    cxx = _compiler()
    if cxx is None:
        return None, "needs a C++17 compiler (g++, c++ or clang++; or set CXX)"
    found = find_headers(libigl, eigen, download=download, log=log)
    if not found["libigl"] or not found["eigen"]:
        absent = " and ".join(n for n, k in (("libigl", "libigl"), ("Eigen", "eigen"))
                              if not found[k])
        return None, "; ".join([f"no {absent} headers found: {NEEDS}", *found["notes"]])
    cmd = [cxx, *FLAGS, f"-I{found['eigen']}", f"-I{found['libigl']}", str(HARNESS)]
    try:
        ver = subprocess.run([cxx, "--version"], capture_output=True, text=True,
                             timeout=60).stdout
    except (OSError, subprocess.TimeoutExpired):
        ver = ""
    h = hashlib.sha256()
    for part in (HARNESS.read_bytes(), " ".join(cmd).encode(), ver.encode()):
        h.update(part)
    for inc in (Path(found["libigl"]) / "igl" / "dqs.cpp",
                Path(found["libigl"]) / "igl" / "parallel_for.h"):
        if inc.exists():
            h.update(inc.read_bytes())
    out_dir = cache_dir() / "igl_dqs" / h.hexdigest()[:16]
    exe = out_dir / "bench_dqs"
    built = (f"{_dqs_variant(Path(found['libigl']))}; libigl headers {found['libigl']}, "
             f"Eigen {found['eigen']}; {Path(cxx).name} {' '.join(FLAGS)}")
    if exe.exists():
        return exe, built
    out_dir.mkdir(parents=True, exist_ok=True)
    log(f"compiling the libigl C++ DQS harness: {' '.join(cmd)}")
    tmp = out_dir / f".bench_dqs.{os.getpid()}"
    try:
        proc = subprocess.run([*cmd, "-o", str(tmp)], capture_output=True, text=True,
                              timeout=600)
    except (OSError, subprocess.TimeoutExpired) as exc:
        return None, f"compiling {HARNESS.name} failed: {exc}"
    if proc.returncode != 0:
        err = [s for s in proc.stderr.splitlines() if "error" in s] or proc.stderr.splitlines()
        tmp.unlink(missing_ok=True)
        return None, f"compiling {HARNESS.name} failed: {(err or ['?'])[0].strip()}"
    os.replace(tmp, exe)
    (out_dir / "command.txt").write_text(" ".join(cmd) + "\n" + ver)
    return exe, built


def _write_dqs_rig(path: Path, V: np.ndarray, idx: np.ndarray, w: np.ndarray,
                   pose: stbs.Pose) -> None:
    """The harness input (format in bench_dqs.cpp): rigid part of ``pose`` as (Q, T)."""
    n, k = idx.shape
    R = pose.rotations
    Q = tf.matrix_to_quat(R)                                  # (w, x, y, z)
    T = pose.origins - np.einsum("bij,bj->bi", R, pose.skeleton.A)   # x -> R x + T
    with open(path, "wb") as f:
        f.write(b"STBSDQS1")
        f.write(np.array([n, pose.skeleton.n_bones, k], dtype="<i8").tobytes())
        for X, dt in ((V, "<f8"), (idx, "<i4"), (w, "<f8"), (Q, "<f8"), (T, "<f8")):
            f.write(np.ascontiguousarray(X, dtype=dt).tobytes())


def igl_dqs_deform(exe: Path, V: np.ndarray, idx: np.ndarray, w: np.ndarray,
                   pose: stbs.Pose, *, repeats: int = 1, single: bool = False,
                   want_output: bool = False) -> tuple[dict, np.ndarray | None]:
    """Run the compiled harness on this rig: libigl's ``igl::dqs`` with the rigid part
    (``R_i``, ``a'_i - R_i a_i``) of each bone; stretch and twist are not libigl's.

    Returns
    -------
    (the harness's JSON report, U (n, 3) float64 or None)
    """
    with tempfile.TemporaryDirectory() as tmp:
        rig = Path(tmp) / "rig.bin"
        _write_dqs_rig(rig, V, idx, w, pose)
        cmd = [str(exe), str(rig), "--repeats", str(int(repeats))]
        if single:
            cmd.append("--float")
        if want_output:
            cmd += ["--out", str(Path(tmp) / "U.bin")]
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=3600)
        if proc.returncode != 0:
            raise RuntimeError(f"{exe.name} failed: {proc.stderr.strip()}")
        report = json.loads(proc.stdout.strip().splitlines()[-1])
        U = (np.fromfile(Path(tmp) / "U.bin", dtype="<f8").reshape(-1, 3)
             if want_output else None)
    return report, U


# --------------------------------------------------------------------------- the peers
def igl_lbs_peer(igl_mod, reason: str = "") -> bench.Peer:
    """The ``igl-lbs`` row maker for :func:`stbs.bench.run_bench` (``igl_mod`` None: a
    skipped row saying ``reason``)."""
    def peer(rig: bench.BenchRig, V_in: np.ndarray, reps: int, bw: dict, log: Log) -> dict:
        n, dt = rig.n, V_in.dtype
        if igl_mod is None:
            return bench.make_row(n, str(dt), "igl-lbs", "peer", bw, reason=reason)
        log(f"{n:,} {dt} igl-lbs")
        M = igl_mod.lbs_matrix(rig.V, rig.W_dense())  # precompute, not timed
        note = "igl.lbs_matrix (dense) @ T, numpy matmul (BLAS)"
        if dt != np.float64:
            M = M.astype(dt)
            note += "; igl builds M in float64, cast to float32"
        out = np.empty((n, 3), dtype=dt)
        med, mn = bench.time_frames(lambda: np.matmul(
            M, bench.stacked_transforms(bench.lbs_affines(rig.pose)).astype(dt), out=out),
            reps)
        return bench.make_row(n, str(dt), "igl-lbs", "peer", bw, med=med, mn=mn,
                              repeats=reps, threads=f"BLAS<={os.cpu_count()}",
                              bytes_per_vertex=(M.shape[1] + 3) * dt.itemsize, note=note)
    return peer


def igl_dqs_peer(exe: Path | None, info: str) -> bench.Peer:
    """The ``igl-dqs`` row maker (``exe`` None: a skipped row saying ``info``, why not)."""
    def peer(rig: bench.BenchRig, V_in: np.ndarray, reps: int, bw: dict, log: Log) -> dict:
        n, b, dt = rig.n, rig.sk.n_bones, V_in.dtype
        if exe is None:
            return bench.make_row(n, str(dt), "igl-dqs", "peer", bw, reason=info)
        log(f"{n:,} {dt} igl-dqs (C++)")
        try:
            rep, _ = igl_dqs_deform(exe, rig.V, rig.idx, rig.w, rig.pose, repeats=reps,
                                    single=dt == np.float32)
        except (OSError, RuntimeError, subprocess.TimeoutExpired, ValueError) as exc:
            return bench.make_row(n, str(dt), "igl-dqs", "peer", bw,
                                  reason=f"the harness failed: {exc}")
        row = bench.make_row(n, str(dt), "igl-dqs", "peer", bw, repeats=reps,
                             threads=rep["threads"], bytes_per_vertex=(3 + b + 3) * dt.itemsize,
                             note=f"C++ igl::dqs, rigid only, dense W (#V by {b}), "
                                  f"Eigen {rep.get('eigen')}")
        row["detail"] = info
        row["ns_per_vertex"] = float(rep["median_ns_per_vertex"])
        row["min_ns_per_vertex"] = float(rep["min_ns_per_vertex"])
        row["ratio_to_bound"] = row["ns_per_vertex"] / row["bound_ns_per_vertex"]
        return row
    return peer


def check_peers(igl_mod, exe: Path | None, *, atol: float = 1e-9) -> list[str]:
    """Each available peer against ``stbs.deform`` on a 600-vertex rig: one line each.

    ``igl-lbs`` against ``lbs`` with the full pose; ``igl-dqs`` against ``dqs`` with a
    rigid pose (no stretch or twist) whose rotations stay under 1.2 rad, where
    libigl's running-sum sign rule and our pivot rule agree.

    Raises
    ------
    RuntimeError
        A peer's result differs from ours by more than ``atol``.
    """
    rig = bench.make_rig(600, bones=20, influences=4, seed=3)
    lines = []
    if igl_mod is not None:
        U = stbs.deform(rig.V, rig.sk, rig.pose, rig.W, method="lbs")
        M = igl_mod.lbs_matrix(rig.V, rig.W_dense())
        d = float(np.abs(M @ bench.stacked_transforms(bench.lbs_affines(rig.pose)) - U).max())
        if not d <= atol:
            raise RuntimeError(f"igl-lbs differs from stbs lbs by {d:.2e} (> {atol:g})")
        lines.append(f"check: igl-lbs equals stbs lbs on {rig.n} vertices "
                     f"(max |dU| {d:.1e})")
    if exe is not None:
        pose = bench.make_pose(rig.sk, 5, stretch=False, twist=False)
        _, U_igl = igl_dqs_deform(exe, rig.V, rig.idx, rig.w, pose, want_output=True)
        U = stbs.deform(rig.V, rig.sk, pose, rig.W, method="dqs")
        d = float(np.abs(U_igl - U).max())
        if not d <= atol:
            raise RuntimeError(f"igl-dqs differs from stbs dqs by {d:.2e} (> {atol:g})")
        lines.append(f"check: igl-dqs equals stbs dqs on {rig.n} vertices, rigid pose "
                     f"(max |dU| {d:.1e})")
    return lines


# --------------------------------------------------------------------------- command line
def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog=f"python benchmarks/{PROG}.py",
        description=__doc__.split("\n\n")[0],
        epilog="examples:\n"
               f"  python benchmarks/{PROG}.py --sizes 1M --dtype float64\n"
               f"  python benchmarks/{PROG}.py --libigl-include ~/src/libigl/include "
               "--json skinning.json\n\n"
               "igl-lbs needs libigl's Python binding (pip install 'stbs-skinning[bench]');\n"
               f"igl-dqs {NEEDS}.",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    bench.add_arguments(p)
    p.add_argument("--libigl-include", metavar="DIR", default=None,
                   help="libigl's include/ folder (default: LIBIGL_INCLUDE, then system "
                        "folders)")
    p.add_argument("--eigen-include", metavar="DIR", default=None,
                   help="Eigen's include folder (default: EIGEN_INCLUDE, then "
                        "/usr/include/eigen3 and other system folders)")
    p.add_argument("--download-libigl", action="store_true",
                   help="if no libigl headers are found, look in the installed libigl "
                        "version's sdist on PyPI (pip download, once; network)")
    p.add_argument("--no-igl", action="store_true", help="skip both libigl peers")
    p.add_argument("--no-check", action="store_true",
                   help="skip checking the peers against stbs.deform before timing")
    return p


def prepare(args: argparse.Namespace, log: Log) -> tuple[list[bench.Peer], list[str], object,
                                                         Path | None]:
    """The libigl peers for this run: (peers, one line per skipped peer, igl, exe)."""
    if args.no_igl:
        return [], [], None, None
    skipped = []
    why_lbs = "needs libigl's Python binding: pip install 'stbs-skinning[bench]'"
    try:
        import igl as igl_mod
    except ImportError:
        igl_mod = None
        skipped.append(f"igl-lbs skipped: {why_lbs}")
    exe, info = build_igl_dqs(args.libigl_include, args.eigen_include,
                              download=args.download_libigl, log=log)
    if exe is None:
        skipped.append(f"igl-dqs skipped: {info}")
    peers = [igl_lbs_peer(igl_mod, why_lbs), igl_dqs_peer(exe, info)]
    return peers, skipped, igl_mod, exe


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)

    def log(msg: str) -> None:
        print(f"{PROG}: {msg}", file=sys.stderr, flush=True)

    try:
        out = check_json_path(args.json)
        peers, skipped, igl_mod, exe = prepare(args, log)
        for line in skipped:
            print(f"{PROG}: {line}", file=sys.stderr)
        if not args.no_check:
            for line in check_peers(igl_mod, exe):
                log(line)
        doc = bench.collect(args, extra_peers=peers, log=log)
    except (ValueError, RuntimeError, OSError) as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 2
    ver = libigl_version()
    if ver:
        doc["machine"]["peer_versions"] = {"libigl": ver}
    doc["targets"] = skinning_targets(doc["rows"])
    bench.print_report(doc)
    lines = format_targets(doc["targets"])
    if lines:
        print("\n" + "\n".join(lines))
    if out is not None:
        write_json(out, doc)
        log(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
