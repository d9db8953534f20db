"""A wrong skeleton argument raises the same error from every public weights function."""

from __future__ import annotations

import numpy as np
import pytest

import stbs
from stbs import weights as w


def grid():
    """A 4 x 2 grid of squares (vertex 3 i + j at (i, j)) and two bones along its middle."""
    x, y = np.meshgrid(np.arange(5.0), np.arange(3.0), indexing="ij")
    V = np.c_[x.ravel(), y.ravel()]
    q = np.array([3 * i + j for i in range(4) for j in range(2)])
    F = np.r_[np.c_[q, q + 3, q + 4], np.c_[q, q + 4, q + 1]]
    sk = stbs.Skeleton([[0.0, 1.0], [2.0, 1.0], [4.0, 1.0]], [[0, 1], [1, 2]])
    return V, F, sk


V, F, SK = grid()

# name -> call(V, sk); every public function of stbs.weights that takes a skeleton
WITH_V = {
    "bone_weights": lambda V, sk: w.bone_weights(V, sk, F=F),
    "bone_weights(heat)": lambda V, sk: w.bone_weights(V, sk, method="heat", F=F),
    "boundary_conditions": lambda V, sk: w.boundary_conditions(V, sk, F=F),
    "bone_heat": lambda V, sk: w.bone_heat(V, F, sk),
    "heat_joint_weights": lambda V, sk: w.heat_joint_weights(V, F, sk),
    "endpoint_weights": lambda V, sk: w.endpoint_weights(V, sk),
    "endpoint_weights(heat)": lambda V, sk: w.endpoint_weights(V, sk, method="heat"),
    "endpoint_weights(bbw)": lambda V, sk: w.endpoint_weights(V, sk, method="bbw", F=F),
    "projection": lambda V, sk: w.projection(V, sk),
    "idw": lambda V, sk: w.idw(V, sk),
    "idw_joint_weights": lambda V, sk: w.idw_joint_weights(V, sk),
    "heat_endpoint": lambda V, sk: w.heat_endpoint(V, F, sk),
    "bbw_endpoint": lambda V, sk: w.bbw_endpoint(V, sk, F=F),
}
WITHOUT_V = {
    "joints_to_endpoint": lambda sk: w.joints_to_endpoint(np.zeros((len(V), 3)), sk),
    "spline_filter": lambda sk: w.spline_filter(np.zeros((len(V), 2)), [], sk=sk),
}


@pytest.mark.parametrize("name", list(WITH_V) + list(WITHOUT_V))
@pytest.mark.parametrize("bad", [np.zeros((3, 2)), (SK.C, SK.BE)], ids=["ndarray", "tuple"])
def test_not_a_skeleton_is_a_type_error(name, bad):
    call = WITH_V.get(name) or (lambda V, sk: WITHOUT_V[name](sk))
    with pytest.raises(TypeError) as info:
        call(V, bad)
    assert str(info.value) == f"sk must be a stbs.Skeleton, got {type(bad).__name__}"


@pytest.mark.parametrize("name", list(WITH_V))
def test_vertices_of_another_dimension_are_worded_once(name):
    V3 = np.c_[V, np.zeros(len(V))]
    with pytest.raises(ValueError) as info:
        WITH_V[name](V3, SK)
    assert str(info.value) == ("V must have shape (15, 2) to match the 2D skeleton sk, "
                               "got (15, 3)")


def test_the_right_skeleton_passes():
    for name, call in WITH_V.items():
        if "heat" in name:
            continue          # the joints lie on the grid's edge, where no vertex sees them
        call(V, SK)
    for call in WITHOUT_V.values():
        call(SK)
