"""Hostile glTF files: one FormatError (one line, naming the file, what was expected and
what arrived), quickly, and no large allocation; buffers confined to the file's folder
and opened only when needed; the command line prints one line and exits 2."""

from __future__ import annotations

import base64
import json
import os
import struct
import time
import tracemalloc

import numpy as np
import pytest
from gltf_files import UBYTE, Builder, write

from stbs.cli import main
from stbs.io import FormatError, read_gltf, read_rig
from stbs.io.gltf import GltfFile, glb_bytes


def _doc(b: Builder, *, anim=False) -> dict:
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], float)
    prim = {"attributes": {"POSITION": b.add(V), "JOINTS_0": b.add(np.zeros((4, 4)), UBYTE),
                           "WEIGHTS_0": b.add(np.tile([1.0, 0, 0, 0], (4, 1)))},
            "indices": b.add(np.array([0, 1, 2, 1, 3, 2]), 5123)}
    doc = {"scene": 0, "scenes": [{"nodes": [0, 2]}],
           "nodes": [{"name": "root", "children": [1]}, {"name": "tip",
                                                         "translation": [0, 1, 0]},
                     {"mesh": 0, "skin": 0}],
           "meshes": [{"primitives": [prim]}], "skins": [{"joints": [0, 1]}]}
    if anim:
        doc["animations"] = [{"samplers": [{"input": b.add(np.array([0.0, 1.0])),
                                            "output": b.add(np.array([[0, 0, 0, 1.0],
                                                                      [0, 0, 1, 0.0]]))}],
                              "channels": [{"sampler": 0,
                                            "target": {"node": 1, "path": "rotation"}}]}]
    return doc


def _gltf(tmp_path, edit=None, name="x.gltf", anim=False):
    b = Builder()
    doc = _doc(b, anim=anim)
    path = write(tmp_path / name, doc, b, glb=name.endswith(".glb"))
    if edit is not None:
        if name.endswith(".glb"):
            path.write_bytes(edit(path.read_bytes()))
        else:
            d = json.loads(path.read_text())
            edit(d)
            path.write_text(json.dumps(d))
    return path


def _refused(path, match, *, peak_mb=64):
    tracemalloc.start()
    t = time.perf_counter()
    try:
        with pytest.raises(FormatError, match=match) as info:
            read_gltf(path)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert time.perf_counter() - t < 5
    assert peak < peak_mb * 2**20, f"{peak / 2**20:.0f} MiB allocated"
    msg = str(info.value)
    assert "\n" not in msg and str(path) in msg and "expected" in msg and "found" in msg
    return msg


def test_a_valid_file_reads(tmp_path):
    rig, clips = read_gltf(_gltf(tmp_path, anim=True))
    assert rig.V.shape == (4, 3) and rig.skeleton.names == ["root", "tip"]
    assert clips["animation_0"].times.tolist() == [0.0, 1.0]


@pytest.mark.parametrize("uri, match", [
    ("../outside.bin", "leads out of it"),
    ("sub/../../outside.bin", "leads out of it"),
    ("%2E%2E/outside.bin", "leads out of it"),
    ("/etc/passwd", "a data: URI or a relative path"),
    ("file:///etc/passwd", "a data: URI or a relative path"),
    ("https://example.com/x.bin", "a data: URI or a relative path"),
    ("C:/x.bin", "a data: URI or a relative path"),
    ("..\\outside.bin", "a data: URI or a relative path"),
])
def test_buffer_uris_stay_in_the_folder(tmp_path, uri, match):
    (tmp_path / "outside.bin").write_bytes(b"\0" * 4096)
    inner = tmp_path / "in"
    inner.mkdir()
    path = _gltf(inner, lambda d: d["buffers"][0].update(uri=uri))
    _refused(path, match)


def test_a_symlink_out_of_the_folder(tmp_path):
    b = Builder()
    _doc(b)
    (tmp_path / "secret.bin").write_bytes(bytes(b.data))
    inner = tmp_path / "in"
    inner.mkdir()
    os.symlink(tmp_path / "secret.bin", inner / "data.bin")
    path = _gltf(inner, lambda d: d["buffers"][0].update(uri="data.bin"))
    _refused(path, "leads out of it")


def test_a_buffer_file_beside_it_reads(tmp_path):
    b = Builder()
    doc = _doc(b)
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "my data.bin").write_bytes(bytes(b.data))
    path = write(tmp_path / "x.gltf", doc, b, glb=False)
    d = json.loads(path.read_text())
    d["buffers"][0]["uri"] = "sub/my%20data.bin"
    path.write_text(json.dumps(d))
    assert read_gltf(path)[0].V.shape == (4, 3)


@pytest.mark.parametrize("edit, match", [
    # a huge declared byteLength in a tiny file: a data URI, a GLB chunk, a file beside
    (lambda d: d["buffers"][0].update(byteLength=10**15), "a data: URI of 1000000000000000"),
    (lambda d: d["accessors"][0].update(count=10**12), "inside its buffer view"),
    (lambda d: d["bufferViews"][0].update(byteLength=10**12), "inside buffer 0"),
    (lambda d: (d["accessors"][0].pop("bufferView"), d["accessors"][0].update(count=10**11)),
     "at most .* bytes of arrays decoded"),
    (lambda d: d["accessors"][0].update(byteOffset=2**62), "inside its buffer view"),
    (lambda d: d["bufferViews"][0].update(byteStride=4), "byteStride of at least"),
    (lambda d: d["accessors"][0].update(count=-1), "an integer >= 1"),
    (lambda d: d["accessors"][0].update(count="7"), "an integer >= 1"),
    (lambda d: d.update(nodes={"0": {}}), "nodes: a JSON array"),
    (lambda d: d["nodes"][0].update(translation=[0, 0]), "translation: 3 numbers"),
    (lambda d: d["nodes"][1].update(children=[0]), "a cycle through nodes 0 -> 1 -> 0"),
    (lambda d: d["nodes"][2].update(children=[1]), "node 1 a child of nodes 0 and 2"),
    (lambda d: d["skins"][0].update(joints=[0, 0]), "distinct joint nodes"),
    (lambda d: (d["nodes"][0].update(children=[]), d["scenes"][0]["nodes"].append(1)),
     "joints under one common root node"),
    (lambda d: d.update(extensionsRequired=["KHR_draco_mesh_compression"]),
     "KHR_draco_mesh_compression"),
])
def test_declared_sizes_and_structure_are_checked(tmp_path, edit, match):
    _refused(_gltf(tmp_path, edit), match)


def test_a_huge_buffer_file_declared_larger_than_it_is(tmp_path):
    b = Builder()
    doc = _doc(b)
    (tmp_path / "x.bin").write_bytes(bytes(b.data))
    path = write(tmp_path / "x.gltf", doc, b, glb=False)
    d = json.loads(path.read_text())
    d["buffers"][0] = {"uri": "x.bin", "byteLength": 10**13}
    path.write_text(json.dumps(d))
    _refused(path, "'x.bin' of at least 10000000000000 bytes")


def _chunks(data: bytes):
    n = struct.unpack_from("<I", data, 12)[0]
    return data[:12], data[12:20 + n], data[20 + n:]


@pytest.mark.parametrize("edit, match", [
    (lambda d: d[:12] + struct.pack("<I", 10**9) + d[16:], "GLB chunk 0 inside the file"),
    (lambda d: (lambda h, j, b: h + j + struct.pack("<I", 2**31) + b[4:])(*_chunks(d)),
     "GLB chunk 1 inside the file"),
    (lambda d: d[:8] + struct.pack("<I", 10**9) + d[12:], "a GLB of 1000000000 bytes"),
    (lambda d: d[:4] + struct.pack("<I", 1) + d[8:], "a GLB of version 2"),
    (lambda d: (lambda h, j, b: h + j + struct.pack("<I4s", 12, b"BIN\0") + b[8:20])(
        *_chunks(d)), "the GLB BIN chunk of at least"),
    (lambda d: d[:30], "GLB"),
])
def test_glb_chunks_are_checked(tmp_path, edit, match):
    path = _gltf(tmp_path, name="x.glb")
    data = edit(path.read_bytes())
    # keep the header's total length honest where the edit is not about it
    if b"1000000000" not in match.encode() and "version" not in match and len(data) > 12:
        data = data[:8] + struct.pack("<I", len(data)) + data[12:]
    path.write_bytes(data)
    _refused(path, match)


@pytest.mark.parametrize("text, match", [
    ("[" * 100_000 + "]" * 100_000, "nested too deeply|a glTF 2.0 JSON object"),
    ('{"asset": {"version": "2.0"}, "nodes": [{"translation": [NaN, 0, 0]}]}',
     "unreadable JSON"),
    ("\xff\xfe", "unreadable JSON"),
    ('{"asset": {}}', "asset.version"),
])
def test_bad_json(tmp_path, text, match):
    path = tmp_path / "x.gltf"
    path.write_bytes(text.encode("utf-8", "surrogateescape") if isinstance(text, str)
                     else text)
    _refused(path, match)


def test_unused_buffers_are_never_opened(tmp_path):
    # buffer 1 (animations only) names a file that is not there; buffer 2 nothing uses
    b = Builder()
    doc = _doc(b, anim=True)
    path = write(tmp_path / "x.gltf", doc, b, glb=False)
    d = json.loads(path.read_text())
    d["buffers"] += [{"uri": "missing-anim.bin", "byteLength": 64},
                     {"uri": "../never.bin", "byteLength": 10**12}]
    for acc in d["animations"][0]["samplers"][0].values():
        if isinstance(acc, int):
            d["bufferViews"].append({"buffer": 1, "byteOffset": 0, "byteLength": 64})
            d["accessors"][acc]["bufferView"] = len(d["bufferViews"]) - 1
    path.write_text(json.dumps(d))
    rig = read_rig(path)
    assert rig.V.shape == (4, 3)
    _, clips = read_gltf(path)
    with pytest.raises(FormatError, match="missing-anim.bin"):
        clips["animation_0"]


def test_a_huge_animation_over_many_bones_is_refused(tmp_path):
    # 60000 keys of one channel (a real 240 KB) over 3000 bones would make gigabytes
    b = Builder()
    doc = _doc(b)
    n = 3000
    doc["nodes"][1]["children"] = list(range(3, 3 + n))
    doc["nodes"] += [{"name": f"j{k}", "translation": [0, 0.001 * k, 0]} for k in range(n)]
    doc["skins"][0]["joints"] = [0, 1, *range(3, 3 + n)]
    t = b.add(np.arange(60000, dtype=float) / 30)
    q = np.tile([0, 0, 0, 1.0], (60000, 1))
    q[::2] = [0, 0, 1.0, 0]
    doc["animations"] = [{"samplers": [{"input": t, "output": b.add(q)}],
                          "channels": [{"sampler": 0, "target": {"node": 1,
                                                                 "path": "rotation"}}]}]
    path = write(tmp_path / "x.glb", doc, b, glb=True)
    _, clips = read_gltf(path)
    with pytest.raises(FormatError, match="at most .* bytes of arrays decoded"):
        clips["animation_0"]


def test_glb_bytes_round_trip(tmp_path):
    doc = {"asset": {"version": "2.0"}, "buffers": [{"byteLength": 5}]}
    p = tmp_path / "x.glb"
    p.write_bytes(glb_bytes(doc, b"12345"))
    f = GltfFile(p)
    assert bytes(f.buffer(0)) == b"12345" and f.doc == doc
    assert len(p.read_bytes()) % 4 == 0


def test_a_data_uri_shorter_than_declared(tmp_path):
    def short(d):
        d["buffers"][0]["uri"] = "data:application/octet-stream;base64," + \
            base64.b64encode(b"\0" * 8).decode()

    _refused(_gltf(tmp_path, short), "a data: URI of .* bytes .*, found one of 8 bytes")


def test_the_command_line_says_one_line(tmp_path, capsys):
    (tmp_path / "outside.bin").write_bytes(b"\0" * 64)
    inner = tmp_path / "in"
    inner.mkdir()
    path = _gltf(inner, lambda d: d["buffers"][0].update(uri="../outside.bin"))
    for argv in (["weights", str(path), "-o", str(tmp_path / "o.glb")],
                 ["deform", str(path), "--pose", str(tmp_path / "p.json"), "-o",
                  str(tmp_path / "o.obj")]):
        (tmp_path / "p.json").write_text('{"rotate": {}}')
        assert main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "leads out of it" in err[0], err
    assert not (tmp_path / "o.glb").exists()
