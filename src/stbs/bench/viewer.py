"""Frame time of the viewer's page in a headless browser (``stbs bench --viewer``).

For each vertex count the benchmark builds a synthetic 3D rig (:func:`tube_rig`: a
tube around a straight chain of 20 bones, four bone weights per vertex,
endpoint weights from the position along each bone; no BBW, so 1M vertices build in
seconds), serves it with :class:`stbs.viewer.ViewerServer` (the page and assets as
shipped) and opens the page in Chromium through Playwright. It sets a pose with a
rotation and a stretch on every bone and twists on some (:func:`bench_pose`), then
times each method with ``stbsViewer.timeFrames``: each frame packs the pose into the
bone texture and uploads it, skins and shades the mesh in the vertex and fragment
shaders and waits for the GPU (a 1-pixel ``readPixels``). After :data:`WARMUP`
untimed frames per method, a method's frames are split into up to :data:`ROUNDS`
rounds, each round visiting every method (and the peer) in turn, so that a change of
the machine's load during the run falls on all of them alike; the figure is the
median of the rounds' median milliseconds per frame.

The peer, ``three-lbs``, is three.js's own ``SkinnedMesh`` (plain linear blend
skinning in three's shader, Phong shading) on the same mesh with the same top-4 bone
indices and weights, on its own page (``static/three-lbs.html``) in the same canvas
size and with the viewer's camera, open beside the viewer's page. Its bones carry the
same rotations and posed starts, but a three.js bone cannot stretch along its axis or
twist along it, so the peer draws the pose without stretch and twist. It is timed the
same way, in the same rounds: pose to bone matrices (three's bone texture upload),
render, 1-pixel ``readPixels``.

Beside the frame times it measures two latencies on the viewer's page: a paint dab
(one mouse stroke of bone-weight painting along the posed chain; each dab timed in the
page: the brush's vertex query, the W/E update, the changed rows' four-heaviest layout
and their upload to the GPU) and a seek (``stbsViewer.seek`` in a :data:`SEEK_KEYS`-key
clip, :func:`seek_clip`), medians; and it gives stbs-dqs's frame time as a ratio of the
peer's at each size both ran.

The canvas is :data:`CANVAS` CSS pixels at a device pixel ratio of 1 for every run.
By default Chromium renders with SwiftShader (``--use-angle=swiftshader``): WebGL on
the CPU, so the figures are those of software rendering; ``--gpu`` starts it with
the machine's GPU instead, and the report names the WebGL renderer either way.

Needs ``playwright`` (the ``bench`` extra) and a Chromium (``/usr/bin/chromium``,
``--browser`` or the ``STBS_CHROMIUM`` environment variable); it never downloads a
browser. Nothing here touches the network: the page talks to 127.0.0.1 only.
Docs: ``docs/benchmarks.md``.
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from .._optional import OptionalDependencyError, missing
from ..rig import Rig
from ..skeleton import Skeleton
from ..skinning import METHODS
from .report import (
    check_json_path,
    cpu_model,
    load_average,
    machine_lines,
    platform_name,
    positive_int,
    quiet,
    write_json,
)
from .skinning import _choice_list, _parse_sizes

__all__ = ["PEER", "VIEWER_METHODS", "DEFAULT_SIZES", "CANVAS", "WARMUP", "ROUNDS", "BONES",
           "SWIFTSHADER_ARGS", "GPU_ARGS", "BUNDLES", "default_browser", "check_browser",
           "check_bundles", "canvas_only", "tube_rig", "bench_pose", "seek_clip", "SEEK_KEYS",
           "SEEKS",
           "auto_frames", "ViewerBench", "run_bench", "format_table", "add_arguments",
           "requires", "collect", "run", "main"]

#: The peer's method name: three.js's SkinnedMesh.
PEER = "three-lbs"
#: What ``--methods`` may name: the four methods and the peer.
VIEWER_METHODS: tuple[str, ...] = tuple(METHODS) + (PEER,)
DEFAULT_SIZES: tuple[int, ...] = (10_000, 100_000, 1_000_000)
#: The canvas of every run, CSS pixels (width, height), at a device pixel ratio of 1.
CANVAS: tuple[int, int] = (1280, 720)
#: Untimed frames before the timed ones, per method.
WARMUP = 2
#: The timed frames of a method are split into up to this many rounds over the methods.
ROUNDS = 5
#: The pages' scripts (in the viewer's static folder), built from ``viewer/``.
BUNDLES: tuple[str, ...] = ("viewer.js", "three-lbs.js")
#: Bones in the tube's chain.
BONES = 20
#: Chromium's options by default: WebGL2 through ANGLE on SwiftShader (the CPU).
SWIFTSHADER_ARGS: tuple[str, ...] = ("--use-angle=swiftshader", "--enable-unsafe-swiftshader",
                                     "--headless=new", "--disable-dev-shm-usage")
#: Chromium's options with ``--gpu``: the machine's GPU, the blocklist ignored.
GPU_ARGS: tuple[str, ...] = ("--headless=new", "--ignore-gpu-blocklist", "--enable-gpu",
                             "--disable-dev-shm-usage")

Log = Callable[[str], None]

_TUBE_LENGTH = 10.0
_TUBE_RADIUS = 0.35


def default_browser() -> str:
    """The Chromium to run: ``$STBS_CHROMIUM``, else ``/usr/bin/chromium``."""
    return os.environ.get("STBS_CHROMIUM") or "/usr/bin/chromium"


# --------------------------------------------------------------------------- rig and pose
def tube_rig(n: int, *, bones: int = BONES, seed: int = 0) -> Rig:
    """A tube (open at both ends) of exactly ``n`` vertices around a straight chain along x.

    The tube has length 10 and radius 0.35; rings of ``s`` vertices (``s`` about
    ``sqrt(n / 4.5)``, at least 8) are spaced along x so that the quads are roughly
    square, and the last ring is cut short to give ``n`` vertices (faces that would
    use a missing vertex are left out). Vertex positions are jittered by 1% of the
    ring spacing, seeded by ``seed``, so every run builds the same rig.

    Weights, without BBW: bone i spans ``[i l, (i+1) l]`` on x (``l = 10 / bones``);
    a vertex at distance ``d_i`` (along x) from bone i gets ``exp(-(d_i / l)^2)`` on
    its 4 nearest bones, normalised; its endpoint weight on bone i is its position
    along that bone, ``clip((x - i l) / l, 0, 1)`` (the projection weights, eq. 8).

    Parameters
    ----------
    n : int
        Vertices, >= 32.
    bones : int, keyword-only
        Bones in the chain, >= 4.
    seed : int, keyword-only

    Returns
    -------
    Rig
        3D, with ``F`` (f, 3), ``W`` and ``E`` (n, bones) CSR with 4 entries a row.
    """
    n, bones = int(n), int(bones)
    if n < 32:
        raise ValueError(f"n: expected a vertex count >= 32, got {n}")
    if bones < 4:
        raise ValueError(f"bones: expected >= 4 (four weights a vertex), got {bones}")
    seg = max(8, round(math.sqrt(n / 4.5)))
    rings = -(-n // seg)
    x = np.linspace(-0.2, _TUBE_LENGTH + 0.2, rings)
    t = 2 * np.pi * np.arange(seg) / seg
    V = np.empty((rings * seg, 3))
    V[:, 0] = np.repeat(x, seg)
    V[:, 1] = np.tile(_TUBE_RADIUS * np.cos(t), rings)
    V[:, 2] = np.tile(_TUBE_RADIUS * np.sin(t), rings)
    V = V[:n]
    rng = np.random.default_rng([seed, 2])
    V += 0.01 * (x[1] - x[0]) * rng.standard_normal(V.shape)

    i = np.arange(rings - 1)[:, None] * seg
    j = np.arange(seg)[None, :]
    p, q = (i + j).ravel(), (i + (j + 1) % seg).ravel()
    F = np.concatenate([np.stack([p, q, q + seg], 1), np.stack([p, q + seg, p + seg], 1)])
    F = F[(F < n).all(axis=1)]

    length = _TUBE_LENGTH / bones
    C = np.zeros((bones + 1, 3))
    C[:, 0] = np.linspace(0.0, _TUBE_LENGTH, bones + 1)
    sk = Skeleton(C, np.column_stack([np.arange(bones), np.arange(1, bones + 1)]),
                  names=[f"b{k}" for k in range(bones)])
    # distance along x to each bone, in chunks so that 1M vertices stay small in memory
    k = 4
    idx = np.empty((n, k), dtype=np.int64)
    w = np.empty((n, k))
    e = np.empty((n, k))
    starts = np.arange(bones) * length
    for lo in range(0, n, 250_000):
        xs = V[lo:lo + 250_000, 0:1]
        d = np.maximum(0.0, np.maximum(starts - xs, xs - (starts + length)))
        near = np.argsort(d, axis=1, kind="stable")[:, :k]
        dn = np.take_along_axis(d, near, axis=1)
        wk = np.exp(-(dn / length) ** 2)
        idx[lo:lo + len(xs)] = near
        w[lo:lo + len(xs)] = wk / wk.sum(axis=1, keepdims=True)
        e[lo:lo + len(xs)] = np.clip((xs - starts[near]) / length, 0.0, 1.0)
    # canonical CSR (columns sorted in each row), each matrix with its own index arrays
    order = np.argsort(idx, axis=1)
    idx, w, e = (np.take_along_axis(a, order, axis=1) for a in (idx, w, e))
    indptr = np.arange(0, n * k + 1, k, dtype=np.int64)
    W = sp.csr_array((w.ravel(), idx.ravel(), indptr), shape=(n, bones))
    E = sp.csr_array((e.ravel(), idx.ravel().copy(), indptr.copy()), shape=(n, bones))
    return Rig(V=V, F=F, skeleton=sk, W=W, E=E,
               meta={"made_by": "stbs.bench.viewer.tube_rig", "vertices": n})


def bench_pose(bones: int = BONES, *, stretch: bool = True, twist: bool = True,
               seed: int = 0) -> dict:
    """The pose the benchmark draws, as a forward-kinematics pose object (see stbs.io.read_pose).

    Every bone is rotated by 8..20 degrees about a random axis; with ``stretch`` each
    is stretched by 0.8..1.25; with ``twist`` every third bone is twisted by -90..90
    degrees at its end. ``stretch=False, twist=False`` gives the rotation-only pose
    that the three-lbs peer can draw exactly.
    """
    rng = np.random.default_rng([seed, 3])
    keys = [str(i) for i in range(int(bones))]
    axes = rng.standard_normal((len(keys), 3))
    angles = rng.uniform(8, 20, len(keys)) * rng.choice([-1, 1], len(keys))
    pose: dict = {"degrees": True,
                  "rotate": {k: {"axis": a.tolist(), "angle": float(g)}
                             for k, a, g in zip(keys, axes, angles, strict=True)}}
    sig = rng.uniform(0.8, 1.25, len(keys))
    tw = rng.uniform(-90, 90, len(keys))
    if stretch:
        pose["stretch"] = {k: float(s) for k, s in zip(keys, sig, strict=True)}
    if twist:
        pose["twist"] = {k: [0.0, float(tw[i])] for i, k in enumerate(keys) if i % 3 == 1}
    return pose


def auto_frames(n: int) -> int:
    """Timed frames for ``n`` vertices when none are given: 3e6 / n, within 3..60."""
    return int(min(60, max(3, 3e6 // max(int(n), 1))))


# --------------------------------------------------------------------------- the browser
_READY = """s => Promise.race([window.{api}.ready, new Promise((_, no) => setTimeout(
    () => no(new Error(`not ready after ${{s}} s`)), s * 1000))])"""
_RENDERER = """() => {
  const gl = document.createElement("canvas").getContext("webgl2");
  if (!gl) return "no WebGL2";
  const ext = gl.getExtension("WEBGL_debug_renderer_info");
  return ext ? gl.getParameter(ext.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER);
}"""


class ViewerBench:
    """Chromium driven by Playwright, its pages in one browser context; a context manager.

    Parameters
    ----------
    browser : path, optional
        Chromium's executable (default :func:`default_browser`).
    args : sequence of str, optional
        Chromium's options (default :data:`SWIFTSHADER_ARGS`).
    canvas : (int, int)
        Viewport in CSS pixels, device pixel ratio 1.
    timeout_s : float
        The most a page may take to load its rig, and a frame count to draw.

    Raises
    ------
    OptionalDependencyError
        Playwright is not installed, the browser is not an executable file, or it
        does not start (one line).
    """

    def __init__(self, browser: str | os.PathLike | None = None,
                 args: Sequence[str] | None = None, *, canvas: tuple[int, int] = CANVAS,
                 timeout_s: float = 600.0):
        self.browser = str(browser or default_browser())
        self.args = list(SWIFTSHADER_ARGS if args is None else args)
        self.canvas = (int(canvas[0]), int(canvas[1]))
        self.timeout_s = float(timeout_s)
        check_browser(self.browser)
        self._pw = None
        self._browser = None
        self._context = None
        self.errors: list[str] = []

    def __enter__(self) -> ViewerBench:
        try:
            from playwright.sync_api import Error, sync_playwright
        except ImportError:
            raise OptionalDependencyError(missing(["playwright"], "stbs bench --viewer")
                                          or "stbs bench --viewer needs playwright") from None
        self._pw = sync_playwright().start()
        try:
            self._browser = self._pw.chromium.launch(executable_path=self.browser,
                                                     args=self.args, headless=True)
        except Error as exc:
            self._pw.stop()
            first = next((ln for ln in str(exc).splitlines() if ln.strip()), "")
            raise OptionalDependencyError(f"--browser {self.browser}: Chromium did not start "
                                          f"({first.strip()})") from None
        self._context = self._browser.new_context(
            viewport={"width": self.canvas[0], "height": self.canvas[1]},
            device_scale_factor=1)
        self._context.set_default_timeout(self.timeout_s * 1000)
        return self

    def __exit__(self, *exc) -> None:
        for x in (self._context, self._browser):
            if x is not None:
                try:
                    x.close()
                except Exception:       # noqa: BLE001 - closing after an error
                    pass
        if self._pw is not None:
            self._pw.stop()
        self._pw = self._browser = self._context = None

    @property
    def version(self) -> str:
        return self._browser.version if self._browser is not None else ""

    def open(self, url: str, api: str):
        """A new page at ``url``, waited on until ``window.<api>.ready`` resolves."""
        from playwright.sync_api import Error

        page = self._context.new_page()
        page.on("console", lambda m: m.type == "error" and self.errors.append(m.text))
        page.on("pageerror", lambda e: self.errors.append(str(e)))
        try:
            page.goto(url)
            page.wait_for_function(f"window.{api} !== undefined")
            page.evaluate(_READY.format(api=api), self.timeout_s)
        except Error as exc:
            page.close()
            where = url.split("?", 1)[0]
            first = next((ln for ln in str(exc).splitlines() if ln.strip()), "")
            raise OptionalDependencyError(f"{where}: the page did not start in Chromium "
                                          f"({first.strip()})") from None
        return page

    def renderer(self, page) -> str:
        """The WebGL renderer of ``page`` (e.g. SwiftShader's, or the GPU's)."""
        return str(page.evaluate(_RENDERER))


_CANVAS_ONLY = """() => {
  for (const el of document.body.children) if (el.id !== "view") el.style.display = "none";
  window.dispatchEvent(new Event("resize"));
  const r = document.getElementById("view").getBoundingClientRect();
  return [r.left, r.top, r.width, r.height];
}"""


def canvas_only(page, canvas: tuple[int, int]) -> None:
    """Hide the viewer page's panels so its canvas fills the page, as the peer's does:
    both then draw the same pixels. Raises RuntimeError if the canvas does not fill it."""
    box = page.evaluate(_CANVAS_ONLY)
    page.evaluate("stbsViewer.idle()")
    if [round(x) for x in box] != [0, 0, int(canvas[0]), int(canvas[1])]:
        raise RuntimeError(f"the viewer's canvas should fill the {canvas[0]}x{canvas[1]} "
                           f"page once its panels are hidden, got {box}")


def check_browser(path: str) -> None:
    """Raise :class:`OptionalDependencyError` unless ``path`` is an executable file."""
    p = Path(path)
    if not (p.is_file() and os.access(p, os.X_OK)):
        raise OptionalDependencyError(
            f"stbs bench --viewer needs Chromium: {path} is not an executable file (install "
            "it, e.g. apt-get install chromium, or give --browser PATH or STBS_CHROMIUM)")


def check_bundles(static_dir: str | os.PathLike | None = None) -> None:
    """Raise :class:`OptionalDependencyError` unless the viewer's page and the peer's
    are built (``viewer.js`` and ``three-lbs.js`` in ``static_dir``, default the
    package's static folder)."""
    from ..viewer import STATIC_DIR

    folder = Path(STATIC_DIR if static_dir is None else static_dir)
    lacking = [b for b in BUNDLES if not (folder / b).is_file()]
    if lacking:
        raise OptionalDependencyError(
            f"stbs bench --viewer needs the pages' scripts, but {', '.join(lacking)} "
            f"{'is' if len(lacking) == 1 else 'are'} not built in {folder} (in a source "
            "checkout: npm ci --prefix viewer && npm run --prefix viewer build)")


def _time(page, api: str, method: str, frames: int) -> float:
    page.bring_to_front()
    if api == "stbsViewer":
        page.evaluate("m => stbsViewer.setMethod(m)", method)
    ms = float(page.evaluate(f"k => window.{api}.timeFrames(k)", int(frames)))
    if not (math.isfinite(ms) and ms > 0):
        raise RuntimeError(f"{api}.timeFrames({frames}) gave {ms!r}, expected a time > 0 ms")
    return ms


def _rounds(pages: dict, methods: Sequence[str], count: int) -> dict[str, float]:
    """ms per frame of each method: ``count`` frames split into up to :data:`ROUNDS`
    rounds that visit every method in turn (forwards, then backwards), so that a change
    in the machine's load while the benchmark runs falls on every method alike; the
    median of the rounds' medians, after :data:`WARMUP` untimed frames per method."""
    def api(m: str) -> str:
        return "stbsThreeLbs" if m == PEER else "stbsViewer"

    for m in methods:
        _time(pages[api(m)], api(m), m, WARMUP)
    r = min(int(count), ROUNDS)
    chunks = [count // r + (1 if i < count % r else 0) for i in range(r)]
    got: dict[str, list[float]] = {m: [] for m in methods}
    for i, k in enumerate(chunks):
        for m in (methods if i % 2 == 0 else methods[::-1]):
            got[m].append(_time(pages[api(m)], api(m), m, k))
    return {m: float(statistics.median(v)) for m, v in got.items()}


def run_bench(sizes: Sequence[int] = DEFAULT_SIZES,
              methods: Sequence[str] = VIEWER_METHODS, frames: int | None = None, *,
              bench: ViewerBench, seed: int = 0, log: Log = quiet) -> tuple[list[dict], dict]:
    """Time the page's methods and the three-lbs peer for each vertex count.

    Parameters
    ----------
    sizes : sequence of int
        Vertex counts (each >= 32).
    methods : sequence of str
        Among :data:`VIEWER_METHODS`.
    frames : int, optional
        Timed frames per method after :data:`WARMUP`; default :func:`auto_frames`.
    bench : ViewerBench, keyword-only
        An entered :class:`ViewerBench`.
    seed : int, keyword-only
        Rig and pose seed.
    log : callable, keyword-only

    Returns
    -------
    rows : list of dict
        ``{"vertices": n, "method": m, "ms_per_frame": t}`` per size and method, in the
        order given (docs/viewer.md).
    meta : dict
        ``renderer`` (WebGL's), ``browser`` (version), ``canvas`` [w, h], ``frames``
        {size: timed frames per method}, ``rounds`` {size: rounds}, ``three`` (three.js
        revision), ``warmup``.
    """
    sizes, methods = _check(sizes, methods, frames)
    from ..viewer import ViewerServer

    rows: list[dict] = []
    meta: dict = {"renderer": None, "browser": bench.version, "canvas": list(bench.canvas),
                  "frames": {}, "rounds": {}, "three": None, "warmup": WARMUP, "latency": {}}
    for n in sizes:
        count = int(frames) if frames is not None else auto_frames(n)
        meta["frames"][str(n)] = count
        meta["rounds"][str(n)] = min(count, ROUNDS)
        log(f"{n:,} vertices: building the rig")
        rig = tube_rig(n, seed=seed)
        with ViewerServer(rig, name=f"tube-{n}") as srv:
            log(f"{n:,} vertices: loading the pages")
            pages: dict[str, object] = {}
            try:
                viewer = pages["stbsViewer"] = bench.open(srv.url, "stbsViewer")
                canvas_only(viewer, bench.canvas)
                if meta["renderer"] is None:
                    meta["renderer"] = bench.renderer(viewer)
                viewer.evaluate("p => stbsViewer.setPose(p)", bench_pose(seed=seed))
                if PEER in methods:
                    cam = viewer.evaluate("stbsViewer.camera()")
                    peer = pages["stbsThreeLbs"] = bench.open(
                        f"http://127.0.0.1:{srv.port}/static/three-lbs.html?token={srv.token}",
                        "stbsThreeLbs")
                    meta["three"] = peer.evaluate("stbsThreeLbs.info()").get("three")
                    peer.evaluate("c => stbsThreeLbs.setCamera(c)", cam)
                log(f"{n:,} vertices: {', '.join(methods)}, {count} frames each in "
                    f"{min(count, ROUNDS)} rounds")
                times = _rounds(pages, methods, count)
                log(f"{n:,} vertices: paint dabs and seeks")
                meta["latency"][str(n)] = _latency(viewer, seed=seed)
            finally:
                for page in pages.values():
                    page.close()
        rows += [{"vertices": n, "method": m, "ms_per_frame": times[m]} for m in methods]
    return rows, meta


#: Keys of the clip the seek latency is measured in.
SEEK_KEYS = 1000
#: Seeks timed per size.
SEEKS = 40


def seek_clip(bones: int = BONES, keys: int = SEEK_KEYS, *, seed: int = 0) -> dict:
    """A clip of ``keys`` keyed poses, 30 keys a second, every bone turning a little
    about its own random axis from key to key (the clip ``stbs bench --viewer`` seeks in)."""
    rng = np.random.default_rng([seed, 5])
    axes = rng.standard_normal((int(bones), 3))
    phase = rng.uniform(0, 2 * np.pi, int(bones))
    out = []
    for k in range(int(keys)):
        ang = 25 * np.sin(0.05 * k + phase)
        rotate = {str(i): {"axis": axes[i].tolist(), "angle": float(ang[i])}
                  for i in range(int(bones))}
        out.append({"time": k / 30, "pose": {"degrees": True, "rotate": rotate}})
    return {"fps": 30, "interpolation": "linear", "keys": out}


_DABS = """async () => {
  const s = await stbsViewer.lastStroke();
  return s ? s.dabs.map(d => [d.ms, d.covered]) : [];
}"""
_SEEKS = """async ([count, end]) => {
  const times = [];
  for (let k = 0; k < count; k++) {
    const t = end * ((k * 0.618034) % 1);
    const t0 = performance.now();
    await stbsViewer.seek(t);
    times.push(performance.now() - t0);
  }
  return times;
}"""


def _latency(page, *, seed: int = 0) -> dict:
    """Paint-dab and seek latency on the viewer's page (ms, medians).

    Dabs: bone-weight painting with the page's default brush (radius 8% of the
    diagonal), one mouse stroke along the posed chain's joints on the page; each dab's
    time is measured in the page (the brush's query, the W/E update, the layout of the
    changed rows and their upload to the GPU; not the drawing, which follows once a
    frame). Seeks: ``stbsViewer.seek(t)`` in a :data:`SEEK_KEYS`-key clip, each until
    the pose is shown, at :data:`SEEKS` times spread over the clip.
    """
    page.bring_to_front()
    page.evaluate("stbsViewer.setPaint({mode: 'bone', bone: 10, op: 'add', strength: 0.1})")
    J = page.evaluate("stbsViewer.jointScreenPositions()")
    m = page.mouse
    m.move(*J[1])
    m.down()
    for x, y in J[2:-1]:
        m.move(x, y, steps=8)
    m.up()
    dabs = page.evaluate(_DABS)
    page.evaluate("stbsViewer.paintUndo()")
    page.evaluate("stbsViewer.setPaint({mode: 'off'})")
    clip = seek_clip(len(J) - 1, seed=seed)
    page.evaluate("c => stbsViewer.setClip(c)", clip)
    seeks = page.evaluate(_SEEKS, [SEEKS, clip["keys"][-1]["time"]])
    page.evaluate("stbsViewer.clearKeys()")
    if not dabs:
        raise RuntimeError("the paint stroke made no dab (the brush found no mesh under the "
                           "pointer)")
    return {"dab_ms": float(statistics.median(d[0] for d in dabs)), "dabs": len(dabs),
            "dab_vertices": int(statistics.median(d[1] for d in dabs)),
            "seek_ms": float(statistics.median(seeks)), "seeks": len(seeks)}


def _check(sizes, methods, frames) -> tuple[tuple[int, ...], tuple[str, ...]]:
    sizes = tuple(int(s) for s in sizes)
    if not sizes or min(sizes) < 32:
        raise ValueError(f"sizes: expected vertex counts >= 32, got {list(sizes)}")
    methods = tuple(methods)
    bad = [m for m in methods if m not in VIEWER_METHODS]
    if bad or not methods:
        raise ValueError(f"methods must be among {', '.join(VIEWER_METHODS)}, got "
                         f"{bad or list(methods)}")
    if frames is not None and int(frames) < 1:
        raise ValueError(f"frames: expected a whole number >= 1, got {frames}")
    return sizes, methods


# --------------------------------------------------------------------------- report
def format_table(rows: Sequence[dict], meta: dict, machine: dict | None = None) -> str:
    """The report: the renderer and canvas, then ms/frame, fps and the ratio to three-lbs."""
    lines = machine_lines(machine, f"Chromium {meta.get('browser')}, three.js r"
                          f"{meta.get('three') or '-'}", "frame times") if machine else []
    end = (machine or {}).get("load_average_end")
    if end:
        lines.append(f"load average at the end: {end[0]:.2f} {end[1]:.2f} {end[2]:.2f}")
    w, h = meta.get("canvas", CANVAS)
    lines.append(f"WebGL renderer: {meta.get('renderer')}; canvas {w}x{h} at device pixel "
                 "ratio 1")
    lines.append("pose: a rotation and a stretch on every bone, twists on every third "
                 f"({PEER}: the same rotations, no stretch or twist: three.js bones have none)")
    lines.append(f"ms/frame: after {meta.get('warmup', WARMUP)} warm-up frames, the median "
                 "of the medians of rounds that visit every method in turn; a frame packs "
                 "and uploads the pose, skins, shades and waits for the GPU (1-pixel "
                 "readPixels)")
    lines.append("")
    head = (f"{'vertices':>10}  {'method':<10} {'ms/frame':>9} {'fps':>7} {'x ' + PEER:>12} "
            f"{'frames':>6}")
    lines += [head, "-" * len(head)]
    peer = {r["vertices"]: r["ms_per_frame"] for r in rows if r["method"] == PEER}
    last = None
    for r in rows:
        n, ms = r["vertices"], r["ms_per_frame"]
        if last is not None and n != last:
            lines.append("")
        last = n
        ratio = f"{ms / peer[n]:12.2f}" if n in peer else f"{'-':>12}"
        frames = meta.get("frames", {}).get(str(n), "-")
        lines.append(f"{n:>10,}  {r['method']:<10} {ms:9.2f} {1000 / ms:7.1f} {ratio} "
                     f"{frames!s:>6}")
    for n in sorted(peer):
        sd = next((r["ms_per_frame"] for r in rows
                   if r["vertices"] == n and r["method"] == "stbs-dqs"), None)
        if sd is not None:
            lines.append(f"\nstbs-dqs (stretch and twist) at {n:,} vertices: "
                         f"{sd / peer[n]:.2f}x {PEER}'s frame time")
    latency = meta.get("latency") or {}
    if latency:
        lines += ["", "latency: a paint dab (median of one stroke's dabs: the brush, the W/E "
                  "update, the changed rows' layout and upload; bone weights, radius 8% of the "
                  f"diagonal) and a seek (median of stbsViewer.seek in a {SEEK_KEYS}-key clip, "
                  "until the pose is shown)", ""]
        head = (f"{'vertices':>10}  {'dab ms':>8} {'dabs':>5} {'vertices/dab':>12}  "
                f"{'seek ms':>8} {'seeks':>5}")
        lines += [head, "-" * len(head)]
        for n, d in sorted(latency.items(), key=lambda kv: int(kv[0])):
            lines.append(f"{int(n):>10,}  {d['dab_ms']:8.2f} {d['dabs']:>5} "
                         f"{d['dab_vertices']:>12,}  {d['seek_ms']:8.2f} {d['seeks']:>5}")
    return "\n".join(lines)


# --------------------------------------------------------------------------- command line
def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add ``stbs bench --viewer``'s options to ``parser``."""
    parser.add_argument("--viewer", action="store_true", required=True,
                        help="time the viewer's page in a headless browser (this benchmark)")
    parser.add_argument("--sizes", type=_parse_sizes, default=DEFAULT_SIZES,
                        help="vertex counts, k and M suffixes allowed (default 10k,100k,1M)")
    parser.add_argument("--methods", type=_choice_list("methods", VIEWER_METHODS),
                        default=VIEWER_METHODS,
                        help="methods to time: lbs,dqs,stbs-lbs,stbs-dqs and the peer "
                             "three-lbs (default all five)")
    parser.add_argument("--frames", type=positive_int, default=None,
                        help=f"timed frames per method after {WARMUP} warm-up frames "
                             "(default 3..60 by size)")
    parser.add_argument("--seed", type=int, default=0, help="rig and pose seed (default 0)")
    parser.add_argument("--browser", metavar="PATH", default=None,
                        help="Chromium's executable (default $STBS_CHROMIUM, else "
                             "/usr/bin/chromium)")
    parser.add_argument("--gpu", action="store_true",
                        help="render with the machine's GPU instead of SwiftShader "
                             f"(Chromium options: {' '.join(GPU_ARGS)})")
    parser.add_argument("--browser-arg", metavar="ARG", action="append", default=[],
                        help="one more Chromium option (repeat for more), after the "
                             "default or --gpu ones")
    parser.add_argument("--timeout", type=positive_int, default=600, metavar="S",
                        help="seconds a page may take to load or to draw its frames "
                             "(default 600)")
    parser.add_argument("--json", metavar="OUT.json", default=None,
                        help='also write {"viewer": [{"vertices", "method", '
                             '"ms_per_frame"}, ...], "latency": [{"vertices", "dab_ms", '
                             '"seek_ms", ...}, ...]} (to a temporary file, then renamed)')


def requires(args: argparse.Namespace) -> list[str]:
    """Optional modules this run needs: Playwright."""
    return ["playwright"]


def collect(args: argparse.Namespace, *, log: Log = quiet) -> tuple[dict, dict, dict]:
    """Run the benchmark for parsed ``args``: (JSON document, meta, machine)."""
    sizes, methods = _check(args.sizes, args.methods, args.frames)
    browser_args = list(GPU_ARGS if args.gpu else SWIFTSHADER_ARGS) + list(args.browser_arg)
    machine = {"cpu": cpu_model(), "cpus": os.cpu_count(), "platform": platform_name(),
               "load_average": load_average()}
    with ViewerBench(args.browser, browser_args, timeout_s=args.timeout) as bench:
        rows, meta = run_bench(sizes, methods, args.frames, bench=bench, seed=args.seed,
                               log=log)
        if bench.errors:
            log("page errors: " + "; ".join(bench.errors[:3]))
    machine["load_average_end"] = load_average()
    if args.gpu and "swiftshader" in str(meta.get("renderer")).lower():
        log("note: --gpu was given, but Chromium found no GPU it could use and rendered "
            "with SwiftShader (see the WebGL renderer line)")
    latency = [dict(vertices=int(n), **d) for n, d in meta.get("latency", {}).items()]
    return {"viewer": rows, "latency": latency}, meta, machine


def run(args: argparse.Namespace) -> int:
    """Run for parsed ``args``; print the table; write ``--json``; return 0.

    Raises
    ------
    ValueError
        An unusable ``--json`` path or bad sizes, before anything is timed.
    OptionalDependencyError
        Playwright or Chromium missing.
    """
    out = check_json_path(args.json)
    check_browser(args.browser or default_browser())
    check_bundles()

    def log(msg: str) -> None:
        print(f"stbs bench --viewer: {msg}", file=sys.stderr, flush=True)

    doc, meta, machine = collect(args, log=log)
    print(format_table(doc["viewer"], meta, machine))
    if out is not None:
        write_json(out, doc)
        log(f"wrote {out}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m stbs.bench --viewer [options]``: the same as ``stbs bench --viewer``;
    returns the exit status (2 and one line on stderr for a bad option or a missing
    Playwright or Chromium)."""
    p = argparse.ArgumentParser(prog="stbs bench --viewer", description=__doc__.splitlines()[0])
    add_arguments(p)
    args = p.parse_args(argv)
    try:
        advice = missing(requires(args), "stbs bench --viewer")
        if advice:
            raise OptionalDependencyError(advice)
        return run(args)
    except (ValueError, OptionalDependencyError) as exc:
        print(f"stbs bench --viewer: error: {exc}", file=sys.stderr)
        return 2
