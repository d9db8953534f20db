"""Motion onto a rig: joint rotations of a capture (a :class:`stbs.Motion`) as a
:class:`stbs.Clip` of poses of a rig's skeleton, across naming schemes, rest postures
and sizes.

1. **Which joint drives which bone.** Both hierarchies are read as bodies
   (:mod:`stbs.retargeting.body`): pelvis, spine, neck, head, and per side collar,
   upper arm, forearm, hand, hip, thigh, shin, foot, toe, from their names in any of
   the usual conventions (:mod:`stbs.retargeting.names`) or, for unnamed joints, from
   the skeleton's shape. Each bone of the rig is driven by the capture joint of the
   same part and side; several spine (or neck) joints are matched by where they lie
   along the spine. A rig named like the capture is matched by name. Bones that are
   no body part (fingers, eyes, tails) take a joint of the same name when there is
   one; any other bone turns with its parent. A ``mapping`` replaces all of this.
2. **Rest postures.** Capture and rig may rest differently (a T-pose capture, an
   A-pose character; a capture whose rest is no pose at all). Each mapped bone turns
   as its source joint turns away from a *reference pose* of the capture, after its
   source bone has been swung onto the rig's rest direction of the bone:
   ``R_t = G^T R_s R_s0^T M^T G``, with ``R_s0`` the joint's rotation in the reference,
   ``M`` the smallest rotation from the source bone's direction there to the rig
   bone's, and ``G`` the turn between the two worlds (the up axes matched, the facing
   fitted to the bones' directions). The bones then point where the capture's point
   (the arms of a T-pose capture stand out from an A-pose character), and their roll
   follows the capture's. The reference is the capture's rest pose, or, when that
   lies far from the rig's rest, the frame nearest to it.
3. **Root travel** is scaled by the ratio of the hip heights (pelvis over the soles
   with straight legs), the capture's up axis found from its frames (feet to pelvis).
   The rig starts where it stands and moves across the ground as the capture's
   pelvis does; its pelvis rises and sinks over its own ground as the capture's does
   over the capture's floor.

``twist="spread"`` (the paper's twistable bones, applied to motion): each bone's rotation
relative to its parent is split into a *twist* about the parent bone's axis and a
*swing*; the twist is moved to the joint between them, where it becomes the parent's end
twist ``theta_b`` and so grows from 0 to its full angle along the parent bone (a
forearm's roll, stored at the wrist by capture, turns the forearm progressively instead
of the wrist alone). The child's final orientation is unchanged. Twist angles are
unwrapped over time, so a roll that keeps turning never jumps back by a full turn.
Only a bone with one child spreads (a chest does not take the neck's roll: the
shoulders hang on it). ``twist="joint"`` keeps the rigid roll at the joint.
"""

from .core import joint_map, retarget

__all__ = ["retarget", "joint_map"]

