"""Writing glTF documents back: every written file is read again with pygltflib and NumPy by hand
(test_gltf_files.decode, never shapeflow's reader) and compared with values derived in the test:
positions and normals in the accessor's own type, every other accessor and byte unchanged."""

from __future__ import annotations

import base64
import warnings

import numpy as np
import pytest
from test_gltf_files import Doc, cube, cube_doc, decode, element_bytes, load
from test_gltf_hostile import quantized_doc

import shapeflow as sf


def vertex_normals(V, T):
    """Area-weighted unit vertex normals of triangles T, computed here."""
    fn = np.cross(V[T[:, 1]] - V[T[:, 0]], V[T[:, 2]] - V[T[:, 0]])
    n = np.zeros_like(V)
    for k in range(3):
        np.add.at(n, T[:, k], fn)
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def save_quietly(path, mesh):
    with warnings.catch_warnings():
        warnings.simplefilter("error", sf.DataLossWarning)       # nothing may be lost here
        sf.save(path, mesh)


@pytest.mark.parametrize("ext", ["glb", "gltf"])
def test_quantized_interleaved_attributes_are_requantized_in_place(tmp_path, ext):
    """int16 normalized positions and int8 normalized normals sharing a stride-12 bufferView:
    new values in int16 / int8 by the spec's rounding, padding and neighbours untouched."""
    d, q, n, uv, rows = quantized_doc()
    src = tmp_path / f"q.{ext}"
    src.write_bytes(d.glb() if ext == "glb" else d.gltf())
    m = sf.load(src)
    new = m.vertices * 0.9 + [0.05, -0.02, 0.01]                  # world; the node scales by 2
    out = tmp_path / f"out.{ext}"
    save_quietly(out, m.with_vertices(new))
    g, blobs = load(out)
    expected = np.rint(new / 2.0 * 32767).astype("<i2")
    np.testing.assert_array_equal(decode(g, blobs, 0), expected)
    V, T = cube()
    want_n = np.rint(vertex_normals(new, T) * 127)                 # a uniform scale keeps directions
    assert np.abs(decode(g, blobs, 1).astype(int) - want_n).max() <= 1
    assert (decode(g, blobs, 1).astype(int) == want_n).mean() > 0.9
    view = np.frombuffer(blobs[0], np.uint8, 96, g.bufferViews[0].byteOffset or 0).reshape(8, 12)
    assert (view[:, 6:8] == 0xAB).all() and (view[:, 11] == 0xCD).all()         # padding bytes
    np.testing.assert_array_equal(decode(g, blobs, 2), uv)                       # texture coordinates
    np.testing.assert_array_equal(decode(g, blobs, 3).reshape(-1, 3), T)         # triangles
    a = g.accessors[0]
    assert (a.componentType, a.normalized) == (5122, True)
    assert a.min == expected.min(0).tolist() and a.max == expected.max(0).tolist()
    assert g.extensionsRequired == ["KHR_mesh_quantization"]
    assert [(v.byteOffset, v.byteLength, v.byteStride) for v in g.bufferViews] == \
        [(v["byteOffset"], v["byteLength"], v.get("byteStride")) for v in d.j["bufferViews"]]


def test_quantized_positions_that_leave_their_range_become_a_float_accessor(tmp_path):
    d, q, n, uv, rows = quantized_doc()
    src = tmp_path / "q.glb"
    src.write_bytes(d.glb())
    m = sf.load(src)
    new = m.vertices * 3.0                                       # local |x| = 1.5: beyond int16 normalized
    save_quietly(tmp_path / "out.glb", m.with_vertices(new))
    g, blobs = load(tmp_path / "out.glb")
    a = g.accessors[0]
    assert (a.componentType, a.normalized, a.byteOffset or 0) == (5126, False, 0)
    assert a.bufferView == len(d.j["bufferViews"])               # a new bufferView, at the end
    np.testing.assert_array_equal(decode(g, blobs, 0), (new / 2.0).astype("<f4"))
    assert a.min == [float(x) for x in (new / 2.0).astype("<f4").min(0)]
    old = np.frombuffer(blobs[0], np.uint8, 96, g.bufferViews[0].byteOffset or 0).reshape(8, 12)
    np.testing.assert_array_equal(old[:, :6], rows[:, :6])       # the old positions' bytes are left alone
    assert g.accessors[1].componentType == 5120 and g.accessors[1].bufferView == 0
    np.testing.assert_array_equal(decode(g, blobs, 2), uv)


def interleaved_float_doc():
    """The cube with float positions, normals and UVs interleaved (stride 32)."""
    V, T = cube()
    rows = np.zeros(8, [("p", "<f4", 3), ("n", "<f4", 3), ("t", "<f4", 2)])
    rows["p"], rows["n"], rows["t"] = V, V / np.sqrt(3), V[:, :2] * 0.5 + 0.5
    d = Doc()
    view = d.view(rows.tobytes(), stride=32)
    pos = d.accessor(rows["p"], "VEC3", view=view, minmax=True)
    nrm = d.accessor(rows["n"], "VEC3", view=view, offset=12)
    tex = d.accessor(rows["t"], "VEC2", view=view, offset=24)
    idx = d.accessor(T.reshape(-1).astype("<u4"), "SCALAR")
    d.node(mesh=d.mesh({"attributes": {"POSITION": pos, "NORMAL": nrm, "TEXCOORD_0": tex}, "indices": idx}))
    return d, rows


def test_interleaved_float_attributes_are_written_in_place(tmp_path):
    d, rows = interleaved_float_doc()
    (tmp_path / "f.glb").write_bytes(d.glb())
    m = sf.load(tmp_path / "f.glb")
    rng = np.random.default_rng(1)
    new = m.vertices + rng.normal(0, 0.05, m.vertices.shape)
    save_quietly(tmp_path / "out.glb", m.with_vertices(new))
    g, blobs = load(tmp_path / "out.glb")
    np.testing.assert_array_equal(decode(g, blobs, 0), new.astype("<f4"))
    np.testing.assert_allclose(decode(g, blobs, 1), vertex_normals(new, cube()[1]), atol=1e-6)
    np.testing.assert_array_equal(element_bytes(g, blobs, 2), element_bytes(*load(tmp_path / "f.glb"), 2))
    assert len(g.bufferViews) == 2 and g.accessors[0].bufferView == 0
    assert g.accessors[0].min == [float(x) for x in new.astype("<f4").min(0)]
    assert g.accessors[0].max == [float(x) for x in new.astype("<f4").max(0)]


def test_primitives_sharing_positions_share_vertices_and_write_them_once(tmp_path):
    """Two primitives (two materials) of one mesh index halves of one POSITION accessor: one vertex
    each, one value each in the file."""
    V, T = cube()
    d = Doc()
    pos = d.accessor(V.astype("<f4"), "VEC3", minmax=True)
    halves = [d.accessor(T[:6].reshape(-1).astype("<u2"), "SCALAR"), d.accessor(T[6:].reshape(-1).astype("<u2"),
                                                                                   "SCALAR")]
    d.j["materials"] = [{"name": "a"}, {"name": "b"}]
    d.node(mesh=d.mesh(*[{"attributes": {"POSITION": pos}, "indices": h, "material": k}
                         for k, h in enumerate(halves)]))
    (tmp_path / "s.gltf").write_bytes(d.gltf())
    m = sf.load(tmp_path / "s.gltf")
    assert m.n_vertices == 8 and m.n_faces == 12
    np.testing.assert_array_equal(m.face_attributes["primitive"], np.repeat([0, 1], 6))
    new = V * 0.5 + [1.0, 0.0, 0.0]
    save_quietly(tmp_path / "out.gltf", m.with_vertices(new))
    g, blobs = load(tmp_path / "out.gltf")
    np.testing.assert_array_equal(decode(g, blobs, 0), new.astype("<f4"))
    assert [p.material for p in g.meshes[0].primitives] == [0, 1]


def two_placements(tmp_path, subset: bool):
    """Mesh 0 (node at the origin) and mesh 1 (node at x = 10) share POSITION accessor 0; mesh 1
    uses the whole cube or (``subset``) only its first side (vertices 0-3)."""
    V, T = cube()
    d = Doc()
    pos = d.accessor(V.astype("<f4"), "VEC3", minmax=True)
    full = d.accessor(T.reshape(-1).astype("<u2"), "SCALAR")
    side = d.accessor(T[[0, 6]].reshape(-1).astype("<u2"), "SCALAR")
    d.node(mesh=d.mesh({"attributes": {"POSITION": pos}, "indices": full}))
    d.node(mesh=d.mesh({"attributes": {"POSITION": pos}, "indices": side if subset else full}),
           translation=[10.0, 0.0, 0.0])
    (tmp_path / "two.glb").write_bytes(d.glb())
    return sf.load(tmp_path / "two.glb"), V


def test_an_accessor_shared_by_two_placements_holds_one_value_per_vertex(tmp_path):
    m, V = two_placements(tmp_path, subset=False)
    assert m.n_vertices == 16
    same = np.concatenate([V * 0.5, V * 0.5 + [10.0, 0, 0]])     # both copies moved alike: nothing lost
    save_quietly(tmp_path / "same.glb", m.with_vertices(same))
    g, blobs = load(tmp_path / "same.glb")
    np.testing.assert_array_equal(decode(g, blobs, 0), (V * 0.5).astype("<f4"))
    differ = np.concatenate([V * 0.5, V * 0.7 + [10.0, 0, 0]])
    with pytest.warns(sf.DataLossWarning, match=r"accessor 0 \(POSITION\) is shared by mesh 0, mesh 1, which moved "
                                                r"differently \(by up to 0\.1\); it holds their mean"):
        sf.save(tmp_path / "differ.glb", m.with_vertices(differ))
    g, blobs = load(tmp_path / "differ.glb")
    np.testing.assert_allclose(decode(g, blobs, 0), V * 0.6, rtol=1e-7)


def test_a_shared_accessor_takes_the_mean_only_of_the_copies_that_use_each_vertex(tmp_path):
    m, V = two_placements(tmp_path, subset=True)        # mesh 1 uses vertices 0-3 only
    new = np.concatenate([V * 0.5, V * 0.7 + [10.0, 0, 0]])
    with pytest.warns(sf.DataLossWarning, match="moved differently"):
        sf.save(tmp_path / "out.glb", m.with_vertices(new))
    g, blobs = load(tmp_path / "out.glb")
    expected = V * 0.5
    expected[:4] = V[:4] * 0.6
    np.testing.assert_allclose(decode(g, blobs, 0), expected, rtol=1e-7)


@pytest.mark.parametrize("ext", ["glb", "gltf"])
def test_a_file_with_two_buffers_is_written_back_with_both(tmp_path, ext):
    """Positions in buffer 1 (a file beside a GLB), indices and UVs in buffer 0: the output keeps
    both buffers and every bufferView as it was, positions changed only."""
    V, T = cube()
    d = Doc(n_buffers=2)
    pos = d.accessor(V.astype("<f4"), "VEC3", buffer=1, minmax=True)
    tex = d.accessor((V[:, :2] * 0.5 + 0.5).astype("<f4"), "VEC2")
    idx = d.accessor(T.reshape(-1).astype("<u2"), "SCALAR")
    d.node(mesh=d.mesh({"attributes": {"POSITION": pos, "TEXCOORD_0": tex}, "indices": idx}))
    (tmp_path / "extra.bin").write_bytes(bytes(d.blobs[1]))
    src = tmp_path / "two.glb"
    src.write_bytes(d.glb({1: "extra.bin"}))
    m = sf.load(src)
    new = V * 0.8
    save_quietly(tmp_path / f"out.{ext}", m.with_vertices(new))
    g, blobs = load(tmp_path / f"out.{ext}")                      # data: URIs or the chunk, never a file
    assert len(g.buffers) == 2 and (g.buffers[0].uri is None) == (ext == "glb")
    assert [len(b) for b in blobs] == [len(b) for b in d.blobs]
    assert [(v.buffer, v.byteOffset, v.byteLength) for v in g.bufferViews] == \
        [(v["buffer"], v["byteOffset"], v["byteLength"]) for v in d.j["bufferViews"]]
    np.testing.assert_array_equal(decode(g, blobs, 0), new.astype("<f4"))
    assert bytes(blobs[0]) == bytes(d.blobs[0])                   # buffer 0 untouched, byte for byte


def textured(folder):
    """model.gltf with its buffer in model.bin and its texture in textures/wood.png."""
    V, T = cube()
    d = Doc()
    pos = d.accessor(V.astype("<f4"), "VEC3", minmax=True)
    tex = d.accessor((V[:, :2] * 0.5 + 0.5).astype("<f4"), "VEC2")
    idx = d.accessor(T.reshape(-1).astype("<u2"), "SCALAR")
    d.j["images"] = [{"uri": "textures/wood.png", "name": "wood"}]
    d.j["textures"] = [{"source": 0}]
    d.j["materials"] = [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]
    d.node(mesh=d.mesh({"attributes": {"POSITION": pos, "TEXCOORD_0": tex}, "indices": idx, "material": 0}))
    (folder / "textures").mkdir()
    png = b"\x89PNG\r\n\x1a\n" + bytes(range(256)) * 4
    (folder / "textures" / "wood.png").write_bytes(png)
    (folder / "model.bin").write_bytes(bytes(d.blobs[0]))
    (folder / "model.gltf").write_bytes(d.gltf({0: "model.bin"}))
    return folder / "model.gltf", png


@pytest.mark.parametrize("ext", ["glb", "gltf"])
def test_external_textures_are_embedded_when_writing_elsewhere(tmp_path, ext):
    a, b = tmp_path / "a", tmp_path / "b"
    a.mkdir()
    b.mkdir()
    src, png = textured(a)
    m = sf.load(src)
    save_quietly(b / f"out.{ext}", m.with_vertices(m.vertices * 0.5))
    assert sorted(p.name for p in b.iterdir()) == [f"out.{ext}"]
    g, blobs = load(b / f"out.{ext}")
    head, data = g.images[0].uri.split(",", 1)
    assert head == "data:image/png;base64" and base64.b64decode(data) == png and g.images[0].name == "wood"
    assert g.materials[0].pbrMetallicRoughness.baseColorTexture.index == 0
    np.testing.assert_array_equal(decode(g, blobs, 0), (cube()[0] * 0.5).astype("<f4"))


def test_a_texture_that_cannot_be_read_when_writing_is_named(tmp_path):
    src, _ = textured(tmp_path)
    m = sf.load(src)
    (tmp_path / "textures" / "wood.png").unlink()
    with pytest.warns(sf.DataLossWarning, match=r"refers to image 0 'textures/wood.png' .* by its relative URI"):
        sf.save(tmp_path / "elsewhere.glb", m)
    g, _ = load(tmp_path / "elsewhere.glb")
    assert g.images[0].uri == "textures/wood.png"


def test_positions_whose_bytes_another_accessor_reads_are_moved_not_overwritten(tmp_path):
    """A TEXCOORD_1 accessor reads the first 8 bytes of every position: the positions go to a new
    float accessor, and TEXCOORD_1 still reads what it read."""
    d = cube_doc()
    d.j["bufferViews"][0]["byteStride"] = 12
    alias = d.accessor(np.zeros((8, 2), "<f4"), "VEC2", view=0)
    d.j["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_1"] = alias
    (tmp_path / "alias.glb").write_bytes(d.glb())
    m = sf.load(tmp_path / "alias.glb")
    save_quietly(tmp_path / "out.glb", m.with_vertices(m.vertices * 0.5))
    g, blobs = load(tmp_path / "out.glb")
    assert g.accessors[0].bufferView == len(d.j["bufferViews"])
    np.testing.assert_array_equal(decode(g, blobs, 0), (cube()[0] * 0.5).astype("<f4"))
    np.testing.assert_array_equal(decode(g, blobs, alias), cube()[0][:, :2].astype("<f4"))


def test_sparse_positions_are_written_as_a_new_accessor(tmp_path):
    from test_gltf_hostile import sparse_doc

    d = sparse_doc(True)
    (tmp_path / "s.glb").write_bytes(d.glb())
    m = sf.load(tmp_path / "s.glb")
    save_quietly(tmp_path / "out.glb", m.with_vertices(m.vertices * 2))
    g, blobs = load(tmp_path / "out.glb")
    assert g.accessors[0].sparse is None
    np.testing.assert_array_equal(decode(g, blobs, 0), (m.vertices * 2).astype("<f4"))
    assert bytes(blobs[0][:len(d.blobs[0])]) == bytes(d.blobs[0])       # sparse and base bytes kept


def test_the_smoothing_command_writes_a_quantized_file_back(tmp_path, capsys):
    from shapeflow.cli import main

    d, *_ = quantized_doc()
    (tmp_path / "q.glb").write_bytes(d.glb())
    assert main(["smooth", str(tmp_path / "q.glb"), str(tmp_path / "out.glb"), "--strength", "0.5"]) == 0
    g, blobs = load(tmp_path / "out.glb")
    raw = decode(g, blobs, 0)
    assert g.accessors[0].componentType == 5122 and np.abs(raw).max() < 0.5 * 32767   # smoothing shrinks


def test_a_deeply_nested_document_is_written_back(tmp_path):
    """extras nested 900 deep (JSON's own limit is near 1,000): written and read again."""
    d = cube_doc()
    d.j["extras"] = {"nest": "NEST"}
    text = d.gltf().replace(b'"NEST"', b"[" * 900 + b"]" * 900)
    (tmp_path / "deep.gltf").write_bytes(text)
    m = sf.load(tmp_path / "deep.gltf")
    save_quietly(tmp_path / "out.gltf", m.with_vertices(m.vertices * 0.5))
    g, blobs = load(tmp_path / "out.gltf")
    np.testing.assert_array_equal(decode(g, blobs, 0), (cube()[0] * 0.5).astype("<f4"))
