"""Real glTF characters (../shared/data/characters/gltf and the Khronos files in
../shared/data/gltf) against the glTF skinning formula evaluated by an independent
reader of their bytes (gltf_files.Reference): every animation at its keys and between
them (a seeded sample for long clips), each branching joint turned by hand, the meshes
and joints read."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from gltf_files import Reference

import stbs
from stbs.io import read_gltf, read_rig

FILES = ["gltf/SimpleSkin.gltf", "gltf/RiggedSimple.glb",
         "characters/gltf/CesiumMan.glb", "characters/gltf/RiggedFigure.glb",
         "characters/gltf/Fox.glb", "characters/gltf/Fox_separate/Fox.gltf",
         "characters/gltf/RobotExpressive.glb", "characters/gltf/threejs_Xbot.glb",
         "characters/gltf/BrainStem.glb"]
BIG = {"characters/gltf/threejs_Xbot.glb", "characters/gltf/BrainStem.glb"}
SLOW = {"characters/gltf/threejs_Xbot.glb"}
TOL = 1e-5
# times checked per animation: every key and mid-key up to SAMPLE of each, else a
# seeded sample, at most about BUDGET poses per file over all its animations
SAMPLE = 24
BUDGET = 160


@pytest.fixture(scope="module")
def characters(shared_data):
    cache = {}

    def get(name):
        if name not in cache:
            path = shared_data / name
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")       # scale noise; RobotExpressive's legs
                rig, clips = read_gltf(path)
            cache[name] = (path, rig, clips, Reference(path))
        return cache[name]

    return get


def _size(X):
    return float(np.linalg.norm(np.ptp(X, axis=0)))


def _times(ref, a, rng, n):
    T = ref.animation_times(a)
    mids = (T[1:] + T[:-1]) / 2
    if len(T) + len(mids) > 2 * n:
        T = np.concatenate([T[[0, -1]], rng.choice(T, n - 2, replace=False)])
        mids = rng.choice(mids, n, replace=False)
    return T, mids


@pytest.mark.parametrize("name", [pytest.param(f, marks=pytest.mark.slow) if f in SLOW else f
                                  for f in FILES])
def test_every_animation_skins_as_the_file_at_and_between_keys(characters, name):
    path, rig, clips, ref = characters(name)
    rng = np.random.default_rng(len(name))
    dfm = stbs.Deformer(rig.V, rig.skeleton, rig.W, method="lbs")
    worst = {}
    n = max(3, min(8 if name in BIG else SAMPLE, BUDGET // (2 * len(clips))))
    for a, anim in enumerate(clips):
        clip = clips[anim]
        keys, mids = _times(ref, a, rng, n)
        size = _size(ref.skin_at(a, float(keys[0])))
        for t in np.concatenate([keys, mids]):
            err = np.abs(dfm(clip.pose(float(t))) - ref.skin_at(a, float(t))).max() / size
            worst[anim] = max(worst.get(anim, 0.0), err)
    assert max(worst.values()) <= TOL, worst


@pytest.mark.parametrize("name", FILES)
def test_each_branching_joint_turned_by_hand(characters, name):
    # turned 40 degrees in its node's frame from the bind pose; FK's local rotation is
    # in the bind-aligned frame: rot(B) D rot(B)^T, carried into the rig's space
    path, rig, clips, ref = characters(name)
    sk = rig.skeleton
    nodes = rig.meta["gltf"]["joints"]
    B = ref.bind_world()
    base = ref.skin_bind()
    # the rig's space against the file's: a similarity (the identity but where the
    # file's skin matrices scale uniformly, as RobotExpressive's armature does)
    Y = _similarity(base, rig.V)
    np.testing.assert_allclose(base @ Y[:3, :3].T + Y[:3, 3], rig.V,
                               atol=1e-6 * _size(rig.V))
    Ry = Y[:3, :3] / np.cbrt(np.linalg.det(Y[:3, :3]))
    D = stbs.transforms.axis_angle_to_matrix(np.array([1.0, 2, 3]), np.radians(40))
    kids = np.bincount(sk.parents[sk.parents >= 0], minlength=sk.n_bones)
    branching = np.flatnonzero(kids >= 2)
    if branching.size == 0:              # a chain: every joint with a child
        branching = np.flatnonzero(kids >= 1)
    assert branching.size
    dfm = stbs.Deformer(rig.V, sk, rig.W, method="lbs")
    for i in branching:
        Bi = B[nodes[i]][:3, :3]
        Rb = Ry @ Bi / np.cbrt(np.linalg.det(Bi))
        R = np.tile(np.eye(3), (sk.n_bones, 1, 1))
        R[i] = Rb @ D @ Rb.T
        U = dfm(stbs.forward_kinematics(sk, rotations=R))
        want = ref.skin_bind(turn=(nodes[i], D)) @ Y[:3, :3].T + Y[:3, 3]
        assert np.abs(U - want).max() <= TOL * _size(rig.V), sk.names[i]
        assert np.abs(U - rig.V).max() > 1e-3 * _size(rig.V), sk.names[i]


def _similarity(X, Y):
    """The 4x4 similarity taking points X to Y (least squares, Umeyama)."""
    mx, my = X.mean(0), Y.mean(0)
    A, Bm = X - mx, Y - my
    U, S, Vt = np.linalg.svd(Bm.T @ A)
    d = np.sign(np.linalg.det(U @ Vt))
    Dg = np.diag([1, 1, d])
    R = U @ Dg @ Vt
    c = (S * np.diag(Dg)).sum() / (A * A).sum()
    out = np.eye(4)
    out[:3, :3] = c * R
    out[:3, 3] = my - c * R @ mx
    return out


@pytest.mark.parametrize("name, vertices, primitives, rigid, bones", [
    ("characters/gltf/BrainStem.glb", 34159, 59, 0, 18),
    ("characters/gltf/threejs_Xbot.glb", 28374, 2, 0, 67),
    # two skinned hands (1,108 vertices), 12 meshes hung on joints (15 primitives)
    ("characters/gltf/RobotExpressive.glb", 7214, 4, 15, 43),
    ("characters/gltf/Fox_separate/Fox.gltf", 1728, 1, 0, 24),
])
def test_every_skinned_mesh_and_primitive_is_read(characters, name, vertices, primitives,
                                                  rigid, bones):
    path, rig, clips, ref = characters(name)
    assert rig.V.shape == (vertices, 3) and len(ref.V) == vertices
    g = rig.meta["gltf"]
    assert len(g["primitives"]) == primitives and len(g["rigid"]) == rigid
    assert [(p["node"], p["mesh"], p["primitive"]) for p in g["primitives"]] == \
        [(k, m, p) for k, m, p, *_ in ref.prims]
    assert [(p["node"], p["mesh"], p["primitive"], p["joint"]) for p in g["rigid"]] == \
        [(k, m, p, j) for k, m, p, _, j in ref.rigid]
    parts = g["primitives"] + g["rigid"]
    assert [p["start"] for p in parts] == np.cumsum([0] + [p["count"] for p in parts])[
        :-1].tolist()
    assert sum(p["count"] for p in parts) == vertices
    assert rig.skeleton.n_bones == bones
    # bones named as their joint nodes
    names = [ref.nodes[j].get("name") for j in g["joints"]]
    assert all(a == b for a, b in zip(rig.skeleton.names, names, strict=True) if b)
    # bone i starts at joint i's bind position
    B = ref.bind_world()
    Y = _similarity(ref.skin_bind(), rig.V)
    A = np.array([B[j][:3, 3] for j in g["joints"]]) @ Y[:3, :3].T + Y[:3, 3]
    np.testing.assert_allclose(rig.skeleton.A, A, atol=1e-6 * _size(rig.V))


def test_xbot_reads_its_two_meshes_on_one_skin(characters):
    path, rig, clips, ref = characters("characters/gltf/threejs_Xbot.glb")
    assert [p["node"] for p in rig.meta["gltf"]["primitives"]] == [67, 68]
    assert rig.meta["gltf"]["skins"] == [0]
    assert list(clips) == ["agree", "headShake", "idle", "run", "sad_pose", "sneak_pose",
                           "walk"]


def test_robot_reads_both_skins_over_one_hierarchy(characters):
    path, rig, clips, ref = characters("characters/gltf/RobotExpressive.glb")
    assert rig.meta["gltf"]["skins"] == [0, 1]
    assert {p["node"] for p in rig.meta["gltf"]["primitives"]} == {72, 73}


def test_robot_reads_its_whole_body(characters):
    # only the hands are skinned; the body, head, arms and legs hang on joint nodes.
    # Each rigid part moves exactly with its joint's skin matrix: its vertices under
    # the rig's lbs are where the file's node hierarchy draws them, at keys and between
    path, rig, clips, ref = characters("characters/gltf/RobotExpressive.glb")
    g = rig.meta["gltf"]
    names = {ref.nodes[p["node"]]["name"] for p in g["rigid"]}
    assert names == {"Foot.L", "Foot.R", "Torso", "Head", "Shoulder.L", "Shoulder.R",
                     "Arm.L", "Arm.R", "Leg.L", "Leg.R", "LowerLeg.L", "LowerLeg.R"}
    sk = rig.skeleton
    for p in g["rigid"]:
        rows = slice(p["start"], p["start"] + p["count"])
        bone = g["joints"].index(p["joint"])
        assert np.all(rig.W[rows, bone] == 1) and np.all(rig.W[rows].sum(axis=1) == 1)
        assert sk.names[bone] == ref.nodes[p["joint"]]["name"]
    skinned = sum(p["count"] for p in g["primitives"])
    assert skinned == 1108 and len(rig.V) == 7214
    assert rig.F.max() < len(rig.V) and rig.F[:, 0].size == 3237
    # every animation, at seeded keys and mid-keys
    rng = np.random.default_rng(7)
    dfm = stbs.Deformer(rig.V, sk, rig.W, method="lbs")
    size = _size(rig.V)
    worst, moved = 0.0, 0.0
    for a, anim in enumerate(clips):
        T = ref.animation_times(a)
        mids = (T[1:] + T[:-1]) / 2
        for t in np.concatenate([rng.choice(T, 2, replace=False), rng.choice(mids, 2)]):
            want = ref.skin_at(a, float(t))
            got = dfm(clips[anim].pose(float(t)))
            worst = max(worst, np.abs(got - want)[skinned:].max() / size)
            moved = max(moved, np.abs(want - rig.V)[skinned:].max() / size)
    assert worst <= TOL and moved > 0.2, (worst, moved)
    # rigid=False: the hands alone, as before
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        hands, _ = read_gltf(path, rigid=False)
    assert len(hands.V) == skinned and hands.meta["gltf"]["rigid"] == []
    np.testing.assert_array_equal(hands.V, rig.V[:skinned])


def test_a_rig_read_decodes_no_animation(shared_data, monkeypatch):
    import stbs.io.gltf.animation as anim

    def boom(*a, **k):
        raise AssertionError("an animation was decoded")

    monkeypatch.setattr(anim, "decode_clip", boom)
    monkeypatch.setattr(anim.Channel, "__init__", boom)
    rig = read_rig(shared_data / "characters/gltf/Fox_separate/Fox.gltf")
    assert rig.V.shape == (1728, 3)
    _, clips = read_gltf(shared_data / "characters/gltf/Fox.glb")
    assert list(clips) == ["Survey", "Walk", "Run"]
