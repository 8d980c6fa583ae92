"""Mesh file I/O: exact round trips, hand-written files, weights, malformed files, atomic save."""

from __future__ import annotations

import dataclasses
import os
import struct

import numpy as np
import pytest
from conftest import MESHES, requires_shared, shared_mesh_paths

import shapeflow as sf
import shapeflow.io as sio
from shapeflow.errors import MeshError, ParameterError

# --------------------------------------------------------------------------
# the hand-written interleaved mesh: tri, quad, quad, tri, pentagon, tri,
# plus an unreferenced vertex (10)
# --------------------------------------------------------------------------

GRID = [(0, 0, 0), (1, 0, 0), (2, 0, 0), (0, 1, 0), (1, 1, 0), (2, 1, 0),
        (0, 2, 0), (1, 2, 0), (2, 2, 0), (3, 1, 0), (9, 9, 9)]
SIZES = [3, 4, 4, 3, 5, 3]
INDICES = [0, 1, 4, 1, 2, 5, 4, 3, 4, 7, 6, 2, 9, 5, 4, 5, 8, 7, 6, 0, 4, 3]
OFFSETS = [0, 3, 7, 11, 14, 19, 22]
WEIGHTS = [0.0, 0.1, 0.25, 1.0, 0.5, 1 / 3, 0.75, 0.9, 0.2, 0.125, 1e-9]

MIXED_OBJ = b"""\
# an interleaved tri/quad/pentagon mesh with every face form
mtllib mixed.mtl
o mixed
v 0 0 0
v 1 0 0
v 2 0 0 1.0
v 0 1 0 0.5 0.5 0.5
v 1 1 0
v 2 1 0
\tv 0 2 0
v 1 2 0
v 2 2 0
v 3 1 0
v 9 9 9
vt 0 0
vt 1 0
vn 0 0 1
vp 0.5
g group1
s 1
usemtl mat
f 1 2 5

f 2/1 3/2 6/1 5/2
f 4//1 5//1 8//1 7//1
t crease 2/1/0 0 1 1.0
f 3/1/1 10/2/1 6/1/1
l 1 2
p 3
f -7 -6 -3 -4 -5
f 1 5 \\
  4
"""

MIXED_OFF = b"""\
OFF
# hand-written, with a face colour
11 6 0
0 0 0
1 0 0
2 0 0
0 1 0
1 1 0
2 1 0
0 2 0
1 2 0
2 2 0
3 1 0
9 9 9
3 0 1 4
4 1 2 5 4 255 0 0
4 3 4 7 6
3 2 9 5
5 4 5 8 7 6 0.5 0.5 0.5 1.0
3 0 4 3
"""

MIXED_PLY_ASCII = b"""\
ply
format ascii 1.0
comment hand-written
element vertex 11
property float x
property float y
property float z
property float weight
element face 6
property uchar flags
property list uchar int vertex_indices
property float quality
element edge 1
property int vertex1
property int vertex2
end_header
0 0 0 0
1 0 0 0.1
2 0 0 0.25
0 1 0 1
1 1 0 0.5
2 1 0 0.333
0 2 0 0.75
1 2 0 0.9
2 2 0 0.2
3 1 0 0.125
9 9 9 0
1 3 0 1 4 0.5
0 4 1 2 5 4 0.5
0 4 3 4 7 6 0.5
0 3 2 9 5 0.5
0 5 4 5 8 7 6 0.5
0 3 0 4 3 0.5
0 1
"""


def _binary_ply(order: str, *, count_type="B", extra_face_list=False) -> bytes:
    """The mixed mesh as binary PLY, built by hand with struct (independent of the writer)."""
    fmt = {"<": "binary_little_endian", ">": "binary_big_endian"}[order]
    ct = {"B": "uchar", "i": "int", "H": "ushort"}[count_type]
    head = [
        "ply", f"format {fmt} 1.0", "element vertex 11", "property float x", "property double y",
        "property float z", "property double weight", "element face 6", f"property list {ct} int vertex_indices",
    ]
    if extra_face_list:
        head.append("property list uchar float texcoord")
    head += ["element material 1", "property uchar red", "end_header"]
    out = bytearray(("\n".join(head) + "\n").encode())
    for (x, y, z), w in zip(GRID, WEIGHTS):
        out += struct.pack(order + "fdfd", x, y, z, w)
    for f in range(len(SIZES)):
        corners = INDICES[OFFSETS[f]:OFFSETS[f + 1]]
        out += struct.pack(order + count_type + "i" * len(corners), len(corners), *corners)
        if extra_face_list:
            out += struct.pack(order + "B" + "f" * (2 * len(corners)), 2 * len(corners), *([0.5] * 2 * len(corners)))
    out += struct.pack("B", 7)
    return bytes(out)


def _check_mixed(m: sf.Mesh) -> None:
    assert m.n_vertices == 11
    np.testing.assert_array_equal(m.vertices, np.array(GRID, dtype=float))
    assert m.face_sizes.tolist() == SIZES
    assert m.face_indices.tolist() == INDICES
    assert m.face_offsets.tolist() == OFFSETS


def _write(tmp_path, name: str, data: bytes):
    p = tmp_path / name
    p.write_bytes(data)
    return p


def _mixed_mesh(**kw) -> sf.Mesh:
    return sf.Mesh.from_csr(GRID, SIZES, INDICES, **kw)


# --------------------------------------------------------------------------
# hand-written files parse to the expected CSR
# --------------------------------------------------------------------------

def test_obj_interleaved_every_corner_form(tmp_path):
    m = sio.load(_write(tmp_path, "mixed.obj", MIXED_OBJ))
    _check_mixed(m)
    assert dict(m.attributes) == {}


def test_obj_crlf_and_bom(tmp_path):
    data = b"\xef\xbb\xbf" + MIXED_OBJ.replace(b"\n", b"\r\n")
    _check_mixed(sio.load(_write(tmp_path, "crlf.obj", data)))


def test_obj_comment_after_data_and_fo(tmp_path):
    p = _write(tmp_path, "c.obj", b"v 0 0 0 # origin\nv 1 0 0\nv 0 1 0\nfo 1 2 3 # old tag\n")
    m = sio.load(p)
    assert m.face_indices.tolist() == [0, 1, 2]


def test_off_interleaved_with_colours(tmp_path):
    _check_mixed(sio.load(_write(tmp_path, "mixed.off", MIXED_OFF)))


def test_off_counts_on_header_line_and_coff(tmp_path):
    lines = MIXED_OFF.decode().splitlines()
    # COFF: a colour after every vertex; counts on the header line
    verts = [f"{ln} 10 20 30 255" for ln in lines[3:14]]
    data = "\n".join(["COFF 11 6 0"] + verts + lines[14:]) + "\n"
    _check_mixed(sio.load(_write(tmp_path, "c.off", data.encode())))


def test_ply_ascii_interleaved_with_weights_and_extra_properties(tmp_path):
    m = sio.load(_write(tmp_path, "mixed.ply", MIXED_PLY_ASCII))
    _check_mixed(m)
    assert list(m.attributes) == ["weight"]
    # ASCII values keep the precision of the text, whatever the declared type
    assert m.weights[2] == 0.25 and m.weights[5] == 0.333


@pytest.mark.parametrize("order", ["<", ">"])
@pytest.mark.parametrize("count_type", ["B", "i", "H"])
def test_ply_binary_interleaved_by_hand(tmp_path, order, count_type):
    m = sio.load(_write(tmp_path, "mixed.ply", _binary_ply(order, count_type=count_type)))
    _check_mixed(m)
    np.testing.assert_array_equal(m.weights, WEIGHTS)


@pytest.mark.parametrize("order", ["<", ">"])
def test_ply_binary_two_face_lists(tmp_path, order):
    _check_mixed(sio.load(_write(tmp_path, "two.ply", _binary_ply(order, extra_face_list=True))))


def test_ply_binary_uniform_faces_with_a_varying_second_list(tmp_path):
    """All triangles, but a texcoord list of varying length: records differ in size."""
    head = (b"ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
            b"property float z\nelement face 3\nproperty list uchar int vertex_indices\n"
            b"property list uchar float texcoord\nend_header\n")
    body = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], "<f4").tobytes()
    for tri, ntex in [((0, 1, 2), 6), ((1, 3, 2), 0), ((0, 2, 3), 2)]:
        body += struct.pack("<B3iB", 3, *tri, ntex) + struct.pack(f"<{ntex}f", *range(ntex))
    m = sio.load(_write(tmp_path, "t.ply", head + body))
    assert m.face_indices.tolist() == [0, 1, 2, 1, 3, 2, 0, 2, 3]


def test_ply_binary_two_lists_compensating_lengths(tmp_path):
    """Records of equal size whose two lists vary in opposite ways."""
    head = (b"ply\nformat binary_little_endian 1.0\nelement vertex 5\nproperty float x\nproperty float y\n"
            b"property float z\nelement face 2\nproperty list uchar int vertex_indices\n"
            b"property list uchar int extra\nend_header\n")
    body = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0, 0]], "<f4").tobytes()
    body += struct.pack("<B3iB2i", 3, 0, 1, 2, 2, 7, 7)  # 3 + 2 ints
    body += struct.pack("<B4iBi", 4, 0, 1, 2, 3, 1, 7)  # 4 + 1 ints: same record size
    m = sio.load(_write(tmp_path, "c.ply", head + body))
    assert m.face_sizes.tolist() == [3, 4]
    assert m.face_indices.tolist() == [0, 1, 2, 0, 1, 2, 3]


def test_ply_binary_uniform_faces_fast_path(tmp_path):
    quads = sf.Mesh([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0, 0], [2, 1, 0]],
                    [[0, 1, 2, 3], [1, 4, 5, 2]])
    sio.save(tmp_path / "q.ply", quads)
    assert sio.load(tmp_path / "q.ply") == quads


def test_ply_big_ngon_uses_int_count(tmp_path):
    k = 300
    t = np.linspace(0, 2 * np.pi, k, endpoint=False)
    m = sf.Mesh(np.column_stack([np.cos(t), np.sin(t), np.zeros(k)]), [list(range(k)), [0, 1, 2]])
    for binary in (True, False):
        sio.save(tmp_path / "big.ply", m, binary=binary)
        assert b"property list int int vertex_indices" in (tmp_path / "big.ply").read_bytes()[:300]
        assert sio.load(tmp_path / "big.ply") == m


def test_format_registry_and_explicit_format(tmp_path):
    assert {".obj", ".ply", ".off"} <= set(sio.FORMATS)
    m = _mixed_mesh()
    sio.save(tmp_path / "mesh.dat", m, format="off")
    assert (tmp_path / "mesh.dat").read_bytes().startswith(b"OFF\n")
    assert sio.load(tmp_path / "mesh.dat", format=".off") == m
    sio.save(tmp_path / "UPPER.OBJ", m)
    assert sio.load(tmp_path / "UPPER.OBJ") == m


def test_register_custom_format(tmp_path, monkeypatch):
    monkeypatch.setattr(sio, "FORMATS", dict(sio.FORMATS))
    fmt = dataclasses.replace(sio.FORMATS[".off"], name="MYOFF", extensions=(".myoff",))
    sio.register_format(fmt)
    sio.save(tmp_path / "a.myoff", _mixed_mesh())
    _check_mixed(sio.load(tmp_path / "a.myoff"))


# --------------------------------------------------------------------------
# exact round trips
# --------------------------------------------------------------------------

ROUND_TRIPS = [("obj", None), ("off", None), ("ply", False), ("ply", True)]


def _assert_same(a: sf.Mesh, b: sf.Mesh) -> None:
    assert np.array_equal(a.vertices, b.vertices)
    assert np.array_equal(a.face_indices, b.face_indices)
    assert np.array_equal(a.face_offsets, b.face_offsets)


@requires_shared
@pytest.mark.parametrize("path", shared_mesh_paths(), ids=lambda p: p.name)
def test_shared_meshes_round_trip_exactly(tmp_path, path):
    m = sio.load(path)
    for ext, binary in ROUND_TRIPS:
        out = tmp_path / f"rt.{ext}"
        sio.save(out, m, binary=binary)
        _assert_same(sio.load(out), m)


@pytest.mark.parametrize("ext,binary", ROUND_TRIPS)
def test_awkward_floats_round_trip_bit_exactly(tmp_path, ext, binary):
    rng = np.random.default_rng(1)
    v = rng.standard_normal((50, 3)) * 10.0 ** rng.integers(-300, 300, (50, 3))
    v[0] = [0.1, 1 / 3, -0.0]
    v[1] = [5e-324, np.finfo(float).max, -np.finfo(float).tiny]
    faces = [[i, i + 1, i + 2] if i % 3 else [i, i + 1, i + 2, i + 3] for i in range(0, 45)]
    m = sf.Mesh(v, faces)
    sio.save(tmp_path / f"f.{ext}", m, binary=binary)
    _assert_same(sio.load(tmp_path / f"f.{ext}"), m)


def test_default_ply_is_binary_little_endian_and_ascii_on_request(tmp_path):
    m = _mixed_mesh()
    sio.save(tmp_path / "b.ply", m)
    sio.save(tmp_path / "a.ply", m, binary=False)
    assert b"format binary_little_endian 1.0" in (tmp_path / "b.ply").read_bytes()[:100]
    assert b"format ascii 1.0" in (tmp_path / "a.ply").read_bytes()[:100]


def test_binary_obj_or_off_is_refused(tmp_path):
    for ext in ("obj", "off"):
        with pytest.raises(MeshError, match=f"x.{ext}.*no binary"):
            sio.save(tmp_path / f"x.{ext}", _mixed_mesh(), binary=True)
        assert not (tmp_path / f"x.{ext}").exists()


def test_empty_face_list_round_trips_through_ply_and_off(tmp_path):
    m = sf.Mesh([[0, 0, 0], [1, 2, 3]], [])
    for ext, binary in [("off", None), ("ply", True), ("ply", False), ("obj", None)]:
        sio.save(tmp_path / f"p.{ext}", m, binary=binary)
        assert sio.load(tmp_path / f"p.{ext}") == m


# --------------------------------------------------------------------------
# attributes and weights
# --------------------------------------------------------------------------

@pytest.mark.parametrize("binary", [True, False])
def test_weights_and_attributes_round_trip_through_ply(tmp_path, binary):
    rng = np.random.default_rng(0)
    m = _mixed_mesh(weights=WEIGHTS, attributes={"curvature": rng.standard_normal(11)})
    sio.save(tmp_path / "w.ply", m, binary=binary)
    r = sio.load(tmp_path / "w.ply")
    assert r == m  # vertices, faces and every attribute bit-exact
    assert set(r.attributes) == {"weight", "curvature"}


def test_obj_and_off_drop_attributes(tmp_path):
    m = _mixed_mesh(weights=WEIGHTS)
    for ext in ("obj", "off"):
        sio.save(tmp_path / f"w.{ext}", m)
        r = sio.load(tmp_path / f"w.{ext}")
        assert dict(r.attributes) == {}
        _assert_same(r, m)


def test_multicolumn_attributes_are_written_to_ply_one_column_each(tmp_path):
    cols = np.arange(33.0).reshape(11, 3)
    m = _mixed_mesh(attributes={"normal": cols, "w2": np.zeros(11)})
    sio.save(tmp_path / "a.ply", m)
    back = sio.load(tmp_path / "a.ply")
    assert list(back.attributes) == ["normal_0", "normal_1", "normal_2", "w2"]
    np.testing.assert_array_equal(np.column_stack([back.attributes[f"normal_{i}"] for i in range(3)]), cols)


def test_attribute_name_that_cannot_be_a_ply_property(tmp_path):
    m = _mixed_mesh(attributes={"two words": np.zeros(11)})
    with pytest.raises(MeshError, match=r"bad\.ply.*two words"):
        sio.save(tmp_path / "bad.ply", m)
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize("ext", [".npy", ".txt"])
def test_weights_side_files_round_trip(tmp_path, ext):
    w = np.array(WEIGHTS)
    sio.save_weights(tmp_path / f"w{ext}", w)
    back = sio.load_weights(tmp_path / f"w{ext}", 11)
    assert back.dtype == np.float64 and np.array_equal(back, w)


def test_weights_txt_with_comments_and_blank_lines(tmp_path):
    p = _write(tmp_path, "w.txt", b"# weights\n0.5\n\n1\n0\n")
    assert sio.load_weights(p, 3).tolist() == [0.5, 1.0, 0.0]


@pytest.mark.parametrize("content,n,pattern", [
    (b"0.5\n0.5\n", 3, r"w\.txt: has 2 weights but the mesh has 3 vertices"),
    (b"0.5\n1.5\n0\n", 3, r"w\.txt: line 2: weight of vertex 1 is 1\.5, outside \[0, 1\]"),
    (b"0.5\n-0.1\n0\n", 3, r"w\.txt: line 2: .*outside"),
    (b"0.5\nabc\n0\n", 3, r"w\.txt: line 2: 'abc' is not a valid number"),
    (b"0.5\n0.1 0.2\n0\n", 3, r"w\.txt: line 2: expected one number a line"),
    (b"0.5\nnan\n0\n", 3, r"w\.txt: line 2: weight of vertex 1 is not finite"),
])
def test_bad_weights_txt(tmp_path, content, n, pattern):
    with pytest.raises(MeshError, match=pattern):
        sio.load_weights(_write(tmp_path, "w.txt", content), n)


def test_bad_weights_npy(tmp_path):
    np.save(tmp_path / "w.npy", np.array([0.1, 2.0]))
    with pytest.raises(MeshError, match=r"w\.npy: value 1: weight of vertex 1 is 2\.0"):
        sio.load_weights(tmp_path / "w.npy", 2)
    with pytest.raises(MeshError, match=r"w\.npy: has 2 weights but the mesh has 3"):
        sio.load_weights(tmp_path / "w.npy", 3)
    _write(tmp_path, "junk.npy", b"not an npy file")
    with pytest.raises(MeshError, match=r"junk\.npy: not a valid \.npy"):
        sio.load_weights(tmp_path / "junk.npy", 2)
    np.save(tmp_path / "obj.npy", np.array(["a", "b"]))
    with pytest.raises(MeshError, match=r"obj\.npy: weights must be real numbers"):
        sio.load_weights(tmp_path / "obj.npy", 2)
    with pytest.raises(MeshError, match=r"missing\.npy: cannot read file.*FileNotFoundError"):
        sio.load_weights(tmp_path / "missing.npy", 2)
    with pytest.raises(MeshError, match=r"w\.csv: unknown weights file extension"):
        sio.load_weights(tmp_path / "w.csv", 2)


def test_save_weights_validates_and_names_the_file(tmp_path):
    with pytest.raises(MeshError, match=r"out\.txt: .*outside \[0, 1\]"):
        sio.save_weights(tmp_path / "out.txt", [0.5, 1.5])
    with pytest.raises(MeshError, match=r"out\.npy: weights must be a 1-D array"):
        sio.save_weights(tmp_path / "out.npy", np.zeros((2, 2)))
    assert os.listdir(tmp_path) == []


# --------------------------------------------------------------------------
# the test meshes' counts (from tests/data/SOURCES.md)
# --------------------------------------------------------------------------

SOURCES_COUNTS = {  # file: (vertices, triangles, quads, n-gons)
    "spot_quad.obj": (2930, 0, 2928, 0),
    "spot_tri.obj": (2930, 5856, 0, 0),
    "spot_control_hybrid.obj": (188, 4, 160, 16),
    "bob_quad.obj": (5344, 0, 5344, 0),
    "bob_control_quad.obj": (334, 0, 334, 0),
    "blub_control_hybrid.obj": (112, 8, 100, 4),
    "penguin_control_hybrid.obj": (201, 48, 169, 4),
    "rook_cage_hybrid_open.obj": (768, 44, 733, 0),
    "pawn_cage_quad_open.obj": (601, 0, 588, 0),
    "plane_holes_tri_open.obj": (8519, 16747, 0, 0),
}


@requires_shared
def test_sources_table_covers_every_shared_mesh():
    assert sorted(p.name for p in shared_mesh_paths()) == sorted(SOURCES_COUNTS)


@requires_shared
@pytest.mark.parametrize("fname", sorted(SOURCES_COUNTS))
def test_shared_mesh_counts_match_sources(fname):
    m = sio.load(MESHES / fname)
    nv, tri, quad, ngon = SOURCES_COUNTS[fname]
    s = m.face_sizes
    assert (m.n_vertices, int((s == 3).sum()), int((s == 4).sum()), int((s >= 5).sum())) == (nv, tri, quad, ngon)
    if fname.endswith("_hybrid.obj") and ngon:
        assert set(np.unique(s).tolist()) == {3, 4, 5}  # the cages' n-gons are pentagons


def test_large_mesh_round_trips(tmp_path):
    """A closed triangle mesh of 163,842 vertices through OBJ and binary PLY (speed:
    benchmarks/bench_operators.py)."""
    from meshgen import icosphere

    sio.save(tmp_path / "large.obj", icosphere(7))
    m = sio.load(tmp_path / "large.obj")
    assert m.n_vertices == 163842 and m.n_faces == 327680
    sio.save(tmp_path / "large.ply", m)
    back = sio.load(tmp_path / "large.ply")
    assert np.array_equal(back.vertices, m.vertices)
    assert np.array_equal(back.face_indices, m.face_indices)


# --------------------------------------------------------------------------
# malformed files: MeshError naming the file and the line / element
# --------------------------------------------------------------------------

TRI = b"v 0 0 0\nv 1 0 0\nv 0 1 0\n"
PLY_HEAD = (b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
            b"property float z\nelement face %d\nproperty list uchar int vertex_indices\nend_header\n")
PLY_VERTS = b"0 0 0\n1 0 0\n0 1 0\n"
BIN_HEAD = (b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
            b"property float z\nelement face %d\nproperty list uchar int vertex_indices\nend_header\n")
BIN_VERTS = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], "<f4").tobytes()


def _bface(*ix) -> bytes:
    return bytes([len(ix)]) + np.array(ix, "<i4").tobytes()


MALFORMED = {
    # name: (content, regex the message must match after the file name)
    "empty.obj": (b"", r"empty file"),
    "blank.off": (b"\n  \n", r"empty file"),
    "comments_only.obj": (b"# nothing\n", r"no vertices"),
    "truncated.obj": (TRI[:-4], r"line 3: vertex line has 1 values"),
    "garbled_number.obj": (b"v 0 0 0\nv 1 0 0\nv 0 1,5 0\nf 1 2 3\n",
                           r"line 3: '1,5' is not a valid vertex coordinate"),
    "garbled_index.obj": (TRI + b"f 1 2 x\n", r"line 4: 'x' is not a valid vertex index"),
    "float_index.obj": (TRI + b"\nf 1 2 3.0\n", r"line 5: '3\.0' is not a valid vertex index"),
    "out_of_range.obj": (TRI + b"f 1 2 4\n", r"line 4: vertex index 4 out of range"),
    "zero_index.obj": (TRI + b"f 0 1 2\n", r"line 4: vertex index 0"),
    "relative_too_far.obj": (b"v 0 0 0\nv 1 0 0\nf -1 -2 -3\nv 0 1 0\n", r"line 3: relative vertex index -3"),
    "two_corners.obj": (TRI + b"f 1 2\n", r"line 4: face has 2 corners"),
    "empty_corner.obj": (TRI + b"f /1 2 3\n", r"line 4: face corner '/1' has no vertex index"),
    "repeated_vertex.obj": (TRI + b"v 1 1 0\nf 1 2 3\nf 1 2 1\n", r"line 6: face 1 repeats a vertex"),
    "nan_vertex.obj": (b"v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n", r"line 2: vertex 1 has a non-finite coordinate"),
    "after_continuation.obj": (TRI + b"f 1 \\\n 2 3\nf 1 2 9\n", r"line 6: vertex index 9 out of range"),
    "binary_junk.obj": (bytes(range(256)) * 4, r"line 1: binary data \(NUL byte\)"),
    "junk_no_nul.obj": (bytes(range(1, 256)) * 4, r"line 1: unrecognised line"),
    "off_header.off": (b"OFX\n3 1 0\n" + PLY_VERTS + b"3 0 1 2\n", r"line 1: not an OFF file"),
    "off_counts_too_big.off": (b"OFF\n3 2 0\n" + PLY_VERTS + b"3 0 1 2\n", r"line 6: file ends after 1 of 2 faces"),
    "off_counts_too_small.off": (b"OFF\n3 1 0\n" + PLY_VERTS + b"3 0 1 2\n3 0 1 2\n", r"line 7: unexpected data"),
    "off_truncated.off": (b"OFF\n3 1 0\n0 0 0\n1 0 0\n", r"line 4: file ends after 2 of 3 vertices"),
    "off_bad_counts.off": (b"OFF\n3\n" + PLY_VERTS, r"line 2: expected the counts"),
    "off_short_face.off": (b"OFF\n3 1 0\n" + PLY_VERTS + b"4 0 1 2\n", r"line 6: face line says 4 corners"),
    "off_out_of_range.off": (b"OFF\n3 1 0\n" + PLY_VERTS + b"3 0 1 3\n", r"line 6: vertex index 3 out of range"),
    "off_two_corners.off": (b"OFF\n3 1 0\n" + PLY_VERTS + b"2 0 1\n", r"line 6: face has 2 corners"),
    "off_garbled.off": (b"OFF\n3 1 0\n0 0 0\n1 x 0\n0 1 0\n3 0 1 2\n", r"line 4: 'x' is not a valid"),
    "off_binary.off": (b"OFF BINARY\n" + b"\x01\x02", r"line 1: binary OFF is not supported"),
    "not_ply.ply": (b"OFF\n3 1 0\n", r"line 1: not a PLY file"),
    "ply_no_end_header.ply": (PLY_HEAD[:60], r"no 'end_header'"),
    "ply_bad_element.ply": (b"ply\nformat ascii 1.0\nelement vertex three\nend_header\n", r"line 3: bad element line"),
    "ply_bad_keyword.ply": (b"ply\nformat ascii 1.0\nelemnt vertex 3\nend_header\n", r"line 3: unknown header keyword"),
    "ply_bad_type.ply": (b"ply\nformat ascii 1.0\nelement vertex 1\nproperty real x\nend_header\n",
                         r"line 4: bad property"),
    "ply_no_format.ply": (b"ply\nelement vertex 0\nend_header\n", r"no 'format' line"),
    "ply_no_xyz.ply": (b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n", r"line 3: .*'y'"),
    "ply_vertex_count_wrong.ply": (PLY_HEAD.replace(b"vertex 3", b"vertex 4") % 1 + PLY_VERTS + b"3 0 1 2\n",
                                   r"line 13: 'vertex' line has 4 values, expected 3"),
    "ply_face_count_too_big.ply": (PLY_HEAD % 2 + PLY_VERTS + b"3 0 1 2\n", r"line 13: file ends after 1 of 2 'face'"),
    "ply_face_count_too_small.ply": (PLY_HEAD % 1 + PLY_VERTS + b"3 0 1 2\n3 0 1 2\n", r"line 14: unexpected data"),
    "ply_garbled.ply": (PLY_HEAD % 1 + b"0 0 0\n1 0.0.1 0\n0 1 0\n3 0 1 2\n", r"line 11: '0\.0\.1' is not a valid"),
    "ply_short_face.ply": (PLY_HEAD % 1 + PLY_VERTS + b"4 0 1 2\n", r"line 13: 'face' line is too short"),
    "ply_long_face.ply": (PLY_HEAD % 1 + PLY_VERTS + b"3 0 1 2 7\n", r"line 13: 'face' line has 1 values too many"),
    "ply_out_of_range.ply": (PLY_HEAD % 1 + PLY_VERTS + b"3 0 1 5\n", r"line 13: face 0 refers to vertex 5"),
    "ply_two_corners.ply": (PLY_HEAD % 1 + PLY_VERTS + b"2 0 1\n", r"line 13: face 0 has 2 corners"),
    "ply_repeated.ply": (PLY_HEAD % 1 + PLY_VERTS + b"3 0 1 1\n", r"line 13: face 0 repeats a vertex"),
    "ply_weight_out_of_range.ply": (
        PLY_HEAD.replace(b"property float z\n", b"property float z\nproperty float weight\n") % 0
        + b"0 0 0 0\n1 0 0 2\n0 1 0 0\n", r"line 12: weights must lie in \[0, 1\]; vertex 1"),
    "bin_truncated_face.ply": (BIN_HEAD % 2 + BIN_VERTS + _bface(0, 1, 2) + _bface(0, 1, 2)[:-3],
                               r"face 1: file is truncated"),
    "bin_truncated_mixed.ply": (BIN_HEAD % 3 + BIN_VERTS + _bface(0, 1, 2) + _bface(0, 1, 2, 0)[:6],
                                r"face 1: file is truncated"),
    "bin_truncated_vertex.ply": (BIN_HEAD % 0 + BIN_VERTS[:20], r"vertex 1: file is truncated"),
    "bin_face_count_too_small.ply": (BIN_HEAD % 1 + BIN_VERTS + _bface(0, 1, 2) * 2, r"13 bytes of unexpected data"),
    "bin_face_17_out_of_range.ply": (BIN_HEAD % 18 + BIN_VERTS + _bface(0, 1, 2) * 17 + _bface(0, 1, 9),
                                     r"face 17 refers to vertex 9"),
    "bin_face_17_repeats.ply": (BIN_HEAD % 18 + BIN_VERTS + _bface(0, 1, 2) * 17 + _bface(2, 1, 2),
                                r"face 17 repeats a vertex"),
    "bin_face_two_corners.ply": (BIN_HEAD % 2 + BIN_VERTS + _bface(0, 1, 2) + _bface(0, 1), r"face 1 has 2 corners"),
    "bin_negative_count.ply": (BIN_HEAD.replace(b"uchar int", b"int int") % 1 + BIN_VERTS
                               + struct.pack("<ii", -1, 0), r"face 0: negative list length -1"),
    "bin_junk.ply": (BIN_HEAD % 5 + bytes(range(7, 200)), r"vertex|face"),
    "unknown.fbx": (b"Kaydara FBX Binary", r"unknown mesh extension '\.fbx'"),
}


@pytest.mark.parametrize("fname", sorted(MALFORMED))
def test_malformed_file_raises_mesh_error_naming_file_and_place(tmp_path, fname):
    content, pattern = MALFORMED[fname]
    path = _write(tmp_path, fname, content)
    with pytest.raises(MeshError) as info:
        sio.load(path)
    msg = str(info.value)
    assert msg.startswith(str(path) + ": "), msg
    assert "\n" not in msg
    import re

    assert re.search(pattern, msg), msg


def test_missing_and_unreadable_files(tmp_path):
    with pytest.raises(MeshError, match=r"nope\.obj: cannot read file: .*\(FileNotFoundError\)") as info:
        sio.load(tmp_path / "nope.obj")
    assert isinstance(info.value.__cause__, FileNotFoundError)
    (tmp_path / "dir.obj").mkdir()
    with pytest.raises(MeshError, match=r"dir\.obj: cannot read file: .*IsADirectoryError"):
        sio.load(tmp_path / "dir.obj")


def test_mesh_error_is_a_value_error(tmp_path):
    with pytest.raises(ValueError):
        sio.load(_write(tmp_path, "e.obj", b""))


def test_random_garbage_never_escapes_as_another_exception(tmp_path):
    """Fuzz: mutilated copies of valid files raise MeshError or load, nothing else."""
    rng = np.random.default_rng(7)
    m = _mixed_mesh(weights=WEIGHTS)
    seeds = {}
    for ext, binary in ROUND_TRIPS:
        p = tmp_path / f"seed.{ext}"
        sio.save(p, m, binary=binary)
        seeds[(ext, binary)] = p.read_bytes()
    for (ext, binary), data in seeds.items():
        for trial in range(150):
            b = bytearray(data)
            op = trial % 3
            if op == 0:  # truncate
                b = b[:int(rng.integers(0, len(b)))]
            elif op == 1:  # flip bytes
                for pos in rng.integers(0, len(b), 3):
                    b[pos] = int(rng.integers(0, 256))
            else:  # splice a chunk elsewhere
                i, j = sorted(rng.integers(0, len(b), 2))
                b = b[:i] + b[j:] + b[i:j]
            p = tmp_path / f"fuzz.{ext}"
            p.write_bytes(bytes(b))
            try:
                sio.load(p)
            except MeshError as exc:
                assert str(exc).startswith(str(p)), exc


# --------------------------------------------------------------------------
# atomic save
# --------------------------------------------------------------------------

def _failing_format(monkeypatch, ext: str):
    """Make the writer of ``ext`` write half its output and then fail."""
    real = sio.FORMATS[ext]

    def writer(f, mesh, *, binary=None):
        real.writer(f, mesh, binary=binary)
        f.seek(0, os.SEEK_END)
        f.truncate(f.tell() // 2)
        raise RuntimeError("disk on fire")

    monkeypatch.setitem(sio.FORMATS, ext, dataclasses.replace(real, writer=writer))


@pytest.mark.parametrize("ext", [".obj", ".ply", ".off"])
def test_failed_save_leaves_no_file(tmp_path, monkeypatch, ext):
    _failing_format(monkeypatch, ext)
    with pytest.raises(RuntimeError, match="disk on fire"):
        sio.save(tmp_path / f"out{ext}", _mixed_mesh())
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize("ext", [".obj", ".ply", ".off"])
def test_failed_save_does_not_clobber_existing_file(tmp_path, monkeypatch, ext):
    target = tmp_path / f"out{ext}"
    sio.save(target, _mixed_mesh())
    before = target.read_bytes()
    _failing_format(monkeypatch, ext)
    other = sf.Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    with pytest.raises(RuntimeError):
        sio.save(target, other)
    assert target.read_bytes() == before
    assert os.listdir(tmp_path) == [target.name]


def test_failed_rename_leaves_no_temp_file(tmp_path, monkeypatch):
    def boom(src, dst):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(__import__("shapeflow.io.atomic").io.atomic.os, "replace", boom)
    with pytest.raises(OSError):
        sio.save(tmp_path / "out.ply", _mixed_mesh())
    assert os.listdir(tmp_path) == []


def test_save_into_missing_directory_raises_oserror(tmp_path):
    with pytest.raises(OSError):
        sio.save(tmp_path / "no" / "such" / "dir.obj", _mixed_mesh())


def test_save_replaces_existing_file_and_keeps_its_mode(tmp_path):
    target = tmp_path / "m.obj"
    target.write_text("old")
    os.chmod(target, 0o640)
    sio.save(target, _mixed_mesh())
    assert oct(os.stat(target).st_mode & 0o777) == oct(0o640)
    _check_mixed(sio.load(target))


def test_new_file_mode_follows_umask(tmp_path):
    old = os.umask(0o027)
    try:
        sio.save(tmp_path / "n.off", _mixed_mesh())
    finally:
        os.umask(old)
    assert os.stat(tmp_path / "n.off").st_mode & 0o777 == 0o640


def test_save_needs_a_mesh(tmp_path):
    with pytest.raises(ParameterError):
        sio.save(tmp_path / "x.obj", [[0, 0, 0]])
