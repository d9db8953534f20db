"""stbs.demo.models: marching tetrahedra, distance fields and the demo's built-in models."""

import numpy as np
import pytest
from scipy.sparse import coo_array
from scipy.sparse.csgraph import connected_components

import stbs
from stbs.demo import models as M
from stbs.geometry import winding_numbers
from stbs.meshing import check_surface
from stbs.meshing._geometry import triangle_angles

MODELS_3D = ["arm", "leg", "torso", "character"]
MODELS_2D = ["long_necked_animal_2d", "picture_2d"]


# ---------------------------------------------------------------- helpers
def volume(V, F) -> float:
    P = V[F]
    return float(np.einsum("ij,ij->i", P[:, 0], np.cross(P[:, 1], P[:, 2])).sum()) / 6.0


def edges(F) -> np.ndarray:
    H = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    return np.unique(np.sort(H, axis=1), axis=0)


def components(n, F) -> int:
    E = edges(F)
    G = coo_array((np.ones(E.shape[0]), (E[:, 0], E[:, 1])), shape=(n, n))
    return int(connected_components(G, directed=False)[0])


def assert_closed_outward(V, F, *, self_intersections=True):
    """Closed, consistently outward, manifold, no zero-area triangle, no self-crossing.

    The raw marching-tetrahedra surface cannot cross itself (each triangle lies in its
    own tetrahedron) but may hold exactly coplanar neighbours on symmetric shapes,
    which check_surface's floating-point crossing test can mistake for a crossing.
    """
    # Every directed edge once and every edge in two triangles: closed and oriented.
    H = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    assert np.unique(H, axis=0).shape[0] == H.shape[0]
    assert 2 * edges(F).shape[0] == H.shape[0]
    assert volume(V, F) > 0
    V2, F2 = check_surface(V, F, self_intersections=self_intersections)
    assert np.array_equal(F2, F)  # not flipped: already outward


def sphere(r=1.0):
    return lambda X: np.linalg.norm(X, axis=1) - r


def torus(R=1.0, r=0.35):
    def sdf(X):
        q = np.stack([np.linalg.norm(X[:, :2], axis=1) - R, X[:, 2]], axis=1)
        return np.linalg.norm(q, axis=1) - r
    return sdf


_CACHE: dict = {}


def model(name, quick):
    """Each model built once per session (they are deterministic: tested below)."""
    key = (name, quick)
    if key not in _CACHE:
        _CACHE[key] = M.MODELS[name](quick=quick)
    return _CACHE[key]


# ---------------------------------------------------------------- marching tetrahedra
def test_octahedron_by_hand():
    # One grid point inside (the origin, d = -0.5) on a 3x3x3 grid of spacing 1: the
    # surface is the link of the origin in the Kuhn triangulation, 24 triangles on the
    # 14 grid edges leaving it (6 axis, 6 face and 2 body diagonals). Along edge e the
    # field goes linearly from -0.5 to |e| - 0.5, so the vertex is at t = 0.5 / |e|: at
    # 0.5 e / |e|, on the sphere.
    V, F = M.implicit_surface(sphere(0.5), [-1, -1, -1], [1, 1, 1], 2, relax=0)
    assert V.shape == (14, 3) and F.shape == (24, 3)
    dirs = np.vstack([np.eye(3), -np.eye(3),
                      [[1, 1, 0], [1, 0, 1], [0, 1, 1], [-1, -1, 0], [-1, 0, -1], [0, -1, -1],
                       [1, 1, 1], [-1, -1, -1]]]).astype(float)
    expect = 0.5 * dirs / np.linalg.norm(dirs, axis=1)[:, None]
    key = np.lexsort(V.T)
    assert np.allclose(V[key], expect[np.lexsort(expect.T)], atol=1e-12)
    assert_closed_outward(V, F, self_intersections=False)
    assert V.shape[0] - edges(F).shape[0] + F.shape[0] == 2


@pytest.mark.parametrize("relax", [0, 4])
def test_sphere_volume_and_orientation(relax):
    V, F = M.implicit_surface(sphere(1.0), [-1.3] * 3, [1.3] * 3, 40, relax=relax)
    assert V.dtype == np.float64 and F.dtype == np.int64
    assert_closed_outward(V, F, self_intersections=relax > 0)
    assert volume(V, F) == pytest.approx(4 / 3 * np.pi, rel=0.02)
    assert components(V.shape[0], F) == 1
    if relax:  # back on the zero set, with well-shaped triangles
        assert np.abs(np.linalg.norm(V, axis=1) - 1.0).max() < 1e-6
        assert np.degrees(triangle_angles(V, F)).min() > 10.0
    else:  # raw marching tetrahedra: vertices interpolated on grid edges, inside the ball
        assert np.linalg.norm(V, axis=1).max() <= 1.0 + 1e-12


def test_torus_has_genus_one():
    V, F = M.implicit_surface(torus(), [-1.5, -1.5, -0.5], [1.5, 1.5, 0.5], 36)
    assert_closed_outward(V, F)
    assert V.shape[0] - edges(F).shape[0] + F.shape[0] == 0  # Euler characteristic 2 - 2g
    assert volume(V, F) == pytest.approx(2 * np.pi ** 2 * 1.0 * 0.35 ** 2, rel=0.03)


def test_values_at_grid_points_do_not_make_degenerate_triangles():
    # The cube's faces pass exactly through grid samples (d = 0 there): they are pushed
    # off zero, so no vertex lands on a sample and no triangle collapses. (Its edges are
    # cut off by up to a cell: a grid does not follow sharp creases.)
    def cube(X):
        return np.abs(X).max(axis=1) - 0.5
    V, F = M.implicit_surface(cube, [-1, -1, -1], [1, 1, 1], 8, relax=0)
    assert_closed_outward(V, F, self_intersections=False)
    assert 0.6 < volume(V, F) < 1.0
    assert np.abs(np.abs(V).max(axis=1) - 0.5).min() < 1e-3  # faces in place
    V, F = M.implicit_surface(sphere(0.5), [-1, -1, -1], [1, 1, 1], 8)  # (0.5, 0, 0) ...
    assert_closed_outward(V, F)


def test_two_shapes_give_two_components_and_grid_per_axis():
    def two(X):
        return np.minimum(sphere(0.4)(X - [0.6, 0, 0]), sphere(0.4)(X + [0.6, 0, 0]))
    V, F = M.implicit_surface(two, [-1.2, -0.6, -0.6], [1.2, 0.6, 0.6], (30, 15, 15))
    assert_closed_outward(V, F)
    assert components(V.shape[0], F) == 2


def test_sixty_cubed_grid_is_fast():
    import time

    t = time.perf_counter()
    V, F = M.implicit_surface(torus(), [-1.5, -1.5, -1.5], [1.5, 1.5, 1.5], 60)
    assert time.perf_counter() - t < 2.0  # about 0.2 s on a 2-core machine
    assert F.shape[0] > 5000


@pytest.mark.parametrize("kwargs, words", [
    (dict(resolution=1), "resolution must be >= 2"),
    (dict(resolution=2.5), "resolution must be an integer"),
    (dict(resolution=(10, 10)), "resolution must be an integer"),
    (dict(resolution=True), "resolution must be an integer"),
    (dict(lo=[1, 1, 1]), "hi must be greater than lo"),
    (dict(lo=[0, 0]), "lo must have shape (3)"),
    (dict(relax=-1), "relax must be an integer >= 0, got -1"),
    (dict(sdf=3.0), "sdf must be callable, got float"),
    (dict(sdf=lambda X: X), "sdf must map points (m, 3) to distances (m,)"),
    (dict(sdf=lambda X: np.full(len(X), np.nan)), "sdf must return finite values, got nan"),
    (dict(sdf=sphere(2.0)), "sdf must be positive on the boundary"),
    (dict(sdf=lambda X: np.ones(len(X))), "sdf has no zero level set"),
])
def test_implicit_surface_bad_arguments(kwargs, words):
    args = dict(sdf=sphere(0.5), lo=[-1, -1, -1], hi=[1, 1, 1], resolution=8)
    args.update(kwargs)
    relax = args.pop("relax", 2)
    with pytest.raises(ValueError, match="^" + words.replace("(", r"\(").replace(")", r"\)")):
        M.implicit_surface(args["sdf"], args["lo"], args["hi"], args["resolution"],
                           relax=relax)


# ---------------------------------------------------------------- distance fields
def test_capsule_sdf_is_the_round_cone_distance():
    rng = np.random.default_rng(1)
    a, b, ra, rb = np.array([0.1, -0.2, 0.3]), np.array([1.4, 0.5, -0.2]), 0.5, 0.2
    X = rng.uniform(-1.5, 2.5, size=(4000, 3))
    d = M.capsule_sdf(X, a, b, (ra, rb))
    # The shape is the union of balls along the segment with linear radius.
    t = np.linspace(0.0, 1.0, 2001)
    centres = a + t[:, None] * (b - a)
    radii = ra + t * (rb - ra)
    ball = np.linalg.norm(X[:, None] - centres[None], axis=2) - radii[None]
    union = ball.min(axis=1)
    assert np.array_equal(d < 0, union < 0) or np.mean((d < 0) != (union < 0)) < 1e-3
    out = union > 1e-3
    assert np.allclose(d[out], union[out], atol=1e-4)  # exact distance outside
    # Constant radius: distance to the segment minus r; and 2D works too.
    d2 = M.capsule_sdf(X[:, :2], a[:2], b[:2], 0.3)
    s = np.clip((X[:, :2] - a[:2]) @ (b - a)[:2] / np.sum((b - a)[:2] ** 2), 0, 1)
    seg = np.linalg.norm(X[:, :2] - (a[:2] + s[:, None] * (b - a)[:2]), axis=1)
    assert np.allclose(d2, seg - 0.3, atol=1e-12)
    with pytest.raises(ValueError, match=r"r must satisfy \|r_a - r_b\| < \|b - a\|"):
        M.capsule_sdf(X, [0, 0, 0], [0.1, 0, 0], (0.5, 0.1))


def test_smooth_union_and_simple_fields():
    rng = np.random.default_rng(2)
    d1, d2 = rng.normal(size=500), rng.normal(size=500)
    assert np.array_equal(M.smooth_union(d1, d2, 0.0), np.minimum(d1, d2))
    s = M.smooth_union(d1, d2, 0.4)
    assert np.all(s <= np.minimum(d1, d2) + 1e-15)
    assert np.all(s >= np.minimum(d1, d2) - 0.4 / 4 - 1e-15)  # the fillet is at most k / 4
    far = np.abs(d1 - d2) >= 0.4
    assert np.allclose(s[far], np.minimum(d1, d2)[far])
    with pytest.raises(ValueError, match="k must be >= 0, got -1"):
        M.smooth_union(d1, d2, -1.0)
    X = rng.uniform(-2, 2, size=(1000, 3))
    assert np.allclose(M.sphere_sdf(X, [0, 0, 0], 1.0), np.linalg.norm(X, axis=1) - 1)
    # An ellipsoid with equal radii is a sphere; the box's zero set is where expected.
    assert np.allclose(M.ellipsoid_sdf(X, [0, 0, 0], [1, 1, 1]), np.linalg.norm(X, axis=1) - 1)
    assert np.array_equal(M.box_sdf(X, [0, 0, 0], [1, 0.5, 0.25]) < 0,
                          np.all(np.abs(X) < [1, 0.5, 0.25], axis=1))
    e = M.ellipsoid_sdf(X, [0.2, 0, 0], [1.0, 0.5, 0.7])
    inside = np.sum(((X - [0.2, 0, 0]) / [1.0, 0.5, 0.7]) ** 2, axis=1) < 1
    assert np.array_equal(e < 0, inside)


# ---------------------------------------------------------------- 3D models
@pytest.mark.parametrize("quick", [False, True], ids=["full", "quick"])
@pytest.mark.parametrize("name", MODELS_3D)
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


def test_arm_layout_and_hand():
    m = model("arm", False)
    assert m.sk.names == ["upper", "fore", "hand"]
    assert np.all(np.abs(m.sk.axes[:, 0]) > 0.99)  # roughly along x
    wrist, axis, hand = m.extra["wrist"], m.extra["wrist_axis"], m.extra["hand"]
    assert np.array_equal(wrist, m.sk.C[2])
    assert np.allclose(axis, m.sk.axes[1])
    assert hand.shape == (m.V.shape[0],) and hand.dtype == bool
    assert np.array_equal(hand, (m.V - wrist) @ axis > 0)
    assert 0.05 < hand.mean() < 0.3
    # The thumb points to +z: the hand is lopsided that way.
    assert m.V[hand, 2].max() > 0.3 > -m.V[hand, 2].min()


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
