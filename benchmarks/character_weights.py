"""Bone and endpoint BBW of a real character, per stage: the winding-number volume mesh,
the Laplacian and bilaplacian, the factorizations, the bounded QP solves, and the
transfer of the weights to the character's own vertices.

The stages are those of ``stbs.build_rig(V, sk, F=F, volume="winding")`` (what
``stbs weights CHARACTER --bone bbw --endpoint bbw`` runs on a character), called one
by one with the library's public pieces so each is timed on its own:

=====================  ===============================================================
volume mesh            :func:`stbs.meshing.volume_mesh` (winding numbers, Delaunay)
transfer matrix        :meth:`VolumeMesh.interpolation` at the character's vertices
laplacian              ``BBWSolver(V, T)``: cotangent Laplacian, mass, ``Q = L M^-1 L``
factor                 sparse Cholesky factorizations (``last_report.seconds``)
qp                     the bounded solves (``last_report.seconds``, factor excluded)
endpoint (wall)        :func:`stbs.weights.endpoint.bbw_endpoint`, one restricted solve
                       per bone, on the cores (its laplacian / factor / qp are summed
                       over the bones, so they may add up to more than the wall time)
transfer               ``W = P Wv``, ``E = P Ev``
=====================  ===============================================================

``--subdivide K`` splits every triangle into four, K times, before timing: the same
character with 4^K times the triangles, to show that the cost follows the shape and
not the surface's resolution. Usage::

    python benchmarks/character_weights.py threejs_Xbot.glb
    python benchmarks/character_weights.py threejs_Xbot.glb --subdivide 1 --json xbot.json

Docs: ``docs/benchmarks.md`` (figures), ``docs/bbw.md`` (the method).
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from stbs.bench.report import check_json_path, machine_lines, write_json
from stbs.bench.weights import machine_info

PROG = "character_weights"


def subdivide(V, F, times: int):
    """Every triangle split into four at its edges' midpoints, ``times`` times."""
    for _ in range(times):
        E = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
        uniq, inv = np.unique(E, axis=0, return_inverse=True)
        mid = V.shape[0] + np.ravel(inv).reshape(3, -1).T        # (f, 3): edges 01 12 20
        V = np.vstack([V, V[uniq].mean(axis=1)])
        a, b, c = F.T
        ab, bc, ca = mid.T
        F = np.concatenate([np.c_[a, ab, ca], np.c_[ab, b, bc], np.c_[ca, bc, c],
                            np.c_[ab, bc, ca]])
    return V, F


class _Clock:
    """Sums the Laplacian, factor and QP seconds of every BBWSolver made while open."""

    def __enter__(self):
        from stbs.weights.bbw import BBWSolver

        self.acc = {"laplacian": 0.0, "factor": 0.0, "qp": 0.0}
        self._init, self._solve = BBWSolver.__init__, BBWSolver.solve
        acc, init, solve = self.acc, self._init, self._solve

        def timed_init(s, *a, **k):
            t = time.perf_counter()
            init(s, *a, **k)
            acc["laplacian"] += time.perf_counter() - t

        def timed_solve(s, *a, **k):
            out = solve(s, *a, **k)
            acc["factor"] += s.last_report.seconds["factor"]
            acc["qp"] += s.last_report.seconds["solve"]
            return out

        BBWSolver.__init__, BBWSolver.solve = timed_init, timed_solve
        return self.acc

    def __exit__(self, *exc):
        from stbs.weights.bbw import BBWSolver

        BBWSolver.__init__, BBWSolver.solve = self._init, self._solve


def run_character(path: str, *, subdivisions: int = 0, size: float | None = None,
                  tol: float = 1e-6, log=print) -> dict:
    from stbs.io import read_rig
    from stbs.meshing import volume_mesh
    from stbs.weights.endpoint import bbw_endpoint

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rig = read_rig(path)
    V, F, sk = rig.V, rig.F, rig.skeleton
    V, F = subdivide(V, F, subdivisions)
    row = {"character": Path(path).name, "subdivisions": subdivisions,
           "vertices": int(V.shape[0]), "triangles": int(F.shape[0]), "bones": sk.n_bones}
    log(f"{row['character']}: {V.shape[0]:,} vertices, {F.shape[0]:,} triangles, "
        f"{sk.n_bones} bones")
    s = {}
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        t = time.perf_counter()
        vm = volume_mesh(V, F, sk, size=size)
        s["volume mesh"] = time.perf_counter() - t
        t = time.perf_counter()
        P = vm.interpolation(V)
        s["transfer matrix"] = time.perf_counter() - t
        row.update(volume_vertices=int(vm.V.shape[0]), tetrahedra=int(vm.T.shape[0]),
                   size=vm.size)
        b, bc, _ = vm.boundary_conditions(sk)
        with _Clock() as bone:
            from stbs.weights.bbw import BBWSolver

            solver = BBWSolver(vm.V, vm.T, degenerate="skip")
            Wv = solver.solve(b, bc, tol=tol)
        Wv /= Wv.sum(axis=1, keepdims=True)
        s.update({f"bone {k}": v for k, v in bone.items()})
        with _Clock() as end:
            t = time.perf_counter()
            inside = np.flatnonzero(vm.bone_points(sk) >= 2)
            Ev = bbw_endpoint(vm.V, sk, W=Wv, T=vm.T, tol=tol, bones=inside)
            s["endpoint (wall)"] = time.perf_counter() - t
        s.update({f"endpoint {k} (sum)": v for k, v in end.items()})
        t = time.perf_counter()
        W, E = np.asarray(P @ Wv), np.clip(np.asarray(P @ Ev), 0.0, 1.0)
        s["transfer"] = time.perf_counter() - t
    s["total"] = time.perf_counter() - t0
    row["stages"] = s
    row["warnings"] = len([w for w in said if issubclass(w.category, UserWarning)])
    ref = np.asarray(rig.W)
    if subdivisions == 0 and ref.shape == W.shape:
        row["dominant_bone_agreement"] = float(np.mean(W.argmax(axis=1) == ref.argmax(axis=1)))
    assert np.allclose(W.sum(axis=1), 1.0) and E.min() >= 0 and E.max() <= 1
    return row


def format_row(r: dict) -> list[str]:
    lines = [f"{r['character']} x{4 ** r['subdivisions']} triangles: {r['vertices']:,} "
             f"vertices, {r['bones']} bones -> volume {r['volume_vertices']:,} vertices, "
             f"{r['tetrahedra']:,} tetrahedra (size {r['size']:.3g})"]
    for k, v in r["stages"].items():
        lines.append(f"  {k:<28} {v:8.2f} s")
    if "dominant_bone_agreement" in r:
        lines.append(f"  dominant bone as in the file's own weights: "
                     f"{100 * r['dominant_bone_agreement']:.0f} % of the vertices")
    return lines


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog=PROG, description=__doc__.split("\n\n")[0])
    p.add_argument("characters", nargs="+", metavar="CHARACTER",
                   help="glTF/FBX characters (anything stbs.io.read_rig reads)")
    p.add_argument("--subdivide", type=int, default=0, metavar="K",
                   help="also time each character with its triangles split into 4^K")
    p.add_argument("--size", type=float, default=None, help="volume mesh edge length")
    p.add_argument("--tol", type=float, default=1e-6, help="KKT tolerance (default 1e-6)")
    p.add_argument("--json", default=None, metavar="OUT.json")
    a = p.parse_args(argv)
    try:
        out = check_json_path(a.json)
    except ValueError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 2
    machine = machine_info()
    for line in machine_lines(machine, f"NumPy {machine['numpy']}, SciPy "
                                       f"{machine.get('scipy')}", "the times"):
        print(line)
    print(f"tol {a.tol:g}; stages of stbs.build_rig(volume='winding'), one by one")
    rows = []
    for path in a.characters:
        for k in sorted({0, a.subdivide}):
            r = run_character(path, subdivisions=k, size=a.size, tol=a.tol,
                              log=lambda m: print(m, file=sys.stderr, flush=True))
            rows.append(r)
            print("\n".join(format_row(r)), flush=True)
    if out is not None:
        write_json(out, {"machine": machine, "tol": a.tol, "rows": rows})
    return 0


if __name__ == "__main__":
    sys.exit(main())
