"""STL, binary and ASCII: written files read back by numpy-stl, numpy-stl's files read by shapeflow,
and a soup smoothed as one surface."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from conftest import MESHES, need, requires_shared

import shapeflow as sf
from shapeflow.errors import DataLossWarning

stl_mesh = need("stl.mesh", "numpy-stl (a test dependency)")


def fan_triangles(mesh):
    """Each face as a fan from its first corner, written out here independently."""
    out = []
    for f in range(mesh.n_faces):
        ids = mesh.face(f)
        out += [[ids[0], ids[k], ids[k + 1]] for k in range(1, len(ids) - 1)]
    return np.array(out)


@pytest.mark.parametrize("binary", [True, False])
def test_written_files_read_by_numpy_stl(tmp_path, spot, binary):
    p = tmp_path / "m.stl"
    with pytest.warns(DataLossWarning, match="triangle fans"):
        sf.save(p, spot, binary=binary)
    got = stl_mesh.Mesh.from_file(str(p), calculate_normals=False)   # the normals as stored
    tris = fan_triangles(spot)
    want = spot.vertices[tris]
    np.testing.assert_allclose(got.vectors.astype(np.float64), want, rtol=0, atol=1e-6 * spot.diagonal)
    # facet normals: unit normals of the triangles, computed here
    n = np.cross(want[:, 1] - want[:, 0], want[:, 2] - want[:, 0])
    n /= np.linalg.norm(n, axis=1)[:, None]
    np.testing.assert_allclose(got.normals.astype(np.float64), n, atol=1e-5)


@pytest.mark.parametrize("mode", ["binary", "ascii"])
def test_numpy_stl_files_read(tmp_path, mode):
    rng = np.random.default_rng(3)
    data = np.zeros(5, dtype=stl_mesh.Mesh.dtype)
    data["vectors"] = rng.random((5, 3, 3)).astype(np.float32)
    m = stl_mesh.Mesh(data, name=b"part")
    p = tmp_path / "np.stl"
    from stl import Mode

    m.save(str(p), mode=Mode.BINARY if mode == "binary" else Mode.ASCII)
    got = sf.load(p)
    assert got.n_faces == 5 and got.face_sizes.tolist() == [3] * 5
    np.testing.assert_allclose(got.vertices.reshape(5, 3, 3), data["vectors"].astype(np.float64), rtol=1e-6)
    if mode == "ascii":
        assert got.metadata["stl"]["name"] == "part"


def test_round_trip_keeps_facets_and_attribute_words(tmp_path):
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], float)
    m = sf.Mesh(V[[0, 1, 2, 1, 3, 2]], [[0, 1, 2], [3, 4, 5]], face_attributes={"stl_attribute": np.array([7, 31])})
    for binary in (True, False):
        p = tmp_path / f"m{binary}.stl"
        sf.save(p, m, binary=binary)
        back = sf.load(p)
        np.testing.assert_array_equal(back.vertices, m.vertices)
        assert back.faces_as_lists() == m.faces_as_lists()
        if binary:
            assert back.face_attributes["stl_attribute"].tolist() == [7, 31]


@pytest.mark.parametrize("text,match", [
    (b"solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nendloop\nendfacet\nendsolid x\n",
     "line 6: expected 'vertex' here, found 'endloop'"),
    (b"solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 zz\nvertex 0 1 0\nendloop\n"
     b"endfacet\nendsolid\n", "line 5: 'zz' is not a valid vertex coordinate"),
    (b"hello", "not an STL file: neither text beginning with 'solid' nor binary STL \\(5 bytes"),
])
def test_bad_files_name_the_problem(tmp_path, text, match):
    p = tmp_path / "bad.stl"
    p.write_bytes(text)
    with pytest.raises(sf.MeshError, match=match):
        sf.load(p)


@requires_shared
def test_an_stl_soup_smooths_as_one_surface(tmp_path, capsys):
    from shapeflow.cli import main

    m = sf.load(MESHES / "spot_tri.obj")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataLossWarning)
        sf.save(tmp_path / "spot.stl", m)
    assert main(["smooth", str(tmp_path / "spot.stl"), str(tmp_path / "out.stl"), "--strength", "2"]) == 0
    assert "welded to 2930" in capsys.readouterr().err
    out = sf.load(tmp_path / "out.stl")
    # the reference: the welded file's surface (float32 positions, as the STL stores them)
    stored = sf.load(tmp_path / "spot.stl")
    w = sf.weld(stored)
    ref = sf.flow(w, 2.0).vertices[w.weld_map]
    np.testing.assert_allclose(out.vertices, ref, rtol=0, atol=1e-6 * m.diagonal)   # float32 on writing
    copies = stored.vertices[:, None] == stored.vertices[None, :20]
    assert copies.all(axis=2).sum() > 20           # the soup really has copies


# --- which variant, and files that do not hold what they declare -------------------------------------

def binary_stl(n: int, header: bytes = b"binary", count: int | None = None, seed: int = 0) -> tuple[bytes, np.ndarray]:
    rng = np.random.default_rng(seed)
    vectors = rng.random((n, 3, 3)).astype(np.float32)
    rec = np.zeros(n, dtype=stl_mesh.Mesh.dtype)       # numpy-stl's own record layout
    rec["vectors"] = vectors
    body = header.ljust(80, b" ") + np.uint32(n if count is None else count).tobytes() + rec.tobytes()
    return body, vectors


def numpy_stl_reads(path):
    """numpy-stl's reading of a file (None if it refuses it)."""
    try:
        return stl_mesh.Mesh.from_file(str(path), calculate_normals=False).vectors.astype(np.float64)
    except Exception:
        return None


@pytest.mark.parametrize("header", [b"solid part exported by CAD", b"SOLID", b"  solid x"])
def test_a_binary_file_whose_header_says_solid_is_binary(tmp_path, header):
    data, vectors = binary_stl(7, header)
    p = tmp_path / "b.stl"
    p.write_bytes(data)
    got = sf.load(p).vertices.reshape(-1, 3, 3)
    np.testing.assert_array_equal(got, vectors.astype(np.float64))
    np.testing.assert_array_equal(got, numpy_stl_reads(p))


@pytest.mark.parametrize("header", [b"binary", b"solid name"])
@pytest.mark.parametrize("cut", [1, 20, 49, 50, 120])
def test_a_truncated_binary_file_is_refused_with_its_sizes(tmp_path, header, cut):
    data, vectors = binary_stl(4, header)
    p = tmp_path / "t.stl"
    p.write_bytes(data[:-cut])
    with pytest.raises(sf.MeshError, match=rf"t\.stl: binary STL is truncated: its header declares 4 facets "
                                           rf"\(84 \+ 50 × 4 = 284 bytes\) but the file has {284 - cut} bytes"):
        sf.load(p)
    theirs = numpy_stl_reads(p)       # numpy-stl drops the incomplete facets silently (or refuses): never us
    assert theirs is None or theirs.shape[0] < 4


@pytest.mark.parametrize("header", [b"binary", b"solid name"])
@pytest.mark.parametrize("extra", [1, 30, 50, 77])
def test_a_padded_binary_file_is_read_as_numpy_stl_reads_it(tmp_path, header, extra):
    data, vectors = binary_stl(4, header)
    p = tmp_path / "pad.stl"
    p.write_bytes(data + b"\0" * extra)
    with pytest.warns(DataLossWarning, match=rf"pad\.stl: {extra} bytes after the 4 facets .* are ignored"):
        got = sf.load(p).vertices.reshape(-1, 3, 3)
    np.testing.assert_array_equal(got, vectors.astype(np.float64))
    theirs = numpy_stl_reads(p)
    if header == b"binary":           # numpy-stl reads the declared facets too
        np.testing.assert_array_equal(got, theirs)


@pytest.mark.parametrize("data,match", [
    (b"solid empty\nendsolid empty\n", "line 1: ASCII STL with no facets"),
    (b"solid\n", "line 1: file ends without 'endsolid'"),
    (b"\xef\xbb\xbf  solid x\n\n endsolid x", "ASCII STL with no facets"),
    (b"binary header".ljust(80) + b"\0\0\0\0", "binary STL with no facets"),
    (b"", "not an STL file"),
    (b"solid" + b"\0" * 60, "not an STL file"),
], ids=["ascii-empty", "ascii-no-end", "bom-empty", "binary-zero", "empty-file", "short-binary"])
def test_no_facets_is_an_error_never_an_empty_mesh(tmp_path, data, match):
    p = tmp_path / "e.stl"
    p.write_bytes(data)
    with pytest.raises(sf.MeshError, match=match):
        sf.load(p)


FACET = "facet normal 0 0 1\n outer loop\n  vertex 0 0 0\n  vertex 1 0 0\n  vertex 0 1 0\n endloop\nendfacet\n"


@pytest.mark.parametrize("lines,match", [
    ({4: "  vertex 1 0"}, "line 4: malformed 'vertex' line: expected 'vertex' and three numbers"),
    ({4: "  vertex 1 0 0 7"}, "line 4: malformed 'vertex' line"),
    ({2: "facet normal 0 0"}, "line 2: malformed 'facet' line: expected 'facet normal' and three numbers"),
    ({2: "facet nromal 0 0 1"}, "line 2: malformed 'facet' line"),
    ({3: " outer lop"}, "line 3: malformed 'outer' line: expected 'outer loop'"),
    ({5: "  vertx 1 0 0"}, "line 5: 'vertx' is not an ASCII STL keyword"),
    ({6: "  vertex 0 1 0\n  vertex 0 1 1"}, "line 7: expected 'endloop' here, found 'vertex'"),
    ({7: " endloop\nendsolid x"}, "line 8: 'endsolid' inside a facet"),
    ({5: "  vertex 0 nan 0"}, "line 5: vertex coordinate is not finite"),
    ({5: "  vertex 0 1e999 0"}, "line 5: vertex coordinate is not finite"),
    ({5: "  vertex 0 0x1 0"}, "line 5: '0x1' is not a valid vertex coordinate"),
    ({9: "endsolid x\nsolid y\nsolid z"}, "line 11: 'solid' without its endsolid"),
    ({9: ""}, "file ends without 'endsolid'"),
    ({1: "facet normal 0 0 1"}, "not an STL file: neither text beginning with 'solid' nor binary STL "
                                r"\(as binary its header's \d+ facets need \d+ bytes, it has 124\)"),
    ({1: "solidworks"}, "line 1: 'solidworks' is not an ASCII STL keyword"),
], ids=lambda v: "" if isinstance(v, str) else next(iter(v.values()))[:16])
def test_a_malformed_ascii_line_is_named(tmp_path, lines, match):
    text = ("solid x\n" + FACET + "endsolid x\n").split("\n")
    for k, v in lines.items():
        text[k - 1] = v
    p = tmp_path / "a.stl"
    p.write_text("\n".join(text))
    with pytest.raises(sf.MeshError, match=match):
        sf.load(p)


def test_ascii_keywords_in_capitals_and_several_solids(tmp_path):
    text = ("SOLID part\n" + FACET.upper() + "ENDSOLID part\nsolid second\n" + FACET.replace("0 1 0", "0 2 0")
            + "endsolid second\n")
    p = tmp_path / "caps.stl"
    p.write_text(text)
    m = sf.load(p)
    assert m.n_faces == 2 and m.metadata["stl"]["name"] == "part"
    np.testing.assert_array_equal(m.vertices[[2, 5]], [[0, 1, 0], [0, 2, 0]])
