"""stbs: skeletal shape deformation with stretchable, twistable bones.

Jacobson & Sorkine, "Stretchable and Twistable Bones for Skeletal Shape
Deformation", SIGGRAPH Asia 2011. DESIGN.md is the contract; names here are stable.
"""

from .io import Rig, load_rig, save_rig
from .pose import Pose, forward_kinematics
from .skeleton import Skeleton
from .skinning import METHODS, Deformer, deform
from .weights import endpoint_weights

__version__ = "0.1.0"

__all__ = ["Skeleton", "Pose", "forward_kinematics", "Deformer", "deform", "METHODS",
           "endpoint_weights", "Rig", "load_rig", "save_rig", "__version__"]
