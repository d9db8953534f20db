"""``stbs rig``: a bare mesh and skeleton in, a complete STBS rig (.npz) out."""

from __future__ import annotations

import argparse
import math
import sys
import time

NAME = "rig"
HELP = "compute bone and endpoint weights for a mesh and skeleton; write a .npz rig"
EXAMPLE = "stbs rig arm.obj arm.tgf -o arm.npz --bone bbw --endpoint bbw"
DESCRIPTION = """\
Turn a bare mesh and skeleton into a complete STBS rig (paper §2.3, §3):
  1. meshing with the skeleton inside (--bone bbw): a 2D mesh's outline is
     re-triangulated with the bones as constrained segments, a closed 3D surface is
     tetrahedralized with the joints and bone samples inserted (--tets auto), or a
     tetrahedral mesh is read (--tets FILE, surface vertices first, as in libigl's
     .mesh files); bone heat (--bone heat) works on the 3D surface itself.
     A skeleton poking out of the shape is an error unless --clip-skeleton; a
     self-intersecting surface is meshed by the builtin mesher (by winding number);
  2. bone weights W: bounded biharmonic weights or bone heat;
  3. endpoint weights E: projection (eq. 8), idw (eq. 9), heat, bbw (direct) or
     bbw-joints, each solved only where the bone's weight exceeds 1e-7.
The BBW solves stop at a KKT residual of --tol (default 1e-6, weights within about
1e-5 of the exact solution; --tol 1e-10 for the exact one).
The rig keeps your mesh's vertices and faces in their order (weights of the inserted
vertices are dropped) and is written atomically. Time per stage is printed on stderr."""
EPILOG = f"""examples:
  {EXAMPLE}
  stbs rig woody.obj woody.tgf -o woody.npz            # 2D: bbw + bbw endpoint weights
  stbs rig arm.obj arm.tgf -o arm.npz --bone heat --endpoint heat"""

BONE = ("bbw", "heat")
ENDPOINT = ("bbw", "bbw-joints", "heat", "projection", "idw")
#: KKT tolerance of the command's BBW solves: weights within about 1e-5 of the exact QP
#: solution (measured: 2e-7 to 3e-6 on the benchmark meshes), up to 1.5x faster than 1e-10
DEFAULT_TOL = 1e-6


def add_tol_argument(p: argparse.ArgumentParser) -> None:
    p.add_argument("--tol", type=float, default=None, metavar="T",
                   help=f"KKT tolerance of the BBW solves (--bone bbw, --endpoint bbw or "
                        f"bbw-joints), in weight units (default: {DEFAULT_TOL:g}; 1e-10 "
                        f"gives the exact QP solution, up to 1.5x slower)")


def add_clip_argument(p: argparse.ArgumentParser) -> None:
    p.add_argument("--clip-skeleton", action="store_true",
                   help="bbw, when stbs meshes the shape (2D, or 3D with --tets auto): mesh "
                        "only the skeleton's parts inside it (for bone tips poking out of the "
                        "skin or past a traced image's edge); without it a joint outside is "
                        "an error")


def resolve_tol(tol: float | None, bone: str, endpoint: str) -> float:
    """The ``--tol`` value checked against the methods it applies to."""
    from ._errors import CommandError

    if tol is None:
        return DEFAULT_TOL
    if not (math.isfinite(tol) and tol > 0):
        raise CommandError(f"--tol: expected a positive number, got {tol!r}")
    if bone != "bbw" and endpoint not in ("bbw", "bbw-joints"):
        raise CommandError(f"--tol applies to --bone bbw or --endpoint bbw/bbw-joints; "
                           f"got --bone {bone} --endpoint {endpoint}")
    return float(tol)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("mesh", metavar="MESH", help="rest mesh: .obj .off .ply .stl .mesh .msh .vtk")
    p.add_argument("skeleton", metavar="SKELETON", help="skeleton: .tgf .bf")
    p.add_argument("-o", "--output", required=True, metavar="RIG.npz", help="output rig (.npz)")
    p.add_argument("--bone", choices=BONE, default="bbw", help="bone weights (default: bbw)")
    p.add_argument("--endpoint", choices=ENDPOINT, default="bbw",
                   help="endpoint weights (default: bbw)")
    p.add_argument("--tets", default="auto", metavar="auto|FILE",
                   help="3D bbw: tetrahedralize the surface (auto) or read tets from FILE")
    add_clip_argument(p)
    add_tol_argument(p)


class _Stages:
    """Times each stage; on a terminal also says which stage is running.

    Progress lines go to stderr only when it is a terminal, so a failed run in a
    script or CI still prints exactly one error line (DESIGN §6).
    """

    def __init__(self) -> None:
        self.times: list[tuple[str, float]] = []
        self.live = sys.stderr.isatty()

    def run(self, label: str, fn, *a, bar: bool = False, **kw):
        """Run ``fn(*a, **kw)`` as a timed stage; ``bar``: pass it a ``progress`` callback."""
        if self.live:
            print(f"stbs rig: {label} ...", file=sys.stderr, flush=True)
        if bar:
            kw["progress"] = self._bar(label) if self.live else None
        t = time.perf_counter()
        out = fn(*a, **kw)
        self.times.append((label, time.perf_counter() - t))
        if bar and self.live:
            print(file=sys.stderr, flush=True)
        return out

    @staticmethod
    def _bar(label: str, width: int = 30):
        t0 = time.perf_counter()

        def progress(done: int, total: int) -> None:
            k = int(width * done / max(total, 1))
            print(f"\r  {label}: [{'#' * k}{'.' * (width - k)}] {done}/{total} "
                  f"{time.perf_counter() - t0:6.1f} s", end="", file=sys.stderr, flush=True)

        return progress

    def summary(self) -> str:
        total = sum(t for _, t in self.times)
        rows = [f"  {label:<28} {t:8.2f} s" for label, t in self.times]
        return "\n".join(["stbs rig: time per stage", *rows, f"  {'total':<28} {total:8.2f} s"])


def compute_weights(st: _Stages, V, F, T, sk, *, bone: str, endpoint: str, tets: str,
                    mesh_name: str, tol: float = DEFAULT_TOL, clip_skeleton: bool = False):
    """Bone and endpoint weights (n, b) of the rest mesh (V, F, T); see DESCRIPTION.

    Returns W, E and whether the rig keeps the mesh's own tetrahedra.
    """
    from ..io import read_mesh
    from ..meshing import tetrahedralize, triangulate_2d
    from ..weights import bone_heat, bone_weights, endpoint_weights
    from ._errors import CommandError

    n = len(V)
    if clip_skeleton and (bone != "bbw" or tets != "auto" or T is not None):
        raise CommandError("--clip-skeleton applies when stbs meshes the shape itself "
                           "(--bone bbw: a 2D mesh, or a 3D surface with --tets auto)")
    if bone == "heat":
        if V.shape[1] != 3 or F is None:
            raise CommandError(f"--bone heat needs a 3D triangle surface; {mesh_name!r} is "
                               f"{V.shape[1]}D" + ("" if F is not None else " without triangles"))
        W = st.run("bone heat", bone_heat, V, F, sk)
        Vm, Fm, Tm, Wm = V, F, None, W
    else:
        if V.shape[1] == 2:
            if F is None:
                raise CommandError(f"{mesh_name!r}: a 2D rig needs triangles to take the "
                                   "outline from")
            tri = st.run("triangulate (bones inside)", triangulate_2d, (V, F), sk,
                         clip_skeleton=clip_skeleton)
            Vm, Fm, Tm = tri.V, tri.F, None
        elif T is not None and tets == "auto":
            Vm, Fm, Tm = V, F, T
        elif tets != "auto":
            tm = st.run("read tets", read_mesh, tets)
            if tm.T is None or len(tm.V) < n or not (tm.V[:n] == V).all():
                raise CommandError(f"--tets {tets!r}: expected tetrahedra whose first "
                                   f"{n} vertices are the surface {mesh_name!r}'s, in order")
            Vm, Fm, Tm = tm.V, F, tm.T
        else:
            if F is None:
                raise CommandError(f"{mesh_name!r}: a 3D rig needs a closed triangle surface")
            tet = st.run("tetrahedralize (bones inside)", tetrahedralize, V, F, sk,
                         clip_skeleton=clip_skeleton)
            Vm, Fm, Tm = tet.V, F, tet.T
        Wm = st.run("bone weights (bbw)", bone_weights, Vm, sk, method="bbw",
                    F=Fm if Tm is None else None, T=Tm, tol=tol, bar=True)
        W = Wm[:n]
    elem = dict(T=Tm) if Tm is not None else dict(F=Fm)
    if endpoint == "heat":
        if V.shape[1] != 3 or F is None:
            raise CommandError("--endpoint heat needs a 3D triangle surface")
        E = st.run("endpoint weights (heat)", endpoint_weights, V, sk, method="heat", W=W, F=F)
    elif endpoint in ("projection", "idw"):
        E = st.run(f"endpoint weights ({endpoint})", endpoint_weights, V, sk, method=endpoint)
    else:
        E = st.run(f"endpoint weights ({endpoint})", endpoint_weights, Vm, sk,
                   method=endpoint, W=Wm, bar=True, **elem, **_tol_kw(endpoint, tol))[:n]
    return W, E, Tm is T and T is not None


def _tol_kw(endpoint: str, tol: float) -> dict:
    return {"tol": tol} if endpoint in ("bbw", "bbw-joints") else {}


def check_output(path: str):
    from pathlib import Path

    from ._errors import CommandError

    out = Path(path)
    if out.suffix.lower() != ".npz":
        raise CommandError(f"output {path!r}: expected a .npz rig file")
    if not (out.parent if str(out.parent) else Path(".")).is_dir():
        raise CommandError(f"output {path!r}: folder {str(out.parent)!r} does not exist")
    return out


def run(args: argparse.Namespace) -> int:
    from ..io import Rig, read_mesh, read_skeleton, save_rig

    out = check_output(args.output)
    tol = resolve_tol(args.tol, args.bone, args.endpoint)
    st = _Stages()
    mesh = st.run("read mesh", read_mesh, args.mesh)
    V, F, T = mesh.V, mesh.F, mesh.T
    sk = st.run("read skeleton", read_skeleton, args.skeleton, dim=V.shape[1])
    W, E, keep_T = compute_weights(st, V, F, T, sk, bone=args.bone, endpoint=args.endpoint,
                                   tets=args.tets, mesh_name=args.mesh, tol=tol,
                                   clip_skeleton=args.clip_skeleton)
    rig = Rig(V=V, F=F, T=T if keep_T else None, C=sk.C, BE=sk.BE, names=sk.names,
              W=W, E=E, meta={"bone": args.bone, "endpoint": args.endpoint})
    st.run("write rig", save_rig, out, rig)
    print(st.summary(), file=sys.stderr)
    print(f"wrote {out}: {len(V)} vertices, {sk.n_bones} bones ({args.bone} bone weights, "
          f"{args.endpoint} endpoint weights)")
    return 0
