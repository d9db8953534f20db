"""``--skin`` and ``--mesh``: which skeleton of a character file (glTF, FBX) to read."""

from __future__ import annotations

import argparse

__all__ = ["add_character_options", "character_options"]


def add_character_options(p: argparse.ArgumentParser, *, mesh: bool = True) -> None:
    """Add ``--skin`` (and ``--mesh``) to a command that reads a rig file."""
    g = p.add_argument_group("character files with several skeletons (glTF, FBX)")
    g.add_argument("--skin", metavar="SKIN",
                   help="read the skeleton of this skin (index or name), with every mesh "
                        "bound to it (default: the first skinned mesh's skeleton)")
    if mesh:
        g.add_argument("--mesh", metavar="MESH",
                       help="read this skinned mesh alone (node or mesh, index or name)")


def character_options(args: argparse.Namespace, mesh: str | None = None) -> dict:
    """``--skin``/``--mesh`` as the readers' keyword options (all digits: an index)."""
    out = {}
    for key, v in (("skin", getattr(args, "skin", None)),
                   ("mesh", mesh if mesh is not None else getattr(args, "mesh", None))):
        if v is not None:
            out[key] = int(v) if v.isdigit() else v
    return out
