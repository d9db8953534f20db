"""Small rigs and motions for the baking tests."""

from __future__ import annotations

import numpy as np

import stbs
from stbs.shapes import bar

ARM_BVH = """HIERARCHY
ROOT shoulder
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT elbow
  {
    OFFSET 2 0 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    JOINT wrist
    {
      OFFSET 1.6 0 0
      CHANNELS 3 Zrotation Xrotation Yrotation
      End Site
      {
        OFFSET 0.4 0 0
      }
    }
  }
}
MOTION
Frames: FRAMES
Frame Time: 0.04
"""


def arm_rig(nx: int = 12) -> stbs.Rig:
    """A bar along x (4 long) with an upper arm, a forearm and a hand, the bones named
    as the BVH's joints that turn them; bone heat weights."""
    V, F, _, _ = bar(nx, 3, 3)
    sk = stbs.Skeleton([[0, 0, 0], [2, 0, 0], [3.6, 0, 0], [4.0, 0, 0]],
                       [[0, 1], [1, 2], [2, 3]], names=["shoulder", "elbow", "wrist"])
    return stbs.build_rig(V, sk, F=F, bone="heat", endpoint="projection")


def arm_bvh(path, frames: int = 30):
    """The arm waving: the shoulder turns about z, the elbow bends, the wrist rolls
    about x by 6 degrees a frame (a forearm's roll, as capture stores it)."""
    rows = []
    for k in range(frames):
        a = 40 * np.sin(2 * np.pi * k / frames)
        rows.append(f"0 0 0 {a:.6f} 0 0 {a / 2:.6f} 0 0 0 {6 * k:.6f} 0")
    path.write_text(ARM_BVH.replace("FRAMES", str(frames)) + "\n".join(rows) + "\n")
    return path


def clip_json(path, rig: stbs.Rig):
    sk = rig.skeleton
    bent = stbs.forward_kinematics(sk, rotations=stbs.transforms.axis_angle_to_matrix(
        np.array([[0, 0, 1.0], [0, 1, 0], [0, 0, 1]]), np.array([0.4, 0.8, 0.2])),
        stretch=[1, 1.3, 1], twist=[0, 0, np.pi, 0])
    clip = stbs.Clip([(0.0, stbs.Pose.rest(sk)), (1.0, bent)], fps=10)
    stbs.io.write_clip(path, clip)
    return path
