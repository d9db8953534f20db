"""The page on skeletons with offset children (DESIGN §2), in a real browser.

A small humanoid whose arms hang off the chest and legs off the hips (offset children,
``Skeleton(P=)``): turning a bone on the page (``turnBone``, what a gizmo ring does),
the twist slider and an IK drag go through the page's own forward-kinematics form
(ik.js ``fkObject``: each bone's rotation and offset in the frame ``R_p K_p(t_c)`` its
parent carries it in), and the skinned positions read back from the shader equal
``stbs.deform`` of the pose the library makes: ``stbs.forward_kinematics`` for a local
rotation, the same world edit done in Python for the others. Then a glTF character
with its own animation: seeks at keys and between show ``clip.pose(t)`` exactly, and
neither seeking nor playing posts the clip, and a turn of its most branching bone is
forward kinematics.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from test_viewer_page import Page, _gauss_weights, browser  # noqa: F401  (fixture)
from test_viewer_posing import _drag

import stbs
from stbs.transforms import axis_angle_to_matrix

POS_TOL = 1e-4      # of the bounding-box diagonal (float32 on the GPU)


def humanoid_rig(seed=5) -> stbs.Rig:
    """Hips, spine, chest, neck, head in a chain; arms off the chest at 3/4 of its
    length, legs off the hips' start (offset children); a tube around every bone."""
    rng = np.random.default_rng(seed)
    C, BE, names, P = [], [], [], []

    def bone(a, b, name, parent):
        C.extend([a, b])
        BE.append([len(C) - 2, len(C) - 1])
        names.append(name)
        P.append(names.index(parent) if parent else -1)

    bone([0, 1.0, 0], [0, 1.2, 0], "hips", None)
    bone([0, 1.2, 0], [0, 1.5, 0], "spine", "hips")
    bone([0, 1.5, 0], [0, 1.7, 0], "chest", "spine")
    bone([0, 1.7, 0], [0, 1.85, 0], "neck", "chest")
    bone([0, 1.85, 0], [0, 2.05, 0], "head", "neck")
    for s, side in ((1, "L"), (-1, "R")):
        bone([0.15 * s, 1.65, 0], [0.45 * s, 1.65, 0.02], f"upperarm{side}", "chest")
        bone([0.45 * s, 1.65, 0.02], [0.75 * s, 1.64, 0], f"forearm{side}", f"upperarm{side}")
        bone([0.75 * s, 1.64, 0], [0.85 * s, 1.64, 0], f"hand{side}", f"forearm{side}")
        bone([0.1 * s, 0.95, 0], [0.1 * s, 0.5, 0.03], f"thigh{side}", "hips")
        bone([0.1 * s, 0.5, 0.03], [0.1 * s, 0.05, 0], f"shin{side}", f"thigh{side}")
    C = np.array(C, dtype=float)
    # merge the duplicated joints of connected bones (a child starts at its parent's end)
    key = {tuple(np.round(c, 9)): k for k, c in reversed(list(enumerate(C)))}
    remap = np.array([key[tuple(np.round(c, 9))] for c in C])
    used, BE = np.unique(remap), remap[np.array(BE)]
    C, BE = C[used], np.searchsorted(used, BE)
    sk = stbs.Skeleton(C, BE, names=names, P=P)
    V, F = [], []
    for a, b in zip(sk.A, sk.B, strict=True):          # an 8-sided tube, 6 rings, per bone
        u = (b - a) / np.linalg.norm(b - a)
        e1 = np.cross(u, [0, 0, 1.0] if abs(u[2]) < 0.9 else [1.0, 0, 0])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(u, e1)
        base = len(V)
        for s in np.linspace(-0.05, 1.05, 6):
            for t in 2 * np.pi * np.arange(8) / 8:
                V.append(a + s * (b - a) + 0.06 * (np.cos(t) * e1 + np.sin(t) * e2))
        for r in range(5):
            for j in range(8):
                p, q = base + 8 * r + j, base + 8 * r + (j + 1) % 8
                F += [[p, q, q + 8], [p, q + 8, p + 8]]
    V = np.array(V)
    E = stbs.weights.projection(V, sk)
    E = np.asarray(E.toarray() if hasattr(E, "toarray") else E)
    E = np.clip(E + 0.05 * rng.standard_normal(E.shape), 0, 1)
    return stbs.Rig(V=V, F=np.array(F), skeleton=sk, W=_gauss_weights(V, sk, 0.12), E=E)


def _diag(V):
    return float(np.linalg.norm(np.ptp(np.asarray(V, dtype=float), axis=0)))


def _check_shader(p, pose, methods=("stbs-dqs",)):
    """The page's skinned positions equal stbs.deform of `pose` (top-4 weights); the
    four methods against the library are test_viewer_page.py's, one is enough here."""
    rig = p.rig
    errs = []
    for m in methods:
        p.js("m => stbsViewer.setMethod(m)", m)
        ref = stbs.deform(rig.V, rig.skeleton, pose, rig.W, rig.E, method=m, max_influences=4)
        errs.append(np.abs(p.positions() - ref).max() / _diag(rig.V))
    p.js("stbsViewer.setMethod('stbs-dqs')")
    assert max(errs) < POS_TOL, errs
    return max(errs)


def _turned(pose, bones, Q, c):
    """`pose` with the bones `bones` turned by Q about the point c (a world edit)."""
    R, O = pose.rotations.copy(), pose.origins.copy()
    R[bones] = Q @ R[bones]
    O[bones] = c + (O[bones] - c) @ Q.T
    return stbs.Pose(pose.skeleton, rotations=R, origins=O, stretch=pose.stretch,
                     twist=pose.twist)


def _subtree(sk, i):
    out = [i]
    for k in out:
        out.extend(np.flatnonzero(sk.parents == k).tolist())
    return out


def _same(a, b, tol=1e-9):
    return max(np.abs(a.rotations - b.rotations).max(), np.abs(a.origins - b.origins).max(),
               np.abs(a.stretch - b.stretch).max(), np.abs(a.twist - b.twist).max()) < tol


@pytest.fixture(scope="module")
def human(browser):  # noqa: F811
    p = Page(browser, humanoid_rig())
    yield p
    p.close()


def test_turning_the_hips_turns_the_legs_as_forward_kinematics_does(human):
    sk = human.rig.skeleton
    assert (~sk.connected & (sk.parents >= 0)).sum() == 4          # arms and legs hang
    human.js("stbsViewer.setPose({})")
    sent = human.js("() => stbsViewer.turnBone('hips', [0.3, 0, 1], 35)")
    # one local rotation on the branching bone, nothing else: the FK form (the server
    # makes it from the page's world transforms; the other bones' local rotations are
    # the identity up to rounding)
    assert set(sent) == {"rotate", "degrees"} and "hips" in sent["rotate"]
    others = {k: r["angle"] for k, r in sent["rotate"].items() if k != "hips"}
    assert max(map(abs, others.values()), default=0) < 1e-9, others
    L = np.tile(np.eye(3), (sk.n_bones, 1, 1))
    L[0] = axis_angle_to_matrix(np.array([0.3, 0, 1.0]), np.radians(35))
    pose = stbs.forward_kinematics(sk, rotations=L)
    assert _same(human.srv.pose, pose)
    legs = [sk.names.index(n) for n in ("thighL", "shinR")]
    assert np.linalg.norm(pose.origins[legs] - sk.A[legs], axis=1).min() > 0.03
    err = _check_shader(human, pose)
    print(f"hips turned: max |shader - stbs.deform| / diag = {err:.2e}")
    assert human.errors == []


def test_a_twisted_stretched_chest_carries_the_arms_through_page_edits(human):
    """Edits on top of a twist and a stretch on the chest, which the arms hang off at
    t_c = 3/4: the page's FK form must carry them by R_p K_p(t_c) and t_c s_p."""
    sk = human.rig.skeleton
    chest = sk.names.index("chest")
    assert sk.hang[sk.names.index("upperarmL")] == pytest.approx(0.75)
    human.js("o => stbsViewer.setPose(o)", {"stretch": {"chest": 1.3},
                                            "twist": {"chest": [10, 70]}, "degrees": True})
    base = human.srv.pose
    arms = [sk.names.index("upperarmL"), sk.names.index("upperarmR")]
    rest = stbs.Pose.rest(sk)
    assert np.linalg.norm(base.origins[arms] - rest.origins[arms], axis=1).min() > 0.02
    # the hips turned on the page: everything turns rigidly about the hips' start
    human.js("() => stbsViewer.turnBone('hips', [0, 0, 1], -25)")
    Q = axis_angle_to_matrix(np.array([0, 0, 1.0]), np.radians(-25))
    want = _turned(base, _subtree(sk, 0), Q, base.origins[0])
    assert _same(human.srv.pose, want)
    # then the chest: it and the arms (hanging off it) and the neck turn, nothing else
    human.js("() => stbsViewer.turnBone('chest', [1, 0.2, 0.3], 50)")
    Q = axis_angle_to_matrix(np.array([1, 0.2, 0.3]), np.radians(50))
    want = _turned(want, _subtree(sk, chest), Q, want.origins[chest])
    assert _same(human.srv.pose, want)
    pose = stbs.io.read_pose(human.js("stbsViewer.getPose()"), sk)
    assert _same(pose, want)
    # the twist slider on the chest: its end twist, the arms carried by the new K(3/4)
    human.js("""() => { const s = document.getElementById('bone'); s.value = '2';
                s.dispatchEvent(new Event('change')); const t = document.getElementById('twist');
                t.value = '-40'; t.dispatchEvent(new Event('input'));
                t.dispatchEvent(new Event('change')); }""")
    human.js("stbsViewer.idle()")
    L, D = want.local()
    theta = want.twist.copy()
    theta[chest, 1] = np.radians(-40)
    slid = stbs.Pose.from_local(sk, L, stretch=want.stretch, twist=theta, offsets=D)
    assert _same(human.srv.pose, slid)
    assert np.linalg.norm(slid.origins[arms] - want.origins[arms], axis=1).min() > 0.01
    err = _check_shader(human, slid)
    print(f"chest twisted, stretched, turned: max |shader - stbs.deform| / diag = {err:.2e}")
    human.js("stbsViewer.undo()")
    assert _same(human.srv.pose, want)
    assert human.errors == []


def test_an_ik_drag_of_a_knee_stops_at_the_hip(human):
    """The chain above a joint stops where an offset child hangs: a knee drag turns the
    thigh about its own start, not the hips (whose end is not the thigh's start)."""
    sk = human.rig.skeleton
    human.js("stbsViewer.setPose({})")
    human.js("stbsViewer.setDragMode('ik')")
    thigh = sk.names.index("thighL")
    knee, hip = int(sk.BE[thigh, 1]), int(sk.BE[thigh, 0])
    J0 = np.array(human.js("stbsViewer.posedJoints()"))
    x, y = human.js("stbsViewer.jointScreenPositions()")[knee]
    _drag(human, x, y, 30, -12)
    J1 = np.array(human.js("stbsViewer.posedJoints()"))
    moved = np.linalg.norm(J1 - J0, axis=1)
    leg = {int(j) for n in ("thighL", "shinL") for j in sk.BE[sk.names.index(n)]}
    assert moved[knee] > 0.02 and moved[hip] < 1e-6            # turned about the hip
    assert np.delete(moved, sorted(leg)).max() < 1e-6          # the rest of the body stays
    L0 = np.linalg.norm(J0[sk.BE[:, 1]] - J0[sk.BE[:, 0]], axis=1)
    L1 = np.linalg.norm(J1[sk.BE[:, 1]] - J1[sk.BE[:, 0]], axis=1)
    assert np.abs(L1 / L0 - 1).max() < 1e-4
    sent = human.js("stbsViewer.getPose()")
    assert set(sent["rotate"]) == {"thighL"} and "translate" not in sent
    pose = stbs.io.read_pose(sent, sk)
    assert _same(pose, human.srv.pose)
    _check_shader(human, pose)
    human.js("stbsViewer.setDragMode('stretch')")
    human.js("stbsViewer.setPose({})")
    assert human.errors == []


# --------------------------------------------------------------------------- a character
def test_a_characters_animation_plays_exactly_without_posting_the_clip(browser,  # noqa: F811
                                                                       shared_data):
    rig, clips = stbs.io.read_gltf(shared_data / "characters" / "gltf" / "CesiumMan.glb")
    name, clip = next(iter(clips.items()))
    p = Page(browser, rig, clip=clip)
    bodies = []
    p.page.on("request", lambda r: bodies.append((r.method, r.url.split("?")[0],
                                                  len(r.post_data or ""))))
    try:
        assert [k["time"] for k in p.js("stbsViewer.keys()")] == pytest.approx(clip.times)
        E = p.srv.payload.E                  # the rig's, or the projection stand-in
        V, sk = rig.V, rig.skeleton
        T = clip.times
        ts = [float(T[0]), float(T[len(T) // 3]), 0.5 * float(T[5] + T[6]),
              float(T[-1]) - 0.0123, 0.37]
        errs = []
        for t in ts:
            assert p.js("t => stbsViewer.seek(t)", t) == {"time": t}
            want = clip.pose(t)
            assert _same(p.srv.pose, want, 1e-9)
            ref = stbs.deform(V, sk, want, rig.W, E, method="stbs-dqs", max_influences=4)
            errs.append(np.abs(p.positions() - ref).max() / _diag(V))
        print(f"{name}: max |shader - stbs.deform(clip.pose(t))| / diag = {max(errs):.2e}")
        assert max(errs) < POS_TOL, errs
        p.js("stbsViewer.play()")
        p.page.wait_for_timeout(600)
        state = p.js("stbsViewer.pause()")
        assert state["playing"] is False
        assert _same(p.srv.pose, clip.pose(state["time"]), 1e-9)
        posts = [b for b in bodies if b[0] == "POST"]
        # each seek and the pause posted {"time": t} and nothing else: no clip was sent
        assert posts and all(u.endswith(("/pose", "/seek")) and n < 64 for _, u, n in posts), posts
        assert any(u.endswith("/frames") for m, u, _ in bodies if m == "GET")
        # the character's own hierarchy: a turn of the bone with the most children
        kids = np.bincount(sk.parents[sk.parents >= 0], minlength=sk.n_bones)
        br = int(np.argmax(kids))
        p.js("stbsViewer.setPose({})")
        p.js("([b, a]) => stbsViewer.turnBone(b, a, 40)", [sk.names[br], [0.2, 1, 0.3]])
        L = np.tile(np.eye(3), (sk.n_bones, 1, 1))
        L[br] = axis_angle_to_matrix(np.array([0.2, 1, 0.3]), np.radians(40))
        pose = stbs.forward_kinematics(sk, rotations=L)
        assert _same(p.srv.pose, pose, 1e-9 * max(1.0, _diag(V)))
        ref = stbs.deform(V, sk, pose, rig.W, E, method="stbs-dqs", max_influences=4)
        assert np.abs(p.positions() - ref).max() / _diag(V) < POS_TOL
        assert p.errors == []
    finally:
        p.close()


def test_the_clip_is_held_once_per_edit(browser):  # noqa: F811
    """Keys made on the page: one POST of the clip after each edit, none per seek."""
    rig = humanoid_rig()
    p = Page(browser, rig)
    sent = []
    p.page.on("request", lambda r: r.method == "POST" and sent.append(
        (r.url.split("?")[0].rsplit("/api/", 1)[1], len(r.post_data or ""))))
    try:
        p.js("stbsViewer.addKey(0, {})")
        p.js("o => stbsViewer.addKey(1, o)", {"rotate": {"hips": {"axis": [0, 0, 1],
                                                                  "angle": 60}}})
        for t in (0.25, 0.5, 0.75, 1.0):
            p.js("t => stbsViewer.seek(t)", t)
        clip = stbs.io.read_clip(p.js("stbsViewer.getClip()"), rig.skeleton)
        assert _same(p.srv.pose, clip.pose(1.0))
        assert [u for u, _ in sent].count("clip") == 1
        p.js("t => stbsViewer.deleteKey(t)", 1)
        p.js("o => stbsViewer.addKey(2, o)", {"stretch": {"spine": 1.5}})
        for t in (0.5, 1.5):
            p.js("t => stbsViewer.seek(t)", t)
        assert [u for u, _ in sent].count("clip") == 2
        assert all(n < 64 for u, n in sent if u.endswith("/pose"))
        assert p.errors == []
    finally:
        p.close()


def test_humanoid_pose_file_round_trip_is_exact():
    """The server side of the page's form: every pose reads back from its FK object."""
    rig = humanoid_rig()
    sk = rig.skeleton
    rng = np.random.default_rng(2)
    R = axis_angle_to_matrix(rng.standard_normal((sk.n_bones, 3)), rng.uniform(-2, 2, sk.n_bones))
    pose = stbs.Pose(sk, rotations=R, origins=sk.A + 0.1 * rng.standard_normal(sk.A.shape),
                     stretch=rng.uniform(0.5, 2, sk.n_bones),
                     twist=rng.uniform(-5, 5, (sk.n_bones, 2)))
    back = stbs.io.read_pose(json.loads(json.dumps(stbs.io.pose_to_dict(pose))), sk)
    assert _same(back, pose, 1e-9)
