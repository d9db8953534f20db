"""The node hierarchy of a glTF file: parents, rest transforms, skins and their joints.

:class:`Scene` checks the nodes once (every child index in range, no node with two
parents, no cycle), keeps each node's rest transform as translation, rotation and
scale (a ``matrix`` is split into them), and answers the questions the reader asks:
which skinned meshes there are, which meshes hang on joints without a skin, which
joints a skin has, where they sit.
"""

from __future__ import annotations

import numpy as np

from ... import transforms as tf
from ...rig.joints import rigid_parts as polar
from .accessors import FLOAT_ONLY, read_accessor
from .container import GltfFile

__all__ = ["Scene", "trs_matrices", "polar"]


def trs_matrices(t: np.ndarray, q: np.ndarray, s: np.ndarray) -> np.ndarray:
    """(..., 4, 4) matrices ``T R S`` of translations (..., 3), unit quaternions
    (..., 4) ``(w, x, y, z)`` and scales (..., 3)."""
    M = np.zeros(t.shape[:-1] + (4, 4))
    M[..., :3, :3] = tf.quat_to_matrix(q) * s[..., None, :]
    M[..., :3, 3] = t
    M[..., 3, 3] = 1.0
    return M


class Scene:
    """The checked node hierarchy of a :class:`GltfFile`.

    Attributes
    ----------
    f : GltfFile
    n : int
        Number of nodes.
    parent : (n,) int
        Parent node, -1 for a root.
    order : (n,) int
        Every node after its parent.
    T, Q, S : (n, 3), (n, 4), (n, 3) float
        Rest translation, rotation ``(w, x, y, z)`` (unit) and scale of each node.
    matrix : (n,) bool
        True where the node gives a ``matrix`` (split into T, Q, S for animation).
    local : (n, 4, 4) float
        Rest local matrices (a given matrix as it is).
    names : list of str or None
    """

    def __init__(self, f: GltfFile):
        self.f = f
        nodes = f.items("nodes")
        n = len(nodes)
        self.n = n
        parent = np.full(n, -1, dtype=np.int64)
        T = np.zeros((n, 3))
        Q = np.tile([1.0, 0, 0, 0], (n, 1))
        S = np.ones((n, 3))
        local = np.tile(np.eye(4), (n, 1, 1))
        is_matrix = np.zeros(n, dtype=bool)
        names: list[str | None] = []
        for k in range(n):
            node = f.item("nodes", k, f"node {k}")
            where = f"nodes[{k}]"
            nm = f.get(node, "name", "string", where, None)
            names.append(nm)
            for c in f.get(node, "children", "array", where, []):
                if isinstance(c, bool) or not isinstance(c, int) or not 0 <= c < n or c == k:
                    raise f.error(f"{where}.children: node indices in 0..{n - 1} other than "
                                  f"{k}", repr(c))
                if parent[c] >= 0:
                    raise f.error("a tree of nodes (each node the child of one node at most)",
                                  f"node {c} a child of nodes {int(parent[c])} and {k}")
                parent[c] = k
            if "matrix" in node:
                m = np.array(f.numbers(node, "matrix", 16, where, ()), float)
                if not np.isfinite(m).all():
                    raise f.error(f"{where}.matrix: finite numbers", "NaN or infinity")
                M = m.reshape(4, 4).T                      # column-major
                local[k] = M
                is_matrix[k] = True
                T[k], Q[k], S[k] = self._split(M, where)
            else:
                T[k] = f.numbers(node, "translation", 3, where, (0, 0, 0))
                x, y, z, w = f.numbers(node, "rotation", 4, where, (0, 0, 0, 1))
                Q[k] = w, x, y, z
                S[k] = f.numbers(node, "scale", 3, where, (1, 1, 1))
        # the nodes given by translation, rotation and scale, all at once
        trs = np.flatnonzero(~is_matrix)
        big = np.abs(Q[trs]).max(axis=1)
        bad = ~(np.isfinite(T[trs]).all(axis=1) & np.isfinite(S[trs]).all(axis=1)
                & np.isfinite(big) & (big > 0))
        if bad.any():
            k = int(trs[np.flatnonzero(bad)[0]])
            raise f.error(f"nodes[{k}]: a finite translation, a non-zero rotation and a "
                          "finite scale", f"{T[k].tolist()}, {Q[k, [1, 2, 3, 0]].tolist()}, "
                          f"{S[k].tolist()}"[:200])
        q = Q[trs] / big[:, None]               # then the norm cannot overflow
        Q[trs] = q / np.linalg.norm(q, axis=1, keepdims=True)
        local[trs] = trs_matrices(T[trs], Q[trs], S[trs])
        # a cycle never reaches a root: walk up from every node until a node whose
        # depth is known, a root, or a node met before on this walk (a cycle); each
        # node's depth is set once, so the walks take O(n) in all
        depth = np.full(n, -1, dtype=np.int64)
        for k in range(n):
            chain: list[int] = []
            met: dict[int, int] = {}
            x = k
            while x >= 0 and depth[x] < 0:
                if x in met:
                    # the loop, parent before child, from its smallest node
                    loop = chain[met[x]:][::-1]
                    m = loop.index(min(loop))
                    loop = loop[m:] + loop[:m]
                    shown = " -> ".join(map(str, loop[:8])) + (" ..." if len(loop) > 8 else "")
                    raise f.error("a tree of nodes (no cycles)",
                                  f"a cycle through nodes {shown} -> {loop[0]}")
                met[x] = len(chain)
                chain.append(x)
                x = int(parent[x])
            base = -1 if x < 0 else depth[x]
            for m, c in enumerate(reversed(chain)):
                depth[c] = base + 1 + m
        self.parent = parent
        self.depth = depth
        self.order = np.argsort(depth, kind="stable")
        tops = np.arange(n)
        for k in self.order:                    # parents first: each node's tree root
            if parent[k] >= 0:
                tops[k] = tops[parent[k]]
        self.tops = tops
        self.T, self.Q, self.S, self.local, self.matrix = T, Q, S, local, is_matrix
        self.names = names
        self._world = None

    def _split(self, M: np.ndarray, where: str):
        """Translation, rotation and scale of a matrix ``T R S`` (None where it has
        shear or a projective row: such a node can still be drawn, not animated)."""
        t = M[:3, 3].copy()
        A = M[:3, :3]
        big = np.abs(A).max()
        s = big * np.linalg.norm(A / big, axis=0) if big > 0 else np.zeros(3)
        if not np.isfinite(s).all():
            raise self.f.error(f"{where}.matrix: a transform of finite scale",
                               f"columns of length {s.tolist()}")
        if np.any(s == 0):
            return t, np.array([1.0, 0, 0, 0]), s
        R = A / s
        if np.linalg.det(R) < 0:
            s[0], R[:, 0] = -s[0], -R[:, 0]
        return t, tf.matrix_to_quat(polar(R)[0]), s

    # ------------------------------------------------------------------ hierarchy
    def world(self) -> np.ndarray:
        """(n, 4, 4) rest world matrices (where a product of huge transforms overflows:
        not finite; see :meth:`finite_world`)."""
        if self._world is None:
            G = self.local.copy()
            with np.errstate(over="ignore", invalid="ignore"):
                for k in self.order:
                    p = self.parent[k]
                    if p >= 0:
                        G[k] = G[p] @ self.local[k]
            self._world = G
        return self._world

    def finite_world(self, nodes) -> np.ndarray:
        """The rest world matrices of ``nodes``, checked finite (a chain of huge
        transforms overflows)."""
        G = self.world()[nodes]
        bad = ~np.isfinite(G).all(axis=(1, 2))
        if bad.any():
            k = int(np.asarray(nodes)[np.flatnonzero(bad)[0]])
            raise self.f.error(f"nodes[{k}]: a rest transform whose product with its "
                               "parents' is finite", "an overflow (transforms too large)")
        return G

    def ancestors(self, k: int) -> list[int]:
        """Nodes above ``k``, nearest first."""
        out = []
        p = int(self.parent[k])
        while p >= 0:
            out.append(p)
            p = int(self.parent[p])
        return out

    def top(self, k: int) -> int:
        """The root of the tree holding node ``k``."""
        return int(self.tops[k])

    def nearest_above(self, marked) -> np.ndarray:
        """(n,) int: each node's nearest ancestor in ``marked`` (a set of nodes), -1 for
        none; one pass down the hierarchy, so deep trees cost no more than wide ones."""
        up = np.full(self.n, -1, dtype=np.int64)
        for k in self.order:
            p = int(self.parent[k])
            if p >= 0:
                up[k] = p if p in marked else up[p]
        return up

    def upward(self, nodes) -> set[int]:
        """``nodes`` and every node above them (each walk stops at a node already met)."""
        out: set[int] = set()
        for k in nodes:
            k = int(k)
            while k >= 0 and k not in out:
                out.add(k)
                k = int(self.parent[k])
        return out

    def name(self, k: int) -> str:
        """Node ``k``'s name, or ``node<k>``."""
        return self.names[k] or f"node{k}"

    # ------------------------------------------------------------------ skins
    def mesh_nodes(self) -> list[tuple[int, int, int | None]]:
        """(node, mesh, skin or None) of every node with a mesh, in node order."""
        f = self.f
        out = []
        nm, ns = len(f.items("meshes")), len(f.items("skins"))
        for k in range(self.n):
            node = f.items("nodes")[k]
            mesh = f.get(node, "mesh", "index", f"nodes[{k}]", None, below=nm)
            skin = f.get(node, "skin", "index", f"nodes[{k}]", None, below=ns)
            if mesh is not None:
                out.append((k, mesh, skin))
        return out

    def skinned_nodes(self) -> list[tuple[int, int, int]]:
        """(node, mesh, skin) of every node with both a mesh and a skin, in node order."""
        return [c for c in self.mesh_nodes() if c[2] is not None]

    def attached(self, joints) -> list[tuple[int, int, int, np.ndarray]]:
        """Meshes hung rigidly on ``joints`` (a set of node indices): (node, mesh, joint,
        L) of every node with a mesh and no skin that is one of ``joints`` or lies
        below one, in node order; ``joint`` is the nearest such node (itself or above),
        ``L`` the product of the rest local matrices of the nodes from just below
        ``joint`` down to ``node`` (the identity when the node is the joint). One pass
        down the hierarchy: deep chains of nodes cost no more than wide trees."""
        up = self.nearest_above(joints)
        hung = [(k, mesh, k if k in joints else int(up[k]))
                for k, mesh, skin in self.mesh_nodes()
                if skin is None and (k in joints or up[k] >= 0)]
        path = self.upward(k for k, _, j in hung if k != j)
        rel: dict[int, np.ndarray] = {}
        for k in self.order:
            k = int(k)
            if k in path and k not in joints and up[k] >= 0:
                p = int(self.parent[k])
                rel[k] = self.local[k] if p in joints else rel[p] @ self.local[k]
        return [(k, mesh, j, rel[k] if k != j else np.eye(4)) for k, mesh, j in hung]

    def skin_joints(self, s: int) -> list[int]:
        """The joint nodes of skin ``s``, checked: distinct nodes with a common root."""
        f = self.f
        key = ("skin joints", s)
        if key in f.cache:
            return f.cache[key]
        skin = f.item("skins", s, f"skin {s}")
        where = f"skins[{s}]"
        joints = f.get(skin, "joints", "array", where)
        if not joints:
            raise f.error(f"{where}.joints: at least one joint node", "none")
        bad = [j for j in joints if isinstance(j, bool) or not isinstance(j, int)
               or not 0 <= j < self.n]
        if bad:
            raise f.error(f"{where}.joints: joint node indices in 0..{self.n - 1}",
                          repr(bad[0]))
        if len(set(joints)) != len(joints):
            dup = next(j for j in joints if joints.count(j) > 1)
            raise f.error(f"{where}.joints: distinct joint nodes (a tree of joints)",
                          f"node {dup} listed {joints.count(dup)} times")
        tops = sorted({self.top(j) for j in joints})
        if len(tops) > 1:
            raise f.error(f"{where}.joints: joints under one common root node (a tree)",
                          f"joints in {len(tops)} separate node trees (under nodes "
                          f"{', '.join(map(str, tops[:4]))})")
        f.cache[key] = joints
        return joints

    def inverse_binds(self, s: int) -> np.ndarray:
        """(j, 4, 4) inverse bind matrices of skin ``s`` (identity when not given)."""
        f = self.f
        joints = self.skin_joints(s)
        skin = f.item("skins", s, f"skin {s}")
        i = f.get(skin, "inverseBindMatrices", "index", f"skins[{s}]", None)
        if i is None:
            return np.tile(np.eye(4), (len(joints), 1, 1))
        m = read_accessor(f, i, f"skin {s} inverseBindMatrices", types=("MAT4",),
                          components=FLOAT_ONLY)
        if len(m) != len(joints):
            raise f.error(f"skins[{s}]: {len(joints)} inverse bind matrices (one per joint)",
                          f"{len(m)}")
        return m.reshape(-1, 4, 4).transpose(0, 2, 1)       # column-major
