"""Hostile glTF files: one FormatError (one line, naming the file, what was expected and
what arrived), after work linear in the file at most and no large allocation; buffers
confined to the file's folder and opened only when needed; the command line prints one
line and exits 2."""

from __future__ import annotations

import base64
import json
import os
import struct
import tracemalloc

import numpy as np
import pytest
from gltf_files import UBYTE, Builder, write

from stbs.cli import main
from stbs.io import FormatError, read_gltf, read_rig
from stbs.io.gltf import GltfFile, glb_bytes
from work_count import Lines


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


def _refusal_budget(path) -> int:
    """Lines of stbs code a refusal may run: work linear in the file at most (reading it,
    one walk of its nodes), never a walk per node or a decode per key. The cases here take
    under 2000 lines, a cycle through 20 000 nodes about 2 a byte."""
    return 10_000 + 4 * path.stat().st_size


def _refused(path, match, *, peak_mb=64):
    tracemalloc.start()
    try:
        with Lines(_refusal_budget(path)), pytest.raises(FormatError, match=match) as info:
            read_gltf(path)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
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
    ("%2e%2e/outside.bin", "leads out of it"),
    ("/proc/self/environ", "a data: URI or a relative path"),
    ("file:outside.bin", "a data: URI or a relative path"),
    ("FILE:///etc/passwd", "a data: URI or a relative path"),
    ("sub%2F..%2F..%2Foutside.bin", "leads out of it"),
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
    ("[" * 100_000 + "]" * 100_000, "nested at most 64 deep"),
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



# ---------------------------------------------------------------------- named findings
# (a) buffers: never read from outside the file's folder, nor copied when unused, nor
# shown in an error


def _canary(tmp_path):
    """A file outside the glTF file's folder holding a unique marker."""
    marker = b"CANARY-" + os.urandom(8).hex().encode()
    (tmp_path / "canary.bin").write_bytes(marker * 64)
    inner = tmp_path / "in"
    inner.mkdir()
    return inner, marker


def _opened(monkeypatch):
    """The files the glTF container opens (its module's ``open``, spied on)."""
    from stbs.io.gltf import container

    seen = []

    def spy(file, *args, **kwargs):
        seen.append(os.path.realpath(file))
        return open(file, *args, **kwargs)

    monkeypatch.setattr(container, "open", spy, raising=False)
    return seen


def _buffers_of(path) -> list[bytes]:
    f = GltfFile(path)
    return [bytes(f.buffer(k)) for k in range(len(f.doc["buffers"]))]


def test_an_unused_buffer_naming_a_file_outside_is_never_read_nor_copied(tmp_path,
                                                                        monkeypatch):
    inner, marker = _canary(tmp_path)

    def edit(d):
        d["buffers"] += [{"uri": "/etc/passwd", "byteLength": 64},
                         {"uri": "../canary.bin", "byteLength": 64},
                         {"uri": "file:///proc/self/environ", "byteLength": 64}]

    path = _gltf(inner, edit)
    seen = _opened(monkeypatch)
    for out in (tmp_path / "out.gltf", tmp_path / "out.glb"):
        assert main(["weights", str(path), "--endpoint", "projection", "-o", str(out)]) == 0
        data = out.read_bytes()
        doc = GltfFile(out).doc
        assert len(doc["buffers"]) == 1
        assert all(b"root:x:0:0" not in x and marker not in x
                   for x in [data, *_buffers_of(out)])
    assert not [p for p in seen if "canary" in p or p.startswith(("/etc", "/proc"))]


@pytest.mark.parametrize("uri", ["/proc/self/environ", "../canary.bin", "link.bin",
                                 "linked/canary.bin", "%2e%2e/canary.bin",
                                 "file:../canary.bin"])
def test_a_refused_buffer_shows_none_of_its_bytes(tmp_path, monkeypatch, capsys, uri):
    inner, marker = _canary(tmp_path)
    monkeypatch.setenv("STBS_TEST_SECRET", marker.decode())
    os.symlink(tmp_path / "canary.bin", inner / "link.bin")
    os.symlink(tmp_path, inner / "linked")
    path = _gltf(inner, lambda d: d["buffers"][0].update(uri=uri))
    seen = _opened(monkeypatch)
    assert main(["weights", str(path), "--endpoint", "projection", "-o",
                 str(tmp_path / "o.glb")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("stbs weights: error: ")
    assert str(path) in err[0] and marker.decode() not in err[0]
    assert not [p for p in seen if "canary" in p or p.startswith("/proc")]
    assert not (tmp_path / "o.glb").exists()


# (b) node cycles: one clear line, at once
@pytest.mark.parametrize("edit, match", [
    (lambda d: d["nodes"][2].update(children=[2]), r"nodes\[2\].children: node indices in "
                                                    r"0..2 other than 2, found 2"),
    # a cycle among two nodes above the skeleton's root (neither of them a joint)
    (lambda d: d["nodes"].extend([{"name": "A", "children": [0, 4]},
                                  {"name": "B", "children": [3]}]),
     r"a tree of nodes \(no cycles\), found a cycle through nodes 3 -> 4 -> 3$"),
    (lambda d: d["nodes"].extend([{"children": [k + 1]} for k in range(3, 3 + 20_000)]
                                 + [{"children": [3]}]),
     r"a cycle through nodes 3 -> 4 -> 5 -> 6 -> 7 -> 8 -> 9 -> 10 \.\.\. -> 3$"),
])
def test_node_cycles(tmp_path, edit, match):
    _refused(_gltf(tmp_path, edit), match)   # one walk of the nodes, not one per node


# (c) a count with nothing behind it
def test_an_accessor_of_400_million_elements_without_data_is_refused(tmp_path):
    def edit(d):
        d["accessors"].append({"componentType": 5126, "count": 400_000_000, "type": "VEC3"})
        d["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = len(d["accessors"]) - 1

    _refused(_gltf(tmp_path, edit), "at most .* bytes of arrays decoded", peak_mb=16)


# (d) commands that use no animation never decode one
def test_commands_without_animations_never_decode_one(tmp_path, monkeypatch):
    from stbs.io.gltf import read as gltf_read

    def keys_file(n):
        b = Builder()
        doc = _doc(b)
        t = b.add(np.arange(n, dtype=float) / 30)
        q = np.tile([0, 0, 0, 1.0], (n, 1))
        q[::2] = [0, 0, 1.0, 0]
        doc["animations"] = [{"samplers": [{"input": t, "output": b.add(q)}],
                              "channels": [{"sampler": 0, "target": {"node": 1,
                                                                     "path": "rotation"}}]}]
        return write(tmp_path / f"keys{n}.glb", doc, b, glb=True), t

    def never(*args, **kwargs):
        raise AssertionError("an animation was decoded")

    def work(path):
        """Lines of stbs code each command runs on ``path``."""
        counts = []
        for argv in (["deform", str(path), "--pose", str(tmp_path / "p.json"), "-o",
                      str(tmp_path / "o.npz")],
                     ["weights", str(path), "--endpoint", "projection", "-o",
                      str(tmp_path / "o.glb")],
                     ["export", str(path), "-o", str(tmp_path / "e.glb")]):
            with Lines() as w:
                assert main(argv) == 0
            counts.append(w.count)
        return counts

    monkeypatch.setattr(gltf_read, "decode_clip", never)
    (tmp_path / "p.json").write_text('{"rotate": {"0": {"axis": [0, 0, 1], "angle": 30}}}')
    n = 200_000
    few, _ = keys_file(2)
    many, t = keys_file(n)
    work(few)                                   # first calls fill caches
    # nothing is done per key: the same code runs for 2 keys and for 200 000
    small = work(few)
    assert work(many) == small
    # the write-back keeps the 200 000 keys as they were
    _, clips = read_gltf(tmp_path / "o.glb")
    assert GltfFile(tmp_path / "o.glb").doc["accessors"][t]["count"] == n


# (e) component types as the specification lists them for each attribute
def _retype(attr, ctype, normalized=None):
    def edit(d):
        prim = d["meshes"][0]["primitives"][0]
        i = prim["indices"] if attr == "indices" else prim["attributes"][attr]
        d["accessors"][i]["componentType"] = ctype
        if normalized is not None:
            d["accessors"][i]["normalized"] = normalized
    return edit


@pytest.mark.parametrize("attr, ctype, normalized, match", [
    ("POSITION", 5125, None, "components of float, found unsigned int"),
    ("POSITION", 5123, True, "components of float, found normalized unsigned short"),
    ("POSITION", 5126, True, "normalized only on byte and short components, found "
                             "normalized float"),
    ("JOINTS_0", 5126, None, "components of unsigned byte, unsigned short, found float"),
    ("JOINTS_0", 5125, None, "components of unsigned byte, unsigned short, found unsigned "
                             "int"),
    ("JOINTS_0", 5121, True, "found normalized unsigned byte"),
    ("WEIGHTS_0", 5121, False, "components of float, normalized unsigned byte, normalized "
                               "unsigned short, found unsigned byte"),
    ("WEIGHTS_0", 5125, None, "found unsigned int"),
    ("WEIGHTS_0", 5120, True, "found normalized byte"),
    ("indices", 5126, None, "components of unsigned byte, unsigned short, unsigned int, "
                            "found float"),
    ("indices", 5120, None, "found byte"),
    ("indices", 5122, None, "found short"),
])
def test_attribute_component_types(tmp_path, attr, ctype, normalized, match):
    # the data is not rewritten: the type is refused before it is decoded
    _refused(_gltf(tmp_path, _retype(attr, ctype, normalized)), match)


def test_inverse_bind_matrices_and_keys_are_floats(tmp_path):
    def ibm(d):
        d["accessors"].append({"bufferView": 0, "componentType": 5125, "count": 2,
                               "type": "MAT4"})
        d["skins"][0]["inverseBindMatrices"] = len(d["accessors"]) - 1

    _refused(_gltf(tmp_path, ibm), "inverseBindMatrices.*components of float, found "
                                   "unsigned int")
    path = _gltf(tmp_path, lambda d: d["accessors"][d["animations"][0]["samplers"][0][
        "input"]].update(componentType=5123), name="k.gltf", anim=True)
    _, clips = read_gltf(path)
    with pytest.raises(FormatError, match="input.*components of float, found unsigned short"):
        clips["animation_0"]


def test_quantized_positions_with_khr_mesh_quantization(tmp_path):
    b = Builder()
    doc = _doc(b)
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], float)
    doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = b.add(
        V * 65535, 5123, normalized=True)
    doc["extensionsUsed"] = doc["extensionsRequired"] = ["KHR_mesh_quantization"]
    path = write(tmp_path / "q.gltf", doc, b, glb=False)
    assert np.allclose(read_gltf(path)[0].V, V)
    d = json.loads(path.read_text())
    del d["extensionsUsed"], d["extensionsRequired"]
    path.write_text(json.dumps(d))
    _refused(path, "components of float, found normalized unsigned short")


def test_an_accessor_named_for_two_uses_is_checked_for_each(tmp_path):
    # POSITION (VEC3) named as WEIGHTS_0 too, after it was decoded: refused by its type,
    # not an IndexError from the array decoded for the first use
    def edit(d):
        at = d["meshes"][0]["primitives"][0]["attributes"]
        at["WEIGHTS_0"] = at["POSITION"]

    _refused(_gltf(tmp_path, edit), "WEIGHTS_0.*of type VEC4, found VEC3")
    path = _gltf(tmp_path, lambda d: d["animations"][0]["samplers"][0].update(
        output=d["animations"][0]["samplers"][0]["input"]), name="k.gltf", anim=True)
    _, clips = read_gltf(path)
    with pytest.raises(FormatError, match="output.*of type VEC4, found SCALAR"):
        clips["animation_0"]


# (f) base64 in data URIs: every character base64, never dropped
@pytest.mark.parametrize("damage, match", [
    (lambda body: body[:8] + "!!" + body[10:], "base64 data, found invalid characters"),
    (lambda body: body[:8] + "\n " + body[10:], "base64 data, found invalid characters"),
    (lambda body: body[:8] + "%41" + body[11:], "base64 data, found invalid characters"),
    (lambda body: body[:8] + "é" + body[9:], "base64 data, found invalid characters"),
    (lambda body: body[:4] + "==" + body[6:], "base64 data, found invalid characters"),
    (lambda body: body[:5] + "==", r"a data: URI of \d+ bytes \(its byteLength\), found one "
                                   r"of \d+ bytes"),
])
def test_a_data_uri_with_characters_outside_base64(tmp_path, damage, match):
    def edit(d):
        head, body = d["buffers"][0]["uri"].split(",", 1)
        d["buffers"][0]["uri"] = head + "," + damage(body)

    _refused(_gltf(tmp_path, edit), r"buffers\[0\]: " + match)


# (g) GLB versions
@pytest.mark.parametrize("version", [0, 1, 3])
def test_a_glb_of_another_version_is_refused(tmp_path, version):
    path = _gltf(tmp_path, lambda x: x[:4] + struct.pack("<I", version) + x[8:], name="v.glb")
    _refused(path, f"a GLB of version 2, found version {version}")


# (h) numbers that break linear algebra, empty parts: errors naming the file, what was
# expected and what was found (never NumPy's own message)
@pytest.mark.parametrize("edit, match", [
    (lambda d: d["nodes"][0].update(matrix=[1e308, 0, 0, 0, 0, 1e308, 0, 0,
                                            0, 0, 1e308, 0, 0, 0, 0, 1]),
     r"positions of magnitude at most 1e\+12, found 1e\+308"),
    (lambda d: (d["nodes"][0].update(matrix=[1e200, 0, 0, 0, 0, 1e200, 0, 0,
                                             0, 0, 1e200, 0, 0, 0, 0, 1]),
                d["nodes"][1].update(scale=[1e200, 1e200, 1e200])),
     "an overflow"),
    (lambda d: d["nodes"][0].update(rotation=[1e308, 1e308, 0, 0]), None),
    (lambda d: d["nodes"][0].update(rotation=[0, 0, 0, 0]), "a non-zero rotation"),
    (lambda d: d["nodes"][0].update(scale=[0, 0, 0]), None),
    (lambda d: d.update(skins=[]), "a skin"),
    (lambda d: d["skins"][0].update(joints=[]), "at least one joint node"),
    (lambda d: d.update(meshes=[]), "an index >= 0 below 0"),
    (lambda d: d["meshes"][0].update(primitives=[]), "a skinned mesh with triangles"),
    (lambda d: d["meshes"][0]["primitives"][0].update(attributes={}), "a POSITION attribute"),
    (lambda d: d["meshes"][0]["primitives"][0].update(mode=1), "a skinned mesh with triangles"),
    (lambda d: d["meshes"][0]["primitives"][0].update(mode=5), None),
    (lambda d: d["bufferViews"][0].update(byteStride=252), "inside its buffer view"),
    (lambda d: d["bufferViews"][0].update(byteStride=253), "byteStride in 4..252"),
    (lambda d: d["bufferViews"][0].update(byteStride=8), "byteStride of at least .* 12"),
    (lambda d: d["accessors"][0].update(byteOffset=2), "inside its buffer view"),
    (lambda d: d["accessors"][0].update(type="MAT5"), "a componentType in"),
])
@pytest.mark.filterwarnings("ignore:.*is points or lines")
def test_numbers_and_empty_parts_give_a_clear_error(tmp_path, edit, match):
    """Each is refused with one FormatError (or, where the file is merely odd, read)."""
    path = _gltf(tmp_path, edit)
    if match is None:
        try:
            rig, _ = read_gltf(path)
        except FormatError as exc:
            msg = str(exc)
            assert str(path) in msg and "expected" in msg and "found" in msg
        else:
            assert np.isfinite(rig.V).all()
        return
    _refused(path, match)


def test_a_huge_scale_in_an_animation_is_refused_by_name(tmp_path):
    def edit(d):
        s = d["animations"][0]["samplers"][0]
        d["animations"][0]["channels"][0]["target"]["path"] = "translation"
        d["accessors"].append(dict(d["accessors"][s["output"]], type="VEC3", count=2))
        s["output"] = len(d["accessors"]) - 1
        d["nodes"][0]["scale"] = [1e300] * 3

    path = _gltf(tmp_path, edit, name="k.gltf", anim=True)
    try:
        _, clips = read_gltf(path)
        clips["animation_0"]
    except FormatError as exc:
        assert str(path) in str(exc) and "found" in str(exc)


def test_no_output_over_a_buffer_file_the_run_reads(tmp_path, capsys):
    # the buffer lives in "out.glb"; writing the rig there would destroy what it reads
    b = Builder()
    doc = _doc(b)
    path = write(tmp_path / "x.gltf", doc, b, glb=False)
    d = json.loads(path.read_text())
    (tmp_path / "out.glb").write_bytes(bytes(b.data))
    d["buffers"][0]["uri"] = "out.glb"
    path.write_text(json.dumps(d))
    before = (tmp_path / "out.glb").read_bytes()
    assert main(["weights", str(path), "--endpoint", "projection", "-o",
                 str(tmp_path / "out.glb")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "refusing to write over a file this command reads" in err[0]
    assert (tmp_path / "out.glb").read_bytes() == before


@pytest.mark.parametrize("uri, match", [
    ("x" * 5000 + ".bin", "a readable file 'xxxx.*' beside the glTF file, found File name "
                          "too long"),
    ("da ta:application/octet-stream;base64," + "A" * 400, "a readable file|no such file"),
    ("sub", "no such file"),
])
def test_a_buffer_file_that_cannot_be_read(tmp_path, uri, match):
    (tmp_path / "sub").mkdir()
    msg = _refused(_gltf(tmp_path, lambda d: d["buffers"][0].update(uri=uri)), match)
    assert len(msg) < 600


def _chains(tmp_path, up, parts):
    """``up`` nodes above the skeleton's root, and ``parts`` rigid parts each hung below
    the last, under its tip."""
    def edit(d):
        n0 = len(d["nodes"])
        d["nodes"] += [{"children": [n0 + k + 1]} for k in range(up - 1)] + [{"children": [0]}]
        d["scenes"][0]["nodes"] = [n0, 2]
        n1 = len(d["nodes"])
        d["nodes"][1]["children"] = [n1]
        d["nodes"] += [{"mesh": 0, "translation": [0, 0.001, 0], "children": [n1 + k + 1]}
                       for k in range(parts)]
        del d["nodes"][-1]["children"]
        d["skins"].append({"joints": [0, 1]})            # a second skin, one skeleton
        d["nodes"].append({"mesh": 0, "skin": 1})
        d["scenes"][0]["nodes"].append(len(d["nodes"]) - 1)

    return _gltf(tmp_path, edit, name=f"chains{up}.gltf")


def test_deep_chains_of_nodes_are_read_in_linear_work(tmp_path):
    # every walk up the hierarchy once would be quadratic: four times the nodes cost
    # (about) four times the lines of stbs code, not sixteen
    read_gltf(_chains(tmp_path, 10, 1))                 # first calls fill caches
    with Lines() as small:
        read_gltf(_chains(tmp_path, 1250, 125))
    with Lines(5 * small.count):                        # stopped there if it runs over
        read_gltf(_chains(tmp_path, 5000, 500))
    # 20 000 nodes above the root (past Python's recursion limit), 2000 parts below
    up, parts = 20_000, 2_000
    rig, _ = read_gltf(_chains(tmp_path, up, parts))
    assert rig.V.shape == (4 * (2 + parts), 3) and len(rig.meta["gltf"]["rigid"]) == parts
    # the last part hangs 2000 steps of 0.001 above the tip's bind (the origin: the
    # skin has no inverse bind matrices)
    assert np.isclose(rig.V[-4:, 1].min(), parts * 0.001)


@pytest.mark.parametrize("weights, match", [
    ([1e308], r"positions of magnitude at most 1e\+12, found 1e\+308"),
    (["a"], r"default morph.weights: 1 numbers, found \['a'\]"),
    ([0.5, 0.5], "default morph.weights: 1 numbers"),
    ([0.5], None),
    ([1e308] * 2, "morph target offsets times their default weights that are finite, "
                  "found an overflow"),
])
def test_default_morph_weights(tmp_path, weights, match):
    def edit(d):
        prim = d["meshes"][0]["primitives"][0]
        prim["targets"] = [{"POSITION": prim["attributes"]["POSITION"]}] * (
            2 if weights == [1e308] * 2 else 1)
        d["meshes"][0]["weights"] = weights
        d["accessors"][prim["attributes"]["POSITION"]]["max"] = [1e308] * 3

    path = _gltf(tmp_path, edit)
    if match is None:
        assert np.allclose(read_gltf(path)[0].V[1], [1.5, 0, 0])
    else:
        _refused(path, match)
