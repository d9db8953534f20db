"""Headless pictures for ``stbs demo``: shaded meshes, skeletons, line plots, PNG and GIF.

Everything is drawn off screen with matplotlib's Agg canvas (no display, no GPU,
never pyplot's global state) and written atomically. matplotlib is an optional
dependency (the ``demo`` extra), imported on first use.

- :class:`Panel` is one picture of a mesh: a 3D surface drawn as a shaded solid
  (Lambert key light + headlight + ambient, painter's algorithm, back faces culled
  on closed meshes), or a flat 2D mesh (plain, per-vertex scalars through a colour
  map, per-vertex colours, or a texture through a small NumPy rasteriser), with the
  posed skeleton ``C``/``BE`` drawn on top.
- :class:`PlotPanel` is a line plot (one curve per method).
- :func:`render_panels` draws panels side by side into one PNG;
  :func:`render_animation` draws a list of frames into an animated GIF;
  :func:`draw_panels` returns the pixels instead of writing a file.
- :class:`Camera` is an orbit camera (azimuth, elevation, up axis), orthographic or
  perspective.

With ``shared_view=True`` (the default) all mesh panels of a picture, and all frames
of an animation, use one camera and one screen window fitted to the union of what
they show, so that methods compare at the same scale and nothing jumps.
"""

from __future__ import annotations

import functools
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace
from typing import Any, Literal

import numpy as np

from .. import _checks
from ..geometry import face_normals, unique_edges
from ..io import atomic_open, atomic_save

__all__ = ["Camera", "Panel", "PlotPanel", "render_panels", "render_animation",
           "draw_panels", "METHOD_COLORS", "MASK_COLOR", "MATPLOTLIB_MISSING"]

#: The message of the ImportError raised when matplotlib is missing.
MATPLOTLIB_MISSING = "the demo's pictures need matplotlib: pip install 'stbs-skinning[demo]'"

#: Curve colours of the skinning methods in :class:`PlotPanel` (others cycle through tab10).
METHOD_COLORS = {"lbs": "#d1495b", "dqs": "#edae49", "stbs-lbs": "#00798c",
                 "stbs-dqs": "#30638e", "rest": "#7f7f7f"}

_BACKGROUND = (1.0, 1.0, 1.0)
_SOLID_COLOR = "#a9bcd0"      # default surface colour: a light steel blue
_FLAT_COLOR = "#c4d3e2"
MASK_COLOR = (0.74, 0.74, 0.74)  # where a panel's scalars are masked out: a neutral grey
_BONE_FILL = "#fbfbf7"
_BONE_EDGE = "#1d1d1f"
_JOINT_FILL = "#e4572e"
_CREASE_COS = math.cos(math.radians(32.0))  # sharper corners keep the face normal
_SUPERSAMPLE = 2                            # rasteriser samples per pixel, per axis
_RASTER_CHUNK = 1 << 21                     # (triangle, pixel) pairs per rasteriser pass

# (a, b, up): the eye sits at cos(el) (cos(az) a + sin(az) b) + sin(el) up, as in
# matplotlib's 3D axes, with a x b = up. Azimuth -90, elevation 0 puts the eye on -b:
# for y up, on +z looking down -z with x to the right.
_UP_FRAMES = {
    "x": ((0.0, 1.0, 0.0), (0.0, 0.0, 1.0), (1.0, 0.0, 0.0)),
    "y": ((1.0, 0.0, 0.0), (0.0, 0.0, -1.0), (0.0, 1.0, 0.0)),
    "z": ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)),
}


def _mpl() -> SimpleNamespace:
    """matplotlib's pieces used here, imported on first use (the ``demo`` extra)."""
    try:
        from matplotlib import colormaps
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.collections import LineCollection, PolyCollection
        from matplotlib.colors import to_rgb
        from matplotlib.figure import Figure
    except ImportError as exc:
        raise ImportError(MATPLOTLIB_MISSING) from exc
    return SimpleNamespace(Figure=Figure, FigureCanvasAgg=FigureCanvasAgg,
                           PolyCollection=PolyCollection, LineCollection=LineCollection,
                           colormaps=colormaps, to_rgb=to_rgb)


def _pil():
    try:
        from PIL import Image
    except ImportError as exc:  # Pillow comes with matplotlib
        raise ImportError(MATPLOTLIB_MISSING) from exc
    return Image


# ---------------------------------------------------------------------- camera
@dataclass(frozen=True)
class Camera:
    """An orbit camera looking at the centre of the scene.

    Parameters
    ----------
    azimuth : float
        Degrees about the ``up`` axis, as in matplotlib's 3D axes. With ``up="y"``:
        -90 looks at the front (down -z, x to the right), 0 from +x; the default -60
        is a 3/4 view from the front right, which shows a shape lying along x broadside.
    elevation : float
        Degrees above the ground plane (positive: looking down on the shape).
    up : {"x", "y", "z"}
        World axis shown upwards on screen. The demo's shapes are built with y up.
    orthographic : bool
        Parallel projection (default); otherwise a perspective with the eye at
        ``distance`` scene radii from the centre.
    distance : float
        Perspective only: eye distance from the scene centre, in scene radii (> 1).

    Notes
    -----
    2D meshes (``V`` of shape (n, 2), or z == 0 everywhere) are drawn flat, x to the
    right and y up, the view of ``Camera(azimuth=-90, elevation=0)``, unless their
    panel sets a camera of its own.
    """

    azimuth: float = -60.0
    elevation: float = 20.0
    up: Literal["x", "y", "z"] = "y"
    orthographic: bool = True
    distance: float = 4.0

    def __post_init__(self) -> None:
        _checks.choice("up", self.up, tuple(_UP_FRAMES))
        for name in ("azimuth", "elevation", "distance"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)) \
                    or not math.isfinite(v):
                raise ValueError(f"Camera.{name} must be a finite number, got {v!r}")
        if not -90.0 <= self.elevation <= 90.0:
            raise ValueError(f"Camera.elevation must lie in [-90, 90] degrees, "
                             f"got {self.elevation}")
        if self.distance <= 1.0:
            raise ValueError(f"Camera.distance must be > 1 (scene radii), got {self.distance}")

    def basis(self) -> np.ndarray:
        """The camera's axes in world coordinates.

        Returns
        -------
        (3, 3) float64
            Rows: screen right, screen up, and the unit direction from the scene
            towards the eye (a right-handed frame).
        """
        a, b, up = (np.array(v) for v in _UP_FRAMES[self.up])
        az, el = math.radians(self.azimuth), math.radians(self.elevation)
        eye = math.cos(el) * (math.cos(az) * a + math.sin(az) * b) + math.sin(el) * up
        # d(eye)/d(azimuth), normalised: defined even when looking straight down.
        right = -math.sin(az) * a + math.cos(az) * b
        return np.stack([right, np.cross(eye, right), eye])

    def project(self, P, *, center=None, radius=None) -> tuple[np.ndarray, np.ndarray]:
        """Project points to screen coordinates and depth.

        Parameters
        ----------
        P : (n, 3) float
            Points in world coordinates.
        center : (3,) float, optional
            The point the camera looks at (default: the middle of ``P``'s bounding box).
        radius : float, optional
            Scene radius, sets the eye distance of a perspective camera (default:
            half the diagonal of ``P``'s bounding box).

        Returns
        -------
        xy : (n, 2) float64
            Screen coordinates, x right and y up, in world units (for a perspective
            camera: world units at the depth of ``center``).
        depth : (n,) float64
            Distance behind the plane through ``center`` facing the eye (larger is
            farther away).
        """
        P = _checks.real_array("P", P, ndim=2, shape=(None, 3))
        lo, hi = (P.min(axis=0), P.max(axis=0)) if len(P) else (np.zeros(3), np.zeros(3))
        c = (lo + hi) / 2 if center is None else _checks.real_array("center", center,
                                                                      shape=(3,))
        r = float(np.linalg.norm(hi - lo)) / 2 if radius is None else float(radius)
        B = self.basis()
        Q = (P - c) @ B.T
        depth = -Q[:, 2]
        xy = Q[:, :2]
        if not self.orthographic:
            d = self.distance * max(r, 1e-12)
            # Points at or behind the eye are pushed to a tiny positive distance.
            xy = xy * (d / np.maximum(d + depth, 1e-6 * d))[:, None]
        return xy, depth


# ---------------------------------------------------------------------- panels
def _skeleton_arrays(C, BE, d: int) -> tuple[np.ndarray | None, np.ndarray | None]:
    if C is None:
        if BE is not None:
            raise ValueError("BE (bone edges) needs C (joint positions), got C=None")
        return None, None
    C = _checks.real_array("C", C, ndim=2)
    if C.shape[1] not in (2, 3):
        raise ValueError(f"C must have shape (k, 2) or (k, 3), got {C.shape}")
    if C.shape[1] != d:
        raise ValueError(f"C must have {d} columns like V, got shape {C.shape}")
    if BE is not None:
        BE = _checks.index_array("BE", BE, ndim=2, shape=(None, 2))
        if BE.size and (BE.min() < 0 or BE.max() >= len(C)):
            bad = BE[(BE < 0) | (BE >= len(C))][0]
            raise ValueError(f"BE must index the {len(C)} rows of C (0 <= BE < {len(C)}), "
                             f"got {bad}")
    return C, BE


def _pad3(X: np.ndarray) -> np.ndarray:
    return X if X.shape[1] == 3 else np.hstack([X, np.zeros((len(X), 1))])


@dataclass(eq=False)
class Panel:
    """One picture of a mesh, with optional colours, texture and skeleton.

    Parameters
    ----------
    V : (n, 2) or (n, 3) float
        Vertex positions (posed). 2D meshes, and 3D ones with z == 0 everywhere and
        no ``camera``, are drawn flat; others as a shaded solid.
    F : (f, 3) int
        Triangles, indices into ``V``.
    title : str
        Shown above the panel.
    C : (k, 2) or (k, 3) float, optional
        Posed joint positions (same number of columns as ``V``), drawn as dots on
        top of the surface (visible even inside the mesh).
    BE : (b, 2) int, optional
        Bone edges, indices into ``C``, drawn as octahedron-like wedges.
    scalars : (n,) float, optional
        Per-vertex values shown through ``cmap`` between ``vmin`` and ``vmax``
        (values outside are clipped), e.g. a bone's weights or endpoint weights.
    cmap : str
        matplotlib colour map name for ``scalars`` ("viridis" for weights,
        "inferno" or "hot" for heat maps).
    vmin, vmax : float
        The range of ``scalars`` mapped onto the colour map.
    isolines : int or sequence of float
        Iso-lines of ``scalars``: a count of evenly spaced interior levels, or the
        levels themselves. 0 (default) draws none.
    mask : (n,) bool, optional
        With ``scalars``: the vertices that show them; the others are drawn in
        :data:`MASK_COLOR` (grey), e.g. a bone's endpoint weights only where its bone
        weight is non-zero. Default: every vertex.
    colors : (n, 3) or (n, 4) float in [0, 1] or uint8, optional
        Per-vertex RGB(A) colours.
    texture : (H, W, 3) or (H, W, 4) uint8 or float in [0, 1], optional
        An image mapped through ``uv`` onto a 2D mesh, sampled bilinearly; row 0 is
        the top of the picture.
    uv : (n, 2) float, optional
        Texture coordinates in [0, 1], (0, 0) at the image's bottom left; required
        with ``texture``.
    color : matplotlib colour, optional
        Base colour when neither ``scalars``, ``colors`` nor ``texture`` is given.
    camera : Camera, optional
        This panel's camera (see ``shared_view`` in :func:`render_panels`).
    subtitle : str
        A line under the panel, e.g. a measured number ("radius ratio 0.36").
    wireframe : bool, optional
        Draw faint mesh edges. Default: on for plain 2D meshes, off otherwise.
    cull : bool, optional
        Hide faces turned away from the eye. Default: on for closed, consistently
        oriented meshes (their orientation is then taken from the signed volume),
        off otherwise, where back faces are lit from the front (two-sided).
    shading : {"smooth", "flat"}
        3D only. "smooth" interpolates the lit colour over each triangle from its
        corners (Gouraud); "flat" gives each triangle one colour, the mean of its
        corners' (a ``PolyCollection``), which shows the facets.

    Raises
    ------
    ValueError
        When an array has the wrong shape, an index is out of range, a value is not
        finite, or more than one of ``scalars``, ``colors``, ``texture`` is given.

    Notes
    -----
    Inputs are checked and converted once, at construction: ``V``, ``C``,
    ``scalars``, ``uv`` to float64, ``F``, ``BE`` to int64, ``colors`` to RGBA
    float64 in [0, 1], ``texture`` to RGBA float32 in [0, 1], ``isolines`` to the
    array of levels.
    """

    V: Any
    F: Any
    title: str = ""
    C: Any = None
    BE: Any = None
    scalars: Any = None
    cmap: str = "viridis"
    vmin: float = 0.0
    vmax: float = 1.0
    isolines: int | Sequence[float] = 0
    mask: Any = None
    colors: Any = None
    texture: Any = None
    uv: Any = None
    color: Any = None
    camera: Camera | None = None
    subtitle: str = ""
    wireframe: bool | None = None
    cull: bool | None = None
    shading: Literal["smooth", "flat"] = "smooth"

    def __post_init__(self) -> None:
        n, d = self._check_mesh()
        self.C, self.BE = _skeleton_arrays(self.C, self.BE, d)
        self._check_scalars(n)
        if not isinstance(self.cmap, str):
            raise ValueError(f"cmap must be a matplotlib colour map name, got {self.cmap!r}")
        self._check_colors(n)
        self._check_camera()
        self._check_options()

    def _check_mesh(self) -> tuple[int, int]:
        """``V`` and ``F`` checked and converted; ``V``'s shape (n, d)."""
        self.V = _checks.vertices(self.V)
        n, d = self.V.shape
        self.F = _checks.index_array("F", self.F, ndim=2, shape=(None, 3))
        if self.F.size and (self.F.min() < 0 or self.F.max() >= n):
            bad = np.flatnonzero(((self.F < 0) | (self.F >= n)).any(axis=1))[0]
            raise ValueError(f"F must index the {n} rows of V (0 <= F < {n}), got "
                             f"{self.F[bad].tolist()} in face {bad}")
        return n, d

    def _check_scalars(self, n: int) -> None:
        """At most one colouring; ``scalars`` with its range, isolines and mask."""
        given = [k for k in ("scalars", "colors", "texture") if getattr(self, k) is not None]
        if len(given) > 1:
            raise ValueError(f"give at most one of scalars, colors, texture; got {given}")
        if self.scalars is not None:
            s = _checks.real_array("scalars", self.scalars)
            if s.shape != (n,):
                raise ValueError(f"scalars must have shape ({n},), one value per row of V, "
                                 f"got {s.shape}")
            self.scalars = s
        for name in ("vmin", "vmax"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)) \
                    or not math.isfinite(v):
                raise ValueError(f"{name} must be a finite number, got {v!r}")
        if not self.vmin < self.vmax:
            raise ValueError(f"vmin must be less than vmax, got vmin={self.vmin}, "
                             f"vmax={self.vmax}")
        self.isolines = self._levels(self.isolines)
        if len(self.isolines) and self.scalars is None:
            raise ValueError("isolines need scalars, got scalars=None")
        if self.mask is not None:
            m = np.asarray(self.mask)
            if self.scalars is None:
                raise ValueError("mask needs scalars, got scalars=None")
            if m.dtype != bool or m.shape != (n,):
                raise ValueError(f"mask must be a ({n},) bool array, one per row of V, got "
                                 f"{m.dtype} of shape {m.shape}")
            self.mask = m

    def _check_colors(self, n: int) -> None:
        """``colors``, ``texture`` and its ``uv`` checked and converted."""
        if self.colors is not None:
            self.colors = self._colors(self.colors, n)
        if self.texture is not None:
            self.texture = self._texture(self.texture)
            if self.uv is None:
                raise ValueError(f"uv must be given with texture: ({n}, 2) texture "
                                 "coordinates, got None")
        elif self.uv is not None:
            raise ValueError("uv needs a texture, got texture=None")
        if self.uv is not None:
            self.uv = _checks.real_array("uv", self.uv, ndim=2)
            if self.uv.shape != (n, 2):
                raise ValueError(f"uv must have shape ({n}, 2), one (u, v) per row of V, "
                                 f"got {self.uv.shape}")

    def _check_camera(self) -> None:
        """``camera`` a Camera or None; a texture only on a mesh drawn flat."""
        if self.camera is not None and not isinstance(self.camera, Camera):
            raise ValueError(f"camera must be a Camera, got {type(self.camera).__name__}")
        if self.texture is not None and not self.flat:
            z = self.V[:, 2]
            raise ValueError("texture is drawn only on 2D meshes (V of shape (n, 2), or "
                             f"z == 0 and no camera), got V of shape {self.V.shape} with "
                             f"z in [{z.min():.3g}, {z.max():.3g}]")

    def _check_options(self) -> None:
        """The titles, ``shading``, ``wireframe`` and ``cull``."""
        for name in ("title", "subtitle"):
            if not isinstance(getattr(self, name), str):
                raise ValueError(f"{name} must be a str, got {getattr(self, name)!r}")
        _checks.choice("shading", self.shading, ("smooth", "flat"))
        for name in ("wireframe", "cull"):
            if getattr(self, name) not in (None, True, False):
                raise ValueError(f"{name} must be True, False or None, got "
                                 f"{getattr(self, name)!r}")

    def _levels(self, iso) -> np.ndarray:
        if isinstance(iso, (int, np.integer)) and not isinstance(iso, bool):
            if iso < 0:
                raise ValueError(f"isolines must be a count >= 0 or a list of levels, got {iso}")
            return np.linspace(self.vmin, self.vmax, int(iso) + 2)[1:-1]
        return _checks.real_array("isolines", iso, ndim=1)

    @staticmethod
    def _colors(c, n: int) -> np.ndarray:
        a = np.asarray(c)
        if a.ndim != 2 or a.shape[0] != n or a.shape[1] not in (3, 4):
            raise ValueError(f"colors must have shape ({n}, 3) or ({n}, 4), RGB(A) per row "
                             f"of V, got {a.shape}")
        if a.dtype == np.uint8:
            a = a / 255.0
        a = _checks.real_array("colors", a)
        if a.min() < 0 or a.max() > 1:
            raise ValueError(f"colors must lie in [0, 1] (or be uint8), got values in "
                             f"[{a.min():.3g}, {a.max():.3g}]")
        return a if a.shape[1] == 4 else np.hstack([a, np.ones((n, 1))])

    @staticmethod
    def _texture(t) -> np.ndarray:
        a = np.asarray(t)
        if a.ndim != 3 or a.shape[2] not in (3, 4) or min(a.shape[:2]) < 1:
            raise ValueError(f"texture must be an (H, W, 3) or (H, W, 4) image, got shape "
                             f"{a.shape}")
        if a.dtype == np.uint8:
            a = a.astype(np.float32) / 255.0
        else:
            a = _checks.real_array("texture", a, dtype=np.float32)
            if a.min() < 0 or a.max() > 1:
                raise ValueError(f"texture must be uint8 or float in [0, 1], got values in "
                                 f"[{a.min():.3g}, {a.max():.3g}]")
        if a.shape[2] == 3:
            a = np.concatenate([a, np.ones(a.shape[:2] + (1,), np.float32)], axis=2)
        return a

    def vertex_colors(self) -> np.ndarray:
        """The colour (n, 3) float64 in [0, 1] each vertex gets before lighting.

        ``scalars`` through ``cmap`` (:data:`MASK_COLOR` where ``mask`` is False),
        ``colors``, or the base ``color``; needs matplotlib. Not for textured panels.
        """
        mpl = _mpl()
        n = self.V.shape[0]
        if self.texture is not None:
            raise ValueError("vertex_colors: a textured panel's colours come from its "
                             "texture, not its vertices")
        if self.scalars is not None:
            t = np.clip((self.scalars - self.vmin) / (self.vmax - self.vmin), 0, 1)
            c = _colormap(self.cmap, mpl)(t)[:, :3]
            if self.mask is not None:
                c[~self.mask] = MASK_COLOR
            return c
        if self.colors is not None:
            return self.colors[:, :3].copy()
        default = _FLAT_COLOR if self.flat else _SOLID_COLOR
        return np.tile(_rgb(self.color, default, mpl), (n, 1))

    @property
    def flat(self) -> bool:
        """Whether the mesh is drawn flat (2D, or z == 0 with no camera of its own)."""
        return self.V.shape[1] == 2 or (self.camera is None and not np.any(self.V[:, 2]))


@dataclass(eq=False)
class PlotPanel:
    """A line plot next to mesh panels: one curve per method.

    Parameters
    ----------
    title : str
        Shown above the plot.
    x : (m,) float
        Abscissae shared by all curves.
    ys : dict[str, (m,) float]
        Curves by label (e.g. method name); the skinning methods get the colours
        of :data:`METHOD_COLORS`.
    xlabel, ylabel : str
        Axis labels.
    subtitle : str
        A line under the plot.
    styles : dict[str, str]
        Optional matplotlib format string per label (e.g. ``{"expected": "k--"}``).

    Raises
    ------
    ValueError
        When ``x`` is not 1-D and finite, or a curve's shape differs from ``x``'s.
    """

    title: str
    x: Any
    ys: Mapping[str, Any]
    xlabel: str = ""
    ylabel: str = ""
    subtitle: str = ""
    styles: Mapping[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.x = _checks.real_array("x", self.x, ndim=1)
        if not isinstance(self.ys, Mapping) or not self.ys:
            raise ValueError(f"ys must be a non-empty dict of label -> curve, got {self.ys!r}")
        ys = {}
        for k, y in self.ys.items():
            y = _checks.real_array(f"ys[{k!r}]", y)
            if y.shape != self.x.shape:
                raise ValueError(f"ys[{k!r}] must have shape {self.x.shape} like x, got "
                                 f"{y.shape}")
            ys[str(k)] = y
        self.ys = ys
        unknown = set(self.styles) - set(ys)
        if unknown:
            raise ValueError(f"styles names curves not in ys: {sorted(unknown)}")


# ---------------------------------------------------------------------- views
@dataclass(eq=False)
class _View:
    """Camera, world centre/radius and screen window shared by a set of panels."""

    camera: Camera
    center: np.ndarray
    radius: float
    bounds: np.ndarray | None = None        # (xmin, xmax, ymin, ymax) of solid panels
    flat_bounds: np.ndarray | None = None   # the same for flat (2D) panels
    xlim: tuple[float, float] | None = None   # plot panels (animations)
    ylim: tuple[float, float] | None = None


def _screen_points(p: Panel, view: _View) -> np.ndarray:
    pts = p.V if p.C is None else np.vstack([_pad3(p.V), _pad3(p.C)])
    if p.flat:
        return pts[:, :2]
    return view.camera.project(_pad3(pts), center=view.center, radius=view.radius)[0]


def _make_view(panels: list, camera: Camera | None) -> _View:
    meshes = [p for p in panels if isinstance(p, Panel)]
    solid = [p for p in meshes if not p.flat]
    if camera is None:
        camera = next((p.camera for p in solid if p.camera is not None), Camera())
    if solid:
        pts = np.vstack([_pad3(p.V) for p in solid] + [_pad3(p.C) for p in solid
                                                         if p.C is not None])
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        center, radius = (lo + hi) / 2, max(float(np.linalg.norm(hi - lo)) / 2, 1e-12)
    else:
        center, radius = np.zeros(3), 1.0
    view = _View(camera, center, radius)
    # Flat and solid panels live in different screen spaces: one window for each.
    for attr, group in (("bounds", solid), ("flat_bounds", [p for p in meshes if p.flat])):
        if group:
            xy = np.vstack([_screen_points(p, view) for p in group])
            lo, hi = xy.min(axis=0), xy.max(axis=0)
            pad = 0.06 * max(float((hi - lo).max()), 1e-9)
            setattr(view, attr, np.array([lo[0] - pad, hi[0] + pad, lo[1] - pad, hi[1] + pad]))
    plots = [p for p in panels if isinstance(p, PlotPanel)]
    if plots:
        x = np.concatenate([p.x for p in plots])
        y = np.concatenate([v for p in plots for v in p.ys.values()])
        ypad = 0.05 * max(float(np.ptp(y)), 1e-9)
        view.xlim = (float(x.min()), float(x.max()))
        view.ylim = (float(y.min()) - ypad, float(y.max()) + ypad)
    return view


# ---------------------------------------------------------------------- geometry
def _closed_and_consistent(F: np.ndarray, n: int) -> bool:
    """Every edge used exactly once in each direction (a closed, oriented surface)."""
    if not len(F):
        return False
    a = F.ravel()
    b = F[:, [1, 2, 0]].ravel()
    fwd = np.sort(a * n + b)
    if np.any(fwd[1:] == fwd[:-1]):
        return False
    return bool(np.array_equal(fwd, np.sort(b * n + a)))


def _iso_segments(P: np.ndarray, F: np.ndarray, s: np.ndarray,
                  levels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Marching triangles: iso-line segments (m, 2, d) of ``s`` and their face ids (m,)."""
    segs, faces = [], []
    sF = s[F]
    for L in levels:
        above = sF >= L
        cut = above.any(axis=1) & ~above.all(axis=1)
        if not np.any(cut):
            continue
        f = np.flatnonzero(cut)
        ends = []
        for i, j in ((0, 1), (1, 2), (2, 0)):
            crosses = above[f, i] != above[f, j]
            si, sj = sF[f, i], sF[f, j]
            den = np.where(crosses, sj - si, 1.0)
            t = np.where(crosses, (L - si) / den, np.nan)
            ends.append((crosses, P[F[f, i]] + t[:, None] * (P[F[f, j]] - P[F[f, i]])))
        # A cut face crosses exactly two of its three edges: take the first two.
        m = np.stack([e[0] for e in ends], axis=1)
        pts = np.stack([e[1] for e in ends], axis=1)
        order = np.argsort(~m, axis=1, kind="stable")[:, :2]
        segs.append(np.take_along_axis(pts, order[:, :, None], axis=1))
        faces.append(f)
    if not segs:
        return np.zeros((0, 2, P.shape[1])), np.zeros(0, np.int64)
    return np.concatenate(segs), np.concatenate(faces)


# ---------------------------------------------------------------------- rasteriser
def _rasterize(xy: np.ndarray, F: np.ndarray, A: np.ndarray, grid) -> tuple[np.ndarray,
                                                                           np.ndarray]:
    """Interpolate per-vertex attributes over triangles at pixel centres.

    ``grid = (x0, y0, dx, dy, W, H)``: pixel (i, j) has its centre at
    ``(x0 + (j + 0.5) dx, y0 + (i + 0.5) dy)`` (row 0 at the bottom). Returns a mask
    (H, W) and values (H, W, k); where triangles overlap, the later one wins.
    """
    x0, y0, dx, dy, W, H = grid
    out = np.zeros((H, W, A.shape[1]), np.float32)
    mask = np.zeros((H, W), bool)
    a, b, c = xy[F[:, 0]], xy[F[:, 1]], xy[F[:, 2]]
    d, e = b - a, c - a
    den = d[:, 0] * e[:, 1] - d[:, 1] * e[:, 0]
    lo, hi = np.minimum(np.minimum(a, b), c), np.maximum(np.maximum(a, b), c)
    j0 = np.clip(np.ceil((lo[:, 0] - x0) / dx - 0.5), 0, W).astype(np.int64)
    j1 = np.clip(np.floor((hi[:, 0] - x0) / dx - 0.5), -1, W - 1).astype(np.int64)
    i0 = np.clip(np.ceil((lo[:, 1] - y0) / dy - 0.5), 0, H).astype(np.int64)
    i1 = np.clip(np.floor((hi[:, 1] - y0) / dy - 0.5), -1, H - 1).astype(np.int64)
    w = np.maximum(j1 - j0 + 1, 0)
    cnt = w * np.maximum(i1 - i0 + 1, 0)
    cnt[np.abs(den) <= 1e-14 * (np.abs(d).max(axis=1) * np.abs(e).max(axis=1) + 1e-300)] = 0
    tri = np.flatnonzero(cnt)
    # Chunks of triangles with a bounded number of (triangle, pixel) pairs.
    cum = np.cumsum(cnt[tri])
    starts = np.searchsorted(cum, np.arange(0, cum[-1] if len(cum) else 0, _RASTER_CHUNK),
                             side="right")
    bounds = list(starts) + [len(tri)]
    for s0, s1 in zip(bounds[:-1], bounds[1:], strict=True):
        t = tri[s0:s1]
        if not len(t):
            continue
        ct = cnt[t]
        tid = np.repeat(t, ct)
        k = np.arange(int(ct.sum())) - np.repeat(np.cumsum(ct) - ct, ct)
        jj = j0[tid] + k % w[tid]
        ii = i0[tid] + k // w[tid]
        qx = x0 + (jj + 0.5) * dx - a[tid, 0]
        qy = y0 + (ii + 0.5) * dy - a[tid, 1]
        l1 = (qx * e[tid, 1] - qy * e[tid, 0]) / den[tid]
        l2 = (d[tid, 0] * qy - d[tid, 1] * qx) / den[tid]
        l0 = 1.0 - l1 - l2
        eps = -1e-9
        inside = (l0 >= eps) & (l1 >= eps) & (l2 >= eps)
        tid, ii, jj = tid[inside], ii[inside], jj[inside]
        l0, l1, l2 = l0[inside, None], l1[inside, None], l2[inside, None]
        Ft = F[tid]
        out[ii, jj] = l0 * A[Ft[:, 0]] + l1 * A[Ft[:, 1]] + l2 * A[Ft[:, 2]]
        mask[ii, jj] = True
    return mask, out


def _sample_bilinear(tex: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """RGBA of ``tex`` (H, W, 4) at ``uv`` (m, 2) in [0, 1], v = 0 at the image's bottom."""
    H, W = tex.shape[:2]
    u = np.clip(uv[:, 0], 0.0, 1.0) * (W - 1)
    v = (1.0 - np.clip(uv[:, 1], 0.0, 1.0)) * (H - 1)
    c0, r0 = np.floor(u).astype(np.int64), np.floor(v).astype(np.int64)
    c1, r1 = np.minimum(c0 + 1, W - 1), np.minimum(r0 + 1, H - 1)
    fu, fv = (u - c0)[:, None], (v - r0)[:, None]
    top = tex[r0, c0] * (1 - fu) + tex[r0, c1] * fu
    bot = tex[r1, c0] * (1 - fu) + tex[r1, c1] * fu
    return top * (1 - fv) + bot * fv


def _raster_image(p: Panel, xlim, ylim, shape_px, mpl) -> np.ndarray:
    """The panel's 2D mesh as an RGBA float image covering the axes (row 0 at the bottom)."""
    W, H = shape_px
    ss = _SUPERSAMPLE
    dx, dy = (xlim[1] - xlim[0]) / (W * ss), (ylim[1] - ylim[0]) / (H * ss)
    grid = (xlim[0], ylim[0], dx, dy, W * ss, H * ss)
    xy = p.V[:, :2]
    if p.texture is not None:
        mask, uv = _rasterize(xy, p.F, p.uv, grid)
        rgba = np.zeros(mask.shape + (4,), np.float32)
        rgba[mask] = _sample_bilinear(p.texture, uv[mask])
    elif p.colors is not None:
        mask, rgba = _rasterize(xy, p.F, p.colors, grid)
    elif p.mask is not None:  # interpolate the colours: the grey has no scalar value
        c = np.hstack([p.vertex_colors(), np.ones((len(xy), 1))])
        mask, rgba = _rasterize(xy, p.F, c, grid)
    else:
        mask, s = _rasterize(xy, p.F, p.scalars[:, None], grid)
        t = np.clip((s[..., 0] - p.vmin) / (p.vmax - p.vmin), 0.0, 1.0)
        rgba = _colormap(p.cmap, mpl)(t).astype(np.float32)
    rgba[~mask] = 0.0
    # Box-filter the supersamples on premultiplied colours (antialiased edges).
    pre = rgba[..., :3] * rgba[..., 3:]
    pre = pre.reshape(H, ss, W, ss, 3).mean(axis=(1, 3))
    alpha = rgba[..., 3].reshape(H, ss, W, ss).mean(axis=(1, 3))
    rgb = pre / np.maximum(alpha, 1e-6)[..., None]
    return np.concatenate([np.clip(rgb, 0, 1), alpha[..., None]], axis=2)


# ---------------------------------------------------------------------- drawing
def _colormap(name: str, mpl):
    try:
        return mpl.colormaps[name]
    except KeyError:
        raise ValueError(f"cmap must be a matplotlib colour map name such as 'viridis' or "
                         f"'inferno', got {name!r}") from None


def _rgb(color, default: str, mpl) -> np.ndarray:
    try:
        return np.array(mpl.to_rgb(default if color is None else color))
    except ValueError:
        raise ValueError(f"color must be a matplotlib colour (a name, '#rrggbb' or an RGB "
                         f"tuple), got {color!r}") from None


def _shade(Pw: np.ndarray, F: np.ndarray, cam: Camera, view: _View, cull: bool | None):
    """Light intensity per face corner, and which faces are kept.

    Lambert diffuse from a key light (upper left, in front) and a headlight, plus a
    little Blinn-Phong specular. Corners use the area-weighted vertex normal unless it
    differs from the face normal by more than ~32 degrees, so that creases such as a
    box's edges stay sharp while curved surfaces look smooth.

    Returns
    -------
    light, spec : (f, 3) float64
        Diffuse light in [0, 1] and specular term per face corner.
    keep : (f,) bool
        Faces to draw (front faces when culling, else all).
    """
    right, up, eye = cam.basis()
    n = len(Pw)
    Nf = face_normals(Pw, F)
    closed = _closed_and_consistent(F, n)
    if closed:
        a, b, c = Pw[F[:, 0]], Pw[F[:, 1]], Pw[F[:, 2]]
        if np.einsum("ij,ij->", a, np.cross(b, c)) < 0:  # inward: flip
            Nf = -Nf
    if cull is None:
        cull = closed
    flat = np.ravel(F)
    Nv = np.stack([np.bincount(flat, np.repeat(Nf[:, k], 3), minlength=n) for k in range(3)],
                  axis=1)
    Nv /= np.maximum(np.linalg.norm(Nv, axis=1), 1e-300)[:, None]
    Nfu = Nf / np.maximum(np.linalg.norm(Nf, axis=1), 1e-300)[:, None]
    if cam.orthographic:
        facing = Nfu @ eye
    else:
        eye_pt = view.center + cam.distance * view.radius * eye
        vdir = eye_pt - Pw[F].mean(axis=1)
        facing = np.einsum("ij,ij->i", Nfu, vdir)
    keep = facing > 0 if cull else np.ones(len(F), bool)
    Nc = Nv[F]                                        # (f, 3 corners, 3)
    smooth = np.einsum("ijk,ik->ij", Nc, Nfu) > _CREASE_COS
    Nc = np.where(smooth[..., None], Nc, Nfu[:, None, :])
    Nc *= np.where(facing >= 0, 1.0, -1.0)[:, None, None]    # two-sided lighting
    key = -0.25 * right + 0.85 * up + 0.45 * eye
    key /= np.linalg.norm(key)
    half = key + eye
    half /= np.linalg.norm(half)
    light = 0.65 * np.clip(Nc @ key, 0, None) + 0.35 * np.clip(Nc @ eye, 0, None)
    spec = np.clip(Nc @ half, 0, None) ** 40
    return light, spec, keep


@functools.cache
def _gouraud_class():
    """An artist drawing triangles with per-corner colours, in the order given."""
    from matplotlib.artist import Artist

    class GouraudTriangles(Artist):
        def __init__(self, verts: np.ndarray, colors: np.ndarray):
            super().__init__()
            self._verts, self._colors = verts, colors

        def draw(self, renderer):
            if not self.get_visible() or not len(self._verts):
                return
            gc = renderer.new_gc()
            self._set_gc_clip(gc)
            # Agg dilates each triangle by half a pixel: no seams between neighbours.
            renderer.draw_gouraud_triangles(gc, self._verts, self._colors,
                                            self.get_transform().frozen())
            gc.restore()

    return GouraudTriangles


def _draw_solid(ax, p: Panel, view: _View, px: float, mpl, dpi: float, xlim, ylim,
                shape_px) -> None:
    cam = view.camera
    Pw = _pad3(p.V)
    F = p.F
    if not len(F):
        return
    xy, depth = cam.project(Pw, center=view.center, radius=view.radius)
    light, spec, keep = _shade(Pw, F, cam, view, p.cull)
    if p.scalars is not None:
        base = p.vertex_colors()[F]
        ambient, shine = 0.5, 0.12
    elif p.colors is not None:
        base = p.colors[F][..., :3]
        ambient, shine = 0.5, 0.12
    else:
        base = np.broadcast_to(_rgb(p.color, _SOLID_COLOR, mpl), F.shape + (3,))
        ambient, shine = 0.34, 0.25
    lit = np.clip(base * (ambient + (1 - ambient) * light)[..., None]
                  + shine * spec[..., None], 0.0, 1.0)
    f = np.flatnonzero(keep)
    order = f[np.argsort(-depth[F[f]].mean(axis=1), kind="stable")]   # far to near
    if p.shading == "flat":
        fc = lit[order].mean(axis=1)
        # Edges in the face colour cover the hairline seams of antialiased polygons.
        ax.add_collection(mpl.PolyCollection(xy[F[order]], closed=True, facecolors=fc,
                                             edgecolors=fc, linewidths=0.5 * 72.0 / dpi,
                                             zorder=1))
    else:
        rgba = np.concatenate([lit[order], np.ones((len(order), 3, 1))], axis=2)
        tris = _gouraud_class()(xy[F[order]], rgba)
        tris.set_zorder(1)
        tris.set_transform(ax.transData)
        tris.set_clip_box(ax.bbox)
        ax.add_artist(tris)
    if len(p.isolines):
        _draw_solid_isolines(ax, p, view, xy, depth, order, base, px, mpl, dpi, xlim, ylim,
                             shape_px)


def _draw_solid_isolines(ax, p: Panel, view: _View, xy, depth, order, base, px, mpl, dpi,
                         xlim, ylim, shape_px) -> None:
    """Iso-lines on a shaded solid, hidden where another part of the surface is in front.

    Visibility comes from a depth buffer: the drawn faces are rasterised in painter's
    order at screen resolution, and a segment is kept when its midpoint is not
    behind the surface seen at that pixel.
    """
    F = p.F
    seg, sf = _iso_segments(_pad3(p.V), F, p.scalars, p.isolines)
    drawn = np.zeros(len(F), bool)
    drawn[order] = True
    on = drawn[sf]
    seg, sf = seg[on], sf[on]
    if not len(seg):
        return
    cam = view.camera
    sxy, sdepth = cam.project(seg.reshape(-1, 3), center=view.center, radius=view.radius)
    sxy, sdepth = sxy.reshape(-1, 2, 2), sdepth.reshape(-1, 2).mean(axis=1)
    W, H = shape_px
    dx, dy = (xlim[1] - xlim[0]) / W, (ylim[1] - ylim[0]) / H
    mask, zbuf = _rasterize(xy, F[order], depth[:, None], (xlim[0], ylim[0], dx, dy, W, H))
    mid = sxy.mean(axis=1)
    j = np.clip(((mid[:, 0] - xlim[0]) / dx).astype(np.int64), 0, W - 1)
    i = np.clip(((mid[:, 1] - ylim[0]) / dy).astype(np.int64), 0, H - 1)
    tol = 0.02 * view.radius + 2 * px
    visible = ~mask[i, j] | (sdepth <= zbuf[i, j, 0] + tol)
    seg, sf = sxy[visible], sf[visible]
    lum = base[sf].mean(axis=1) @ np.array([0.299, 0.587, 0.114])
    colors = np.where((lum > 0.6)[:, None], [[0.1, 0.1, 0.12, 0.9]], [[1.0, 1.0, 1.0, 0.9]])
    ax.add_collection(mpl.LineCollection(seg, colors=colors, linewidths=1.2 * 72.0 / dpi,
                                         zorder=2, capstyle="round"))


def _draw_flat(ax, p: Panel, xlim, ylim, shape_px, px: float, mpl, dpi: float) -> None:
    xy = p.V[:, :2]
    F = p.F
    pt = 72.0 / dpi   # points per pixel
    if not len(F):
        return
    if p.texture is not None or p.colors is not None or p.scalars is not None:
        img = _raster_image(p, xlim, ylim, shape_px, mpl)
        ax.imshow(img, extent=(xlim[0], xlim[1], ylim[0], ylim[1]), origin="lower",
                  interpolation="nearest", zorder=1, aspect="auto")
        wire = bool(p.wireframe)
    else:
        base = _rgb(p.color, _FLAT_COLOR, mpl)
        ax.add_collection(mpl.PolyCollection(xy[F], closed=True, facecolors=[base],
                                             edgecolors=[base], linewidths=0.5 * pt,
                                             zorder=1))
        wire = p.wireframe is None or p.wireframe
    E, _, count = unique_edges(F)
    if wire:
        ax.add_collection(mpl.LineCollection(xy[E], colors=[(0.1, 0.15, 0.25, 0.28)],
                                             linewidths=0.6 * pt, zorder=1.5))
    if len(p.isolines):
        seg, _ = _iso_segments(xy, F, p.scalars, p.isolines)
        ax.add_collection(mpl.LineCollection(seg, colors=[(1, 1, 1, 0.85)],
                                             linewidths=1.1 * pt, zorder=1.6))
    border = E[count == 1]
    if len(border) and p.texture is None:
        ax.add_collection(mpl.LineCollection(xy[border], colors=["#3a4150"],
                                             linewidths=1.2 * pt, zorder=1.7))


def _draw_skeleton(ax, p: Panel, view: _View, px: float, mpl, dpi: float) -> None:
    if p.C is None:
        return
    if p.flat:
        xy, depth = p.C[:, :2], np.zeros(len(p.C))
    else:
        xy, depth = view.camera.project(_pad3(p.C), center=view.center, radius=view.radius)
    pt = 72.0 / dpi
    if p.BE is not None and len(p.BE):
        a, b = xy[p.BE[:, 0]], xy[p.BE[:, 1]]
        d = b - a
        L = np.linalg.norm(d, axis=1)
        ok = L > 2 * px
        a, b, d, L = a[ok], b[ok], d[ok], L[ok]
        # An octahedron's outline: widest a fifth of the way from parent to child.
        half = np.clip(0.09 * L, 2.5 * px, 8.0 * px)
        nrm = np.stack([-d[:, 1], d[:, 0]], axis=1) / L[:, None] * half[:, None]
        mid = a + 0.2 * d
        wedges = np.stack([a, mid + nrm, b, mid - nrm], axis=1)
        order = np.argsort(-depth[p.BE[ok]].mean(axis=1), kind="stable")
        ax.add_collection(mpl.PolyCollection(wedges[order], closed=True,
                                             facecolors=[_BONE_FILL], edgecolors=[_BONE_EDGE],
                                             linewidths=1.3 * pt, zorder=3))
    order = np.argsort(-depth, kind="stable")
    ax.scatter(xy[order, 0], xy[order, 1], s=(7.5 * pt) ** 2, c=_JOINT_FILL,
               edgecolors="white", linewidths=1.3 * pt, zorder=4)


def _method_color(label: str, k: int, mpl):
    if label in METHOD_COLORS:
        return METHOD_COLORS[label]
    return mpl.colormaps["tab10"](k % 10)


def _draw_plot(ax, p: PlotPanel, view: _View | None, mpl) -> None:
    for k, (label, y) in enumerate(p.ys.items()):
        fmt = p.styles.get(label)
        if fmt:
            ax.plot(p.x, y, fmt, label=label, linewidth=1.8)
        else:
            ax.plot(p.x, y, color=_method_color(label, k, mpl), label=label, linewidth=2.0)
    ax.set_xlabel(p.xlabel, fontsize=9)
    ax.set_ylabel(p.ylabel, fontsize=9)
    ax.tick_params(labelsize=8)
    ax.grid(True, color="#dddddd", linewidth=0.6)
    for side in ("top", "right"):
        ax.spines[side].set_visible(False)
    if view is not None and view.xlim is not None:
        if view.xlim[1] > view.xlim[0]:
            ax.set_xlim(*view.xlim)
        ax.set_ylim(*view.ylim)
    ax.legend(fontsize=8, frameon=False, loc="best")


# ---------------------------------------------------------------------- layout
def _check_panels(name: str, panels) -> list:
    if isinstance(panels, (Panel, PlotPanel)) or not isinstance(panels, Sequence) or \
            not len(panels):
        raise ValueError(f"{name} must be a non-empty list of Panel or PlotPanel, got "
                         f"{type(panels).__name__}")
    for k, p in enumerate(panels):
        if not isinstance(p, (Panel, PlotPanel)):
            raise ValueError(f"{name}[{k}] must be a Panel or PlotPanel, got "
                             f"{type(p).__name__}")
    return list(panels)


def _check_layout(ncols, panel_size, dpi, n: int) -> tuple[int, tuple[int, int], float]:
    if ncols is None:
        ncols = min(n, 4)
    if isinstance(ncols, bool) or not isinstance(ncols, (int, np.integer)) or ncols < 1:
        raise ValueError(f"ncols must be a positive integer or None, got {ncols!r}")
    try:
        w, h = (int(v) for v in panel_size)
        ok = all(float(v) == int(v) for v in panel_size)
    except (TypeError, ValueError):
        ok = False
    if not ok or w < 64 or h < 64:
        raise ValueError(f"panel_size must be two whole numbers of pixels >= 64, got "
                         f"{panel_size!r}")
    if isinstance(dpi, bool) or not isinstance(dpi, (int, float)) or not 10 <= dpi <= 1000:
        raise ValueError(f"dpi must be a number in [10, 1000], got {dpi!r}")
    return min(int(ncols), n), (w, h), float(dpi)


def _fontsize(text: str, base: float, width_px: int, dpi: float) -> float:
    # About 0.55 em per character; shrink long lines to fit the panel's width.
    fits = width_px / (0.55 * base * dpi / 72.0)
    return base if len(text) <= fits else max(6.0, base * fits / len(text))


def _draw(panels: list, views: list[_View], *, ncols: int, size: tuple[int, int],
          title: str | None, dpi: float) -> np.ndarray:
    """Draw ``panels`` (each with its view) into an RGBA uint8 array (H, W, 4)."""
    mpl = _mpl()
    pw, ph = size
    nrows = -(-len(panels) // ncols)
    top = 40 if title else 0
    W, H = ncols * pw, nrows * ph + top
    fig = mpl.Figure(figsize=(W / dpi, H / dpi), dpi=dpi, facecolor=_BACKGROUND)
    canvas = mpl.FigureCanvasAgg(fig)
    has_title = any(p.title for p in panels)
    has_sub = any(p.subtitle for p in panels)
    th = 30 if has_title else 6
    sh = 26 if has_sub else 6
    if title:
        fig.text(0.5, 1 - 20 / H, title, ha="center", va="center", color="#111111",
                 fontsize=_fontsize(title, 14, W - 20, dpi), fontweight="bold")
    for k, (p, view) in enumerate(zip(panels, views, strict=True)):
        r, c = divmod(k, ncols)
        x0, y0 = c * pw, top + r * ph          # the cell's top left, in pixels from the top
        if p.title:
            fig.text((x0 + pw / 2) / W, 1 - (y0 + th / 2 + 2) / H, p.title, ha="center",
                     va="center", fontsize=_fontsize(p.title, 11, pw - 10, dpi),
                     color="#222222")
        if p.subtitle:
            fig.text((x0 + pw / 2) / W, 1 - (y0 + ph - sh / 2 - 1) / H, p.subtitle,
                     ha="center", va="center", fontsize=_fontsize(p.subtitle, 9.5, pw - 10,
                                                                   dpi), color="#444444")
        if isinstance(p, PlotPanel):
            left, right, atop, bottom = 56, 20, th + 6, sh + 38
        else:
            left, right, atop, bottom = 4, 4, th, sh
        aw, ah = pw - left - right, ph - atop - bottom
        ax = fig.add_axes(((x0 + left) / W, 1 - (y0 + ph - bottom) / H, aw / W, ah / H))
        if isinstance(p, PlotPanel):
            _draw_plot(ax, p, view, mpl)
            continue
        ax.set_axis_off()
        # Fit the view's window into the axes at one scale for x and y (equal aspect).
        b = view.flat_bounds if p.flat else view.bounds
        s = min(aw / (b[1] - b[0]), ah / (b[3] - b[2]))
        cx, cy = (b[0] + b[1]) / 2, (b[2] + b[3]) / 2
        xlim = (cx - aw / (2 * s), cx + aw / (2 * s))
        ylim = (cy - ah / (2 * s), cy + ah / (2 * s))
        ax.set_xlim(*xlim)
        ax.set_ylim(*ylim)
        px = 1.0 / s   # data units per pixel
        if p.flat:
            _draw_flat(ax, p, xlim, ylim, (aw, ah), px, mpl, dpi)
        else:
            _draw_solid(ax, p, view, px, mpl, dpi, xlim, ylim, (aw, ah))
        _draw_skeleton(ax, p, view, px, mpl, dpi)
    canvas.draw()
    return np.asarray(canvas.buffer_rgba()).copy()


def _views(panels_by_frame: list[list], shared_view: bool, camera: Camera | None) -> list:
    """One view per panel position, fitted over every frame."""
    if camera is not None and not isinstance(camera, Camera):
        raise ValueError(f"camera must be a Camera or None, got {type(camera).__name__}")
    npos = len(panels_by_frame[0])
    if shared_view:
        v = _make_view([p for fr in panels_by_frame for p in fr], camera)
        # Meshes share one scale; each plot keeps its own axes (they plot different things).
        columns = [[fr[j] for fr in panels_by_frame] for j in range(npos)]
        return [_make_view(c, camera) if all(isinstance(p, PlotPanel) for p in c) else v
                for c in columns]
    out = []
    for j in range(npos):
        column = [fr[j] for fr in panels_by_frame]
        cam = camera
        if cam is None:
            cam = next((p.camera for p in column if isinstance(p, Panel) and p.camera), None)
        out.append(_make_view(column, cam))
    return out


def draw_panels(panels: Sequence[Panel | PlotPanel], *, ncols: int | None = None,
                panel_size: tuple[int, int] = (360, 360), title: str | None = None,
                shared_view: bool = True, camera: Camera | None = None,
                dpi: float = 100) -> np.ndarray:
    """Draw panels side by side and return the pixels.

    Parameters
    ----------
    panels, ncols, panel_size, title, shared_view, camera, dpi
        As :func:`render_panels`.

    Returns
    -------
    (H, W, 4) uint8
        RGBA pixels, row 0 at the top; ``W = ncols * panel_size[0]`` and
        ``H = nrows * panel_size[1]`` plus 40 when there is a ``title``.

    Raises
    ------
    ImportError
        When matplotlib is missing.
    ValueError
        For an empty or mistyped ``panels``, a bad ``ncols``, ``panel_size``, ``dpi``
        or ``camera``, or an unknown ``cmap``/``color``.
    """
    panels = _check_panels("panels", panels)
    ncols, size, dpi = _check_layout(ncols, panel_size, dpi, len(panels))
    views = _views([panels], shared_view, camera)
    return _draw(panels, views, ncols=ncols, size=size, title=title, dpi=dpi)


def _check_suffix(path, allowed: tuple[str, ...]) -> Path:
    p = Path(os.fspath(path))
    if p.suffix.lower() not in allowed:
        raise ValueError(f"path must end with {' or '.join(allowed)}, got {str(p)!r}")
    return p


def render_panels(path: str | os.PathLike, panels: Sequence[Panel | PlotPanel], *,
                  ncols: int | None = None, panel_size: tuple[int, int] = (360, 360),
                  title: str | None = None, shared_view: bool = True,
                  camera: Camera | None = None, dpi: float = 100) -> Path:
    """Draw panels side by side into one PNG, written atomically.

    Parameters
    ----------
    path : str or os.PathLike
        Destination ``.png``; its folder must exist. An existing file is replaced
        only once the new one is complete.
    panels : sequence of Panel or PlotPanel
        The pictures, left to right, then top to bottom.
    ncols : int, optional
        Panels per row (default: all of them, at most 4).
    panel_size : (int, int)
        Width and height of each panel in pixels, title and subtitle included.
    title : str, optional
        A line above all panels (adds 40 pixels to the height).
    shared_view : bool
        One camera and one screen window for all 3D mesh panels, fitted to the
        union of their projected vertices and joints with a margin, so that they
        compare at the same scale (flat 2D panels share a window of their own).
        Otherwise each panel is fitted on its own, with its own camera.
    camera : Camera, optional
        The camera of the 3D panels. Default: with ``shared_view``, the first panel's
        camera that is set, else ``Camera()``; otherwise each panel's own, else
        ``Camera()``.
    dpi : float
        Pixels per inch: sets the size of text and lines relative to the panel.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    ImportError
        When matplotlib is missing.
    ValueError
        For a path not ending in ``.png``, or bad panels or options (see
        :func:`draw_panels`).

    Examples
    --------
    >>> import os, tempfile
    >>> import stbs
    >>> V, F, sk, W = stbs.shapes.cigar(8)
    >>> U = stbs.deform(V, sk, stbs.forward_kinematics(sk, stretch=[2.0]), W, method="lbs")
    >>> path = os.path.join(tempfile.mkdtemp(), "stretch.png")
    >>> render_panels(path, [Panel(V, F, "rest"), Panel(U, F, "LBS")],
    ...               title="one bone stretched x2").name
    'stretch.png'

    """
    p = _check_suffix(path, (".png",))
    rgba = draw_panels(panels, ncols=ncols, panel_size=panel_size, title=title,
                       shared_view=shared_view, camera=camera, dpi=dpi)
    Image = _pil()
    img = Image.fromarray(np.ascontiguousarray(rgba[..., :3]), "RGB")
    with atomic_open(p, "wb") as f:
        img.save(f, format="PNG", optimize=False, compress_level=6)
    return p


def _gif_frames(rgbs: list[np.ndarray]):
    """Quantise RGB frames onto one shared palette (no flicker, delta-friendly).

    The palette (octree, 255 colours, no dithering: dithering noise doubles the file
    size) is built from a sample of the frames; pure white is added so that the
    background stays exactly white.
    """
    Image = _pil()
    step = max(1, len(rgbs) // 8)
    sample = np.concatenate([fr[::2, ::2] for fr in rgbs[::step]], axis=0)
    q = Image.fromarray(np.ascontiguousarray(sample), "RGB").quantize(
        colors=255, method=Image.Quantize.FASTOCTREE, dither=Image.Dither.NONE)
    colors = np.asarray(q.getpalette()[:3 * 255], np.uint8).reshape(-1, 3)
    colors = np.vstack([colors, [[255, 255, 255]]])
    palette = Image.new("P", (1, 1))
    palette.putpalette(colors.ravel().tolist())
    out = []
    for fr in rgbs:
        idx = np.array(Image.fromarray(fr, "RGB").quantize(palette=palette,
                                                           dither=Image.Dither.NONE))
        # Pillow's palette lookup is approximate (254 for 255): pin the background.
        idx[(fr == 255).all(axis=2)] = len(colors) - 1
        im = Image.fromarray(idx, "P")
        im.putpalette(colors.ravel().tolist())
        out.append(im)
    return out


def render_animation(path: str | os.PathLike, frames: Sequence[Sequence[Panel | PlotPanel]],
                     *, fps: float = 12, panel_size: tuple[int, int] = (360, 360),
                     ncols: int | None = None, title: str | Sequence[str] | None = None,
                     shared_view: bool = True, camera: Camera | None = None,
                     dpi: float = 100) -> Path:
    """Draw frames of panels into an animated GIF (or MP4), written atomically.

    Parameters
    ----------
    path : str or os.PathLike
        Destination ``.gif`` (looping forever, one shared optimised palette), or
        ``.mp4`` when the optional package ``imageio-ffmpeg`` is installed.
    frames : sequence of sequences of Panel or PlotPanel
        Every frame has the same layout: the same number of panels, the same kind
        at each position.
    fps : float
        Frames per second, in (0, 50].
    panel_size, ncols, shared_view, camera, dpi
        As :func:`render_panels`. The camera and the screen window are fitted once
        over all frames, so nothing jumps; with ``shared_view=False`` once per panel
        position over all frames. Line plots keep fixed axis limits too.
    title : str or sequence of str, optional
        One line above the panels, or one per frame (e.g. the pose's parameter).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    ImportError
        When matplotlib is missing, or for ``.mp4`` when imageio-ffmpeg is.
    ValueError
        For an empty ``frames``, frames of different layouts, a bad ``fps``, a
        ``title`` list of the wrong length, or bad panels or options.
    """
    p = _check_suffix(path, (".gif", ".mp4"))
    if isinstance(frames, (Panel, PlotPanel)) or not isinstance(frames, Sequence) \
            or not len(frames):
        raise ValueError(f"frames must be a non-empty list of lists of panels, got "
                         f"{type(frames).__name__}")
    frames = [_check_panels(f"frames[{k}]", fr) for k, fr in enumerate(frames)]
    kinds = [type(q) for q in frames[0]]
    for k, fr in enumerate(frames):
        if [type(q) for q in fr] != kinds:
            raise ValueError(f"frames[{k}] must have the layout of frames[0] "
                             f"({len(kinds)} panels: {[t.__name__ for t in kinds]}), got "
                             f"{[type(q).__name__ for q in fr]}")
    if isinstance(fps, bool) or not isinstance(fps, (int, float)) or not 0 < fps <= 50:
        raise ValueError(f"fps must be a number in (0, 50], got {fps!r}")
    if title is None or isinstance(title, str):
        titles = [title] * len(frames)
    else:
        titles = list(title)
        if len(titles) != len(frames):
            raise ValueError(f"title must be a str or one str per frame ({len(frames)}), got "
                             f"{len(titles)} titles")
    ncols, size, dpi = _check_layout(ncols, panel_size, dpi, len(kinds))
    views = _views(frames, shared_view, camera)
    rgbs = [np.ascontiguousarray(_draw(fr, views, ncols=ncols, size=size, title=t,
                                       dpi=dpi)[..., :3])
            for fr, t in zip(frames, titles, strict=True)]
    if p.suffix.lower() == ".mp4":
        _write_mp4(p, rgbs, fps)
        return p
    images = _gif_frames(rgbs)
    with atomic_open(p, "wb") as f:
        images[0].save(f, format="GIF", save_all=True, append_images=images[1:],
                       duration=int(round(1000 / fps)), loop=0, optimize=True)
    return p


def _write_mp4(p: Path, rgbs: list[np.ndarray], fps: float) -> None:
    try:
        import imageio_ffmpeg
    except ImportError as exc:
        raise ImportError("writing .mp4 needs imageio-ffmpeg: pip install imageio-ffmpeg "
                          "(or write a .gif)") from exc
    H, W = rgbs[0].shape[:2]
    H2, W2 = H + H % 2, W + W % 2   # yuv420p needs even sizes: pad with white

    def write(tmp: str) -> None:
        w = imageio_ffmpeg.write_frames(tmp, (W2, H2), fps=fps, macro_block_size=1)
        w.send(None)
        for fr in rgbs:
            out = np.full((H2, W2, 3), 255, np.uint8)
            out[:H, :W] = fr
            w.send(out)
        w.close()

    atomic_save(p, write)
