"""stbs.shapes.implicit_surface and mesh_primitives: marching tetrahedra, relaxed."""

import tracemalloc

import numpy as np
import pytest

from shape_checks import assert_closed_outward, components, edges, sphere, torus, volume
from stbs.meshing._geometry import triangle_angles
from stbs.shapes import (
    ellipsoid,
    implicit_surface,
    mesh_primitives,
    mirror,
    round_cone,
    rounded_box,
)
from work_count import Lines


# ---------------------------------------------------------------- marching tetrahedra
def test_octahedron_by_hand():
    # One grid point inside (the origin, d = -0.5) on a 3x3x3 grid of spacing 1: the
    # surface is the link of the origin in the Kuhn triangulation, 24 triangles on the
    # 14 grid edges leaving it (6 axis, 6 face and 2 body diagonals). Along edge e the
    # field goes linearly from -0.5 to |e| - 0.5, so the vertex is at t = 0.5 / |e|: at
    # 0.5 e / |e|, on the sphere.
    V, F = implicit_surface(sphere(0.5), [-1, -1, -1], [1, 1, 1], 2, relax=0)
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
    V, F = implicit_surface(sphere(1.0), [-1.3] * 3, [1.3] * 3, 40, relax=relax)
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
    V, F = implicit_surface(torus(), [-1.5, -1.5, -0.5], [1.5, 1.5, 0.5], 36)
    assert_closed_outward(V, F)
    assert V.shape[0] - edges(F).shape[0] + F.shape[0] == 0  # Euler characteristic 2 - 2g
    assert volume(V, F) == pytest.approx(2 * np.pi ** 2 * 1.0 * 0.35 ** 2, rel=0.03)


def test_values_at_grid_points_do_not_make_degenerate_triangles():
    # The cube's faces pass exactly through grid samples (d = 0 there): they are pushed
    # off zero, so no vertex lands on a sample and no triangle collapses. (Its edges are
    # cut off by up to a cell: a grid does not follow sharp creases.)
    def cube(X):
        return np.abs(X).max(axis=1) - 0.5
    V, F = implicit_surface(cube, [-1, -1, -1], [1, 1, 1], 8, relax=0)
    assert_closed_outward(V, F, self_intersections=False)
    assert 0.6 < volume(V, F) < 1.0
    assert np.abs(np.abs(V).max(axis=1) - 0.5).min() < 1e-3  # faces in place
    V, F = implicit_surface(sphere(0.5), [-1, -1, -1], [1, 1, 1], 8)  # (0.5, 0, 0) ...
    assert_closed_outward(V, F)


def test_two_shapes_give_two_components_and_grid_per_axis():
    def two(X):
        return np.minimum(sphere(0.4)(X - [0.6, 0, 0]), sphere(0.4)(X + [0.6, 0, 0]))
    V, F = implicit_surface(two, [-1.2, -0.6, -0.6], [1.2, 0.6, 0.6], (30, 15, 15))
    assert_closed_outward(V, F)
    assert components(V.shape[0], F) == 2


def test_sixty_cubed_grid_in_one_sampling_and_no_loop_per_cell():
    # The grid is sampled in one call of sdf and each of the 4 relaxation steps and the
    # last projection in one more; no Python loop runs per sample, cube or vertex (the
    # same lines of stbs code run for a 15^3 and a 60^3 grid); memory a few hundred bytes
    # a sample (about 140), never a table over pairs of them.
    def run(n):
        calls = []

        def sdf(X):
            calls.append(len(X))
            return torus()(X)

        tracemalloc.start()
        try:
            with Lines() as work:
                V, F = implicit_surface(sdf, [-1.5, -1.5, -1.5], [1.5, 1.5, 1.5], n)
            _, peak = tracemalloc.get_traced_memory()
        finally:
            tracemalloc.stop()
        return V, F, calls, work.count, peak

    run(4)                                          # first calls fill caches
    _, _, _, small, _ = run(15)
    V, F, calls, work, peak = run(60)
    assert calls == [61**3] + [4 * len(V)] * 5
    assert work <= small + 100, (small, work)
    assert peak < 300 * 61**3, f"{peak / 2**20:.0f} MiB allocated"
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
        implicit_surface(args["sdf"], args["lo"], args["hi"], args["resolution"],
                           relax=relax)



def test_mesh_primitives_meshes_the_blend_in_its_bounds():
    parts = [round_cone((0, 0, 0), (1, 0, 0), 0.3, 0.2),
             ellipsoid((1.1, 0.0, 0.0), (0.3, 0.2, 0.2), k=0.1),
             rounded_box((-0.45, 0.0, 0.0), (0.3, 0.15, 0.15), 0.05, k=0.1)]
    V, F = mesh_primitives(parts + mirror(parts[1:2]), 0.06)
    assert_closed_outward(V, F)
    assert components(V.shape[0], F) == 1
    assert np.degrees(triangle_angles(V, F)).min() > 5.0
    assert V[:, 0].max() == pytest.approx(1.4, abs=0.02)   # the ellipsoid's tip
    assert V[:, 0].min() == pytest.approx(-1.4, abs=0.02)  # and its mirror image's
    # The grid follows h: a finer one gives more, shorter edges.
    V2, F2 = mesh_primitives(parts, 0.12)
    assert V2.shape[0] < 0.5 * V.shape[0]
    with pytest.raises(ValueError, match="h must be > 0, got 0.0"):
        mesh_primitives(parts, 0.0)
