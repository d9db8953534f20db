"""The body parts of a joint hierarchy: which joint is the pelvis, the spine, each arm
and leg, and on which side.

Two readings, the first that finds a body wins:

1. **Names** (:mod:`stbs.retargeting.names`). The joints whose names say an arm or leg
   part are grouped by side and limb; in each group the longest chain of joints (each
   below the one before) is aligned with the limb's roles from the body outwards
   (collar, upper arm, forearm, hand; hip, thigh, shin, foot, toe) by dynamic
   programming, so that an ambiguous name takes the place its chain leaves it
   (``LeftShoulder`` before ``LeftArm`` is the collar, ``lShoulder`` after
   ``lTorso_Clavicle`` the upper arm). A joint off that chain keeps a role only its
   name can mean (an IK-driven ``Foot.L`` parented to the root). The pelvis is the
   joint the legs hang from; the torso's named joints below it are aligned with
   root, pelvis, spine..., neck..., head.
2. **Structure**, for joints without telling names (``joint_0``, ``joint_1`` ...): the
   legs and the arms are the two pairs of mirror-image branches (the pair nearer the
   root: the legs); the spine runs between the two branching joints, the neck and
   head beyond the upper one. Along a leg, the thigh is the first long bone pointing
   away from the spine, then shin, foot and toe; along an arm, a first bone that
   starts near the spine's line is the collar, then upper arm, forearm and hand. The
   sides come from the feet: a character's forward is where its toes point, and its
   left is ``up × forward``.

Repeated roles (several spine or neck joints) carry a *span*: where along the spine
(or neck) the joint's bone lies, from 0 (the first) to 1 (the last one's end), by
length, so that chains of different counts can be matched by position.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .names import ARM, LEG, TORSO, candidates, parse_name

__all__ = ["Tree", "Body", "read_body"]

_MULTI = ("spine", "neck")
# A branch is a limb when it reaches this far (a fraction of the skeleton's size).
_LIMB_REACH = 0.12
# Mirror images to this error (a fraction of the size) are a pair of limbs.
_MIRROR_ERROR = 0.06


class Tree:
    """A joint hierarchy in one pose: parents, positions, and which joints are tips
    (ends of chains that turn nothing: BVH end sites, the tails of leaf bones).

    Parameters
    ----------
    parents : (n,) int
        -1 for roots; any order.
    X : (n, 3) float
        Positions.
    tips : (n,) bool
    """

    def __init__(self, parents, X, tips):
        self.parents = np.asarray(parents, dtype=np.int64)
        self.X = np.asarray(X, dtype=float)
        self.tips = np.asarray(tips, dtype=bool)
        n = self.parents.size
        self.n = n
        self.kids: list[list[int]] = [[] for _ in range(n)]
        for k, p in enumerate(self.parents):
            if p >= 0:
                self.kids[p].append(k)
        # depth by a walk down from the roots: linear, however deep the tree
        depth = np.zeros(n, dtype=np.int64)
        stack = [k for k in range(n) if self.parents[k] < 0]
        while stack:
            k = stack.pop()
            for c in self.kids[k]:
                depth[c] = depth[k] + 1
                stack.append(c)
        self.depth = depth
        ext = np.ptp(self.X, axis=0) if n else np.zeros(3)
        self.size = float(np.linalg.norm(ext)) or 1.0
        # reach: the longest way down to a tip; main: the child on that way
        self.reach = np.zeros(n)
        self.main = np.full(n, -1, dtype=np.int64)
        for k in np.argsort(-depth, kind="stable"):
            best = -1.0
            for c in self.kids[k]:
                r = float(np.linalg.norm(self.X[c] - self.X[k])) + self.reach[c]
                if r > best:
                    best, self.main[k] = r, c
            self.reach[k] = max(best, 0.0)

    def branch(self, k: int, c: int) -> float:
        """How far the branch from joint k through its child c reaches."""
        return float(np.linalg.norm(self.X[c] - self.X[k])) + self.reach[c]

    def path(self, k: int) -> list[int]:
        """Joint k and its main descendants down to a tip."""
        out = [k]
        while self.main[out[-1]] >= 0:
            out.append(int(self.main[out[-1]]))
        return out

    def segment_end(self, k: int) -> int:
        """The first joint down the main path away from k's place (-1: none)."""
        tol = 1e-6 * self.size
        c = int(self.main[k])
        while c >= 0 and np.linalg.norm(self.X[c] - self.X[k]) <= tol:
            c = int(self.main[c])
        return c

    def ancestors(self, k: int) -> list[int]:
        out, p = [], int(self.parents[k])
        while p >= 0 and len(out) <= self.n:
            out.append(p)
            p = int(self.parents[p])
        return out

    def is_below(self, k: int, a: int) -> bool:
        """True when a is a proper ancestor of k."""
        return a in self.ancestors(k)


@dataclass
class Body:
    """Roles of a hierarchy's joints (see the module docs).

    Attributes
    ----------
    role : list of str or None
        Per joint: a role of :data:`stbs.retargeting.names.ROLES`, or None.
    side : list of str
        Per joint: ``"l"``, ``"r"`` or ``""``.
    span : (n, 2) float
        For spine and neck joints, where the joint's bone lies along its group (0..1).
    how : str
        ``"names"`` or ``"structure"``: what the roles were read from.
    depth : (n,) int
        Per joint, its number of ancestors.
    """

    role: list
    side: list
    span: np.ndarray
    how: str
    depth: np.ndarray

    def find(self, role: str, side: str = "") -> list[int]:
        """Joints with this role and side, nearest the root first."""
        got = [k for k, (r, s) in enumerate(zip(self.role, self.side, strict=True))
               if r == role and s == side]
        return sorted(got, key=lambda k: (self.depth[k], k))

    def first(self, role: str, side: str = "") -> int:
        got = self.find(role, side)
        return got[0] if got else -1

    @property
    def pelvis(self) -> int:
        return self.first("pelvis")

    def limbs(self, kind: str) -> dict[str, dict[str, int]]:
        """``{side: {role: joint}}`` of the arms (``kind="arm"``) or legs."""
        roles = ARM if kind == "arm" else LEG
        out: dict[str, dict[str, int]] = {}
        for k, (r, s) in enumerate(zip(self.role, self.side, strict=True)):
            if r in roles:
                out.setdefault(s, {}).setdefault(r, k)
        return out

    def count(self) -> int:
        return sum(r is not None for r in self.role)


# ------------------------------------------------------------------ alignment
def _align_chain(nodes: list[int], template: tuple[str, ...], score) -> dict[int, str]:
    """Roles for ``nodes`` (in chain order) taken in ``template`` order, maximising the
    sum of ``score(node, role)`` (None: not allowed) by dynamic programming; spine and
    neck may repeat; a small cost for each role skipped between two assigned ones
    breaks ties toward neighbours (``ShoulderLeft`` right before ``ElbowLeft`` is the
    upper arm)."""
    m = len(template)
    NEG = -1e18
    best = np.full(m + 1, NEG)
    best[0] = 0.0
    # choice[k][state] = (previous state, assigned?) for node k ending in state
    choice: list[list[tuple[int, bool]]] = []
    for v in nodes:
        new = best.copy()
        ch = [(s, False) for s in range(m + 1)]
        for s in range(m):
            sc = score(v, template[s])
            if sc is None:
                continue
            for r in range(-1, m):
                if best[r + 1] <= NEG / 2 or not (s > r or (s == r and template[s] in _MULTI)):
                    continue
                gap = 0.1 * (s - r - 1) if r >= 0 and s > r else 0.0
                val = best[r + 1] + sc - gap
                if val > new[s + 1] + 1e-12:
                    new[s + 1] = val
                    ch[s + 1] = (r + 1, True)
        choice.append(ch)
        best = new
    out: dict[int, str] = {}
    state = int(np.argmax(best))
    for v, ch in zip(reversed(nodes), reversed(choice), strict=True):
        prev, took = ch[state]
        if took:
            out[v] = template[state - 1]
        state = prev
    return out


def _longest_chain(tree: Tree, group: list[int], weight) -> list[int]:
    """The longest run of group joints each below the one before (ties: by weight)."""
    members = set(group)
    order = sorted(group, key=lambda k: (tree.depth[k], k))
    prev: dict[int, int] = {}
    length: dict[int, tuple[int, float]] = {}
    for k in order:
        up = next((a for a in tree.ancestors(k) if a in members), -1)
        prev[k] = up
        base = length[up] if up >= 0 else (0, 0.0)
        length[k] = (base[0] + 1, base[1] + weight(k))
    if not length:
        return []
    end = max(order, key=lambda k: length[k])
    chain = [end]
    while prev[chain[-1]] >= 0:
        chain.append(prev[chain[-1]])
    return chain[::-1]


def _spans(tree: Tree, chain: list[int], roles: dict[int, str]) -> dict[int, tuple[float, float]]:
    """Spans of the repeated roles along a chain (by length between the joints)."""
    pos = np.zeros(len(chain))
    for k in range(1, len(chain)):
        pos[k] = pos[k - 1] + np.linalg.norm(tree.X[chain[k]] - tree.X[chain[k - 1]])
    out: dict[int, tuple[float, float]] = {}
    for role in _MULTI:
        idx = [k for k, v in enumerate(chain) if roles.get(v) == role]
        if not idx:
            continue
        ends = []
        for k in idx:
            if k + 1 < len(chain):
                ends.append(pos[k + 1])
            else:
                e = tree.segment_end(chain[k])
                ends.append(pos[k] + (np.linalg.norm(tree.X[e] - tree.X[chain[k]])
                                      if e >= 0 else 0.0))
        a, b = pos[idx[0]], max(ends[-1], pos[idx[-1]])
        width = b - a
        for k, e in zip(idx, ends, strict=True):
            if width <= 1e-12:
                out[chain[k]] = (0.0, 1.0)
            else:
                out[chain[k]] = ((pos[k] - a) / width, (e - a) / width)
    return out


def _empty(tree: Tree, how: str) -> Body:
    n = tree.n
    return Body([None] * n, [""] * n, np.zeros((n, 2)), how, tree.depth)


# ------------------------------------------------------------------ by names
class _Names:
    """What the joints' names say: each joint's parsed name and candidate roles (with
    their scores), and the chains of a group they best fill."""

    def __init__(self, tree: Tree, names):
        self.tree = tree
        n = tree.n
        self.parsed = [None if (nm is None or tree.tips[k]) else parse_name(nm)
                       for k, nm in enumerate(names)]
        self.cand = [{} if p is None else candidates(p) for p in self.parsed]
        tol = 1e-6 * tree.size
        self.zero = np.array([tree.segment_end(k) < 0
                              or np.linalg.norm(tree.X[tree.main[k]] - tree.X[k]) <= tol
                              if tree.main[k] >= 0 else True for k in range(n)])

    def score(self, k, role, extra=None):
        """How well joint ``k``'s name means ``role`` (with ``extra`` points), or None."""
        c = self.cand[k].get(role)
        if extra is not None and role in extra.get(k, {}):
            c = (c or 0) + extra[k][role]
        if c is None:
            return None
        # of two joints at one place named alike, the one whose bone has a length
        return c - (0.5 if self.zero[k] else 0.0)

    def groups(self) -> dict[tuple[str, str], list[int]]:
        """(side, "leg" | "arm" | "torso") -> the joints whose names mean only such
        roles, in joint order."""
        groups: dict[tuple[str, str], list[int]] = {}
        for k in range(self.tree.n):
            roles = set(self.cand[k])
            if not roles:
                continue
            side = self.parsed[k].side
            if roles <= set(LEG):
                groups.setdefault((side, "leg"), []).append(k)
            elif roles <= set(ARM):
                groups.setdefault((side, "arm"), []).append(k)
            elif roles <= set(TORSO) and side == "":
                groups.setdefault(("", "torso"), []).append(k)
        return groups

    def assign(self, group, template, extra=None):
        """The longest chain through ``group``, its joints' roles from ``template``
        (and the roles only a name off the chain can mean), the chain's joints that
        got one."""
        cand = self.cand
        chain = _longest_chain(self.tree, group, lambda k: max(cand[k].values(), default=0))
        got = _align_chain(chain, template, lambda k, r: self.score(k, r, extra))
        on_chain = [k for k in chain if k in got]
        for k in group:                    # off the chain: a role only its name can mean
            if k in got or len(cand[k]) != 1:
                continue
            (role, sc), = cand[k].items()
            if sc >= 3 and role not in got.values():
                got[k] = role
        return chain, got, on_chain


def _pelvis_of_legs(tree: Tree, body: Body, legs: dict[str, list[int]]) -> int:
    """The joint the legs hang from (-1: none, or one that already has a role)."""
    tops = []
    for chain in legs.values():
        if chain:
            first = chain[0]
            if tree.parents[first] >= 0:
                tops.append(int(tree.parents[first]))
    pelvis = -1
    if tops:
        common = [a for a in [tops[0]] + tree.ancestors(tops[0])
                  if all(a == t or a in tree.ancestors(t) for t in tops)]
        pelvis = common[0] if common else tops[0]
        if body.role[pelvis] is not None:
            pelvis = -1
    return pelvis


def _by_names(tree: Tree, names) -> Body:
    body = _empty(tree, "names")
    nm = _Names(tree, names)
    groups = nm.groups()
    legs = {}
    for (side, kind), group in groups.items():
        if kind == "leg":
            _, got, on_chain = nm.assign(group, LEG)
            legs[side] = on_chain
            for k, r in got.items():
                body.role[k], body.side[k] = r, side
        elif kind == "arm":
            _, got, _ = nm.assign(group, ARM)
            for k, r in got.items():
                body.role[k], body.side[k] = r, side
    pelvis = _pelvis_of_legs(tree, body, legs)
    torso = list(groups.get(("", "torso"), []))
    extra: dict[int, dict[str, int]] = {}
    if pelvis >= 0:
        if pelvis not in torso:
            torso.append(pelvis)
        extra[pelvis] = {"pelvis": 4}
        # the torso runs up from the pelvis: named joints beside it are not on it
        torso = [k for k in torso if k == pelvis or tree.is_below(k, pelvis)
                 or tree.is_below(pelvis, k)]
    if torso:
        chain, got, _ = nm.assign(torso, TORSO, extra)
        for k, r in got.items():
            body.role[k] = r
        for k, s in _spans(tree, chain, got).items():
            body.span[k] = s
    return body


# ------------------------------------------------------------------ by structure
def _mirror_error(tree: Tree, a: int, b: int) -> float:
    pa = [k for k in tree.path(a) if not tree.tips[k]]
    pb = [k for k in tree.path(b) if not tree.tips[k]]
    K = min(len(pa), len(pb), 4)
    if K < 2:
        return np.inf
    P, Q = tree.X[pa[:K]], tree.X[pb[:K]]
    # a reflection keeps lengths: compare the bones' first
    la = np.linalg.norm(np.diff(P, axis=0), axis=1)
    lb = np.linalg.norm(np.diff(Q, axis=0), axis=1)
    if np.any(np.abs(la - lb) > 0.25 * np.maximum(np.maximum(la, lb), 1e-9 * tree.size)):
        return np.inf
    nv = (P - Q).mean(axis=0)
    if np.linalg.norm(nv) <= 1e-9 * tree.size:
        return np.inf
    nv = nv / np.linalg.norm(nv)
    m = 0.5 * (P + Q).mean(axis=0)
    Pm = P - 2.0 * ((P - m) @ nv)[:, None] * nv
    return float(np.linalg.norm(Pm - Q, axis=1).mean() / tree.size)


def _pairs(tree: Tree) -> dict[int, tuple[int, int, float]]:
    """Per branching joint, its best pair of mirror-image long branches."""
    out = {}
    for k in range(tree.n):
        long = [c for c in tree.kids[k] if tree.branch(k, c) >= _LIMB_REACH * tree.size]
        best = None
        for i in range(len(long)):
            for j in range(i + 1, len(long)):
                a, b = long[i], long[j]
                ra, rb = tree.branch(k, a), tree.branch(k, b)
                err = _mirror_error(tree, a, b) + 0.05 * abs(ra - rb) / max(ra, rb)
                if err < _MIRROR_ERROR and (best is None or err < best[2]):
                    best = (a, b, err)
        if best is not None:
            out[k] = best
    return out


def _unit(v):
    n = np.linalg.norm(v)
    return v / n if n > 1e-12 else None


def _pelvis_and_chest(tree: Tree, pairs: dict) -> tuple[int, int] | None:
    """The two heaviest joints with a mirrored pair of branches: the lower one the
    pelvis, the one above it the chest (None: neither is above the other)."""
    weight = {k: tree.branch(k, a) + tree.branch(k, b) for k, (a, b, _) in pairs.items()}
    top = sorted(pairs, key=lambda k: -weight[k])[:2]
    k0, k1 = top
    if tree.is_below(k1, k0):
        return k0, k1
    if tree.is_below(k0, k1):
        return k1, k0
    return None


def _structure_torso(tree: Tree, body: Body, pelvis: int, chest: int, arms) -> None:
    """The roles of the torso: root above the pelvis, spine up to the chest, and neck
    and head on the chest's heaviest branch that is not an arm; with their spans."""
    body.role[pelvis] = "pelvis"
    for a in tree.ancestors(pelvis):
        if not tree.tips[a]:
            body.role[a] = "root"
    spine = [chest]
    while tree.parents[spine[-1]] != pelvis:
        spine.append(int(tree.parents[spine[-1]]))
    torso_chain = [pelvis] + spine[::-1]
    for k in spine:
        body.role[k] = "spine"
    rest = [c for c in tree.kids[chest] if c not in arms]
    if rest:
        c = max(rest, key=lambda c: tree.branch(chest, c))
        neck = [k for k in tree.path(c) if not tree.tips[k]]
        if neck:
            body.role[neck[-1]] = "head"
            for k in neck[:-1]:
                body.role[k] = "neck"
            torso_chain += neck
    got = {k: body.role[k] for k in torso_chain}
    for k, s in _spans(tree, torso_chain, got).items():
        body.span[k] = s


def _segments(tree: Tree, start: int) -> list[tuple[int, np.ndarray]]:
    """(joint, bone vector) along a limb's main path; short bones are passed over
    (a zero-length joint, a knuckle), but not the last joint, whose bone (a leaf's
    tail) may be short."""
    path = [k for k in tree.path(start) if not tree.tips[k]]
    out = []
    for k in path:
        e = tree.segment_end(k)
        if e < 0:
            continue
        seg = tree.X[e] - tree.X[k]
        if np.linalg.norm(seg) >= 0.03 * tree.size or (k == path[-1] and out):
            out.append((k, seg))
    return out


def _leg_roles(tree: Tree, starts, up: np.ndarray) -> dict[int, dict[int, str]]:
    """Leg start -> the roles of its joints: the thigh from the first long bone that
    points down (a hip above it), then shin, foot and toe."""
    legs = {}
    for a in starts:
        segs = _segments(tree, a)
        if not segs:
            continue
        long = [i for i, (_, s) in enumerate(segs) if np.linalg.norm(s) >= 0.1 * tree.size]
        down = [i for i in long if -(segs[i][1] @ up) >= 0.5 * np.linalg.norm(segs[i][1])]
        t = (down or long or [0])[0]
        roles = {}
        if t > 0:
            roles[segs[t - 1][0]] = "hip"
        for r, (k, _) in zip(("thigh", "shin", "foot", "toe"), segs[t:], strict=False):
            roles[k] = r
        legs[a] = roles
    return legs


def _forward(tree: Tree, legs: dict[int, dict[int, str]], up: np.ndarray) -> np.ndarray:
    """The body's forward: where the feet point (the foot's bone, across the up axis),
    else the usual facing of rigs."""
    tol = 1e-6 * tree.size
    fwd = np.zeros(3)
    for roles in legs.values():
        foot = next((k for k, r in roles.items() if r == "foot"), -1)
        if foot >= 0:
            e = tree.segment_end(foot)
            d = tree.X[e] - tree.X[foot]
            d = d - (d @ up) * up
            if np.linalg.norm(d) > tol:
                fwd += d / np.linalg.norm(d)
    fwd = _unit(fwd)
    if fwd is None:
        # the usual facing of rigs: +z when y is up (glTF), -y when z is up (Blender)
        ax = int(np.argmax(np.abs(up)))
        fwd = np.array([0, 0, 1.0]) if ax == 1 else np.array([0, -1.0, 0])
        fwd = _unit(fwd - (fwd @ up) * up)
        if fwd is None:
            fwd = _unit(np.cross(up, [1.0, 0, 0])) or np.array([0, 0, 1.0])
    return fwd


def _sides(tree: Tree, a: int, b: int, left: np.ndarray) -> tuple[str, str]:
    """The sides ("l", "r") of the limbs starting at ``a`` and ``b``."""
    pa = [k for k in tree.path(a) if not tree.tips[k]]
    pb = [k for k in tree.path(b) if not tree.tips[k]]
    d = tree.X[pa].mean(axis=0) - tree.X[pb].mean(axis=0)
    return ("l", "r") if d @ left >= 0 else ("r", "l")


def _arm_roles(tree: Tree, body: Body, chest: int, arms, up: np.ndarray,
               left: np.ndarray) -> None:
    """The roles and sides of the arms' joints (a collar where the arm's first bone
    starts close to the chest's axis)."""
    for node, side in zip(arms, _sides(tree, *arms, left), strict=True):
        segs = _segments(tree, node)
        if not segs:
            continue
        tip = tree.X[tree.path(node)[-1]] - tree.X[chest]
        reach = np.linalg.norm(tip - (tip @ up) * up)
        start = tree.X[segs[0][0]] - tree.X[chest]
        lateral = np.linalg.norm(start - (start @ up) * up)
        names = ARM if len(segs) >= 4 and lateral < 0.12 * reach else ARM[1:]
        for r, (k, _) in zip(names, segs, strict=False):
            body.role[k], body.side[k] = r, side


def _by_structure(tree: Tree) -> Body | None:
    pairs = _pairs(tree)
    if len(pairs) < 2:
        return None
    found = _pelvis_and_chest(tree, pairs)
    if found is None:
        return None
    pelvis, chest = found
    up = _unit(tree.X[chest] - tree.X[pelvis])
    if up is None:
        return None
    body = _empty(tree, "structure")
    arms = pairs[chest][:2]
    _structure_torso(tree, body, pelvis, chest, arms)
    legs = _leg_roles(tree, pairs[pelvis][:2], up)
    left = np.cross(up, _forward(tree, legs, up))
    a, b = pairs[pelvis][:2]
    for node, side in zip((a, b), _sides(tree, a, b, left), strict=True):
        for k, r in legs.get(node, {}).items():
            body.role[k], body.side[k] = r, side
    _arm_roles(tree, body, chest, arms, up, left)
    return body


def read_body(names, parents, X, tips) -> Body:
    """The roles of a hierarchy's joints (see the module docs).

    Parameters
    ----------
    names : sequence of str or None
        Joint names (None for tips).
    parents : (n,) int
    X : (n, 3) float
        Positions in a pose where the body is recognisable (a rest pose).
    tips : (n,) bool
        Joints that turn nothing (end sites, tails of leaf bones).

    Returns
    -------
    Body
    """
    tree = Tree(parents, X, tips)
    by_names = _by_names(tree, names)
    limbs = [g for kind in ("arm", "leg") for g in by_names.limbs(kind).values() if len(g) >= 2]
    if by_names.pelvis >= 0 and len(limbs) >= 2:
        return by_names
    by_structure = _by_structure(tree)
    if by_structure is not None and by_structure.count() >= by_names.count():
        return by_structure
    return by_names
