"""glTF 2.0 both ways, in one place.

=====================  ==============================================================
module                 what it owns
=====================  ==============================================================
``container``          the file: JSON, GLB chunks, buffers (confined, sized, lazy),
                       the decoding budget; :func:`glb_bytes`, :func:`pad4`
``accessors``          the component-type table, :func:`read_accessor`,
                       :class:`AccessorWriter`
``scene``              the node hierarchy (checked: a tree), skins and their joints
``read``               :func:`read_gltf`: a character as a rig, its animations as a
                       lazy mapping of clips
``animation``          an animation as a clip equal to the node hierarchy at any time
``write``              :func:`write_gltf`: a rig (and a clip, or a baked clip)
``patch``              :func:`write_back`: a character's own file plus endpoint weights
``bones``              the bone table kept in ``skin.extras["stbs"]``
=====================  ==============================================================

The container is parsed here, not by a library: JSON and GLB chunks are a few dozen
lines, and owning them is what lets the reader confine buffer URIs to the file's folder,
check every declared size before allocating, and never open a buffer it does not need
(see :mod:`stbs.io.gltf.container`).
"""

from .accessors import AccessorWriter, read_accessor
from .container import GltfFile, glb_bytes, pad4
from .patch import write_back
from .read import GLTF_EXTENSIONS, GltfAnimations, read_gltf
from .write import quantize_weights, write_gltf

__all__ = ["read_gltf", "write_gltf", "write_back", "GLTF_EXTENSIONS", "GltfAnimations",
           "GltfFile", "read_accessor", "AccessorWriter", "glb_bytes", "pad4",
           "quantize_weights"]
