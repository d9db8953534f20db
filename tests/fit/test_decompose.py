"""stbs.fit.decompose (stbs/fit/ssdr.py): a mesh animation decomposed into stretchable,
twistable bones."""

from __future__ import annotations

import numpy as np
import pytest

import stbs
from stbs.fit import Decomposition
from stbs.fit.ssdr import decompose, frames_needed
from stbs.shapes import cigar
from stbs.transforms import axis_angle_to_matrix


# --------------------------------------------------------------------------- fixtures
def _chain_animation(frames: int = 10, seed: int = 1):
    """A 3-bone chain in an ellipsoid (366 vertices) animated with bends, stretches of
    0.7-1.4 and twists up to 80 degrees: rest V, F, frames (frames, n, 3)."""
    V, F, _, _ = cigar(14, half_length=2.0, radius=0.45)
    x = np.linspace(-1.8, 1.8, 4)
    sk = stbs.Skeleton(np.c_[x, np.zeros(4), np.zeros(4)], [[0, 1], [1, 2], [2, 3]])
    centres = 0.5 * (x[:-1] + x[1:])
    W = np.exp(-((V[:, :1] - centres) / 0.45) ** 2)
    W[W < 1e-3 * W.max(axis=1, keepdims=True)] = 0.0
    W /= W.sum(axis=1, keepdims=True)
    E = stbs.endpoint_weights(V, sk, method="projection")
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(frames):
        axes = rng.normal(size=(3, 3)) * [0.2, 1.0, 1.0]          # bend, little roll
        L = axis_angle_to_matrix(axes / np.linalg.norm(axes, axis=1, keepdims=True),
                                 rng.uniform(-0.6, 0.6, 3))
        pose = stbs.forward_kinematics(sk, rotations=L, stretch=rng.uniform(0.7, 1.4, 3),
                                       twist=rng.uniform(-1.4, 1.4, 4),
                                       translation=rng.normal(scale=0.3, size=3))
        out.append(stbs.deform(V, sk, pose, W, E, method="stbs-lbs"))
    return V, F, np.stack(out)


@pytest.fixture(scope="module")
def chain():
    return _chain_animation()


@pytest.fixture(scope="module")
def chain_fits(chain):
    V, F, Y = chain
    return {m: decompose(V, Y, 3, F=F, iterations=16, method=m, seed=0)
            for m in ("stbs-lbs", "lbs")}


def _rmse(U, Y) -> float:
    return float(np.sqrt(np.mean(np.sum((U - Y) ** 2, axis=-1))))


# --------------------------------------------------------------------------- a known rig
def test_stretch_and_twist_are_recovered_where_rigid_bones_cannot(chain, chain_fits):
    V, _, Y = chain
    diag = np.linalg.norm(V.max(0) - V.min(0))
    st, lbs = chain_fits["stbs-lbs"], chain_fits["lbs"]
    assert st.diagonal == pytest.approx(diag)
    assert st.rmse_percent < 0.5                      # of the bounding-box diagonal
    assert st.rmse < 0.25 * lbs.rmse                  # rigid LBS, same bone count
    assert lbs.rmse_percent > 1.0
    # both are measured the same way, on the frames the rigs reproduce
    assert st.rmse == pytest.approx(_rmse(st.frames(), Y), rel=1e-9)
    assert lbs.rmse == pytest.approx(_rmse(lbs.frames(), Y), rel=1e-9)
    sig = np.array([p.stretch for p in st.poses])
    assert sig.min() < 0.85 and sig.max() > 1.2       # the fit uses stretch ...
    th = np.array([p.twist for p in st.poses])
    assert np.ptp(th) > 0.5                           # ... and twist
    # within the documented bounds: stretch in SIGMA_RANGE, twist along a bone <= pi,
    # kept symmetric (a twist common to the whole bone is in R)
    from stbs.fit._ssdr_model import SIGMA_RANGE
    assert SIGMA_RANGE[0] <= sig.min() and sig.max() <= SIGMA_RANGE[1]
    assert np.abs(th[..., 1] - th[..., 0]).max() <= np.pi + 1e-12
    np.testing.assert_allclose(th[..., 0], -th[..., 1], atol=1e-12)


def test_reconstruction_is_stbs_deform_of_the_returned_rig(chain, chain_fits):
    V, F, Y = chain
    d = chain_fits["stbs-lbs"]
    assert isinstance(d, Decomposition)
    sk = d.skeleton
    assert sk.n_bones == 3 and np.all(sk.parents == -1) and len(d.poses) == Y.shape[0]
    assert d.W.shape == (V.shape[0], 3) and d.E.shape == (V.shape[0], 3)
    assert d.W.min() >= 0 and np.allclose(d.W.sum(axis=1), 1.0, atol=1e-12)
    assert d.E.min() >= 0 and d.E.max() <= 1
    U = d.frames()
    for f in (0, 4, 9):
        ref = stbs.deform(V, sk, d.poses[f], d.W, d.E, method="stbs-lbs")
        np.testing.assert_allclose(U[f], ref, atol=1e-12)
    # the plain NumPy reading of eq. 5 agrees too
    from stbs.skinning.reference import reference_deform
    np.testing.assert_allclose(reference_deform(V, d.poses[3], d.W, d.E, "stbs-lbs"), U[3],
                               atol=1e-9)
    rig = d.rig()
    assert rig.skeleton is sk and np.array_equal(rig.F, F)
    np.testing.assert_allclose(stbs.deform(rig.V, rig.skeleton, d.poses[5], rig.W, rig.E,
                                           method="stbs-lbs"), U[5], atol=1e-12)


def test_weights_are_sparse(chain):
    V, F, Y = chain
    d = decompose(V, Y, 3, F=F, iterations=3, max_influences=2, seed=0)
    assert np.count_nonzero(d.W, axis=1).max() <= 2
    assert np.allclose(d.W.sum(axis=1), 1.0)


def test_a_rigid_motion_is_one_bone_exactly():
    rng = np.random.default_rng(3)
    rest = rng.normal(size=(50, 3))
    R = axis_angle_to_matrix(np.array([[0.3, -0.5, 0.8]]) / np.sqrt(0.98), np.array([2.5]))[0]
    frames = np.stack([rest, rest @ R.T + [1.0, -2.0, 0.5], rest + [0.0, 3.0, 0.0]])
    d = decompose(rest, frames, 1, iterations=2)
    assert d.rmse < 1e-9
    assert d.rmse_percent < 1e-7


def test_same_seed_same_result_and_seeds_matter(chain):
    V, F, Y = chain
    a = decompose(V, Y, 3, F=F, iterations=3, seed=5)
    b = decompose(V, Y, 3, F=F, iterations=3, seed=5)
    np.testing.assert_array_equal(a.W, b.W)
    np.testing.assert_array_equal(a.E, b.E)
    np.testing.assert_array_equal(a.skeleton.C, b.skeleton.C)
    for p, q in zip(a.poses, b.poses, strict=True):
        np.testing.assert_array_equal(p.rotations, q.rotations)
        np.testing.assert_array_equal(p.twist, q.twist)
    assert a.history == b.history
    c = decompose(V, Y, 3, F=F, iterations=3, seed=6)      # another start, another answer
    assert np.abs(c.W - a.W).max() > 0.1


def test_progress_reports_stages_and_a_raise_cancels(chain):
    V, F, Y = chain
    calls = []
    decompose(V, Y, 3, F=F, iterations=2, progress=lambda *a: calls.append(a))
    assert calls[0] == ("cluster", 0, 0)
    assert ("fit", 0, 0) in calls and calls[-1] == ("fit", 2, 2)

    class Stop(Exception):
        pass

    def stop(stage, done, total):
        if stage == "fit" and done == 1:
            raise Stop

    with pytest.raises(Stop):
        decompose(V, Y, 3, F=F, iterations=5, progress=stop)
    with pytest.raises(TypeError, match="progress"):
        decompose(V, Y, 3, progress=3)


# --------------------------------------------------------------------------- bad input
@pytest.mark.parametrize("change, match", [
    (dict(frames=np.zeros((4, 7, 3))), r"frames must have shape \(frames, 20, 3\).*\(20, 3\).*"
                                       r"\(4, 7, 3\)"),
    (dict(frames=np.zeros((20, 3))), r"frames must have shape"),
    (dict(rest=np.zeros((20, 2))), r"rest must have shape \(n, 3\)"),
    (dict(n_bones=0), r"n_bones must be >= 1, got 0"),
    (dict(n_bones=7), r"n_bones must be at most 6 for 20 vertices"),
    (dict(method="dqs"), r"method must be one of 'stbs-lbs', 'lbs', got 'dqs'"),
    (dict(smoothness=-1.0), r"smoothness must be a finite number >= 0"),
    (dict(F=[[0, 1, 20]]), r"F must hold vertex indices in 0..19, got 20"),
    (dict(frames=np.ones((2, 20, 3)), n_bones=4),
     r"stbs-lbs with max_influences=4 needs at least 3 frames.*got 2"),
])
def test_bad_inputs_one_clear_error_each(change, match):
    rng = np.random.default_rng(0)
    rest = rng.normal(size=(20, 3))
    args = dict(rest=rest, frames=np.stack([rest] * 4), n_bones=2)
    args.update(change)
    with pytest.raises(ValueError, match=match):
        decompose(args.pop("rest"), args.pop("frames"), args.pop("n_bones"), **args)


def test_non_finite_frames_are_refused():
    rest = np.random.default_rng(0).normal(size=(20, 3))
    frames = np.stack([rest] * 4)
    frames[2, 5, 1] = np.nan
    with pytest.raises(ValueError, match=r"frames must be finite, got nan at index \(2, 5, 1\)"):
        decompose(rest, frames, 2)
    with pytest.raises(TypeError, match="n_bones must be an integer"):
        decompose(rest, np.stack([rest] * 4), 2.0)


def test_frames_needed_counts_each_vertexs_unknowns():
    # k - 1 free weights (+ k endpoint weights for stbs-lbs) against 3 coordinates a frame
    assert frames_needed(4, "stbs-lbs") == 3       # 7 unknowns
    assert frames_needed(4, "lbs") == 1            # 3 unknowns
    assert frames_needed(1, "lbs") == 1
    assert frames_needed(8, "stbs-lbs") == 5       # 15 unknowns
    rest = np.random.default_rng(0).normal(size=(30, 3))
    decompose(rest, np.stack([rest] * 2), 2, method="lbs", iterations=1)   # 1 is enough


# --------------------------------------------------------------------------- real data
@pytest.fixture(scope="module")
def horse_part(shared_data):
    path = shared_data / "sequences" / "horse-gallop.npz"
    if not path.is_file():
        pytest.skip(f"{path} not found")
    with np.load(path) as z:
        rest, frames, F = z["rest"], z["frames"], z["F"]
    # the front third of the horse (along its longest axis), every fourth frame
    ax = int(np.argmax(np.ptp(rest, axis=0)))
    keep = rest[:, ax] > np.quantile(rest[:, ax], 2 / 3)
    tri = keep[F].all(axis=1)
    index = np.full(rest.shape[0], -1)
    index[keep] = np.arange(int(keep.sum()))
    return rest[keep], frames[::4][:, keep], index[F[tri]]


@pytest.mark.slow
def test_horse_part_error_falls_across_iterations(horse_part):
    rest, frames, F = horse_part
    d = decompose(rest, frames, 6, F=F, iterations=6, seed=0)
    h = np.array(d.history)
    assert len(h) == 7
    assert h[-1] < 0.6 * h[0]
    assert np.all(np.diff(h) <= 1e-3 * h[0])          # never worse, to rounding
    assert d.rmse == pytest.approx(h[-1], rel=1e-6)
    lbs = decompose(rest, frames, 6, F=F, iterations=6, seed=0, method="lbs")
    assert d.rmse < lbs.rmse


# --------------------------------------------------------------------------- the benchmark
def test_bench_fit_runs_both_methods_and_measures_them_alike(chain, tmp_path):
    from threadpoolctl import threadpool_limits

    from stbs.bench import fit as bench

    V, F, Y = chain
    Y = Y[:5]
    np.savez(tmp_path / bench.FILE, rest=V, frames=Y, F=F)
    lines: list[str] = []
    # one OpenMP thread: on a busy 2-core machine Dem Bones' threads wait on each other
    with threadpool_limits(1, user_api="openmp"):
        doc = bench.report((3,), iterations=2, peer_iterations=3, out=lines.append,
                        data=tmp_path)
    rows = {r["method"].split()[0]: r for r in doc["rows"]}
    assert set(rows) == {"STBS-SSDR", "ours,", "Dem"}
    assert all(r["bones"] == 3 for r in rows.values())
    diag = np.linalg.norm(V.max(0) - V.min(0))
    ours = decompose(V, Y, 3, F=F, iterations=2, seed=0)
    assert rows["STBS-SSDR"]["rmse"] == pytest.approx(ours.rmse, rel=1e-9)
    assert rows["STBS-SSDR"]["percent"] == pytest.approx(100 * ours.rmse / diag)
    rigid = decompose(V, Y, 3, F=F, iterations=2, seed=0, method="lbs")
    assert rows["ours,"]["rmse"] == pytest.approx(rigid.rmse, rel=1e-9)
    # the peer's error by hand from its own weights and transforms
    from py_dem_bones import solve_skinning
    with threadpool_limits(1, user_api="openmp"):
        res = solve_skinning(V, Y, 3, faces=F, max_influences=4, iterations=3)
    U = np.einsum("bn,fbij,nj->fni", res.weights, res.transforms[:, :, :3, :3], V) \
        + np.einsum("bn,fbi->fni", res.weights, res.transforms[:, :, :3, 3])
    assert rows["Dem"]["rmse"] == pytest.approx(_rmse(U, Y), rel=1e-9)
    text = "\n".join(lines)
    assert "STBS-SSDR (stbs-lbs)" in text and "Dem Bones (lbs)" in text
    assert f"{rows['STBS-SSDR']['percent']:.3f}" in text
    assert "3 bones: STBS-SSDR's RMSE is" in text and "(our rigid bones: " in text


def test_bench_fit_data_is_found_or_named(tmp_path, monkeypatch):
    from stbs.bench import fit as bench

    (tmp_path / "sequences").mkdir()
    f = tmp_path / "sequences" / bench.FILE
    np.savez(f, rest=np.zeros((3, 3)))
    assert bench.find_data(tmp_path) == f
    assert bench.find_data(f) == f
    monkeypatch.setenv("STBS_DATA", str(tmp_path))
    assert bench.find_data() == f
    with pytest.raises(ValueError, match="horse-gallop.npz not found; tried"):
        bench.find_data(tmp_path / "nowhere")
    with pytest.raises(ValueError, match="a member 'frames'"):
        bench.load_sequence(f)
    np.savez(f, frames=np.zeros((2, 3, 3)))
    with pytest.raises(ValueError, match="has no triangles 'F'"):
        bench.load_sequence(f)
    assert bench.main(["--data", str(tmp_path / "nowhere")]) == 2


def test_smoothness_pulls_weights_towards_their_neighbours(chain):
    V, F, Y = chain
    E = np.r_[F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]

    def roughness(W):
        return float(np.sum((W[E[:, 0]] - W[E[:, 1]]) ** 2))

    rough = decompose(V, Y, 3, F=F, iterations=4, smoothness=0.0, seed=0)
    smooth = decompose(V, Y, 3, F=F, iterations=4, smoothness=1e-2, seed=0)
    assert roughness(smooth.W) < 0.7 * roughness(rough.W)
    assert smooth.rmse > rough.rmse                   # smoothness costs some fit
