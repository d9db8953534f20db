"""Progress callbacks: a callback that raises cancels the solve, promptly and for good."""

from __future__ import annotations

import importlib

import numpy as np
import pytest

import stbs
from stbs.weights import BBWSolver, boundary_conditions
from stbs.weights.qp import DualActiveSet


class Stop(Exception):
    """The caller's own reason to stop."""


def strip_chain(bones=6, nx=60):
    """A 2D strip nx/10 x 1 (spacing 0.1) with a chain of bones along its middle line."""
    ny = 10
    I, J = np.meshgrid(np.arange(nx + 1), np.arange(ny + 1), indexing="ij")
    V = np.c_[I.ravel(), J.ravel()] / 10.0
    idx = np.arange(V.shape[0]).reshape(nx + 1, ny + 1)
    a, b = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel()
    c, d = idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    F = np.r_[np.c_[a, b, c], np.c_[a, c, d]]
    x = np.linspace(0.5, nx / 10 - 0.5, bones + 1)
    C = np.c_[x, np.full_like(x, 0.5)]
    BE = np.c_[np.arange(bones), np.arange(1, bones + 1)]
    return V, F, stbs.Skeleton(C, BE)


def raising_at(k: int, calls: list):
    """A progress callback that records its calls and raises Stop at the k-th."""
    def progress(*args):
        calls.append(args)
        if len(calls) == k:
            raise Stop(f"stopped at call {k}")
    return progress


def _count_rounds(monkeypatch) -> list:
    """Count the rounds of the QP engine (one _columns call each)."""
    rounds = []
    orig = DualActiveSet._columns
    monkeypatch.setattr(DualActiveSet, "_columns",
                        lambda self, *a: rounds.append(1) or orig(self, *a))
    return rounds


@pytest.mark.parametrize("restrict", [False, True])
def test_a_raising_callback_stops_a_bbw_solve_at_once(monkeypatch, restrict):
    V, F, sk = strip_chain()
    b, bc = boundary_conditions(V, sk, F=F)
    rounds = _count_rounds(monkeypatch)
    full = []
    BBWSolver(V, F, threads=1).solve(b, bc, restrict=restrict,
                                     progress=lambda d, t: full.append((d, t)))
    full_rounds = len(rounds)
    assert full[-1] == (6, 6) and len(full) > 6     # a report per round, not only per bone
    rounds.clear()
    calls = []
    with pytest.raises(Stop, match="stopped at call 3"):
        BBWSolver(V, F, threads=1).solve(b, bc, restrict=restrict,
                                         progress=raising_at(3, calls))
    assert len(calls) == 3                           # never called after it raised
    assert len(rounds) < full_rounds / 2             # and the work stopped there


def test_a_raising_callback_stops_the_solver_threads(monkeypatch):
    from stbs.weights import _cholmod

    if _cholmod.library() is None:
        pytest.skip("parts are solved on threads only with CHOLMOD through ctypes")
    mod = importlib.import_module("stbs.weights.bbw")
    monkeypatch.setattr(mod, "_REGION_MAX", 0.5)    # every bone on a part of its own
    V, F, sk = strip_chain(bones=8, nx=80)
    b, bc = boundary_conditions(V, sk, F=F)
    rounds = _count_rounds(monkeypatch)
    BBWSolver(V, F, threads=4).solve(b, bc)
    full_rounds = len(rounds)
    rounds.clear()
    calls = []
    with pytest.raises(Stop):
        BBWSolver(V, F, threads=4).solve(b, bc, progress=raising_at(2, calls))
    assert len(calls) == 2
    assert len(rounds) < full_rounds


@pytest.mark.parametrize("workers", [1, 3])
@pytest.mark.parametrize("method", ["bbw", "bbw-joints"])
def test_a_raising_callback_stops_bbw_endpoint_weights(monkeypatch, workers, method):
    ep = importlib.import_module("stbs.weights.endpoint")
    monkeypatch.setattr(ep, "_bone_workers", lambda cls, b: min(workers, b))
    V, F, sk = strip_chain(bones=5)                # joints on vertices
    W = stbs.bone_weights(V, sk, F=F)
    solves = []
    orig = BBWSolver.solve
    monkeypatch.setattr(BBWSolver, "solve",
                        lambda self, *a, **kw: solves.append(1) or orig(self, *a, **kw))
    calls = []
    with pytest.raises(Stop, match="stopped at call 1"):
        stbs.endpoint_weights(V, sk, method=method, F=F, W=W, progress=raising_at(1, calls))
    assert calls == [(1, 5)]              # never called again, from any thread
    if workers == 1:
        assert len(solves) == 1            # one bone done, no other started


def test_a_raising_callback_stops_bone_heat():
    from rigs import icosphere

    V, F = icosphere(2)
    sk = stbs.Skeleton([[0, 0, -0.5], [0, 0, 0.0], [0, 0, 0.5]], [[0, 1], [1, 2]])
    calls = []
    with pytest.raises(Stop):
        stbs.weights.bone_heat(V, F, sk, progress=raising_at(1, calls))
    assert calls == [(0, 3)]


def test_a_raising_callback_stops_build_rig_and_its_exception_propagates():
    from rigs import u_shape

    V, F, sk = u_shape()
    calls = []

    def progress(stage, done, total):
        calls.append((stage, done, total))
        if stage == "bone weights (bbw)" and total:
            raise KeyboardInterrupt          # any exception, even a BaseException

    with pytest.raises(KeyboardInterrupt):
        stbs.build_rig(V, sk, F=F, progress=progress)
    assert calls[-1][0] == "bone weights (bbw)" and calls[-1][2] > 0
    assert [c for c in calls if c[0].startswith("endpoint")] == []


def test_progress_must_be_callable():
    V, F, sk = strip_chain(bones=2, nx=20)
    with pytest.raises(TypeError, match="progress must be callable"):
        stbs.endpoint_weights(V, sk, method="bbw", F=F, progress="yes")
    with pytest.raises(TypeError, match="progress must be callable"):
        stbs.weights.bone_heat(np.c_[V, 0 * V[:, 0]], F,
                               stbs.Skeleton(np.c_[sk.C, [0, 0, 0]], sk.BE), progress=1)
