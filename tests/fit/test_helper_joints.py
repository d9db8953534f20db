"""stbs.fit.helper_joints (stbs/fit/twist_bones.py): an STBS rig as plain LBS with k rigid
helper joints per bone.

By hand (the helpers' places and maps, a stretch that hat weights reproduce exactly, the
chord a 180-degree twist cuts with k = 2), properties (rest, rigid poses, k = 1, the
weights' bounds, clips), the libigl arm twisted 180 degrees and stretched 1.5 times, the
GLB through the Khronos validator and three.js's SkinnedMesh in headless Chromium.
"""

from __future__ import annotations

import functools
import http.server
import json
import shutil
import subprocess
import threading
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

import stbs
import stbs.fit
from rigs import random_rotations
from stbs import io
from stbs.fit.twist_bones import HelperRig, helper_joints, helper_params, helper_skeleton
from stbs.shapes import bar, cigar

REPO = Path(__file__).resolve().parents[2]
PAGE = Path(__file__).resolve().parent / "helper_page"
THREE = REPO / "viewer" / "node_modules" / "three"


def chain():
    """Bone 0 from the origin 2 along x, bone 1 from its end 1 along y."""
    return stbs.Skeleton([[0, 0, 0], [2, 0, 0], [2, 1, 0.0]], [[0, 1], [1, 2]],
                         names=["arm", "hand"])


@pytest.fixture(scope="module")
def bar_rig():
    V, F, sk, W = bar(8, 2, 2)
    return stbs.Rig(V=V, F=F, skeleton=sk, W=W, E=stbs.weights.projection(V, sk))


def bent_pose(sk, seed, *, stretch=None, twist=None, translation=(0.3, -0.2, 0.1)):
    rng = np.random.default_rng(seed)
    return stbs.forward_kinematics(sk, rotations=random_rotations(rng, sk.n_bones, 3),
                                   stretch=stretch, twist=twist, translation=translation)


# --------------------------------------------------------------------------- by hand
def test_the_helpers_sit_along_each_bone_with_both_ends():
    sk = chain()
    assert helper_params(3).tolist() == [0.0, 0.5, 1.0]
    assert helper_params(1).tolist() == [0.0]
    hsk = helper_skeleton(sk, 3)
    assert hsk.names == ["arm", "arm_twist_1", "arm_twist_2", "hand", "hand_twist_1",
                         "hand_twist_2"]
    np.testing.assert_allclose(hsk.A, [[0, 0, 0], [1, 0, 0], [2, 0, 0],
                                       [2, 0, 0], [2, 0.5, 0], [2, 1, 0]])
    # the last helper of a bone gets a tail of half a segment past the bone's end
    np.testing.assert_allclose(hsk.B[2], [2.5, 0, 0])
    np.testing.assert_allclose(hsk.B[5], [2, 1.25, 0])
    # a chain per bone; the child's first helper hangs off the parent's last
    assert hsk.parents.tolist() == [-1, 0, 1, 2, 3, 4]
    assert helper_skeleton(sk, 1) == sk


def test_a_helper_is_the_bone_map_at_its_parameter():
    sk = stbs.Skeleton([[1, 0, 0], [3, 0, 0.0]], [[0, 1]])
    pose = stbs.forward_kinematics(sk, stretch=[1.5], twist=[0, np.pi])
    helper = helper_joints(np.array([[2, 1, 0.0]]), sk, [[1.0]], [[0.5]], k=2, fit="hat")
    hp = helper.pose(pose)
    assert np.all(hp.stretch == 1) and np.all(hp.twist == 0)
    # t = 1/2: turned 90 degrees about x, starting half-way along the stretched bone (3)
    np.testing.assert_allclose(hp.rotations[1], [[1, 0, 0], [0, 0, -1], [0, 1, 0]],
                               atol=1e-15)
    np.testing.assert_allclose(hp.origins, [[1, 0, 0], [2.5, 0, 0], [4, 0, 0]])
    # the vertex at e = 1/2 (rest (2, 1, 0)) goes to (2.5, 0, 1): half the twist, and it
    # moves with the stretched bone's middle; the helper at t = 1/2 carries it there
    U = helper.deform(pose)
    np.testing.assert_allclose(U, [[2.5, 0, 1]], atol=1e-15)
    np.testing.assert_allclose(helper.W.toarray(), [[0, 1, 0]])


def test_two_helpers_half_a_turn_apart_cut_the_chord_to_the_axis():
    # k = 1: the bone's joint and one helper, at e = 0 and 1, 180 degrees apart; a
    # vertex at e = 1/2 blends them half and half, which lands on the bone's axis
    # whatever its radius
    V, F, sk, W = cigar(8)
    E = stbs.weights.projection(V, sk)
    helper = helper_joints(V, sk, W, E, k=1, fit="hat", F=F)
    pose = stbs.forward_kinematics(sk, twist=[0, np.pi])
    mid = np.flatnonzero(np.abs(V[:, 0]) < 1e-9)
    assert mid.size == 16 and np.allclose(E[mid, 0], 0.5)
    U = helper.deform(pose)
    np.testing.assert_allclose(U[mid], 0.0, atol=1e-12)


def test_stretch_and_bends_without_twist_are_exact_with_hat_weights(bar_rig):
    # without twist a bone's map is affine in e, so splitting w_i by the hat functions
    # in e reproduces stbs-lbs exactly (two bones a vertex: every bone gets its pair)
    sk = bar_rig.skeleton
    helper = helper_joints(bar_rig, k=2, fit="hat", method="stbs-lbs")
    for seed in range(3):
        pose = bent_pose(sk, seed, stretch=[1.7, 0.6])
        U = stbs.deform(bar_rig.V, sk, pose, bar_rig.W, bar_rig.E, method="stbs-lbs")
        np.testing.assert_allclose(helper.deform(pose), U, atol=1e-12)


# --------------------------------------------------------------------------- properties
def test_rest_and_rigid_poses_are_reproduced_exactly(bar_rig):
    sk, V = bar_rig.skeleton, bar_rig.V
    for fit in ("lsq", "hat"):
        helper = helper_joints(bar_rig, k=3, fit=fit, n_poses=6)
        np.testing.assert_allclose(helper.deform(stbs.Pose.rest(sk)), V, atol=1e-13)
        # two bones a vertex fit in four influences: the bone totals are W itself
        np.testing.assert_allclose(helper.bone_weights.toarray(), bar_rig.W, atol=1e-15)
        for seed in range(3):
            pose = bent_pose(sk, seed)
            U = stbs.deform(V, sk, pose, bar_rig.W, method="lbs")
            np.testing.assert_allclose(helper.deform(pose), U, atol=1e-12)


def test_k0_is_the_bone_itself(bar_rig):
    sk = bar_rig.skeleton
    helper = helper_joints(bar_rig, k=0)
    assert helper.skeleton == sk and helper.t.tolist() == [0.0]
    np.testing.assert_allclose(helper.W.toarray(), bar_rig.W, atol=1e-15)
    pose = bent_pose(sk, 4, stretch=[1.4, 0.8], twist=[0, 1.0, 2.0])
    hp = helper.pose(pose)
    np.testing.assert_array_equal(hp.origins, pose.origins)
    np.testing.assert_allclose(hp.rotations, pose.rotations @ pose.twist_rotations(0.0),
                               atol=1e-15)
    rigid = stbs.Pose(sk, rotations=hp.rotations, origins=pose.origins)
    np.testing.assert_allclose(helper.deform(pose),
                               stbs.deform(bar_rig.V, sk, rigid, bar_rig.W, method="lbs"),
                               atol=1e-13)


def test_the_weights_are_convex_sparse_and_add_up_per_bone(arm):
    rig = arm["rig"]
    for m, helper in ((4, arm["k3"]), (8, arm["k3_8"])):
        W = helper.W
        assert sp.issparse(W) and W.shape == (rig.V.shape[0], 4 * 4)   # 4 joints a bone
        assert W.data.min() > 0 and np.diff(W.indptr).max() <= m
        np.testing.assert_allclose(W.sum(axis=1), 1.0, atol=1e-12)
        # a bone's helpers share exactly its weight (the bone totals)
        per_bone = W @ sp.csr_array(np.kron(np.eye(4), np.ones((4, 1))))
        np.testing.assert_allclose(per_bone.toarray(), helper.bone_weights.toarray(),
                                   atol=1e-12)
        # only bones the vertex has; with 8 influences every bone keeps its weight
        assert np.all(rig.W[helper.bone_weights.toarray() > 0] > 0)
    np.testing.assert_allclose(arm["k3_8"].bone_weights.toarray(), rig.W, atol=1e-12)
    assert np.diff(arm["k3_8"].W.indptr).max() > 4
    with pytest.raises(ValueError, match="glTF is written with 4 joints a vertex .JOINTS_0., "
                                         "this helper rig has up to [5-8]; make it with "
                                         "max_influences=4"):
        arm["k3_8"].write_gltf(Path("never-written.glb"))
    assert not Path("never-written.glb").exists()


def test_least_squares_beat_hat_weights_on_their_own_poses():
    # the hat split is the best one where e is midway between helpers (by symmetry) or
    # for a stretch (affine in e); off the middle of a twist's chord the fit does better
    V, F, sk, W = cigar(8)
    E = stbs.weights.projection(V, sk)
    rng = np.random.default_rng(7)
    poses = [stbs.forward_kinematics(sk, stretch=rng.uniform(0.6, 1.8, 1),
                                     twist=rng.uniform(-np.pi, np.pi, 2)) for _ in range(6)]

    def error(helper):
        return sum(np.sum((helper.deform(p) - stbs.deform(V, sk, p, W, E)) ** 2)
                   for p in poses)

    lsq, hat = (helper_joints(V, sk, W, E, k=1, poses=poses, fit=f) for f in ("lsq", "hat"))
    assert error(lsq) < 0.995 * error(hat)
    assert np.abs(lsq.W - hat.W).max() > 0.01
    np.testing.assert_allclose(lsq.W.sum(axis=1), 1.0, atol=1e-12)


def test_clips_become_rigid_clips_of_the_helper_poses(bar_rig):
    sk = bar_rig.skeleton
    helper = helper_joints(bar_rig, k=2, n_poses=4)
    clip = stbs.Clip([(0.0, stbs.Pose.rest(sk)),
                      (0.5, bent_pose(sk, 1, stretch=[1.5, 1.0], twist=[0, 0, np.pi])),
                      (1.3, bent_pose(sk, 2, stretch=[0.8, 1.3], twist=[0, -2.0, 1.0]))],
                     fps=8)
    hc = helper.clip(clip)
    assert hc.skeleton == helper.skeleton
    assert np.all(hc.stretch == 1) and not np.any(hc.twist)
    np.testing.assert_allclose(hc.times, np.r_[np.arange(11) / 8, 1.3])   # + the last key
    for t in (0.0, 0.375, 0.5, 1.1, 1.27, 1.3, 0.3):
        want = helper.pose(clip.pose(t))
        got = hc.pose(t)
        np.testing.assert_allclose(got.origins, want.origins, atol=1e-9)
        np.testing.assert_allclose(got.rotations, want.rotations, atol=1e-9)
    step = stbs.Clip(clip.keys, interpolation="step")
    hs = helper.clip(step)
    assert hs.interpolation == "step" and hs.times.tolist() == [0.0, 0.5, 1.3]
    np.testing.assert_allclose(hs.pose(0.9).origins, helper.pose(clip.pose(0.5)).origins,
                               atol=1e-12)


def test_a_2d_rig_gets_helpers_too():
    V = np.array([[0.5, 0.1], [1.5, -0.1], [2.5, 0.1]])
    sk = stbs.Skeleton([[0, 0], [2, 0], [3, 0.0]], [[0, 1], [1, 2]])
    W = np.array([[1, 0], [0.5, 0.5], [0, 1.0]])
    E = stbs.weights.projection(V, sk)
    helper = helper_joints(V, sk, W, E, k=2, fit="hat", method="stbs-lbs")
    pose = stbs.forward_kinematics(sk, rotations=[0.4, -0.7], stretch=[1.5, 0.5])
    np.testing.assert_allclose(helper.deform(pose),
                               stbs.deform(V, sk, pose, W, E, method="stbs-lbs"), atol=1e-13)


def test_the_package_exports_the_converter():
    assert stbs.fit.HelperRig is HelperRig
    assert stbs.fit.__getattr__("helper_joints") is helper_joints
    assert "helper_joints" in stbs.fit.__all__


# --------------------------------------------------------------------------- the arm
@pytest.fixture(scope="module")
def arm(shared_data):
    d = shared_data / "libigl-tutorial-data"
    mesh = io.read_mesh(d / "arm.obj")
    sk = io.read_skeleton(d / "arm.tgf")
    W = io.read_dmat(d / "arm-weights.dmat")
    E = stbs.endpoint_weights(mesh.V, sk)
    rig = stbs.Rig(V=mesh.V, F=mesh.F, skeleton=sk, W=W, E=E)
    # stretch the forearm (bone 2) 1.5 times and twist it 180 degrees at the wrist
    pose = stbs.forward_kinematics(sk, stretch=[1, 1, 1.5, 1], twist=[0, 0, 0, np.pi, 0])
    return {"rig": rig, "pose": pose, "k3": helper_joints(rig, k=3),
            "k3_8": helper_joints(rig, k=3, max_influences=8, fit="hat", n_poses=4),
            "clip": stbs.Clip([(0.0, stbs.Pose.rest(sk)), (1.0, pose)], fps=10)}


def forearm_radius(rig):
    """Largest distance from the forearm's axis of a vertex that follows it most."""
    sk = rig.skeleton
    on = rig.W.argmax(axis=1) == 2
    r = rig.V[on] - sk.A[2]
    r -= np.outer(r @ sk.axes[2], sk.axes[2])
    return np.linalg.norm(r, axis=1).max()


@pytest.mark.parametrize("method", ["stbs-dqs", pytest.param("stbs-lbs",
                                                              marks=pytest.mark.slow)])
def test_the_twisted_and_stretched_arm_plays_within_the_chord_bound(arm, method):
    rig, pose = arm["rig"], arm["pose"]
    diagonal = np.linalg.norm(np.ptp(rig.V, axis=0))
    U = stbs.deform(rig.V, rig.skeleton, pose, rig.W, rig.E, method=method)
    assert np.linalg.norm(U - rig.V, axis=1).max() > 0.1 * diagonal   # it does move
    r = forearm_radius(rig)
    for k in (2, 3):
        helper = arm["k3"] if (k == 3 and method == "stbs-dqs") else helper_joints(
            rig, k=k, method=method)
        err = np.linalg.norm(helper.deform(pose) - U, axis=1) / diagonal
        # the bone's joint and k helpers, 180 / k degrees apart: a vertex midway sinks by
        # the chord's sagitta r (1 - cos(90 / k degrees)); the fit gets close, not past
        sag = r * (1 - np.cos(np.pi / (2 * k))) / diagonal
        assert 0.5 * sag < err.max() <= 1.02 * sag
        assert np.sqrt(np.mean(err ** 2)) < 0.25 * sag
    assert err.max() < 0.01                     # k = 3: within 1 % of the diagonal
    # the rigid pose of plain LBS on the bones alone, no twist helpers, is far worse
    k0 = np.linalg.norm(helper_joints(rig, k=0).deform(pose) - U, axis=1) / diagonal
    assert k0.max() > 0.05


# --------------------------------------------------------------------------- glTF
def validate(*paths) -> list[dict]:
    """The Khronos glTF validator's reports (tests/node, installed by make test)."""
    node = shutil.which("node")
    assert node, "node is needed for the glTF validator (make test installs it)"
    tools = REPO / "tests" / "node"
    assert (tools / "node_modules" / "gltf-validator").is_dir(), (
        "npm ci --prefix tests/node (make test does)")
    out = subprocess.run([node, str(tools / "validate.mjs"), *map(str, paths)],
                         capture_output=True, text=True, timeout=120, check=True)
    return [json.loads(line) for line in out.stdout.splitlines()]


@pytest.fixture(scope="module")
def arm_glb(arm, tmp_path_factory):
    path = tmp_path_factory.mktemp("helpers") / "arm.glb"
    arm["k3"].write_gltf(path, arm["clip"])
    return path


def test_the_glb_validates_and_reads_back_as_the_helper_rig(arm, arm_glb):
    assert [r["errors"] for r in validate(arm_glb)] == [0]
    helper, clip = arm["k3"], arm["clip"]
    rig, clips = io.read_gltf(arm_glb)
    assert rig.skeleton.names == helper.skeleton.names
    np.testing.assert_allclose(rig.skeleton.C, helper.skeleton.C, atol=1e-6)
    np.testing.assert_allclose(rig.W.toarray() if sp.issparse(rig.W) else rig.W,
                               helper.W.toarray(), atol=1.0 / 65535)
    (played,) = clips.values()
    for t in (0.0, 0.35, 0.8, 1.0):
        U = stbs.deform(rig.V, rig.skeleton, played.pose(t), rig.W, method="lbs")
        np.testing.assert_allclose(U, helper.deform(clip.pose(t)), atol=1e-4)


class _Files(http.server.SimpleHTTPRequestHandler):
    """/three/ from the viewer's three.js, /page/ the test page, /files/ the GLB."""

    def __init__(self, *args, roots, **kw):
        self.roots = roots
        super().__init__(*args, **kw)

    def translate_path(self, path):
        path = path.split("?")[0]
        for prefix, root in self.roots.items():
            if path.startswith(prefix):
                return str(root / path[len(prefix):])
        return str(PAGE / "missing")

    def log_message(self, *args):
        pass


@pytest.mark.slow
def test_three_js_skinned_mesh_plays_the_glb_as_stbs_lbs(arm, arm_glb):
    sync_api = pytest.importorskip("playwright.sync_api", reason="playwright is not "
                                   "installed (pip install playwright)")
    from stbs.bench.viewer import default_browser

    browser = default_browser()
    if not Path(browser).is_file():
        pytest.skip(f"no Chromium at {browser} (apt-get install chromium)")
    if not (THREE / "examples" / "jsm" / "loaders" / "GLTFLoader.js").is_file():
        pytest.skip("three.js is not installed in viewer/node_modules (npm ci --prefix viewer)")
    handler = functools.partial(_Files, roots={"/three/": THREE, "/page/": PAGE,
                                               "/files/": arm_glb.parent})
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    times = [0.0, 0.35, 0.8, 1.0]
    errors: list[str] = []
    try:
        with sync_api.sync_playwright() as pw:
            chromium = pw.chromium.launch(executable_path=browser, headless=True, args=[
                "--use-angle=swiftshader", "--enable-unsafe-swiftshader"])
            try:
                page = chromium.new_page()
                page.on("pageerror", lambda e: errors.append(str(e)))
                page.goto(f"http://127.0.0.1:{server.server_address[1]}/page/index.html")
                page.wait_for_function("window.pageReady === true")
                out = page.evaluate("([url, times]) => window.skinAt(url, times)",
                                    [f"/files/{arm_glb.name}", times])
            finally:
                chromium.close()
    finally:
        server.shutdown()
        server.server_close()
    assert errors == []
    rig, clips = io.read_gltf(arm_glb)
    (played,) = clips.values()
    helper = arm["k3"]
    assert out["n"] == rig.V.shape[0] and out["bones"] == helper.skeleton.n_bones
    for t, xyz in zip(times, out["positions"], strict=True):
        P = np.asarray(xyz).reshape(-1, 3)
        U = stbs.deform(rig.V, rig.skeleton, played.pose(t), rig.W, method="lbs")
        np.testing.assert_allclose(P, U, atol=1e-4)
        np.testing.assert_allclose(P, helper.deform(arm["clip"].pose(t)), atol=1e-4)
    # the last frame is the twisted, stretched arm, not the rest mesh
    assert np.abs(P - rig.V).max() > 0.1


# --------------------------------------------------------------------------- bad input
def test_bad_input_is_refused_with_the_argument_named(bar_rig):
    V, sk, W, E = bar_rig.V, bar_rig.skeleton, bar_rig.W, bar_rig.E
    with pytest.raises(ValueError, match=r"k must be >= 0 \(helper joints per bone, "
                                         r"beside its own\), got -1"):
        helper_joints(bar_rig, k=-1)
    with pytest.raises(TypeError, match="k must be an int"):
        helper_joints(bar_rig, k=2.0)
    with pytest.raises(TypeError, match="k must be an int"):
        helper_joints(bar_rig, k=True)
    with pytest.raises(ValueError, match="method must be one of 'stbs-dqs', 'stbs-lbs', "
                                         "got 'lbs'"):
        helper_joints(bar_rig, method="lbs")
    with pytest.raises(ValueError, match="fit must be one of 'lsq', 'hat', got 'nnls'"):
        helper_joints(bar_rig, fit="nnls")
    with pytest.raises(ValueError, match="max_influences must be 4 or 8, got 6"):
        helper_joints(bar_rig, max_influences=6)
    with pytest.raises(ValueError, match=r"rig\.E is None: STBS methods need endpoint "
                                         r"weights E \(n, 2\)"):
        helper_joints(bar_rig.replace(E=None))
    with pytest.raises(ValueError, match=r"E is None"):
        helper_joints(V, sk, W)
    with pytest.raises(ValueError, match=r"E must lie in \[0, 1\], got 1\.5"):
        helper_joints(V, sk, W, E + 0.5 * (E == 1))
    with pytest.raises(ValueError, match=rf"W must have shape \({len(V)}, 2\)"):
        helper_joints(V, sk, W[:, :1], E)
    with pytest.raises(TypeError, match="give a stbs.Rig alone"):
        helper_joints(bar_rig, sk)
    with pytest.raises(TypeError, match="needs a stbs.Rig, or V with sk, W and E"):
        helper_joints(V)
    with pytest.raises(ValueError, match="n_poses must be an int >= 1, got 0"):
        helper_joints(bar_rig, n_poses=0)
    other = chain()
    with pytest.raises(ValueError, match=r"poses\[0\] must be a pose of the skeleton"):
        helper_joints(bar_rig, poses=[stbs.Pose.rest(other)])
    with pytest.raises(TypeError, match="poses must be a sequence of stbs.Pose, got Pose; "
                                        "wrap a single Pose in a list"):
        helper_joints(bar_rig, poses=stbs.Pose.rest(sk))
    helper = helper_joints(bar_rig, k=1, fit="hat", n_poses=2)
    with pytest.raises(ValueError, match="pose must be a pose of the STBS skeleton"):
        helper.pose(stbs.Pose.rest(other))
    with pytest.raises(TypeError, match="pose must be a stbs.Pose, got Clip"):
        helper.pose(stbs.Clip([(0.0, stbs.Pose.rest(sk))]))
    with pytest.raises(ValueError, match="clip must be a clip of the STBS skeleton"):
        helper.clip(stbs.Clip([(0.0, stbs.Pose.rest(other))]))
    clash = stbs.Skeleton(sk.C, sk.BE, names=["upper", "upper_twist_1"])
    with pytest.raises(ValueError, match="helper bone name 'upper_twist_1' is also a "
                                         "bone's name"):
        helper_skeleton(clash, 2)


def test_progress_reports_every_fitting_pose_and_a_raise_cancels(bar_rig):
    seen = []
    helper_joints(bar_rig, k=2, n_poses=3, progress=lambda *a: seen.append(a))
    assert seen[:4] == [("fitting poses", q, 3) for q in range(4)]
    assert seen[-2:] == [("least squares", 0, 1), ("least squares", 1, 1)]

    def stop(stage, done, total):
        if done == 1:
            raise KeyboardInterrupt
    with pytest.raises(KeyboardInterrupt):
        helper_joints(bar_rig, k=2, n_poses=3, progress=stop)
    with pytest.raises(TypeError, match="progress must be callable"):
        helper_joints(bar_rig, k=2, progress=3)
