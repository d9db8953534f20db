"""A rig from or to any rig file: the native ``.npz``, a glTF character, or (to read) an
FBX character.

The paper's promise is that STBS needs "only an extra scalar weight function per
bone ... without changing the existing skeleton rig or bone weights". So a glTF
character is a rig wherever a rig is read, and :func:`write_rig` of a rig read from a
glTF file *adds* its endpoint weights to a copy of that file, keeping everything else
of it (nodes, joint orientations, animations, materials) as it was.
"""

from __future__ import annotations

import os
from typing import Any

from ..rig.model import Rig
from ._parse import input_path, suffix
from .fbx import FBX_EXTENSIONS
from .fbx import _read as _read_fbx
from .gltf import GLTF_EXTENSIONS, read_gltf, write_back, write_gltf
from .rig import load_rig, save_rig

__all__ = ["read_rig", "write_rig", "RIG_EXTENSIONS"]

RIG_EXTENSIONS = (".npz", *GLTF_EXTENSIONS, *FBX_EXTENSIONS)


def read_rig(path: str | os.PathLike, **gltf_options: Any) -> Rig:
    """The rig in a ``.npz`` rig file, a glTF 2.0 file (``.gltf``/``.glb``) or an FBX file.

    ``gltf_options`` (``skin=``, ``mesh=``, ``rigid=``) pick the skinned mesh of a glTF
    file or the skeleton of an FBX file, and whether the meshes hung rigidly on its
    joints come too (see :func:`stbs.io.read_gltf`, :func:`stbs.io.read_fbx`); their
    animations are not read here.
    """
    ext = suffix(path, RIG_EXTENSIONS, "read_rig")
    if ext == ".npz":
        if gltf_options:
            raise TypeError(f"{', '.join(gltf_options)}: options for glTF files, not .npz")
        return load_rig(path)
    if ext in FBX_EXTENSIONS:
        return _read_fbx(path, anims=False, **gltf_options)[0]
    return read_gltf(path, **gltf_options)[0]


def write_rig(path: str | os.PathLike, rig: Rig, *, source: str | os.PathLike | None = None
              ) -> None:
    """Write a rig to ``.npz`` or glTF (``.glb``/``.gltf``), atomically.

    Parameters
    ----------
    path : str or os.PathLike
        The destination; its extension picks the format.
    rig : Rig
    source : str or os.PathLike, optional
        The glTF file ``rig`` was read from. Writing glTF then copies that file and adds
        the rig's endpoint weights (``_ENDPOINT_WEIGHTS_0`` on every primitive of the
        skinned meshes, aligned with ``JOINTS_0``) and its bone table
        (``skin.extras["stbs"]``); nothing else of the file changes (meshes hung rigidly
        on joints stay as they were, see :mod:`stbs.io.gltf.patch`). Without it, glTF
        is written afresh by :func:`stbs.io.write_gltf`.
    """
    ext = suffix(path, RIG_EXTENSIONS, "write_rig")
    if ext in FBX_EXTENSIONS:
        raise ValueError(f"write_rig: cannot write FBX ({os.fspath(path)!r}); stbs reads FBX "
                         "characters only: write .npz, .glb or .gltf")
    if ext == ".npz":
        save_rig(path, rig)
    elif source is not None and str(source).lower().endswith(GLTF_EXTENSIONS):
        write_back(input_path(source, "glTF"), path, rig)
    else:
        write_gltf(path, rig)

