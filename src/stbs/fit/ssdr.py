"""A mesh animation decomposed into stretchable, twistable bones (STBS-SSDR).

Smooth skinning decomposition (SSDR, Le & Deng 2012) fits rigid bones, sparse convex
bone weights and per-frame bone transforms to a mesh animation alone, with no
skeleton given. :func:`decompose` fits the STBS model instead (eq. 5,
``method="stbs-lbs"``): each bone also stretches along its rest segment and twists
about it, and each vertex has an endpoint weight per bone, so one bone can follow a
limb that lengthens or turns along its length where rigid bones need more bones.
``method="lbs"`` fits classic rigid-bone LBS the same way, for comparison.

The fit alternates, as SSDR does, over blocks of the least-squares error of all
frames, each block solved with the others held:

1. per bone, its rotation, posed start, stretch and twists in every frame (weighted
   Procrustes for the rigid part, then a linear solve for the stretch and a
   Gauss-Newton step for the twists, repeated);
2. per vertex, its bone weights (>= 0, summing to 1, at most ``max_influences``
   non-zero, pulled towards its mesh neighbours' average);
3. per vertex and bone, its endpoint weight (a 1D search on [0, 1]).

See ``docs/fitting.md``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from numbers import Integral, Real
from typing import Literal

import numpy as np

from .. import _checks
from ..pose import Pose
from ..skeleton import Skeleton
from . import _ssdr_init as init
from . import _ssdr_model as model
from ._ssdr_weights import fit_weights, neighbour_average

__all__ = ["decompose", "Decomposition", "METHODS", "frames_needed"]

#: The skinning methods :func:`decompose` can fit.
METHODS: tuple[str, ...] = ("stbs-lbs", "lbs")
#: Rounds of rigid clustering before the alternation starts.
CLUSTER_ROUNDS = 10
#: Weight of the pull of endpoint weights towards their projection values, relative
#: to a squared error of 1e-3 bounding-box diagonals in every frame.
ENDPOINT_PRIOR = 1.0

Progress = Callable[[str, int, int], None]


@dataclass(eq=False)
class Decomposition:
    """The result of :func:`decompose`: a rig of independent bones and one pose per frame.

    Attributes
    ----------
    skeleton : Skeleton
        b root bones (``P = -1`` for all), bone i from joint ``2i`` to ``2i + 1``.
    W : (n, b) float64
        Bone weights: >= 0, rows summing to 1, at most ``max_influences`` non-zero.
    E : (n, b) float64
        Endpoint weights in [0, 1] (projection values where ``W`` is 0; all projection
        values for ``method="lbs"``, which does not use them).
    poses : list of Pose
        One per frame.
    rest : (n, 3) float64
        The rest mesh.
    F : (f, 3) int64 or None
        Its triangles, when given.
    method : {"stbs-lbs", "lbs"}
        The skinning method the frames are reproduced with.
    rmse : float
        Root mean squared distance between the reproduced and the given vertex
        positions over all frames and vertices, ``sqrt(mean_f,v |p'_fv - y_fv|^2)``.
    rmse_percent : float
        ``100 * rmse / diagonal``.
    diagonal : float
        The diagonal of the rest mesh's axis-aligned bounding box.
    history : list of float
        ``rmse`` after the starting point and after each iteration, as the fit saw it.
    """

    skeleton: Skeleton
    W: np.ndarray
    E: np.ndarray
    poses: list
    rest: np.ndarray
    F: np.ndarray | None
    method: str
    rmse: float
    rmse_percent: float
    diagonal: float
    history: list = field(default_factory=list)

    def frames(self) -> np.ndarray:
        """(F, n, 3) every frame as :func:`stbs.deform` reproduces it from the rig."""
        from ..skinning import Deformer

        dfm = Deformer(self.rest, self.skeleton, self.W,
                       self.E if self.method.startswith("stbs") else None,
                       method=self.method, dtype=np.float64)
        return np.stack([dfm(p) for p in self.poses])

    def rig(self):
        """A :class:`stbs.Rig` of the rest mesh, skeleton, ``W`` and ``E``."""
        from ..rig import Rig

        return Rig(V=self.rest, W=self.W, skeleton=self.skeleton, F=self.F, E=self.E,
                   meta={"fitted": "stbs.fit.decompose", "method": self.method,
                         "rmse": self.rmse})

    def __repr__(self) -> str:
        return (f"Decomposition({self.skeleton.n_bones} bones, {len(self.poses)} frames, "
                f"{self.rest.shape[0]} vertices, {self.method}, "
                f"rmse {self.rmse_percent:.3f} % of the diagonal)")


# --------------------------------------------------------------------------- checks
def frames_needed(max_influences: int, method: str) -> int:
    """Frames needed so that each vertex's unknowns are determined: 3 coordinates per
    frame against ``k - 1`` free bone weights (``k = max_influences``), plus ``k``
    endpoint weights for ``"stbs-lbs"``; at least 1."""
    unknowns = (max_influences - 1) + (max_influences if method.startswith("stbs") else 0)
    return max(1, -(-unknowns // 3))


def _count(name: str, value, low: int) -> int:
    if isinstance(value, bool) or not isinstance(value, Integral):
        raise TypeError(f"{name} must be an integer, got {type(value).__name__}")
    if value < low:
        raise ValueError(f"{name} must be >= {low}, got {value}")
    return int(value)


def _inputs(rest, frames, n_bones, F, max_influences, iterations, method, smoothness):
    """Everything checked; returns ``X`` (n, 3), ``Y`` (F, n, 3) float64 and ``F``."""
    method = _checks.choice("method", method, METHODS)
    n_bones = _count("n_bones", n_bones, 1)
    k = _count("max_influences", max_influences, 1)
    _count("iterations", iterations, 0)
    if isinstance(smoothness, bool) or not isinstance(smoothness, Real) \
            or not np.isfinite(smoothness) or smoothness < 0:
        raise ValueError(f"smoothness must be a finite number >= 0, got {smoothness!r}")
    X = _checks.vertices(rest, name="rest")
    n = X.shape[0]
    if X.shape[1] != 3:
        raise ValueError(f"rest must have shape (n, 3) (a 3D mesh), got {X.shape}")
    shape = np.shape(frames)
    if len(shape) != 3 or shape[1:] != (n, 3):
        raise ValueError(f"frames must have shape (frames, {n}, 3) to match rest {X.shape}, "
                         f"got {shape}")
    Y = _checks.real_array("frames", frames, ndim=3)
    need = frames_needed(min(k, n_bones), method)
    if Y.shape[0] < need:
        raise ValueError(f"frames: {method} with max_influences={min(k, n_bones)} needs at "
                         f"least {need} frames (3 coordinates per frame must determine each "
                         f"vertex's weights), got {Y.shape[0]}")
    if n_bones * init.MIN_CLUSTER > n:
        raise ValueError(f"n_bones must be at most {n // init.MIN_CLUSTER} for {n} vertices "
                         f"(each bone needs {init.MIN_CLUSTER} vertices to fix its rotation), "
                         f"got {n_bones}")
    if F is not None:
        F = _checks.index_array("F", F, ndim=2, shape=(None, 3))
        if F.size and (F.min() < 0 or F.max() >= n):
            bad = int(F.min()) if F.min() < 0 else int(F.max())
            raise ValueError(f"F must hold vertex indices in 0..{n - 1}, got {bad}")
    return X, Y, F, method, n_bones, k


# --------------------------------------------------------------------------- fit
def decompose(rest, frames, n_bones: int, *, F=None, max_influences: int = 4,
              iterations: int = 20, method: Literal["stbs-lbs", "lbs"] = "stbs-lbs",
              smoothness: float = 1e-4, seed: int = 0,
              progress: Progress | None = None) -> Decomposition:
    """Fit bones, weights and per-frame poses to a mesh animation.

    Parameters
    ----------
    rest : (n, 3) float
        The rest mesh's vertex positions.
    frames : (F, n, 3) float
        The animation: the same vertices in every frame.
    n_bones : int
        Number of bones b to fit (at most n / 3).
    F : (f, 3) int, optional
        The mesh's triangles; when given, each vertex's weights are pulled towards its
        neighbours' average (``smoothness``) and the rig keeps them.
    max_influences : int
        Most bones per vertex (non-zero entries of a row of ``W``).
    iterations : int
        Rounds of the alternation (bone transforms, weights, endpoint weights) after
        the rigid start; for ``"stbs-lbs"`` the first quarter keep the bones rigid.
    method : {"stbs-lbs", "lbs"}
        ``"stbs-lbs"`` (eq. 5): stretchable, twistable bones with endpoint weights;
        ``"lbs"``: rigid bones (classic SSDR).
    smoothness : float
        Pull of each vertex's weights towards its neighbours' average, relative to a
        squared error of one bounding-box diagonal per frame (0: none; needs ``F``).
    seed : int
        Seeds the clustering; the same inputs and seed give the same result.
    progress : callable, optional
        ``progress(stage, done, total)``: each stage (``"cluster"``, ``"fit"``) starts
        with ``(stage, 0, 0)``, then reports ``done`` of ``total`` rounds. Raise any
        exception from it to cancel; it propagates.

    Returns
    -------
    Decomposition
        ``skeleton``, ``W``, ``E``, ``poses``; ``stbs.deform(rest, d.skeleton,
        d.poses[f], d.W, d.E, method=d.method)`` reproduces frame f.

    Raises
    ------
    ValueError
        ``frames`` not (F, n, 3) for an (n, 3) ``rest``, non-finite values, fewer frames
        than :func:`frames_needed`, ``n_bones`` < 1 or over n / 3, an unknown
        ``method``, a negative ``smoothness`` or ``F`` out of range.
    TypeError
        A count that is not an integer, or a ``progress`` that is not callable.

    Examples
    --------
    >>> import numpy as np
    >>> from stbs.fit import decompose
    >>> rng = np.random.default_rng(0)
    >>> rest = rng.normal(size=(60, 3))
    >>> frames = np.stack([rest + [t, 0, 0] for t in range(4)])   # a translation
    >>> d = decompose(rest, frames, 1, iterations=2)
    >>> d.rmse < 1e-9
    True
    """
    _checks.progress(progress, "progress(stage, done, total)")
    X, Y, F, method, b, k = _inputs(rest, frames, n_bones, F, max_influences, iterations,
                                    method, smoothness)
    say = progress or (lambda stage, done, total: None)
    rng = np.random.default_rng(seed)
    diag = float(np.linalg.norm(X.max(axis=0) - X.min(axis=0)))
    scale = diag if diag > 0 else 1.0
    Fn, n = Y.shape[0], X.shape[0]
    stbs = method.startswith("stbs")

    say("cluster", 0, 0)
    bones, st = init.start(X, Y, b, rng, rounds=CLUSTER_ROUNDS, diag=scale,
                           report=lambda d, t: say("cluster", d, t))
    E0 = st.E.copy()
    st.P = model.reconstruct(X, bones, st)
    avg = neighbour_average(F, n)
    lam_w = float(smoothness) * Fn * scale ** 2
    lam_e = ENDPOINT_PRIOR * Fn * (1e-3 * scale) ** 2
    rigid_rounds = iterations // 4 if stbs else iterations
    history = [np.sqrt(model.sq_error(st.P, Y) / (Fn * n))]

    say("fit", 0, 0)
    for it in range(iterations):
        say("fit", it, iterations)
        free = stbs and it >= rigid_rounds
        fit_weights(X, Y, bones, st, k=min(k, b), avg=avg, lam=lam_w)
        st.P = model.reconstruct(X, bones, st)
        for i in range(b):
            model.fit_bone(X, Y, bones, i, st, stbs=free)
        if free:
            for i in range(b):
                model.fit_endpoints(X, Y, bones, i, st, E0, lam_e)
        history.append(np.sqrt(model.sq_error(st.P, Y) / (Fn * n)))
    say("fit", iterations, iterations)
    return _result(X, Y, F, bones, st, method, diag, history)


def _result(X, Y, F, bones, st, method, diag, history) -> Decomposition:
    b = st.W.shape[1]
    C = np.empty((2 * b, 3))
    C[0::2], C[1::2] = bones.a, bones.ends
    sk = Skeleton(C, np.arange(2 * b).reshape(b, 2), P=np.full(b, -1))
    poses = [Pose(sk, rotations=st.R[f], origins=st.O[f], stretch=st.sig[f], twist=st.th[f])
             for f in range(Y.shape[0])]
    W = st.W / st.W.sum(axis=1, keepdims=True)
    d = Decomposition(skeleton=sk, W=W, E=np.clip(st.E, 0.0, 1.0), poses=poses, rest=X, F=F,
                      method=method, rmse=0.0, rmse_percent=0.0, diagonal=diag,
                      history=[float(h) for h in history])
    U = d.frames()
    d.rmse = float(np.sqrt(np.einsum("fni,fni->", U - Y, U - Y) / (Y.shape[0] * Y.shape[1])))
    d.rmse_percent = 100.0 * d.rmse / diag if diag > 0 else 0.0
    return d
