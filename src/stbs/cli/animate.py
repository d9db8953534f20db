"""``stbs animate``: bake a motion (BVH, glTF or FBX animation, clip JSON) on a rig, or a batch
of rigs × motions (``--manifest``) on Dask."""

from __future__ import annotations

import argparse
import sys

from ..methods import SKINNING_METHODS as METHODS
from ._character import add_character_options

NAME = "animate"
HELP = "bake a motion (BVH, glTF, FBX, clip JSON) on a rig into frames (.npz, .glb, meshes)"
EXAMPLE = "stbs animate arm.npz --motion wave.json -o arm-wave.glb"
DESCRIPTION = """\
Bake an animation: the rig (.npz, or a character: glTF .gltf .glb, FBX .fbx) deformed by every
frame of a motion, with the rig's Deformer built once so that each frame costs the
skinning alone. The motion is a clip file (.json, stbs.io.read_clip), a BVH capture
(.bvh, retargeted onto the rig by joint names or --mapping, its twist spread along
the bones with --twist spread), or an animation of a glTF or FBX file of the same
skeleton (the character's own file: CHAR.fbx --motion CHAR.fbx).

Output (-o): a .npz (U (frames, n, d) float32, times, F/T, method), a .glb/.gltf
whose morph targets play the baked frames in any glTF viewer, or a folder (a path
ending in /, or without extension) of one mesh per frame (--mesh-format). Written
atomically; a progress bar and the frames per second go to stderr. A clip .json
instead writes the motion on the rig, not baked (stbs.io.write_clip): a capture
retargeted once, to open with stbs view RIG --motion CLIP.json or to bake later.

A capture is retargeted by body part: the rig's and the capture's joints are read
as pelvis, spine, neck, head, collars, arms and legs from their names (CMU, Mixamo,
Blender, Unreal, Bandai Namco ... conventions) or from the skeleton's shape, rest
postures are matched (a T-pose capture on an A-pose character), and the root's
travel is scaled by the hip heights. --mapping MAP.json ({"rig bone": "capture
joint"}) names every bone's joint instead.

With --manifest BATCH.json, bake many rigs × motions on Dask: the manifest is a
JSON list of {"rig", "motion", "output", "method"} (paths relative to it; also
"fps", "frames", "mapping", "twist", "stretch"; outputs inside its folder unless
--outputs-anywhere). In-process by default, a local cluster of --workers N
processes, or an existing cluster at --scheduler ADDRESS. Each output is named from
a hash of its inputs (OUTPUT-HASH.npz), frames are baked in chunks, and a re-run
skips what is finished and sound, rebakes what is damaged and removes what a killed
run left (see docs/pipelines.md)."""
EPILOG = f"""examples:
  {EXAMPLE}
  stbs animate character.glb --motion 131_01.bvh --frames 0:600:2 -o run.npz
  stbs animate character.glb --motion 131_01.bvh --mapping map.json -o walk.json
  stbs animate arm.npz --motion wave.json --method stbs-lbs -o frames/
  stbs animate --manifest batch.json --workers 2"""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("rig", nargs="?", metavar="RIG", help="rig: .npz, .gltf, .glb or .fbx")
    p.add_argument("--motion", metavar="FILE",
                   help="motion: .bvh, .gltf, .glb, .fbx or clip .json")
    p.add_argument("-o", "--output", metavar="OUT",
                   help="output: .npz, .glb, .gltf or FOLDER/; or a clip .json (not baked)")
    p.add_argument("--method", choices=METHODS, default="stbs-dqs",
                   help="skinning method (default: %(default)s)")
    p.add_argument("--frames", metavar="A:B:STEP", help="bake these of the sampled frames")
    p.add_argument("--fps", type=float, help="sampling rate (default: the motion's)")
    p.add_argument("--max-frames", type=int, metavar="N",
                   help="bake at most N frames (default: as many as fit in 2 GiB of "
                        "frames in memory, at most 36000); more is an error")
    p.add_argument("--animation", metavar="NAME",
                   help="glTF or FBX motion: the animation (stack) to bake")
    p.add_argument("--mapping", metavar="MAP.json",
                   help="BVH motion: {rig bone: capture joint} for every bone (default: by "
                        "body part, from the names or the skeletons' shapes)")
    p.add_argument("--twist", choices=("spread", "joint"), default="spread",
                   help="BVH motion: spread each joint's twist along its bone, or keep it "
                        "at the joint (default: %(default)s)")
    p.add_argument("--stretch", choices=("keep", "match"), default="keep",
                   help="BVH motion: keep bone lengths, or match the source's as stretch "
                        "(default: %(default)s)")
    p.add_argument("--mesh-format", choices=(".obj", ".ply", ".off"), default=".obj",
                   help="folder output: mesh format (default: %(default)s)")
    g = p.add_argument_group("batches on Dask")
    g.add_argument("--manifest", metavar="BATCH.json", help="bake every job of a manifest")
    g.add_argument("--workers", type=int, metavar="N", help="a local cluster of N processes")
    g.add_argument("--scheduler", metavar="ADDRESS", help="an existing Dask cluster")
    g.add_argument("--chunk", type=int, default=64, metavar="FRAMES",
                   help="frames per task (default: %(default)s)")
    g.add_argument("--outputs-anywhere", action="store_true",
                   help="allow outputs outside the manifest's folder")
    add_character_options(p)


def requires(args: argparse.Namespace) -> list[str]:
    need = []
    if args.manifest is not None:
        need.append("dask")
        if args.workers or args.scheduler:
            need.append("distributed")
    for path in (args.rig, args.motion):
        if path and path.lower().endswith(".fbx"):
            need.append("ufbx")
    return need


def _bar(label: str):
    """The progress bar of ``stbs rig``'s stages on a terminal, closed at the end."""
    from .rig import _Stages

    if not sys.stderr.isatty():
        return None
    draw = _Stages._bar(label)

    def progress(done: int, total: int) -> None:
        draw(done, total)
        if done == total:
            print(file=sys.stderr, flush=True)
    return progress


def run(args: argparse.Namespace) -> int:
    from ._errors import CommandError

    if args.manifest is not None:
        single = [k for k in ("rig", "motion", "output", "frames", "fps", "animation",
                              "mapping", "max_frames") if getattr(args, k) is not None]
        if single:
            raise CommandError(f"--manifest gives every job; drop {', '.join(single)} "
                               f"(put them in the manifest's jobs)")
        if args.workers is not None and args.scheduler is not None:
            raise CommandError("give --workers N (a local cluster) or --scheduler ADDRESS, "
                               "not both")
        if args.workers is not None and args.workers < 1:
            raise CommandError(f"--workers: expected 1 or more, got {args.workers}")
        if args.chunk < 1:
            raise CommandError(f"--chunk: expected 1 or more frames, got {args.chunk}")
        from ..bake.batch import run_manifest

        report = run_manifest(args.manifest, workers=args.workers, scheduler=args.scheduler,
                              chunk=args.chunk, outputs_anywhere=args.outputs_anywhere)
        print(report.summary())
        return 0
    missing = [k for k, v in (("RIG", args.rig), ("--motion", args.motion),
                              ("-o", args.output)) if v is None]
    if missing:
        raise CommandError(f"give {', '.join(missing)} (or --manifest BATCH.json)")
    if args.workers is not None or args.scheduler is not None:
        raise CommandError("--workers and --scheduler apply to --manifest")
    if args.mapping is not None and not args.motion.lower().endswith(".bvh"):
        raise CommandError(f"--mapping applies to a .bvh motion (the capture's joints it "
                           f"maps), not {args.motion!r}")
    from ..bake import bake, clip_frames, load_motion, output_kind
    from ..io import read_rig, write_clip
    from ._character import character_options

    as_clip = args.output.lower().endswith(".json")
    if not as_clip:
        output_kind(args.output)
    rig = read_rig(args.rig, **character_options(args))
    clip = load_motion(args.motion, rig, mapping=args.mapping, twist=args.twist,
                       stretch=args.stretch, animation=args.animation)
    if as_clip:
        clip = clip_frames(clip, fps=args.fps, frames=args.frames)
        write_clip(args.output, clip)
        print(f"wrote {args.output}: a clip of {len(clip)} keys over {clip.duration:.2f} s "
              f"({clip.fps:g} fps) of the rig's {rig.skeleton.n_bones} bones")
        return 0
    done = bake(rig, clip, args.output, method=args.method, fps=args.fps, frames=args.frames,
                mesh_format=args.mesh_format, progress=_bar(f"bake ({args.method})"),
                max_frames=args.max_frames)
    print(f"baked {done.frames} frames in {done.total_s:.2f} s ({done.fps:.1f} frames/s; "
          f"the skinning alone {done.skinning_s:.2f} s)", file=sys.stderr)
    print(f"wrote {done.path}: {done.frames} frames of {len(rig.V)} vertices by {args.method}")
    return 0
