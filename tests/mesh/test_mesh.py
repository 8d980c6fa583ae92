"""The Mesh type: construction, normalisation, topology, diagnostics (issue 2)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import FIXTURES, MESHES, load_fixture_mesh, requires_shared
from meshgen import grid

import shapeflow as sf

# --- construction and the one normaliser ------------------------------------------

def test_three_input_layouts_give_the_same_csr():
    V = np.zeros((6, 3))
    V[:, 0] = np.arange(6)
    lists = [[0, 1, 2], [1, 3, 4, 2], [2, 4, 5]]
    a = sf.Mesh(V, lists)
    b = sf.Mesh.from_csr(V, [3, 4, 3], [0, 1, 2, 1, 3, 4, 2, 2, 4, 5])
    assert a == b
    assert a.face_offsets.tolist() == [0, 3, 7, 10]
    assert a.face_sizes.tolist() == [3, 4, 3]
    tri = sf.Mesh(V, np.array([[0, 1, 2], [3, 4, 5]]))
    assert tri.face_indices.tolist() == [0, 1, 2, 3, 4, 5] and tri.face_offsets.tolist() == [0, 3, 6]
    quad = sf.Mesh(V, np.array([[0, 1, 2, 3]], dtype=np.int32))
    assert quad.face_sizes.tolist() == [4]


def test_arrays_are_float64_read_only_and_topology_is_shared():
    m = grid(4)
    assert m.vertices.dtype == np.float64 and m.face_indices.dtype == np.int64
    with pytest.raises(ValueError):
        m.vertices[0, 0] = 1.0
    m2 = m.with_vertices(m.vertices * 2)
    assert m2.topology is m.topology
    assert m.topology.edges is m.topology.edges  # cached


def test_corner_neighbours_in_loop_order():
    m = sf.Mesh(np.zeros((7, 3)), [[0, 1, 2], [3, 4, 5, 6]])
    t = m.topology
    assert t.corner_vertices.tolist() == [[2, 0, 1], [0, 1, 2], [1, 2, 0],
                                          [6, 3, 4], [3, 4, 5], [4, 5, 6], [5, 6, 3]]
    assert t.corner_face.tolist() == [0, 0, 0, 1, 1, 1, 1]


def test_edges_and_edge_faces():
    m = sf.Mesh(np.zeros((5, 3)), [[0, 1, 2, 3], [1, 4, 2]])
    t = m.topology
    assert t.edges.tolist() == [[0, 1], [0, 3], [1, 2], [1, 4], [2, 3], [2, 4]]
    e12 = t.edges.tolist().index([1, 2])
    assert sorted(t.edge_faces(e12).tolist()) == [0, 1]
    assert t.edge_face_count.tolist() == [1, 1, 2, 1, 1, 1]
    assert t.boundary_vertices.tolist() == [0, 1, 2, 3, 4]
    assert t.boundary_loop_count == 1


# --- topology on the fixtures and shared meshes -------------------------------------------

@pytest.mark.skipif(FIXTURES is None, reason="shared/ not found")
def test_boundary_of_grid_open_fixture():
    m = load_fixture_mesh("grid_open")
    t = m.topology
    # an open grid: boundary = the vertices on the outer rectangle of the xy extent
    lo, hi = m.vertices[:, :2].min(axis=0), m.vertices[:, :2].max(axis=0)
    on_rim = (np.isclose(m.vertices[:, 0], lo[0]) | np.isclose(m.vertices[:, 0], hi[0])
              | np.isclose(m.vertices[:, 1], lo[1]) | np.isclose(m.vertices[:, 1], hi[1]))
    assert np.array_equal(t.boundary_vertex_mask, on_rim)
    assert t.boundary_loop_count == 1
    assert t.euler_characteristic == 1
    assert int(t.boundary_edge_mask.sum()) == int(on_rim.sum())   # a closed loop: as many edges as vertices


@pytest.mark.skipif(FIXTURES is None, reason="shared/ not found")
def test_closed_torus_fixture():
    t = load_fixture_mesh("torus").topology
    assert not t.boundary_edge_mask.any() and t.boundary_loop_count == 0
    assert t.euler_characteristic == 0
    assert (t.edge_face_count == 2).all()
    assert not t.inconsistent_edge_mask.any()


def test_generated_torus_is_closed_with_euler_zero():
    nu, nv = 12, 8
    u, v = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    idx = lambda i, j: (i % nu) * nv + (j % nv)  # noqa: E731
    faces = [[idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1)] for i in range(nu) for j in range(nv)]
    a, b = 2 * np.pi * u.ravel() / nu, 2 * np.pi * v.ravel() / nv
    V = np.c_[(2 + np.cos(b)) * np.cos(a), (2 + np.cos(b)) * np.sin(a), np.sin(b)]
    t = sf.Mesh(V, faces).topology
    assert t.euler_characteristic == 0 and t.boundary_loop_count == 0 and t.n_edges == 2 * nu * nv


# χ = V − E + F from tests/data/SOURCES.md's genus, boundary loops and components: χ = Σ (2 − 2g − b)
EULER = {
    "spot_quad": 2, "spot_tri": 2, "spot_control_hybrid": 2, "bob_quad": 0, "bob_control_quad": 0,
    "blub_control_hybrid": 2, "penguin_control_hybrid": 2,
    "rook_cage_hybrid_open": 1, "pawn_cage_quad_open": 1, "plane_holes_tri_open": -25,
}
LOOPS = {"rook_cage_hybrid_open": 1, "pawn_cage_quad_open": 1, "plane_holes_tri_open": 27}


@requires_shared
@pytest.mark.parametrize("name", sorted(EULER))
def test_euler_characteristic_and_boundary_loops_of_shared_meshes(name):
    m = sf.load(MESHES / f"{name}.obj")
    t = m.topology
    assert t.euler_characteristic == EULER[name]
    assert t.boundary_loop_count == LOOPS.get(name, 0)
    assert not t.nonmanifold_edge_mask.any()
    d = m.diagnostics()
    assert d.nonmanifold_edges == 0 and d.nonmanifold_vertices == 0 and d.unreferenced_vertices == 0
    assert d.duplicate_faces == 0 and d.inconsistent_orientation_edges == 0


# --- diagnostics: reported, not rejected ------------------------------------------------------

def test_diagnostics_report_suspicious_but_legal_input():
    V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0, 0], [0, 0, 1], [9, 9, 9],
                  [3, 0, 0], [4, 0, 0], [5, 0, 0]], float)
    faces = [[0, 1, 2, 3],
             [0, 1, 2],                                       # a triangle on the same edge 0-1
             [1, 0, 5],                                       # third face on edge 0-1: non-manifold
             [3, 2, 1, 0],                                    # the quad again, reversed: duplicate face
             [7, 8, 9]]                                       # collinear: zero area
    m = sf.Mesh(V, faces)
    d = m.diagnostics()
    assert d.nonmanifold_edges >= 1
    assert d.unreferenced_vertices == 2          # vertices 4 and 6
    assert d.duplicate_faces == 1
    assert d.zero_area_faces == 1
    assert len(d.warnings()) == 4
    # a face traversed the wrong way round is reported
    good = sf.Mesh(V[:6], [[0, 1, 2, 3], [2, 1, 4]])   # the quad runs 1→2, the triangle 2→1
    assert good.diagnostics().inconsistent_orientation_edges == 0
    bad = sf.Mesh(V[:6], [[0, 1, 2, 3], [1, 2, 4]])    # both run 1→2
    assert bad.diagnostics().inconsistent_orientation_edges == 1


def test_nonmanifold_vertex_bowtie():
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0]], float)
    m = sf.Mesh(V, [[0, 1, 2], [0, 3, 4]])       # two triangles touching at vertex 0 only
    d = m.diagnostics()
    assert d.nonmanifold_vertices == 1 and d.examples["nonmanifold_vertices"] == 0


def test_repr_and_face_helpers():
    m = sf.Mesh(np.zeros((5, 3)), [[0, 1, 2, 3], [1, 4, 2]])
    assert "1×3" in repr(m) and "1×4" in repr(m)
    assert m.face(1).tolist() == [1, 4, 2]
    with pytest.raises(IndexError):
        m.face(2)
    with pytest.raises(sf.MeshError, match="mixed sizes"):
        m.faces_as_array()
    assert m.faces_as_lists() == [[0, 1, 2, 3], [1, 4, 2]]


def test_a_mesh_pickles_read_only_with_its_attributes_and_weld_map():
    import pickle

    soup = sf.Mesh(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0.]]),
                   [[0, 1, 2], [3, 4, 5, 0]], weights=np.linspace(0, 1, 6), metadata={"name": "soup"})
    welded = sf.weld(soup)
    for m in (soup, welded):
        back = pickle.loads(pickle.dumps(m))
        np.testing.assert_array_equal(back.vertices, m.vertices)
        np.testing.assert_array_equal(back.face_indices, m.face_indices)
        np.testing.assert_array_equal(back.face_offsets, m.face_offsets)
        np.testing.assert_array_equal(back.weights, m.weights)
        assert back.metadata == m.metadata
        assert not back.vertices.flags.writeable and not back.face_indices.flags.writeable
        np.testing.assert_array_equal(back.topology.edges, m.topology.edges)   # caches rebuilt, not carried
    np.testing.assert_array_equal(pickle.loads(pickle.dumps(welded)).weld_map, welded.weld_map)


def test_weld_if_split_welds_only_split_meshes():
    from shapeflow.geometry.weld import weld_if_split

    closed = sf.load_example("spot")
    assert weld_if_split(closed) is closed
    soup = sf.Mesh(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0.]]),
                   [[0, 1, 2], [3, 4, 5]])
    w = weld_if_split(soup)
    assert w is not soup and w.n_vertices == 4 and w.weld_map.tolist() == [0, 1, 2, 1, 3, 2]
    open_grid = sf.Mesh(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.]]), [[0, 1, 2]])
    assert weld_if_split(open_grid) is open_grid                # open, but nothing coincides
