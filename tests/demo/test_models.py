"""stbs.demo.models: the demo's built-in models (the generators: tests/shapes)."""

import numpy as np
import pytest

import stbs
from shape_checks import assert_closed_outward, components, edges
from stbs.demo import models as M
from stbs.geometry import winding_numbers
from stbs.meshing._geometry import triangle_angles

MODELS_3D = ["arm", "leg", "torso", "character"]
MODELS_2D = ["long_necked_animal_2d", "picture_2d"]




_CACHE: dict = {}


def model(name, quick):
    """Each model built once per session (they are deterministic: tested below)."""
    key = (name, quick)
    if key not in _CACHE:
        _CACHE[key] = M.MODELS[name](quick=quick)
    return _CACHE[key]


# ---------------------------------------------------------------- 3D models
@pytest.mark.parametrize("quick", [False, True], ids=["full", "quick"])
@pytest.mark.parametrize("name", [n for n in MODELS_3D if n != "arm"])  # arm: tests/shapes
def test_3d_model_is_a_closed_surface_around_its_skeleton(name, quick):
    m = model(name, quick)
    assert m.name == name and m.dim == 3 and isinstance(m.sk, stbs.Skeleton)
    V, F, sk = m.V, m.F, m.sk
    assert V.dtype == np.float64 and F.dtype == np.int64 and sk.dim == 3
    assert_closed_outward(V, F)
    assert components(V.shape[0], F) == 1
    assert np.degrees(triangle_angles(V, F)).min() > 5.0  # no slivers
    lo, hi = (1000, 3000) if quick else (3000, 8000)
    assert lo <= V.shape[0] <= hi
    size = float((V.max(axis=0) - V.min(axis=0)).max())
    assert 1.0 <= size <= 4.0
    # Strictly inside: winding number 1 at joints and along every bone, and clear of
    # the surface (the shape's own distance field).
    t = np.linspace(0.0, 1.0, 25)
    X = (sk.A[:, None] + t[None, :, None] * (sk.B - sk.A)[:, None]).reshape(-1, 3)
    assert np.allclose(winding_numbers(X, V, F), 1.0, atol=1e-6)
    assert m.extra["sdf"](X).max() < -0.05
    assert np.abs(m.extra["sdf"](V)).max() < 1e-3  # vertices on the zero set


def test_quick_is_smaller_and_models_are_deterministic():
    for name in MODELS_3D + MODELS_2D:
        assert model(name, True).V.shape[0] < 0.6 * model(name, False).V.shape[0]
    for name in ("arm", "picture_2d"):
        again = M.MODELS[name](quick=True)
        assert np.array_equal(again.V, model(name, True).V)
        assert np.array_equal(again.F, model(name, True).F)


def test_leg_torso_character_layout():
    leg = model("leg", False)
    assert leg.sk.names == ["thigh", "shin", "foot"]
    thigh, shin = leg.sk.axes[0], leg.sk.axes[1]
    assert np.degrees(np.arccos(thigh @ shin)) > 30  # bent at the knee
    assert leg.V[:, 1].min() == pytest.approx(0.0, abs=0.05)  # on the ground
    torso = model("torso", False)
    assert torso.sk.n_bones == 1 and np.allclose(torso.sk.axes[0], [0, 1, 0])
    ab, ch = torso.extra["abdomen"], torso.extra["chest"]
    a, b = torso.sk.C[:, 1]
    assert a < ab[0] < ab[1] <= ch[0] < b < ch[1]
    # Wider than deep, so that a twist about y shows.
    mid = np.abs(torso.V[:, 1] - 0.6) < 0.05
    assert np.ptp(torso.V[mid, 0]) > 1.3 * np.ptp(torso.V[mid, 2])
    ch = model("character", False)
    assert 12 <= ch.sk.n_bones <= 15
    assert np.all(ch.sk.BE[ch.sk.roots, 0] == 0)  # one tree: every root starts at the pelvis
    names = ch.sk.names
    for i, nm in enumerate(names):  # left and right mirror each other in x = 0
        if nm.endswith("_l"):
            k = names.index(nm[:-2] + "_r")
            assert np.allclose(ch.sk.A[i] * [-1, 1, 1], ch.sk.A[k])
            assert np.allclose(ch.sk.B[i] * [-1, 1, 1], ch.sk.B[k])
    height = np.ptp(ch.V[:, 1])
    assert 2.5 < height < 4.0 and np.argmax(np.ptp(ch.V, axis=0)) in (0, 1)


@pytest.mark.parametrize("name", MODELS_3D)
def test_3d_models_tetrahedralize(name):
    m = model(name, True)
    tm = stbs.tetrahedralize(m.V, m.F, m.sk, engine="builtin")
    assert np.array_equal(tm.V[:m.V.shape[0]], m.V)
    assert np.array_equal(tm.V[tm.joint_vertex], m.sk.C)
    assert tm.T.shape[0] > 3 * m.V.shape[0]


# ---------------------------------------------------------------- 2D models
@pytest.mark.parametrize("quick", [False, True], ids=["full", "quick"])
@pytest.mark.parametrize("name", MODELS_2D)
def test_2d_model_is_a_triangulation_with_bones_as_edges(name, quick):
    m = model(name, quick)
    V, F, sk = m.V, m.F, m.sk
    assert m.dim == 2 and sk.dim == 2 and F.dtype == np.int64
    lo, hi = (400, 1200) if quick else (2000, 4500)
    assert lo <= V.shape[0] <= hi
    P = V[F]
    e1, e2 = P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]
    area = (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]) / 2
    assert area.min() > 0  # counter-clockwise
    assert np.degrees(triangle_angles(V, F)).min() > 15.0
    assert 1.0 <= np.ptp(V, axis=0).max() <= 4.0
    tm = m.extra["mesh"]
    assert np.array_equal(tm.V, V) and np.array_equal(tm.F, F)
    assert np.array_equal(V[tm.joint_vertex], sk.C)
    E = {tuple(e) for e in edges(F)}
    for i in range(sk.n_bones):
        idx, _ = tm.bone_vertices(i, sk.BE)
        assert idx.size >= 3
        chain = np.sort(np.stack([idx[:-1], idx[1:]], axis=1), axis=1)
        assert all(tuple(e) in E for e in chain), sk.names[i]
    # One piece, one boundary loop: the bones are inside, not on the outline.
    assert components(V.shape[0], F) == 1
    Eall = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    _, cnt = np.unique(np.sort(Eall, axis=1), axis=0, return_counts=True)
    boundary_edges = np.unique(np.sort(Eall, axis=1), axis=0)[cnt == 1]
    on_skeleton = np.zeros(V.shape[0], dtype=bool)
    on_skeleton[tm.joint_vertex] = True
    on_skeleton[tm.on_bone >= 0] = True
    assert not on_skeleton[boundary_edges].any()


def test_animal_neck_and_head():
    m = model("long_necked_animal_2d", False)
    neck = m.extra["neck"]
    assert m.sk.names[neck] == "neck"
    assert m.sk.lengths[neck] == pytest.approx(m.sk.lengths.max())  # the longest bone
    head = m.extra["head"]
    assert head.shape == (m.V.shape[0],) and 50 < head.sum() < 0.2 * m.V.shape[0]
    tip = m.sk.B[neck]
    # The head lies beyond the neck's end, and the rest of the animal below it.
    assert np.all(m.V[head, 1] > tip[1] - 0.2)
    assert m.V[~head, 1].max() < m.V[head, 1].max()
    assert np.all(m.sk.C[:, 1] > 0) and m.V[:, 1].min() == pytest.approx(0.0, abs=0.05)


def test_picture_texture_and_uv():
    m = model("picture_2d", False)
    tex, uv = m.extra["texture"], m.extra["uv"]
    assert tex.shape == (256, 256, 4) and tex.dtype == np.uint8
    assert uv.shape == (m.V.shape[0], 2) and uv.min() >= 0 and uv.max() <= 1
    H, W = tex.shape[:2]
    # Bilinear alpha at every vertex: inside or on the traced edge (alpha 0.5 there).
    col, row = uv[:, 0] * W - 0.5, (1 - uv[:, 1]) * H - 0.5
    c0, r0 = np.floor(col).astype(int), np.floor(row).astype(int)
    fc, fr = col - c0, row - r0
    A = tex[..., 3].astype(float) / 255

    def at(r, c):
        return A[np.clip(r, 0, H - 1), np.clip(c, 0, W - 1)]

    alpha = ((1 - fr) * ((1 - fc) * at(r0, c0) + fc * at(r0, c0 + 1))
             + fr * ((1 - fc) * at(r0 + 1, c0) + fc * at(r0 + 1, c0 + 1)))
    assert alpha.min() > 0.3
    tm = m.extra["mesh"]
    assert np.all(alpha[tm.n_input:][np.isin(np.arange(tm.n_input, len(alpha)),
                                             tm.joint_vertex)] > 0.99)
    # The UVs land on the right pixels: the chest joint is the red button, the pelvis
    # joint the blue one.
    names = {n: i for i, n in enumerate(m.sk.names)}
    for bone, end, colour in (("spine", 1, 0), ("spine", 0, 2)):
        v = tm.joint_vertex[m.sk.BE[names[bone], end]]
        r, c = int(round(row[v])), int(round(col[v]))
        rgb = tex[r, c, :3].astype(int)
        assert np.argmax(rgb) == colour and rgb[colour] > 150
    # The picture is drawn, not blank: several colours inside the shape.
    inside = tex[..., 3] == 255
    assert len(np.unique(tex[inside][:, :3], axis=0)) >= 8


def test_bad_model_arguments():
    with pytest.raises(ValueError, match="quick must be True or False, got 'yes'"):
        M.arm(quick="yes")
    with pytest.raises(ValueError, match="size must be an integer >= 64 \\(pixels\\), got 10"):
        M.picture_2d(size=10)
    with pytest.raises(TypeError):
        M.leg(True)  # quick is keyword-only
