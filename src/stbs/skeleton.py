"""The rig's skeleton: joints ``C``, directed bones ``BE`` and parent bones ``P``."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from . import _arrays


class Skeleton:
    """A forest of directed bones between joints, with a parent bone for each bone.

    Parameters
    ----------
    C : (j, d) float
        Rest joint positions, d = 2 or 3.
    BE : (b, 2) int
        Bones as directed joint pairs: bone i runs from ``C[BE[i, 0]]`` to ``C[BE[i, 1]]``.
    names : sequence of b str, optional
        Bone names (unique). Defaults to ``"bone0"``, ``"bone1"``, ...
    P : (b,) int, optional
        Parent bone of each bone, -1 for roots. A child whose start joint is its
        parent's end joint is *connected*; any other child is an *offset child*
        (shoulders off the chest, legs off the hips), carried by its parent's map at
        the point where it hangs (DESIGN §2). Default: inferred from shared joints,
        the parent of a bone being the bone that ends at its start joint (so every
        child is connected).

    Attributes
    ----------
    parents : (b,) int
        Parent bone, -1 for roots (``P``).
    connected : (b,) bool
        True for a child that starts at its parent's end joint.
    hang : (b,) float
        ``t_c`` in [0, 1]: where a child hangs on its parent bone, the projection of
        its start on the parent bone clamped to [0, 1]; 1 for a connected child, 0 for
        a root.
    lengths : (b,) float
        Rest bone lengths ``|b_i - a_i|``.
    axes : (b, d) float
        Unit rest axes ``u_i``.
    dim : int
        2 or 3.
    roots : (r,) int
        Bones without a parent.
    order : (b,) int
        A topological order: every bone comes after its parent.
    depth : (b,) int
        Number of ancestors of each bone (0 for a root).

    Raises
    ------
    ValueError
        For joint indices out of range, a bone listed twice (in either direction),
        a zero-length bone, a bone with two parents (without ``P``), a parent out of
        range or a cycle; the message names the bone.

    Examples
    --------
    A hip bone with a leg hanging off its start (an offset child):

    >>> import stbs
    >>> sk = stbs.Skeleton([[0, 0, 0], [0, 1, 0], [0.2, 0, 0], [0.2, -1, 0]],
    ...                    [[0, 1], [2, 3]], names=["hips", "leg"], P=[-1, 0])
    >>> sk.parents.tolist(), sk.connected.tolist(), sk.hang.tolist()
    ([-1, 0], [False, False], [0.0, 0.0])
    """

    def __init__(self, C, BE, names: Sequence[str] | None = None, P=None):
        C = _arrays.real_array("C", C, ndim=2)
        if C.shape[1] not in (2, 3):
            raise ValueError(f"C must have shape (j, 2) or (j, 3), got {C.shape}")
        BE = _arrays.index_array("BE", BE, ndim=2, shape=(None, 2))
        if BE.shape[0] == 0:
            raise ValueError("BE must hold at least one bone, got shape (0, 2)")
        names = _bone_names(names, BE.shape[0])
        self.C = C
        self.BE = BE
        self.names = names

        def label(i: int) -> str:
            return f"bone {i} ({names[i]!r}, joints {BE[i, 0]}->{BE[i, 1]})"

        _check_bones(C, BE, label)
        vec = C[BE[:, 1]] - C[BE[:, 0]]
        lengths = np.linalg.norm(vec, axis=1)
        scale = max(float(np.abs(C).max()), 1.0)
        zero = np.flatnonzero(lengths <= 1e-12 * scale)
        if zero.size:
            i = int(zero[0])
            raise ValueError(f"BE: {label(i)} has zero length; STBS needs a bone direction "
                             "(merge the joints or drop the bone)")
        parents = _parents_from_joints(BE, label) if P is None else _given_parents(P, label,
                                                                                   len(BE))
        # Topological order by depth; a bone no root reaches lies on (or under) a cycle.
        depth = tree_depths(parents)
        if (depth < 0).any():
            i = _on_cycle(parents, depth)
            raise ValueError(f"{'BE' if P is None else 'P'}: {label(i)} lies on a cycle of "
                             "bones")
        self.parents = parents
        self.connected, self.hang = _hangs(C, BE, parents, vec, lengths)
        self.lengths = lengths
        self.axes = vec / lengths[:, None]
        self.dim = int(C.shape[1])
        self.roots = np.flatnonzero(parents < 0)
        self.order = np.argsort(depth, kind="stable")
        self.depth = depth
        for arr in (self.C, self.BE, self.parents, self.connected, self.hang, self.lengths,
                    self.axes, self.roots, self.order, self.depth):
            arr.setflags(write=False)

    @property
    def P(self) -> np.ndarray:
        """(b,) parent bone of each bone, -1 for roots (the same array as ``parents``)."""
        return self.parents

    @property
    def n_bones(self) -> int:
        """Number of bones b."""
        return int(self.BE.shape[0])

    @property
    def n_joints(self) -> int:
        """Number of joints j."""
        return int(self.C.shape[0])

    @property
    def A(self) -> np.ndarray:
        """(b, d) rest start joints ``a_i``."""
        return self.C[self.BE[:, 0]]

    @property
    def B(self) -> np.ndarray:
        """(b, d) rest end joints ``b_i``."""
        return self.C[self.BE[:, 1]]

    def levels(self) -> list[np.ndarray]:
        """Bones grouped by depth: roots first, then their children, and so on."""
        return [np.flatnonzero(self.depth == k) for k in range(int(self.depth.max()) + 1)]

    def bone_index(self, key: int | str) -> int:
        """Index of a bone given by index (int or digit string) or by name."""
        if isinstance(key, (int, np.integer)) and not isinstance(key, bool):
            i = int(key)
        elif isinstance(key, str) and key in self.names:
            return self.names.index(key)
        elif isinstance(key, str) and key.lstrip("-").isdigit():
            i = int(key)
        else:
            raise ValueError(f"bone {key!r} does not exist; bones are 0..{self.n_bones - 1} "
                             f"or names {self.names[:8]}{'...' if self.n_bones > 8 else ''}")
        if not 0 <= i < self.n_bones:
            raise ValueError(f"bone {key!r} does not exist; bones are 0..{self.n_bones - 1}")
        return i

    def __eq__(self, other: object) -> bool:
        """Equal joints (exactly), bones, parents and names: poses of equal skeletons compose."""
        if self is other:
            return True
        if not isinstance(other, Skeleton):
            return NotImplemented
        return (self.C.shape == other.C.shape and self.BE.shape == other.BE.shape
                and bool(np.array_equal(self.C, other.C))
                and bool(np.array_equal(self.BE, other.BE))
                and bool(np.array_equal(self.parents, other.parents))
                and self.names == other.names)

    def __hash__(self) -> int:
        return hash((self.C.shape, self.C.tobytes(), self.BE.tobytes(), self.parents.tobytes(),
                     tuple(self.names)))

    def __repr__(self) -> str:
        return (f"Skeleton({self.n_joints} joints, {self.n_bones} bones, {self.dim}D, "
                f"{self.roots.size} root{'s' if self.roots.size != 1 else ''})")


def tree_depths(parents) -> np.ndarray:
    """The depth of each node of a forest given by its parents (-1 for a root): 0 for a
    root, 1 for its children and so on; -1 for a node no root reaches (one on a cycle,
    or below one). One walk down from the roots: linear however deep the tree."""
    p = np.asarray(parents, dtype=np.int64).tolist()
    n = len(p)
    kids: list[list[int]] = [[] for _ in range(n)]
    for i, q in enumerate(p):
        if 0 <= q < n:
            kids[q].append(i)
    depth = [-1] * n
    stack = [i for i, q in enumerate(p) if q < 0]
    for i in stack:
        depth[i] = 0
    while stack:
        k = stack.pop()
        for c in kids[k]:
            depth[c] = depth[k] + 1
            stack.append(c)
    return np.array(depth, dtype=np.int64)


def _on_cycle(parents: np.ndarray, depth: np.ndarray) -> int:
    """A node on a cycle, given the depths of :func:`tree_depths` (some are -1)."""
    k = int(np.flatnonzero(depth < 0)[0])
    seen = set()
    while k not in seen:        # walking up from an unreached node ends on its cycle
        seen.add(k)
        k = int(parents[k])
    return k


def _bone_names(names, b: int) -> list[str]:
    """One unique name per bone (default ``bone0``, ``bone1``, ...)."""
    if names is None:
        names = [f"bone{i}" for i in range(b)]
    names = [str(s) for s in names]
    if len(names) != b:
        raise ValueError(f"names must have {b} entries (one per bone), got {len(names)}")
    if len(set(names)) != b:
        dup = next(s for s in names if names.count(s) > 1)
        raise ValueError(f"names must be unique, got {dup!r} twice")
    return names


def _check_bones(C: np.ndarray, BE: np.ndarray, label) -> None:
    """Every bone joins two different joints of ``C``, and no two bones join the same."""
    j = C.shape[0]
    bad = np.flatnonzero((BE < 0).any(axis=1) | (BE >= j).any(axis=1))
    if bad.size:
        raise ValueError(f"BE: {label(int(bad[0]))} refers to a joint outside 0..{j - 1}")
    seen: dict[tuple[int, int], int] = {}
    for i, (s, e) in enumerate(BE.tolist()):
        if s == e:
            raise ValueError(f"BE: {label(i)} starts and ends at the same joint")
        key = (min(s, e), max(s, e))
        if key in seen:
            raise ValueError(f"BE: {label(i)} is listed twice (also bone {seen[key]})")
        seen[key] = i


def _parents_from_joints(BE: np.ndarray, label) -> np.ndarray:
    """Each bone's parent: the one bone that ends where it starts (-1: none)."""
    parents = np.full(len(BE), -1, dtype=np.int64)
    for i, s in enumerate(BE[:, 0].tolist()):
        enders = np.flatnonzero(BE[:, 1] == s)
        if enders.size > 1:
            raise ValueError(
                f"BE: {label(i)} has {enders.size} parents (bones "
                f"{', '.join(map(str, enders.tolist()))} all end at joint {s}); "
                "give P to say which bone is its parent")
        if enders.size == 1:
            parents[i] = enders[0]
    return parents


def _given_parents(P, label, b: int) -> np.ndarray:
    """``P`` checked: one parent per bone in -1..b-1, none its own."""
    parents = _arrays.index_array("P", P, ndim=1, shape=(b,)).astype(np.int64)
    bad = np.flatnonzero((parents < -1) | (parents >= b))
    if bad.size:
        i = int(bad[0])
        raise ValueError(f"P: {label(i)} has parent {int(parents[i])}, outside -1..{b - 1}")
    own = np.flatnonzero(parents == np.arange(b))
    if own.size:
        raise ValueError(f"P: {label(int(own[0]))} is its own parent")
    return parents


def _hangs(C, BE, parents, vec, lengths) -> tuple[np.ndarray, np.ndarray]:
    """Which bones start at their parent's end (connected), and where each child hangs
    on its parent: t_c of DESIGN §2, the start's projection on the parent bone clamped
    to [0, 1] (1 for a connected child, 0 for a root)."""
    has = parents >= 0
    connected = np.zeros(len(BE), dtype=bool)
    connected[has] = BE[has, 0] == BE[parents[has], 1]
    hang = np.zeros(len(BE))
    off = has & ~connected
    if off.any():
        p = parents[off]
        rel = C[BE[off, 0]] - C[BE[p, 0]]
        hang[off] = np.clip(np.einsum("bi,bi->b", rel, vec[p]) / lengths[p] ** 2, 0, 1)
    hang[connected] = 1.0
    return connected, hang
