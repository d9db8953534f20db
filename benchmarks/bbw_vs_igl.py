"""Time stbs's bounded biharmonic weights against libigl's ``igl.bbw`` on the same problems.

Usage::

    python benchmarks/bbw_vs_igl.py                 # all cases, 3 functions each
    python benchmarks/bbw_vs_igl.py --cases 2d-5k hand-all --backends cholespy scipy

Each case builds (V, E, b, bc) once; both solvers get exactly the same b and bc. Our
time includes building L, M and Q (``BBWSolver(V, E)``) and the solve, as igl.bbw's
does. Needs ``libigl`` (the ``bench`` extra); the 2D cases need ``triangle`` (else a
coarser grid-based shape is used). Reports the largest |W - W_igl| and both KKT
residuals (``max |w - clip(w - grad / diag Q, 0, 1)|`` over the unknowns).
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np

import stbs
from stbs.io import read_bf, read_mesh, read_tgf
from stbs.io.shared_data import data_dir
from stbs.weights._cholesky import available_backends
from stbs.weights.bbw import BBWSolver
from stbs.weights.boundary import boundary_conditions


def blob_2d(n_target: int):
    """A wavy blob around a 3-bone chain, bones inserted as mesh edges (needs triangle)."""
    import triangle

    t = np.linspace(0, 2 * np.pi, 200, endpoint=False)
    r = 1 + 0.25 * np.sin(3 * t)
    outline = np.c_[2.2 * r * np.cos(t), r * np.sin(t)]
    C = np.array([[-1.5, 0.0], [-0.5, 0.1], [0.5, -0.1], [1.5, 0.0]])
    BE = np.array([[0, 1], [1, 2], [2, 3]])
    s = np.linspace(0, 1, 21)[:, None]
    chain = np.vstack([C[0] + s * (C[1] - C[0])] + [C[i] + s[1:] * (C[i + 1] - C[i])
                                                     for i in (1, 2)])
    pts = np.vstack([outline, chain])
    seg = np.r_[np.c_[np.arange(200), (np.arange(200) + 1) % 200],
                np.c_[np.arange(len(chain) - 1), np.arange(1, len(chain))] + 200]
    area = 2.2 * np.pi / n_target * 0.85
    out = triangle.triangulate({"vertices": pts, "segments": seg}, f"pq30a{area:.10f}")
    return out["vertices"], out["triangles"], stbs.Skeleton(C, BE)


def case(name: str):
    root = data_dir()
    if name in ("2d-5k", "2d-20k"):
        V, F, sk = blob_2d(5000 if name == "2d-5k" else 20000)
        b, bc = boundary_conditions(V, sk, F=F)
        return V, F, b, bc
    if name.startswith("hand"):
        m = read_mesh(root / "libigl-tutorial-data/hand.mesh")
        C, BE = read_tgf(root / "libigl-tutorial-data/hand.tgf")
        b, bc = boundary_conditions(m.V, stbs.Skeleton(C, BE), T=m.T)
        return m.V, m.T, b, bc
    if name in ("fatman", "male"):
        m = read_mesh(root / f"FAST/{name}/mesh.mesh")
        sk = read_bf(root / f"FAST/{name}/bone_roots.bf").skeleton()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")      # these meshes hold no bone samples
            b, bc = boundary_conditions(m.V, sk, T=m.T)
        return m.V, m.T, b, bc
    raise SystemExit(f"unknown case {name!r}")


def kkt(Q, W, b):
    U = np.setdiff1d(np.arange(W.shape[0]), b)
    X = W[U]
    Z = (Q @ W)[U] / Q.diagonal()[U][:, None]
    return float(np.abs(X - np.clip(X - Z, 0, 1)).max())


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cases", nargs="+",
                    default=["2d-5k", "2d-20k", "hand", "hand-all", "fatman"])
    ap.add_argument("--functions", type=int, default=3, help="weight functions (not *-all)")
    ap.add_argument("--backends", nargs="+", default=available_backends())
    ap.add_argument("--tol", type=float, default=1e-10, help="our KKT tolerance")
    ap.add_argument("--no-igl", action="store_true", help="skip igl.bbw (ours only)")
    args = ap.parse_args(argv)
    rows = []
    for name in args.cases:
        V, E, b, bc = case(name)
        if not name.endswith("-all"):
            bc = bc[:, :args.functions]
        label = f"{name} ({V.shape[0]} v, {E.shape[1] == 4 and 'tets' or 'tris'})"
        ours = {}
        for be in args.backends:
            t = time.perf_counter()
            solver = BBWSolver(V, E, backend=be)
            W = solver.solve(b, bc, tol=args.tol)
            ours[be] = (time.perf_counter() - t, W, solver.last_report)
        Q = solver.Q
        res_ours = max(r.kkt_residual.max() for _, _, r in ours.values())
        if args.no_igl:
            t_igl, diff, res_igl = float("nan"), float("nan"), float("nan")
        else:
            import igl

            t = time.perf_counter()
            Wi = igl.bbw(V, E, b, bc)
            t_igl = time.perf_counter() - t
            diff = max(float(np.abs(W - Wi).max()) for _, W, _ in ours.values())
            res_igl = kkt(Q, Wi, b)
        best = min(v[0] for v in ours.values())
        rows.append((label, bc.shape[1], t_igl, {k: v[0] for k, v in ours.items()},
                     t_igl / best, diff, res_ours, res_igl))
        print(f"{label}: m={bc.shape[1]} igl {t_igl:.2f}s, "
              + ", ".join(f"{k} {v[0]:.3f}s" for k, v in ours.items())
              + f", speed-up {t_igl / best:.1f}x, max|dW| {diff:.1e}, "
              f"kkt ours {res_ours:.1e} igl {res_igl:.1e}", flush=True)
        print(ours[args.backends[0]][2])
    print(f"\nstbs tol = {args.tol:g}")
    print("\n| case | m | igl.bbw (s) | " + " | ".join(f"stbs {k} (s)" for k in args.backends)
          + " | speed-up | max abs dW | KKT stbs | KKT igl |")
    print("|---|---|---|" + "---|" * len(args.backends) + "---|---|---|---|")
    for label, m, ti, ts, sp, d, ro, ri in rows:
        print(f"| {label} | {m} | {ti:.2f} | " + " | ".join(f"{ts[k]:.3f}" for k in args.backends)
              + f" | {sp:.1f}x | {d:.1e} | {ro:.0e} | {ri:.0e} |")


if __name__ == "__main__":
    main()
