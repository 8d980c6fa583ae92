"""Catmull–Clark and simple subdivision (shapeflow.subdivision).

* every ``subdiv_*`` Blender fixture: level-1 cases in Blender's exact vertex and
  face order, deeper levels as point sets (Blender evaluates a grid per face,
  we refine level by level: same points and faces, other order);
* analytic checks: bicubic B-spline on a regular grid, the cube's limit,
  Euler characteristic, quads, rows of S;
* the rules for boundaries and non-manifold configurations (OpenSubdiv's,
  which Blender uses; each was compared with Blender 5.0.1 when written, and
  ``test_matches_live_blender`` re-checks them when ``bpy`` is importable).
"""

from __future__ import annotations

import importlib.util
import re

import numpy as np
import pytest
import scipy.sparse as sp
from conftest import ROOT, fixture_cases, load_fixture_case, load_fixture_mesh, requires_shared
from scipy.spatial import cKDTree

import shapeflow as sf
from shapeflow.errors import ParameterError
from shapeflow.subdivision import subdivide, subdivision_matrix

TOL = 1e-5  # × bounding-box diagonal (Blender works in float32)

#: the fixtures were made by a Blender running 2 threads: meshes with >= 1000
#: faces get their edges from 2 hash maps (see shapeflow.subdivision)
FIXTURE_THREADS = 2

BOUNDARY = {"ALL": "smooth", "PRESERVE_CORNERS": "keep-corners"}
SCHEME = {"CATMULL_CLARK": "catmull-clark", "SIMPLE": "simple"}


# --------------------------------------------------------------------------
# small meshes (built here, independent of other test helpers)
# --------------------------------------------------------------------------

def grid(nx, ny, z=None, seed=0):
    """nx × ny vertices at integer (i, j), unit quads; vertex id i * ny + j."""
    i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    rng = np.random.default_rng(seed)
    h = rng.normal(size=i.shape) if z is None else z
    V = np.stack([i, j, h], -1).reshape(-1, 3).astype(float)
    a = (i[:-1, :-1] * ny + j[:-1, :-1]).ravel()
    F = np.stack([a, a + ny, a + ny + 1, a + 1], 1)
    return sf.Mesh(V, F)


def cube(half=1.0):
    V = [[x, y, z] for x in (-half, half) for y in (-half, half) for z in (-half, half)]
    F = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]
    return sf.Mesh(V, F)


def hybrid():
    """A closed mesh with triangles, quads and two hexagons (a hexagonal prism,
    one side split into triangles)."""
    t = np.linspace(0, 2 * np.pi, 7)[:-1]
    ring = np.c_[np.cos(t), np.sin(t)]
    V = np.r_[np.c_[ring, np.zeros(6)], np.c_[ring * 0.8, np.ones(6)]]
    F = [[5, 4, 3, 2, 1, 0], [6, 7, 8, 9, 10, 11]]
    for k in range(6):
        a, b = k, (k + 1) % 6
        if k == 0:
            F += [[a, b, b + 6], [a, b + 6, a + 6]]
        else:
            F.append([a, b, b + 6, a + 6])
    return sf.Mesh(V, F)


def bowtie():
    """Two triangles sharing only vertex 0."""
    return sf.Mesh([[0, 0, 0], [1, 0, 0], [1, 1, 0], [-1, 0, 0.2], [-1, -1, 0.5]], [[0, 1, 2], [0, 3, 4]])


def two_tets():
    """Two closed tetrahedra touching at vertex 0 (two closed fans at one vertex)."""
    T = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    V = np.vstack([T, -T[1:] * [1, 1.3, 0.7]])
    F = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3], [0, 5, 4], [0, 4, 6], [0, 6, 5], [4, 5, 6]]
    return sf.Mesh(V, F)


def fin():
    """Three quads sharing the edge (0, 1)."""
    V = [[0, 0, 0], [0, 0, 1], [1, 0, 0], [1, 0, 1], [-1, 0.2, 0], [-1, 0.2, 1], [0, 1, 0], [0, 1, 1.2]]
    return sf.Mesh(V, [[0, 2, 3, 1], [1, 5, 4, 0], [0, 6, 7, 1]])


def box_with_wall():
    """A closed 2×1×1 box of quads with an inner wall: an interior non-manifold crease."""
    xs = [0, 1, 2.2]
    V = np.array([[x, y, z] for x in xs for y in (0, 1) for z in (0, 1)], float)
    V[4] += [0.1, 0, 0]

    def idx(i, y, z):
        return i * 4 + y * 2 + z

    F = []
    for i in range(2):
        F += [[idx(i, 0, 0), idx(i + 1, 0, 0), idx(i + 1, 0, 1), idx(i, 0, 1)],
              [idx(i, 1, 0), idx(i, 1, 1), idx(i + 1, 1, 1), idx(i + 1, 1, 0)],
              [idx(i, 0, 0), idx(i, 1, 0), idx(i + 1, 1, 0), idx(i + 1, 0, 0)],
              [idx(i, 0, 1), idx(i + 1, 0, 1), idx(i + 1, 1, 1), idx(i, 1, 1)]]
    F += [[idx(0, 0, 0), idx(0, 0, 1), idx(0, 1, 1), idx(0, 1, 0)],
          [idx(2, 0, 0), idx(2, 1, 0), idx(2, 1, 1), idx(2, 0, 1)],
          [idx(1, 0, 0), idx(1, 1, 0), idx(1, 1, 1), idx(1, 0, 1)]]  # the wall
    return sf.Mesh(V, F)


def flipped_quad():
    """A 2×2 quad grid whose second quad is wound the other way."""
    V = [[0, 0, 0], [1, 0, 0], [2, 0, 0.3], [0, 1, 0], [1, 1, 0.2], [2, 1, 0], [1, 2, 0], [0, 2, 0.1], [2, 2, 0.0]]
    return sf.Mesh(V, [[0, 1, 4, 3], [4, 5, 2, 1], [3, 4, 6, 7], [4, 5, 8, 6]])


def squares_at_corner():
    """Two quads touching at vertex 2: a boundary vertex with four boundary edges."""
    V = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 1, 0], [2, 2, 0], [1, 2, 0.3]]
    return sf.Mesh(V, [[0, 1, 2, 3], [2, 4, 5, 6]])


def diag_of(points):
    return float(np.linalg.norm(points.max(0) - points.min(0)))


def cyclic_faces(fs, fi):
    """Faces as a set of tuples, each rotated to start at its smallest vertex."""
    off = np.r_[0, np.cumsum(fs)]
    out = set()
    for f in range(len(fs)):
        c = list(fi[off[f]:off[f + 1]])
        k = int(np.argmin(c))
        out.add(tuple(c[k:] + c[:k]))
    return out


# --------------------------------------------------------------------------
# Blender fixtures
# --------------------------------------------------------------------------

def _run_case(case):
    c = load_fixture_case(case)
    p = c["params"]
    mesh = load_fixture_mesh(c["mesh"]).with_weights(c["weights"])
    out = subdivide(mesh, p["levels"], scheme=SCHEME[p["subdivision_type"]],
                    boundary=BOUNDARY[p["boundary_smooth"]], weights_rule="linear",
                    blender_threads=FIXTURE_THREADS)
    return mesh, out, c


@requires_shared
@pytest.mark.parametrize("case", fixture_cases("subdiv_"))
def test_blender_fixture(case):
    mesh, out, c = _run_case(case)
    R = c["result"]
    diag = diag_of(R)
    # same face count and face sizes (all quads)
    assert out.n_faces == len(c["result_face_sizes"])
    assert out.face_sizes.tolist() == c["result_face_sizes"].tolist()
    assert out.n_vertices == len(R)
    n = mesh.n_vertices
    if c["params"]["levels"] == 1:
        # Blender's own order: vertices, faces (and each face's first corner)
        err = np.abs(out.vertices - R).max() / diag
        assert err < TOL, err
        assert np.array_equal(out.face_indices, c["result_face_indices"])
        np.testing.assert_allclose(out.weights, c["result_weights"], atol=1e-6)
        return
    # deeper levels: original vertices first in both, in the same order
    assert np.abs(out.vertices[:n] - R[:n]).max() / diag < TOL
    # the new vertices as point sets: a one-to-one nearest-neighbour matching
    dist, j = cKDTree(R[n:]).query(out.vertices[n:])
    assert dist.max() / diag < TOL, dist.max() / diag
    assert np.unique(j).size == j.size, "the matching is not one-to-one"
    ours_to_blender = np.r_[np.arange(n), n + j]
    # the same faces, with the same orientation, once mapped
    mapped = ours_to_blender[out.face_indices]
    assert cyclic_faces(out.face_sizes, mapped) == cyclic_faces(c["result_face_sizes"], c["result_face_indices"])
    # the linearly interpolated weights
    w = np.empty(out.n_vertices)
    w[ours_to_blender] = out.weights
    np.testing.assert_allclose(w, c["result_weights"], atol=1e-6)


@requires_shared
def test_blender_edge_order_depends_on_threads():
    # suzanne_hybrid has 2945 faces: Blender split its edges over 2 hash maps
    case = "subdiv_suzanne_hybrid_simple_all_1"
    c = load_fixture_case(case)
    mesh = load_fixture_mesh(c["mesh"])
    n = mesh.n_vertices
    one = subdivide(mesh, scheme="simple", blender_threads=1)
    two = subdivide(mesh, scheme="simple", blender_threads=2)
    srt = subdivide(mesh, scheme="simple", edge_order="sorted")
    diag = diag_of(c["result"])
    assert np.abs(two.vertices - c["result"]).max() / diag < TOL
    assert np.abs(one.vertices - c["result"]).max() / diag > 0.01  # another order...
    for other in (one, srt):  # ...of the same points
        d, j = cKDTree(c["result"]).query(other.vertices)
        assert d.max() / diag < TOL and np.unique(j).size == j.size
        assert np.array_equal(other.vertices[:n], two.vertices[:n])
    # fewer than 1000 faces: one map whatever the thread count
    small = load_fixture_mesh("suzanne")
    assert np.array_equal(subdivide(small, blender_threads=1).vertices, subdivide(small, blender_threads=8).vertices)


def read_obj(path):
    """A tiny OBJ reader (``v`` and ``f`` lines; ``f a/b/c`` tokens), independent of shapeflow.io."""
    V, sizes, idx = [], [], []
    for line in path.read_text().splitlines():
        parts = line.split()
        if not parts:
            continue
        if parts[0] == "v":
            V.append([float(x) for x in parts[1:4]])
        elif parts[0] == "f":
            corners = [int(tok.split("/")[0]) for tok in parts[1:]]
            sizes.append(len(corners))
            idx += [c - 1 if c > 0 else len(V) + c for c in corners]
    return sf.Mesh.from_csr(np.array(V), sizes, idx)


@requires_shared
@pytest.mark.parametrize("cage, fine, levels", [
    ("spot_control_hybrid", "spot_quad", 2),    # triangles, quads, pentagons
    ("bob_control_quad", "bob_quad", 2),        # genus 1
])
def test_crane_meshes_are_catmull_clark_of_their_cages(cage, fine, levels):
    """Keenan Crane's quad meshes are the Catmull–Clark subdivisions of his cages
    (made with other software): an independent check of the rules on real cages."""
    from conftest import MESHES

    c = read_obj(MESHES / f"{cage}.obj")
    q = read_obj(MESHES / f"{fine}.obj")
    out = subdivide(c, levels)
    assert out.n_vertices == q.n_vertices and out.n_faces == q.n_faces
    d, j = cKDTree(q.vertices).query(out.vertices)
    assert d.max() / q.diagonal < TOL
    assert np.unique(j).size == j.size
    assert out.topology.euler_characteristic == c.topology.euler_characteristic


# --------------------------------------------------------------------------
# analytic checks
# --------------------------------------------------------------------------

def cubic_bspline(x):
    """The centred uniform cubic B-spline basis function (support [-2, 2])."""
    x = np.abs(x)
    return np.where(x < 1, (4 - 6 * x**2 + 3 * x**3) / 6, np.where(x < 2, (2 - x) ** 3 / 6, 0.0))


def bspline_surface(ctrl, u, v, spacing):
    """Σ ctrl[a, b] B(u/spacing − a) B(v/spacing − b) for control points at (a, b)·spacing."""
    na, nb = ctrl.shape[:2]
    Bu = cubic_bspline(u[:, None] / spacing - np.arange(na)[None, :])  # (p, na)
    Bv = cubic_bspline(v[:, None] / spacing - np.arange(nb)[None, :])  # (p, nb)
    return np.einsum("pa,pb,abk->pk", Bu, Bv, ctrl)


def test_regular_grid_interior_is_the_bicubic_bspline():
    """Catmull–Clark on a regular grid is knot insertion for the uniform bicubic
    B-spline: the refined control net describes the same surface.  Checked by
    evaluating both B-spline surfaces (from their basis functions) away from the
    boundary, where only the interior rules were used."""
    nx, ny = 9, 8
    rng = np.random.default_rng(1)
    coarse = grid(nx, ny)
    # random 3-D control points (the identity is linear, any values will do)
    V = coarse.vertices + rng.normal(scale=0.3, size=coarse.vertices.shape)
    coarse = coarse.with_vertices(V)
    fine = subdivide(coarse, 1)
    # the fine net's grid indices: the simple scheme applied to the parameters
    param = subdivide(sf.Mesh(np.c_[grid(nx, ny).vertices[:, :2], np.zeros(nx * ny)], coarse.faces_as_array()),
                      1, scheme="simple").vertices[:, :2]
    k = np.rint(2 * param).astype(int)
    assert np.allclose(2 * param, k)
    fine_ctrl = np.full((2 * nx - 1, 2 * ny - 1, 3), np.nan)
    fine_ctrl[k[:, 0], k[:, 1]] = fine.vertices
    assert not np.isnan(fine_ctrl).any()
    coarse_ctrl = V.reshape(nx, ny, 3)
    # parameters at least two coarse spans from the boundary
    u = rng.uniform(2, nx - 3, 200)
    v = rng.uniform(2, ny - 3, 200)
    a = bspline_surface(coarse_ctrl, u, v, 1.0)
    b = bspline_surface(fine_ctrl, u, v, 0.5)
    np.testing.assert_allclose(b, a, atol=1e-12)
    # and so do two levels (same surface, quarter spacing)
    fine2 = subdivide(coarse, 2)
    param2 = subdivide(sf.Mesh(np.c_[grid(nx, ny).vertices[:, :2], np.zeros(nx * ny)], coarse.faces_as_array()),
                       2, scheme="simple").vertices[:, :2]
    k2 = np.rint(4 * param2).astype(int)
    ctrl2 = np.zeros((4 * nx - 3, 4 * ny - 3, 3))
    ctrl2[k2[:, 0], k2[:, 1]] = fine2.vertices
    np.testing.assert_allclose(bspline_surface(ctrl2, u, v, 0.25), a, atol=1e-12)


def test_regular_vertex_and_edge_stencils():
    """The tensor-product masks of the cubic B-spline at an interior vertex and edge."""
    m = grid(5, 5)
    S, _ = subdivision_matrix(m)
    center = 2 * 5 + 2
    row = S[center].toarray().ravel()
    w1 = np.array([1, 6, 1]) / 8
    expect = np.zeros((5, 5))
    expect[1:4, 1:4] = np.outer(w1, w1)
    np.testing.assert_allclose(row.reshape(5, 5), expect, atol=1e-15)
    # the edge point of (2,2)-(3,2): (1/2, 1/2) across the edge ⊗ (1/8, 6/8, 1/8) along it
    S, _ = subdivision_matrix(m, edge_order="sorted")
    e = int(np.flatnonzero((m.topology.edges == [center, center + 5]).all(1))[0])
    row = S[25 + e].toarray().ravel()
    expect = np.zeros((5, 5))
    expect[2:4, 1:4] = np.outer([0.5, 0.5], w1)
    np.testing.assert_allclose(row.reshape(5, 5), expect, atol=1e-15)


def test_cube_converges_to_its_limit():
    m = cube(1.0)
    # vertices keep their index at every level, so vertex 0 (a corner) can be followed
    pts = [(subdivision_matrix(m, levels=L)[0] @ m.vertices)[0] for L in range(1, 8)]
    pts = np.array(pts)
    # limit of a cube corner of [-1, 1]^3 (valence 3): (n²v + 4Σe + Σf) / (n(n+5)) on
    # the quad mesh itself = (9 + 4 − 1)/24 · (−1, −1, −1) = (−1/2, −1/2, −1/2)
    limit = np.full(3, -0.5)
    err = np.linalg.norm(pts - limit, axis=1)
    assert np.all(np.diff(err) < 0)
    ratio = err[1:] / err[:-1]
    np.testing.assert_allclose(ratio, 1 / 6, rtol=1e-6)  # subdominant eigenvalue at valence 3
    assert err[-1] < 2e-5
    np.testing.assert_allclose(pts[0], np.full(3, -5 / 9))  # level 1: (1/3)v + Σe/9 + Σf/9


def test_limit_positions_of_every_vertex():
    """After one step the mesh is all quads: the limit of each vertex is
    (k² v + 4 Σ neighbours + Σ diagonals) / (k (k + 5)); further levels converge to it."""
    m1 = subdivide(hybrid(), 1)
    t = m1.topology
    V = m1.vertices
    n = m1.n_vertices
    k = t.vertex_edge_count.astype(float)
    nb = np.zeros((n, 3))
    np.add.at(nb, t.edges[:, 0], V[t.edges[:, 1]])
    np.add.at(nb, t.edges[:, 1], V[t.edges[:, 0]])
    quads = m1.faces_as_array()
    diag = np.zeros((n, 3))
    for c in range(4):
        np.add.at(diag, quads[:, c], V[quads[:, (c + 2) % 4]])
    limit = (k[:, None] ** 2 * V + 4 * nb + diag) / (k * (k + 5))[:, None]
    S, _ = subdivision_matrix(m1, levels=6)
    approx = (S @ V)[:n]
    assert np.abs(approx - limit).max() < 1e-3 * diag_of(V)
    S5, _ = subdivision_matrix(m1, levels=5)
    assert np.abs(approx - limit).max() < np.abs((S5 @ V)[:n] - limit).max()


@pytest.mark.parametrize("make", [cube, hybrid, bowtie, fin, box_with_wall, two_tets, squares_at_corner,
                                  lambda: grid(5, 4)])
@pytest.mark.parametrize("scheme", ["catmull-clark", "simple"])
def test_euler_characteristic_and_quads(make, scheme):
    m = make()
    for levels in (1, 2):
        out = subdivide(m, levels, scheme=scheme)
        assert out.topology.euler_characteristic == m.topology.euler_characteristic
        assert set(out.face_sizes.tolist()) == {4}
        assert out.n_faces == m.n_corners * 4 ** (levels - 1)
        one = subdivide(m, 1, scheme=scheme)
        assert one.n_vertices == m.n_vertices + m.topology.n_edges + m.n_faces
        assert out.topology.boundary_loop_count == m.topology.boundary_loop_count


@requires_shared
@pytest.mark.parametrize("name", ["suzanne_hybrid", "cylinder_ngon", "grid_open", "ico_sphere", "torus"])
def test_euler_characteristic_fixture_meshes(name):
    m = load_fixture_mesh(name)
    out = subdivide(m, 2)
    assert out.topology.euler_characteristic == m.topology.euler_characteristic
    assert set(out.face_sizes.tolist()) == {4}
    assert not out.topology.inconsistent_edge_mask.any()


@pytest.mark.parametrize("scheme", ["catmull-clark", "simple"])
@pytest.mark.parametrize("boundary", ["smooth", "keep-corners"])
def test_matrix_rows_sum_to_one(scheme, boundary):
    for m in (hybrid(), grid(6, 5), fin(), two_tets()):
        for levels in (1, 2):
            S, topo = subdivision_matrix(m, levels=levels, scheme=scheme, boundary=boundary)
            assert sp.issparse(S) and S.format == "csr"
            assert S.shape == (topo.n_vertices, m.n_vertices)
            np.testing.assert_allclose(np.asarray(S.sum(axis=1)).ravel(), 1.0, atol=1e-14)
            assert S.data.min() >= 0  # convex combinations (no creases): weights stay in [0, 1]


def test_simple_scheme_is_midpoints_and_centroids():
    m = hybrid()
    out = subdivide(m, 1, scheme="simple")
    n = m.n_vertices
    np.testing.assert_array_equal(out.vertices[:n], m.vertices)
    t = m.topology
    mids = m.vertices[t.edges].mean(1)
    cents = np.array([m.vertices[f].mean(0) for f in m.faces_as_lists()])
    E = t.n_edges
    d, _ = cKDTree(mids).query(out.vertices[n:n + E])
    assert d.max() < 1e-12
    np.testing.assert_allclose(out.vertices[n + E:], cents, atol=1e-12)


def test_catmull_clark_rules_on_a_closed_mesh():
    """Face point = centroid; edge point = (a + b + f0 + f1)/4; vertex =
    (k−2)/k v + Σ neighbours/k² + Σ face points/k²; checked for every element."""
    m = hybrid()
    V = m.vertices
    faces = m.faces_as_lists()
    cents = np.array([V[f].mean(0) for f in faces])
    out = subdivide(m, 1, edge_order="sorted")
    t = m.topology
    n, E = m.n_vertices, t.n_edges
    np.testing.assert_allclose(out.vertices[n + E:], cents, atol=1e-12)
    for e, (a, b) in enumerate(t.edges):
        f0, f1 = t.edge_faces(e)
        np.testing.assert_allclose(out.vertices[n + e], (V[a] + V[b] + cents[f0] + cents[f1]) / 4, atol=1e-12)
    for v in range(n):
        nbrs = [b if a == v else a for a, b in t.edges if v in (a, b)]
        fs = [f for f, face in enumerate(faces) if v in face]
        k = len(nbrs)
        assert k == len(fs)
        expect = (k - 2) / k * V[v] + V[nbrs].sum(0) / k**2 + cents[fs].sum(0) / k**2
        np.testing.assert_allclose(out.vertices[v], expect, atol=1e-12)


# --------------------------------------------------------------------------
# boundaries and non-manifold configurations
# --------------------------------------------------------------------------

def test_open_boundary_rules():
    m = grid(4, 4)
    V = m.vertices
    smooth = subdivide(m, 1, edge_order="sorted")
    keep = subdivide(m, 1, boundary="keep-corners", edge_order="sorted")
    t = m.topology
    n = m.n_vertices
    # boundary edge points are midpoints
    for e in np.flatnonzero(t.boundary_edge_mask):
        a, b = t.edges[e]
        np.testing.assert_allclose(smooth.vertices[n + e], (V[a] + V[b]) / 2)
    # boundary vertices: 3/4 v + 1/8 (two boundary neighbours), corners included
    edge_v = 1 * 4 + 0  # (i=1, j=0): boundary, not a corner; neighbours (0,0) and (2,0)
    np.testing.assert_allclose(smooth.vertices[edge_v], 0.75 * V[edge_v] + (V[0] + V[8]) / 8)
    corner = 0  # neighbours along the boundary: (1,0) = 4 and (0,1) = 1
    np.testing.assert_allclose(smooth.vertices[corner], 0.75 * V[0] + (V[4] + V[1]) / 8)
    np.testing.assert_allclose(keep.vertices[corner], V[0])
    corners = [0, 3, 12, 15]
    others = np.setdiff1d(np.arange(keep.n_vertices), corners)
    np.testing.assert_allclose(keep.vertices[others], smooth.vertices[others])
    # the corner stays a corner at every level
    np.testing.assert_allclose(subdivide(m, 3, boundary="keep-corners").vertices[corners], V[corners])
    # the boundary curve is the cubic B-spline of the boundary polygon: evenly
    # spaced collinear control points give evenly spaced points on the line
    flat = grid(5, 5, z=np.zeros((5, 5)))
    out = subdivide(flat, 2)
    P = out.vertices
    on_side = (np.abs(P[:, 1]) < 1e-12) & (P[:, 0] > 1 - 1e-12) & (P[:, 0] < 3 + 1e-12)
    np.testing.assert_allclose(np.sort(P[on_side, 0]), np.linspace(1, 3, 9), atol=1e-12)


def test_nonmanifold_vertex_with_two_fans_stays():
    m = two_tets()
    out = subdivide(m, 2)
    np.testing.assert_array_equal(out.vertices[0], m.vertices[0])
    # the other vertices are ordinary smooth vertices (valence 3)
    one = subdivide(m, 1)
    assert not np.allclose(one.vertices[1:7], m.vertices[1:7])


def test_bowtie_and_touching_squares_keep_the_shared_vertex():
    for m, v in ((bowtie(), 0), (squares_at_corner(), 2)):
        for boundary in ("smooth", "keep-corners"):
            out = subdivide(m, 2, boundary=boundary)
            np.testing.assert_array_equal(out.vertices[v], m.vertices[v])


def test_fin_edge_is_sharp():
    m = fin()
    out = subdivide(m, 1, edge_order="sorted")
    t = m.topology
    e = int(np.flatnonzero(t.edge_face_count == 3)[0])
    assert t.edges[e].tolist() == [0, 1]
    np.testing.assert_allclose(out.vertices[m.n_vertices + e], m.vertices[[0, 1]].mean(0))
    np.testing.assert_array_equal(out.vertices[:2], m.vertices[:2])  # non-manifold vertices stay


def test_interior_nonmanifold_crease_follows_the_crease_rule():
    m = box_with_wall()
    V = m.vertices
    out = subdivide(m, 1, edge_order="sorted")
    # wall vertex 4 = (1, 0, 0): wall edges to 6 = (1, 1, 0) and 5 = (1, 0, 1)
    np.testing.assert_allclose(out.vertices[4], 0.75 * V[4] + (V[5] + V[6]) / 8)
    t = m.topology
    for e in np.flatnonzero(t.edge_face_count == 3):
        a, b = t.edges[e]
        np.testing.assert_allclose(out.vertices[m.n_vertices + e], (V[a] + V[b]) / 2)


def test_inconsistent_orientation_makes_a_sharp_edge():
    m = flipped_quad()
    V = m.vertices
    out = subdivide(m, 1, edge_order="sorted")
    t = m.topology
    e = int(np.flatnonzero(t.inconsistent_edge_mask)[0])
    a, b = t.edges[e]
    np.testing.assert_allclose(out.vertices[m.n_vertices + e], (V[a] + V[b]) / 2)
    np.testing.assert_array_equal(out.vertices[[a, b]], V[[a, b]])  # both ends are non-manifold


def test_unreferenced_vertex_is_kept():
    m = sf.Mesh([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [5, 5, 5]], [[0, 1, 2, 3]])
    out = subdivide(m, 2)
    np.testing.assert_array_equal(out.vertices[4], [5, 5, 5])
    assert out.n_vertices == 5 + 4 + 1 + 12 + 4


def test_mesh_without_faces():
    m = sf.Mesh([[0, 0, 0], [1, 2, 3]], np.zeros((0, 3), dtype=int))
    out = subdivide(m, 2)
    np.testing.assert_array_equal(out.vertices, m.vertices)
    assert out.n_faces == 0


def test_ngon_becomes_quads_around_its_centroid():
    t = np.linspace(0, 2 * np.pi, 13)[:-1]
    m = sf.Mesh(np.c_[np.cos(t), np.sin(t), np.zeros(12)], [list(range(12))])
    out = subdivide(m, 1, scheme="simple")
    assert out.face_count_by_size() == {4: 12}
    np.testing.assert_allclose(out.vertices[-1], 0, atol=1e-15)
    cc = subdivide(m, 1)
    np.testing.assert_allclose(cc.vertices[-1], 0, atol=1e-15)  # face point is the centroid


# --------------------------------------------------------------------------
# attributes, weights, matrices, levels
# --------------------------------------------------------------------------

def test_weights_linear_and_smooth():
    m = hybrid()
    rng = np.random.default_rng(3)
    w = rng.uniform(0, 1, m.n_vertices)
    w[0] = 1.0
    m = m.with_weights(w)
    lin = subdivide(m, 2)
    smo = subdivide(m, 2, weights_rule="smooth")
    S_simple, _ = subdivision_matrix(m, levels=2, scheme="simple")
    S_cc, _ = subdivision_matrix(m, levels=2)
    np.testing.assert_allclose(lin.weights, S_simple @ w, atol=1e-15)
    np.testing.assert_allclose(smo.weights, S_cc @ w, atol=1e-15)
    np.testing.assert_array_equal(lin.vertices, smo.vertices)
    np.testing.assert_array_equal(lin.weights[:m.n_vertices], w)  # linear: old vertices keep theirs
    for out in (lin, smo):
        assert out.weights.min() >= 0 and out.weights.max() <= 1
    ones = subdivide(m.with_weights(np.ones(m.n_vertices)), 3, weights_rule="smooth")
    assert ones.weights.max() <= 1.0  # round-off never leaves [0, 1]


def test_other_attributes_follow_the_scheme():
    m = hybrid()
    rng = np.random.default_rng(4)
    color = rng.uniform(size=(m.n_vertices, 3))
    frames = rng.normal(size=(m.n_vertices, 2, 2))
    m = m.with_attributes(color=color, frames=frames, weight=rng.uniform(size=m.n_vertices))
    out = subdivide(m, 2)
    S, _ = subdivision_matrix(m, levels=2)
    np.testing.assert_allclose(out.attributes["color"], S @ color, atol=1e-14)
    assert out.attributes["frames"].shape == (out.n_vertices, 2, 2)
    np.testing.assert_allclose(out.attributes["frames"].reshape(-1, 4), S @ frames.reshape(-1, 4), atol=1e-14)
    np.testing.assert_allclose(out.vertices, S @ m.vertices, atol=1e-14)
    assert set(out.attributes) == {"color", "frames", "weight"}


def test_composite_matrix_and_reuse():
    m = hybrid()
    S1, t1 = subdivision_matrix(m)
    S2, t2 = subdivision_matrix(t1)
    S, t = subdivision_matrix(m, levels=2)
    assert abs(S - S2 @ S1).max() < 1e-15
    np.testing.assert_array_equal(t.face_indices, t2.face_indices)
    out = subdivide(m, 2)
    np.testing.assert_array_equal(out.face_indices, t.face_indices)
    np.testing.assert_array_equal(out.face_offsets, t.face_offsets)
    # an animated cage: one sparse product per frame, faces shared
    moved = m.vertices * 1.5 + 0.25
    frame = out.with_vertices(S @ moved)
    np.testing.assert_allclose(frame.vertices, subdivide(m.with_vertices(moved), 2).vertices, atol=1e-14)
    assert frame.topology is out.topology


def test_levels_zero():
    m = hybrid().with_weights(np.linspace(0, 1, 12))
    out = subdivide(m, 0)
    assert out == m
    S, topo = subdivision_matrix(m, levels=0)
    assert (S != sp.identity(m.n_vertices)).nnz == 0
    assert topo is m.topology


def test_input_mesh_is_not_modified():
    m = hybrid()
    before = m.vertices.copy()
    subdivide(m, 2)
    np.testing.assert_array_equal(m.vertices, before)


@pytest.mark.parametrize("kw, bad", [
    (dict(levels=-1), "-1"),
    (dict(levels=1.5), "1.5"),
    (dict(levels=True), "True"),
    (dict(levels="2"), "'2'"),
    (dict(scheme="loop"), "'loop'"),
    (dict(scheme="Catmull-Clark"), "'Catmull-Clark'"),
    (dict(boundary="all"), "'all'"),
    (dict(weights_rule="cubic"), "'cubic'"),
    (dict(edge_order="random"), "'random'"),
    (dict(blender_threads=0), "0"),
])
def test_bad_parameters(kw, bad):
    m = cube()
    kw = dict(kw)
    levels = kw.pop("levels", 1)
    with pytest.raises(ParameterError, match=re.escape(bad)) as exc:
        subdivide(m, levels, **kw)
    assert isinstance(exc.value, ValueError)
    if "weights_rule" not in kw:
        with pytest.raises(ParameterError, match=re.escape(bad)):
            subdivision_matrix(m, levels=levels, **kw)


def test_not_a_mesh():
    with pytest.raises(ParameterError, match="Mesh"):
        subdivide(np.zeros((3, 3)))
    with pytest.raises(ParameterError, match="Mesh"):
        subdivision_matrix([[0, 1, 2]])


def test_torus_level_two_counts():
    """A 10K-vertex quad torus to level 2 (speed: benchmarks/bench_subdivision.py)."""

    N = 100
    i, j = np.meshgrid(np.arange(N), np.arange(N), indexing="ij")
    th, ph = 2 * np.pi * i / N, 2 * np.pi * j / N
    V = np.stack([(2 + np.cos(ph)) * np.cos(th), (2 + np.cos(ph)) * np.sin(th), np.sin(ph)], -1).reshape(-1, 3)
    idx = lambda a, b: (a % N) * N + (b % N)  # noqa: E731
    F = np.stack([idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1)], -1).reshape(-1, 4)
    m = sf.Mesh(V, F)
    out = subdivide(m, 2)
    assert out.n_vertices == 16 * N * N and out.n_faces == 16 * N * N
    assert out.topology.euler_characteristic == 0 and not out.topology.boundary_edge_mask.any()


# --------------------------------------------------------------------------
# CLI
# --------------------------------------------------------------------------

def test_cli_registered():
    from shapeflow.cli import build_parser

    p = build_parser()
    args = p.parse_args(["subdivide", "a.obj", "b.obj", "--levels", "2", "--scheme", "simple",
                         "--boundary", "keep-corners", "--weights-rule", "smooth"])
    assert (args.levels, args.scheme, args.boundary, args.weights_rule) == (2, "simple", "keep-corners", "smooth")
    with pytest.raises(SystemExit):
        p.parse_args(["subdivide", "a.obj", "b.obj", "--scheme", "loop"])


def test_cli_negative_levels(capsys):
    from shapeflow.cli import main

    assert main(["subdivide", "in.obj", "out.obj", "--levels", "-1"]) == 2
    err = capsys.readouterr().err
    assert "-1" in err and "Traceback" not in err


def test_cli_end_to_end(tmp_path, capsys):
    io = pytest.importorskip("shapeflow.io")
    from shapeflow.cli import main

    m = hybrid()
    src = tmp_path / "in.obj"
    io.save(src, m)
    w = np.linspace(0, 1, m.n_vertices)
    np.savetxt(tmp_path / "w.txt", w)
    dst = tmp_path / "out.obj"
    rc = main(["subdivide", str(src), str(dst), "--levels", "2", "--weights", str(tmp_path / "w.txt"),
               "--weights-out", str(tmp_path / "w_out.npy")])
    assert rc == 0
    err = capsys.readouterr().err
    assert "12 vertices" in err and "->" in err
    out = io.load(dst)
    ref = subdivide(m.with_weights(w), 2)
    assert out.n_vertices == ref.n_vertices and out.n_faces == ref.n_faces
    np.testing.assert_allclose(out.vertices, ref.vertices, atol=1e-5)
    np.testing.assert_allclose(np.load(tmp_path / "w_out.npy"), ref.weights, atol=1e-12)
    # a weights file of the wrong length is a clean error, as for every command that reads weights
    np.savetxt(tmp_path / "short.txt", w[:3])
    assert main(["subdivide", str(src), str(dst), "--weights", str(tmp_path / "short.txt")]) == 2
    assert "short.txt: has 3 weights but the mesh has 12 vertices" in capsys.readouterr().err


# --------------------------------------------------------------------------
# live Blender (only when bpy and the harness are available)
# --------------------------------------------------------------------------

def _blender_harness():
    import sys

    path = ROOT / "benchmarks" / "blender_ref.py"
    if not path.exists() or importlib.util.find_spec("bpy") is None:
        return None
    mod = sys.modules.get("blender_ref")  # shared with test_blender_ref.py: one Blender session
    if mod is None:
        spec = importlib.util.spec_from_file_location("blender_ref", path)
        mod = importlib.util.module_from_spec(spec)
        try:
            spec.loader.exec_module(mod)
        except Exception:
            return None
        mod = sys.modules.setdefault("blender_ref", mod)
    if not hasattr(mod, "subdivision_surface") or not mod.available():
        return None
    return mod


@pytest.mark.parametrize("make", [bowtie, two_tets, fin, box_with_wall, flipped_quad, squares_at_corner, hybrid])
@pytest.mark.parametrize("boundary", ["smooth", "keep-corners"])
def test_matches_live_blender(make, boundary):
    br = _blender_harness()
    if br is None:
        pytest.skip("Blender (bpy) or benchmarks/blender_ref.py not available")
    m = make()
    for levels in (1, 2):
        P, fs, fi, _, _ = br.subdivision_surface(
            m.vertices, m.face_sizes, m.face_indices, levels=levels,
            boundary_smooth={"smooth": "ALL", "keep-corners": "PRESERVE_CORNERS"}[boundary])
        out = subdivide(m, levels, boundary=boundary)
        diag = diag_of(P)
        assert out.n_vertices == len(P) and out.n_faces == len(fs)
        if levels == 1:
            assert np.abs(out.vertices - P).max() / diag < TOL
            assert np.array_equal(out.face_indices, fi)
        else:
            d1, _ = cKDTree(P).query(out.vertices)
            d2, _ = cKDTree(out.vertices).query(P)
            assert max(d1.max(), d2.max()) / diag < TOL
