"""``stbs view``: serve a rig to the browser viewer on 127.0.0.1 (the server half)."""

from __future__ import annotations

import argparse
import sys

NAME = "view"
HELP = "serve a rig to the browser viewer on 127.0.0.1 (prints the page's URL)"
EXAMPLE = "stbs view arm.npz"
#: The built-in rigs of --example (the first is the default with no input at all).
EXAMPLES = ("arm", "picture")
DESCRIPTION = """\
Serve a rig to the browser viewer: start a server on 127.0.0.1 (only), print one line,
the page's URL http://127.0.0.1:PORT/?token=TOKEN (a new token each run), open it in
the browser (unless --no-browser), and serve until Ctrl-C.

The rig is a .npz rig file, a character (glTF .gltf .glb or FBX .fbx, every mesh
skinned to its skeleton; --skin and --mesh pick another skeleton or one mesh), a MESH
and SKELETON rigged first as 'stbs rig' does
(--bone, --endpoint, --tets, --clip-skeleton, --tol; an outline MESH, .poly or an
image, is traced and meshed with the defaults of 'stbs rig'), or a built-in example:
  arm      an arm with a mitten hand, three bones, bone heat + heat endpoint weights
           (paper Figs. 1, 5; the default with no input)
  picture  the 2D picture of the paper's Fig. 12, BBW + BBW endpoint weights, textured

Every request other than the page and its assets needs the token; a request for
another host name than 127.0.0.1:PORT or localhost:PORT is refused. The page saves
poses and clips (keyed poses, played on its timeline) as JSON files and clips as
animated GIFs into the rig's folder (the folder of --save-as when given) and the
rig to --save-as (.npz, or .glb/.gltf: a glTF character's own file with the page's
endpoint weights, and its painted bone weights, added), or beside the input: RIG.npz
is saved as RIG-edited.npz (never over the input unless --save-as names it), CHAR.glb
as CHAR-edited.glb, MESH as MESH.npz; for an --example only with --save-as. Files are
written to a temporary file and renamed, and the page replaces an existing file only
when asked to. MESH SKELETON is rigged (each stage said on stderr) and written to
MESH.npz (or --save-as) before the server starts; an existing file there is replaced
only with --force.

The page draws the rig lit and shaded with its skeleton, skins it in a vertex shader
with any of the four methods (lbs, dqs, stbs-lbs, stbs-dqs), two of them side by side
on request, poses it by dragging joints (stretching the bones, or by inverse kinematics
keeping their lengths), a rotation gizmo and twist and stretch sliders, saves, downloads
and loads pose files, colours the mesh by its bone or endpoint weights, paints them with
a brush (undoable), recomputes one bone's endpoint weights by any --endpoint method,
shapes them with a curve (paper Fig. 10), saves the painted rig, and can be scripted
through window.stbsViewer (docs/viewer.md).

--motion FILE opens the timeline with an animation of the rig: a BVH capture
(retargeted onto the rig by joint names, or by --mapping MAP.json, each joint's twist
spread along its bone), a clip .json, or a glTF animation of the rig's skeleton (a
character opens with its own first animation when it has one). The page plays the
animation exactly as stbs.Clip.pose gives it."""
EPILOG = f"""examples:
  {EXAMPLE}
  stbs view                                     # the arm example
  stbs view --example picture --no-browser --port 8765
  stbs view arm.obj arm.tgf --bone heat --endpoint heat --save-as arm-rig.npz
  stbs view character.glb --motion 131_01.bvh --mapping map.json
  stbs view character.glb --save-as painted.glb"""


def add_arguments(p: argparse.ArgumentParser) -> None:
    from ._character import add_character_options
    from .rig import BONE, ENDPOINT, add_clip_argument, add_tol_argument

    p.add_argument("input", nargs="?", metavar="RIG|MESH",
                   help="a rig (.npz), a character (.gltf, .glb, ...), or a mesh (then give "
                        "its SKELETON too)")
    p.add_argument("skeleton", nargs="?", metavar="SKELETON",
                   help="the skeleton (.tgf .bf) of MESH, rigged before serving")
    p.add_argument("--example", choices=EXAMPLES, default=None,
                   help="a built-in rig instead of files (default with no input: arm)")
    p.add_argument("--port", type=int, default=0, metavar="N",
                   help="port on 127.0.0.1 (default: a free one)")
    p.add_argument("--no-browser", action="store_true",
                   help="only print the URL; do not open a browser")
    p.add_argument("--save-as", default=None, metavar="PATH",
                   help="where the page saves the rig: .npz, or .glb/.gltf (its folder also "
                        "takes the poses)")
    p.add_argument("--motion", default=None, metavar="FILE",
                   help="open the timeline with this animation: .bvh (retargeted), clip "
                        ".json, or a glTF animation of the rig's skeleton")
    p.add_argument("--mapping", default=None, metavar="MAP.json",
                   help="with --motion CAPTURE.bvh: which capture joint drives which rig "
                        "bone ({rig bone: joint name}, as stbs.retarget takes it)")
    add_character_options(p)
    g = p.add_argument_group("rigging MESH SKELETON (as stbs rig)")
    g.add_argument("--bone", choices=BONE, default=None, help="bone weights (default: bbw)")
    g.add_argument("--endpoint", choices=ENDPOINT, default=None,
                   help="endpoint weights (default: bbw)")
    g.add_argument("--tets", default=None, metavar="auto|winding|conforming|FILE",
                   help="3D bbw: the volume the weights are solved on, as for 'stbs rig' "
                        "(default: auto), or tets read from FILE")
    add_clip_argument(g)
    add_tol_argument(g)
    g.add_argument("--force", action="store_true",
                   help="replace the rig file MESH SKELETON writes (MESH.npz, or --save-as) "
                        "when it exists")


def requires(args: argparse.Namespace) -> list[str]:
    """Optional modules this run needs: Pillow for an image MESH."""
    from .rig import IMAGE_EXTENSIONS

    need = []
    if args.skeleton is not None and args.input is not None:
        return need + (["PIL"] if args.input.lower().endswith(IMAGE_EXTENSIONS) else [])
    return sorted(set(need))


def _check(args: argparse.Namespace):
    """The run's plan from its arguments, before any work: (kind, save target)."""
    kind = _kind(args)
    _check_options(args, kind)
    _check_motion(args)
    from ._errors import CommandError

    if not 0 <= args.port <= 65535:
        raise CommandError(f"--port: expected 0..65535 (0: a free port), got {args.port}")
    save_as = _check_save_as(args)
    _check_input(args, kind)
    if kind == "mesh":
        _check_rig_output(args, _targets(kind, args.input, save_as)[0])
    elif args.force:
        raise CommandError("--force applies to MESH SKELETON, whose rig stbs view writes")
    return kind, save_as


def _kind(args: argparse.Namespace) -> str:
    """"example", "rig" (a rig or character file) or "mesh" (MESH SKELETON)."""
    from ._errors import CommandError

    if args.example is not None and args.input is not None:
        raise CommandError(f"give a rig (RIG.npz or MESH SKELETON) or --example "
                           f"{args.example}, not both")
    if args.input is None:
        return "example"
    if args.skeleton is not None:
        return "mesh"
    rig_ext = _rig_extensions()
    if not args.input.lower().endswith(rig_ext):
        raise CommandError(f"{args.input!r}: expected a rig (.npz, or a character "
                           f"{' '.join(e for e in rig_ext if e != '.npz')}), or a MESH "
                           f"followed by its SKELETON")
    return "rig"


def _check_options(args: argparse.Namespace, kind: str) -> None:
    """The character and rigging options apply to their kinds of input only."""
    from ._errors import CommandError

    character = {"--skin": args.skin, "--mesh": args.mesh}
    given = [k for k, v in character.items() if v is not None]
    if given and (kind != "rig" or args.input.lower().endswith(".npz")):
        raise CommandError(f"{given[0]} applies to a character file (a .npz rig or a mesh "
                           "has one skinned mesh)")
    rigging = {"--bone": args.bone, "--endpoint": args.endpoint, "--tets": args.tets,
               "--tol": args.tol, "--clip-skeleton": args.clip_skeleton or None}
    given = [k for k, v in rigging.items() if v is not None]
    if given and kind != "mesh":
        raise CommandError(f"{given[0]} applies to MESH SKELETON, which stbs view rigs first")


def _check_motion(args: argparse.Namespace) -> None:
    from pathlib import Path

    from ._errors import CommandError

    if args.motion is not None:
        from ..bake import MOTION_EXTENSIONS

        if not args.motion.lower().endswith(MOTION_EXTENSIONS):
            raise CommandError(f"--motion {args.motion!r}: expected one of "
                               f"{', '.join(MOTION_EXTENSIONS)}")
        if not Path(args.motion).is_file():
            raise CommandError(f"--motion {args.motion!r}: file not found")
    if args.mapping is not None:
        if args.motion is None or not args.motion.lower().endswith(".bvh"):
            raise CommandError("--mapping applies to --motion CAPTURE.bvh (the joints it maps "
                               "are a capture's)")
        if not Path(args.mapping).is_file():
            raise CommandError(f"--mapping {args.mapping!r}: file not found")


def _check_save_as(args: argparse.Namespace):
    """--save-as as a Path (a rig file in an existing folder), or None."""
    from pathlib import Path

    from ._errors import CommandError

    if args.save_as is None:
        return None
    save_as = Path(args.save_as)
    folder = save_as.parent if str(save_as.parent) else Path(".")
    from ..viewer.state import RIG_TARGETS

    if save_as.suffix.lower() not in RIG_TARGETS:
        raise CommandError(f"--save-as {args.save_as!r}: expected a rig file "
                           f"({', '.join(RIG_TARGETS)})")
    if not folder.is_dir():
        raise CommandError(f"--save-as {args.save_as!r}: folder {str(folder)!r} does "
                           f"not exist")
    if save_as.is_dir():
        raise CommandError(f"--save-as {args.save_as!r}: is a folder, expected a file")
    return save_as


def _check_input(args: argparse.Namespace, kind: str) -> None:
    from pathlib import Path

    from ._errors import CommandError

    if kind != "example" and not Path(args.input).is_file():
        what = "rig" if kind == "rig" else "mesh"
        raise CommandError(f"{args.input!r}: {what} file not found")


def _check_rig_output(args: argparse.Namespace, target) -> None:
    """MESH SKELETON: the rig file this run writes must not exist, unless --force."""
    import os

    from ._errors import CommandError

    if os.path.lexists(target) and not args.force:
        raise CommandError(f"{str(target)!r} exists: stbs view MESH SKELETON writes the rig "
                           "it builds there; pass --force to replace it (or --save-as "
                           "another file)")


def _rig_extensions() -> tuple[str, ...]:
    """The rig files stbs view reads: those of stbs.io.read_rig."""
    from ..io import RIG_EXTENSIONS

    return tuple(RIG_EXTENSIONS)


def _is_gltf(path) -> bool:
    return str(path).lower().endswith((".gltf", ".glb"))


def _targets(kind: str, path: str | None, save_as):
    """Where the page may write: (rig file, pose folder); None where saving is off.

    --save-as: the rig goes there and poses into its folder. Otherwise poses go into
    the input's folder and the rig beside the input: RIG.npz as RIG-edited.npz (never
    the input itself), a glTF character CHAR.glb as CHAR-edited.glb (other characters
    as CHAR-edited.npz), MESH as MESH.npz; an example without --save-as saves nothing.
    """
    from pathlib import Path

    if save_as is not None:
        return save_as, (save_as.parent if str(save_as.parent) else Path("."))
    if kind == "example":
        return None, None
    p = Path(path)
    folder = p.parent if str(p.parent) else Path(".")
    if kind != "rig":
        return p.with_name(p.stem + ".npz"), folder
    ext = p.suffix.lower() if _is_gltf(p) or p.suffix.lower() == ".npz" else ".npz"
    return p.with_name(p.stem + "-edited" + ext), folder


def _example(name: str):
    """A built-in rig: (rig, extras for the page)."""
    import numpy as np

    from ..rig import build_rig

    if name == "picture":
        from ..demo.models import picture_2d

        m = picture_2d()
        rig = build_rig(m.V, m.sk, F=m.F, bone="bbw", endpoint="bbw", remesh=False)
        return rig.replace(texture=np.asarray(m.extra["texture"], dtype=np.uint8),
                           UV=m.extra["uv"]), {}
    from ..shapes import arm

    m = arm()
    return build_rig(m.V, m.sk, F=m.F, bone="heat", endpoint="heat"), {}


def _rig_from_files(args: argparse.Namespace, target):
    """MESH SKELETON rigged as ``stbs rig`` does (outlines with its default options), each
    stage said on stderr as it starts, then written to ``target`` (atomically)."""
    from ..io import write_rig
    from .rig import _Stages, resolve_tol, rig_from_files

    bone = args.bone or "bbw"
    endpoint = args.endpoint or "bbw"
    tol = resolve_tol(args.tol, bone, endpoint)
    stages = _Stages()
    stages.live = True      # the progress of rigging, on stderr, terminal or not
    rig = rig_from_files(stages, args.input, args.skeleton, bone=bone, endpoint=endpoint,
                         tets=args.tets or "auto", tol=tol, clip_skeleton=args.clip_skeleton)
    write_rig(target, rig)
    print(f"stbs view: rig written to {target}", file=sys.stderr, flush=True)
    return rig


def _read_character(path: str, options: dict):
    """(rig, clips) of a rig or character file; clips: its own animations by name."""
    from .. import io as sio
    from ._errors import CommandError

    ext = path.lower().rsplit(".", 1)[-1]
    reader = sio.read_gltf if ext in ("gltf", "glb") else getattr(sio, f"read_{ext}", None)
    try:
        if ext != "npz" and reader is not None:
            return reader(path, **options)
        return sio.read_rig(path, **options), {}
    except TypeError as exc:     # an option this reader does not take
        flags = ", ".join(f"--{k}" for k in options) or "these options"
        raise CommandError(f"{path!r}: {flags} not taken for this file ({exc})") from None


def _first_animation(clips: dict):
    """The first animation that moves (an FBX file may open with a still "Take 001"),
    else the first, else None."""
    import numpy as np

    for clip in clips.values():
        if len(clip) > 1 and any(np.ptp(a, axis=0).max() > 1e-9 for a in (
                clip.quaternions, clip.offsets, clip.stretch, clip.twist)):
            return clip
    return next(iter(clips.values()), None)


def _motion(args: argparse.Namespace, rig, clips: dict):
    """The clip the timeline opens with: --motion (a BVH capture retargeted with
    --mapping), else the character's own first animation, else None."""
    from ..bake import load_motion

    if args.motion is not None:
        return load_motion(args.motion, rig, mapping=args.mapping)
    return _first_animation(clips)


def _serve(args: argparse.Namespace, kind: str, save_as):
    """The rig and its server, ready to serve (warnings reported as they happen)."""
    import errno
    from pathlib import Path

    from ..viewer import ViewerServer
    from ._character import character_options
    from ._errors import CommandError

    extras: dict = {}
    own: dict = {}
    if kind == "example":
        name = args.example or EXAMPLES[0]
        rig, extras = _example(name)
    elif kind == "rig":
        name = Path(args.input).stem
        rig, own = _read_character(args.input, character_options(args))
    rig_target, pose_folder = _targets(kind, args.input, save_as)
    if kind == "mesh":
        name = Path(args.input).stem
        rig = _rig_from_files(args, rig_target)
    source = args.input if kind == "rig" and _is_gltf(args.input) else None
    clip = _motion(args, rig, own)
    try:
        return ViewerServer(rig, port=args.port, rig_target=rig_target,
                            pose_folder=pose_folder, name=name, extras=extras, clip=clip,
                            rig_source=source)
    except OSError as exc:
        why = exc.strerror or str(exc)
        if exc.errno == errno.EADDRINUSE:
            why = "the port is in use"
        raise CommandError(f"--port {args.port}: cannot listen on 127.0.0.1:{args.port} "
                           f"({why})") from None


def run(args: argparse.Namespace) -> int:
    import warnings

    from ..viewer.static import page_missing
    from ._errors import CommandError
    from ._report import flush_warnings as _flush

    kind, save_as = _check(args)
    missing = page_missing()
    if missing is not None:
        raise CommandError(missing)
    # The server runs until Ctrl-C: say the warnings of loading and rigging now, not
    # when the command ends.
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", UserWarning)
        server = _serve(args, kind, save_as)
    _flush(caught)
    try:
        print(server.url, flush=True)
        if not args.no_browser:
            import webbrowser

            if not webbrowser.open(server.url):
                print("stbs: warning: no browser could be opened; open the URL above",
                      file=sys.stderr, flush=True)
        server.serve_forever()
    except KeyboardInterrupt:
        print("stbs view: stopped", file=sys.stderr, flush=True)
    finally:
        server.shutdown()
    return 0
