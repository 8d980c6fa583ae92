"""Creased Catmull–Clark subdivision: the crease rules on their own (expected values derived here),
the creases a result carries, OBJ crease tags and the parameter checks.  Blender's own results:
test_blender_creases.py."""

from __future__ import annotations

import numpy as np
import pytest

import shapeflow as sf
from shapeflow.errors import ParameterError
from shapeflow.subdivision import subdivide, subdivision_matrix


def box():
    """A 2 × 2 × 2 box of quads (a cube, simply subdivided once, stretched) and the edges of the box."""
    cube = sf.Mesh([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)],
                   [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]])
    m = sf.subdivide(cube, 1, scheme="simple")
    V, e = m.vertices, m.topology.edges
    extreme = (np.abs(V) == 1).sum(axis=1) >= 2                 # on an edge of the box
    return m.with_vertices(V * [1.0, 0.8, 0.6]), e[extreme[e[:, 0]] & extreme[e[:, 1]]]


def test_carried_creases_continue_the_surface():
    mesh, pairs = box()
    values = np.resize([1.0, 0.5, 0.25, 0.1, 0.8, 0.3], len(pairs))
    for boundary in ("smooth", "keep-corners"):
        step = subdivide(mesh, 1, boundary=boundary, creases=(pairs, values))
        for _ in range(2):
            step = subdivide(step, 1, boundary=boundary, creases="mesh")
        full = subdivide(mesh, 3, boundary=boundary, creases=(pairs, values))
        assert np.abs(step.vertices - full.vertices).max() <= 1e-12 * mesh.diagonal


def test_carried_creases_are_the_halves_one_level_down():
    mesh, pairs = box()
    values = np.resize([1.0, 0.5, 0.25, 0.1, 0.8, 0.3], len(pairs))
    out = subdivide(mesh, 1, creases=(pairs, values))
    got_pairs, got = out.creases
    # Blender's 10·c²: one level takes 1 off; a crease <= sqrt(0.1) is gone, c = 1 stays 1
    left = np.where(values >= 1.0, 1.0, np.sqrt(np.maximum(10 * values ** 2 - 1, 0) / 10))
    expect = np.sort(np.repeat(left[left > 0], 2))
    np.testing.assert_allclose(np.sort(got), expect, rtol=1e-12)
    # every carried pair is an edge of the result, an old vertex joined to an edge point
    assert np.isin(np.sort(got_pairs, axis=1).tolist(), out.topology.edges.tolist()).all()
    assert (np.sort(got_pairs, axis=1)[:, 0] < mesh.n_vertices).all()
    assert (np.sort(got_pairs, axis=1)[:, 1] >= mesh.n_vertices).all()


# --- the rules, derived ----------------------------------------------------------------------

def strip(s_value):
    """Four quads in a row with the middle vertical edges creased: the crease-line vertices are the
    interesting ones.  Returns mesh, the creased pairs and the grid index."""
    xs, ys = np.meshgrid(np.arange(5.0), np.arange(5.0), indexing="ij")
    V = np.c_[xs.ravel(), ys.ravel(), (xs.ravel() == 2) * 1.0]     # a ridge along x = 2
    idx = lambda i, j: i * 5 + j  # noqa: E731
    F = [[idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1)] for i in range(4) for j in range(4)]
    m = sf.Mesh(V, F)
    pairs = np.array([[idx(2, j), idx(2, j + 1)] for j in range(4)])
    return m, pairs, idx


def test_edge_points_blend_by_the_sharpness():
    m, pairs, idx = strip(0.0)
    smooth = subdivide(m, 1, edge_order="sorted")
    sharp = subdivide(m, 1, edge_order="sorted", creases=(pairs, 1.0))
    e = m.topology.edges
    k = int(np.flatnonzero((e == np.sort([idx(2, 1), idx(2, 2)])).all(axis=1))[0])
    mid = m.vertices[[idx(2, 1), idx(2, 2)]].mean(axis=0)
    n = m.n_vertices
    np.testing.assert_allclose(sharp.vertices[n + k], mid, atol=1e-15)
    for c in (0.1, 0.2, 0.3):
        s = 10 * c * c                                   # < 1: s of the way to the midpoint
        out = subdivide(m, 1, edge_order="sorted", creases=(pairs, c))
        np.testing.assert_allclose(out.vertices[n + k], s * mid + (1 - s) * smooth.vertices[n + k], atol=1e-14)


def test_vertex_points_blend_when_the_crease_fades():
    # on the ridge, an interior vertex of the creased line: rule crease at the top level; with
    # sharpness s <= 1 its edges are smooth one level down, so it is s × crease + (1 − s) × smooth
    m, pairs, idx = strip(0.0)
    v = idx(2, 2)
    V = m.vertices
    smooth = subdivide(m, 1)
    crease = 0.75 * V[v] + 0.125 * (V[idx(2, 1)] + V[idx(2, 3)])
    for c, s in ((0.2, 0.4), (0.3, 0.9)):
        out = subdivide(m, 1, creases=(pairs, c))
        np.testing.assert_allclose(out.vertices[v], s * crease + (1 - s) * smooth.vertices[v], atol=1e-14)
    # s > 1: the crease rule alone; and a line end (one creased edge: a dart) is smooth
    out = subdivide(m, 1, creases=(pairs, 0.5))
    np.testing.assert_allclose(out.vertices[v], crease, atol=1e-15)
    dart = subdivide(m, 1, creases=(pairs[1:2], 0.5))
    np.testing.assert_allclose(dart.vertices[idx(2, 1)], smooth.vertices[idx(2, 1)], atol=1e-15)


def test_full_creases_keep_a_box_a_box():
    cube = sf.Mesh([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)],
                   [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]])
    out = subdivide(cube, 3, creases=(cube.topology.edges, 1.0))
    assert np.array_equal(out.vertices, subdivide(cube, 3, scheme="simple").vertices)
    assert len(out.creases[0]) == 12 * 2 ** 3 and np.all(out.creases[1] == 1.0)


def test_zero_creases_change_nothing():
    cube = sf.Mesh([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)],
                   [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]])
    plain = subdivide(cube, 2)
    out = subdivide(cube, 2, creases=(cube.topology.edges, 0.0))
    assert np.array_equal(out.vertices, plain.vertices) and out.creases[0].shape == (0, 2)
    S0, _ = subdivision_matrix(cube, levels=2)
    S1, _ = subdivision_matrix(cube, levels=2, creases=(cube.topology.edges[:3], [0.5, 0.2, 1.0]))
    assert (S0 != S1).nnz and np.allclose(S1.sum(axis=1), 1.0)


def test_obj_crease_tags(tmp_path):
    m, pairs, idx = strip(0.0)
    lines = ["v %r %r %r" % tuple(p) for p in m.vertices.tolist()]
    lines += ["f " + " ".join(str(i + 1) for i in f) for f in m.faces_as_lists()]
    lines += [f"t crease 2/1/0 {a} {b} 2.5" for a, b in pairs]          # OpenSubdiv sharpness 2.5 = 10·0.5²
    p = tmp_path / "ridge.obj"
    p.write_text("\n".join(lines) + "\n")
    got = subdivide(sf.load(p), 2, creases="mesh")
    ref = subdivide(m, 2, creases=(pairs, 0.5))
    np.testing.assert_allclose(got.vertices, ref.vertices, atol=1e-14)


@pytest.mark.parametrize("creases, msg", [
    ("file", "creases must be"),
    (([[0, 1]],), "pair"),
    (([[0, 6]], [0.5]), "row 0 \\(0, 6\\) is not an edge"),
    (([[0, 1], [1, 2]], [0.5, 1.5]), "value 1 is 1.5"),
    (([[0, 1], [1, 2]], [0.5, 0.2, 0.1]), "2 edges but 3 values"),
    (([[0, 1]], [np.nan]), "value 0"),
])
def test_bad_creases(creases, msg):
    m, _, _ = strip(0.0)
    with pytest.raises(ParameterError, match=msg):
        subdivide(m, 1, creases=creases)
