"""Writing a glTF character back (stbs.io.write_rig with source=): a copy of the file
with endpoint weights on every primitive the rig came from and the bone table; the rest
as it was; the Khronos validator finds no more than in the source (nothing in a clean
one); bone weights recomputed elsewhere replace the file's JOINTS_0/WEIGHTS_0."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
from gltf_files import load_raw
from test_io_gltf_write import validate

import stbs
from stbs.io import read_gltf, write_rig

FILES = ["gltf/SimpleSkin.gltf", "gltf/RiggedSimple.glb",
         "characters/gltf/CesiumMan.glb", "characters/gltf/RiggedFigure.glb",
         "characters/gltf/Fox.glb", "characters/gltf/Fox_separate/Fox.gltf",
         "characters/gltf/RobotExpressive.glb", "characters/gltf/threejs_Xbot.glb",
         "characters/gltf/BrainStem.glb"]


def _read(path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return read_gltf(path)


@pytest.mark.parametrize("name", FILES)
def test_a_character_written_back(shared_data, tmp_path, name):
    src = shared_data / name
    rig, clips = _read(src)
    E = stbs.weights.projection(rig.V, rig.skeleton)
    out = tmp_path / ("back.gltf" if name.endswith(".gltf") else "back.glb")
    write_rig(out, rig.replace(E=E), source=src)
    back, clips_b = _read(out)
    np.testing.assert_array_equal(back.V, rig.V)
    np.testing.assert_array_equal(back.F, rig.F)
    np.testing.assert_array_equal(back.W, rig.W)
    np.testing.assert_array_equal(back.C, rig.C)
    np.testing.assert_array_equal(back.skeleton.parents, rig.skeleton.parents)
    assert back.skeleton.names == rig.skeleton.names
    on = np.asarray(rig.W) > 0
    np.testing.assert_allclose(np.asarray(back.E)[on], E[on], atol=1e-7)
    # the animations are the file's own
    assert list(clips_b) == list(clips)
    first = next(iter(clips))
    np.testing.assert_array_equal(clips_b[first].times, clips[first].times)
    np.testing.assert_allclose(clips_b[first].quaternions, clips[first].quaternions)
    # every primitive the rig came from carries its endpoint weights; the nodes and
    # animations are the source's
    doc_a, _ = load_raw(src)
    doc_b, _ = load_raw(out)
    for p in rig.meta["gltf"]["primitives"]:
        assert "_ENDPOINT_WEIGHTS_0" in \
            doc_b["meshes"][p["mesh"]]["primitives"][p["primitive"]]["attributes"]
    assert doc_b["nodes"] == doc_a["nodes"]
    assert doc_b.get("animations") == doc_a.get("animations")
    assert doc_b.get("materials") == doc_a.get("materials")
    assert len(doc_b["buffers"]) == 1
    a, b = validate(src, out)
    assert b["errors"] <= a["errors"] and b["warnings"] <= a["warnings"], (a, b)
    if (a["errors"], a["warnings"]) == (0, 0):
        assert (b["errors"], b["warnings"]) == (0, 0), b


def test_new_bone_weights_replace_the_files(shared_data, tmp_path):
    # bone weights recomputed (here: each vertex to its two nearest bone starts) go into
    # JOINTS_0/WEIGHTS_0 of each primitive, over that primitive's skin
    src = shared_data / "characters/gltf/Fox.glb"
    rig, _ = _read(src)
    sk = rig.skeleton
    d = np.linalg.norm(rig.V[:, None] - sk.A[None], axis=2)
    near = np.argsort(d, axis=1)[:, :2]
    W = np.zeros((len(rig.V), sk.n_bones))
    np.put_along_axis(W, near, [0.75, 0.25], axis=1)
    E = stbs.weights.projection(rig.V, sk)
    out = tmp_path / "fox.glb"
    write_rig(out, rig.replace(W=W, E=E), source=src)
    back, _ = _read(out)
    np.testing.assert_allclose(back.W, W, atol=1 / 65535)
    on = W > 0
    np.testing.assert_allclose(np.asarray(back.E)[on], E[on], atol=1e-7)
    a, b = validate(src, out)
    assert (b["errors"], b["warnings"]) == (0, 0), b


def test_an_external_texture_is_embedded(shared_data, tmp_path):
    src = shared_data / "characters/gltf/Fox_separate/Fox.gltf"
    rig, _ = _read(src)
    out = tmp_path / "elsewhere" / "fox.gltf"
    out.parent.mkdir()
    write_rig(out, rig.replace(E=stbs.weights.projection(rig.V, rig.skeleton)), source=src)
    doc = json.loads(out.read_text())
    assert all("uri" not in img and img["mimeType"] == "image/png" for img in doc["images"])
    assert doc["buffers"][0]["uri"].startswith("data:")
    assert validate(out)[0]["errors"] == 0


def test_a_rig_from_elsewhere_is_refused(shared_data, tmp_path):
    rig, _ = _read(shared_data / "characters/gltf/Fox.glb")
    rig = rig.replace(E=stbs.weights.projection(rig.V, rig.skeleton))
    with pytest.raises(ValueError, match="not the file the rig was read from"):
        write_rig(tmp_path / "x.glb", rig, source=shared_data / "characters/gltf/CesiumMan.glb")
    with pytest.raises(ValueError, match="no endpoint weights"):
        write_rig(tmp_path / "x.glb", rig.replace(E=None), source=shared_data /
                  "characters/gltf/Fox.glb")
    assert not list(tmp_path.iterdir())
