"""File input and output: meshes, skeletons, weights, rigs and poses.

Readers raise :class:`FileNotFoundError` for a missing file, :class:`ValueError`
for an unknown extension (listing the supported ones) and :class:`FormatError`
(a ``ValueError``) for a malformed file, naming the file, the line, what was
expected and what was found. Writers write to a temporary file in the
destination folder and rename it (:func:`atomic_open`, :func:`atomic_save`).

=====================  ==============================================
function               formats
=====================  ==============================================
:func:`read_mesh`      .obj .off .ply .stl .mesh .msh .vtk
:func:`write_mesh`     .obj .off .ply
:func:`read_tgf`       .tgf (libigl, 1-based, optional bone flags)
:func:`write_tgf`      .tgf
:func:`read_bf`        .bf (libigl 5 columns, FAST 27 columns)
:func:`read_skeleton`  .tgf .bf  -> :class:`stbs.Skeleton`
:func:`read_dmat`      .dmat (ASCII and binary)
:func:`write_dmat`     .dmat
:func:`read_weights`   .dmat .npy .npz .csv
:func:`load_rig`       .npz rig, format version 1 (see :mod:`stbs.io.rig`)
:func:`save_rig`       .npz rig (a :class:`stbs.Rig`)
:func:`read_pose`      .json pose (either form, see :mod:`stbs.io.pose`)
:func:`write_pose`     .json pose
:func:`read_clip`      .json clip: keyed poses (see :mod:`stbs.io.clip`)
:func:`write_clip`     .json clip
:func:`read_bvh`       .bvh motion capture -> :class:`stbs.Motion`
:func:`read_gltf`      .gltf .glb skinned meshes of a skeleton, animations -> rig, clips
:func:`read_fbx`       .fbx (binary, ASCII) skinned meshes and animation stacks -> rig, clips
:func:`write_gltf`     .gltf .glb skin (+ endpoint weights), clip, baked morph targets
:func:`write_usd`      .usda .usdc .usd: UsdSkel rig, clip, baked points cache
:func:`read_rig`       .npz .gltf .glb .fbx -> :class:`stbs.Rig`
:func:`write_rig`      .npz .gltf .glb (a glTF character keeps its file, plus E)
:func:`read_polygons`  .poly (Triangle's planar straight-line graph) -> polygons
:func:`read_sequence`  .npz mesh animation, or a rest mesh and its frames as mesh files
=====================  ==============================================
"""

from ._atomic import atomic_open, atomic_save, atomic_write
from .anyrig import RIG_EXTENSIONS, read_rig, write_rig
from .bf import BoneForest, read_bf
from .bvh import read_bvh
from .clip import clip_to_dict, read_clip, write_clip
from .dmat import read_dmat, write_dmat
from .errors import FormatError
from .fbx import FBX_EXTENSIONS, read_fbx
from .gltf import GLTF_EXTENSIONS, read_gltf, write_gltf
from .mesh import MESH_READ_EXTENSIONS, MESH_WRITE_EXTENSIONS, Mesh, read_mesh, write_mesh
from .poly import read_polygons
from .pose import pose_to_dict, read_pose, write_pose
from .rig import RIG_VERSION, load_rig, save_rig
from .sequence import MeshSequence, read_sequence
from .skeleton_file import SKELETON_READ_EXTENSIONS, read_skeleton
from .tgf import read_tgf, write_tgf
from .usd import USD_EXTENSIONS, write_usd
from .weights import WEIGHT_READ_EXTENSIONS, read_weights

__all__ = [
    "FormatError",
    "Mesh", "read_mesh", "write_mesh", "MESH_READ_EXTENSIONS", "MESH_WRITE_EXTENSIONS",
    "read_tgf", "write_tgf", "BoneForest", "read_bf", "read_skeleton",
    "SKELETON_READ_EXTENSIONS",
    "read_dmat", "write_dmat", "read_weights", "WEIGHT_READ_EXTENSIONS",
    "save_rig", "load_rig", "RIG_VERSION", "read_pose", "write_pose", "pose_to_dict",
    "read_clip", "write_clip", "clip_to_dict",
    "read_polygons", "read_bvh", "read_gltf", "write_gltf", "GLTF_EXTENSIONS",
    "read_rig", "write_rig", "RIG_EXTENSIONS", "write_usd", "USD_EXTENSIONS",
    "read_fbx", "FBX_EXTENSIONS", "MeshSequence", "read_sequence",
    "atomic_open", "atomic_save", "atomic_write",
]
