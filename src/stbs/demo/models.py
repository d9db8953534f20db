"""The demo's models, built from :mod:`stbs.shapes`: leg, torso, character, 2D shapes.

The 3D models are blended primitives (round cones and ellipsoids) meshed by
:func:`stbs.shapes.mesh_primitives`; the 2D models are outlines traced from a sampled
distance field (:func:`stbs.shapes.outline_of_field`) or an image's alpha mask and
triangulated with their skeleton as constrained segments (:func:`stbs.triangulate_2d`).
The arm of Figs. 1 and 5 is :func:`stbs.shapes.arm`.

Every model is a :class:`stbs.shapes.Model` ``(V, F, sk, name, extra)``; characters
have y up.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np

from ..shapes import (
    Model,
    Primitive,
    arm,
    blend,
    bounds,
    ellipsoid,
    mesh_primitives,
    mirror,
    outline_of_field,
    resample_loop,
    round_cone,
)
from ..skeleton import Skeleton

__all__ = ["Model", "MODELS", "arm", "leg", "torso", "character", "long_necked_animal_2d",
           "picture_2d"]


def _flag(name: str, x) -> bool:
    if not isinstance(x, (bool, np.bool_)):
        raise ValueError(f"{name} must be True or False, got {x!r}")
    return bool(x)


# ============================================================================ 3D models


def _model3d(name: str, parts: list[Primitive], h: float, C, BE, names) -> Model:
    V, F = mesh_primitives(parts, h)
    sk = Skeleton(np.asarray(C, dtype=float), np.asarray(BE, dtype=np.int64), names=names)
    return Model(V, F, sk, name, {"sdf": blend(parts, h)})


def leg(*, quick: bool = False) -> Model:
    """A leg bent at the knee, y up, toes towards +z: the paper's Fig. 4.

    Hip at y = 2, knee bent forwards (z = 0.3) at y = 1.1, ankle at y = 0.25, the
    foot on the ground plane y = 0. One watertight surface (thigh, knee cap, calf,
    shin, foot).

    Parameters
    ----------
    quick : bool, keyword-only
        A coarser mesh (about 1.5k vertices instead of 5k).

    Returns
    -------
    Model
        ``sk``: bones ``"thigh"`` (hip -> knee), ``"shin"`` (knee -> ankle) and
        ``"foot"`` (ankle -> toes). ``extra``: ``"sdf"``.
    """
    quick = _flag("quick", quick)
    C = [[0.0, 2.0, 0.0], [0.0, 1.1, 0.38], [0.0, 0.25, 0.0], [0.0, 0.1, 0.42]]
    parts = [
        round_cone((0.0, 2.2, -0.02), C[1], 0.3, 0.19),                          # thigh
        ellipsoid((0.0, 1.95, -0.1), (0.3, 0.3, 0.25), k=0.15),            # buttock
        ellipsoid((0.0, 1.55, 0.14), (0.24, 0.4, 0.22), k=0.15),           # front thigh
        ellipsoid((0.0, 1.1, 0.5), (0.12, 0.12, 0.08), k=0.1),             # knee cap
        round_cone(C[1], C[2], 0.18, 0.1, k=0.08),                               # shin
        ellipsoid((0.0, 0.8, 0.16), (0.16, 0.3, 0.16), k=0.12),            # calf
        ellipsoid((0.0, 0.11, 0.17), (0.13, 0.1, 0.33), k=0.1),            # foot
        round_cone(C[2], (0.0, 0.12, 0.3), 0.1, 0.07, k=0.08),                   # instep
    ]
    return _model3d("leg", parts, 0.11 if quick else 0.06, C, [[0, 1], [1, 2], [2, 3]],
                    ["thigh", "shin", "foot"])


def torso(*, quick: bool = False) -> Model:
    """A torso along y with one bone from the pelvis to the chest: the paper's Fig. 10.

    Pelvis (with leg stubs) around y = 0, a narrower abdomen, the chest around
    y = 1.25 with shoulder stubs along x and a neck stub up to y = 1.9. The cross
    sections are wider in x than in z, so a twist about y shows.

    Parameters
    ----------
    quick : bool, keyword-only
        A coarser mesh (about 2k vertices instead of 7k).

    Returns
    -------
    Model
        ``sk``: one bone ``"spine"`` from ``(0, 0.1, 0)`` to ``(0, 1.35, 0)``.
        ``extra``: ``"abdomen"`` and ``"chest"``, the (2,) y-ranges of the two
        regions (the spline filter should move the twist into the abdomen);
        ``"sdf"``.
    """
    quick = _flag("quick", quick)
    C = [[0.0, 0.1, 0.0], [0.0, 1.35, 0.0]]
    parts = [
        ellipsoid((0.0, 0.1, 0.0), (0.5, 0.3, 0.3)),                       # pelvis
        round_cone((0.25, 0.0, 0.0), (0.28, -0.4, 0.02), 0.22, 0.2, k=0.1),      # leg stubs
        round_cone((-0.25, 0.0, 0.0), (-0.28, -0.4, 0.02), 0.22, 0.2, k=0.1),
        ellipsoid((0.0, 0.6, 0.01), (0.4, 0.45, 0.26), k=0.2),             # abdomen
        ellipsoid((0.0, 1.2, 0.02), (0.55, 0.45, 0.31), k=0.2),            # chest
        round_cone((-0.3, 1.5, 0.0), (-0.8, 1.42, 0.0), 0.18, 0.14, k=0.12),     # shoulders
        round_cone((0.3, 1.5, 0.0), (0.8, 1.42, 0.0), 0.18, 0.14, k=0.12),
        round_cone((0.0, 1.5, 0.0), (0.0, 1.85, 0.02), 0.15, 0.12, k=0.1),       # neck
    ]
    m = _model3d("torso", parts, 0.12 if quick else 0.065, C, [[0, 1]], ["spine"])
    m.extra.update(abdomen=np.array([0.3, 0.85]), chest=np.array([0.85, 1.7]))
    return m


def character(*, quick: bool = False) -> Model:
    """A small humanoid, y up, facing +z, 15 bones: the paper's Fig. 6.

    Head, neck, chest, belly, pelvis, arms held down and out, legs; about 3.1 units
    tall, standing on y = 0. One watertight surface.

    Parameters
    ----------
    quick : bool, keyword-only
        A coarser mesh (about 2.8k vertices instead of 7.4k).

    Returns
    -------
    Model
        ``sk``: bones ``spine``, ``neck``, ``head``, ``clavicle_l``, ``upper_arm_l``,
        ``forearm_l`` (and ``_r``), ``hip_l``, ``thigh_l``, ``shin_l`` (and ``_r``);
        ``_l`` is the character's left, at +x. ``extra``: ``"sdf"``.
    """
    quick = _flag("quick", quick)
    C = np.array([
        [0.0, 1.55, 0.0],    # 0 pelvis
        [0.0, 2.2, 0.0],     # 1 chest
        [0.0, 2.5, 0.0],     # 2 neck
        [0.0, 2.92, 0.03],   # 3 head top
        [0.42, 2.38, 0.0],   # 4 shoulder
        [0.8, 2.0, 0.0],     # 5 elbow
        [1.1, 1.64, 0.04],   # 6 wrist
        [0.21, 1.42, 0.0],   # 7 hip
        [0.24, 0.82, 0.05],  # 8 knee
        [0.25, 0.22, 0.0],   # 9 ankle
    ])
    left = C[4:]
    right = left * [-1.0, 1.0, 1.0]
    C = np.vstack([C, right])  # right side: joints 10..15
    r = 6
    BE = [[0, 1], [1, 2], [2, 3],
          [1, 4], [4, 5], [5, 6], [1, 4 + r], [4 + r, 5 + r], [5 + r, 6 + r],
          [0, 7], [7, 8], [8, 9], [0, 7 + r], [7 + r, 8 + r], [8 + r, 9 + r]]
    names = ["spine", "neck", "head",
             "clavicle_l", "upper_arm_l", "forearm_l", "clavicle_r", "upper_arm_r", "forearm_r",
             "hip_l", "thigh_l", "shin_l", "hip_r", "thigh_r", "shin_r"]
    body = [
        ellipsoid((0.0, 1.5, 0.0), (0.36, 0.24, 0.23)),                    # pelvis
        ellipsoid((0.0, 1.85, 0.01), (0.32, 0.3, 0.22), k=0.15),           # belly
        ellipsoid((0.0, 2.2, 0.0), (0.42, 0.3, 0.25), k=0.15),             # chest
        round_cone((0.0, 2.3, 0.0), (0.0, 2.62, 0.01), 0.13, 0.11, k=0.1),       # neck
        ellipsoid((0.0, 2.78, 0.03), (0.23, 0.26, 0.24), k=0.08),          # head
        ellipsoid((0.0, 2.75, 0.26), (0.05, 0.07, 0.06), k=0.04),          # nose
    ]
    side = [
        round_cone((0.2, 2.33, 0.0), tuple(left[0]), 0.15, 0.13, k=0.1),        # shoulder
        round_cone(tuple(left[0]), tuple(left[1]), 0.13, 0.105, k=0.06),         # upper arm
        round_cone(tuple(left[1]), tuple(left[2]), 0.105, 0.09, k=0.05),         # forearm
        round_cone(tuple(left[2]), (1.22, 1.48, 0.06), 0.1, 0.09, k=0.05),       # hand
        round_cone((0.21, 1.5, 0.0), tuple(left[4]), 0.18, 0.13, k=0.08),       # thigh
        round_cone(tuple(left[4]), tuple(left[5]), 0.13, 0.1, k=0.05),          # shin
        ellipsoid((0.25, 0.08, 0.1), (0.1, 0.08, 0.2), k=0.06),           # foot
    ]
    parts = body + side + mirror(side)
    return _model3d("character", parts, 0.105 if quick else 0.066, C, BE, names)


# ============================================================================ 2D models


def _model2d(name: str, outline, sk: Skeleton, spacing: float, extra: dict) -> Model:
    from ..meshing import triangulate_2d

    tm = triangulate_2d(outline, sk, max_area=0.5 * spacing * spacing)
    extra = dict(extra)
    extra["mesh"] = tm
    return Model(tm.V, tm.F, sk, name, extra)


def long_necked_animal_2d(*, quick: bool = False) -> Model:
    """A 2D giraffe-like animal in profile (facing +x, y up): the paper's Fig. 7.

    Body, a long neck rising to the upper right, a head with snout and horn, four
    legs standing on y = 0 and a tail, blended into one smooth outline (a sampled
    distance field, traced and resampled evenly) and triangulated with the skeleton
    as constrained segments. About 3.5 units long and 3.8 tall.

    Parameters
    ----------
    quick : bool, keyword-only
        A coarser mesh (about 800 vertices instead of 3k).

    Returns
    -------
    Model
        2D: ``V`` (n, 2), counter-clockwise ``F``. ``sk``: bones ``"body"`` (hip ->
        shoulder), ``"neck"`` (shoulder -> head), ``"head"`` (to the snout), ``"tail"``
        (from the hip), and four legs ``"front_leg_a"``, ``"front_leg_b"``,
        ``"back_leg_a"``, ``"back_leg_b"`` (each its own root, from the body down to the
        hoof). ``extra``: ``"neck"`` the neck's bone index, ``"head"`` (n,) bool, the
        vertices of the head, ``"mesh"`` the :class:`stbs.meshing.TriMesh` (joint
        vertices, bone samples), ``"sdf"`` the shape's distance field.
    """
    quick = _flag("quick", quick)
    C = np.array([[-0.7, 1.68], [0.62, 1.72], [1.45, 3.3], [1.95, 3.32],       # hip .. snout
                  [0.45, 1.45], [0.4, 0.12], [0.8, 1.45], [0.88, 0.12],        # front legs
                  [-0.55, 1.45], [-0.5, 0.12], [-0.88, 1.45], [-0.95, 0.12],   # back legs
                  [-1.33, 1.2]])                                               # tail tip
    BE = [[0, 1], [1, 2], [2, 3], [0, 12], [4, 5], [6, 7], [8, 9], [10, 11]]
    names = ["body", "neck", "head", "tail", "front_leg_a", "front_leg_b", "back_leg_a",
             "back_leg_b"]
    head = [
        ellipsoid((1.6, 3.4), (0.27, 0.16)),
        round_cone((1.62, 3.4), (2.02, 3.3), 0.14, 0.08, k=0.08),                 # snout
        round_cone((1.5, 3.5), (1.43, 3.74), 0.035, 0.045, k=0.04),              # horn
    ]
    parts = [
        ellipsoid((0.0, 1.72), (0.95, 0.4)),                               # body
        ellipsoid((0.6, 1.8), (0.42, 0.42), k=0.2),                        # chest
        ellipsoid((-0.72, 1.62), (0.35, 0.36), k=0.2),                     # haunch
        round_cone((0.62, 1.8), (1.45, 3.3), 0.22, 0.1, k=0.15),                 # neck
        *[dataclasses.replace(p, k=0.1) for p in head],
        round_cone(tuple(C[0]), tuple(C[12]), 0.05, 0.03, k=0.06),               # tail
        ellipsoid((-1.37, 1.1), (0.06, 0.11), k=0.04),                     # tuft
    ]
    for top, foot in ((4, 5), (6, 7), (8, 9), (10, 11)):
        parts.append(round_cone(tuple(C[top]), tuple(C[foot] + [0.0, -0.04]), 0.085, 0.06, k=0.06))
        parts.append(ellipsoid(tuple(C[foot] - [0.0, 0.04]), (0.085, 0.06), k=0.03))  # hoof
    sdf = blend(parts)
    lo, hi = bounds(parts)
    spacing = 0.08 if quick else 0.04
    sk = Skeleton(C, BE, names=names)
    m = _model2d("long_necked_animal_2d", outline_of_field(sdf, lo, hi, spacing), sk, spacing,
                 {"neck": 1, "sdf": sdf})
    m.extra["head"] = blend(head)(m.V) <= 1e-9
    return m


def _gingerbread(size: int) -> tuple[np.ndarray, dict]:
    """The picture, RGBA (size, size, 4) uint8, and the skeleton's joints in pixel
    units (x = column, y = size - 1 - row, as :func:`stbs.outline_from_image`)."""
    s = size / 256.0  # the design below is in pixels of a 256 x 256 image
    head = ((128 * s, 194 * s), 36 * s)
    arm = ((128 * s, 150 * s), (44 * s, 172 * s), 22 * s, 17 * s)
    leg = ((112 * s, 100 * s), (84 * s, 30 * s), 24 * s, 20 * s)
    parts = [
        round_cone((128 * s, 140 * s), (128 * s, 100 * s), 44 * s),              # body
        ellipsoid(head[0], (head[1], head[1]), k=10 * s),
        round_cone(*arm[:2], *arm[2:], k=10 * s),
        round_cone((256 * s - arm[0][0], arm[0][1]), (256 * s - arm[1][0], arm[1][1]), *arm[2:],
              k=10 * s),
        round_cone(*leg[:2], *leg[2:], k=10 * s),
        round_cone((256 * s - leg[0][0], leg[0][1]), (256 * s - leg[1][0], leg[1][1]), *leg[2:],
              k=10 * s),
    ]
    sdf = blend(parts)
    yy, xx = np.mgrid[:size, :size]
    P = np.stack([xx, size - 1 - yy], axis=-1).reshape(-1, 2).astype(float)
    d = sdf(P).reshape(size, size)
    x, y = P[:, 0].reshape(size, size), P[:, 1].reshape(size, size)

    def disc(c, r):
        return np.hypot(x - c[0], y - c[1]) - r

    rgb = np.empty((size, size, 3))
    rgb[:] = (0.71, 0.42, 0.2)  # dough, also outside the shape, so edges sample well
    stripe = np.sin(2 * np.pi * (x + 0.6 * y) / (22 * s)) > 0.55
    rgb[stripe] = (0.6, 0.33, 0.14)
    icing = np.abs(d + 6 * s + 1.2 * s * np.sin(x / (3 * s)) * np.cos(y / (3 * s))) < 1.6 * s
    rgb[icing] = (0.98, 0.97, 0.94)
    # Zig-zag icing across each wrist and ankle.
    for (a, b, _, _), sign in ((arm, 1), (arm, -1), (leg, 1), (leg, -1)):
        a = np.array([128 * s + sign * (a[0] - 128 * s), a[1]])
        b = np.array([128 * s + sign * (b[0] - 128 * s), b[1]])
        u = (b - a) / np.linalg.norm(b - a)
        along = (x - a[0]) * u[0] + (y - a[1]) * u[1]
        across = -(x - a[0]) * u[1] + (y - a[1]) * u[0]
        zig = 0.7 * np.linalg.norm(b - a) + 5 * s * np.abs(((across / (5 * s)) % 2) - 1)
        rgb[(np.abs(along - zig) < 1.8 * s) & (d < -8 * s)] = (0.98, 0.97, 0.94)
    for c, col in (((128, 150), (0.86, 0.12, 0.15)), ((128, 124), (0.1, 0.62, 0.25)),
                   ((128, 98), (0.15, 0.35, 0.85))):  # buttons with a white rim
        c = (c[0] * s, c[1] * s)
        rgb[disc(c, 9 * s) < 0] = (0.98, 0.97, 0.94)
        rgb[disc(c, 7 * s) < 0] = col
    cheeks = (disc((106 * s, 186 * s), 6 * s) < 0) | (disc((150 * s, 186 * s), 6 * s) < 0)
    rgb[cheeks] = 0.5 * rgb[cheeks] + 0.5 * np.array([0.95, 0.45, 0.5])
    for ex in (114, 142):  # eyes with a highlight
        rgb[disc((ex * s, 202 * s), 6 * s) < 0] = (0.12, 0.06, 0.03)
        rgb[disc(((ex + 2) * s, 204 * s), 2 * s) < 0] = (1.0, 1.0, 1.0)
    smile = (np.abs(disc((128 * s, 196 * s), 17 * s)) < 2.2 * s) & (y < 188 * s)
    rgb[smile] = (0.45, 0.1, 0.08)
    alpha = np.clip(0.5 - d / (1.5 * s), 0.0, 1.0)  # anti-aliased edge, 1.5 px wide
    img = np.concatenate([rgb, alpha[..., None]], axis=-1)
    texture = np.round(255 * img).astype(np.uint8)
    joints = {
        "pelvis": (128, 98), "chest": (128, 150), "head": (128, 206),
        "elbow_l": (88, 160), "hand_l": (52, 170), "elbow_r": (168, 160), "hand_r": (204, 170),
        "knee_l": (99, 66), "foot_l": (87, 36), "knee_r": (157, 66), "foot_r": (169, 36),
    }
    return texture, {k: (v[0] * s, v[1] * s) for k, v in joints.items()}


def picture_2d(*, quick: bool = False, size: int = 256) -> Model:
    """A gingerbread man drawn in code, with texture coordinates: the paper's Fig. 12.

    An RGBA picture (a biscuit with a striped dough, an icing border, zig-zag icing
    at wrists and ankles, buttons, eyes and a smile) is drawn with NumPy; its alpha
    mask is traced with :func:`stbs.outline_from_image` and triangulated with the
    skeleton inside. Model units: the picture is 3 units wide, y up, its lower left
    corner at the origin.

    Parameters
    ----------
    quick : bool, keyword-only
        A coarser mesh (about 500 vertices instead of 2.4k).
    size : int, keyword-only
        The picture's width and height in pixels (>= 64; default 256).

    Returns
    -------
    Model
        2D: ``V`` (n, 2), counter-clockwise ``F``. ``sk``: bones ``"spine"`` (pelvis
        -> chest), ``"head"``, ``"upper_arm_l"``, ``"forearm_l"``, ``"thigh_l"``,
        ``"shin_l"`` and the same with ``_r`` (``_l`` on the left of the picture).
        ``extra``: ``"texture"`` (size, size, 4) uint8, RGBA, row 0 at the top;
        ``"uv"`` (n, 2) float64 in [0, 1], OpenGL convention: ``u`` across from the
        left edge, ``v`` up from the bottom edge, so that vertex ``k`` shows pixel
        ``(row, col) = ((1 - v) size - 1/2, u size - 1/2)``; ``"scale"``, model
        units per pixel; ``"mesh"`` the :class:`stbs.meshing.TriMesh`.
    """
    from ..meshing import outline_from_image

    quick = _flag("quick", quick)
    if isinstance(size, bool) or not isinstance(size, (int, np.integer)) or size < 64:
        raise ValueError(f"size must be an integer >= 64 (pixels), got {size!r}")
    size = int(size)
    texture, J = _gingerbread(size)
    scale = 3.0 / size
    names = ["spine", "head", "upper_arm_l", "forearm_l", "upper_arm_r", "forearm_r",
             "thigh_l", "shin_l", "thigh_r", "shin_r"]
    order = list(J)
    pairs = [("pelvis", "chest"), ("chest", "head"), ("chest", "elbow_l"),
             ("elbow_l", "hand_l"), ("chest", "elbow_r"), ("elbow_r", "hand_r"),
             ("pelvis", "knee_l"), ("knee_l", "foot_l"), ("pelvis", "knee_r"),
             ("knee_r", "foot_r")]
    C = np.array([J[k] for k in order]) * scale
    BE = [[order.index(a), order.index(b)] for a, b in pairs]
    sk = Skeleton(C, BE, names=names)
    spacing = 0.1 if quick else 0.045
    loops = [resample_loop(L * scale, spacing)
             for L in outline_from_image(texture, tolerance=0.25)]
    m = _model2d("picture_2d", loops, sk, spacing, {"texture": texture, "scale": scale})
    m.extra["uv"] = np.clip((m.V / scale + 0.5) / size, 0.0, 1.0)
    return m


#: The models by name: ``MODELS[name](quick=...)`` builds one.
MODELS: dict[str, Callable[..., Model]] = {
    "arm": arm,
    "leg": leg,
    "torso": torso,
    "character": character,
    "long_necked_animal_2d": long_necked_animal_2d,
    "picture_2d": picture_2d,
}
