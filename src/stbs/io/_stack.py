"""Meshes stacked into one rig as a reader finds them (glTF primitives, FBX meshes)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class MeshStack:
    """The meshes read so far, in the order they are stacked into the rig's ``V``, ``F``
    (indices into the stack) and ``W``."""

    Vs: list = field(default_factory=list)
    Fs: list = field(default_factory=list)
    Ws: list = field(default_factory=list)
    off: int = 0

    def add(self, V: np.ndarray, F: np.ndarray, W: np.ndarray) -> int:
        """Stack one mesh's vertices, triangles and weights; its first row."""
        start = self.off
        self.Vs.append(V)
        self.Fs.append(F + start)
        self.Ws.append(W)
        self.off += len(V)
        return start
