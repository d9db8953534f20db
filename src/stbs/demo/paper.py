"""The paper's Figs. 4-12 on built-in models: weights, poses, numbers and pictures.

Each ``figN`` function builds a model (:mod:`stbs.demo.models`), computes its weights
with the library's own methods, poses it, deforms it and returns a
:class:`~stbs.demo.figures.Figure` whose ``numbers`` prove the figure's point and
whose ``pictures`` say what to draw (panels for :func:`stbs.demo.render.render_panels`,
frames for :func:`stbs.demo.render.render_animation`). Figs. 2 and 3 live in
:mod:`stbs.demo.figures`.
"""

from __future__ import annotations

import numpy as np

from .. import transforms as tf
from ..geometry import triangle_areas
from ..pose import Pose, forward_kinematics
from ..skeleton import Skeleton
from ..skinning import deform
from ..weights.endpoint import endpoint_weights, idw_joint_weights, projection
from . import models
from .figures import Figure, section_radius, section_twist
from .render import Camera, Panel, PlotPanel

__all__ = ["fig4_leg", "fig5_arm", "fig6_character", "fig7_neck", "fig8_box_twist",
           "fig10_torso", "fig12_picture", "rigid_distortion", "hull_volume"]

SKIN = "#e8b89a"


# ---------------------------------------------------------------------- measures
def rigid_distortion(P, Q) -> float:
    """RMS distance of ``Q`` from the best rigid motion of ``P``, relative to ``P``'s size.

    0 when ``Q`` is a rotated and translated copy of ``P`` (Kabsch fit).
    """
    P = np.asarray(P, float)
    Q = np.asarray(Q, float)
    p, q = P - P.mean(axis=0), Q - Q.mean(axis=0)
    U, _, Vt = np.linalg.svd(p.T @ q)
    D = np.eye(P.shape[1])
    D[-1, -1] = np.sign(np.linalg.det(U @ Vt))
    R = U @ D @ Vt
    size = np.sqrt(np.mean(np.sum(p ** 2, axis=1)))
    return float(np.sqrt(np.mean(np.sum((p @ R - q) ** 2, axis=1))) / size)


def hull_volume(P) -> float:
    """Volume of the convex hull of the points ``P`` (n, 3)."""
    from scipy.spatial import ConvexHull

    return float(ConvexHull(np.asarray(P, float)).volume)


def _slabs(V, origin, axis, t0: float, t1: float, h: float):
    """Vertex index sets of thin slabs across ``axis`` at offsets t0..t1 (step h)."""
    t = (V - origin) @ axis
    out = []
    for c in np.arange(t0, t1 + 1e-9, h):
        idx = np.flatnonzero(np.abs(t - c) <= 0.5 * h)
        if idx.size >= 8:
            out.append((float(c), idx))
    return out


def _bone_colors(b: int) -> np.ndarray:
    import colorsys

    return np.array([colorsys.hsv_to_rgb((0.61 * i) % 1.0, 0.65, 0.95) for i in range(b)])


def _sub_skeleton(sk: Skeleton, bones) -> Skeleton:
    """The skeleton made of the given bones only (joints renumbered)."""
    BE = sk.BE[list(bones)]
    used = np.unique(BE)
    remap = np.full(sk.n_joints, -1)
    remap[used] = np.arange(used.size)
    return Skeleton(sk.C[used], remap[BE], names=[sk.names[i] for i in bones])


def _heat(V, F, sk):
    from ..weights.heat import bone_heat

    return bone_heat(V, F, sk)


# ---------------------------------------------------------------------- Fig. 5
def fig5_arm(quick: bool = False, *, twist: float = 180.0, bend: float = 60.0,
             sigma: float = 1.4) -> Figure:
    """Figs. 1 and 5: an arm twisted 180 degrees, then bent, then stretched.

    Rig: bones upper arm and forearm (the hand lies beyond the forearm's end, as the
    head and hand of the paper's Fig. 5), bone-heat bone weights, projection endpoint
    weights. STBS gets the twist at the wrist (spread along the forearm); LBS and DQS
    have no twist term, so their forearm is turned about its own axis instead, and
    they blend that turn with the upper arm at the elbow.

    Numbers per method: ``radius``, the smallest cross-section size between elbow and
    wrist relative to rest in the twisted pose (LBS collapses: candy wrapper); and
    ``hand``, the hand's volume (convex hull) in the stretched pose relative to rest
    (LBS/DQS scale it by ``sigma``, STBS keeps it).
    """
    m = models.arm(quick=quick)
    V, F = m.V, m.F
    sk = _sub_skeleton(m.sk, [0, 1])
    W = _heat(V, F, sk)
    E = projection(V, sk)
    th = np.radians(twist)
    L = np.tile(np.eye(3), (2, 1, 1))
    Lb = L.copy()
    Lb[1] = tf.axis_angle_to_matrix(np.array([0.0, 0.0, 1.0]), np.radians(bend))
    turn = tf.axis_angle_to_matrix(sk.axes[1], th)
    poses = {}
    for label, rot, st in (("twist", L, [1, 1]), ("twist + bend", Lb, [1, 1]),
                           ("twist + bend + stretch", Lb, [sigma, sigma])):
        stbs_pose = forward_kinematics(sk, rotations=rot, stretch=st,
                                       twist=[0.0, 0.0, th])
        R2 = rot.copy()
        R2[1] = rot[1] @ turn
        rigid_pose = forward_kinematics(sk, rotations=R2, stretch=st)
        poses[label] = {"lbs": rigid_pose, "dqs": rigid_pose, "stbs-dqs": stbs_pose}
    fig = Figure("arm", f"Figs. 1, 5: an arm twisted {twist:g} deg at the wrist, bent "
                 f"{bend:g} deg, stretched x{sigma:g}", V, F, sk, W, E)
    fig.key = "fig5"
    methods = ("lbs", "dqs", "stbs-dqs")
    wrist, elbow = sk.C[2], sk.C[1]
    axis = sk.axes[1]
    hand = m.extra["hand"]
    slabs = _slabs(V, elbow, axis, 0.1, float(np.linalg.norm(wrist - elbow)) - 0.05, 0.06)
    rows = []
    for method in methods:
        Us = {lab: deform(V, sk, p[method], W, E, method=method) for lab, p in poses.items()}
        for lab, U in Us.items():
            fig.U[f"{method}/{lab}"] = U
        Ut, Us_ = Us["twist"], Us["twist + bend + stretch"]
        fig.numbers[method] = {
            "radius": min(section_radius(V[i], Ut[i]) for _, i in slabs),
            "hand": hull_volume(Us_[hand]) / hull_volume(V[hand]),
        }
        rows.append([Panel(Us[lab], F, title=f"{method}: {lab}", C=poses[lab][method].joints(),
                           BE=sk.BE, color=SKIN) for lab in poses])
    fig.columns = [("radius", "min radius elbow-wrist", "{:.3f}"),
                   ("hand", "hand volume (stretch)", "{:.3f}")]
    fig.expected = {"radius": "lbs collapses (candy wrapper at the elbow); dqs, stbs-dqs ~1",
                    "hand": f"lbs, dqs: ~{sigma:g} (the hand explodes); stbs-dqs: 1"}
    fig.notes = ["bone heat bone weights, projection endpoint weights; the rig's bones are "
                 "the upper arm and forearm, so the hand lies beyond the forearm's end",
                 "lbs/dqs cannot twist along a bone: their forearm is turned about its axis"]
    fig.caption = ("The paper's teaser and Fig. 5. Top to bottom: LBS, DQS, STBS-DQS; left "
                   "to right: the hand twisted half a turn, then the elbow bent, then the arm "
                   "stretched. LBS collapses where the turned forearm meets the upper arm "
                   "(candy wrapper); DQS keeps the volume but packs the whole twist into the "
                   "elbow; STBS spreads it along the forearm. Stretched, LBS and DQS scale the "
                   "hand with the bone (it explodes); STBS moves it rigidly.")
    fig.pictures = {"fig5_arm.png": dict(panels=[p for r in rows for p in r], ncols=3,
                                        camera=Camera(azimuth=-70.0, elevation=25.0))}
    frames = []
    n = 8 if quick else 16
    for k in range(n + 1):
        a = th * k / n
        sp = forward_kinematics(sk, twist=[0.0, 0.0, a])
        rp = forward_kinematics(sk, rotations=np.stack(
            [np.eye(3), tf.axis_angle_to_matrix(sk.axes[1], a)]))
        frames.append([Panel(deform(V, sk, rp if mm != "stbs-dqs" else sp, W, E, method=mm),
                             F, title=mm, color=SKIN) for mm in methods])
    fig.animations = {"fig5_arm_twist.gif": dict(frames=frames,
                                                 camera=Camera(azimuth=-70.0, elevation=25.0))}
    return fig


# ---------------------------------------------------------------------- Fig. 4
def _point_skinning(V, sk: Skeleton, pose: Pose, J) -> np.ndarray:
    """LBS with point handles at the joints: joint k moves by the rotation of the bone
    leaving it (or arriving at it, for end joints) about its posed position."""
    Cp = pose.joints()
    Rk = np.zeros((sk.n_joints, 3, 3))
    for i in range(sk.n_bones - 1, -1, -1):
        a, b = sk.BE[i]
        Rk[b] = pose.rotations[i] if not Rk[b].any() else Rk[b]
        Rk[a] = pose.rotations[i]
    out = np.zeros_like(V)
    for k in range(sk.n_joints):
        out += J[:, k:k + 1] * ((V - sk.C[k]) @ Rk[k].T + Cp[k])
    return out


def fig4_leg(quick: bool = False, *, bend: float = 50.0, sigma: float = 1.5) -> Figure:
    """Fig. 4: a bent leg bent further and stretched, with bone weights, point weights, STBS.

    Rig: bones thigh and shin (the foot lies beyond the shin's end); bone weights by
    bone heat; point weights are inverse-distance joint weights (eq. 9) with one
    point handle per joint; STBS (stbs-lbs) uses the bone weights and projection
    endpoint weights.

    Numbers: ``bend``, the thigh's distortion (distance from its best rigid motion,
    relative to its size) when the knee bends ``bend`` degrees more (point handles
    blend rotations, so the limb loses its rigidity); ``stretch``, the foot's
    distortion when both bones stretch by ``sigma`` (bone weights scale it: it
    explodes).
    """
    m = models.leg(quick=quick)
    V, F = m.V, m.F
    sk = _sub_skeleton(m.sk, [0, 1])
    W = _heat(V, F, sk)
    E = projection(V, sk)
    J = idw_joint_weights(V, sk, alpha=2.0)
    knee_axis = np.array([1.0, 0.0, 0.0])
    Lb = np.tile(np.eye(3), (2, 1, 1))
    Lb[1] = tf.axis_angle_to_matrix(knee_axis, -np.radians(bend))
    bent = forward_kinematics(sk, rotations=Lb)
    stretched = forward_kinematics(sk, stretch=[sigma, sigma])
    ankle = sk.C[2]
    ax = sk.axes[0]
    t = (V - sk.C[0]) @ ax
    length = float(sk.lengths[0])
    thigh = (t > 0.3 * length) & (t < 0.7 * length)
    foot = V[:, 1] < ankle[1] - 0.02
    fig = Figure("leg", f"Fig. 4: a leg bent {bend:g} deg more, and stretched x{sigma:g}",
                 V, F, sk, W, E)
    fig.key = "fig4"
    rows = {}
    for name, fn in (("bone weights", lambda p: deform(V, sk, p, W, method="lbs")),
                     ("point weights", lambda p: _point_skinning(V, sk, p, J)),
                     ("stbs", lambda p: deform(V, sk, p, W, E, method="stbs-lbs"))):
        Ub, Us = fn(bent), fn(stretched)
        fig.U[f"{name}/bend"], fig.U[f"{name}/stretch"] = Ub, Us
        fig.numbers[name] = {"bend": rigid_distortion(V[thigh], Ub[thigh]),
                             "stretch": rigid_distortion(V[foot], Us[foot])}
        rows[name] = (Ub, Us)
    cam = Camera(azimuth=0.0, elevation=0.0)
    panels = [Panel(rows[k][0], F, title=f"{k}: bent", C=bent.joints(), BE=sk.BE, color=SKIN)
              for k in rows]
    panels += [Panel(rows[k][1], F, title=f"{k}: stretched", C=stretched.joints(), BE=sk.BE,
                     color=SKIN) for k in rows]
    for p, k in zip(panels, list(rows) * 2, strict=True):
        key = "bend" if "bent" in p.title else "stretch"
        p.subtitle = f"{'thigh' if key == 'bend' else 'foot'} distortion " \
                     f"{fig.numbers[k][key]:.3f}"
    fig.columns = [("bend", "thigh distortion (bend)", "{:.3f}"),
                   ("stretch", "foot distortion (stretch)", "{:.3f}")]
    fig.expected = {"bend": "point weights: large (limbs lose rigidity); bone weights, stbs: "
                            "small",
                    "stretch": "bone weights: large (the foot explodes); point weights, stbs: "
                               "small"}
    fig.notes = ["bone heat bone weights; point weights = inverse-distance joint weights "
                 "(eq. 9, alpha 2); stbs = stbs-lbs with projection endpoint weights"]
    fig.caption = ("Fig. 4. Columns: bone weights (LBS), point handles at the joints, STBS. "
                   "Top: the knee bent further - bones keep the thigh rigid, point handles "
                   "blend the knee's rotation into the thigh and bend it. Bottom: both "
                   "bones stretched - bone weights scale the foot (it explodes), point "
                   "handles and STBS translate it.")
    fig.pictures = {"fig4_leg.png": dict(panels=panels, ncols=3, camera=cam)}
    return fig


# ---------------------------------------------------------------------- Fig. 6
#: Fig. 6 shows a bone's endpoint weights where its bone weight is at least this: bone
#: heat weights decay but never reach 0, and below this the bone moves a point by less
#: than 5% of its motion, so its endpoint weights hardly matter there (grey).
FIG6_SUPPORT = 0.05


def fig6_character(quick: bool = False) -> Figure:
    """Fig. 6: a character's bone weights as colours and endpoint weights as heat maps.

    Bone weights by bone heat; endpoint weights by heat with the joints as points
    (eq. 7). Each endpoint-weight panel colours ``e_i`` only where the bone's weight
    ``w_i`` is at least :data:`FIG6_SUPPORT` (the bone's region), grey elsewhere, as
    in the paper. Numbers: the mean ``e`` at the surface vertex nearest each bone's
    start (should be low) and end (high), and the share of the surface inside the
    shown bones' regions.
    """
    m = models.character(quick=quick)
    V, F, sk = m.V, m.F, m.sk
    W = _heat(V, F, sk)
    E = endpoint_weights(V, sk, method="heat", W=W, F=F)
    fig = Figure("character", "Fig. 6: bone weights as colours, endpoint weights as heat maps",
                 V, F, sk, W, E)
    fig.key = "fig6"
    colors = W @ _bone_colors(sk.n_bones)
    cam = Camera(azimuth=-90.0, elevation=0.0)
    panels = [Panel(V, F, title="bone weights", colors=np.clip(colors, 0, 1), C=sk.C, BE=sk.BE)]
    show = [i for i, nm in enumerate(sk.names) if nm in
            ("spine", "neck", "upper_arm_l", "forearm_l", "thigh_r", "shin_r")]
    region = W >= FIG6_SUPPORT
    for i in show:
        panels.append(Panel(V, F, title=f"e: {sk.names[i]}", scalars=E[:, i], cmap="Reds",
                            mask=region[:, i], C=sk.C, BE=sk.BE[[i]],
                            subtitle=f"w \u2265 {FIG6_SUPPORT:g} on {region[:, i].mean():.0%} "
                                     "of the surface"))
    near_a = np.array([E[np.argmin(np.linalg.norm(V - sk.A[i], axis=1)), i]
                       for i in range(sk.n_bones)])
    near_b = np.array([E[np.argmin(np.linalg.norm(V - sk.B[i], axis=1)), i]
                       for i in range(sk.n_bones)])
    fig.numbers["heat"] = {"bones": float(sk.n_bones),
                           "start": float(near_a.mean()), "end": float(near_b.mean()),
                           "region": float(region[:, show].mean())}
    fig.columns = [("bones", "bones", "{:.0f}"),
                   ("start", "mean e near starts", "{:.2f}"),
                   ("end", "mean e near ends", "{:.2f}"),
                   ("region", "shown region (mean)", "{:.2f}")]
    fig.expected = {"bones": "-", "start": "low (e = 0 at a)", "end": "high (e = 1 at b)",
                    "region": "well below 1 (each bone's own region, grey elsewhere)"}
    fig.notes = ["bone heat bone weights; heat endpoint weights (joints as points, eq. 7); "
                 "e at the surface vertex nearest each joint; e shown where w >= "
                 f"{FIG6_SUPPORT:g}"]
    fig.caption = ("Fig. 6. Left: each bone has a colour and every point shows the "
                   "weighted mix of its bones' colours. Right: endpoint weights of six bones "
                   "(white 0 at the bone's start, red 1 at its end), computed automatically, "
                   f"shown where the bone's weight is at least {FIG6_SUPPORT:g} (grey "
                   "elsewhere: there the bone hardly moves the surface).")
    fig.pictures = {"fig6_character.png": dict(panels=panels, ncols=4, camera=cam)}
    return fig


# ---------------------------------------------------------------------- Fig. 7
def _slope_jump(V2, e, a, b) -> float:
    """|de/dt inside - de/dt outside| at the bone's end b, from vertices near its line."""
    u = b - a
    L2 = float(u @ u)
    t = (V2 - a) @ u / L2
    d = np.linalg.norm(V2 - (a + np.outer(t, u)), axis=1)
    near = d < 0.08 * np.sqrt(L2)
    inside = near & (t > 0.75) & (t < 1.0)
    outside = near & (t > 1.0) & (t < 1.25)
    if inside.sum() < 2 or outside.sum() < 2:
        return float("nan")
    s_in = np.polyfit(t[inside], e[inside], 1)[0]
    s_out = np.polyfit(t[outside], e[outside], 1)[0]
    return float(abs(s_in - s_out))


def fig7_neck(quick: bool = False, *, sigma: float = 1.6) -> Figure:
    """Fig. 7: a 2D long-necked animal, the neck bone stretched, four endpoint weights.

    Bone weights: 2D bounded biharmonic weights. Endpoint weights of the neck bone:
    projection, IDW, heat, BBW (stbs-lbs in every case).

    Numbers: ``sag``, the head's RMS distance from where the neck's end carries it
    rigidly, relative to the neck's extension (IDW's fall-off lets it sag); ``jump``,
    the jump of de/dt across the bone's end along the bone's line (projection is only
    C0 there: 1).
    """
    from ..weights.bbw import bone_weights

    m = models.long_necked_animal_2d(quick=quick)
    V, F = m.V, m.F
    keep = [i for i, nm in enumerate(m.sk.names) if nm != "head"]   # one bone: neck + head
    sk = _sub_skeleton(m.sk, keep)
    neck = keep.index(int(m.extra["neck"]))
    head = np.asarray(m.extra["head"], dtype=bool)
    W = bone_weights(V, sk, method="bbw", F=F, tol=1e-8)
    stretch = np.ones(sk.n_bones)
    stretch[neck] = sigma
    pose = forward_kinematics(sk, stretch=stretch)
    delta = (sigma - 1.0) * (sk.B[neck] - sk.A[neck])
    fig = Figure("neck", f"Fig. 7: a 2D animal's neck bone stretched x{sigma:g}", V, F, sk, W,
                 projection(V, sk))
    fig.key = "fig7"
    panels = []
    for method in ("projection", "idw", "heat", "bbw"):
        E = endpoint_weights(V, sk, method=method, W=W, F=F)
        U = deform(V, sk, pose, W, E, method="stbs-lbs")
        fig.U[method] = U
        sag = float(np.sqrt(np.mean(np.sum((U[head] - V[head] - delta) ** 2, axis=1))))
        fig.numbers[method] = {"sag": sag / float(np.linalg.norm(delta)),
                               "jump": _slope_jump(V, E[:, neck], sk.A[neck], sk.B[neck])}
        panels.append(Panel(U, F, title=f"e: {method}", scalars=E[:, neck], cmap="Reds",
                            C=pose.joints(), BE=sk.BE,
                            subtitle=f"head sag {fig.numbers[method]['sag']:.3f}"))
    fig.columns = [("sag", "head sag / stretch", "{:.3f}"),
                   ("jump", "slope jump at b", "{:.2f}")]
    fig.expected = {"sag": "idw: sags (fall-off); heat, bbw, projection: ~0",
                    "jump": "projection, bbw: ~1 (linear along the bone, so only C0 at b, "
                            "paper 2.2); idw, heat: smoother"}
    fig.notes = ["2D BBW bone weights; stbs-lbs; the neck bone stretched, every other bone "
                 "at rest"]
    fig.caption = ("Fig. 7. The neck bone stretched with four kinds of endpoint weights "
                   "(colours: the neck's e, white 0 to red 1). Projection is not smooth at "
                   "the bone's ends; inverse distance is smooth but not shape-aware and its "
                   "fall-off lets the head sag; heat and BBW carry the head rigidly.")
    fig.pictures = {"fig7_neck.png": dict(panels=panels, ncols=4)}
    return fig


# ---------------------------------------------------------------------- Fig. 8
def fig8_box_twist(quick: bool = False, *, degrees: float = 360.0) -> Figure:
    """Fig. 8: a box twisted 360 degrees; heat vs BBW endpoint weights.

    One bone along the middle half of a 4 x 1 x 1 box; the bone's end joint is
    twisted by ``degrees``. Number: the twist reached at the far end of the box
    (``degrees`` times the mean endpoint weight there). Heat endpoint weights fall
    short beyond the handles; BBW reach it.
    """
    from ..shapes import box_tets

    V, T, F = box_tets(h=0.5 if quick else 0.25)
    sk = Skeleton([[1.0, 0.5, 0.5], [3.0, 0.5, 0.5]], [[0, 1]])
    W = np.ones((len(V), 1))
    pose = forward_kinematics(sk, twist=[0.0, np.radians(degrees)])
    fig = Figure("box360", f"Fig. 8: a box twisted {degrees:g} deg, heat vs BBW endpoint "
                 "weights", V, F, sk, W, projection(V, sk))
    fig.key = "fig8"
    far = np.isclose(V[:, 0], V[:, 0].max())
    xs = np.unique(np.round(V[:, 0], 9))
    curves, panels = {}, []
    for method, mesh in (("heat", {"F": F}), ("bbw", {"T": T})):   # each on its own mesh
        E = endpoint_weights(V, sk, method=method, **mesh)
        U = deform(V, sk, pose, W, E, method="stbs-dqs")
        fig.U[method] = U
        fig.numbers[method] = {"far": degrees * float(E[far, 0].mean())}
        curves[method] = np.array([degrees * E[np.isclose(V[:, 0], x), 0].mean() for x in xs])
        panels.append(Panel(U, F, title=f"{method} endpoint weights", scalars=E[:, 0],
                            cmap="Reds", C=pose.joints(), BE=sk.BE,
                            subtitle=f"far end {fig.numbers[method]['far']:.0f} deg"))
    panels.append(PlotPanel(title="twist along the box", x=xs, ys=curves, xlabel="x",
                            ylabel="twist (deg)"))
    fig.columns = [("far", "twist at far end (deg)", "{:.1f}")]
    fig.expected = {"far": f"bbw: {degrees:g} (full); heat: short of it"}
    fig.notes = ["stbs-dqs; the bone covers x in [1, 3] of a box [0, 4] x [0, 1]^2; heat on "
                 "the surface, BBW on a Kuhn-subdivided tet grid"]
    fig.caption = ("Fig. 8. One bone twisted a full turn at its end. Heat endpoint weights "
                   "(joints as points) fall off beyond the joints, so the far end of the box "
                   "does not turn all the way; BBW endpoint weights reach the full 360 "
                   "degrees.")
    fig.pictures = {"fig8_box360.png": dict(panels=panels, ncols=3,
                                           camera=Camera(azimuth=-60.0, elevation=25.0))}
    return fig


# ---------------------------------------------------------------------- Fig. 10
def _stripes(V, axis, origin, *, count: int = 10) -> np.ndarray:
    """Per-vertex colours (n, 3): ``count`` dark stripes running along ``axis`` on skin,
    by each point's rest angle about the axis, so that a twist turns them into helices."""
    u = axis / np.linalg.norm(axis)
    ref = np.cross(u, [0.0, 0.0, 1.0]) if abs(u[2]) < 0.9 else np.cross(u, [1.0, 0.0, 0.0])
    ref /= np.linalg.norm(ref)
    d = V - origin
    phi = np.arctan2(d @ np.cross(u, ref), d @ ref)
    # A smooth band (a few triangles wide on these meshes), dark at its middle.
    band = np.clip(1.6 * np.cos(count * phi) - 0.6, 0.0, 1.0)
    skin, ink = np.array([0.91, 0.72, 0.6]), np.array([0.36, 0.2, 0.17])
    return skin + band[:, None] * (ink - skin)


def fig10_torso(quick: bool = False, *, degrees: float = 90.0) -> Figure:
    """Fig. 10: a torso twisted by one bone, identity vs spline-filtered endpoint weights.

    Endpoint weights: projection along the spine, then a monotone spline filter ``f``
    through (0.15, 0.05) and (0.6, 0.9) that moves the twist down into the abdomen.
    The surface carries stripes along the spine (drawn at rest), so the twist shows
    as their turn. Numbers per variant: the share of the twist that happens in the
    abdomen (twist at the top of the abdomen minus at its bottom, over the twist at
    the chest's top), the share left to the chest, and how far the chest's lower
    end is turned (degrees).
    """
    from ..weights.spline import SplineFilter

    m = models.torso(quick=quick)
    V, F, sk = m.V, m.F, m.sk
    W = np.ones((len(V), 1))
    E0 = projection(V, sk)
    f = SplineFilter([[0.15, 0.05], [0.6, 0.9]])
    pose = forward_kinematics(sk, twist=[0.0, np.radians(degrees)])
    axis = sk.axes[0]
    lo, hi = m.extra["abdomen"]
    fig = Figure("torso", f"Fig. 10: a torso twisted {degrees:g} deg by one bone, identity "
                 "vs spline-filtered endpoint weights", V, F, sk, W, E0)
    fig.key = "fig10"
    stripes = _stripes(V, axis, sk.C[0])
    ys = np.linspace(float(V[:, 1].min()) + 0.05, float(V[:, 1].max()) - 0.05, 60)

    def twist_at(U, y):
        idx = np.flatnonzero(np.abs(V[:, 1] - y) < 0.04)
        return float(np.degrees(section_twist(V[idx], U[idx], axis)))

    panels, curves = [], {}
    for name, E in (("identity", E0), ("spline", f(E0))):
        U = deform(V, sk, pose, W, E, method="stbs-dqs")
        fig.U[name] = U
        total = twist_at(U, float(sk.B[0, 1]))
        share = (twist_at(U, hi) - twist_at(U, lo)) / total
        fig.numbers[name] = {"abdomen": share, "chest": 1.0 - twist_at(U, hi) / total,
                             "turn": twist_at(U, hi)}
        curves[name] = np.array([twist_at(U, y) for y in ys])
        panels.append(Panel(U, F, title=f"{name} endpoint weights", colors=stripes,
                            C=pose.joints(),  # no bone drawn: it would hide the stripes
                            subtitle=f"abdomen share {share:.2f}, chest "
                                     f"{fig.numbers[name]['chest']:.2f}"))
    panels.append(PlotPanel(title="twist along the spine", x=ys, ys=curves,
                            xlabel=f"height y (abdomen: {lo:g} to {hi:g})",
                            ylabel="twist (deg)"))
    e = np.linspace(0.0, 1.0, 101)
    panels.append(PlotPanel(title="spline filter f(e)", x=e, ys={"identity": e, "spline": f(e)},
                            xlabel="e", ylabel="f(e)"))
    fig.columns = [("abdomen", "twist share abdomen", "{:.2f}"),
                   ("chest", "twist share chest", "{:.2f}"),
                   ("turn", "chest's lower end (deg)", "{:.0f}")]
    fig.expected = {"abdomen": "spline > identity (the twist moves into the abdomen)",
                    "chest": "spline < identity",
                    "turn": f"spline nearer {degrees:g} (the chest turns as one piece)"}
    fig.notes = ["stbs-dqs; projection endpoint weights along the spine, then f through "
                 "(0.15, 0.05), (0.6, 0.9); stripes drawn along the spine at rest"]
    fig.caption = ("Fig. 10. One spine bone twisted at the chest; the stripes ran straight "
                   "up the body at rest. With the endpoint weights as they are, the twist "
                   "grows evenly up the body and the chest is wrung too; a monotone spline "
                   "filter on them moves it down into the abdomen, and the chest turns as "
                   "one piece (its stripes stay straight), as a body twists.")
    fig.pictures = {"fig10_torso.png": dict(panels=panels, ncols=2,
                                           camera=Camera(azimuth=-90.0, elevation=10.0))}
    return fig


# ---------------------------------------------------------------------- Fig. 12
def fig12_picture(quick: bool = False) -> Figure:
    """Fig. 12: a 2D picture made in code, brought to life by dragging joints.

    2D BBW bone weights and BBW endpoint weights; three poses from dragged joint
    positions (``Pose.from_joints``: stretches come from the new bone lengths),
    stbs-dqs, drawn with the picture as texture. Number: the smallest ratio of a
    triangle's posed area to its rest area over the poses (no triangle flips or
    collapses: well above 0).
    """
    from ..weights.bbw import bone_weights

    m = models.picture_2d(quick=quick)
    V, F, sk = m.V, m.F, m.sk
    tex, uv = m.extra["texture"], m.extra["uv"]
    W = bone_weights(V, sk, method="bbw", F=F, tol=1e-8)
    E = endpoint_weights(V, sk, method="bbw", W=W, F=F)
    fig = Figure("picture", "Fig. 12: a picture brought to life by dragging joints", V, F, sk,
                 W, E)
    fig.key = "fig12"
    poses = {"rest": Pose.rest(sk)}
    span = float(np.ptp(sk.C, axis=0).max())
    # Bone name -> offset of its end joint (in units of the skeleton's span). Drags that
    # turn bones rather than push joints into the body: the head tilts by 16 degrees
    # (dragged further, it swings into the shoulder, where the head and arm weights
    # meet, and flattens the triangles there), the hand swings down about the elbow
    # (pulled towards the body as well, the forearm shortens to 0.78 while it bends and
    # folds the inside of the elbow).
    drags = {
        "wave": {"forearm_r": (0.10, 0.22), "upper_arm_r": (0.02, 0.10)},
        "lean": {"head": (0.10, 0.0), "forearm_l": (0.0, -0.14)},
        "stretch": {"head": (0.0, 0.12), "shin_l": (-0.05, -0.10), "shin_r": (0.05, -0.10),
                    "forearm_l": (-0.10, 0.0), "forearm_r": (0.10, 0.0)},
    }
    for label, moves in drags.items():
        Cp = sk.C.copy()
        for bone, off in moves.items():   # drag the bone's end joint (children follow)
            i = sk.names.index(bone)
            d = np.asarray(off) * span
            stack = [int(sk.BE[i, 1])]
            while stack:
                j = stack.pop()
                Cp[j] += d
                stack += [int(c) for c in sk.BE[sk.BE[:, 0] == j, 1]]
        poses[label] = Pose.from_joints(sk, Cp)

    a0 = triangle_areas(V, F)
    panels = []
    worst = np.inf
    for label, p in poses.items():
        U = deform(V, sk, p, W, E, method="stbs-dqs")[:, :2]
        fig.U[label] = U
        ratio = float((triangle_areas(U, F) / a0).min())
        worst = min(worst, ratio)
        panels.append(Panel(U, F, title=label, texture=tex, uv=uv, C=p.joints(), BE=sk.BE,
                            subtitle=f"smallest triangle keeps {ratio:.2f} of its area"))
    fig.numbers["stbs-dqs"] = {"area": worst}
    fig.columns = [("area", "min triangle area ratio", "{:.2f}")]
    fig.expected = {"area": "well above 0 (no triangle turns over or collapses)"}
    fig.notes = ["2D BBW bone and endpoint weights; poses from dragged joints"]
    fig.caption = ("Fig. 12. A picture drawn in code, its outline traced and meshed with the "
                   "skeleton inside, then posed by dragging joints: bones bend, stretch and "
                   "the picture follows.")
    fig.pictures = {"fig12_picture.png": dict(panels=panels, ncols=4)}
    frames = []
    n = 8 if quick else 16
    labels = list(poses)[1:]
    for k in range(n + 1):
        s = np.sin(np.pi * k / n) ** 2
        p = Pose.rest(sk).interpolate(poses[labels[0]], s)
        frames.append([Panel(deform(V, sk, p, W, E, method="stbs-dqs")[:, :2], F,
                             texture=tex, uv=uv)])
    fig.animations = {"fig12_picture.gif": dict(frames=frames)}
    return fig


#: Figure functions of this module, in display order.
FIGURES = (fig4_leg, fig5_arm, fig6_character, fig7_neck, fig8_box_twist, fig10_torso,
           fig12_picture)


# ---------------------------------------------------------------------- Fig. 5, real scan
def fig5_libigl_arm(quick: bool = False, *, folder, bend: float = 60.0,
                    twist: float = 180.0) -> Figure:
    """Fig. 5 on real data: libigl's arm rig, bent and twisted.

    Its own bone weights (arm-weights.dmat), projection endpoint weights, 60 degrees
    at the elbow and 180 degrees of twist at the wrist for every method (one pose:
    LBS/DQS see the twist through the hand's inherited rotation). Number: the
    wrist cross-section's size relative to rest.

    Parameters
    ----------
    quick : bool
        Unused (the scan is what it is); for the same call as the other figures.
    folder : str or os.PathLike, keyword-only
        The folder holding libigl's ``arm.obj``, ``arm.tgf`` and ``arm-weights.dmat``.
    """
    from pathlib import Path

    from .. import io

    d = Path(folder)
    mesh = io.read_mesh(d / "arm.obj")
    V, F = mesh.V, mesh.F
    sk = io.read_skeleton(d / "arm.tgf")
    W = io.read_dmat(d / "arm-weights.dmat")
    E = projection(V, sk)
    axis = np.cross(sk.axes[1], [0.0, 0.0, 1.0])
    L = np.tile(np.eye(3), (sk.n_bones, 1, 1))
    L[2] = tf.axis_angle_to_matrix(axis, np.radians(bend))
    tau = np.zeros(sk.n_joints)
    tau[3] = np.radians(twist)
    pose = forward_kinematics(sk, rotations=L, twist=tau)
    fig = Figure("libigl_arm", f"Fig. 5 on a scan: libigl's arm bent {bend:g} deg, wrist "
                 f"twisted {twist:g} deg", V, F, sk, W, E)
    fig.key = "fig5"
    wrist, u = sk.C[3], sk.axes[2]
    slab = np.abs((V - wrist) @ u + 0.03) < 0.015
    panels = []
    for m in ("lbs", "dqs", "stbs-dqs"):
        U = deform(V, sk, pose, W, E, method=m)
        fig.U[m] = U
        fig.numbers[m] = {"radius": section_radius(V[slab], U[slab])}
        panels.append(Panel(U, F, title=m, C=pose.joints(), BE=sk.BE, color=SKIN,
                            subtitle=f"wrist radius {fig.numbers[m]['radius']:.2f}"))
    fig.columns = [("radius", "wrist radius / rest", "{:.3f}")]
    fig.expected = {"radius": "lbs collapses (< 0.5); dqs, stbs-dqs ~1"}
    fig.notes = ["libigl-tutorial-data arm.obj/arm.tgf/arm-weights.dmat; projection endpoint "
                 "weights"]
    fig.caption = ("Fig. 5 on a real scan (libigl's arm, its own weights): the same twist "
                   "and bend. LBS collapses the wrist; DQS and STBS-DQS keep it.")
    fig.pictures = {"fig5_libigl_arm.png": dict(panels=panels, ncols=3)}
    return fig
