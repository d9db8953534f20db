"""``stbs fit``: rigs fitted from examples (:mod:`stbs.fit`), four jobs:

- ``decompose``: a mesh animation into bones, weights and per-frame poses;
- ``endpoints``: a rig's endpoint weights from example meshes in known poses;
- ``weights``: its bone and endpoint weights together from the same;
- ``helpers``: an STBS rig as plain LBS with helper joints (twist bones).
"""

from __future__ import annotations

import argparse
import sys

NAME = "fit"
HELP = "fit rigs to examples: decompose a mesh animation, fit weights, add helper joints"
EXAMPLE = "stbs fit decompose horse.npz --bones 20 -o horse-rig.npz --clip-out horse.json"
DESCRIPTION = """\
Fit rigs to examples.

  decompose  a mesh animation (one .npz with 'frames', optional 'rest' and 'F'; or the
             rest mesh and its frames as mesh files) into bones, bone weights, endpoint
             weights and per-frame rotations, translations, stretches and twists
             (smooth skinning decomposition with stretchable, twistable bones); writes
             the rig and, with --clip-out, the frames' poses as a clip
  endpoints  a rig's endpoint weights from example meshes whose poses are known (the
             keys of a clip, one per frame, in order): an exact bounded least-squares
             solve per vertex
  weights    the rig's bone weights and endpoint weights together from the same:
             sparse (--influences per vertex), bounded and smooth across the surface
  helpers    an STBS rig as plain linear blend skinning with K helper joints per bone
             (twist bones), so that any engine plays its deformation; .glb/.gltf out
             (with --clip, the clip as the helpers' joint animation) or a .npz rig

Every job reports its progress on stderr, takes --seed where it draws random numbers,
and writes its outputs atomically."""
EPILOG = f"""examples:
  {EXAMPLE}
  stbs fit decompose rest.obj f1.obj f2.obj f3.obj --bones 3 -o rig.npz
  stbs fit endpoints arm.npz examples.npz --poses poses.json -o arm-fitted.npz
  stbs fit weights arm.npz examples.npz --poses poses.json --influences 4 -o arm-fitted.npz
  stbs fit helpers arm.npz -k 3 --clip wave.json -o arm-helpers.glb"""

RIG_OUT = (".npz",)
HELPER_OUT = (".npz", ".glb", ".gltf")


def _common(p: argparse.ArgumentParser, *, seed: bool = True,
            methods: tuple[str, ...] = ("stbs-lbs", "stbs-dqs")) -> None:
    p.add_argument("--method", choices=methods, default="stbs-lbs",
                   help="the skinning model fitted (default: stbs-lbs"
                        + ("; lbs: rigid bones" if "lbs" in methods else "") + ")")
    p.add_argument("--iterations", type=int, default=None,
                   help="rounds of the alternating solve (default: the function's)")
    if seed:
        p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--quiet", action="store_true", help="no progress on stderr")
    p.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                   help="show the full traceback instead of a one-line error")


def add_arguments(p: argparse.ArgumentParser) -> None:
    sub = p.add_subparsers(dest="job", metavar="JOB", required=True, parser_class=type(p))
    fmt = argparse.RawDescriptionHelpFormatter
    d = sub.add_parser("decompose", formatter_class=fmt,
                       help="a mesh animation into a rig and per-frame poses",
                       description="Decompose a mesh animation into a rig with stretchable, "
                                   "twistable bones and per-frame poses.",
                       epilog=f"example:\n  {EXAMPLE}")
    d.add_argument("animation", nargs="+", metavar="ANIMATION",
                   help="one .npz ('frames' (f, n, d); optional 'rest', 'F') or the rest "
                        "mesh followed by its frames as mesh files")
    d.add_argument("--bones", type=int, required=True, help="number of bones to fit")
    d.add_argument("--influences", type=int, default=4,
                   help="bones per vertex at most (default 4)")
    d.add_argument("-o", "--output", required=True, metavar="RIG.npz", help="the rig")
    d.add_argument("--clip-out", metavar="CLIP.json", help="also write the frames' poses")
    d.add_argument("--fps", type=float, default=30.0,
                   help="frames per second of --clip-out (default 30)")
    _common(d, methods=("stbs-lbs", "lbs"))
    for job, what in (("endpoints", "endpoint weights"),
                      ("weights", "bone weights and endpoint weights")):
        e = sub.add_parser(job, formatter_class=fmt,
                           help=f"a rig's {what} from examples in known poses",
                           description=f"Fit a rig's {what} to example meshes whose "
                                       "poses are known (a clip's keys, one per example, "
                                       "in order).",
                           epilog=f"example:\n  stbs fit {job} arm.npz examples.npz "
                                  "--poses poses.json -o arm-fitted.npz")
        e.add_argument("rig", metavar="RIG", help="the rig: .npz, .gltf, .glb or .fbx")
        e.add_argument("examples", nargs="+", metavar="EXAMPLES",
                       help="one .npz ('frames' (f, n, d)) or mesh files, one per pose")
        e.add_argument("--poses", required=True, metavar="CLIP.json",
                       help="a clip of the rig's skeleton whose keys are the examples' poses")
        e.add_argument("-o", "--output", required=True, metavar="RIG.npz",
                       help="the rig with the fitted weights")
        if job == "weights":
            e.add_argument("--influences", type=int, default=4,
                           help="bones per vertex at most (default 4)")
            e.add_argument("--smoothness", type=float, default=None,
                           help="weight of the smoothness term across the surface "
                                "(default: the function's)")
        _common(e, seed=job == "weights",
                methods=("stbs-lbs", "stbs-dqs") if job == "endpoints" else ("stbs-lbs",))
    h = sub.add_parser("helpers", formatter_class=fmt,
                       help="an STBS rig as plain LBS with helper joints",
                       description="Turn an STBS rig into plain linear blend skinning with "
                                   "K helper joints per bone (twist bones).",
                       epilog="example:\n  stbs fit helpers arm.npz -k 3 --clip wave.json "
                              "-o arm-helpers.glb")
    h.add_argument("rig", metavar="RIG", help="the rig: .npz, .gltf, .glb or .fbx")
    h.add_argument("-k", type=int, default=3, help="helper joints per bone (default 3)")
    h.add_argument("-o", "--output", required=True, metavar="OUT",
                   help="output: .glb, .gltf (a skin any engine plays) or .npz (the rig)")
    h.add_argument("--clip", metavar="CLIP.json", help="a clip of the rig's skeleton to "
                   "carry over as the helpers' animation (glTF output)")
    h.add_argument("--method", choices=("stbs-lbs", "stbs-dqs"), default="stbs-dqs",
                   help="the deformation the helpers reproduce (default: stbs-dqs)")
    h.add_argument("--seed", type=int, default=0,
                   help="seed of the poses the helper weights are fitted on (default 0)")
    h.add_argument("--quiet", action="store_true", help="no progress on stderr")
    h.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                   help="show the full traceback instead of a one-line error")


def _progress(args):
    if args.quiet:
        return None
    last = {}

    def report(stage: str, done: int, total: int) -> None:
        step = max(1, total // 10) if total else 1
        if done in (0, total) or done - last.get(stage, -step) >= step:
            last[stage] = done
            print(f"stbs fit: {stage} {done}/{total}", file=sys.stderr, flush=True)

    return report


def _positive(name: str, value, low: float = 1) -> None:
    from ._errors import CommandError

    if value is not None and value < low:
        raise CommandError(f"--{name} must be >= {low:g}, got {value}")


def _suffix(path: str, allowed: tuple[str, ...], what: str) -> None:
    from ._errors import CommandError

    if not path.lower().endswith(allowed):
        raise CommandError(f"{what} {path!r}: expected {' or '.join(allowed)}")


def _options(args, *names) -> dict:
    return {k: getattr(args, k) for k in names if getattr(args, k, None) is not None}


def _decompose(args) -> int:
    _positive("bones", args.bones)
    _positive("influences", args.influences)
    _positive("iterations", args.iterations)
    _suffix(args.output, RIG_OUT, "output")
    _positive("fps", args.fps, 1e-9)
    if args.clip_out:
        _suffix(args.clip_out, (".json",), "--clip-out")
    from ..fit import decompose
    from ..io import read_sequence, save_rig, write_clip

    seq = read_sequence(args.animation if len(args.animation) > 1 else args.animation[0])
    dec = decompose(seq.rest, seq.frames, args.bones, F=seq.F,
                    max_influences=args.influences, method=args.method, seed=args.seed,
                    progress=_progress(args), **_options(args, "iterations"))
    save_rig(args.output, dec.rig())
    print(f"wrote {args.output}: {len(seq.rest)} vertices, {args.bones} bones; "
          f"{len(seq.frames)} frames fitted with RMSE {dec.rmse:.6g} "
          f"({dec.rmse_percent:.4f} % of the bounding-box diagonal)")
    if args.clip_out:
        from ..clip import Clip

        clip = Clip([(k / args.fps, p) for k, p in enumerate(dec.poses)], fps=args.fps)
        write_clip(args.clip_out, clip)
        print(f"wrote {args.clip_out}: {len(dec.poses)} keys at {args.fps:g} fps")
    return 0


def _examples(args, rig):
    from ..io import read_clip, read_sequence
    from ._errors import CommandError

    clip = read_clip(args.poses, rig.skeleton)
    paths = args.examples
    if len(paths) == 1:
        frames = read_sequence(paths[0]).frames
    else:       # mesh files, one per pose: none of them is a rest mesh here
        seq = read_sequence([paths[0], *paths])
        frames = seq.frames
    poses = [p for _, p in clip.keys]
    if len(poses) != len(frames):
        raise CommandError(f"--poses {args.poses!r} has {len(poses)} keys but the examples "
                           f"hold {len(frames)} meshes: give one key per example")
    return poses, frames


def _fit_weights(args) -> int:
    _positive("iterations", args.iterations)
    _suffix(args.output, RIG_OUT, "output")
    from ..fit import fit_endpoint_weights, fit_weights
    from ..io import read_rig, save_rig

    rig = read_rig(args.rig)
    poses, frames = _examples(args, rig)
    if args.job == "endpoints":
        E = fit_endpoint_weights(rig.V, rig.skeleton, rig.W, poses, frames,
                                 method=args.method, progress=_progress(args),
                                 **_options(args, "iterations"))
        W = rig.W
    else:
        _positive("influences", args.influences)
        _positive("smoothness", args.smoothness, 0)
        W, E = fit_weights(rig.V, rig.skeleton, poses, frames, F=rig.F,
                           max_influences=args.influences, method=args.method,
                           seed=args.seed, progress=_progress(args),
                           **_options(args, "iterations", "smoothness"))
    save_rig(args.output, rig.replace(W=W, E=E))
    print(f"wrote {args.output}: {args.job} fitted to {len(frames)} examples "
          f"({len(rig.V)} vertices, {rig.skeleton.n_bones} bones)")
    return 0


def _helpers(args) -> int:
    _positive("k", args.k)
    _suffix(args.output, HELPER_OUT, "output")
    from ..fit import helper_joints
    from ..io import read_clip, read_rig, save_rig

    rig = read_rig(args.rig)
    clip = read_clip(args.clip, rig.skeleton) if args.clip else None
    helper = helper_joints(rig, k=args.k, method=args.method, seed=args.seed,
                           progress=_progress(args))
    if args.output.lower().endswith(".npz"):
        save_rig(args.output, helper.rig())
    else:
        helper.write_gltf(args.output, clip)
    print(f"wrote {args.output}: {rig.skeleton.n_bones} bones as "
          f"{helper.skeleton.n_bones} LBS joints ({args.k} per bone)"
          + (f", clip of {len(clip.keys)} keys" if clip else ""))
    return 0


def run(args: argparse.Namespace) -> int:
    return {"decompose": _decompose, "endpoints": _fit_weights, "weights": _fit_weights,
            "helpers": _helpers}[args.job](args)
