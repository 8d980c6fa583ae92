"""Other libraries' meshes in, shapeflow meshes out, and back: trimesh, pyvista, meshio."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from conftest import need

import shapeflow as sf
from shapeflow.errors import DataLossWarning

trimesh = need("trimesh", "trimesh (a test dependency)")
pv = need("pyvista", "pyvista (a test dependency)")
meshio = need("meshio", "meshio (a test dependency)")


@pytest.fixture
def spot():
    return sf.load_example("spot_cage")       # triangles, quads and pentagons


def faces(mesh):
    return [list(map(int, f)) for f in mesh.faces_as_lists()]


def test_pyvista_round_trip_keeps_ngons_and_point_data(spot):
    w = np.linspace(0, 1, spot.n_vertices)
    poly = spot.with_weights(w).to_pyvista()
    assert poly.n_cells == spot.n_faces and poly.n_points == spot.n_vertices
    np.testing.assert_array_equal(poly.point_data["weight"], w)
    back = sf.Mesh.from_pyvista(poly)
    assert faces(back) == faces(spot) and np.array_equal(back.vertices, spot.vertices)
    # every call takes the pyvista object as it is, and agrees with the shapeflow mesh
    np.testing.assert_array_equal(sf.flow(poly, -5.0, weights="weight").vertices,
                                  sf.flow(spot, -5.0, weights=w).vertices)


def test_meshio_round_trip_groups_by_size(spot):
    with pytest.warns(DataLossWarning, match="face order"):
        mm = spot.to_meshio()
    kinds = {b.type: len(b.data) for b in mm.cells}
    assert kinds == {{3: "triangle", 4: "quad"}.get(k, "polygon"): c for k, c in spot.face_count_by_size().items()}
    back = sf.Mesh.from_meshio(mm)
    assert sorted(map(tuple, faces(back))) == sorted(map(tuple, faces(spot)))
    assert np.allclose(sf.laplacian(mm).diagonal(), sf.laplacian(back).diagonal())


def test_trimesh_in_and_out(spot):
    with pytest.warns(DataLossWarning, match="fans"):
        tm = spot.to_trimesh()
    assert len(tm.faces) == sum(k - 2 for k in spot.face_sizes)        # fans: k - 2 triangles per face
    assert np.array_equal(tm.vertices, spot.vertices)                   # no merging or reordering
    m = sf.Mesh.from_trimesh(tm)
    out = sf.smooth(tm, 2.0)
    np.testing.assert_array_equal(out.vertices, sf.smooth(m, 2.0).vertices)
    # an independent check of the triangles trimesh holds: its area is that of the fans, summed here
    area = 0.0
    for f in faces(spot):
        p = spot.vertices[f]
        area += sum(0.5 * np.linalg.norm(np.cross(p[k] - p[0], p[k + 1] - p[0])) for k in range(1, len(f) - 1))
    assert abs(tm.area - area) < 1e-12 * area


def test_objects_with_vertices_and_faces_are_accepted_everywhere(spot):
    class Plain:
        vertices = spot.vertices
        faces = spot.faces_as_lists()

    tri = sf.Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0.0]], [[0, 1, 2]])

    class Triangles:                           # open3d's names
        vertices = tri.vertices
        triangles = np.array([[0, 1, 2]])

    for obj in (Plain(),):
        assert sf.flow(obj, -1.0).n_faces == spot.n_faces
        assert sf.subdivide(obj).n_faces == spot.n_corners
        assert sf.Brush(obj, radius=0.2).mesh.n_vertices == spot.n_vertices
    assert sf.cotan_weights(Triangles()).W.shape == (3, 3)
    with pytest.raises(sf.ParameterError, match="vertices and faces"):
        sf.flow(object(), -1.0)


def test_a_cli_like_trip_through_files_keeps_the_library_objects_honest(tmp_path, spot):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataLossWarning)
        sf.save(tmp_path / "a.ply", spot.to_pyvista())
    assert faces(sf.load(tmp_path / "a.ply")) == faces(spot)


def test_open3d_round_trip_with_colours(spot):
    """A real open3d TriangleMesh: built by to_open3d, passed to every call as it is, read back;
    open3d's own surface area checks the triangles it holds."""
    o3d = need("open3d", "open3d (a test dependency on Linux x86-64)")
    colors = np.random.default_rng(0).random((spot.n_vertices, 3))
    with pytest.warns(DataLossWarning, match="fans"):
        om = spot.with_attributes(color=colors).to_open3d()
    assert isinstance(om, o3d.geometry.TriangleMesh)
    assert len(om.triangles) == sum(k - 2 for k in spot.face_sizes)
    np.testing.assert_array_equal(np.asarray(om.vertices), spot.vertices)
    np.testing.assert_array_equal(np.asarray(om.vertex_colors), colors)
    area = sum(0.5 * np.linalg.norm(np.cross(spot.vertices[f[k]] - spot.vertices[f[0]],
                                              spot.vertices[f[k + 1]] - spot.vertices[f[0]]))
               for f in faces(spot) for k in range(1, len(f) - 1))
    assert abs(om.get_surface_area() - area) < 1e-12 * area
    back = sf.Mesh.from_open3d(om)
    np.testing.assert_array_equal(back.attributes["color"], colors)
    assert back.n_faces == len(om.triangles)
    np.testing.assert_array_equal(sf.smooth(om, 2.0).vertices, sf.smooth(back, 2.0).vertices)
    out = sf.enhance(back, 10.0).to_open3d()
    assert out.has_vertex_colors() and not np.allclose(np.asarray(out.vertices), spot.vertices)
