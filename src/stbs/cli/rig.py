"""``stbs rig``: a bare mesh and skeleton in, a complete STBS rig (.npz) out."""

from __future__ import annotations

import argparse
import math
import sys
import time

from ..methods import BONE_METHODS as BONE
from ..methods import ENDPOINT_METHODS as ENDPOINT

NAME = "rig"
HELP = "compute bone and endpoint weights for a mesh and skeleton; write a .npz rig"
EXAMPLE = "stbs rig arm.obj arm.tgf -o arm.npz --bone bbw --endpoint bbw"
DESCRIPTION = """\
Turn a bare mesh and skeleton into a complete STBS rig (paper §2.3, §3):
  1. meshing with the skeleton inside (--bone bbw, --endpoint bbw): a 2D mesh's
     outline is re-triangulated with the bones as constrained segments; a 3D surface
     (any: open, in parts, self-intersecting, non-manifold) gets a volume mesh of its
     inside by winding number, edges about --tet-size long (default: about 12,000
     vertices, finer in the hands), with the joints and bone samples inside as
     vertices, and the weights are interpolated to the surface's vertices (--tets
     winding); --tets conforming tetrahedralizes a closed, clean surface through its
     own vertices instead; --tets auto (default) takes conforming for such a surface
     of up to 10,000 vertices that holds the skeleton, else winding; --tets FILE reads
     a tetrahedral mesh (surface vertices first, as in libigl's .mesh files). Bone
     heat (--bone heat) works on the 3D surface, or a tetrahedral mesh's boundary.
     With the winding volume the parts of the skeleton outside the shape are left
     out with a warning naming the bones; in 2D and with --tets conforming that is an
     error unless --clip-skeleton;
  2. bone weights W: bounded biharmonic weights or bone heat;
  3. endpoint weights E: projection (eq. 8), idw (eq. 9), heat, bbw (direct) or
     bbw-joints, each solved only where the bone's weight exceeds 1e-7.
The BBW solves stop at a KKT residual of --tol (default 1e-6, weights within about
1e-5 of the exact solution; --tol 1e-10 for the exact one).
The rig keeps your mesh's vertices and faces in their order (weights of the inserted
vertices are dropped) and is written atomically. Time per stage is printed on stderr.
A 2D shape may also come as an outline, and the rig then keeps stbs's triangle mesh:
a Triangle .poly file, or an image (paper §4, Fig. 12) whose shape, alpha above
--threshold (or luma; --invert for dark on light), is traced. Image coordinates are
pixels with y up: pixel (row r, column c) of an H-row image is at (c, H - 1 - r), and
the skeleton is given in them.
--keep-volume keeps the volume mesh the weights were solved on in the rig file (a 3D
surface's tetrahedra, or a 2D mesh's re-triangulation with the bones inside), so that
BBW endpoint weights can be solved again later, e.g. in the viewer."""
EPILOG = f"""examples:
  {EXAMPLE}
  stbs rig woody.obj woody.tgf -o woody.npz            # 2D: bbw + bbw endpoint weights
  stbs rig arm.obj arm.tgf -o arm.npz --bone heat --endpoint heat
  stbs rig drawing.png drawing.tgf -o drawing.npz --clip-skeleton   # 2D, from a picture"""

#: The rig pipeline's choices (BONE, ENDPOINT: from the import-free stbs.methods) and
#: default KKT tolerance (stbs.rig.build), repeated here so that building the parser
#: imports nothing heavy; a test checks they agree.
DEFAULT_TOL = 1e-6


def add_tol_argument(p: argparse.ArgumentParser) -> None:
    p.add_argument("--tol", type=float, default=None, metavar="T",
                   help=f"KKT tolerance of the BBW solves (--bone bbw, --endpoint bbw or "
                        f"bbw-joints), in weight units (default: {DEFAULT_TOL:g}; 1e-10 "
                        f"gives the exact QP solution, up to 1.5x slower)")


def add_clip_argument(p: argparse.ArgumentParser) -> None:
    p.add_argument("--clip-skeleton", action="store_true",
                   help="bbw, when stbs meshes the shape (2D, or 3D with --tets conforming): "
                        "mesh only the skeleton's parts inside it (for bone tips poking out of "
                        "the skin or past a traced image's edge); without it a joint outside "
                        "is an error. 3D --tets auto always does so (with a warning)")


def add_tets_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--tets", default="auto", metavar="auto|winding|conforming|FILE",
                   help="3D bbw: the volume the weights are solved on: a volume mesh of the "
                        "surface's inside by winding number, weights interpolated to the "
                        "surface (winding: any surface); tetrahedra through a closed, clean "
                        "surface's own vertices (conforming); auto: conforming for such a "
                        "surface of up to 10,000 vertices holding the skeleton, else (or with "
                        "--tet-size) winding; or read tets from FILE")
    p.add_argument("--tet-size", type=float, default=None, metavar="H",
                   help="--tets auto/winding: the winding-number volume mesh's edge length, "
                        "in the mesh's units (default: about 12,000 vertices, finer in the "
                        "hands)")


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
    p.add_argument("mesh", metavar="MESH",
                   help="rest mesh: .obj .off .ply .stl .mesh .msh .vtk; or a 2D outline: a "
                        "Triangle .poly file, or an image (.png .jpg ...) whose shape is traced")
    p.add_argument("skeleton", metavar="SKELETON", help="skeleton: .tgf .bf")
    p.add_argument("-o", "--output", required=True, metavar="RIG.npz", help="output rig (.npz)")
    p.add_argument("--bone", choices=BONE, default="bbw", help="bone weights (default: bbw)")
    p.add_argument("--endpoint", choices=ENDPOINT, default="bbw",
                   help="endpoint weights (default: bbw)")
    add_tets_arguments(p)
    add_clip_argument(p)
    p.add_argument("--threshold", type=float, default=None, metavar="T",
                   help="image MESH: the shape is where alpha (or, without alpha, the luma) "
                        "exceeds T, in [0, 1] (default 0.5)")
    p.add_argument("--max-area", type=float, default=None, metavar="A",
                   help="outline MESH: largest triangle area, in the outline's units (pixels "
                        f"squared for an image; default: the shape's area / "
                        f"{OUTLINE_TRIANGLES})")
    p.add_argument("--invert", action="store_true",
                   help="image MESH: the shape is where the value is below --threshold (a "
                        "dark shape on a light background)")
    p.add_argument("--keep-volume", action="store_true",
                   help="keep the volume mesh the weights were solved on in the rig (a 3D "
                        "surface's tetrahedra, built even for --bone heat with --endpoint "
                        "heat/projection/idw; a 2D mesh's re-triangulation), so that BBW "
                        "endpoint weights can be solved again later (the viewer)")
    add_tol_argument(p)


class _Stages:
    """Times each stage; on a terminal also says which stage is running.

    Progress lines go to stderr only when it is a terminal, so a failed run in a
    script or CI still prints exactly one error line.
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

    def progress(self, stage: str, done: int, total: int) -> None:
        """A :func:`stbs.build_rig` progress callback: times each stage it reports."""
        now = time.perf_counter()
        if total == 0 and done == 0:
            self._close(now)
            self._open = (stage, now)
            if self.live:
                print(f"stbs rig: {stage} ...", file=sys.stderr, flush=True)
                self._bar_fn = self._bar(stage)
            return
        if self.live:
            self._bar_fn(done, total)

    def _close(self, now: float) -> None:
        if getattr(self, "_open", None) is not None:
            label, t0 = self._open
            self.times.append((label, now - t0))
            if self.live:
                print(file=sys.stderr, flush=True)
            self._open = None

    def pipeline(self, fn, *a, **kw):
        """Run ``fn(*a, progress=self.progress, **kw)``, timing the stages it reports."""
        try:
            return fn(*a, progress=self.progress, **kw)
        finally:
            self._close(time.perf_counter())

    def summary(self) -> str:
        total = sum(t for _, t in self.times)
        rows = [f"  {label:<28} {t:8.2f} s" for label, t in self.times]
        return "\n".join(["stbs rig: time per stage", *rows, f"  {'total':<28} {total:8.2f} s"])


#: --tets values that mesh the surface (the others name a file): build_rig's ``volume``.
TETS_MESHERS = {"auto": "auto", "winding": "winding", "conforming": "conforming"}
#: MESH files that are a 2D shape's outline (stbs.rig.pipeline's, repeated so that
#: building the parser imports nothing heavy; a test checks they agree).
IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg", ".bmp", ".gif", ".tif", ".tiff", ".webp")
OUTLINE_EXTENSIONS = (".poly", *IMAGE_EXTENSIONS)
OUTLINE_TRIANGLES = 4000


def check_tet_size(tet_size: float | None, tets: str) -> float | None:
    """``--tet-size``: a positive number, with ``--tets auto`` only."""
    from ._errors import CommandError

    if tet_size is None:
        return None
    if not (math.isfinite(tet_size) and tet_size > 0):
        raise CommandError(f"--tet-size: expected a positive number, got {tet_size!r}")
    if tets not in ("auto", "winding"):
        raise CommandError(f"--tet-size applies to --tets auto or winding (the winding-number "
                           f"volume mesh), got --tets {tets}")
    return float(tet_size)


def check_methods(V, F, T, *, bone: str, endpoint: str, tets: str, mesh_name: str,
                  clip_skeleton: bool = False, W=None) -> None:
    """The flags checked against the mesh, before any work (one-line errors)."""
    from ._errors import CommandError

    meshes = T is None and tets in TETS_MESHERS and (
        (bone == "bbw" and W is None) or (V.shape[1] == 3 and endpoint in ("bbw", "bbw-joints")))
    if clip_skeleton and not meshes:
        raise CommandError("--clip-skeleton applies when stbs meshes the shape itself "
                           "(--bone bbw: a 2D mesh, or a 3D surface with --tets auto, "
                           "winding or conforming)")
    if bone == "heat" and (V.shape[1] != 3 or (F is None and T is None)):
        raise CommandError(f"--bone heat needs a 3D triangle surface or tetrahedra; "
                           f"{mesh_name!r} is {V.shape[1]}D"
                           + ("" if F is not None else " without triangles"))
    if endpoint == "heat" and (V.shape[1] != 3 or (F is None and T is None)):
        raise CommandError("--endpoint heat needs a 3D triangle surface or tetrahedra")
    if bone == "bbw" and W is None and V.shape[1] == 2 and F is None:
        raise CommandError(f"{mesh_name!r}: a 2D rig needs triangles to take the outline from")
    if bone == "bbw" and W is None and V.shape[1] == 3 and T is None and F is None:
        raise CommandError(f"{mesh_name!r}: a 3D rig needs a triangle surface or tetrahedra")


def build(st: _Stages, V, F, T, sk, *, bone: str, endpoint: str, tets: str, mesh_name: str,
          tol: float = DEFAULT_TOL, clip_skeleton: bool = False, meshed: bool = False, W=None,
          tet_size: float | None = None, keep_volume: bool = False):
    """:func:`stbs.rig.rig_from_mesh` for the command line: the flags checked,
    ``--tets FILE`` read, the stages timed; returns the rig (weights restricted to ``V``)."""
    from ..io import read_mesh
    from ..rig import rig_from_mesh
    from ._errors import CommandError

    tet_size = check_tet_size(tet_size, tets)
    check_methods(V, F, T, bone=bone, endpoint=endpoint, tets=tets, mesh_name=mesh_name,
                  clip_skeleton=clip_skeleton, W=W)
    volume = TETS_MESHERS.get(tets, "auto")
    if tets not in TETS_MESHERS and W is None and bone == "bbw":
        tm = st.run("read tets", read_mesh, tets)
        n = len(V)
        if tm.T is None or len(tm.V) < n or not (tm.V[:n] == V).all():
            raise CommandError(f"--tets {tets!r}: expected tetrahedra whose first "
                               f"{n} vertices are the surface {mesh_name!r}'s, in order")
        volume = (tm.V, tm.T)
    return st.pipeline(rig_from_mesh, V, sk, F=F, T=T, W=W, bone=bone, endpoint=endpoint,
                       tol=tol, clip_skeleton=clip_skeleton, remesh=not meshed, tets=volume,
                       tet_size=tet_size, keep_volume=keep_volume)


def check_output(path: str, *, gltf: bool = False):
    from pathlib import Path

    from ._errors import CommandError

    out = Path(path)
    allowed = (".npz", ".gltf", ".glb") if gltf else (".npz",)
    if out.suffix.lower() not in allowed:
        raise CommandError(f"output {path!r}: expected a rig file "
                           f"({' '.join(allowed)})")
    if not (out.parent if str(out.parent) else Path(".")).is_dir():
        raise CommandError(f"output {path!r}: folder {str(out.parent)!r} does not exist")
    return out


def requires(args: argparse.Namespace) -> list[str]:
    """Optional modules this run needs: Pillow for an image MESH."""
    return ["PIL"] if args.mesh.lower().endswith(IMAGE_EXTENSIONS) else []


def rig_from_files(st: _Stages, mesh: str, skeleton: str, *, bone: str, endpoint: str,
                   tets: str, tol: float, clip_skeleton: bool, threshold: float = 0.5,
                   invert: bool = False, max_area: float | None = None,
                   tet_size: float | None = None, keep_volume: bool = False):
    """MESH (a mesh, a ``.poly`` outline or a picture) and SKELETON files -> a rig
    (:func:`stbs.rig.rig_from_files`), the flags checked and the stages timed."""
    from ..io import read_mesh, read_skeleton
    from ..rig import rig_from_files as from_files
    from ._errors import CommandError

    if mesh.lower().endswith(OUTLINE_EXTENSIONS):
        if bone != "bbw":
            raise CommandError(f"--bone {bone} needs a 3D surface; an outline "
                               f"({mesh!r}) is rigged with --bone bbw")
        return st.pipeline(from_files, mesh, skeleton, bone=bone, endpoint=endpoint, tol=tol,
                           clip_skeleton=clip_skeleton, threshold=threshold, invert=invert,
                           max_area=max_area)
    m = st.run("read mesh", read_mesh, mesh)
    sk = st.run("read skeleton", read_skeleton, skeleton, dim=m.V.shape[1])
    return build(st, m.V, m.F, m.T, sk, bone=bone, endpoint=endpoint, tets=tets,
                 mesh_name=mesh, tol=tol, clip_skeleton=clip_skeleton, tet_size=tet_size,
                 keep_volume=keep_volume)


def run(args: argparse.Namespace) -> int:
    from ..io import save_rig
    from ._errors import CommandError

    out = check_output(args.output)
    tol = resolve_tol(args.tol, args.bone, args.endpoint)
    st = _Stages()
    outline = args.mesh.lower().endswith(OUTLINE_EXTENSIONS)
    if not outline and (args.threshold is not None or args.invert):
        raise CommandError("--threshold and --invert apply to an image MESH "
                           f"({' '.join(IMAGE_EXTENSIONS)}); got {args.mesh!r}")
    if not outline and args.max_area is not None:
        raise CommandError(f"--max-area applies to an outline MESH (.poly or an image); got "
                           f"{args.mesh!r}, whose own vertices are kept")
    if args.max_area is not None and not (math.isfinite(args.max_area) and args.max_area > 0):
        raise CommandError(f"--max-area: expected a positive number, got {args.max_area!r}")
    rig = rig_from_files(st, args.mesh, args.skeleton, bone=args.bone, endpoint=args.endpoint,
                         tets=args.tets, tol=tol, clip_skeleton=args.clip_skeleton,
                         tet_size=args.tet_size,
                         threshold=0.5 if args.threshold is None else args.threshold,
                         invert=args.invert, max_area=args.max_area,
                         keep_volume=args.keep_volume)
    st.run("write rig", save_rig, out, rig)
    print(st.summary(), file=sys.stderr)
    kept = "" if rig.volume is None else (f"; kept its volume mesh of "
                                          f"{len(rig.volume.V)} vertices")
    print(f"wrote {out}: {len(rig.V)} vertices, {rig.skeleton.n_bones} bones ({args.bone} bone "
          f"weights, {args.endpoint} endpoint weights{kept})")
    return 0
