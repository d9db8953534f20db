"""Pictures brought to life (paper §4, Fig. 12): a rig made from an image keeps the
image and its texture coordinates, in the rig file, in ``stbs deform -o .png`` and in
the viewer's payload."""

from __future__ import annotations

import importlib.util
import io

import numpy as np
import pytest

import stbs
from stbs.cli import main
from stbs.io import load_rig, save_rig
from stbs.viewer import RigPayload

H, W = 120, 200


def _gradient_picture(tmp_path):
    """A bar whose red channel is the pixel's column and green its row: a vertex at
    pixel coordinates (x, y) (y up) should show red x and green H - 1 - y."""
    from PIL import Image

    yy, xx = np.mgrid[:H, :W]
    img = np.zeros((H, W, 4), np.uint8)
    img[..., 0] = xx
    img[..., 1] = yy
    img[..., 2] = 90
    img[..., 3] = ((np.abs(xx - 100) < 80) & (np.abs(yy - 60) < 25)) * 255
    png = tmp_path / "bar.png"
    Image.fromarray(img).save(png)
    tgf = tmp_path / "bar.tgf"
    tgf.write_text("1 40 59 0\n2 100 59 0\n3 170 59 0\n#\n1 2\n2 3\n#\n")
    return png, tgf, img


def _bilinear(tex, uv):
    """Sample an (H, W, c) image at OpenGL texture coordinates (v up), bilinearly."""
    h, w = tex.shape[:2]
    col = np.clip(uv[:, 0] * w - 0.5, 0, w - 1)
    row = np.clip((1 - uv[:, 1]) * h - 0.5, 0, h - 1)
    c0, r0 = np.floor(col).astype(int), np.floor(row).astype(int)
    c1, r1 = np.minimum(c0 + 1, w - 1), np.minimum(r0 + 1, h - 1)
    fc, fr = (col - c0)[:, None], (row - r0)[:, None]
    t = tex.astype(float)
    top = t[r0, c0] * (1 - fc) + t[r0, c1] * fc
    bot = t[r1, c0] * (1 - fc) + t[r1, c1] * fc
    return top * (1 - fr) + bot * fr


@pytest.fixture(scope="module")
def picture_rig(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("picture")
    png, tgf, img = _gradient_picture(tmp)
    out = tmp / "bar.npz"
    assert main(["rig", str(png), str(tgf), "-o", str(out)]) == 0
    return out, img


def test_a_rig_from_an_image_keeps_the_picture_and_maps_each_vertex_to_its_pixel(picture_rig):
    path, img = picture_rig
    rig = load_rig(path)
    assert rig.texture is not None and rig.texture.dtype == np.uint8
    np.testing.assert_array_equal(rig.texture, img)          # the image as read, RGBA
    assert rig.UV.shape == (len(rig.V), 2)
    rgb = _bilinear(rig.texture, rig.UV)
    x, y = rig.V[:, 0], rig.V[:, 1]
    inside = (x > 21) & (x < 179) & (y > 36) & (y < 83)     # away from the clamped edge
    assert inside.sum() > 500
    np.testing.assert_allclose(rgb[inside, 0], x[inside], atol=0.02)
    np.testing.assert_allclose(rgb[inside, 1], H - 1 - y[inside], atol=0.02)


def test_the_picture_survives_a_round_trip_and_replace(tmp_path, picture_rig):
    rig = load_rig(picture_rig[0])
    p = tmp_path / "again.npz"
    save_rig(p, rig.replace(E=None))
    back = load_rig(p)
    np.testing.assert_array_equal(back.texture, rig.texture)
    np.testing.assert_array_equal(back.UV, rig.UV)
    assert back.E is None
    assert "texture=(120, 200, 4)" in repr(back)


def _tiny(**kw):
    sk = stbs.Skeleton([[0, 0], [1, 0]], [[0, 1]])
    return stbs.Rig(V=[[0, 0.1], [1, 0.1], [1, -0.1]], F=[[0, 2, 1]], skeleton=sk,
                    W=np.ones((3, 1)), **kw)


@pytest.mark.parametrize("kw, match", [
    ({"texture": np.zeros((4, 4, 4), np.uint8)}, "texture needs UV"),
    ({"UV": np.zeros((3, 2))}, "UV needs texture"),
    ({"texture": np.zeros((4, 4, 4)), "UV": np.zeros((3, 2))}, "uint8 image, got float64"),
    ({"texture": np.zeros((4, 4), np.uint8), "UV": np.zeros((3, 2))}, r"shape \(4, 4\)"),
    ({"texture": np.zeros((4, 4, 3), np.uint8), "UV": np.zeros((2, 2))}, "UV"),
    ({"texture": np.zeros((4, 4, 3), np.uint8), "UV": np.full((3, 2), 1.5)}, r"\[0, 1\]"),
    ({"texture": np.zeros((4, 4, 3), np.uint8), "UV": np.full((3, 2), np.nan)}, "finite"),
])
def test_bad_pictures_are_refused_by_name(kw, match):
    with pytest.raises(ValueError, match=match):
        _tiny(**kw)


def test_the_viewer_serves_a_rigs_picture_as_rgba():
    rgb = np.arange(4 * 5 * 3, dtype=np.uint8).reshape(4, 5, 3)
    uv = np.array([[0, 0], [1, 0], [1, 1]], float)
    payload = RigPayload(_tiny(texture=rgb, UV=uv))
    tex = payload.array("texture")
    assert tex.shape == (4, 5, 4) and tex.dtype == np.uint8
    np.testing.assert_array_equal(tex[..., :3], rgb)
    assert (tex[..., 3] == 255).all()
    np.testing.assert_array_equal(payload.array("UV"), uv.astype(np.float32))
    assert {"texture", "UV"} <= set(payload.info()["arrays"])
    assert payload.extras == {}          # the rig's own picture, not a caller's extras
    assert "texture" not in RigPayload(_tiny()).info()["arrays"]


def _png(path):
    from PIL import Image

    with Image.open(path) as im:
        return np.asarray(im.convert("RGB"), dtype=int)


def test_deform_draws_the_posed_picture(picture_rig, tmp_path, capsys):
    rig_path, img = picture_rig
    pose = tmp_path / "bend.json"
    pose.write_text('{"rotate": {"1": {"angle": 70}}}')
    out = tmp_path / "bent.png"
    code = main(["deform", str(rig_path), "--pose", str(pose), "-o", str(out),
                 "--size", "400"])
    assert code == 0, capsys.readouterr().err
    a = _png(out)
    assert a.shape[1] == 400 or a.shape[0] == 400
    # The picture's own colours are drawn: blue 90 with red and green from the
    # gradient, over a white background.
    painted = (np.abs(a[..., 2] - 90) <= 3) & (a[..., 0] < 200)
    assert painted.mean() > 0.1
    # Bent by 70 degrees, the drawn shape is far from the straight bar's aspect (5:3).
    ys, xs = np.nonzero(painted)
    assert np.ptp(ys) / np.ptp(xs) > 0.6
    # Straight, the same command draws the straight bar.
    pose.write_text("{}")
    assert main(["deform", str(rig_path), "--pose", str(pose), "-o", str(out)]) == 0
    a = _png(out)
    painted = (np.abs(a[..., 2] - 90) <= 3) & (a[..., 0] < 200)
    ys, xs = np.nonzero(painted)
    assert np.ptp(ys) / np.ptp(xs) < 0.45       # 49 / 159 pixels of bar, plus the skeleton


def test_deform_png_of_a_plain_mesh_and_its_errors(tmp_path, capsys):
    rig = _tiny()
    p = tmp_path / "tiny.npz"
    save_rig(p, rig)
    pose = tmp_path / "rest.json"
    pose.write_text("{}")
    out = tmp_path / "tiny.png"
    assert main(["deform", str(p), "--pose", str(pose), "-o", str(out), "--size", "200"]) == 0
    assert out.is_file()
    capsys.readouterr()
    assert main(["deform", str(p), "--pose", str(pose), "-o", str(tmp_path / "x.png"),
                 "--size", "10"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["stbs deform: error: --size: expected 64 to 8192 pixels, got 10"]
    assert not (tmp_path / "x.png").exists()


def test_deform_png_without_matplotlib_is_one_line(tmp_path, capsys, monkeypatch):
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a, **kw: None
                        if name.split(".")[0] == "matplotlib" else real(name, *a, **kw))
    p = tmp_path / "tiny.npz"
    save_rig(p, _tiny())
    (tmp_path / "rest.json").write_text("{}")
    code = main(["deform", str(p), "--pose", str(tmp_path / "rest.json"), "-o",
                 str(tmp_path / "t.png")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "matplotlib" in err[0]
    assert not (tmp_path / "t.png").exists()
    # the mesh formats need nothing optional
    assert main(["deform", str(p), "--pose", str(tmp_path / "rest.json"), "-o",
                 str(tmp_path / "t.obj")]) == 0


def test_pillow_reads_what_deform_wrote(tmp_path, picture_rig):
    # a PNG, not just a file: its signature and a decodable image
    out = tmp_path / "rest.png"
    (tmp_path / "rest.json").write_text("{}")
    assert main(["deform", str(picture_rig[0]), "--pose", str(tmp_path / "rest.json"),
                 "-o", str(out)]) == 0
    data = out.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    from PIL import Image

    Image.open(io.BytesIO(data)).verify()
