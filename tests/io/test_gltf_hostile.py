"""Hostile glTF / GLB files, built in the tests: each ends in a MeshError naming the file and the
offending URI, accessor, bufferView, node or extension, and nothing outside the file's folder is
read.  Valid-but-unusual files (sparse accessors, KHR_mesh_quantization) read as the spec says."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest
from test_gltf_files import Doc, cube, cube_doc, glb_bytes

import shapeflow as sf
from shapeflow.io.gltf import mesh_placements, read_gltf


def refused(data: bytes, match: str, name: str = "hostile.gltf", **kw):
    with pytest.raises(sf.MeshError, match=match) as info:
        read_gltf(data, name, **kw)
    assert str(info.value).startswith(name)
    return str(info.value)


# ---------------------------------------------------------------- URIs stay inside the folder

def external(tmp_path, uri: str, **kw):
    """The cube with its buffer in a file: the .gltf names it by ``uri``."""
    d = cube_doc()
    (tmp_path / "cube.bin").write_bytes(bytes(d.blobs[0]))
    path = tmp_path / "model.gltf"
    path.write_bytes(d.gltf({0: uri}))
    return path


def test_a_buffer_beside_the_file_is_read(tmp_path):
    m = sf.load(external(tmp_path, "cube.bin"))
    np.testing.assert_array_equal(m.vertices, cube()[0])
    sub = tmp_path / "data dir"
    sub.mkdir()
    (sub / "cube.bin").write_bytes((tmp_path / "cube.bin").read_bytes())
    assert sf.load(external(tmp_path, "data%20dir/cube.bin")).n_faces == 12     # percent-encoded


@pytest.mark.parametrize("uri, match", [
    ("/etc/passwd", "absolute path"),
    ("/proc/self/environ", "absolute path"),
    ("/dev/zero", "absolute path"),
    ("%2Fetc%2Fpasswd", "absolute path"),
    ("../outside.bin", r"leaves the glTF file's folder \('\.\.'\)"),
    ("sub/../../outside.bin", "leaves the glTF file's folder"),
    ("file:///etc/passwd", "scheme"),
    ("https://example.com/cube.bin", "scheme"),
    ("C:/Windows/cube.bin", "scheme"),
    ("cube%00.bin", "not a file name"),
    ("%ff%fe.bin", "percent-encoded"),
])
def test_a_uri_leaving_the_folder_is_refused_by_name(tmp_path, uri, match):
    (tmp_path.parent / "outside.bin").write_bytes(b"\0" * 64)
    path = external(tmp_path, uri)
    msg = refused(path.read_bytes(), match, name=str(path))
    assert repr(uri) in msg


def test_a_symlink_leading_out_of_the_folder_is_refused(tmp_path):
    inner = tmp_path / "model"
    inner.mkdir()
    secret = tmp_path / "secret.bin"
    secret.write_bytes(bytes(cube_doc().blobs[0]))           # a valid buffer: only the place is wrong
    (inner / "cube.bin").symlink_to(secret)
    path = external(inner, "cube.bin")
    (inner / "cube.bin").unlink()
    (inner / "cube.bin").symlink_to(secret)
    refused(path.read_bytes(), f"symbolic link leading outside.*{secret}", name=str(path))
    # a link that stays inside the folder is followed
    (inner / "cube.bin").unlink()
    (inner / "real.bin").write_bytes(secret.read_bytes())
    (inner / "cube.bin").symlink_to(inner / "real.bin")
    assert sf.load(path).n_faces == 12


@pytest.mark.parametrize("target", ["/proc/self/environ", "/dev/zero"])
def test_links_to_proc_and_dev_are_refused(tmp_path, target):
    path = external(tmp_path, "cube.bin")
    (tmp_path / "cube.bin").unlink()
    (tmp_path / "cube.bin").symlink_to(target)
    refused(path.read_bytes(), "symbolic link leading outside", name=str(path))


def test_a_fifo_or_device_in_the_folder_is_refused_without_waiting(tmp_path):
    path = external(tmp_path, "cube.bin")
    (tmp_path / "cube.bin").unlink()
    os.mkfifo(tmp_path / "cube.bin")         # opening it for reading would wait for a writer
    refused(path.read_bytes(), "not a regular file", name=str(path))


def test_a_buffer_shorter_than_declared_is_refused(tmp_path):
    path = external(tmp_path, "cube.bin")
    (tmp_path / "cube.bin").write_bytes(b"\0" * 10)
    refused(path.read_bytes(), "holds 10 bytes", name=str(path))


def test_image_uris_are_checked_like_buffers(tmp_path):
    d = cube_doc()
    d.j["images"] = [{"uri": "../../etc/passwd"}]
    refused(d.gltf(), r"image 0 '\.\./\.\./etc/passwd' leaves", name=str(tmp_path / "m.gltf"))
    d.j["images"] = [{"uri": "/etc/passwd"}]
    refused(d.gltf(), "image 0 '/etc/passwd' is an absolute path", name=str(tmp_path / "m.gltf"))
    d.j["images"] = [{"uri": "missing.png"}]                  # absent texture: the mesh still reads
    assert read_gltf(d.gltf(), str(tmp_path / "m.gltf")).n_faces == 12


def test_external_files_false_refuses_every_file_uri(tmp_path):
    """A file read on its own (an upload) holds data: URIs only: a buffer or an image naming a file
    is refused by its URI, even one that exists beside it."""
    path = external(tmp_path, "cube.bin")
    assert read_gltf(path.read_bytes(), str(path)).n_faces == 12
    refused(path.read_bytes(), "buffer 0 refers to the file 'cube.bin'.*upload", name=str(path),
            external_files=False)
    d = cube_doc()
    (tmp_path / "tex.png").write_bytes(b"\x89PNG....")
    d.j["images"] = [{"uri": "tex.png"}]
    refused(d.gltf(), "image 0 refers to the file 'tex.png'", name=str(tmp_path / "up.gltf"), external_files=False)
    d.j["images"] = [{"uri": "data:image/png;base64,iVBORw0K"}]
    assert read_gltf(d.gltf(), "up.gltf", external_files=False).n_faces == 12
    assert read_gltf(cube_doc().glb(), "up.glb", external_files=False).n_faces == 12


def test_data_uris_are_decoded_strictly():
    d = cube_doc()
    d.finish_buffers()
    good = d.j["buffers"][0]["uri"]
    for bad, match in [(good.replace(";base64", ""), "not base64"), (good[:-3] + "!!=", "base64 is broken"),
                       (good + "A", "base64 is broken")]:
        d.j["buffers"][0]["uri"] = bad
        refused(json.dumps(d.j).encode(), match)


# ---------------------------------------------------------------- accessors and bufferViews

def broken(change) -> bytes:
    d = cube_doc()
    d.finish_buffers()
    change(d.j)
    return json.dumps(d.j).encode()


def acc0(**kw):
    return lambda j: j["accessors"][0].update(kw)


def view0(**kw):
    return lambda j: j["bufferViews"][0].update(kw)


@pytest.mark.parametrize("change, match", [
    (view0(byteStride=-12), "byteStride -12 is not a multiple of 4 from 4 to 252"),
    (view0(byteStride=-(2 ** 62)), "byteStride"),
    (view0(byteStride=14), "byteStride 14 is not a multiple of 4"),
    (view0(byteStride=8), "byteStride 8 is less than one element"),
    (view0(byteStride=256), "byteStride 256"),
    (view0(byteStride=12.0), "byteStride 12.0"),
    (view0(byteOffset=-4), "bufferView 0: byteOffset -4"),
    (acc0(byteOffset=-12), r"accessor 0 \(POSITION\): byteOffset -12"),
    (acc0(byteOffset=2), "byteOffset 2 is not a multiple of its component size 4"),
    (acc0(byteOffset=12), "run past the end of bufferView 0"),
    (acc0(count=2 ** 62), "run past the end of bufferView 0"),
    (acc0(count=-1), "count -1"),
    (acc0(count="8"), "count '8'"),
    (view0(byteLength=2 ** 64), "runs past the end of buffer 0"),
    (view0(buffer=7), "buffer 7, which does not exist"),
    (acc0(bufferView=99), "bufferView 99, which does not exist"),
    (acc0(type="VEC2"), "VEC2 of componentType 5126, which glTF does not allow for POSITION"),
    (acc0(componentType=5124), "componentType 5124"),
    (acc0(componentType=5125), "componentType 5125, which glTF does not allow for POSITION"),
    (acc0(type="MAT9"), "type 'MAT9'"),
    (acc0(normalized="yes"), "normalized 'yes'"),
    (lambda j: j["accessors"][1].update(componentType=5126), r"accessor 1 \(indices\).*componentType 5126"),
    (lambda j: j["accessors"][1].update(count=35), "35 indices are not whole triangles"),
    (lambda j: j["meshes"][0]["primitives"][0].update(indices=5), "indices refers to accessor 5"),
    (lambda j: j["meshes"][0]["primitives"][0]["attributes"].update(POSITION=-1), "refers to accessor -1"),
    (lambda j: j["meshes"][0]["primitives"][0].update(mode=99), "mode 99"),
    (lambda j: j.update(accessors=[5, 6]), "accessor 0 is not an object"),
    (lambda j: j.update(nodes="x"), "'nodes' is not an array"),
    (lambda j: j["buffers"][0].update(byteLength=-1), "buffer 0: byteLength -1"),
])
def test_bad_accessors_and_views_are_refused_before_any_array(change, match):
    refused(broken(change), match)


def test_index_values_beyond_the_vertices_are_refused():
    d = cube_doc()
    d.blobs[0][96:98] = np.array([8], "<u2").tobytes()           # the first index: vertex 8 of 8
    refused(d.gltf(), r"index 8 \(accessor 1\) is not below its vertex count 8")


def test_attribute_counts_must_agree():
    d = cube_doc()
    d.j["meshes"][0]["primitives"][0]["attributes"]["NORMAL"] = d.accessor(np.zeros((7, 3), "<f4"), "VEC3")
    refused(d.gltf(), "NORMAL .* has 7 elements, POSITION has 8")


LARGE_NEGATIVE_STRIDE = r"""
import json, sys
sys.path.insert(0, {tests!r})
from test_gltf_files import cube_doc
from shapeflow.errors import MeshError
from shapeflow.io.gltf import read_gltf
d = cube_doc()
d.finish_buffers()
d.j["bufferViews"][0]["byteStride"] = -(2 ** 40)
d.j["accessors"][0]["byteOffset"] = 2 ** 40
try:
    read_gltf(json.dumps(d.j).encode(), "stride.gltf")
except MeshError as exc:
    print("MeshError:", exc)
"""


def test_a_large_negative_stride_is_refused_in_a_child_that_does_not_crash():
    """The class of stride that went through as_strided: run apart, so a crash would show as a signal."""
    tests = os.path.dirname(os.path.abspath(__file__))
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([os.path.join(os.path.dirname(os.path.dirname(tests)), "src"),
                                                      os.environ.get("PYTHONPATH", "")]))
    out = subprocess.run([sys.executable, "-c", LARGE_NEGATIVE_STRIDE.format(tests=tests)], capture_output=True,
                         text=True, env=env, timeout=120)
    assert out.returncode == 0, out.stderr
    assert "MeshError: stride.gltf: bufferView 0: byteStride -1099511627776" in out.stdout


ZERO_RULE = r"exceed the {limit} a file may declare without bytes behind them \(max\(65,536, 16 × the {nbytes} bytes"


def test_accessors_without_buffer_view_are_bounded_by_the_files_bytes(tmp_path):
    """Zeros need no bytes: a file may declare max(65,536, 16 × its bytes and its buffers') of them."""
    d = cube_doc()
    d.j["accessors"][0].pop("bufferView")
    for count in (10 ** 13, 10 ** 400, 65_537):
        d.j["accessors"][0]["count"] = count
        data = d.gltf()
        msg = refused(data, ZERO_RULE.format(limit="65,536", nbytes=f"{len(data):,}"))
        assert f"its {count:,} elements (zeros)" in msg
    d.j["accessors"][0]["count"] = 65_536                        # at the floor: zeros, as the spec says
    m = read_gltf(d.gltf(), "z.gltf")
    assert m.n_vertices == 65_536 and not m.vertices.any()
    # a buffer file of 8,192 bytes beside it raises the limit to 16 × (its bytes + the file's)
    d.j["accessors"].append({"componentType": 5126, "type": "VEC3", "count": 75_000})
    d.j["meshes"][0]["primitives"][0]["attributes"]["NORMAL"] = 2
    d.j["accessors"][0]["count"] = d.j["accessors"][2]["count"] = 75_000
    (tmp_path / "pad.bin").write_bytes(b"\0" * 8_192)
    d.j["buffers"].append({"byteLength": 8_192})
    d.blobs.append(bytearray(8_192))
    path = tmp_path / "z.gltf"
    path.write_bytes(d.gltf({1: "pad.bin"}))
    limit = 16 * (os.path.getsize(path) + 8_192)
    assert 75_000 < limit < 150_000                              # one accessor fits, both do not
    with pytest.raises(sf.MeshError, match=ZERO_RULE.format(limit=f"{limit:,}",
                                                            nbytes=f"{os.path.getsize(path) + 8_192:,}")) as info:
        sf.load(path)
    assert "accessor 2 (NORMAL: VEC3) has no bufferView: its 75,000 elements (zeros) and the 75,000 of earlier" \
        in str(info.value)
    d.j["meshes"][0]["primitives"][0]["attributes"]["NORMAL"] = 0    # one accessor in two roles: counted once
    path.write_bytes(d.gltf({1: "pad.bin"}))
    assert sf.load(path).n_vertices == 75_000


def test_zeros_under_sparse_values_count_against_the_same_limit():
    d = sparse_doc(with_base=False)
    d.j["accessors"][0]["count"] = 65_537
    data = d.gltf()
    refused(data, ZERO_RULE.format(limit="65,536", nbytes=f"{len(data):,}"))


def test_the_cli_reads_the_most_zeros_a_small_file_may_hold_in_one_pass(tmp_path):
    """65,536 coinciding zeros: welded by one sort, not compared pair by pair (2·10⁹ pairs); a hang
    detector, not a clock, bounds the run."""
    d = cube_doc()
    d.j["accessors"][0].pop("bufferView")
    d.j["accessors"][0]["count"] = 65_536
    (tmp_path / "zeros.glb").write_bytes(d.glb())
    d.j["accessors"][0]["count"] = 65_537
    (tmp_path / "more.glb").write_bytes(d.glb())
    env = dict(os.environ, PYTHONPATH=os.path.join(os.path.dirname(__file__), "..", "..", "src"))
    run = [sys.executable, "-m", "shapeflow", "info"]
    out = subprocess.run(run + ["zeros.glb"], capture_output=True, text=True, cwd=tmp_path, env=env, timeout=300)
    assert out.returncode == 0 and out.stderr == "", out.stderr
    assert "vertices        65536" in out.stdout and "65535 vertices share a position" in out.stdout
    out = subprocess.run(run + ["more.glb"], capture_output=True, text=True, cwd=tmp_path, env=env, timeout=300)
    assert out.returncode == 2 and out.stderr.count("\n") == 1
    assert "more.glb: accessor 0 (POSITION: VEC3) has no bufferView: its 65,537 elements (zeros)" in out.stderr


def sparse_doc(with_base: bool, indices=(1, 6), values=((5.0, 6.0, 7.0), (-1.0, -2.0, -3.0))) -> Doc:
    V, T = cube()
    d = cube_doc()
    acc = d.j["accessors"][0]
    if not with_base:
        acc.pop("bufferView")
    acc["sparse"] = {"count": len(indices),
                     "indices": {"bufferView": d.view(np.array(indices, "<u2").tobytes()), "componentType": 5123},
                     "values": {"bufferView": d.view(np.array(values, "<f4").tobytes())}}
    return d


@pytest.mark.parametrize("with_base", [True, False])
def test_sparse_accessors_are_read_as_the_spec_says(with_base):
    V, _ = cube()
    expected = V.copy() if with_base else np.zeros_like(V)
    expected[[1, 6]] = [[5, 6, 7], [-1, -2, -3]]
    np.testing.assert_array_equal(read_gltf(sparse_doc(with_base).gltf(), "s.gltf").vertices, expected)


@pytest.mark.parametrize("indices, match", [((6, 1), "not strictly increasing"), ((1, 1), "not strictly"),
                                            ((1, 8), "below its count 8")])
def test_bad_sparse_indices_are_refused(indices, match):
    refused(sparse_doc(True, indices).gltf(), match)


def test_sparse_parts_past_their_views_are_refused():
    d = sparse_doc(True)
    d.j["accessors"][0]["sparse"]["count"] = 3
    refused(d.gltf(), "sparse indices: 3 elements of 2 bytes from byte 0 run past the end")


# ---------------------------------------------------------------- the node graph

class Counting(dict):
    """A node whose ``children`` reads are counted."""

    reads = 0

    def get(self, key, default=None):
        if key == "children":
            Counting.reads += 1
        return super().get(key, default)


def dag(depth: int) -> list:
    """2 nodes per level, each the parent of both nodes of the next: 2^depth paths to the bottom."""
    nodes = []
    for level in range(depth):
        kids = [2 * level + 2, 2 * level + 3] if level < depth - 1 else []
        nodes += [Counting(children=list(kids)), Counting(children=list(kids), mesh=0)]
    return nodes


def test_a_shared_child_dag_of_depth_40_is_refused_after_one_pass():
    """2^40 root-to-leaf paths: a walk that follows them never ends; each node's children are read
    at most once before the shared node is named."""
    Counting.reads = 0
    doc = {"nodes": dag(40), "meshes": [{"primitives": []}], "scenes": [{"nodes": [0, 1]}]}
    with pytest.raises(sf.MeshError, match=r"node 2 has two parents \(nodes 0 and 1\)"):
        mesh_placements(doc, "dag.gltf")
    assert Counting.reads <= 80


def test_a_deep_tree_is_walked_once_per_node():
    """A chain of 5,000 nodes (deeper than Python's recursion limit) and a binary tree: each node's
    children are read once, each mesh placed by its first node."""
    Counting.reads = 0
    n = 5000
    chain = [Counting(children=[i + 1], translation=[1.0, 0.0, 0.0]) for i in range(n - 1)]
    chain.append(Counting(mesh=0, translation=[1.0, 0.0, 0.0]))
    first, count = mesh_placements({"nodes": chain, "meshes": [{}], "scenes": [{"nodes": [0]}]}, "chain.gltf")
    assert Counting.reads == n and count == {0: 1}
    np.testing.assert_array_equal(first[0][:3, 3], [n, 0, 0])
    Counting.reads = 0
    tree = [Counting(children=[2 * i + 1, 2 * i + 2] if 2 * i + 2 < 1023 else [], mesh=0) for i in range(1023)]
    first, count = mesh_placements({"nodes": tree, "meshes": [{}]}, "tree.gltf")     # no scenes: the roots
    assert Counting.reads == 1023 and count == {0: 1023}


@pytest.mark.parametrize("nodes, scene, match", [
    ([{"children": [1]}, {"children": [0], "mesh": 0}], [], r"node 0 lies on or below a cycle"),
    ([{"children": [0], "mesh": 0}], [0], r"node 0 is its own child"),
    ([{"children": [1]}, {"children": [2]}, {"children": [1], "mesh": 0}], [0], "node 1 has two parents"),
    ([{"children": [1]}, {"mesh": 0}], [0, 1], "lists node 1 as a root, but it is the child of node 0"),
    ([{"mesh": 0}], [0, 0], "lists node 0 twice"),
    ([{"children": [5]}], [0], "children is not a list of node indices below 1"),
    ([{"mesh": 3}], [0], "node 0: mesh 3"),
    ([{"matrix": [1] * 15}], [0], "node 0: matrix is not 16 finite numbers"),
    ([{"translation": [10 ** 400, 0, 0], "mesh": 0}], [0], "node 0: translation is not 3 finite numbers"),
    ([{"translation": [1e308, 0, 0], "children": [1]}, {"translation": [1e308, 0, 0], "mesh": 0}], [0],
     "node 1: its world transform overflows"),
])
def test_cycles_shared_nodes_and_bad_nodes_are_refused_by_name(nodes, scene, match):
    d = cube_doc()
    d.j["nodes"], d.j["scenes"] = nodes, [{"nodes": scene}]
    refused(d.gltf(), match)


# ---------------------------------------------------------------- extensions

@pytest.mark.parametrize("ext", ["KHR_draco_mesh_compression", "EXT_meshopt_compression", "EXT_mesh_gpu_instancing",
                                 "KHR_something_new"])
def test_a_required_extension_that_changes_geometry_is_refused_by_name(ext):
    d = cube_doc()
    d.j["extensionsUsed"] = d.j["extensionsRequired"] = [ext, "KHR_materials_unlit", "KHR_texture_transform"]
    msg = refused(d.gltf(), f"requires the glTF extension.*{ext}, which shapeflow cannot read")
    assert "KHR_materials_unlit" not in msg


def test_a_draco_primitive_without_fallback_is_refused():
    d = cube_doc()
    d.j["extensionsUsed"] = ["KHR_draco_mesh_compression"]
    d.j["accessors"][0].pop("bufferView")
    d.j["meshes"][0]["primitives"][0]["extensions"] = {"KHR_draco_mesh_compression": {"bufferView": 0}}
    refused(d.gltf(), "mesh 0 primitive 0 is compressed with KHR_draco_mesh_compression and has no uncompressed")


def quantized_doc():
    """The cube with int16 normalized positions (the node scales them back), int8 normalized
    normals interleaved with them (stride 12) and uint16 normalized texture coordinates."""
    V, T = cube()
    q = np.rint(V * 0.5 * 32767).astype("<i2")                      # positions in [-0.5, 0.5]
    n = np.rint(V / np.sqrt(3) * 127).astype("<i1")
    rows = np.zeros((8, 12), np.uint8)
    rows[:, 0:6] = q.view(np.uint8).reshape(8, 6)
    rows[:, 6:8] = 0xAB                                               # padding bytes
    rows[:, 8:11] = n.view(np.uint8).reshape(8, 3)
    rows[:, 11] = 0xCD
    uv = np.rint(np.stack([V[:, 0] + 1, V[:, 1] + 1], 1) / 2 * 65535).astype("<u2")
    d = Doc()
    view = d.view(rows.tobytes(), stride=12)
    d.j["bufferViews"][view]["target"] = 34962
    pos = d.accessor(q, "VEC3", view=view, normalized=True, minmax=True)
    nrm = d.accessor(n, "VEC3", view=view, offset=8, normalized=True)
    tex = d.accessor(uv, "VEC2", normalized=True)
    idx = d.accessor(T.reshape(-1).astype("<u2"), "SCALAR")
    d.node(mesh=d.mesh({"attributes": {"POSITION": pos, "NORMAL": nrm, "TEXCOORD_0": tex}, "indices": idx}),
           scale=[2.0, 2.0, 2.0])
    d.j["extensionsUsed"] = d.j["extensionsRequired"] = ["KHR_mesh_quantization"]
    return d, q, n, uv, rows


def test_quantized_attributes_are_read_as_the_spec_maps_them():
    d, q, n, uv, _ = quantized_doc()
    for data in (d.gltf(), d.glb()):
        m = read_gltf(data, "q.glb")
        np.testing.assert_allclose(m.vertices, q / 32767.0 * 2.0, rtol=1e-15)
        corner_n = sf.mesh.attributes.expand(m.corner_attributes["normal"])
        raw = np.maximum(n / 127.0, -1.0)[m.face_indices]
        np.testing.assert_allclose(corner_n, raw / np.linalg.norm(raw, axis=1, keepdims=True), rtol=1e-12)
        np.testing.assert_allclose(sf.mesh.attributes.expand(m.corner_attributes["uv"]),
                                   (uv / 65535.0)[m.face_indices], rtol=1e-15)
    plain = quantized_doc()[0]
    plain.j["accessors"][0].pop("normalized")                          # unnormalized int16: integer values
    np.testing.assert_array_equal(read_gltf(plain.gltf(), "q16.gltf").vertices, q * 2.0)
    int8 = quantized_doc()[0]
    int8.j["accessors"][0].update(componentType=5120)                 # the same bytes read as int8: allowed
    assert read_gltf(int8.gltf(), "q8.gltf").n_vertices == 8
    bad = quantized_doc()[0]
    bad.j["accessors"][1].update(componentType=5121)                  # uint8 normals: not allowed
    refused(bad.gltf(), "componentType 5121 normalized, which glTF does not allow for NORMAL")


# ---------------------------------------------------------------- containers and JSON

@pytest.mark.parametrize("data, match", [
    (b"glTF" + bytes(8), "too short"),
    (glb_bytes(b"{}", None, version=1), "GLB version 1"),
    (glb_bytes(b'{"asset":{"version":"2.0"}}', None)[:-3], "declares .* bytes, the file has"),
    (b"glTF" + (2).to_bytes(4, "little") + (24).to_bytes(4, "little") + (4000).to_bytes(4, "little") + b"JSON{}  ",
     "chunk at byte 12 declares 4000 bytes; 4 remain"),
    (glb_bytes(b"\x00\x01", None).replace(b"JSON", b"BIN\x00"), "first GLB chunk is not JSON"),
    (b'{"asset": {"version": "1.0"}}', "glTF version '1.0'"),
    (b'{"asset": {"version": "2.0"}, "x": NaN}', "NaN is not a JSON number"),
    (b'{"asset": {"version": "2.0"}, "x": 1e999}', "beyond double precision"),
    (b"[" * 100000 + b"]" * 100000, "nested too deeply|not a glTF file"),
    (b'{"x": "\xff"}', "not UTF-8"),
    (b"[1, 2]", "the JSON is not an object"),
    (b'{"x": ' + b"9" * 5000 + b"}", "not a glTF file"),
])
def test_broken_containers_and_json_are_refused(data, match):
    refused(data, match, name="broken.glb")


def test_a_glb_whose_buffer_has_no_chunk_is_refused():
    d = cube_doc()
    d.finish_buffers(glb=True)
    refused(glb_bytes(json.dumps(d.j).encode(), None), "buffer 0 has no uri.*has none", name="c.glb")
    d2 = cube_doc(2)
    d2.finish_buffers(glb=True)
    d2.j["buffers"][1].pop("uri")
    refused(glb_bytes(json.dumps(d2.j).encode(), bytes(d2.blobs[0])), "buffer 1 has no uri", name="c.glb")


def test_load_names_the_file_for_every_refusal(tmp_path):
    p = tmp_path / "x.glb"
    d = cube_doc()
    d.j["accessors"][0]["count"] = -8
    p.write_bytes(d.glb())
    with pytest.raises(sf.MeshError, match=f"^{p}: accessor 0 .*count -8"):
        sf.load(p)
