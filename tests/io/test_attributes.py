"""Attributes: kept in their own type, normals recomputed from the moved surface, never stale."""

from __future__ import annotations

import numpy as np
import pytest

import shapeflow as sf
from shapeflow import io as sio
from shapeflow.errors import MeshError

PLY_TYPES = {"uchar": "u1", "char": "i1", "ushort": "u2", "short": "i2", "int": "i4", "uint": "u4",
             "float": "f4", "double": "f8"}


def read_ply_vertices(path):
    """A small independent binary-little-endian PLY vertex reader (header by hand, body by NumPy)."""
    data = path.read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    props, count, in_vertex = [], 0, False
    for line in data[:end].decode().splitlines():
        w = line.split()
        if w[:1] == ["element"]:
            in_vertex = w[1] == "vertex"
            count = int(w[2]) if in_vertex else count
        elif w[:1] == ["property"] and in_vertex:
            props.append((w[2], "<" + PLY_TYPES[w[1]]))
    return np.frombuffer(data, dtype=np.dtype(props), count=count, offset=end), dict(props)


def normals_by_definition(mesh):
    """Unit sum of the faces' vector areas (Newell) around each vertex, face by face in Python."""
    V = mesh.vertices
    acc = np.zeros_like(V)
    for f in range(mesh.n_faces):
        idx = mesh.face_indices[mesh.face_offsets[f]:mesh.face_offsets[f + 1]]
        P = V[idx]
        area = 0.5 * np.cross(P, np.roll(P, -1, axis=0)).sum(axis=0)
        acc[idx] += area
    return acc / np.linalg.norm(acc, axis=1)[:, None]


@pytest.fixture
def colourful():
    mesh = sf.load_example("spot")
    n = mesh.n_vertices
    rng = np.random.default_rng(4)
    return mesh.with_attributes(red=rng.integers(0, 256, n).astype(np.uint8),
                                green=np.full(n, 255, np.uint8), label=rng.integers(-5, 5, n).astype(np.int32),
                                quality=rng.random(n).astype(np.float32),
                                nx=np.zeros(n, np.float32), ny=np.zeros(n, np.float32), nz=np.ones(n, np.float32))


@pytest.mark.parametrize("binary", [True, False])
def test_ply_round_trip_keeps_types(tmp_path, colourful, binary):
    sio.save(tmp_path / "c.ply", colourful, binary=binary)
    back = sio.load(tmp_path / "c.ply")
    for k in ("red", "green", "label"):
        assert back.attributes[k].dtype == colourful.attributes[k].dtype
        assert np.array_equal(back.attributes[k], colourful.attributes[k])
    head = (tmp_path / "c.ply").read_bytes()[:600].decode("ascii", "replace")
    for line in ("property uchar red", "property uchar green", "property int label", "property float quality"):
        assert line in head
    if binary:
        assert back.attributes["quality"].dtype == np.float32
        rec, types = read_ply_vertices(tmp_path / "c.ply")
        assert types["red"] == "<u1" and np.array_equal(rec["red"], colourful.attributes["red"])


def test_flow_recomputes_normals_and_keeps_colours(tmp_path, colourful):
    out = sf.smooth(colourful, 5.0)
    assert any("normals" in n for n in out.report.notes)
    ref = normals_by_definition(out)
    got = np.c_[[out.attributes[k] for k in ("nx", "ny", "nz")]].T
    assert got.dtype == np.float32
    assert np.abs(got - ref).max() < 1e-6                   # float32 rounding of unit vectors
    assert np.array_equal(out.attributes["red"], colourful.attributes["red"])
    sio.save(tmp_path / "o.ply", out)
    rec, types = read_ply_vertices(tmp_path / "o.ply")
    assert types["red"] == "<u1" and types["nx"] == "<f4"
    assert np.array_equal(rec["red"], colourful.attributes["red"])
    assert np.abs(np.c_[rec["nx"], rec["ny"], rec["nz"]] - ref).max() < 1e-6


def test_brush_and_subdivision_recompute_normals(colourful):
    b = sf.Brush(colourful, lam=-30.0, radius=0.3)
    b.dab(colourful.vertices[0])
    m = b.mesh
    got = np.c_[m.attributes["nx"], m.attributes["ny"], m.attributes["nz"]]
    assert np.abs(got - normals_by_definition(m)).max() < 1e-6
    fine = sf.subdivide(colourful, 1)
    got = np.c_[fine.attributes["nx"], fine.attributes["ny"], fine.attributes["nz"]]
    assert np.abs(got - normals_by_definition(fine)).max() < 1e-6
    assert np.allclose(np.linalg.norm(got, axis=1), 1.0, atol=1e-6)
    # integer attributes stay integers in their range; averages are rounded
    assert fine.attributes["red"].dtype == np.uint8 and fine.attributes["label"].dtype == np.int32
    S, _ = sf.subdivision_matrix(colourful, levels=1)
    exact = S @ colourful.attributes["red"].astype(float)
    assert np.abs(fine.attributes["red"] - exact).max() <= 0.5 + 1e-9      # rounded to the nearest
    assert np.array_equal(fine.attributes["green"], np.full(fine.n_vertices, 255, np.uint8))


@pytest.mark.parametrize("value", ["300", "-1", "2.5"])
def test_ascii_integer_property_out_of_its_type_is_an_error(tmp_path, value):
    p = tmp_path / "m.ply"
    p.write_text("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                 "property uchar red\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
                 f"0 0 0 1\n1 0 0 {value}\n0 1 0 3\n3 0 1 2\n")
    with pytest.raises(MeshError, match=r"line 12: property 'red' is uint8 but has the value"):
        sio.load(p)
