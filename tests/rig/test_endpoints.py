"""Rigs that keep their volume; endpoint_methods and rig_endpoint_weights on any rig."""

from __future__ import annotations

import numpy as np
import pytest

import stbs
from rigs import u_shape
from stbs.rig import endpoint_methods, rig_endpoint_weights
from surfaces import box

BOX_SK = stbs.Skeleton([[0.2, 0.5, 0.5], [1.0, 0.5, 0.5], [1.8, 0.5, 0.5]], [[0, 1], [1, 2]])


def test_a_2d_rig_keeps_its_retriangulation_and_bbw_runs_on_it_again(tmp_path):
    V, F, sk = u_shape()
    rig = stbs.build_rig(V, sk, F=F, keep_volume=True)
    vol = rig.volume
    n = len(V)
    # the rig's vertices come first in the re-triangulation, each mapped to itself
    np.testing.assert_array_equal(vol.index, np.arange(n))
    np.testing.assert_array_equal(vol.V[:n], V)
    assert vol.T.shape[1] == 3
    # the same mesh as triangulate_2d makes with the bones inside
    tri = stbs.triangulate_2d((V, F), sk)
    np.testing.assert_array_equal(vol.V, tri.V)
    stbs.save_rig(tmp_path / "u.npz", rig)
    back = stbs.load_rig(tmp_path / "u.npz")
    np.testing.assert_array_equal(back.volume.V, vol.V)
    np.testing.assert_array_equal(back.volume.T, vol.T)
    assert (back.volume.M != vol.M).nnz == 0
    # on the whole volume (no restriction), as endpoint_weights on that mesh gives
    E = rig_endpoint_weights(back, "bbw", threshold=None)
    want = stbs.endpoint_weights(tri.V, sk, method="bbw", F=tri.F, threshold=None,
                                 tol=1e-10)[:n]
    np.testing.assert_allclose(E, want, atol=1e-8)


def test_a_3d_surface_rig_keeps_its_winding_volume(tmp_path):
    V, F = box([0, 0, 0], [2, 1, 1], 3)
    rig = stbs.build_rig(V, BOX_SK, F=F, volume="winding", volume_size=0.12,
                         keep_volume=True)
    vol = rig.volume
    assert vol.T.shape[1] == 4 and vol.index is None
    # rows are barycentric: they give back the surface's vertices (inside the volume)
    np.testing.assert_allclose(vol.M.sum(axis=1), 1.0, atol=1e-12)
    assert np.abs(vol.M @ vol.V - V).max() < 0.12
    assert endpoint_methods(rig) == stbs.methods.ENDPOINT_METHODS
    stbs.save_rig(tmp_path / "b.npz", rig)
    back = stbs.load_rig(tmp_path / "b.npz")
    E = rig_endpoint_weights(back, "bbw")
    W = np.asarray(rig.W)
    # where each bone carries the vertex, e agrees with the weights of the build
    for i in range(2):
        heavy = W[:, i] > 0.2
        np.testing.assert_allclose(E[heavy, i], np.asarray(rig.E)[heavy, i], atol=0.02)
    # e runs along the bone: its mean grows with x where the bone dominates
    x = V[W[:, 0] > 0.5, 0]
    e = E[W[:, 0] > 0.5, 0]
    assert np.corrcoef(x, e)[0, 1] > 0.9


def test_a_conforming_volume_is_kept_as_a_selection():
    V, F = box([0, 0, 0], [2, 1, 1], 3)
    rig = stbs.build_rig(V, BOX_SK, F=F, bone="heat", endpoint="projection",
                         volume="conforming", keep_volume=True)
    vol = rig.volume
    np.testing.assert_array_equal(vol.V[vol.index], V)       # each rig vertex is one
    assert "bbw" in endpoint_methods(rig)
    E = rig_endpoint_weights(rig, "bbw", bones=[1])
    # the bone not asked for keeps the rig's own (projection) endpoint weights
    np.testing.assert_array_equal(E[:, 0], np.asarray(rig.E)[:, 0])
    assert E[:, 1].min() >= 0 and E[:, 1].max() <= 1
    W = np.asarray(rig.W)
    mine = W[:, 1] > 0.5                 # e runs along bone 1 where it carries the vertex
    assert np.corrcoef(V[mine, 0], E[mine, 1])[0, 1] > 0.9


def test_without_a_volume_bbw_is_refused_with_the_reason():
    V, F = box([0, 0, 0], [2, 1, 1], 3)
    rig = stbs.build_rig(V, BOX_SK, F=F, bone="heat", endpoint="projection")
    assert rig.volume is None
    assert endpoint_methods(rig) == ("heat", "projection", "idw")
    with pytest.raises(ValueError, match="endpoint method 'bbw' cannot work on this rig: "
                                         "BBW needs a volume .* keep_volume=True"):
        rig_endpoint_weights(rig, "bbw")
    stages = []
    E = rig_endpoint_weights(rig, "heat", progress=lambda s, d, t: stages.append((s, d, t)))
    np.testing.assert_allclose(E, stbs.endpoint_weights(V, BOX_SK, method="heat",
                                                        W=rig.W, F=F))
    assert stages[0] == ("endpoint weights (heat)", 0, 0) and stages[-1][1:] == (2, 2)


def test_methods_of_2d_rigs_and_bad_arguments():
    V, F, sk = u_shape()
    rig = stbs.build_rig(V, sk, F=F, endpoint="projection")
    assert rig.volume is None                         # the rig's own triangles serve
    assert endpoint_methods(rig) == ("bbw", "bbw-joints", "projection", "idw")
    with pytest.raises(ValueError, match="'heat' cannot work on this rig: heat needs a 3D"):
        rig_endpoint_weights(rig, "heat")
    with pytest.raises(ValueError, match="method must be one of"):
        rig_endpoint_weights(rig, "paint")
    with pytest.raises(ValueError, match="bones must hold bone indices in 0..2"):
        rig_endpoint_weights(rig, "idw", bones=[3])
    with pytest.raises(ValueError, match="options must be among .* got 'alhpa'"):
        rig_endpoint_weights(rig, "idw", alhpa=3)
    E = rig_endpoint_weights(rig, "idw", bones=[0], alpha=3)
    np.testing.assert_allclose(E[:, 0], stbs.endpoint_weights(V, sk, method="idw",
                                                              alpha=3)[:, 0])
    np.testing.assert_array_equal(E[:, 1:], np.asarray(rig.E)[:, 1:])


def test_a_kept_volume_is_checked():
    from stbs.rig import Volume

    V, F, sk = u_shape()
    rig = stbs.build_rig(V, sk, F=F, endpoint="projection", keep_volume=True)
    vol = rig.volume
    with pytest.raises(ValueError, match=r"volume.M must have shape"):
        rig.replace(volume=Volume(V=vol.V, T=vol.T, M=vol.M[:-1]))
    with pytest.raises(ValueError, match="rows sum to 1"):
        rig.replace(volume=Volume(V=vol.V, T=vol.T, M=vol.M * 2.0))
    with pytest.raises(TypeError, match="volume must be a stbs.rig.Volume"):
        rig.replace(volume=(vol.V, vol.T))
