"""The rig pipelines of files and pictures: what ``stbs rig`` runs, as library functions.

=============================  ==========================================================
function                       what it rigs
=============================  ==========================================================
:func:`rig_from_files`         a MESH file (a mesh, a Triangle ``.poly`` outline or a
                               picture) and a SKELETON file (``.tgf``, ``.bf``)
:func:`rig_from_mesh`          mesh arrays and a skeleton, with ``tets`` as ``stbs rig``
                               takes ``--tets`` (a mesher's name, or a tetrahedral mesh)
:func:`rig_from_outline`       a 2D shape's closed polygons: triangulated with the bones
                               inside; the rig keeps that triangle mesh
:func:`rig_from_picture`       a picture (paper §4, Fig. 12): its shape traced, then as
                               :func:`rig_from_outline`, with the picture as texture
=============================  ==========================================================

Progress and cancelling
-----------------------
Every function takes ``progress(stage, done, total)``: each stage starts with
``(stage, 0, 0)``; the long ones (weight solves, meshing) then report ``done`` of
``total`` units, at least once per solver round or bone. Raise any exception from
``progress`` to cancel: the computation stops at its next report and the exception
propagates to the caller, unchanged; ``progress`` is not called again.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Literal

import numpy as np

from ..skeleton import Skeleton
from .build import DEFAULT_TOL, VOLUME_METHODS, Progress, build_rig
from .model import Rig

__all__ = ["rig_from_files", "rig_from_mesh", "rig_from_outline", "rig_from_picture",
           "read_image", "rgba", "picture_uv", "IMAGE_EXTENSIONS", "OUTLINE_EXTENSIONS",
           "OUTLINE_TRIANGLES", "Progress"]

#: MESH files that are a 2D shape's outline rather than a mesh: traced or read, then
#: triangulated with the bones inside; the rig keeps that triangle mesh.
IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg", ".bmp", ".gif", ".tif", ".tiff", ".webp")
OUTLINE_EXTENSIONS = (".poly", *IMAGE_EXTENSIONS)
#: Triangles an outline is meshed into by default (``max_area`` = area / this).
OUTLINE_TRIANGLES = 4000


def _stages(progress: Progress | None) -> Callable:
    """``run(label, fn, *a, **kw)``: report the stage's start, then ``fn(*a, **kw)``."""
    say = progress or (lambda stage, done, total: None)

    def run(label: str, fn, *a, **kw):
        say(label, 0, 0)
        return fn(*a, **kw)

    return run


def read_image(path) -> np.ndarray:
    """An image file as an array (H, W[, C]) of uint8 or bool for :func:`rig_from_picture`.

    Raises
    ------
    FileNotFoundError
        No file at ``path``.
    ValueError
        Not an image Pillow can read (the message names the file).
    stbs.OptionalDependencyError
        Pillow is not installed (the ``demo`` extra brings it).
    """
    from .._optional import require

    Image = require("PIL.Image", f"reading the image {str(path)!r}")
    try:
        with Image.open(path) as im:
            if im.mode not in ("L", "LA", "RGB", "RGBA", "1"):
                im = im.convert("RGBA" if "A" in im.getbands() else "RGB")
            return np.asarray(im)
    except FileNotFoundError:
        raise FileNotFoundError(f"{str(path)!r}: image file not found") from None
    except OSError as exc:
        raise ValueError(f"{str(path)!r}: not a readable image ({exc})") from None


def rgba(image) -> np.ndarray:
    """An image array (H, W), (H, W, 2|3|4), bool or uint8 -> (H, W, 4) uint8 RGBA."""
    a = np.asarray(image)
    if a.dtype == bool:
        a = a.astype(np.uint8) * 255
    a = a.astype(np.uint8, copy=False)
    if a.ndim == 2:
        a = a[:, :, None]
    c = a.shape[2]
    rgb = np.repeat(a[:, :, :1], 3, axis=2) if c in (1, 2) else a[:, :, :3]
    alpha = a[:, :, -1:] if c in (2, 4) else np.full(a.shape[:2] + (1,), 255, np.uint8)
    return np.ascontiguousarray(np.concatenate([rgb, alpha], axis=2))


def picture_uv(V, shape) -> np.ndarray:
    """Texture coordinates (n, 2) of points in pixel units with y up (pixel (row r,
    column c) of an H-row image at (c, H - 1 - r)): u = (x + 1/2) / W, v = (y + 1/2) / H,
    in [0, 1]."""
    h, w = shape[:2]
    return np.clip((np.asarray(V, dtype=float) + 0.5) / np.array([w, h], dtype=float), 0.0, 1.0)


def _positive(name: str, value) -> float | None:
    if value is None:
        return None
    value = float(value)
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be a positive number, got {value!r}")
    return value


def rig_from_outline(polygons, sk: Skeleton, *,
                     endpoint: Literal["bbw", "bbw-joints", "heat", "projection",
                                       "idw"] = "bbw",
                     max_area: float | None = None, clip_skeleton: bool = False,
                     tol: float = DEFAULT_TOL, progress: Progress | None = None) -> Rig:
    """A 2D rig of a shape's outline: triangulated with the bones inside, then BBW.

    Parameters
    ----------
    polygons : sequence of (k, 2) float
        The shape's closed polygons (outer boundaries and holes).
    sk : Skeleton
        A 2D skeleton in the polygons' coordinates.
    endpoint : str
        Endpoint weights (:func:`stbs.build_rig`'s ``endpoint``).
    max_area : float, optional
        Largest triangle area (default: the shape's area / :data:`OUTLINE_TRIANGLES`,
        a smooth field for BBW).
    clip_skeleton : bool
        Mesh only the skeleton's parts inside the shape (else a joint outside is an
        error).
    tol : float
        KKT tolerance of the BBW solves.
    progress : callable, optional
        ``progress(stage, done, total)`` (module docs: raise from it to cancel).

    Returns
    -------
    Rig
        On stbs's triangle mesh (the polygons' vertices first), bone weights BBW.
    """
    from ..geometry import polygons_area
    from ..meshing import triangulate_2d

    max_area = _positive("max_area", max_area)
    if max_area is None:
        max_area = max(polygons_area(polygons), 1e-300) / OUTLINE_TRIANGLES
    tri = _stages(progress)("triangulate (bones inside)", triangulate_2d, polygons, sk,
                            max_area=max_area, clip_skeleton=clip_skeleton)
    return build_rig(tri.V, sk, F=tri.F, bone="bbw", endpoint=endpoint, tol=tol,
                     remesh=False, progress=progress)


def rig_from_picture(image, sk: Skeleton, *, threshold: float = 0.5, invert: bool = False,
                     endpoint: Literal["bbw", "bbw-joints", "heat", "projection",
                                       "idw"] = "bbw",
                     max_area: float | None = None, clip_skeleton: bool = False,
                     tol: float = DEFAULT_TOL, progress: Progress | None = None) -> Rig:
    """A 2D rig of the shape in a picture (paper §4, Fig. 12), the picture its texture.

    Parameters
    ----------
    image : (H, W) or (H, W, C) uint8 or bool
        The picture, row 0 at the top (:func:`read_image` reads a file).
    sk : Skeleton
        A 2D skeleton in pixel units with y up: pixel (row r, column c) of an H-row
        image is at (c, H - 1 - r).
    threshold : float
        The shape is where alpha (or, without alpha, the luma) exceeds ``threshold``,
        in [0, 1].
    invert : bool
        The shape is where the value is below ``threshold`` (dark on light).
    endpoint, max_area, clip_skeleton, tol, progress
        As for :func:`rig_from_outline` (``max_area`` in pixels squared).

    Returns
    -------
    Rig
        As :func:`rig_from_outline`, with ``texture`` (the picture as RGBA) and ``UV``.

    Raises
    ------
    ValueError
        No shape in the picture at this ``threshold``, or as :func:`rig_from_outline`.
    """
    from ..meshing import outline_from_image

    polygons = _stages(progress)("trace outline", outline_from_image, image,
                                 threshold=threshold, invert=invert)
    if not polygons:
        raise ValueError(f"image: no shape found (nothing {'below' if invert else 'above'} "
                         f"threshold {threshold:g})")
    rig = rig_from_outline(polygons, sk, endpoint=endpoint, max_area=max_area,
                           clip_skeleton=clip_skeleton, tol=tol, progress=progress)
    texture = rgba(image)
    return rig.replace(texture=texture, UV=picture_uv(rig.V, texture.shape))


def rig_from_mesh(V, sk: Skeleton, *, F=None, T=None, W=None,
                  bone: Literal["bbw", "heat"] = "bbw",
                  endpoint: Literal["bbw", "bbw-joints", "heat", "projection", "idw"] = "bbw",
                  tets="auto", tet_size: float | None = None, tol: float = DEFAULT_TOL,
                  clip_skeleton: bool = False, remesh: bool = True, keep_volume: bool = False,
                  progress: Progress | None = None) -> Rig:
    """:func:`stbs.build_rig` with ``tets`` as ``stbs rig --tets`` takes it.

    Parameters
    ----------
    tets : {"auto", "winding", "conforming"} or (Vt, Tt)
        A mesher's name (:func:`stbs.build_rig`'s ``volume``), or a tetrahedral mesh of
        the surface: ``Vt`` (m, 3) whose first n vertices are ``V`` in order (as
        libigl's ``.mesh`` files have them), ``Tt`` (t, 4). The bone weights are then
        solved on it (``W`` None); heat endpoint weights still on the surface ``F``.
    tet_size : float, optional
        The winding-number volume's edge length (``volume_size``).
    keep_volume : bool
        Keep the volume the weights were solved on in the rig (``rig.volume``).
    V, sk, F, T, W, bone, endpoint, tol, clip_skeleton, remesh, progress
        As for :func:`stbs.build_rig`.

    Returns
    -------
    Rig
        On ``V`` (and ``F``, ``T`` as given).
    """
    if isinstance(tets, str) and tets in VOLUME_METHODS:
        return build_rig(V, sk, F=F, T=T, W=W, bone=bone, endpoint=endpoint, tol=tol,
                         clip_skeleton=clip_skeleton, remesh=remesh, volume=tets,
                         volume_size=tet_size, keep_volume=keep_volume, progress=progress)
    if isinstance(tets, str) or W is not None or T is not None:
        raise ValueError(f"tets must be one of {', '.join(VOLUME_METHODS)} or a tetrahedral "
                         f"mesh (Vt, Tt) for a surface whose bone weights are computed, got "
                         + (repr(tets) if isinstance(tets, str) else
                            "a mesh with " + ("W given" if W is not None else "T given")))
    return _rig_on_tets(V, sk, F, tets, bone=bone, endpoint=endpoint, tol=tol,
                        keep_volume=keep_volume, progress=progress)


def _rig_on_tets(V, sk, F, tets, *, bone, endpoint, tol, keep_volume, progress) -> Rig:
    """The rig of a surface ``(V, F)`` whose weights are solved on given tetrahedra."""
    from .. import _checks
    from .model import Volume

    V = _checks.skeleton(sk, V)
    n = V.shape[0]
    Vt, Tt = tets
    Vt = np.asarray(Vt, dtype=float)
    if Vt.ndim != 2 or Vt.shape[0] < n or Vt.shape[1] != V.shape[1] \
            or not (Vt[:n] == V).all():
        raise ValueError(f"tets: expected tetrahedra whose first {n} vertices are the "
                         f"surface's, in order; got {Vt.shape[0]} vertices"
                         + ("" if Vt.ndim != 2 or Vt.shape[0] < n else
                            " starting with others"))
    first = "projection" if endpoint == "heat" else endpoint     # heat: on the surface
    full = build_rig(Vt, sk, T=Tt, bone=bone, endpoint=first, tol=tol, progress=progress)
    W, E = np.asarray(full.W)[:n], np.asarray(full.E)[:n]
    if endpoint == "heat":
        E = build_rig(V, sk, F=F, W=W, endpoint="heat", progress=progress).E
    volume = Volume.selection(full.V, full.T, np.arange(n)) if keep_volume else None
    return Rig(V=V, F=F, skeleton=sk, W=W, E=E, meta={"bone": bone, "endpoint": endpoint},
               volume=volume)


def _read_outline_rig(mesh: str, skeleton: str, run, *, bone, endpoint, tol, clip_skeleton,
                      threshold, invert, max_area, progress) -> Rig:
    from ..io import read_polygons, read_skeleton

    if bone != "bbw":
        raise ValueError(f"bone={bone!r} needs a 3D surface; an outline ({mesh!r}) is "
                         "rigged with bone='bbw'")
    if mesh.lower().endswith(IMAGE_EXTENSIONS):
        image = run("read image", read_image, mesh)
        sk = run("read skeleton", read_skeleton, skeleton, dim=2)
        try:
            return rig_from_picture(image, sk, threshold=threshold, invert=invert,
                                    endpoint=endpoint, max_area=max_area,
                                    clip_skeleton=clip_skeleton, tol=tol, progress=progress)
        except ValueError as exc:
            if str(exc).startswith("image: no shape found"):
                raise ValueError(f"{mesh!r}: " + str(exc)[len("image: "):]) from None
            raise
    polygons = run("read polygons", read_polygons, mesh)
    sk = run("read skeleton", read_skeleton, skeleton, dim=2)
    return rig_from_outline(polygons, sk, endpoint=endpoint, max_area=max_area,
                            clip_skeleton=clip_skeleton, tol=tol, progress=progress)


def rig_from_files(mesh, skeleton, *, bone: Literal["bbw", "heat"] = "bbw",
                   endpoint: Literal["bbw", "bbw-joints", "heat", "projection",
                                     "idw"] = "bbw",
                   tets: str = "auto", tet_size: float | None = None,
                   tol: float = DEFAULT_TOL, clip_skeleton: bool = False,
                   threshold: float = 0.5, invert: bool = False,
                   max_area: float | None = None, keep_volume: bool = False,
                   progress: Progress | None = None) -> Rig:
    """MESH and SKELETON files -> a rig, as ``stbs rig`` makes it.

    Parameters
    ----------
    mesh : str or os.PathLike
        A mesh (``.obj .off .ply .stl .mesh .msh .vtk``), or a 2D outline: a Triangle
        ``.poly`` file or a picture (:data:`IMAGE_EXTENSIONS`), rigged by
        :func:`rig_from_outline` or :func:`rig_from_picture`.
    skeleton : str or os.PathLike
        A ``.tgf`` or ``.bf`` skeleton in the mesh's coordinates (a picture's: pixels,
        y up).
    tets : {"auto", "winding", "conforming"} or str
        A mesher's name, or a tetrahedral mesh file (surface vertices first) that the
        bone weights are solved on (:func:`rig_from_mesh`).
    threshold, invert, max_area
        Picture and outline options (:func:`rig_from_picture`).
    bone, endpoint, tet_size, tol, clip_skeleton, keep_volume, progress
        As for :func:`rig_from_mesh`. ``progress`` also hears the reading stages.

    Returns
    -------
    Rig
        On the mesh's own vertices and faces in their order, or (an outline) on stbs's
        triangle mesh of it.
    """
    from ..io import read_mesh, read_skeleton

    run = _stages(progress)
    mesh = str(mesh)
    if mesh.lower().endswith(OUTLINE_EXTENSIONS):
        return _read_outline_rig(mesh, str(skeleton), run, bone=bone, endpoint=endpoint,
                                 tol=tol, clip_skeleton=clip_skeleton, threshold=threshold,
                                 invert=invert, max_area=max_area, progress=progress)
    m = run("read mesh", read_mesh, mesh)
    sk = run("read skeleton", read_skeleton, skeleton, dim=m.V.shape[1])
    if tets not in VOLUME_METHODS and m.T is None and (bone == "bbw"):
        tm = run("read tets", read_mesh, tets)
        if tm.T is None:
            raise ValueError(f"tets {tets!r}: expected tetrahedra, got a mesh without any")
        tets = (tm.V, tm.T)
    elif tets not in VOLUME_METHODS:
        tets = "auto"        # a tetrahedral MESH, or heat bone weights: no volume to read
    return rig_from_mesh(m.V, sk, F=m.F, T=m.T, bone=bone, endpoint=endpoint, tets=tets,
                         tet_size=tet_size, tol=tol, clip_skeleton=clip_skeleton,
                         keep_volume=keep_volume, progress=progress)
