"""PLY keeps face properties (in their types), per-corner texture coordinates (texcoord lists),
multi-column vertex attributes, comments and obj_info; checked with plyfile both ways."""

from __future__ import annotations

import numpy as np
import pytest
from plyfile import PlyData, PlyElement

import shapeflow as sf
from shapeflow.errors import DataLossWarning


@pytest.fixture
def quad_tri():
    V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0.5, 0.3]])
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [1, 0], [0.5, 0.5], [1, 1]], float)
    return sf.Mesh(V, [[0, 1, 2, 3], [1, 4, 2]], attributes={"color": np.arange(15.0).reshape(5, 3) / 15},
                   corner_attributes={"uv": uv},
                   face_attributes={"quality": np.array([0.5, 2.0], np.float32), "region": np.array([3, 9], np.uint8)},
                   metadata={"ply": {"comment": ["scanned 2026"], "obj_info": ["units mm"]}})


@pytest.mark.parametrize("binary", [True, False])
def test_plyfile_reads_what_is_written(tmp_path, quad_tri, binary):
    p = tmp_path / "m.ply"
    sf.save(p, quad_tri, binary=binary)
    d = PlyData.read(str(p))
    face = d["face"].data
    assert [list(v) for v in face["vertex_indices"]] == quad_tri.faces_as_lists()
    np.testing.assert_array_equal(face["quality"], [0.5, 2.0])
    assert face["region"].dtype == np.uint8 and face["region"].tolist() == [3, 9]
    tc = np.concatenate([np.asarray(t) for t in face["texcoord"]]).reshape(-1, 2)
    np.testing.assert_allclose(tc, quad_tri.corner_attributes["uv"], rtol=1e-7)
    vert = d["vertex"].data
    np.testing.assert_allclose(np.column_stack([vert["red"], vert["green"], vert["blue"]]),
                               quad_tri.attributes["color"])
    assert "scanned 2026" in d.comments and "units mm" in d.obj_info


@pytest.mark.parametrize("text", [True, False])
def test_plyfile_files_read(tmp_path, text):
    verts = np.array([(0, 0, 0), (1, 0, 0), (0, 1, 0), (1, 1, 0)], dtype=[("x", "f4"), ("y", "f4"), ("z", "f4")])
    faces = np.array([([0, 1, 2], 7, [0, 0, 1, 0, 0, 1]), ([1, 3, 2], 8, [1, 0, 1, 1, 0, 1])],
                     dtype=[("vertex_indices", "i4", (3,)), ("label", "i2"), ("texcoord", "f4", (6,))])
    PlyData([PlyElement.describe(verts, "vertex"), PlyElement.describe(faces, "face"),
             PlyElement.describe(np.array([(1.5,)], dtype=[("w", "f8")]), "camera")],
            text=text, comments=["from plyfile"]).write(str(tmp_path / "p.ply"))
    with pytest.warns(DataLossWarning, match="element 'camera'"):
        m = sf.load(tmp_path / "p.ply")
    assert m.faces_as_lists() == [[0, 1, 2], [1, 3, 2]]
    assert m.face_attributes["label"].dtype == np.int16 and m.face_attributes["label"].tolist() == [7, 8]
    np.testing.assert_array_equal(m.corner_attributes["uv"], faces["texcoord"].reshape(-1, 2))
    assert m.metadata["ply"]["comment"] == ["from plyfile"]


def test_round_trip_and_flow_keep_everything(tmp_path, quad_tri):
    p = tmp_path / "m.ply"
    out = sf.flow(quad_tri, -2.0, lam_border=0.3)
    sf.save(p, out)
    back = sf.load(p)
    np.testing.assert_array_equal(back.vertices, out.vertices)
    for k in ("quality", "region"):
        assert back.face_attributes[k].dtype == quad_tri.face_attributes[k].dtype
        np.testing.assert_array_equal(back.face_attributes[k], quad_tri.face_attributes[k])
    np.testing.assert_allclose(back.corner_attributes["uv"], quad_tri.corner_attributes["uv"], rtol=1e-7)
    assert back.metadata["ply"]["comment"] == ["scanned 2026"] and back.metadata["ply"]["obj_info"] == ["units mm"]


def test_what_ply_cannot_hold_is_named(tmp_path, quad_tri):
    m = quad_tri.with_face_attributes(material=["wood", "steel"])
    with pytest.warns(DataLossWarning, match="face attribute 'material'"):
        sf.save(tmp_path / "m.ply", m)
