"""stbs.build_rig on the surfaces real characters are made of: open, in parts,
self-intersecting, non-manifold, with bones poking out; and bone heat on tetrahedra."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import stbs
from surfaces import box, join, merged, tube


def _rig(V, sk, **kw):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        rig = stbs.build_rig(V, sk, **kw)
    return rig, [str(w.message) for w in caught if issubclass(w.category, UserWarning)]


def _valid(rig, n, b):
    W, E = np.asarray(rig.W), np.asarray(rig.E)
    assert W.shape == E.shape == (n, b)
    np.testing.assert_allclose(W.sum(axis=1), 1.0, atol=1e-9)
    assert W.min() >= 0 and W.max() <= 1 + 1e-12
    assert E.min() >= 0 and E.max() <= 1
    return W, E


def _along(V, sk, i):
    """Each vertex's parameter along bone i (unclamped)."""
    return (V - sk.A[i]) @ (sk.B[i] - sk.A[i]) / sk.lengths[i] ** 2


def _e_runs_from_0_to_1(V, sk, W, E, i, *, end=1.0):
    """Where bone i holds most of the weight, e is ~0 by its start and ~end by its end."""
    t, mine = _along(V, sk, i), W[:, i] > 0.5
    start, stop = mine & (t < 0.15), mine & (t > end - 0.15) & (t < end)
    assert start.sum() >= 5 and stop.sum() >= 5
    assert E[start, i].mean() < 0.3
    assert E[stop, i].mean() > end - 0.3
    assert np.corrcoef(E[mine, i], np.clip(t[mine], 0, 1))[0, 1] > 0.9


TUBE_SK = stbs.Skeleton([[0.5, 0, 0], [2.5, 0, 0], [5.0, 0, 0]], [[0, 1], [1, 2]],
                        names=["upper", "tip"])


@pytest.mark.parametrize("bone", ["bbw", "heat"])
def test_an_open_tube_with_a_bone_poking_out(bone):
    V, F = tube()                     # open at both ends; bone 1 leaves it at x = 4
    rig, said = _rig(V, TUBE_SK, F=F, bone=bone, endpoint="bbw", volume_size=0.15)
    W, E = _valid(rig, V.shape[0], 2)
    np.testing.assert_array_equal(rig.V, V)
    np.testing.assert_array_equal(rig.F, F)
    assert rig.T is None and rig.meta == {"bone": bone, "endpoint": "bbw"}
    assert any("bone 1 ('tip', joints 1->2): 40 % outside" in s for s in said)
    x = V[:, 0]
    assert W[x < 2.0, 0].mean() > 0.9 and W[x > 3.0, 1].mean() > 0.9
    _e_runs_from_0_to_1(V, TUBE_SK, W, E, 0)
    # bone 1 is inside up to t = 0.6 (x = 4): e follows t there
    _e_runs_from_0_to_1(V, TUBE_SK, W, E, 1, end=0.6)


def test_two_parts_a_bone_across_the_gap_and_bones_wholly_outside():
    V, F = join(box([0, 0, 0], [1, 1, 1], 10), box([2, 0, 0], [3, 1, 1], 10))
    # "toe" lies just under box b's floor (as a Mixamo toe bone lies on the sole);
    # "antenna" floats far above box a (as an IK pole target)
    sk = stbs.Skeleton([[0.1, 0.5, 0.5], [0.9, 0.5, 0.5], [2.1, 0.5, 0.5], [2.9, 0.5, 0.5],
                        [0.5, 0.5, 3.0], [0.5, 0.5, 4.0], [2.2, 0.5, -0.02], [2.6, 0.5, -0.02]],
                       [[0, 1], [1, 2], [2, 3], [4, 5], [6, 7]],
                       names=["a", "gap", "b", "antenna", "toe"])
    rig, said = _rig(V, sk, F=F, volume_size=0.1)
    W, E = _valid(rig, V.shape[0], 5)
    assert len(said) == 1
    for name in ("bone 1 ('gap', joints 1->2)", "bone 3 ('antenna', joints 4->5)",
                 "bone 4 ('toe', joints 6->7)", "the 1 wholly outside but near it hold",
                 "get no bone weight (bone 3 ('antenna'"):
        assert name in said[0]
    a, b = V[:, 0] < 1.5, V[:, 0] > 1.5
    assert W[a, 0].mean() > 0.5 and W[b, 2].mean() > 0.5
    _e_runs_from_0_to_1(V, sk, W, E, 0)
    _e_runs_from_0_to_1(V, sk, W, E, 2)
    # the toe holds the floor of box b it lies under; the antenna holds nothing
    floor = b & (V[:, 2] < 0.01) & (V[:, 0] < 2.6)
    assert W[floor, 4].mean() > 0.3 and W[:, 4].max() > 0.9
    assert W[:, 3].max() == 0
    # wholly outside, both keep the projection as endpoint weights
    P = stbs.endpoint_weights(V, sk)
    np.testing.assert_allclose(E[:, 3:], P[:, 3:], atol=1e-12)


def test_self_intersecting_boxes_and_a_non_manifold_edge():
    # a bar through a block (the surfaces cross), and a second block touching the first
    # along one edge only (that edge is in four triangles)
    V, F = merged(*join(box([0, 0, 0], [1, 1, 1]), box([0.4, 0.4, -1], [0.6, 0.6, 2], 12),
                        box([1, 1, 0], [2, 2, 1])))
    sk = stbs.Skeleton([[0.2, 0.2, 0.5], [0.8, 0.8, 0.5], [0.5, 0.5, -0.9], [0.5, 0.5, 1.9],
                        [1.2, 1.2, 0.5], [1.8, 1.8, 0.5]],
                       [[0, 1], [2, 3], [1, 4], [4, 5]])
    with pytest.raises(ValueError, match="non-manifold"):
        stbs.meshing.check_surface(V, F)           # not a surface TetGen could take
    rig, said = _rig(V, sk, F=F, volume_size=0.12)
    W, E = _valid(rig, V.shape[0], 4)
    bar = (np.abs(V[:, 0] - 0.5) < 0.11) & (np.abs(V[:, 1] - 0.5) < 0.11) & (
        (V[:, 2] < -0.2) | (V[:, 2] > 1.2))
    assert W[bar, 1].mean() > 0.9
    assert W[V[:, 0] > 1.3, 3].mean() > 0.6
    _e_runs_from_0_to_1(V, sk, W, E, 1)
    _e_runs_from_0_to_1(V, sk, W, E, 3)


def test_kept_weights_with_bbw_endpoint_weights_on_an_open_surface():
    V, F = tube()
    # painted-like weights: a smooth ramp across the middle joint
    s = np.clip((V[:, 0] - 2.0) / 1.0, 0, 1)
    W = np.c_[1 - s, s]
    rig, said = _rig(V, TUBE_SK, F=F, W=W, endpoint="bbw", volume_size=0.15)
    W2, E = _valid(rig, V.shape[0], 2)
    np.testing.assert_array_equal(W2, W)                  # kept exactly
    assert rig.meta["bone"] == "given"
    _e_runs_from_0_to_1(V, TUBE_SK, W, E, 0)
    # where bone 0 has no weight at all (x > 3), its e is never solved: the projection
    np.testing.assert_allclose(E[V[:, 0] > 3.5, 0], 1.0)


def test_auto_meshes_a_small_closed_surface_through_its_vertices():
    V, F = box([0, 0, 0], [2, 1, 1], 3)
    sk = stbs.Skeleton([[0.2, 0.5, 0.5], [1.0, 0.5, 0.5], [1.8, 0.5, 0.5]], [[0, 1], [1, 2]])
    stages = []
    rig = stbs.build_rig(V, sk, F=F, progress=lambda s, d, t: stages.append(s) if t == 0
                         else None)
    assert "tetrahedralize (bones inside)" in stages and "volume mesh" not in stages
    _valid(rig, V.shape[0], 2)
    stages.clear()
    rig = stbs.build_rig(V, sk, F=F, volume="winding", volume_size=0.1,
                         progress=lambda s, d, t: stages.append(s) if t == 0 else None)
    assert stages[0] == "volume mesh" and "transfer to the surface" in stages
    _valid(rig, V.shape[0], 2)


def test_bone_heat_on_tetrahedra_uses_their_boundary():
    V, F = box([0, 0, 0], [3, 1, 1], 3)
    sk = stbs.Skeleton([[0.3, 0.5, 0.5], [1.5, 0.5, 0.5], [2.7, 0.5, 0.5]], [[0, 1], [1, 2]])
    tm = stbs.tetrahedralize(V, F, sk, engine="builtin")
    inner = np.setdiff1d(np.arange(tm.V.shape[0]), np.unique(tm.F))
    assert inner.size > 0                                # vertices on no boundary triangle
    for endpoint in ("projection", "heat", "bbw"):
        rig = stbs.build_rig(tm.V, sk, T=tm.T, bone="heat", endpoint=endpoint)
        W, E = _valid(rig, tm.V.shape[0], 2)
        # the inside follows its bones too, by the Laplace equation from the boundary
        assert W[inner][tm.V[inner, 0] < 1.0, 0].min() > 0.5
        assert W[inner][tm.V[inner, 0] > 2.0, 1].min() > 0.5


@pytest.mark.parametrize("kw, match", [
    (dict(volume="magic"), "volume must be one of auto, winding, conforming"),
    (dict(volume_size=0.0), "volume_size must be a positive number"),
    (dict(volume_size=float("inf")), "volume_size must be a positive number"),
])
def test_bad_volume_options(kw, match):
    V, F = tube()
    with pytest.raises(ValueError, match=match):
        stbs.build_rig(V, TUBE_SK, F=F, **kw)
