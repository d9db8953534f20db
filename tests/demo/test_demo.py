"""stbs.demo: the per-figure numbers and run_demo's files (shapes: tests/shapes)."""

import json

import numpy as np
import pytest

import stbs
from stbs import transforms as tf
from stbs.demo import (
    fig2_cigar_stretch,
    fig3_bar_bend_twist,
    fig3_box_twist,
    run_demo,
)
from stbs.demo.figures import section_radius, section_twist
from stbs.io import read_mesh

LBS_DQS = ("lbs", "dqs")
STBS = ("stbs-lbs", "stbs-dqs")


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
@pytest.fixture(scope="module")
def quick_demo(tmp_path_factory):
    root = tmp_path_factory.mktemp("demo")
    out = root / "a" / "demo"
    import io

    buf, bar = io.StringIO(), io.StringIO()
    res = run_demo(out, quick=True, stream=buf, progress=bar)
    return root, out, res, buf.getvalue(), bar.getvalue()


PNGS = ["fig2_cigar.png", "fig3_box.png", "fig3_bar.png", "fig4_leg.png", "fig5_arm.png",
        "fig6_character.png", "fig7_neck.png", "fig8_box360.png", "fig10_torso.png",
        "fig12_picture.png"]
GIFS = ["fig2_cigar.gif", "fig3_box_twist.gif", "fig5_arm_twist.gif", "fig12_picture.gif"]


@pytest.mark.slow
def test_run_demo_writes_every_file_only_inside_out_dir(quick_demo):
    root, out, res, printed, bar = quick_demo
    assert sorted(p.name for p in root.iterdir()) == ["a"]
    names = sorted(p.name for p in out.iterdir())
    meshes = [f"{c}_{m}.obj" for c in ("cigar", "box", "bar") for m in ("rest", *stbs.METHODS)]
    assert names == sorted(meshes + PNGS + GIFS + ["index.html", "summary.json",
                                                   "summary.txt"])
    assert sorted(p.name for p in res.files) == names
    for c in ("cigar", "box", "bar"):
        fig = res.figures[c]
        np.testing.assert_allclose(read_mesh(out / f"{c}_rest.obj").V, fig.V, atol=0)
        for m in stbs.METHODS:
            np.testing.assert_allclose(read_mesh(out / f"{c}_{m}.obj").V, fig.U[m], atol=0)
    assert printed.startswith(res.summary)
    assert (out / "summary.txt").read_text() == res.summary
    saved = json.loads((out / "summary.json").read_text())
    assert saved["numbers"] == res.numbers
    assert "10/10" in bar and "fig12" in bar       # the progress lines


@pytest.mark.slow
def test_pictures_are_not_blank_and_the_gallery_links_them(quick_demo):
    from PIL import Image

    _, out, res, _, _ = quick_demo
    for name in PNGS:
        im = np.asarray(Image.open(out / name).convert("RGB"))
        assert im.shape[0] > 100 and im.shape[1] > 100, name
        ink = np.any(im < 235, axis=2).mean()
        assert ink > 0.05, f"{name}: {ink:.3f} of the pixels drawn"
        assert len(np.unique(im.reshape(-1, 3), axis=0)) > 200, name
    for name in GIFS:
        with Image.open(out / name) as g:
            assert g.n_frames >= 8, name
    html = (out / "index.html").read_text()
    for name in PNGS + GIFS:
        assert f'src="{name}"' in html, name
    for fig in res.figures.values():
        assert fig.title.split(":")[0] in html


@pytest.mark.slow
def test_method_panels_differ(quick_demo):
    from stbs.demo.render import Panel, draw_panels

    _, _, res, _, _ = quick_demo
    for name in ("arm", "leg", "neck", "box360", "torso", "box", "bar"):
        fig = res.figures[name]
        kw = next(iter(fig.pictures.values()))
        panels = [p for p in kw["panels"] if isinstance(p, Panel)]
        a = draw_panels([panels[0]], camera=kw.get("camera"))
        b = draw_panels([panels[-1]], camera=kw.get("camera"))
        assert a.shape == b.shape and np.abs(a.astype(int) - b.astype(int)).mean() > 0.5, name


@pytest.mark.slow
def test_numbers_point_the_papers_way(quick_demo):
    n = quick_demo[2].numbers
    # Fig. 2: STBS keeps the cigar's end, LBS grows it
    assert n["cigar"]["lbs"]["beyond"] == pytest.approx(2)
    assert n["cigar"]["stbs-lbs"]["beyond"] == pytest.approx(1)
    # Fig. 3: STBS spreads the twist, LBS/DQS concentrate it
    assert n["box"]["stbs-dqs"]["mid"] == pytest.approx(157.5)
    assert n["box"]["lbs"]["mid"] == pytest.approx(315)
    assert n["bar"]["stbs-dqs"]["twist_mid"] == pytest.approx(90, abs=1)
    assert abs(n["bar"]["dqs"]["twist_mid"]) < 1 and n["bar"]["lbs"]["radius"] < 0.5
    # Figs. 1/5: LBS collapses, STBS-DQS does not; the hand explodes without STBS
    arm = n["arm"]
    assert arm["lbs"]["radius"] < 0.5 and arm["dqs"]["radius"] > 0.95
    assert arm["stbs-dqs"]["radius"] > 0.95
    assert arm["lbs"]["hand"] > 1.3 and arm["dqs"]["hand"] > 1.3
    assert arm["stbs-dqs"]["hand"] == pytest.approx(1, abs=0.02)
    # Fig. 4: point weights bend the thigh, bone weights explode the foot, STBS does neither
    leg = n["leg"]
    assert leg["point weights"]["bend"] > 2 * leg["stbs"]["bend"]
    assert leg["bone weights"]["stretch"] > 2 * leg["stbs"]["stretch"]
    # Fig. 6: e low at the bones' starts, high at their ends
    assert n["character"]["heat"]["start"] < 0.4 < 0.7 < n["character"]["heat"]["end"]
    # Fig. 7: IDW lets the head sag; projection is only C0 at the bone's end
    neck = n["neck"]
    assert neck["idw"]["sag"] > 5 * max(neck["heat"]["sag"], neck["bbw"]["sag"])
    assert neck["projection"]["jump"] == pytest.approx(1, abs=0.05)
    assert neck["idw"]["jump"] < 0.8
    # Fig. 8: BBW reaches the full 360 degrees, heat does not
    assert n["box360"]["bbw"]["far"] > 355 and n["box360"]["heat"]["far"] < 350
    # Fig. 10: the spline filter moves the twist into the abdomen
    torso = n["torso"]
    assert torso["spline"]["abdomen"] > torso["identity"]["abdomen"] + 0.2
    assert torso["spline"]["chest"] < torso["identity"]["chest"]
    # Fig. 12: no triangle turns over
    assert n["picture"]["stbs-dqs"]["area"] > 0


def test_run_demo_only_quiet_and_bad_input(tmp_path, capsys):
    res = run_demo(tmp_path / "d", quick=True, quiet=True, only="fig2, fig1")
    assert capsys.readouterr() == ("", "")
    assert sorted(res.figures) == ["arm", "cigar"]
    with pytest.raises(ValueError, match="--only: unknown figure 'fig9'; expected"):
        run_demo(tmp_path / "e", quick=True, quiet=True, only="fig2,fig9")
    assert not (tmp_path / "e").exists()
    (tmp_path / "file").write_text("x")
    with pytest.raises(NotADirectoryError):
        run_demo(tmp_path / "file", quick=True, quiet=True)
    assert (tmp_path / "file").read_text() == "x"
