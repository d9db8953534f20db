"""What the meshers return: the mesh plus an exact record of the skeleton's vertices."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["TriMesh", "TetMesh"]


class _SkeletonRecord:
    """Methods shared by :class:`TriMesh` and :class:`TetMesh`."""

    V: np.ndarray
    on_bone: np.ndarray
    t_bone: np.ndarray
    joint_vertex: np.ndarray
    n_input: int

    @property
    def dim(self) -> int:
        """2 or 3."""
        return int(self.V.shape[1])

    @property
    def n_vertices(self) -> int:
        """Number of vertices n."""
        return int(self.V.shape[0])

    @property
    def on_joint(self) -> np.ndarray:
        """(n,) int64: the joint a vertex sits on, -1 elsewhere."""
        out = np.full(self.V.shape[0], -1, dtype=np.int64)
        has = self.joint_vertex >= 0        # -1: a joint left out (clip_skeleton)
        out[self.joint_vertex[has]] = np.flatnonzero(has)
        return out

    def bone_vertices(self, i: int, BE: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """All vertices on bone ``i``, its two joints included, sorted along the bone.

        A joint left out of the mesh (``joint_vertex`` -1, ``clip_skeleton``) is omitted.

        Parameters
        ----------
        i : int
            Bone index.
        BE : (b, 2) int
            The skeleton's bones (``sk.BE``), to find bone ``i``'s joints.

        Returns
        -------
        idx : (k,) int64
            Vertex indices, from the start joint to the end joint.
        t : (k,) float64
            Their parameters along the bone, 0 at ``a_i`` and 1 at ``b_i``.
        """
        BE = np.asarray(BE)
        if not 0 <= i < BE.shape[0]:
            raise ValueError(f"i must be a bone index in 0..{BE.shape[0] - 1}, got {i}")
        inner = np.flatnonzero(self.on_bone == i)
        order = np.argsort(self.t_bone[inner], kind="stable")
        s, e = self.joint_vertex[BE[i]]
        idx = np.concatenate([[s], inner[order], [e]]).astype(np.int64)
        t = np.concatenate([[0.0], self.t_bone[inner[order]], [1.0]])
        has = idx >= 0                      # a joint left out by clip_skeleton
        return idx[has], t[has]


@dataclass(frozen=True, eq=False)
class TriMesh(_SkeletonRecord):
    """A 2D triangle mesh with the skeleton's samples among its vertices.

    Attributes
    ----------
    V : (n, 2) float64
        Vertex positions. ``V[:n_input]`` are the input points, unchanged and in
        order (the outline's polygon vertices, or all vertices of an input mesh).
    F : (f, 3) int64
        Triangles, counter-clockwise (positive area).
    on_bone : (n,) int64
        The bone whose inside (0 < t < 1) a vertex lies on, -1 elsewhere (joints
        included: see ``joint_vertex``).
    t_bone : (n,) float64
        Parameter along that bone, ``V[k] = a_i + t (b_i - a_i)`` to rounding;
        NaN where ``on_bone`` is -1.
    joint_vertex : (j,) int64
        The vertex of every joint: ``V[joint_vertex] == sk.C`` exactly, except where
        a vertex of an input mesh already sits on the joint (within ``1e-6`` times
        the shape's size), which is then the joint's vertex.
    n_input : int
        How many leading vertices are the input points.
    engine : str
        The mesher that made it: ``"triangle"`` or ``"builtin"``.
    """

    V: np.ndarray
    F: np.ndarray
    on_bone: np.ndarray
    t_bone: np.ndarray
    joint_vertex: np.ndarray
    n_input: int
    engine: str

    def __repr__(self) -> str:
        return (f"TriMesh({self.V.shape[0]} vertices, {self.F.shape[0]} triangles, "
                f"{int((self.on_bone >= 0).sum())} bone samples, "
                f"{self.joint_vertex.size} joints, engine={self.engine!r})")


@dataclass(frozen=True, eq=False)
class TetMesh(_SkeletonRecord):
    """A tetrahedral mesh of a closed surface with the skeleton's samples inside.

    Attributes
    ----------
    V : (n, 3) float64
        Vertex positions. ``V[:n_input]`` are the surface's vertices, unchanged and
        in order, so ``W[:n_input]`` are the weights of the input surface; the
        joints, bone samples and Steiner points follow.
    T : (t, 4) int64
        Tetrahedra, positively oriented (positive volume).
    F : (g, 3) int64
        The boundary triangles of ``T``, oriented outwards. With
        ``keep_surface=True`` and TetGen this is the input surface (up to
        order); the builtin mesher's boundary only approximates it.
    on_bone, t_bone, joint_vertex, n_input
        As for :class:`TriMesh`; with ``clip_skeleton=True`` a joint outside the
        surface has ``joint_vertex`` -1.
    engine : str
        ``"tetgen"`` or ``"builtin"``.
    """

    V: np.ndarray
    T: np.ndarray
    F: np.ndarray
    on_bone: np.ndarray
    t_bone: np.ndarray
    joint_vertex: np.ndarray
    n_input: int
    engine: str

    def __repr__(self) -> str:
        return (f"TetMesh({self.V.shape[0]} vertices ({self.n_input} surface), "
                f"{self.T.shape[0]} tetrahedra, {int((self.on_bone >= 0).sum())} bone "
                f"samples, {int((self.joint_vertex >= 0).sum())} joints, engine={self.engine!r})")
