"""stbs.demo.render: headless pictures (PNG panels, GIF animations) with matplotlib's Agg."""

from __future__ import annotations

import subprocess
import sys
import types

import numpy as np
import pytest

pytest.importorskip("matplotlib")
from PIL import Image  # noqa: E402  (Pillow comes with matplotlib)

from rigs import icosphere  # noqa: E402
from stbs.demo import render  # noqa: E402
from stbs.demo.render import (  # noqa: E402
    MASK_COLOR,
    METHOD_COLORS,
    Camera,
    Panel,
    PlotPanel,
    draw_panels,
    render_animation,
    render_panels,
)
from work_count import Lines  # noqa: E402

SIZE = (160, 160)
JOINT_RGB = np.array([0xE4, 0x57, 0x2E])


# ---------------------------------------------------------------- test meshes


def grid2d(nx: int, ny: int) -> tuple[np.ndarray, np.ndarray]:
    """The unit square as an (nx x ny)-cell triangle grid, counter-clockwise."""
    x, y = np.meshgrid(np.linspace(0, 1, nx + 1), np.linspace(0, 1, ny + 1))
    V = np.stack([x.ravel(), y.ravel()], axis=1)
    k = np.arange((nx + 1) * (ny + 1)).reshape(ny + 1, nx + 1)
    a, b, c, d = (k[:-1, :-1].ravel(), k[:-1, 1:].ravel(), k[1:, 1:].ravel(),
                  k[1:, :-1].ravel())
    return V, np.vstack([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])


SPHERE = icosphere(2)
C2 = np.array([[-0.6, 0.0, 0.0], [0.0, 0.0, 0.0], [0.6, 0.3, 0.0]])
BE2 = np.array([[0, 1], [1, 2]])


def posed(V: np.ndarray, t: float) -> np.ndarray:
    """Stretch along x and bend: a second pose that changes the silhouette."""
    U = V * np.array([1 + t, 1, 1])
    U[:, 1] += 0.4 * t * U[:, 0] ** 2
    return U


def rgb(a: np.ndarray) -> np.ndarray:
    return a[..., :3].astype(int)


def n_colors(a: np.ndarray) -> int:
    return len(np.unique(rgb(a).reshape(-1, 3), axis=0))


def not_white(a: np.ndarray) -> np.ndarray:
    return (rgb(a) < 250).any(axis=-1)


def near(a: np.ndarray, color, tol: int = 12) -> np.ndarray:
    return (np.abs(rgb(a) - np.asarray(color)) <= tol).all(axis=-1)


# ---------------------------------------------------------------- PNG panels
def test_two_poses_give_valid_distinct_nonblank_pngs(tmp_path):
    V, F = SPHERE
    paths = []
    for k, t in enumerate((0.0, 0.8)):
        p = render_panels(tmp_path / f"pose{k}.png",
                          [Panel(posed(V, t), F, f"pose {k}", subtitle=f"t = {t}")],
                          panel_size=(200, 180), title="a sphere")
        paths.append(p)
        with Image.open(p) as im:
            assert im.format == "PNG"
            assert im.size == (200, 180 + 40)    # the title adds 40 pixels
            im.verify()
    a, b = (np.asarray(Image.open(p).convert("RGB")) for p in paths)
    for img in (a, b):
        assert n_colors(img) > 100                 # shaded, not a flat silhouette
        assert 0.1 < not_white(img).mean() < 0.9
    assert np.abs(a.astype(int) - b.astype(int)).mean() > 2


def test_shading_looks_like_a_lit_solid():
    V, F = SPHERE
    img = draw_panels([Panel(V, F)], panel_size=(200, 200))
    lum = rgb(img) @ np.array([0.299, 0.587, 0.114])
    ii, jj = np.nonzero(not_white(img))
    ci, cj = ii.mean(), jj.mean()
    upper_left = lum[ii[(ii < ci) & (jj < cj)], jj[(ii < ci) & (jj < cj)]].mean()
    lower_right = lum[ii[(ii > ci) & (jj > cj)], jj[(ii > ci) & (jj > cj)]].mean()
    # The key light comes from the upper left: that side is brighter, with a gradient.
    assert upper_left > lower_right + 25
    assert lum[ii, jj].std() > 15
    # An orthographic sphere projects to a disc: check the silhouette is round.
    r = np.hypot(ii - ci, jj - cj)
    edge = r[r > np.percentile(r, 97)]
    assert edge.std() < 0.05 * edge.mean()


def test_flat_shading_shows_facets():
    V, F = icosphere(1)
    smooth = draw_panels([Panel(V, F)], panel_size=SIZE)
    flat = draw_panels([Panel(V, F, shading="flat")], panel_size=SIZE)
    assert not_white(flat).sum() == pytest.approx(not_white(smooth).sum(), rel=0.03)
    # One colour per facet: most pixels repeat their neighbour's colour exactly.
    def repeats(img):
        inside = not_white(img)[:, 1:] & not_white(img)[:, :-1]
        return (rgb(img)[:, 1:] == rgb(img)[:, :-1]).all(axis=-1)[inside].mean()

    assert repeats(flat) > 0.7 > 0.5 > repeats(smooth)
    with pytest.raises(ValueError, match=r"shading must be one of 'smooth', 'flat'"):
        Panel(V, F, shading="phong")


def test_flat_and_solid_panels_each_fill_their_window():
    V, F = SPHERE
    G, GF = grid2d(2, 2)
    img = draw_panels([Panel(3 * V, F), Panel(G, GF)], panel_size=SIZE)
    for half in np.split(not_white(img), 2, axis=1):
        jj = np.nonzero(half)[1]
        assert jj.max() - jj.min() > 0.75 * SIZE[0]


def test_scalars_follow_the_colormap_and_isolines_change_pixels():
    V, F = SPHERE
    plain = draw_panels([Panel(V, F)], panel_size=SIZE)
    low = draw_panels([Panel(V, F, scalars=np.zeros(len(V)))], panel_size=SIZE)
    high = draw_panels([Panel(V, F, scalars=np.ones(len(V)))], panel_size=SIZE)
    inside = not_white(plain)
    lo, hi = rgb(low)[inside].mean(axis=0), rgb(high)[inside].mean(axis=0)
    assert lo[2] > lo[1] + 20       # viridis(0) is purple: blue over green
    assert hi[0] > hi[2] + 60       # viridis(1) is yellow: red over blue
    s = (V[:, 0] + 1) / 2
    smooth = draw_panels([Panel(V, F, scalars=s)], panel_size=SIZE)
    lines = draw_panels([Panel(V, F, scalars=s, isolines=4)], panel_size=SIZE)
    heat = draw_panels([Panel(V, F, scalars=s, cmap="inferno")], panel_size=SIZE)
    assert n_colors(smooth) > 100
    assert (np.abs(rgb(smooth) - rgb(lines)).sum(axis=-1) > 60).sum() > 50
    assert (np.abs(rgb(smooth) - rgb(heat)).sum(axis=-1) > 60).mean() > 0.1


def test_skeleton_is_drawn_on_top_even_inside_the_mesh():
    V, F = SPHERE
    bare = draw_panels([Panel(V, F)], panel_size=SIZE)
    rig = draw_panels([Panel(V, F, C=C2, BE=BE2)], panel_size=SIZE)
    assert not near(bare, JOINT_RGB).any()
    assert near(rig, JOINT_RGB).sum() > 3 * 20     # three joint dots, inside the sphere
    changed = (np.abs(rgb(bare) - rgb(rig)).sum(axis=-1) > 60).sum()
    assert changed > 300                           # the bones' wedges too
    joints_only = draw_panels([Panel(V, F, C=C2)], panel_size=SIZE)
    assert near(joints_only, JOINT_RGB).sum() > 3 * 20


def test_colors_per_vertex_are_drawn():
    V, F = SPHERE
    red = np.tile([1.0, 0.0, 0.0], (len(V), 1))
    img = draw_panels([Panel(V, F, colors=red)], panel_size=SIZE)
    inside = not_white(img)
    mean = rgb(img)[inside].mean(axis=0)
    assert mean[0] > 2 * mean[1] and mean[0] > 2 * mean[2]


def quadrant_texture() -> np.ndarray:
    """Top left red, top right green, bottom left blue, bottom right yellow."""
    tex = np.zeros((32, 32, 3), np.uint8)
    tex[:16, :16] = (255, 0, 0)
    tex[:16, 16:] = (0, 255, 0)
    tex[16:, :16] = (0, 0, 255)
    tex[16:, 16:] = (255, 255, 0)
    return tex


def sample_quadrants(img: np.ndarray) -> dict[str, np.ndarray]:
    ii, jj = np.nonzero(not_white(img))
    i0, i1, j0, j1 = ii.min(), ii.max(), jj.min(), jj.max()
    at = {"tl": (0.25, 0.25), "tr": (0.25, 0.75), "bl": (0.75, 0.25), "br": (0.75, 0.75)}
    return {k: rgb(img)[int(i0 + a * (i1 - i0)), int(j0 + b * (j1 - j0))]
            for k, (a, b) in at.items()}


def test_textured_square_shows_its_texture_and_follows_the_deformation():
    V, F = grid2d(6, 6)
    tex = quadrant_texture()
    q = sample_quadrants(draw_panels([Panel(V, F, texture=tex, uv=V)], panel_size=SIZE))
    np.testing.assert_allclose(q["tl"], [255, 0, 0], atol=3)
    np.testing.assert_allclose(q["tr"], [0, 255, 0], atol=3)
    np.testing.assert_allclose(q["bl"], [0, 0, 255], atol=3)
    np.testing.assert_allclose(q["br"], [255, 255, 0], atol=3)
    # Mirror the shape left-right: the picture mirrors with it.
    U = V * [-1, 1]
    q = sample_quadrants(draw_panels([Panel(U, F, texture=tex, uv=V)], panel_size=SIZE))
    np.testing.assert_allclose(q["tl"], [0, 255, 0], atol=3)
    np.testing.assert_allclose(q["br"], [0, 0, 255], atol=3)
    # Float textures in [0, 1] with an alpha channel are accepted too.
    rgba = np.concatenate([tex / 255.0, np.ones((32, 32, 1))], axis=2)
    q2 = sample_quadrants(draw_panels([Panel(V, F, texture=rgba, uv=V)], panel_size=SIZE))
    np.testing.assert_allclose(q2["tl"], [255, 0, 0], atol=3)


def test_flat_2d_meshes_plain_and_with_scalars():
    V, F = grid2d(8, 4)
    plain = draw_panels([Panel(V, F, C=[[0.1, 0.5], [0.9, 0.5]], BE=[[0, 1]])],
                        panel_size=SIZE)
    assert near(plain, JOINT_RGB).any()
    three = draw_panels([Panel(np.hstack([V, np.zeros((len(V), 1))]), F,
                               C=[[0.1, 0.5, 0], [0.9, 0.5, 0]], BE=[[0, 1]])],
                        panel_size=SIZE)
    np.testing.assert_array_equal(plain, three)     # z == 0 and no camera: drawn flat
    s = V[:, 0]
    img = draw_panels([Panel(V, F, scalars=s, isolines=[0.5])], panel_size=SIZE)
    ii, jj = np.nonzero(not_white(img))
    row = rgb(img)[int(ii.mean())]
    left, right = row[jj.min() + 3], row[jj.max() - 3]
    assert left[2] > left[1] and right[0] > right[2]   # purple to yellow along x
    assert Panel(V, F).flat
    assert not Panel(np.hstack([V, np.zeros((len(V), 1))]), F, camera=Camera()).flat


def test_mask_greys_out_scalars_flat_and_solid():
    V, F = grid2d(8, 4)
    s = V[:, 0]
    keep = V[:, 0] > 0.5
    p = Panel(V, F, scalars=s, cmap="Reds", mask=keep)
    c = p.vertex_colors()
    assert np.all(c[~keep] == MASK_COLOR) and not np.any(np.all(c[keep] == MASK_COLOR, axis=1))
    grey = np.round(255 * np.array(MASK_COLOR))
    img = draw_panels([p], panel_size=SIZE)
    ii, jj = np.nonzero(not_white(img))
    row = rgb(img)[int(ii.mean())]
    left, right = row[jj.min() + 3], row[jj.max() - 3]
    assert np.abs(left - grey).max() <= 3 and right[0] > right[2] + 40   # grey | red
    full = draw_panels([Panel(V, F, scalars=s, cmap="Reds")], panel_size=SIZE)
    assert rgb(full)[int(ii.mean()), jj.min() + 3][0] > 200   # without a mask: white-red
    # Solid: the masked side of a sphere is grey under the lighting (no hue).
    Vs, Fs = SPHERE
    img = draw_panels([Panel(Vs, Fs, scalars=Vs[:, 0], cmap="Reds", mask=Vs[:, 0] > 0)],
                      panel_size=SIZE, camera=Camera(azimuth=-90.0, elevation=0.0))
    ii, jj = np.nonzero(not_white(img))
    left = rgb(img)[int(ii.mean()), jj.min() + 12]
    assert np.ptp(left) <= 3
    with pytest.raises(ValueError, match="mask needs scalars"):
        Panel(V, F, mask=keep)
    with pytest.raises(ValueError, match=r"mask must be a \(45,\) bool array"):
        Panel(V, F, scalars=s, mask=keep.astype(int))
    with pytest.raises(ValueError, match="textured panel"):
        Panel(V, F, texture=np.zeros((4, 4, 3), np.uint8), uv=V).vertex_colors()


def test_open_mesh_is_drawn_from_behind():
    V, F = grid2d(4, 4)
    V3 = np.hstack([V, np.zeros((len(V), 1))])
    for cam in (Camera(azimuth=-90, elevation=0), Camera(azimuth=90, elevation=0)):
        img = draw_panels([Panel(V3, F, camera=cam)], panel_size=SIZE)
        assert not_white(img).mean() > 0.3
    V, F = SPHERE
    assert not_white(draw_panels([Panel(V, F, cull=False)], panel_size=SIZE)).mean() > 0.2


def test_shared_view_compares_at_one_scale():
    V, F = SPHERE
    panels = [Panel(V, F), Panel(0.5 * V, F)]

    def widths(img):
        out = []
        for half in np.split(not_white(img), 2, axis=1):
            jj = np.nonzero(half)[1]
            out.append(jj.max() - jj.min())
        return out

    big, small = widths(draw_panels(panels, panel_size=SIZE))
    assert small == pytest.approx(big / 2, abs=3)
    big, small = widths(draw_panels(panels, panel_size=SIZE, shared_view=False))
    assert small == pytest.approx(big, abs=3)


def test_layout_and_plot_panel(tmp_path):
    V, F = SPHERE
    x = np.linspace(0, 1, 30)
    plot = PlotPanel("twist along the box", x, {"lbs": 315.0 * (x > 0.5),
                                                "stbs-dqs": 315 * x,
                                                "expected": 315 * x},
                     xlabel="x / length", ylabel="twist (degrees)",
                     styles={"expected": "k--"})
    p = render_panels(tmp_path / "fig.png", [Panel(V, F, "a"), Panel(V, F, "b"), plot],
                      ncols=2, panel_size=(180, 150))
    img = np.asarray(Image.open(p).convert("RGB"))
    assert img.shape == (300, 360, 3)
    plot_cell = img[150:, :180]
    for m in ("lbs", "stbs-dqs"):
        color = np.array([int(METHOD_COLORS[m][k:k + 2], 16) for k in (1, 3, 5)])
        assert near(plot_cell, color, tol=20).sum() > 30, m
    assert not not_white(img[150:, 180:]).any()        # the empty fourth cell


def test_camera_basis_and_projection():
    for cam in (Camera(), Camera(azimuth=30, elevation=-45, up="z"),
                Camera(azimuth=0, elevation=90, up="x")):
        B = cam.basis()
        np.testing.assert_allclose(B @ B.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(B) == pytest.approx(1.0)
    front = Camera(azimuth=-90, elevation=0)
    xy, depth = front.project(np.eye(3), center=np.zeros(3))
    np.testing.assert_allclose(xy, [[1, 0], [0, 1], [0, 0]], atol=1e-12)
    np.testing.assert_allclose(depth, [0, 0, -1], atol=1e-12)   # +z is nearer the eye
    persp = Camera(azimuth=-90, elevation=0, orthographic=False, distance=3)
    xy, _ = persp.project([[1, 0, 1], [1, 0, -1]], center=np.zeros(3), radius=1.0)
    assert xy[0, 0] > 1 > xy[1, 0] > 0                         # nearer looks bigger
    V, F = SPHERE
    img = draw_panels([Panel(V, F)], panel_size=SIZE, camera=persp)
    assert n_colors(img) > 50


# ---------------------------------------------------------------- animation
def test_gif_has_every_frame_at_a_fixed_size_and_view(tmp_path):
    V, F = icosphere(1)
    frames = [[Panel(V + [0.3 * k, 0, 0], F, "moving", C=C2, BE=BE2), Panel(V, F, "still")]
              for k in range(6)]
    p = render_animation(tmp_path / "a.gif", frames, fps=10, panel_size=SIZE,
                         title=[f"frame {k}" for k in range(6)])
    with Image.open(p) as im:
        assert im.format == "GIF" and im.n_frames == 6 and im.size == (320, 200)
        assert im.info.get("loop") == 0 and im.info.get("duration") == 100
        imgs = []
        for k in range(im.n_frames):
            im.seek(k)
            imgs.append(np.asarray(im.convert("RGB")))
    left = [np.nonzero(not_white(a[40:, :160]))[1] for a in imgs]
    centers = [j.mean() for j in left]
    assert all(b > a + 2 for a, b in zip(centers, centers[1:], strict=False))
    # The same mesh in every frame stays put: one view fitted over all frames.
    still = [a[60:, 160:] for a in imgs]
    for a in still[1:]:
        assert np.abs(a.astype(int) - still[0].astype(int)).max() <= 8
    assert (imgs[0][3, 3] == 255).all()                 # a pure white background


def test_gif_is_small(tmp_path):
    V, F = icosphere(3)
    frames = [[Panel(posed(V, t), F, C=C2, BE=BE2)] for t in np.linspace(0, 1, 24)]
    p = render_animation(tmp_path / "s.gif", frames, panel_size=(360, 360))
    assert p.stat().st_size < 400_000


def test_mp4_needs_imageio_ffmpeg(tmp_path, monkeypatch):
    V, F = icosphere(1)
    frames = [[Panel(V, F)], [Panel(1.1 * V, F)]]
    monkeypatch.setitem(sys.modules, "imageio_ffmpeg", None)
    with pytest.raises(ImportError, match="imageio-ffmpeg"):
        render_animation(tmp_path / "a.mp4", frames, panel_size=(101, 101))
    sent = []

    def write_frames(path, size, **kw):
        with open(path, "wb") as f:
            f.write(b"mp4")
        sent.append(size)
        while True:
            fr = yield
            if fr is not None:
                sent.append(fr.shape)

    monkeypatch.setitem(sys.modules, "imageio_ffmpeg",
                        types.SimpleNamespace(write_frames=write_frames))
    p = render_animation(tmp_path / "a.mp4", frames, panel_size=(101, 101))
    assert p.read_bytes() == b"mp4"
    assert sent == [(102, 102), (102, 102, 3), (102, 102, 3)]    # padded to even sizes
    assert sorted(x.name for x in tmp_path.iterdir()) == ["a.mp4"]


# ---------------------------------------------------------------- atomic writes
def test_writes_are_atomic(tmp_path, monkeypatch):
    V, F = SPHERE
    target = tmp_path / "x.png"
    target.write_bytes(b"old")
    render_panels(target, [Panel(V, F)], panel_size=SIZE)
    assert target.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert [x.name for x in tmp_path.iterdir()] == ["x.png"]
    before = target.read_bytes()

    class Broken:
        @staticmethod
        def fromarray(*args, **kwargs):
            class Img:
                def save(self, f, **kw):
                    f.write(b"half")
                    raise OSError("disk full")
            return Img()

    monkeypatch.setattr(render, "_pil", lambda: Broken)
    with pytest.raises(OSError, match="disk full"):
        render_panels(target, [Panel(V, F)], panel_size=SIZE)
    assert target.read_bytes() == before
    assert [x.name for x in tmp_path.iterdir()] == ["x.png"]


# ---------------------------------------------------------------- bad input
@pytest.mark.parametrize("kwargs, match", [
    ({"scalars": np.zeros(41)}, r"scalars must have shape \(42,\).*got \(41,\)"),
    ({"F": [[0, 1, 42]]}, r"F must index the 42 rows of V \(0 <= F < 42\), got \[0, 1, 42\]"),
    ({"F": [[0, 1]]}, r"F must have shape \(\?, 3\), got \(1, 2\)"),
    ({"texture": np.zeros((4, 4)), "uv": np.zeros((42, 2))},
     r"texture must be an \(H, W, 3\) or \(H, W, 4\) image, got shape \(4, 4\)"),
    ({"texture": np.zeros((4, 4, 3), np.uint8)}, r"uv must be given with texture"),
    ({"texture": np.zeros((4, 4, 3), np.uint8), "uv": np.zeros((41, 2))},
     r"uv must have shape \(42, 2\).*got \(41, 2\)"),
    ({"colors": np.zeros((42, 2))}, r"colors must have shape \(42, 3\) or \(42, 4\).*"
                                    r"got \(42, 2\)"),
    ({"colors": np.full((42, 3), 2.0)}, r"colors must lie in \[0, 1\]"),
    ({"scalars": np.zeros(42), "colors": np.zeros((42, 3))}, r"at most one of"),
    ({"C": np.zeros((3, 2))}, r"C must have 3 columns like V, got shape \(3, 2\)"),
    ({"C": np.zeros((3, 3)), "BE": [[0, 3]]}, r"BE must index the 3 rows of C.*got 3"),
    ({"BE": [[0, 1]]}, r"BE .* needs C"),
    ({"isolines": 3}, r"isolines need scalars"),
    ({"scalars": np.zeros(42), "vmin": 1.0, "vmax": 0.0}, r"vmin must be less than vmax"),
    ({"V": np.full((42, 3), np.nan)}, r"V must be finite"),
    ({"camera": "front"}, r"camera must be a Camera, got str"),
])
def test_bad_panel_input_names_the_argument(kwargs, match):
    V, F = icosphere(1)
    assert len(V) == 42
    args = {"V": V, "F": F, **kwargs}
    with pytest.raises(ValueError, match=match):
        Panel(**args)


def test_texture_needs_a_flat_mesh():
    V, F = SPHERE
    with pytest.raises(ValueError, match=r"texture is drawn only on 2D meshes"):
        Panel(V, F, texture=np.zeros((2, 2, 3), np.uint8), uv=np.zeros((len(V), 2)))


def test_bad_render_input(tmp_path):
    V, F = icosphere(1)
    with pytest.raises(ValueError, match=r"cmap must be a matplotlib colour map name.*'nope'"):
        draw_panels([Panel(V, F, scalars=np.zeros(len(V)), cmap="nope")])
    with pytest.raises(ValueError, match=r"color must be a matplotlib colour.*'notacolour'"):
        draw_panels([Panel(V, F, color="notacolour")])
    with pytest.raises(ValueError, match=r"panels must be a non-empty list"):
        draw_panels([])
    with pytest.raises(ValueError, match=r"panels\[1\] must be a Panel or PlotPanel, got int"):
        draw_panels([Panel(V, F), 3])
    with pytest.raises(ValueError, match=r"panel_size must be two whole numbers"):
        draw_panels([Panel(V, F)], panel_size=(10, 10))
    with pytest.raises(ValueError, match=r"ncols must be a positive integer"):
        draw_panels([Panel(V, F)], ncols=0)
    with pytest.raises(ValueError, match=r"path must end with \.png, got"):
        render_panels(tmp_path / "x.jpg", [Panel(V, F)])
    with pytest.raises(ValueError, match=r"frames\[1\] must have the layout of frames\[0\]"):
        render_animation(tmp_path / "a.gif", [[Panel(V, F)], [Panel(V, F), Panel(V, F)]])
    with pytest.raises(ValueError, match=r"fps must be a number in \(0, 50\], got 0"):
        render_animation(tmp_path / "a.gif", [[Panel(V, F)]], fps=0)
    with pytest.raises(ValueError, match=r"ys\['lbs'\] must have shape \(3,\) like x, got \(2,\)"):
        PlotPanel("t", [0, 1, 2], {"lbs": [0, 1]})
    with pytest.raises(ValueError, match=r"Camera.elevation must lie in \[-90, 90\]"):
        Camera(elevation=100)
    with pytest.raises(ValueError, match=r"up must be one of 'x', 'y', 'z', got 'w'"):
        Camera(up="w")
    assert list(tmp_path.iterdir()) == []


# ---------------------------------------------------------------- import and speed
def test_import_does_not_load_matplotlib():
    code = ("import sys, stbs.demo.render, stbs.demo.gallery; "
            "print('matplotlib' in sys.modules, 'PIL' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.split()
    assert out == ["False", "False"]


def test_missing_matplotlib_says_which_extra(monkeypatch):
    V, F = icosphere(1)
    monkeypatch.setitem(sys.modules, "matplotlib.figure", None)
    with pytest.raises(ImportError, match=r"pip install 'stbs-skinning\[demo\]'"):
        draw_panels([Panel(V, F)])


def test_a_10k_face_panel_renders_with_the_work_of_a_small_one(monkeypatch):
    # no loop and no matplotlib artist per face: two panels of 5120 faces each run the
    # same lines of stbs code and make the same artists as two of 320
    from matplotlib.artist import Artist

    made = []
    init = Artist.__init__
    monkeypatch.setattr(Artist, "__init__",
                        lambda self, *a, **k: made.append(1) or init(self, *a, **k))

    def work(level):
        V, F = icosphere(level)
        panels = [Panel(V, F, C=C2, BE=BE2),
                  Panel(posed(V, 0.5), F, scalars=(V[:, 0] + 1) / 2, isolines=5)]
        made.clear()
        with Lines() as lines:
            draw_panels(panels)
        return lines.count, len(made)

    work(2)                      # warm up (fonts, caches)
    small_lines, small_artists = work(2)
    lines, artists = work(4)     # 5120 faces; two of them side by side: 10240
    assert lines <= small_lines + 100, (small_lines, lines)
    assert artists == small_artists
