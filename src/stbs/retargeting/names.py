"""What a joint's name says: its side and the body part it may be.

Capture files and rigs name the same joint in many ways: ``LeftForeArm`` (CMU,
Mixamo ``mixamorig:LeftForeArm``, LAFAN), ``LowerArm_L`` (Bandai Namco),
``lElbow`` (short side-prefixed names), ``forearm.L`` (Blender, Rigify ``DEF-forearm.L``),
``lowerarm_l`` (Unreal), ``Bip01 L Forearm`` (3ds Max Biped), ``ElbowLeft`` (Kinect).
:func:`parse_name` reads any of them as a side and the words of the name;
:func:`candidates` lists the *roles* (:data:`ROLES`) a name may stand for, with a
score. Several names are ambiguous on their own and are settled by the joint's place
in its chain (:mod:`stbs.retargeting.body`): ``shoulder`` is the collar bone in CMU,
Mixamo and Bandai Namco files but the upper arm when a ``clavicle``/``collar`` joint
comes before it (short side-prefixed names such as ``lShoulder``, Kinect, the older
CMU conversions); ``leg`` is the shin after an ``upleg`` (CMU, Mixamo) and the thigh
of a chain ``Leg01, Leg02``; a sided ``hip`` is the thigh (``lHip``) or the pelvis's
side piece before it (``LHipJoint``).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

__all__ = ["ROLES", "TORSO", "ARM", "LEG", "Name", "parse_name", "candidates"]

#: Torso roles from the root to the head (``spine`` and ``neck`` may repeat).
TORSO = ("root", "pelvis", "spine", "neck", "head")
#: Arm roles from the body outwards.
ARM = ("collar", "upperarm", "forearm", "hand")
#: Leg roles from the body outwards (``hip``: the pelvis's side piece before the thigh).
LEG = ("hip", "thigh", "shin", "foot", "toe")
#: Every role, each a place in one of the three chains.
ROLES = TORSO + ARM + LEG

# word -> (role, score): 3 the name says it, 2 or 1 it may (settled by the chain).
_WORDS: dict[str, tuple[tuple[str, int], ...]] = {}


def _add(words: str, *roles: tuple[str, int]) -> None:
    for w in words.split():
        _WORDS[w] = roles


_add("hips pelvis", ("pelvis", 3))
_add("root", ("root", 2), ("pelvis", 1))
_add("spine back lowerback upperback abdomen abdomin torso chest upperchest thorax waist "
     "belly stomach ribcage", ("spine", 3))
_add("neck lowerneck upperneck", ("neck", 3))
_add("head", ("head", 3))
_add("clavicle collar collarbone clav", ("collar", 3))
_add("shoulder", ("collar", 2), ("upperarm", 2))
_add("upperarm uparm arm humerus bicep", ("upperarm", 3))
_add("forearm lowerarm loarm elbow radius ulna", ("forearm", 3))
_add("hand wrist", ("hand", 3))
_add("palm", ("hand", 1))
_add("hip hipjoint", ("hip", 2), ("thigh", 2))
_add("upleg upperleg thigh femur", ("thigh", 3))
_add("leg", ("thigh", 1), ("shin", 2))
_add("lowerleg loleg shin calf knee tibia crus", ("shin", 3))
_add("foot ankle", ("foot", 3))
_add("toe toes toebase ball", ("toe", 3))

#: Words of joints that are not the body part they name: ends of chains, twist and
#: roll helpers, IK targets, eyes, fingers (fingers follow the hand).
_NOT_A_PART = set("end top tip nub site effector twist roll ik pole target eye eyes jaw "
                  "tongue thumb index middle ring pinky little finger fingers digit "
                  "ear ears tail weapon prop".split())
#: Words that carry no meaning: namespaces and rig prefixes.
_IGNORE = set("joint jnt jt bone bn def org mch drv fk mixamorig bip bip01 bip001 "
              "b j bind skin deform".split())
#: Words made of two or three of a name's tokens (``Fore`` + ``Arm``).
_COMPOUNDS = {"forearm", "upperarm", "uparm", "lowerarm", "upleg", "upperleg", "lowerleg",
              "lowerback", "upperback", "upperchest", "lowerneck", "upperneck", "toebase",
              "collarbone", "hipjoint", "headtop"}
_SIDES = {"left": "l", "l": "l", "lft": "l", "lf": "l",
          "right": "r", "r": "r", "rt": "r", "rgt": "r"}
_TOKENS = re.compile(r"[A-Z]+(?=[A-Z][a-z])|[A-Z]?[a-z]+|[A-Z]+|\d+")


@dataclass(frozen=True)
class Name:
    """A parsed joint name.

    Attributes
    ----------
    side : {"l", "r", ""}
        Left, right, or no side.
    words : tuple of str
        The name's lower-case words without side, digits and prefixes, compounds
        joined (``"LeftUpLeg"`` -> ``("upleg",)``, ``"DEF-upper_arm.L"`` ->
        ``("upperarm",)``).
    part : bool
        False when a word says the joint is not the body part it names (an end,
        a twist helper, an IK target, a finger, an eye).
    """

    side: str
    words: tuple[str, ...]
    part: bool

    @property
    def key(self) -> str:
        """Side and words as one string, to compare names across conventions."""
        return f"{self.side}:{''.join(self.words)}"


def _tokens(name: str) -> list[str]:
    name = re.split(r"[:|]", name)[-1]          # namespaces: mixamorig:Hips, Armature|Hips
    out: list[str] = []
    for part in re.split(r"[^A-Za-z0-9]+", name):
        out.extend(t.lower() for t in _TOKENS.findall(part))
    return out


def _split_side(tok: str) -> tuple[str, str] | None:
    """A token that glues a side to a word (``lhand``, ``leftarm``, ``handl``)."""
    for pre in ("left", "right", "l", "r"):
        rest = tok[len(pre):]
        if tok.startswith(pre) and (rest in _WORDS or rest in _NOT_A_PART):
            return _SIDES[pre], rest
    for suf in ("left", "right", "l", "r"):
        rest = tok[:-len(suf)]
        if tok.endswith(suf) and (rest in _WORDS or rest in _NOT_A_PART):
            return _SIDES[suf], rest
    return None


def parse_name(name: str) -> Name:
    """Side and words of a joint name (see :class:`Name`).

    Examples
    --------
    >>> parse_name("mixamorig:LeftForeArm")
    Name(side='l', words=('forearm',), part=True)
    >>> parse_name("UpperLeg_R").key, parse_name("lShoulder").key, parse_name("thigh.L").key
    ('r:upperleg', 'l:shoulder', 'l:thigh')
    >>> parse_name("LHipJoint"), parse_name("HeadTop_End").part
    (Name(side='l', words=('hipjoint',), part=True), False)
    """
    toks = [t for t in _tokens(str(name)) if not t.isdigit()]
    side = ""
    words: list[str] = []
    for k, t in enumerate(toks):
        if t in _SIDES and len(toks) > 1 and (t in ("left", "right") or k in (0, len(toks) - 1)
                                              or toks[k - 1] in _IGNORE):
            side = side or _SIDES[t]
            continue
        if t not in _WORDS and t not in _NOT_A_PART and t not in _COMPOUNDS:
            glued = _split_side(t)
            if glued is not None:
                side = side or glued[0]
                t = glued[1]
        words.append(t)
    # join compounds, longest first: ("up", "leg") -> "upleg"
    joined: list[str] = []
    k = 0
    while k < len(words):
        for n in (3, 2):
            w = "".join(words[k:k + n])
            if k + n <= len(words) and w in _COMPOUNDS:
                joined.append(w)
                k += n
                break
        else:
            joined.append(words[k])
            k += 1
    # "HipJoint" is a word of its own; other "joint"s and prefixes say nothing
    kept = tuple(w for w in joined if w not in _IGNORE)
    part = not any(w in _NOT_A_PART for w in kept)
    return Name(side, kept, part)


def candidates(name: Name) -> dict[str, int]:
    """``{role: score}`` a parsed name may stand for (empty: none).

    The last word that names a part decides (``pelvis_lowerback`` is the lower back,
    ``torso_head`` the head); a name without a side takes torso words first and a
    sided name limb words first (Kinect's ``SpineShoulder`` is the spine).
    """
    if not name.part:
        return {}
    torso = set(TORSO)
    found = [w for w in name.words if w in _WORDS]
    if not found:
        return {}
    pick = [w for w in found if (_WORDS[w][0][0] in torso) == (name.side == "")]
    word = (pick or found)[-1]
    if name.side == "" and word in ("hip", "hipjoint"):
        return {"pelvis": 2}                    # "Hip" alone: the pelvis (a sided one: a leg)
    return dict(_WORDS[word])
