"""Baking animations: a rig and a motion (BVH, glTF, clip JSON) in, deformed frames out;
and many rigs × motions at once on Dask (:mod:`stbs.bake.batch`)."""

from .core import (
    MESH_FOLDER_FORMATS,
    MOTION_EXTENSIONS,
    Baked,
    bake,
    bake_frames,
    clip_frames,
    export,
    frame_times,
    load_motion,
    output_kind,
    write_frames,
)

__all__ = ["load_motion", "frame_times", "clip_frames", "bake", "bake_frames", "export",
           "Baked", "write_frames",
           "output_kind", "MOTION_EXTENSIONS", "MESH_FOLDER_FORMATS"]
