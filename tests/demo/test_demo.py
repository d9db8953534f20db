"""stbs.demo: built-in shapes, the per-figure numbers, and run_demo's files."""

import json

import numpy as np
import pytest

import stbs
from stbs import transforms as tf
from stbs.demo import (
    bar,
    box,
    cigar,
    fig2_cigar_stretch,
    fig3_bar_bend_twist,
    fig3_box_twist,
    run_demo,
)
from stbs.demo.figures import section_radius, section_twist
from stbs.io import read_mesh

LBS_DQS = ("lbs", "dqs")
STBS = ("stbs-lbs", "stbs-dqs")


# ---------------------------------------------------------------- shapes
def closed_outward(V, F):
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    volume = np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6
    directed = np.vstack([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    _, count = np.unique(directed, axis=0, return_counts=True)
    undirected = np.unique(np.sort(directed, axis=1), axis=0)
    area = np.linalg.norm(np.cross(b - a, c - a), axis=1)
    # Closed and consistently oriented: every edge used once in each direction.
    return (volume > 0 and count.max() == 1 and len(undirected) * 2 == len(directed)
            and area.min() > 0)


@pytest.mark.parametrize("make", [lambda: cigar(6), lambda: cigar(20), lambda: box(4, 2, 3),
                                  lambda: bar(8, 3, 2)])
def test_shapes_are_closed_outward_meshes_with_valid_weights(make):
    V, F, sk, W = make()
    assert V.shape[1] == 3 and F.dtype == np.int64 and F.min() == 0 and F.max() == len(V) - 1
    assert closed_outward(V, F)
    assert isinstance(sk, stbs.Skeleton) and W.shape == (len(V), sk.n_bones)
    np.testing.assert_allclose(W.sum(axis=1), 1)
    assert W.min() >= 0


def test_cigar_extends_beyond_both_bone_ends():
    V, _, sk, _ = cigar(10)
    assert V[:, 0].min() == pytest.approx(-2) and V[:, 0].max() == pytest.approx(2)
    np.testing.assert_allclose(sk.C, [[-1, 0, 0], [1, 0, 0]])
    np.testing.assert_allclose(np.abs(V[:, 1:]).max(), 0.5, atol=1e-3)


def test_box_and_bar_skeletons():
    V, _, sk, _ = box(4, 2, 2)
    np.testing.assert_allclose(sk.C, [[0, 0, 0], [4, 0, 0]])
    np.testing.assert_allclose(V.min(axis=0), [0, -0.5, -0.5])
    V, _, sk, W = bar(8, 2, 2)
    assert sk.names == ["upper", "lower"] and sk.parents.tolist() == [-1, 0]
    np.testing.assert_allclose(W[V[:, 0] <= 1.5], [[1, 0]] * int((V[:, 0] <= 1.5).sum()))
    np.testing.assert_allclose(W[V[:, 0] == 2.0, 1], 0.5)
    with pytest.raises(ValueError, match="nx must be even"):
        box(5, 2, 2)
    with pytest.raises(ValueError, match="n must be an integer >= 3"):
        cigar(2)


# ---------------------------------------------------------------- measures
def test_section_twist_and_radius_by_hand():
    t = np.linspace(0, 2 * np.pi, 7)[:-1]
    P = np.stack([np.full_like(t, 3.0), np.cos(t), np.sin(t)], axis=1)
    R = tf.axis_angle_to_matrix(np.array([1.0, 0, 0]), np.radians(40))
    Q = P @ R.T + [1, 2, 3]
    assert np.degrees(section_twist(P, Q, [1, 0, 0])) == pytest.approx(40)
    assert np.degrees(section_twist(P, Q, [-1, 0, 0])) == pytest.approx(-40)
    assert section_radius(P, Q) == pytest.approx(1)
    assert section_radius(P, 0.5 * Q) == pytest.approx(0.5)


# ---------------------------------------------------------------- figures: the paper's points
def test_fig2_lbs_explodes_stbs_keeps_the_part_beyond_the_bone():
    fig = fig2_cigar_stretch(quick=True)
    for m in LBS_DQS:
        assert fig.numbers[m]["beyond"] == pytest.approx(2.0, abs=1e-9)
    for m in STBS:
        assert fig.numbers[m]["beyond"] == pytest.approx(1.0, abs=1e-9)
    # The bone itself is stretched by every method: the posed end joint lies at x = 3.
    assert fig.poses["lbs"].ends[0] == pytest.approx([3, 0, 0])


def test_fig3_box_stbs_spreads_the_twist_lbs_dqs_turn_rigidly():
    fig = fig3_box_twist(quick=True)
    for m in STBS:
        assert fig.numbers[m]["mid"] == pytest.approx(157.5, abs=1e-6)
        assert fig.numbers[m]["far"] == pytest.approx(315.0, abs=1e-6)
    for m in LBS_DQS:
        assert fig.numbers[m]["mid"] == pytest.approx(315.0, abs=1e-6)
        assert fig.numbers[m]["far"] == pytest.approx(315.0, abs=1e-6)
        # A rigid turn: every vertex keeps its distance to the axis.
        r0 = np.linalg.norm(fig.V[:, 1:], axis=1)
        np.testing.assert_allclose(np.linalg.norm(fig.U[m][:, 1:], axis=1), r0, atol=1e-12)


def test_fig3_bar_candy_wrapper_and_twist_packing():
    fig = fig3_bar_bend_twist(quick=True)
    n = fig.numbers
    assert n["lbs"]["radius"] < 0.5  # candy wrapper: the joint collapses
    assert n["dqs"]["radius"] == pytest.approx(1, abs=0.02)
    assert n["stbs-dqs"]["radius"] == pytest.approx(1, abs=0.02)
    assert n["stbs-lbs"]["radius"] > 0.9  # only the 60 degree bend is blended linearly
    for m in LBS_DQS:
        assert n[m]["twist_mid"] == pytest.approx(0, abs=1e-6)  # twist packed at the joint
    for m in STBS:
        assert n[m]["twist_mid"] == pytest.approx(90, abs=1e-6)  # spread along the bone
    # One pose for every method, as the module documents.
    assert len({id(p) for p in fig.poses.values()}) == 1


def test_quick_and_full_meshes_give_the_same_numbers():
    for make in (fig2_cigar_stretch, fig3_box_twist, fig3_bar_bend_twist):
        q, f = make(quick=True), make(quick=False)
        assert len(f.V) > len(q.V)
        for m in stbs.METHODS:
            for k in q.numbers[m]:
                assert f.numbers[m][k] == pytest.approx(q.numbers[m][k], abs=1e-6), (make, m, k)


# ---------------------------------------------------------------- run_demo
def test_run_demo_writes_meshes_and_summary_only_inside_out_dir(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "a" / "demo"
    res = run_demo(out, quick=True)
    printed = capsys.readouterr().out
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a"]
    names = sorted(p.name for p in out.iterdir())
    want = [f"{c}_{m}.obj" for c in ("cigar", "box", "bar") for m in ("rest", *stbs.METHODS)]
    assert names == sorted(want + ["summary.json", "summary.txt"])
    assert sorted(p.name for p in res.files) == names
    for c, fig in res.figures.items():
        rest = read_mesh(out / f"{c}_rest.obj")
        np.testing.assert_allclose(rest.V, fig.V, atol=0)
        np.testing.assert_array_equal(rest.F, fig.F)
        for m in stbs.METHODS:
            np.testing.assert_allclose(read_mesh(out / f"{c}_{m}.obj").V, fig.U[m], atol=0)
    assert printed.startswith(res.summary)
    assert (out / "summary.txt").read_text() == res.summary
    for line in ("Fig. 2", "Fig. 3 left", "Fig. 3 right", "beyond end / rest",
                 "mid twist (deg)", "min radius / rest", "note: lbs, dqs: no twist term"):
        assert line in res.summary
    saved = json.loads((out / "summary.json").read_text())
    assert saved["numbers"] == res.numbers
    assert res.numbers["cigar"]["lbs"]["beyond"] == pytest.approx(2)
    assert res.numbers["box"]["stbs-dqs"]["mid"] == pytest.approx(157.5)


def test_run_demo_quiet_and_bad_out_dir(tmp_path, capsys):
    run_demo(tmp_path / "d", quick=True, quiet=True)
    assert capsys.readouterr().out == ""
    (tmp_path / "file").write_text("x")
    with pytest.raises(NotADirectoryError):
        run_demo(tmp_path / "file", quick=True, quiet=True)
    assert (tmp_path / "file").read_text() == "x"
