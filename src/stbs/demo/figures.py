"""The paper's Figs. 2 and 3 as computations: one function per figure, returning numbers.

Each function builds a built-in shape (:mod:`stbs.shapes`), poses it, deforms it
with the four skinning methods and measures one or two numbers per method that show
the paper's point. They return a :class:`Figure` holding the rest mesh, the deformed
positions per method and the numbers, so that a renderer can draw the same cases.

Endpoint weights are projection weights (eq. 8) throughout: on these shapes they
are exactly the linear fall-off the figures need.

How twists are given to LBS and DQS
-----------------------------------
The LBS and DQS formulas have no twist term: a bone's twist angles are ignored,
only its rotation ``R_i`` counts. The poses are therefore chosen so that each
method gets the same *rotations*:

- Fig. 3 left (one bone): a twist at the far end joint would leave LBS/DQS
  unchanged, so for them the bone is instead rotated by the twist about its own
  axis. That is what "twisting the whole shape uniformly" means in the paper: with
  w = 1 everywhere the box turns rigidly. STBS gets the twist at the end joint.
- Fig. 3 right (two bones): one forward-kinematics pose for every method, with the
  twist at the middle joint. STBS spreads it along the upper bone (theta_b); the
  lower bone inherits it as part of its rotation ``R_1``, which all methods use. So
  LBS/DQS see the lower bone turned by 180 degrees against the upper one and blend
  the two rotations in the small overlap at the joint (candy wrapper for LBS,
  twist packed near the joint for DQS).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .. import shapes
from .. import transforms as tf
from ..pose import Pose, forward_kinematics
from ..skeleton import Skeleton
from ..skinning import METHODS, deform
from ..weights.endpoint import projection
from .render import Camera, Panel, PlotPanel

__all__ = ["Figure", "fig2_cigar_stretch", "fig3_box_twist", "fig3_bar_bend_twist",
           "section_twist", "section_radius", "FIGURES"]


@dataclass(eq=False)
class Figure:
    """One demo case: a rest shape, its deformations per method and the measured numbers.

    Attributes
    ----------
    name : str
        Short name, used as the file prefix (``cigar``, ``box``, ``bar``).
    title : str
        One line saying what is done.
    V : (n, 3) float64
        Rest positions.
    F : (f, 3) int64
        Triangles.
    sk : Skeleton
    W, E : (n, b) float64
        Bone and endpoint weights used.
    poses : dict[str, Pose]
        The pose each method was given.
    U : dict[str, (n, 3) float64]
        Deformed positions per method.
    numbers : dict[str, dict[str, float]]
        ``numbers[method][column]``.
    columns : list of (key, header, format)
        The columns of ``numbers`` in display order.
    expected : dict[str, str]
        ``expected[column]``: what the paper predicts, in words.
    notes : list of str
        How the case was set up.
    key : str
        The paper's figure (``"fig2"``, ...), as ``stbs demo --only`` takes it.
    caption : str
        What the pictures show, for the gallery.
    pictures : dict[str, dict]
        PNG file name -> keyword arguments of :func:`stbs.demo.render.render_panels`
        (``panels``, ``ncols``, ``camera``, ...).
    animations : dict[str, dict]
        GIF file name -> keyword arguments of :func:`stbs.demo.render.render_animation`.
    """

    name: str
    title: str
    V: np.ndarray
    F: np.ndarray
    sk: Skeleton
    W: np.ndarray
    E: np.ndarray
    poses: dict[str, Pose] = field(default_factory=dict)
    U: dict[str, np.ndarray] = field(default_factory=dict)
    numbers: dict[str, dict[str, float]] = field(default_factory=dict)
    columns: list[tuple[str, str, str]] = field(default_factory=list)
    expected: dict[str, str] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    key: str = ""
    caption: str = ""
    pictures: dict = field(default_factory=dict)
    animations: dict = field(default_factory=dict)


# ---------------------------------------------------------------------- measures
def section_twist(P, Q, axis) -> float:
    """Angle (radians, in (-pi, pi]) that turns cross-section ``P`` into ``Q`` about ``axis``.

    Parameters
    ----------
    P, Q : (m, 3) float
        The rest and deformed positions of one cross-section's vertices.
    axis : (3,) float
        Direction of the rotation axis (the bone's posed axis).

    Notes
    -----
    Both sections are centred and projected onto the plane normal to ``axis``; the
    angle is the least-squares 2D rotation between them,
    ``atan2(sum axis . (p x q), sum p . q)``.
    """
    n = np.asarray(axis, dtype=float)
    n = n / np.linalg.norm(n)
    p = P - P.mean(axis=0)
    q = Q - Q.mean(axis=0)
    p = p - np.outer(p @ n, n)
    q = q - np.outer(q @ n, n)
    return float(np.arctan2(np.sum(np.cross(p, q) @ n), np.sum(p * q)))


def section_radius(P, Q) -> float:
    """RMS distance of ``Q``'s vertices from their centroid, relative to that of ``P``."""
    rp = np.sqrt(np.mean(np.sum((P - P.mean(axis=0)) ** 2, axis=1)))
    rq = np.sqrt(np.mean(np.sum((Q - Q.mean(axis=0)) ** 2, axis=1)))
    return float(rq / rp)


def _unwrapped_twists(V, U, axis) -> tuple[np.ndarray, np.ndarray]:
    """Twist (degrees) of every cross-section along x, unwrapped from the x = min end.

    The first section's angle is put in [0, 360); the rest follow by continuity
    (neighbouring sections differ by far less than 180 degrees on these grids).
    """
    secs = shapes.sections(V)
    xs = np.array([x for x, _ in secs])
    ang = np.array([section_twist(V[i], U[i], axis) for _, i in secs])
    ang = np.unwrap(ang)
    first = np.mod(ang[0] + 1e-9, 2 * np.pi) - 1e-9
    return xs, np.degrees(ang - ang[0] + first)


def _run(fig: Figure, methods) -> None:
    for m in methods:
        fig.U[m] = deform(fig.V, fig.sk, fig.poses[m], fig.W, fig.E, method=m)


# ---------------------------------------------------------------------- figures
def fig2_cigar_stretch(quick: bool = False, *, sigma: float = 2.0,
                       methods=METHODS) -> Figure:
    """Fig. 2: one bone inside a cigar, stretched to ``sigma`` times its length.

    Number per method: ``beyond`` = length of the part of the shape beyond the
    bone's posed end, relative to rest. LBS and DQS scale the whole shape along the
    bone, so that part grows by ``sigma`` ("explosion"); STBS translates it with the
    bone's end (e = 1 there), so it keeps its length (1).
    """
    V, F, sk, W = shapes.cigar(12 if quick else 32)
    fig = Figure("cigar", f"Fig. 2: one bone in a cigar, stretched x{sigma:g}", V, F, sk, W,
                 projection(V, sk))
    pose = forward_kinematics(sk, stretch=[sigma])
    fig.poses = {m: pose for m in methods}
    _run(fig, methods)
    u0, b0 = sk.axes[0], sk.B[0]
    rest = float(np.max((V - b0) @ u0))
    u1 = pose.rotations[0] @ u0
    b1 = pose.ends[0]
    for m in methods:
        fig.numbers[m] = {"beyond": float(np.max((fig.U[m] - b1) @ u1)) / rest}
    fig.columns = [("beyond", "beyond end / rest", "{:.3f}")]
    fig.expected = {"beyond": f"lbs, dqs: {sigma:g} (explodes); stbs-*: 1 (kept)"}
    fig.notes = [f"stretch sigma = {sigma:g}; projection endpoint weights (eq. 8); "
                 f"rest length beyond the bone's end = {rest:g}"]
    fig.key = "fig2"
    fig.caption = (f"Fig. 2. One bone inside a cigar, stretched to {sigma:g} times its "
                   "length. LBS (and DQS) must scale the whole shape, so the part beyond the "
                   "bone's end explodes; STBS varies the stretch with the endpoint weight "
                   "and carries the tip rigidly.")
    cam = Camera(azimuth=-90.0, elevation=15.0)
    panels = [Panel(V, F, title="rest", C=sk.C, BE=sk.BE, color="#c9a27e")]
    panels += [Panel(fig.U[m], F, title=m, C=pose.joints(), BE=sk.BE, color="#c9a27e",
                     subtitle=f"beyond end x{fig.numbers[m]['beyond']:.2f}")
               for m in ("lbs", "stbs-lbs") if m in fig.U]
    fig.pictures = {"fig2_cigar.png": dict(panels=panels, ncols=1, camera=cam,
                                           panel_size=(640, 220))}
    if "lbs" in fig.U and "stbs-lbs" in fig.U:
        frames = []
        for k in range(13 if quick else 25):
            s_k = 1.0 + (sigma - 1.0) * np.sin(np.pi * k / (12 if quick else 24))
            p_k = forward_kinematics(sk, stretch=[s_k])
            frames.append([Panel(deform(V, sk, p_k, W, fig.E, method=m), F, title=m,
                                 color="#c9a27e") for m in ("lbs", "stbs-lbs")])
        fig.animations = {"fig2_cigar.gif": dict(frames=frames, ncols=1, camera=cam,
                                                  panel_size=(480, 170))}
    return fig


def fig3_box_twist(quick: bool = False, *, degrees: float = 315.0,
                   methods=METHODS) -> Figure:
    """Fig. 3 left: one bone along a box, twisted by ``degrees`` at its far end.

    Numbers per method: the twist (degrees) of the middle cross-section (``mid``)
    and of the far end (``far``). STBS spreads the twist along the bone (mid = half,
    far = all of it); LBS/DQS, which can only rotate the bone (see the module
    notes), turn the whole box rigidly (mid = far).
    """
    V, F, sk, W = shapes.box(*((8, 2, 2) if quick else (32, 6, 6)))
    fig = Figure("box", f"Fig. 3 left: one bone in a box, twisted {degrees:g} deg at its "
                 "far end", V, F, sk, W, projection(V, sk))
    theta = np.radians(degrees)
    twisted = forward_kinematics(sk, twist=[0.0, theta])
    turned = forward_kinematics(sk, rotations=tf.axis_angle_to_matrix(sk.axes, [theta]))
    fig.poses = {m: (twisted if m.startswith("stbs") else turned) for m in methods}
    _run(fig, methods)
    for m in methods:
        xs, ang = _unwrapped_twists(V, fig.U[m], sk.axes[0])
        mid = int(np.argmin(np.abs(xs - xs.mean())))
        fig.numbers[m] = {"mid": float(ang[mid]), "far": float(ang[-1])}
    fig.columns = [("mid", "mid twist (deg)", "{:.1f}"), ("far", "far twist (deg)", "{:.1f}")]
    fig.expected = {"mid": f"stbs-*: {degrees / 2:g} (half); lbs, dqs: {degrees:g} (rigid)",
                    "far": f"all: {degrees:g}"}
    fig.notes = [f"stbs-*: twist {degrees:g} deg at the bone's end joint (theta = [0, "
                 f"{degrees:g}])",
                 f"lbs, dqs: no twist term, so the bone is rotated {degrees:g} deg about its own "
                 "axis (a joint twist alone would not move them at all)"]
    fig.key = "fig3"
    fig.caption = (f"Fig. 3 left. One bone twisted {degrees:g} degrees at its end. With a "
                   "single bone, LBS and DQS can only turn the whole box rigidly; STBS lets "
                   "the twist grow along the bone. The plot gives the twist of every "
                   "cross-section along the box.")
    shown = [m for m in ("lbs", "dqs", "stbs-dqs") if m in fig.U]
    panels = [Panel(fig.U[m], F, title=m, C=fig.poses[m].joints(), BE=sk.BE, color="#9fb7d9",
                    subtitle=f"mid {fig.numbers[m]['mid']:.0f} deg, far "
                             f"{fig.numbers[m]['far']:.0f} deg") for m in shown]
    curves = {}
    for m in shown:
        xs, ang = _unwrapped_twists(V, fig.U[m], sk.axes[0])
        curves[m] = ang
    panels.append(PlotPanel(title="twist along the box", x=xs, ys=curves, xlabel="x",
                            ylabel="twist (deg)"))
    fig.pictures = {"fig3_box.png": dict(panels=panels, ncols=2,
                                         camera=Camera(azimuth=-60.0, elevation=25.0))}
    frames = []
    n = 8 if quick else 20
    for k in range(n + 1):
        a = theta * k / n
        frames.append([Panel(deform(V, sk, forward_kinematics(sk, twist=[0.0, a]) if m.startswith(
            "stbs") else forward_kinematics(sk, rotations=tf.axis_angle_to_matrix(sk.axes, [a])),
            W, fig.E, method=m), F, title=m, color="#9fb7d9") for m in ("lbs", "stbs-dqs")])
    fig.animations = {"fig3_box_twist.gif": dict(frames=frames, ncols=2,
                                                 camera=Camera(azimuth=-60.0, elevation=25.0))}
    return fig


def fig3_bar_bend_twist(quick: bool = False, *, bend: float = 60.0, twist: float = 180.0,
                        sigma: float = 1.5, methods=METHODS) -> Figure:
    """Fig. 3 right: a two-bone bar bent at the middle joint, twisted and stretched.

    One forward-kinematics pose for every method: the lower bone bends by ``bend``
    degrees about z at the middle joint, the middle joint twists by ``twist`` degrees
    and the upper bone stretches by ``sigma``.

    Numbers per method: ``radius``, the smallest cross-section size near the joint
    (|x - joint| <= 1) relative to rest, which LBS collapses (candy wrapper); and
    ``twist_mid``, the twist of the cross-section half-way along the upper bone, which
    STBS spreads to half the twist while LBS/DQS leave it at 0 (all twisting packed
    into the overlap of the bone weights at the joint).
    """
    V, F, sk, W = shapes.bar(*((8, 2, 2) if quick else (32, 6, 6)))
    fig = Figure("bar", f"Fig. 3 right: two bones in a bar, bent {bend:g} deg, twisted "
                 f"{twist:g} deg, stretched x{sigma:g}", V, F, sk, W, projection(V, sk))
    joint = int(sk.BE[0, 1])
    tau = np.zeros(sk.n_joints)
    tau[joint] = np.radians(twist)
    L = np.tile(np.eye(3), (2, 1, 1))
    L[1] = tf.axis_angle_to_matrix(np.array([0.0, 0.0, 1.0]), np.radians(bend))
    pose = forward_kinematics(sk, rotations=L, stretch=[sigma, 1.0], twist=tau)
    fig.poses = {m: pose for m in methods}
    _run(fig, methods)
    xj = float(sk.C[joint, 0])
    xm = float(0.5 * (sk.A[0, 0] + sk.B[0, 0]))
    axis0 = pose.rotations[0] @ sk.axes[0]
    secs = shapes.sections(V)
    near = [i for x, i in secs if abs(x - xj) <= 1.0 + 1e-9]
    mid = min(secs, key=lambda s: abs(s[0] - xm))[1]
    for m in methods:
        U = fig.U[m]
        fig.numbers[m] = {
            "radius": min(section_radius(V[i], U[i]) for i in near),
            "twist_mid": float(np.degrees(section_twist(V[mid], U[mid], axis0))),
        }
    fig.columns = [("radius", "min radius / rest", "{:.3f}"),
                   ("twist_mid", "twist mid-upper (deg)", "{:.1f}")]
    fig.expected = {"radius": "lbs: collapses (candy wrapper); dqs, stbs-dqs: 1; stbs-lbs: a "
                              f"little below 1 (only the {bend:g} deg bend is blended linearly)",
                    "twist_mid": f"stbs-*: {twist / 2:g} (spread); lbs, dqs: 0 (packed at "
                                 "the joint)"}
    fig.notes = [f"one pose for all methods: joint twist {twist:g} deg at the middle joint, "
                 f"lower bone bent {bend:g} deg about z, upper bone stretched x{sigma:g}",
                 "lbs/dqs ignore the twist angles but the lower bone inherits the twist in "
                 "its rotation"]
    fig.key = "fig3"
    fig.caption = (f"Fig. 3 right. Two bones bent {bend:g} degrees, twisted {twist:g} degrees "
                   f"at the joint and stretched. LBS collapses at the joint (candy wrapper); "
                   "DQS keeps the volume but packs the twist into the joint; STBS spreads it "
                   "along the upper bone.")
    panels = [Panel(fig.U[m], F, title=m, C=pose.joints(), BE=sk.BE, color="#9fb7d9",
                    subtitle=f"radius {fig.numbers[m]['radius']:.2f}, mid twist "
                             f"{fig.numbers[m]['twist_mid']:.0f} deg")
              for m in ("lbs", "dqs", "stbs-dqs") if m in fig.U]
    fig.pictures = {"fig3_bar.png": dict(panels=panels, ncols=3,
                                         camera=Camera(azimuth=-60.0, elevation=30.0))}
    return fig


#: The figure functions in display order.
FIGURES = (fig2_cigar_stretch, fig3_box_twist, fig3_bar_bend_twist)
