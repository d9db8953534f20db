"""``stbs export``: a rig (and a clip) as glTF 2.0 for other tools."""

from __future__ import annotations

import argparse

from ..methods import SKINNING_METHODS as METHODS
from ._character import add_character_options

NAME = "export"
HELP = "write a rig (and a clip) as glTF 2.0 (.glb, .gltf) or OpenUSD (.usda, .usdc)"
EXAMPLE = "stbs export arm.npz -o arm.glb"
DESCRIPTION = """\
Write a rig as glTF 2.0: a standard skin that every glTF viewer plays (linear blend
skinning, the four heaviest bones per vertex), with the endpoint weights as the
attribute _ENDPOINT_WEIGHTS_0 and the skeleton in the skin's extras, so stbs reads
the file back whole. --clip adds the clip as a joint animation (rotations and
positions: what linear blend skinning shows); --bake METHOD instead bakes what that
method computes, stretch and twist included, as morph targets played in time.

OpenUSD (.usda, .usdc, .usd; the usd extra, usd-core): a UsdSkel rig (joints, bind
transforms, the four heaviest bones per vertex, skel:skinningMethod classicLinear or,
with --skinning dqs, dualQuaternion; endpoint weights as primvars:stbs:endpointWeights),
the clip as a SkelAnimation, and with --bake the baked frames as a time-sampled points
cache (/Baked) for film pipelines."""
EPILOG = f"""examples:
  {EXAMPLE}
  stbs export arm.npz --clip wave.json -o arm-wave.glb
  stbs export arm.npz --clip wave.json --bake stbs-dqs -o arm-wave-stbs.glb
  stbs export arm.npz --clip wave.json --bake stbs-dqs --skinning dqs -o arm.usda"""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("rig", metavar="RIG", help="rig: .npz, .gltf or .glb")
    p.add_argument("-o", "--output", required=True, metavar="OUT",
                   help="output: .glb, .gltf, .usda, .usdc or .usd")
    p.add_argument("--clip", metavar="CLIP.json", help="a clip of the rig's skeleton")
    p.add_argument("--bake", choices=METHODS, metavar="METHOD",
                   help=f"bake the clip with this method ({', '.join(METHODS)})")
    p.add_argument("--skinning", choices=("lbs", "dqs"), default="lbs",
                   help="OpenUSD: the skinning method the file asks for (default: lbs)")
    add_character_options(p)


USD = (".usda", ".usdc", ".usd")


def requires(args: argparse.Namespace) -> list[str]:
    need = []
    if args.output.lower().endswith(USD):
        need.append("pxr")
    return need


def run(args: argparse.Namespace) -> int:
    from ..bake import export
    from ..io import read_clip, read_rig
    from ._character import character_options
    from ._errors import CommandError

    usd = args.output.lower().endswith(USD)
    if not usd and not args.output.lower().endswith((".glb", ".gltf")):
        raise CommandError(f"output {args.output!r}: expected .glb, .gltf, .usda, .usdc or "
                           f".usd")
    if args.skinning != "lbs" and not usd:
        raise CommandError("--skinning applies to OpenUSD output (glTF skins linearly)")
    if args.bake and not args.clip:
        raise CommandError("--bake needs --clip: the animation to bake")
    rig = read_rig(args.rig, **character_options(args))
    clip = read_clip(args.clip, rig.skeleton) if args.clip else None
    export(args.output, rig, clip, bake=args.bake, skinning=args.skinning)
    what = f", clip of {len(clip.sample_times())} frames" if clip else ""
    print(f"wrote {args.output}: {len(rig.V)} vertices, {rig.skeleton.n_bones} bones{what}"
          + (f" baked by {args.bake}" if args.bake else ""))
    return 0
