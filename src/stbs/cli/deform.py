"""``stbs deform``: deform a rigged mesh by a pose file and write the result."""

from __future__ import annotations

import argparse
import os
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..methods import SKINNING_METHODS as METHODS
from ._character import add_character_options, character_options
from ._errors import CommandError

NAME = "deform"
HELP = "deform a rigged mesh by a pose (JSON) and write the result"
EXAMPLE = "stbs deform arm.npz --pose twist.json --method stbs-dqs -o arm-twisted.obj"
OUTPUT_EXTENSIONS = (".obj", ".off", ".ply", ".npz", ".npy", ".png")
#: Pixels of the longer side of a .png picture (--size).
PNG_SIZE = 720

DESCRIPTION = """\
Deform a rigged mesh by a pose and write the deformed mesh.

The rig is either a .npz rig file (stbs.io.save_rig: mesh, skeleton, bone weights W
and optionally endpoint weights E), a glTF 2.0 character (.gltf, .glb: its skin,
and its endpoint weights when it has them), or the three files --mesh, --skeleton and
--weights. --endpoint gives endpoint weights E (and replaces a rig's E). The STBS
methods need E; without it they use projection endpoint weights (paper eq. 8)
and say so on stderr.

The pose is a JSON file naming bones by index or by name (see stbs.io.read_pose):
  {"joints": [[x, y, z], ...], "twist": {"3": [0, 180]}}
  {"rotate": {"2": {"axis": [0, 1, 0], "angle": 90}}, "stretch": {"4": 1.5},
   "twist": {"forearm": [0, 180]}, "translate": [0, 0, 0]}
Angles are in degrees unless the file says "degrees": false.

The output format follows the extension of -o:
  .obj .off .ply  the deformed triangle mesh (for a tetrahedral rig without
                  triangles: the boundary of the tetrahedra)
  .npz            U (n, d) float64 deformed positions, F (f, 3) and/or T (t, 4)
                  when the rig has them, and method (a string)
  .npy            U only
  .png            a picture of the deformed mesh with its posed skeleton; a rig
                  made from an image (stbs rig picture.png ...) is drawn with its
                  picture (needs the demo extra: matplotlib, Pillow)
It is written to a temporary file and renamed, so a failed run leaves nothing
behind; the inputs are only read (an output path equal to an input is refused)."""

EPILOG = f"""\
examples:
  {EXAMPLE}
  stbs deform --mesh arm.obj --skeleton arm.tgf --weights arm-W.dmat \\
      --endpoint arm-E.dmat --pose twist.json --method stbs-lbs -o arm-twisted.ply
  stbs deform drawing.npz --pose wave.json -o drawing-waving.png"""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("rig", nargs="?", metavar="RIG",
                   help="rig file: .npz, or a glTF character .gltf .glb (instead of --mesh, "
                        "--skeleton and --weights)")
    p.add_argument("--pose", required=True, metavar="POSE.json", help="pose file (JSON)")
    p.add_argument("--method", choices=METHODS, default="stbs-dqs",
                   help="skinning method (default: %(default)s)")
    p.add_argument("-o", "--output", required=True, metavar="OUT",
                   help=f"output file: {' '.join(OUTPUT_EXTENSIONS)}")
    g = p.add_argument_group("rig from separate files (instead of RIG.npz)")
    g.add_argument("--mesh", metavar="MESH",
                   help="rest mesh: .obj .off .ply .stl .mesh .msh .vtk (with a character RIG "
                        "alone: the skinned mesh whose skeleton to read, index or name)")
    g.add_argument("--skeleton", metavar="SKEL", help="skeleton: .tgf .bf")
    g.add_argument("--weights", metavar="W", help="bone weights (n, b): .dmat .npy .npz .csv")
    p.add_argument("--endpoint", metavar="E",
                   help="endpoint weights (n, b) in [0, 1]: .dmat .npy .npz .csv")
    p.add_argument("--size", type=int, default=PNG_SIZE, metavar="PX",
                   help="-o .png: pixels of the picture's longer side (default: %(default)s)")
    add_character_options(p, mesh=False)


def requires(args: argparse.Namespace) -> list[str]:
    """Optional modules this run needs: matplotlib and Pillow for a .png picture."""
    return ["matplotlib", "PIL"] if str(args.output).lower().endswith(".png") else []


@dataclass
class _Rig:
    V: Any
    F: Any
    T: Any
    sk: Any
    W: Any
    E: Any
    W_src: str
    E_src: str | None
    E_flag: bool = False  # E came from --endpoint
    texture: Any = None   # a picture rig's picture and texture coordinates
    UV: Any = None


def _output_path(out: str) -> tuple[Path, str]:
    p = Path(out)
    if p.is_dir():
        raise CommandError(f"output {out!r} is a folder; expected a file path")
    ext = p.suffix.lower()
    if ext not in OUTPUT_EXTENSIONS:
        got = f"extension {ext!r}" if ext else "a file without an extension"
        raise CommandError(f"output {out!r}: cannot write {got}; expected one of "
                           f"{', '.join(OUTPUT_EXTENSIONS)}")
    folder = p.parent if str(p.parent) else Path(".")
    if not folder.is_dir():
        raise CommandError(f"output {out!r}: folder {str(folder)!r} does not exist")
    if not os.access(folder, os.W_OK):
        raise CommandError(f"output {out!r}: folder {str(folder)!r} is not writable")
    return p, ext


def _load(args) -> _Rig:
    from ..io import read_mesh, read_rig, read_skeleton, read_weights

    files = {"--mesh": args.mesh, "--skeleton": args.skeleton, "--weights": args.weights}
    if args.rig is not None:
        # with a rig alone, --mesh picks a character's skinned mesh
        pick = args.mesh if args.skeleton is None and args.weights is None else None
        given = [k for k, v in files.items() if v is not None and k != "--mesh" or
                 k == "--mesh" and v is not None and pick is None]
        if given:
            raise CommandError(f"give either a rig file or --mesh, --skeleton and --weights, "
                              f"not both (got {args.rig!r} and {', '.join(given)})")
        rig = read_rig(args.rig, **character_options(args, mesh=pick))
        r = _Rig(rig.V, rig.F, rig.T, rig.skeleton, rig.W, rig.E, f"{args.rig} (W)",
                 None if rig.E is None else f"{args.rig} (E)",
                 texture=rig.texture, UV=rig.UV)
    else:
        missing = [k for k, v in files.items() if v is None]
        if missing:
            raise CommandError("give a rig file, or all of --mesh, --skeleton and --weights "
                              f"(missing {', '.join(missing)})")
        mesh = read_mesh(args.mesh)
        sk = read_skeleton(args.skeleton, dim=mesh.dim)
        W = read_weights(args.weights)
        r = _Rig(mesh.V, mesh.F, mesh.T, sk, W, None, args.weights, None)
    if args.endpoint is not None:
        r.E = read_weights(args.endpoint)
        r.E_src = args.endpoint
        r.E_flag = True
    return r


def _check_shape(src: str, X, n: int, b: int, what: str) -> None:
    shape = tuple(X.shape)
    if shape != (n, b):
        raise CommandError(f"{src}: {what} must have shape ({n}, {b}) (one row per mesh vertex, "
                          f"one column per bone), found {shape}")


def _validate(r: _Rig, method: str) -> None:
    """Check W and E against the mesh and skeleton; name the file in every message."""
    from .. import _checks
    from ..weights.endpoint import projection

    n, b = r.V.shape[0], r.sk.n_bones
    _check_shape(r.W_src, r.W, n, b, "bone weights")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            r.W = _checks.bone_weights(r.W, n, b)
        except ValueError as exc:
            raise CommandError(f"{r.W_src}: {exc}") from None
    for w in caught:
        warnings.warn(f"{r.W_src}: {w.message}", UserWarning, stacklevel=2)
    if r.E is not None:
        _check_shape(r.E_src, r.E, n, b, "endpoint weights")
        try:
            r.E = _checks.endpoint_weights(r.E, n, b)
        except ValueError as exc:
            raise CommandError(f"{r.E_src}: {exc}") from None
        if not method.startswith("stbs") and r.E_flag:
            warnings.warn(f"{r.E_src}: endpoint weights are not used by {method}",
                          UserWarning, stacklevel=2)
    elif method.startswith("stbs"):
        warnings.warn(f"no endpoint weights given; {method} uses projection endpoint "
                      "weights (paper eq. 8)", UserWarning, stacklevel=2)
        r.E = projection(r.V, r.sk)


def _picture(out: Path, U, r: _Rig, pose, method: str, size: int) -> None:
    """The deformed mesh drawn into a PNG (with the rig's picture when it has one)."""
    import numpy as np

    from ..demo.render import Panel, render_panels
    from ..geometry import boundary_faces

    F = r.F if r.F is not None else boundary_faces(r.T, r.V) if r.T is not None else None
    if F is None:
        raise CommandError(f"output {str(out)!r}: a picture needs triangles or tetrahedra; "
                          "the mesh has neither")
    lo, hi = np.min(U, axis=0), np.max(U, axis=0)
    span = np.maximum(hi - lo, 1e-12)
    aspect = float(span[0] / span[1]) if U.shape[1] == 2 else 1.0
    aspect = min(max(aspect, 0.25), 4.0)
    if aspect >= 1:
        wh = (size, max(64, round(size / aspect)))
    else:
        wh = (max(64, round(size * aspect)), size)
    picture = {} if r.texture is None else {"texture": r.texture, "uv": r.UV}
    panel = Panel(V=U, F=F, C=pose.joints(), BE=r.sk.BE, **picture)
    render_panels(out, [panel], panel_size=wh)


def _write(out: Path, ext: str, U, r: _Rig, method: str) -> None:
    import numpy as np

    from ..geometry import boundary_faces
    from ..io import atomic_open, write_mesh

    if ext == ".npz":
        arrays = {"U": np.asarray(U, dtype=np.float64), "method": np.asarray(method)}
        if r.F is not None:
            arrays["F"] = np.asarray(r.F, dtype=np.int64)
        if r.T is not None:
            arrays["T"] = np.asarray(r.T, dtype=np.int64)
        with atomic_open(out, "wb") as f:
            np.savez(f, **arrays)
    elif ext == ".npy":
        with atomic_open(out, "wb") as f:
            np.save(f, np.asarray(U, dtype=np.float64))
    else:
        F = r.F
        if F is None and r.T is not None:
            F = boundary_faces(r.T, r.V)
        elif F is None:
            warnings.warn(f"the mesh has no triangles; {out} holds the vertices only",
                          UserWarning, stacklevel=2)
        write_mesh(out, U, F)


def run(args: argparse.Namespace) -> int:
    from ..io import read_pose
    from ..skinning import deform

    out, ext = _output_path(args.output)
    r = _load(args)
    pose = read_pose(args.pose, r.sk)
    if ext == ".png" and not 64 <= args.size <= 8192:
        raise CommandError(f"--size: expected 64 to 8192 pixels, got {args.size}")
    _validate(r, args.method)
    U = deform(r.V, r.sk, pose, r.W, r.E, method=args.method)
    if ext == ".png":
        _picture(out, U, r, pose, args.method, args.size)
    else:
        _write(out, ext, U, r, args.method)
    print(f"wrote {out}: {U.shape[0]} vertices deformed by {args.method}")
    return 0
