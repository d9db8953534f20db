"""``stbs rig``: mesh + skeleton in, a complete rig out (2D bbw, 3D heat, 3D bbw)."""

import numpy as np
import pytest

import stbs
from stbs.cli import main


def check_rig(path, n, b):
    rig = stbs.load_rig(path)
    assert rig.V.shape[0] == n and rig.W.shape == (n, b) and rig.E.shape == (n, b)
    W = np.asarray(rig.W)
    E = np.asarray(rig.E)
    assert W.min() >= -1e-12 and np.allclose(W.sum(axis=1), 1.0, atol=1e-8)
    assert E.min() >= -1e-12 and E.max() <= 1 + 1e-12
    return rig


def test_rig_2d_bbw_then_deform(shared_data, tmp_path, capsys):
    d = shared_data / "fast_support_reduction"
    out = tmp_path / "cant.npz"
    assert main(["rig", str(d / "cantilever_S.obj"), str(d / "cantilever_S.tgf"),
                 "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert "time per stage" in err and "bone weights (bbw)" in err
    rig = check_rig(out, 200, 4)
    sk = rig.skeleton
    # bones inserted as constrained segments: vertices near the bone follow it (w ~ 1)
    # and endpoint weights grow along each bone
    on = np.argmin(np.linalg.norm(rig.V[:, None] - sk.C[None], axis=2), axis=0)
    np.testing.assert_allclose(rig.E[on[sk.BE[:, 1]], np.arange(4)], 1.0, atol=0.05)
    pose = stbs.forward_kinematics(sk, stretch=[1.5, 1, 1, 1])
    U = stbs.deform(rig.V, sk, pose, rig.W, rig.E)
    assert np.isfinite(U).all()


def test_rig_3d_heat(shared_data, tmp_path):
    d = shared_data / "libigl-tutorial-data"
    out = tmp_path / "arm.npz"
    assert main(["rig", str(d / "arm.obj"), str(d / "arm.tgf"), "-o", str(out),
                 "--bone", "heat", "--endpoint", "heat"]) == 0
    check_rig(out, 8311, 4)


def test_rig_3d_bbw_tetrahedralized(shared_data, tmp_path):
    out = tmp_path / "knight.npz"
    assert main(["rig", str(shared_data / "libigl-tutorial-data" / "decimated-knight.off"),
                 str(shared_data / "computer-graphics-kinematics" / "knight.tgf"),
                 "-o", str(out)]) == 0
    rig = check_rig(out, 502, 18)
    assert rig.F is not None and rig.T is None  # the user's surface, not our tets


@pytest.mark.slow
def test_rig_elephant_with_its_tips_outside(shared_data, tmp_path, capsys):
    # elephant.tgf's trunk and tail tips poke out of the skin by 0.05 and 0.11.
    d = shared_data / "libigl-tutorial-data"
    out = tmp_path / "elephant.npz"
    args = ["rig", str(d / "elephant.obj"), str(d / "elephant.tgf"), "-o", str(out)]
    # the default (winding-number volume): the tips are left out, with a warning
    assert main(args) == 0
    err = capsys.readouterr().err
    assert "warning: volume mesh: 2 bone(s) leave the shape (bone 5 ('bone5', joints " \
        "5->6): 6 % outside, up to 0.0452; bone 18 ('bone18', joints 18->19)" in err
    rig = check_rig(out, 6034, 24)
    # Against the weights shipped with the model (libigl's tutorial): same dominant
    # bone on most of the surface (measured 0.88).
    ref = stbs.io.read_dmat(d / "elephant-weights.dmat")
    assert (np.argmax(rig.W, axis=1) == np.argmax(ref, axis=1)).mean() > 0.8
    # tetrahedra through the surface's vertices: the tips are an error unless clipped
    conforming = [*args, "--tets", "conforming"]
    assert main(conforming) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "outside the surface by 0.0452" in err[0]
    assert "--clip-skeleton" in err[0]
    assert main([*conforming, "--clip-skeleton"]) == 0
    err = capsys.readouterr().err
    assert "warning: tetrahedralize: 2 skeleton point(s)" in err
    # The joints left out are outside the mesh: no nearest-vertex stand-in for them.
    assert "no mesh vertex lies on" not in err
    rig = check_rig(out, 6034, 24)
    assert (np.argmax(rig.W, axis=1) == np.argmax(ref, axis=1)).mean() > 0.8


def test_rig_2d_with_a_joint_past_the_edge(shared_data, tmp_path, capsys):
    # cantilever_S spans x in [-1, 1]; its last joint moved to x = 1.3, outside.
    d = shared_data / "fast_support_reduction"
    tgf = tmp_path / "long.tgf"
    tgf.write_text((d / "cantilever_S.tgf").read_text().replace("5  0.8", "5  1.3", 1))
    out = tmp_path / "cant.npz"
    args = ["rig", str(d / "cantilever_S.obj"), str(tgf), "-o", str(out)]
    assert main(args) == 2
    assert "joint 4 at (1.3, 0) outside the outline" in capsys.readouterr().err
    assert main([*args, "--clip-skeleton"]) == 0
    err = capsys.readouterr().err
    assert "1 bone(s) cross the outline" in err and "the farthest 0.3 outside" in err
    rig = check_rig(out, 200, 4)
    # The last bone's endpoint weight grows along it up to the shape's end (t = 0.6).
    tip = np.argmin(np.linalg.norm(rig.V - [1.0, 0.0], axis=1))
    assert 0.5 < rig.E[tip, 3] < 0.7


@pytest.mark.parametrize("extra, match", [
    (["-o", "x.obj"], "expected a rig file (.npz)"),
    (["-o", "nofolder/x.npz"], "does not exist"),
    (["-o", "x.npz", "--bone", "heat"], "needs a 3D triangle surface"),
    (["-o", "x.npz", "--bone", "magic"], "invalid choice"),
    (["-o", "x.npz", "--tol", "0"], "--tol: expected a positive number, got 0.0"),
    (["-o", "x.npz", "--tol", "nan"], "--tol: expected a positive number, got nan"),
    (["-o", "x.npz", "--tol", "abc"], "invalid float value"),
    (["-o", "x.npz", "--bone", "heat", "--endpoint", "idw", "--tol", "1e-6"],
     "--tol applies to --bone bbw or --endpoint bbw/bbw-joints"),
    (["-o", "x.npz", "--bone", "heat", "--clip-skeleton"],
     "--clip-skeleton applies when stbs meshes the shape itself"),
])
def test_rig_errors_exit_2_one_line(shared_data, tmp_path, capsys, monkeypatch, extra, match):
    monkeypatch.chdir(tmp_path)
    d = shared_data / "fast_support_reduction"
    code = main(["rig", str(d / "cantilever_S.obj"), str(d / "cantilever_S.tgf"), *extra])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and match in err[0] and "Traceback" not in err[0]
    assert not (tmp_path / "x.npz").exists()


def test_weights_recomputes_endpoint_weights(shared_data, tmp_path, capsys):
    d = shared_data / "fast_support_reduction"
    rig_path = tmp_path / "cant.npz"
    assert main(["rig", str(d / "cantilever_S.obj"), str(d / "cantilever_S.tgf"),
                 "-o", str(rig_path), "--endpoint", "projection"]) == 0
    before = stbs.load_rig(rig_path)
    data = rig_path.read_bytes()
    capsys.readouterr()
    # never over its own input, even when asked
    assert main(["weights", str(rig_path), "--endpoint", "idw", "-o", str(rig_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "refusing to write over a file this command reads" in err[0]
    assert rig_path.read_bytes() == data
    rig_path = tmp_path / "cant-idw.npz"
    assert main(["weights", str(tmp_path / "cant.npz"), "--endpoint", "idw",
                 "-o", str(rig_path)]) == 0
    after = check_rig(rig_path, 200, 4)
    np.testing.assert_array_equal(np.asarray(after.W), np.asarray(before.W))  # kept
    np.testing.assert_allclose(after.E, stbs.endpoint_weights(before.V, before.skeleton,
                                                              method="idw"))
    assert after.meta["endpoint"] == "idw"
    # recompute the bone weights too
    out2 = tmp_path / "cant2.npz"
    assert main(["weights", str(rig_path), "--bone", "bbw", "-o", str(out2)]) == 0
    check_rig(out2, 200, 4)


def test_tol_reaches_both_bbw_stages(shared_data, tmp_path, monkeypatch):
    """--tol (default 1e-6) is the KKT tolerance of the bone and the endpoint BBW solves."""
    import stbs.weights as weights

    seen = []

    def spy(fn, stage):
        def wrapped(*a, **kw):
            seen.append((stage, kw.get("tol")))
            return fn(*a, **kw)
        return wrapped

    monkeypatch.setattr(weights, "bone_weights", spy(weights.bone_weights, "bone"))
    monkeypatch.setattr(weights, "endpoint_weights", spy(weights.endpoint_weights, "end"))
    d = shared_data / "fast_support_reduction"
    args = [str(d / "cantilever_S.obj"), str(d / "cantilever_S.tgf")]
    assert main(["rig", *args, "-o", str(tmp_path / "a.npz")]) == 0
    assert seen == [("bone", 1e-6), ("end", 1e-6)]
    seen.clear()
    assert main(["rig", *args, "-o", str(tmp_path / "b.npz"), "--tol", "1e-10"]) == 0
    assert seen == [("bone", 1e-10), ("end", 1e-10)]
    seen.clear()
    assert main(["weights", str(tmp_path / "b.npz"), "-o", str(tmp_path / "c.npz"),
                 "--endpoint", "bbw-joints", "--tol", "1e-5"]) == 0
    assert seen == [("end", 1e-5)]
    seen.clear()
    # methods that take no tolerance are not given one
    assert main(["weights", str(tmp_path / "b.npz"), "-o", str(tmp_path / "d.npz"),
                 "--endpoint", "idw"]) == 0
    assert seen == [("end", None)]
    # the default tolerance gives the exact solution's weights to well within 1e-4
    a, b = stbs.load_rig(tmp_path / "a.npz"), stbs.load_rig(tmp_path / "b.npz")
    assert np.abs(np.asarray(a.W) - np.asarray(b.W)).max() < 1e-4
    assert np.abs(np.asarray(a.E) - np.asarray(b.E)).max() < 1e-4


def test_weights_tol_without_bbw_is_an_error(shared_data, tmp_path, capsys):
    d = shared_data / "fast_support_reduction"
    rig_path = tmp_path / "cant.npz"
    assert main(["rig", str(d / "cantilever_S.obj"), str(d / "cantilever_S.tgf"),
                 "-o", str(rig_path), "--endpoint", "projection"]) == 0
    capsys.readouterr()
    assert main(["weights", str(rig_path), "--endpoint", "idw", "--tol", "1e-6",
                 "-o", str(tmp_path / "x.npz")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["stbs weights: error: --tol applies to --bone bbw or --endpoint "
                   "bbw/bbw-joints; got --bone keep --endpoint idw"]
    assert not (tmp_path / "x.npz").exists()
    assert main(["weights", str(rig_path), "--clip-skeleton", "-o", str(tmp_path / "x.npz")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--clip-skeleton applies when stbs meshes the shape: a 3D " \
        "surface with --endpoint bbw or bbw-joints, or --bone bbw" in err[0]
    assert not (tmp_path / "x.npz").exists()


def test_progress_bars_on_a_terminal(capsys):
    """On a terminal the long stages show a bar that counts the bones; off it, nothing."""
    from stbs.cli.rig import _Stages
    from stbs.weights import bone_weights

    V = np.array([[x, y] for x in np.linspace(0, 4, 21) for y in np.linspace(0, 1, 6)])
    idx = np.arange(len(V)).reshape(21, 6)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), \
        idx[:-1, 1:].ravel()
    F = np.r_[np.c_[a, b, c], np.c_[a, c, d]]
    sk = stbs.Skeleton(np.array([[0.4, 0.4], [2.0, 0.4], [3.6, 0.4]]), [[0, 1], [1, 2]])
    st = _Stages()
    st.live = True
    W = st.run("bone weights (bbw)", bone_weights, V, sk, F=F, bar=True)
    err = capsys.readouterr().err
    assert W.shape == (len(V), 2)
    assert "bone weights (bbw) ..." in err and "[" + "#" * 30 + "] 2/2" in err
    st.live = False
    st.run("again", bone_weights, V, sk, F=F, bar=True)
    assert capsys.readouterr().err == ""
    assert [label for label, _ in st.times] == ["bone weights (bbw)", "again"]


def _bar_picture(tmp_path):
    """A 200x120 RGBA picture of a bar (alpha 255 on columns 21..179, rows 36..84) and
    a skeleton along it in pixel units, y up, whose last joint is 15 px past its end."""
    Image = pytest.importorskip("PIL.Image")
    H, W = 120, 200
    yy, xx = np.mgrid[:H, :W]
    img = np.zeros((H, W, 4), np.uint8)
    img[..., 0] = 200
    img[..., 3] = ((np.abs(xx - 100) < 80) & (np.abs(yy - 60) < 25)) * 255
    png = tmp_path / "bar.png"
    Image.fromarray(img).save(png)
    tgf = tmp_path / "bar.tgf"
    tgf.write_text("1 40 59 0\n2 100 59 0\n3 195 59 0\n#\n1 2\n2 3\n#\n")
    return png, tgf


def test_rig_from_a_picture(tmp_path, capsys):
    png, tgf = _bar_picture(tmp_path)
    out = tmp_path / "bar.npz"
    args = ["rig", str(png), str(tgf), "-o", str(out)]
    assert main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "joint 2 at (195, 59) outside the outline" in err[0]
    assert main([*args, "--clip-skeleton"]) == 0
    err = capsys.readouterr().err
    assert "read image" in err and "trace outline" in err
    rig = stbs.load_rig(out)
    n = rig.V.shape[0]
    assert rig.V.shape[1] == 2 and rig.T is None and 1000 < n < 10_000
    check_rig(out, n, 2)
    # The traced bar: x in [20.5, 179.5], y in [34.5, 83.5] (y = 119 - row, edges at
    # half pixels).
    np.testing.assert_allclose(rig.V.min(axis=0), [20.5, 34.5], atol=0.01)
    np.testing.assert_allclose(rig.V.max(axis=0), [179.5, 83.5], atol=0.01)
    # Bone 0's start holds it; e grows along bone 1 to the bar's end.
    a = np.argmin(np.linalg.norm(rig.V - [40, 59], axis=1))
    assert rig.W[a, 0] == pytest.approx(1.0)
    mid = np.abs(rig.V[:, 1] - 59) < 1e-9                # the vertices on the skeleton
    x, e = rig.V[mid, 0], rig.E[mid, 1]
    order = np.argsort(x)
    along = (x[order] > 100) & (x[order] < 170)     # bone 1 inside the bar: e = t there
    np.testing.assert_allclose(e[order][along], (x[order][along] - 100) / 95, atol=1e-6)
    assert e[np.argmax(x)] > 0.75          # ~t = 0.83 where the bar ends


def test_rig_from_a_poly_file_and_max_area(tmp_path):
    poly = tmp_path / "square.poly"
    poly.write_text("4 2 0 0\n1 0 0\n2 4 0\n3 4 2\n4 0 2\n4 0\n1 1 2\n2 2 3\n3 3 4\n4 4 1\n0\n")
    tgf = tmp_path / "sq.tgf"
    tgf.write_text("1 0.5 1 0\n2 2 1 0\n3 3.5 1 0\n#\n1 2\n2 3\n#\n")
    out = tmp_path / "sq.npz"
    assert main(["rig", str(poly), str(tgf), "-o", str(out), "--max-area", "0.01"]) == 0
    rig = stbs.load_rig(out)
    check_rig(out, rig.V.shape[0], 2)
    P = rig.V[rig.F]
    u, v = P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]
    area = 0.5 * np.abs(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0])
    assert area.max() <= 0.01 * (1 + 1e-9) and area.sum() == pytest.approx(8.0)


@pytest.mark.parametrize("case, extra, match", [
    ("obj", ["--threshold", "0.3"], "--threshold and --invert apply to an image MESH"),
    ("obj", ["--max-area", "1"], "--max-area applies to an outline MESH"),
    ("png", ["--bone", "heat"], "--bone heat needs a 3D surface; an outline"),
    ("png", ["--max-area", "0"], "--max-area: expected a positive number"),
    ("png", ["--threshold", "1"], "no shape found"),
    ("fake", [], "not a readable image"),
])
def test_rig_outline_errors(shared_data, tmp_path, capsys, case, extra, match):
    png, tgf = _bar_picture(tmp_path)
    if case == "obj":
        d = shared_data / "fast_support_reduction"
        mesh, sk = d / "cantilever_S.obj", d / "cantilever_S.tgf"
    elif case == "fake":
        mesh, sk = tmp_path / "fake.png", tgf
        mesh.write_text("not a picture")
    else:
        mesh, sk = png, tgf
    code = main(["rig", str(mesh), str(sk), "-o", str(tmp_path / "x.npz"), *extra])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and match in err[0], err
    assert not (tmp_path / "x.npz").exists()


def test_the_command_offers_what_the_pipeline_takes():
    # cli.rig repeats the choices so that building the parser imports nothing heavy
    import stbs.rig
    from stbs.cli import rig as cli_rig

    assert cli_rig.BONE == stbs.rig.BONE_METHODS
    assert cli_rig.ENDPOINT == stbs.rig.ENDPOINT_METHODS
    assert cli_rig.DEFAULT_TOL == stbs.rig.DEFAULT_TOL
    assert cli_rig.IMAGE_EXTENSIONS == stbs.rig.IMAGE_EXTENSIONS
    assert cli_rig.OUTLINE_EXTENSIONS == stbs.rig.OUTLINE_EXTENSIONS
    assert cli_rig.OUTLINE_TRIANGLES == stbs.rig.OUTLINE_TRIANGLES


def test_keep_volume_stores_the_tetrahedra_in_the_rig(tmp_path, capsys):
    from stbs.io import write_mesh, write_tgf
    from stbs.rig import endpoint_methods
    from surfaces import box

    V, F = box([0, 0, 0], [2, 1, 1], 3)
    write_mesh(tmp_path / "box.obj", V, F)
    write_tgf(tmp_path / "box.tgf", [[0.2, 0.5, 0.5], [1.0, 0.5, 0.5], [1.8, 0.5, 0.5]],
              [[0, 1], [1, 2]])
    base = ["rig", str(tmp_path / "box.obj"), str(tmp_path / "box.tgf"), "--bone", "heat",
            "--endpoint", "projection", "-o"]
    assert main([*base, str(tmp_path / "plain.npz")]) == 0
    assert "kept its volume" not in capsys.readouterr().out
    assert main([*base, str(tmp_path / "kept.npz"), "--keep-volume", "--tets",
                 "conforming"]) == 0
    out = capsys.readouterr().out
    plain, kept = stbs.load_rig(tmp_path / "plain.npz"), stbs.load_rig(tmp_path / "kept.npz")
    assert plain.volume is None and "bbw" not in endpoint_methods(plain)
    assert kept.volume is not None and "bbw" in endpoint_methods(kept)
    assert f"kept its volume mesh of {len(kept.volume.V)} vertices" in out
    np.testing.assert_array_equal(kept.volume.V[kept.volume.index], V)
    np.testing.assert_array_equal(np.asarray(kept.W), np.asarray(plain.W))


def test_the_pipeline_is_a_library_function_with_stages(tmp_path):
    """stbs.rig.rig_from_files is what the command runs; its progress names each stage."""
    from stbs.rig import rig_from_files, rig_from_picture

    png, tgf = _bar_picture(tmp_path)
    stages = []
    with pytest.warns(UserWarning, match="meshed only inside it"):
        rig = rig_from_files(png, tgf, clip_skeleton=True,
                             progress=lambda s, d, t: stages.append(s) if t == 0 else None)
    assert stages[:3] == ["read image", "read skeleton", "trace outline"]
    assert "triangulate (bones inside)" in stages and stages[-1] == "endpoint weights (bbw)"
    assert main(["rig", str(png), str(tgf), "-o", str(tmp_path / "b.npz"),
                 "--clip-skeleton"]) == 0
    cli = stbs.load_rig(tmp_path / "b.npz")
    np.testing.assert_array_equal(cli.V, rig.V)
    np.testing.assert_allclose(np.asarray(cli.E), np.asarray(rig.E), atol=1e-12)
    np.testing.assert_array_equal(cli.texture, rig.texture)
    # a picture as an array: no shape at this threshold is an error naming it
    from stbs.rig import read_image

    with pytest.raises(ValueError, match="image: no shape found .nothing above threshold 1"):
        rig_from_picture(read_image(png), rig.skeleton, threshold=1.0)
