"""``stbs weights``: recompute the weights of an existing rig (.npz)."""

from __future__ import annotations

import argparse
import sys

from ._character import add_character_options
from .rig import BONE, ENDPOINT, add_clip_argument, add_tets_arguments, add_tol_argument

NAME = "weights"
HELP = "recompute a rig's bone and/or endpoint weights; write a rig (.npz or glTF)"
EXAMPLE = "stbs weights arm.npz --endpoint heat -o arm-heat.npz"
DESCRIPTION = """\
Recompute the weights of a rig written by 'stbs rig' or stbs.save_rig, or of a
glTF 2.0 character (.gltf, .glb), with the same methods and meshing as 'stbs rig'
(see 'stbs rig --help'). --bone keep keeps the rig's bone weights W and recomputes
only the endpoint weights E (for --endpoint bbw, solved where each bone's weight
exceeds 1e-7). Characters work as they come: open, in several parts,
self-intersecting, non-manifold, with bones or leaf tails outside the mesh (a warning
names them). A glTF character written back as glTF keeps its file
as it was (skeleton, joint orientations, bone weights, animations, materials) and
gains the endpoint weights (attribute _ENDPOINT_WEIGHTS_0, aligned with JOINTS_0).
The output is written atomically and may be the input file itself."""
EPILOG = f"""examples:
  {EXAMPLE}
  stbs weights woody.npz --bone bbw --endpoint idw -o woody-idw.npz
  stbs weights character.glb --endpoint bbw -o character-stbs.glb"""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("rig", metavar="RIG", help="rig file: .npz, or a glTF character .gltf .glb")
    p.add_argument("-o", "--output", required=True, metavar="OUT",
                   help="output rig: .npz, .gltf or .glb")
    p.add_argument("--bone", choices=(*BONE, "keep"), default="keep",
                   help="bone weights: bbw, heat, or keep the rig's (default: keep)")
    p.add_argument("--endpoint", choices=ENDPOINT, default="bbw",
                   help="endpoint weights (default: bbw)")
    add_tets_arguments(p)
    add_clip_argument(p)
    add_tol_argument(p)
    add_character_options(p)


def run(args: argparse.Namespace) -> int:
    from ..io import read_rig, write_rig
    from ..rig import build_rig
    from ._character import character_options
    from ._errors import CommandError
    from .rig import TETS_MESHERS, _Stages, build, check_output, check_tet_size, resolve_tol

    out = check_output(args.output, gltf=True)
    tol = resolve_tol(args.tol, args.bone, args.endpoint)
    tet_size = check_tet_size(args.tet_size, args.tets)
    if args.bone == "keep" and args.tets not in TETS_MESHERS:
        raise CommandError(f"--tets {args.tets!r}: a tetrahedra file applies when the bone "
                           "weights are recomputed (--bone bbw); with --bone keep use --tets "
                           "auto or conforming")
    st = _Stages()
    rig = st.run("read rig", read_rig, args.rig, **character_options(args))
    sk = rig.skeleton
    if args.bone == "keep":
        # With the bone weights kept, stbs meshes only a 3D surface, for BBW endpoint
        # weights (the winding-number volume leaves the skeleton's parts outside out
        # by itself; --clip-skeleton is for the conforming mesh).
        meshes = rig.T is None and rig.V.shape[1] == 3 and args.endpoint in ("bbw",
                                                                             "bbw-joints")
        if args.clip_skeleton and not meshes:
            raise CommandError("--clip-skeleton applies when stbs meshes the shape: a 3D "
                               "surface with --endpoint bbw or bbw-joints, or --bone bbw")
        new = st.pipeline(build_rig, rig.V, sk, F=rig.F, T=rig.T, W=rig.W,
                          endpoint=args.endpoint, tol=tol, volume=TETS_MESHERS[args.tets],
                          volume_size=tet_size, clip_skeleton=args.clip_skeleton and meshes)
    else:
        new = build(st, rig.V, rig.F, rig.T, sk, bone=args.bone, endpoint=args.endpoint,
                    tets=args.tets, mesh_name=args.rig, tol=tol,
                    clip_skeleton=args.clip_skeleton, tet_size=tet_size)
    meta = dict(rig.meta or {}, endpoint=args.endpoint)
    if args.bone != "keep":
        meta["bone"] = args.bone
    new = new.replace(meta=meta, F=rig.F)
    source = args.rig if args.rig.lower().endswith((".gltf", ".glb")) else None
    st.run("write rig", write_rig, out, new, source=source)
    print(st.summary(), file=sys.stderr)
    print(f"wrote {out}: {len(rig.V)} vertices, {sk.n_bones} bones")
    return 0
