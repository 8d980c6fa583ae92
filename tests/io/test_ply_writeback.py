"""PLY write-back keeps every property's type and order, and list properties besides the faces'
corners: files built with plyfile, smoothed, written, and read back with plyfile."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from meshgen import cube_sphere
from plyfile import PlyData, PlyElement

import shapeflow as sf
from shapeflow.errors import DataLossWarning, MeshError

rng = np.random.default_rng(7)
BALL = cube_sphere(3, mix=0.3, seed=2)      # quads and triangles
NV, NF = BALL.n_vertices, BALL.n_faces


def ragged(counts, dtype, lo=0, hi=100):
    out = np.empty(len(counts), dtype=object)
    for i, k in enumerate(counts):
        out[i] = rng.integers(lo, hi, k).astype(dtype) if np.dtype(dtype).kind in "iu" else \
            rng.random(k).astype(dtype)
    return out


VERTEX = np.empty(NV, dtype=[("x", "f4"), ("y", "f4"), ("z", "f4"), ("quality", "f8"), ("confidence", "f4"),
                             ("red", "u1"), ("neighbors", object), ("scan", "i2")])
FACE = np.empty(NF, dtype=[("flags", object), ("vertex_indices", object), ("area", "f8"), ("label", "i2"),
                           ("texcoord", object), ("weights", object)])


def _fill():
    VERTEX["x"], VERTEX["y"], VERTEX["z"] = BALL.vertices.T.astype(np.float32)
    VERTEX["quality"] = rng.random(NV) * 1e-3 + 1.0 / 3.0       # needs double precision
    VERTEX["confidence"] = rng.random(NV).astype(np.float32)
    VERTEX["red"] = rng.integers(0, 256, NV)
    VERTEX["neighbors"] = ragged(rng.integers(0, 6, NV), "i4", 0, NV)
    VERTEX["scan"] = rng.integers(-300, 300, NV)
    FACE["flags"] = ragged(rng.integers(0, 4, NF), "u2")
    FACE["vertex_indices"] = [np.array(f, np.uint32) for f in BALL.faces_as_lists()]
    FACE["area"] = rng.random(NF) / 7
    FACE["label"] = rng.integers(-5, 5, NF)
    FACE["texcoord"] = [rng.random(2 * len(f)) for f in BALL.faces_as_lists()]
    FACE["weights"] = ragged(rng.integers(1, 3, NF), "f4")


_fill()
LEN = {"neighbors": "u1", "flags": "u2", "vertex_indices": "u1", "texcoord": "u1", "weights": "u1"}
VAL = {"neighbors": "i4", "flags": "u2", "vertex_indices": "u4", "texcoord": "f8", "weights": "f4"}


PLY_NAME = {"f4": "float", "f8": "double", "u1": "uchar", "i2": "short", "u2": "ushort", "i4": "int", "u4": "uint"}
TYPES = {"vertex": [("x", "f4"), ("y", "f4"), ("z", "f4"), ("quality", "f8"), ("confidence", "f4"), ("red", "u1"),
                    ("neighbors", None), ("scan", "i2")],
         "face": [("flags", None), ("vertex_indices", None), ("area", "f8"), ("label", "i2"), ("texcoord", None),
                  ("weights", None)]}


def write_input(path, text, byte_order="<"):
    """The input file: ASCII through plyfile; binary written here record by record (plyfile writes the
    scalars of an element that has lists in the machine's byte order whatever ``byte_order`` says)."""
    if text:
        PlyData([PlyElement.describe(VERTEX, "vertex", len_types=LEN, val_types=VAL),
                 PlyElement.describe(FACE, "face", len_types=LEN, val_types=VAL)], text=True).write(str(path))
        return
    head = ["ply", f"format binary_{'little' if byte_order == '<' else 'big'}_endian 1.0"]
    body = []
    for el, data in (("vertex", VERTEX), ("face", FACE)):
        head.append(f"element {el} {len(data)}")
        for k, t in TYPES[el]:
            head.append(f"property {PLY_NAME[t]} {k}" if t else
                        f"property list {PLY_NAME[LEN[k]]} {PLY_NAME[VAL[k]]} {k}")
        for row in data:
            for k, t in TYPES[el]:
                if t:
                    body.append(np.array(row[k], byte_order + t).tobytes())
                else:
                    body.append(np.array(len(row[k]), byte_order + LEN[k]).tobytes())
                    body.append(np.asarray(row[k]).astype(byte_order + VAL[k]).tobytes())
    path.write_bytes(("\n".join(head + ["end_header"]) + "\n").encode() + b"".join(body))
    back = PlyData.read(str(path))        # plyfile reads back what was meant
    assert all(np.array_equal(back["vertex"].data[k], VERTEX[k]) for k, _ in TYPES["vertex"][:6])
    assert all(np.array_equal(a, b) for a, b in zip(back["face"].data["flags"], FACE["flags"]))


def signature(element):
    """(name, type, count type) of each property, in order, as plyfile reads them."""
    return [(p.name, np.dtype(p.val_dtype).str[1:], np.dtype(p.len_dtype).str[1:] if hasattr(p, "len_dtype")
             else None) for p in element.properties]


@pytest.mark.parametrize("text_in,order", [(False, "<"), (False, ">"), (True, "=")], ids=["le", "be", "ascii"])
@pytest.mark.parametrize("binary_out", [True, False], ids=["binary-out", "ascii-out"])
def test_types_order_and_lists_survive_smoothing(tmp_path, text_in, order, binary_out):
    src, out = tmp_path / "in.ply", tmp_path / "out.ply"
    write_input(src, text_in, order)
    result = sf.smooth(sf.load(src), 2.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")          # nothing is lost
        sf.save(out, result, binary=binary_out)
    before, after = PlyData.read(str(src)), PlyData.read(str(out))
    for el in ("vertex", "face"):
        assert signature(after[el]) == signature(before[el])
    v, f = after["vertex"].data, after["face"].data
    np.testing.assert_array_equal(np.column_stack([v["x"], v["y"], v["z"]]), result.vertices.astype(np.float32))
    assert not np.array_equal(v["x"], VERTEX["x"])                   # smoothed
    for k in ("quality", "confidence", "red", "scan"):
        np.testing.assert_array_equal(v[k], VERTEX[k])
    for k in ("area", "label"):
        np.testing.assert_array_equal(f[k], FACE[k])
    for el, data, k in (("vertex", v, "neighbors"), ("face", f, "flags"), ("face", f, "vertex_indices"),
                        ("face", f, "texcoord"), ("face", f, "weights")):
        want = (VERTEX if el == "vertex" else FACE)[k]
        assert all(np.array_equal(a, b) for a, b in zip(data[k], want)), k


def test_lists_after_subdivision_are_named(tmp_path):
    src = tmp_path / "in.ply"
    write_input(src, False)
    sub = sf.subdivide(sf.load(src), 1)
    with pytest.warns(DataLossWarning, match=r"vertex list 'neighbors' .*face list 'flags' .*face list 'weights'"):
        sf.save(tmp_path / "sub.ply", sub)
    names = [p.name for p in PlyData.read(str(tmp_path / "sub.ply"))["face"].properties]
    assert "flags" not in names and "vertex_indices" in names


def test_values_that_no_longer_fit_take_a_wider_type(tmp_path):
    src, out = tmp_path / "in.ply", tmp_path / "out.ply"
    write_input(src, False)
    m = sf.load(src)
    red = m.attributes["red"].astype(np.int64) + 200            # beyond uchar
    conf = m.attributes["confidence"].astype(np.float64) * 1e300  # beyond float
    sf.save(out, m.with_attributes(red=red, confidence=conf))
    v = PlyData.read(str(out))["vertex"]
    types = {p.name: np.dtype(p.val_dtype).str[1:] for p in v.properties}
    assert types["red"] == "i4" and types["confidence"] == "f8" and types["x"] == "f4"
    np.testing.assert_array_equal(v.data["red"], red)
    np.testing.assert_array_equal(v.data["confidence"], conf)


def test_a_mesh_from_elsewhere_gets_double_coordinates_and_int_indices(tmp_path):
    sf.save(tmp_path / "m.ply", BALL)
    d = PlyData.read(str(tmp_path / "m.ply"))
    assert signature(d["vertex"]) == [("x", "f8", None), ("y", "f8", None), ("z", "f8", None)]
    assert signature(d["face"]) == [("vertex_indices", "i4", "u1")]


def test_an_ascii_face_value_out_of_its_type_is_named(tmp_path):
    p = tmp_path / "bad.ply"
    p.write_text("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                 "element face 2\nproperty list uchar int vertex_indices\nproperty uchar region\nend_header\n"
                 "0 0 0\n1 0 0\n0 1 0\n3 0 1 2 7\n3 0 2 1 300\n")
    with pytest.raises(MeshError, match=r"bad\.ply: line 15: property 'region' is uint8 but has the value 300$"):
        sf.load(p)
