"""shapeflow's writers, read back by independent parsers (plyfile, meshio, and a reader written here)."""

from __future__ import annotations

import meshio  # test dependencies (the test extra)
import numpy as np
import plyfile
import pytest

import shapeflow as sf
from shapeflow import io as sio


@pytest.fixture(scope="module")
def cage():
    """Triangles, quads and pentagons, with weights and a uchar colour."""
    m = sf.load_example("spot_cage")
    n = m.n_vertices
    return m.with_attributes(weight=np.linspace(0.0, 1.0, n), red=(np.arange(n) % 256).astype(np.uint8))


def _faces(mesh):
    return [list(mesh.face_indices[a:b]) for a, b in zip(mesh.face_offsets[:-1], mesh.face_offsets[1:])]


@pytest.mark.parametrize("binary", [True, False])
def test_ply_read_by_plyfile(tmp_path, cage, binary):
    p = tmp_path / "m.ply"
    sio.save(p, cage, binary=binary)
    data = plyfile.PlyData.read(str(p))
    v = data["vertex"]
    assert np.array_equal(np.c_[v["x"], v["y"], v["z"]], cage.vertices)
    assert np.array_equal(v["weight"], cage.attributes["weight"])
    assert v["red"].dtype == np.uint8 and np.array_equal(v["red"], cage.attributes["red"])
    got = [list(f) for f in data["face"]["vertex_indices"]]
    assert got == _faces(cage)


@pytest.mark.parametrize("ext", [".obj", ".ply"])   # meshio reads only triangle OFF files
def test_read_by_meshio(tmp_path, cage, ext):
    p = tmp_path / f"m{ext}"
    # meshio reads OBJ texture coordinates only when there is one per vertex; the cage's are per corner
    sio.save(p, cage.with_corner_attributes(**{k: None for k in cage.corner_attributes}))
    m = meshio.read(str(p))
    assert np.array_equal(m.points, cage.vertices)
    faces = [list(c) for block in m.cells for c in block.data]
    # meshio groups faces into blocks of one size: compare as multisets, corner order included
    assert sorted(map(tuple, faces)) == sorted(map(tuple, _faces(cage)))


def test_obj_read_by_a_reader_written_here(tmp_path, cage):
    p = tmp_path / "m.obj"
    sio.save(p, cage)
    V, F = [], []
    for line in p.read_text().splitlines():
        w = line.split()
        if w[:1] == ["v"]:
            V.append([float(x) for x in w[1:4]])
        elif w[:1] == ["f"]:
            F.append([int(x.split("/")[0]) - 1 for x in w[1:]])
    assert np.array_equal(np.array(V), cage.vertices) and F == _faces(cage)


def test_off_read_by_a_reader_written_here(tmp_path, cage):
    p = tmp_path / "m.off"
    sio.save(p, cage)
    words = [ln.split() for ln in p.read_text().splitlines() if ln.strip() and not ln.startswith("#")]
    assert words[0] == ["OFF"]
    nv, nf = int(words[1][0]), int(words[1][1])
    V = np.array([[float(x) for x in w[:3]] for w in words[2:2 + nv]])
    F = [[int(x) for x in w[1:1 + int(w[0])]] for w in words[2 + nv:2 + nv + nf]]
    assert np.array_equal(V, cage.vertices) and F == _faces(cage)
