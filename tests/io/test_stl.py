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


@pytest.fixture
def spot():
    return sf.load_example("spot")


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
     "facet has 2 vertices"),
    (b"solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 zz\nvertex 0 1 0\nendloop\n"
     b"endfacet\nendsolid\n", "vertex coordinate"),
    (b"hello", "not an STL file"),
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
