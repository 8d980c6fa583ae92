"""The sculpt brush of section 4.3 (issue 8): shapeflow.Brush, InflateBrush, ``shapeflow brush``."""

from __future__ import annotations

import json
import sys
import tracemalloc

import numpy as np
import pytest
from conftest import MESHES, requires_shared
from meshgen import cube_sphere, grid, icosphere, ngon_disk, random_rotation

import shapeflow as sf
from shapeflow.cli import main
from shapeflow.geometry import vertex_normals
from shapeflow.operators.weights import assemble as _assemble


def _pair_weights(mesh, scheme="tqlbo"):
    """flow's pair weights summed per vertex pair, pairs sorted (as Brush.pair_weights)."""
    st, pw, _, _, locked, _ = _assemble(mesh, scheme, "relative")
    keys = st.pairs[:, 0] * mesh.n_vertices + st.pairs[:, 1]
    _, inv = np.unique(keys, return_inverse=True)
    return np.bincount(inv, pw), locked


def _brush_pw(b):
    return b.pair_weights()[1]


def _tol(mesh) -> float:
    return 1e-10 * max(1.0, mesh.diagonal)


def _independent_region(mesh, V, c, r):
    """inside / rim straight from the definition (faces with a vertex outside)."""
    inside = np.einsum("ij,ij->i", V - c, V - c) <= r * r
    rim = np.zeros(mesh.n_vertices, bool)
    for f in mesh.faces_as_lists():
        f = np.asarray(f)
        if not inside[f].all():
            rim[f[inside[f]]] = True
    return inside, rim


def _bumpy_grid(n=24, mix=0.3):
    return grid(n, n, jitter=0.2, mix=mix, seed=3,
                z=lambda x, y: 0.3 * np.sin(0.5 * x) * np.cos(0.4 * y))


# --- the whole mesh: a dab with an empty rim is flow() --------------------------------------

CLOSED = {
    "cube_sphere_mixed": lambda: cube_sphere(7, mix=0.3, seed=1),
    "icosphere": lambda: icosphere(2),
}


@pytest.mark.parametrize("name", sorted(CLOSED))
@pytest.mark.parametrize("lam", [-20.0, 7.0])
@pytest.mark.parametrize("solver", ["auto", "banded", "lu"])
def test_whole_mesh_dab_equals_flow(name, lam, solver):
    mesh = CLOSED[name]()
    brush = sf.Brush(mesh, lam=lam, radius=10 * mesh.diagonal, solver=solver)
    reg = brush.region(mesh.vertices.mean(axis=0))
    assert reg["rim"].size == 0 and reg["free"].size == mesh.n_vertices
    moved = brush.dab(mesh.vertices.mean(axis=0))
    assert moved.size == mesh.n_vertices
    ref = sf.flow(mesh, lam, solver="lu")
    assert np.abs(brush.mesh.vertices - ref.vertices).max() <= _tol(mesh)


@requires_shared
@pytest.mark.parametrize("fname", ["spot_quad.obj", "spot_control_hybrid.obj", "blub_control_hybrid.obj",
                                   "bob_quad.obj"])
def test_whole_mesh_dab_equals_flow_shared(fname):
    mesh = sf.load(MESHES / fname)
    for lam, normalized in ((-50.0, True), (10.0, False)):
        brush = sf.Brush(mesh, lam=lam, radius=10 * mesh.diagonal, normalized=normalized)
        brush.dab(mesh.vertices[0])
        ref = sf.flow(mesh, lam, normalized=normalized, solver="lu")
        assert np.abs(brush.mesh.vertices - ref.vertices).max() <= _tol(mesh), (fname, lam)


def test_whole_mesh_dab_equals_flow_with_weights():
    mesh = cube_sphere(6, mix=0.4, seed=2)
    rng = np.random.default_rng(0)
    w = rng.uniform(0.0, 1.0, mesh.n_vertices)
    w[::5] = 0.0
    brush = sf.Brush(mesh, lam=-30.0, radius=10.0, weights=w)
    moved = brush.dab([0, 0, 0])
    assert set(moved.tolist()) == set(np.flatnonzero(w > 0).tolist())
    ref = sf.flow(mesh, -30.0, weights=w, solver="lu")
    assert np.abs(brush.mesh.vertices - ref.vertices).max() <= _tol(mesh)
    # weights by attribute name
    m2 = mesh.with_weights(w)
    b2 = sf.Brush(m2, lam=-30.0, radius=10.0, weights="weight")
    b2.dab([0, 0, 0])
    assert np.array_equal(b2.mesh.vertices, brush.mesh.vertices)


def test_whole_mesh_dab_with_falloff_equals_flow_with_falloff_weights():
    mesh = icosphere(2)
    c = np.array([0.2, -0.1, 0.3])
    r = 3.0
    brush = sf.Brush(mesh, lam=-15.0, radius=r, falloff="smooth")
    brush.dab(c)
    t = np.linalg.norm(mesh.vertices - c, axis=1) / r
    ref = sf.flow(mesh, -15.0, weights=(1 - t * t) ** 2, solver="lu")
    assert np.abs(brush.mesh.vertices - ref.vertices).max() <= _tol(mesh)
    # a callable falloff
    b2 = sf.Brush(mesh, lam=-15.0, radius=r, falloff=lambda s: (1 - s * s) ** 2)
    b2.dab(c)
    assert np.abs(b2.mesh.vertices - brush.mesh.vertices).max() <= 1e-14


def test_whole_mesh_dab_ngons_and_blender_scheme():
    mesh = ngon_disk(7, rings=3)
    mesh = mesh.with_vertices(mesh.vertices + np.c_[np.zeros((mesh.n_vertices, 2)),
                                                    0.1 * np.sin(mesh.vertices[:, 0])])
    for scheme in ("tqlbo", "blender"):
        brush = sf.Brush(mesh, lam=-8.0, radius=100.0, scheme=scheme, lam_border=2.0)
        brush.dab([0, 0, 0])
        ref = sf.flow(mesh, -8.0, scheme=scheme, lam_border=2.0, solver="lu")
        assert np.abs(brush.mesh.vertices - ref.vertices).max() <= _tol(mesh), scheme


@pytest.mark.parametrize("lam_border", [0.0, 3.0, -2.0])
def test_whole_open_mesh_dab_equals_flow_with_lam_border(lam_border):
    mesh = _bumpy_grid(14)
    brush = sf.Brush(mesh, lam=-12.0, radius=100.0, lam_border=lam_border)
    moved = brush.dab([5, 5, 0])
    ref = sf.flow(mesh, -12.0, lam_border=lam_border, solver="lu")
    assert np.abs(brush.mesh.vertices - ref.vertices).max() <= _tol(mesh)
    boundary = mesh.topology.boundary_vertex_mask
    if lam_border == 0.0:
        assert not boundary[moved].any()
        assert np.array_equal(brush.mesh.vertices[boundary], mesh.vertices[boundary])
    else:
        assert boundary[moved].any()


@requires_shared
@pytest.mark.parametrize("fname", ["plane_holes_tri_open.obj", "pawn_cage_quad_open.obj", "rook_cage_hybrid_open.obj"])
def test_whole_open_shared_mesh_dab_equals_flow(fname):
    mesh = sf.load(MESHES / fname)
    brush = sf.Brush(mesh, lam=-20.0, radius=10 * mesh.diagonal, lam_border=4.0)
    brush.dab(mesh.vertices[0])
    ref = sf.flow(mesh, -20.0, lam_border=4.0, solver="lu")
    assert np.abs(brush.mesh.vertices - ref.vertices).max() <= _tol(mesh)


def test_locked_vertices_match_flow():
    """A zero-length edge and a flat triangle: the same vertices stay as in flow()."""
    mesh = _bumpy_grid(10, mix=0.0)
    V = mesh.vertices.copy()
    V[45] = V[46]                      # zero-length edge 45-46
    V[12] = 0.5 * (V[11] + V[13])      # collinear: flat corner triangles
    mesh = mesh.with_vertices(V)
    brush = sf.Brush(mesh, lam=-10.0, radius=100.0)
    brush.dab([4, 4, 0])
    ref = sf.flow(mesh, -10.0, solver="lu")
    assert ref.report.locked > 0
    assert np.abs(brush.mesh.vertices - ref.vertices).max() <= _tol(mesh)
    locked = ref.report.locked_vertices
    assert np.array_equal(brush.mesh.vertices[locked], V[locked])


# --- local dabs: the rim and the outside never move ------------------------------------------

def _check_dabs_keep_outside(brush, centers):
    mesh = brush.original
    for c in centers:
        V0 = brush.vertices.copy()
        reg = brush.region(c)
        inside, rim = _independent_region(mesh, V0, c, brush.radius)
        assert np.array_equal(np.sort(reg["inside"]), np.flatnonzero(inside))
        assert np.array_equal(reg["rim"], np.flatnonzero(rim))
        moved = brush.dab(c)
        V1 = brush.vertices
        assert np.array_equal(np.sort(moved), reg["free"])
        fixed = np.ones(mesh.n_vertices, bool)
        fixed[moved] = False
        assert not (inside & ~rim & fixed)[reg["free"]].any()
        assert np.array_equal(V1[fixed], V0[fixed])          # bit-identical
        assert not rim[moved].any() and inside[moved].all()
        assert np.abs(V1[moved] - V0[moved]).max() > 0


@pytest.mark.parametrize("falloff", [None, "smooth"])
def test_outside_and_rim_never_move(falloff):
    mesh = cube_sphere(12, mix=0.3, seed=4)
    brush = sf.Brush(mesh, lam=-40.0, radius=0.5, falloff=falloff)
    rng = np.random.default_rng(1)
    centers = mesh.vertices[rng.choice(mesh.n_vertices, 6, replace=False)]
    _check_dabs_keep_outside(brush, centers)


def test_outside_and_rim_never_move_open_mesh_with_lam_border():
    mesh = _bumpy_grid(24)
    brush = sf.Brush(mesh, lam=-25.0, radius=4.0, lam_border=5.0)
    centers = [[0.0, 5.0, 0.0], [23.0, 23.0, 0.0], [10.0, 0.5, 0.0], [12.0, 12.0, 0.0]]
    _check_dabs_keep_outside(brush, centers)
    # boundary vertices did move (those near a centre on the border)
    boundary = mesh.topology.boundary_vertex_mask
    assert np.any(brush.vertices[boundary] != mesh.vertices[boundary])


@requires_shared
def test_stroke_on_shared_mesh_keeps_outside():
    mesh = sf.load(MESHES / "bob_quad.obj")
    r = 0.03 * mesh.diagonal
    brush = sf.Brush(mesh, lam=-60.0, radius=r, falloff="smooth")
    a = mesh.vertices[100]
    b = mesh.vertices[np.argmin(np.abs(np.linalg.norm(mesh.vertices - a, axis=1) - 4 * r))]
    moved = brush.stroke([a, b], spacing=0.3)
    near = np.zeros(mesh.n_vertices, bool)
    for c in brush.dab_centers([a, b], 0.3):
        near |= np.linalg.norm(brush.vertices - c, axis=1) <= r
    changed = np.any(brush.vertices != mesh.vertices, axis=1)
    assert changed.any()
    assert np.array_equal(np.flatnonzero(changed), np.intersect1d(np.flatnonzero(changed), moved))
    # nothing far from every dab moved
    far = np.linalg.norm(mesh.vertices[:, None, :] - brush.dab_centers([a, b], 0.3)[None], axis=2).min(axis=1) > 3 * r
    assert not changed[far].any()


# --- pose insensitivity (figure 12) ------------------------------------------------------------

def test_pose_insensitivity():
    mesh = cube_sphere(10, mix=0.3, seed=5)
    Q = random_rotation(7)
    t = np.array([3.0, -1.0, 2.5])
    moved_mesh = mesh.with_vertices(mesh.vertices @ Q.T + t)
    pts = np.array([[1.0, 0.1, 0.0], [0.5, 0.8, 0.3], [-0.2, 0.9, 0.4]])
    kw = dict(lam=-40.0, radius=0.6, falloff="smooth")
    b1 = sf.Brush(mesh, **kw)
    b2 = sf.Brush(moved_mesh, **kw)
    m1 = b1.stroke(pts, spacing=0.25)
    m2 = b2.stroke(pts @ Q.T + t, spacing=0.25)
    assert np.array_equal(np.sort(m1), np.sort(m2))
    back = (b2.vertices - t) @ Q
    err = np.abs(back - b1.vertices).max()
    assert err <= 1e-9 * mesh.diagonal
    assert np.abs(b1.vertices - mesh.vertices).max() > 1e-3   # the stroke did something


# --- preview, commit, discard, undo --------------------------------------------------------

def test_preview_discard_and_commit():
    mesh = icosphere(3)
    c = mesh.vertices[5]
    b1 = sf.Brush(mesh, lam=-30.0, radius=0.5)
    V0 = b1.vertices.copy()
    pw0 = b1._pw.copy()
    dab = b1.preview(c)
    assert b1.pending is dab and dab.indices.size > 0
    assert np.array_equal(b1.vertices, V0)                   # nothing applied yet
    pm = b1.preview_mesh
    assert np.array_equal(pm.vertices[dab.indices], dab.positions)
    b1.preview(c + 0.05)                                     # dragging the dot
    b1.discard()
    assert b1.pending is None
    assert np.array_equal(b1.vertices, V0) and np.array_equal(b1.mesh.vertices, mesh.vertices)
    assert np.array_equal(b1._pw, pw0)
    assert b1.commit().size == 0                             # nothing pending
    b1.preview(c)
    moved = b1.commit()
    b2 = sf.Brush(mesh, lam=-30.0, radius=0.5)
    moved2 = b2.dab(c)
    assert np.array_equal(moved, moved2)
    assert np.array_equal(b1.vertices, b2.vertices)


def test_undo_redo_exact():
    mesh = cube_sphere(8, mix=0.2)
    b = sf.Brush(mesh, lam=-50.0, radius=0.6)
    V0 = b.vertices.copy()
    b.dab(mesh.vertices[3])
    V1 = b.vertices.copy()
    b.stroke([mesh.vertices[10], mesh.vertices[40]], spacing=0.5)
    V2 = b.vertices.copy()
    assert b.can_undo
    b.undo()
    assert np.array_equal(b.vertices, V1)                    # the whole stroke, in one step
    b.undo()
    assert np.array_equal(b.vertices, V0)
    assert b.undo().size == 0
    b.redo()
    b.redo()
    assert np.array_equal(b.vertices, V2)
    # caches follow: a dab after undo equals a dab on a fresh brush
    b.undo()
    b.undo()
    b.refresh()
    fresh = sf.Brush(mesh, lam=-50.0, radius=0.6)
    assert np.array_equal(b._pw, fresh._pw)
    b.dab(mesh.vertices[7])
    fresh.dab(mesh.vertices[7])
    assert np.abs(b.vertices - fresh.vertices).max() <= 1e-14


@pytest.mark.parametrize("scheme", ["tqlbo", "blender"])
def test_initial_pair_weights_match_operator(scheme):
    for mesh in (ngon_disk(7), cube_sphere(5, mix=0.5), _bumpy_grid(8)):
        b = sf.Brush(mesh, radius=1.0, scheme=scheme)
        pw, locked = _pair_weights(mesh, scheme)
        assert np.abs(_brush_pw(b) - pw).max() <= 1e-14 * np.abs(pw).max()
        assert np.array_equal(b.locked, locked)


@pytest.mark.parametrize("compiled", [False, True])
def test_caches_follow_the_sculpted_mesh(compiled):
    if compiled and not sf.accel.available():
        pytest.skip("numba (the 'fast' extra) not installed")
    mesh = cube_sphere(9, mix=0.3, seed=8)
    with sf.accel.enabled(compiled):
        b = sf.Brush(mesh, lam=-60.0, radius=0.7)
        rng = np.random.default_rng(3)
        b.stroke(mesh.vertices[rng.choice(mesh.n_vertices, 5)], spacing=0.3)
    pw, locked = _pair_weights(b.mesh)
    assert np.abs(_brush_pw(b) - pw).max() <= 1e-12 * np.abs(pw).max()
    assert np.array_equal(b.locked, locked)


@pytest.mark.skipif(not sf.accel.available(), reason="numba (the 'fast' extra) not installed")
def test_compiled_cache_update_matches_numpy():
    """Dabs next to a zero-length edge, an undo: locks, lock counts and weights agree on both paths."""
    mesh = _bumpy_grid(12)
    V = mesh.vertices.copy()
    V[40] = V[41]                      # a zero-length edge: its ends and triangles are locked
    mesh = mesh.with_vertices(V)
    runs = []
    for compiled in (False, True):
        with sf.accel.enabled(compiled):
            b = sf.Brush(mesh, lam=-40.0, radius=2.5)
            b.dab(V[40])
            b.dab(V[60])
            b.undo()                   # restores positions: triangles flip back
            b.dab(V[45] + 0.3)
            runs.append((b.vertices.copy(), _brush_pw(b), b.locked.copy(), b._tri_degenerate.copy(),
                         b._lock_count.copy()))
    (v0, pw0, l0, tb0, vl0), (v1, pw1, l1, tb1, vl1) = runs
    assert l0.any() and np.array_equal(l0, l1) and np.array_equal(tb0, tb1) and np.array_equal(vl0, vl1)
    assert np.abs(pw0 - pw1).max() <= 1e-13 * np.abs(pw0).max()
    assert np.abs(v0 - v1).max() <= 1e-12 * np.ptp(V)


@pytest.mark.skipif(not sf.accel.available(), reason="numba (the 'fast' extra) not installed")
@pytest.mark.parametrize("falloff", [None, "smooth"])
def test_compiled_region_matches_numpy(falloff):
    """Rim, degrees and the assembled system (boundary neighbours solved first, weights,
    falloff) of the compiled region path give the NumPy path's dabs bit for bit."""
    mesh = _bumpy_grid(20)
    w = np.random.default_rng(5).uniform(0.2, 1.0, mesh.n_vertices)
    centers = [[0.0, 5.0, 0.0], [10.0, 0.5, 0.0], [9.0, 9.0, 0.1]]
    runs = []
    for compiled in (False, True):
        with sf.accel.enabled(compiled):
            b = sf.Brush(mesh, lam=-30.0, radius=4.0, lam_border=-5.0, weights=w, falloff=falloff)
            dabs = [b.preview(c) for c in centers[:1]] + [None]
            b.commit()
            for c in centers[1:]:
                b.dab(c)
                dabs.append(b.last)
            runs.append((b.vertices.copy(), [(d.indices, d.positions, d.rim) for d in dabs if d is not None]))
    (v0, d0), (v1, d1) = runs
    assert np.array_equal(v0, v1)
    assert v0[mesh.topology.boundary_vertex_mask].tolist() != mesh.vertices[mesh.topology.boundary_vertex_mask].tolist()
    for (i0, p0, r0), (i1, p1, r1) in zip(d0, d1):
        assert np.array_equal(i0, i1) and np.array_equal(p0, p1) and np.array_equal(np.sort(r0), np.sort(r1))


@pytest.mark.skipif(not sf.accel.available(), reason="numba (the 'fast' extra) not installed")
def test_kernels_switched_off_on_a_live_brush():
    """A brush made with the compiled kernels keeps working (same dabs) when they are switched
    off and on again: the spatial index follows."""
    mesh = cube_sphere(8, mix=0.3, seed=4)
    c = mesh.vertices[[3, 40, 77]]
    ref = sf.Brush(mesh, lam=-20.0, radius=0.5)
    with sf.accel.enabled(False):
        for x in c:
            ref.dab(x)
    b = sf.Brush(mesh, lam=-20.0, radius=0.5)
    b.dab(c[0])
    with sf.accel.enabled(False):
        b.dab(c[1])
    b.dab(c[2])
    # the index follows the switch: built at construction (grid), rebuilt when the kernels go off
    # (SciPy's k-d tree) and again when they come back (grid): three builds, no more
    assert b.tree_rebuilds == 3
    assert np.abs(b.vertices - ref.vertices).max() <= 1e-12 * mesh.diagonal


@pytest.mark.skipif(not sf.accel.available(), reason="numba (the 'fast' extra) not installed")
def test_compiled_local_order_matches_scipy():
    """The compiled breadth-first searches of the local band ordering give scipy's order."""
    mesh = cube_sphere(6, mix=0.4, seed=2)
    e = mesh.topology.edges
    rng = np.random.default_rng(0)
    k = mesh.n_vertices
    shuffle = rng.permutation(k)
    a, c = shuffle[np.concatenate([e[:, 0], e[:, 1]])], shuffle[np.concatenate([e[:, 1], e[:, 0]])]
    o = np.lexsort((rng.random(a.size), a))          # grouped by row, neighbours in a random order
    ri, ci = a[o], c[o]
    from shapeflow.linalg.ordering import local_order

    perms = []
    for compiled in (False, True):
        with sf.accel.enabled(compiled):
            perms.append(local_order(k, ri, ci, grouped=True))
    assert np.array_equal(perms[0][0], perms[1][0]) and np.array_equal(perms[0][1], perms[1][1])
    assert np.array_equal(np.sort(perms[1][0]), np.arange(k))
    # the narrower of the two sweeps' Cuthill-McKee orders (u = last reached from 0, w = last from u)
    import scipy.sparse as sp
    from scipy.sparse.csgraph import breadth_first_order

    ptr = np.concatenate([[0], np.cumsum(np.bincount(ri, minlength=k))])
    G = sp.csr_matrix((np.ones(ri.size), ci, ptr), shape=(k, k))      # neighbours in stored order

    def band(p):
        inv = np.empty(k, np.int64)
        inv[p] = np.arange(k)
        return int(np.abs(inv[ri] - inv[ci]).max())

    u = breadth_first_order(G, 0, return_predecessors=False)[-1]
    p_u = breadth_first_order(G, u, return_predecessors=False)
    p_w = breadth_first_order(G, p_u[-1], return_predecessors=False)
    assert band(perms[1][0]) == min(band(p_u), band(p_w))
    assert np.array_equal(perms[1][1][perms[1][0]], np.arange(k))


# --- strokes ----------------------------------------------------------------------------------

def test_stroke_spacing():
    mesh = icosphere(3)
    b = sf.Brush(mesh, lam=-10.0, radius=0.4)
    pts = np.array([[1.0, 0, 0], [0, 1.0, 0], [0, 1.0, 1.0]])
    centers = b.dab_centers(pts, spacing=0.25)
    step = 0.25 * 0.4
    length = np.sqrt(2) + 1.0
    assert len(centers) == int(np.floor(length / step)) + 1
    assert np.allclose(centers[0], pts[0])
    # consecutive centres are `step` apart along the polyline (chords at the corner are shorter)
    d = np.linalg.norm(np.diff(centers, axis=0), axis=1)
    assert np.all(d <= step + 1e-12) and np.median(d) == pytest.approx(step)
    # every centre lies on the polyline
    on_first = np.abs(centers[:, 2]) < 1e-12
    assert np.allclose(centers[on_first, 0] + centers[on_first, 1], 1.0)
    assert np.allclose(centers[~on_first, :2], [0, 1])
    # the stroke is those dabs
    moved = b.stroke(pts, spacing=0.25)
    b2 = sf.Brush(mesh, lam=-10.0, radius=0.4)
    moved2 = [b2.dab(c) for c in centers]
    assert np.array_equal(b.vertices, b2.vertices)
    assert np.array_equal(moved, np.unique(np.concatenate(moved2)))
    # spacing=None: one dab per given point; a single point is one dab
    assert len(b.dab_centers(pts, spacing=None)) == 3
    assert len(b.dab_centers([[0.0, 0.0, 1.0]])) == 1
    assert len(b.dab_centers(pts, spacing=10.0)) == 1


def test_settable_radius_and_lambda_and_zero_lambda():
    mesh = icosphere(3)
    b = sf.Brush(mesh, lam=0.0, radius=0.3)
    assert b.dab(mesh.vertices[0]).size == 0
    assert np.array_equal(b.vertices, mesh.vertices)
    b.lam = -20.0
    small = b.dab(mesh.vertices[0]).size
    b.undo()
    b.radius = 0.6
    big = b.dab(mesh.vertices[0]).size
    assert big > small > 0
    assert b.dab([10.0, 10.0, 10.0]).size == 0              # nowhere near the mesh


def test_spatial_index_stays_exact_as_vertices_move():
    mesh = cube_sphere(10)
    b = sf.Brush(mesh, lam=-200.0, radius=0.5, rebuild_fraction=0.01)
    rng = np.random.default_rng(5)
    for c in mesh.vertices[rng.choice(mesh.n_vertices, 8)]:
        b.dab(c)
        for q in rng.normal(size=(3, 3)) * 0.7:
            brute = np.flatnonzero(np.linalg.norm(b.vertices - q, axis=1) <= b.radius)
            assert np.array_equal(b.inside(q), brute)
    assert b._far_count > 0 or b.tree_rebuilds > 1


@pytest.mark.skipif(not sf.accel.available(), reason="numba (the 'fast' extra) not installed")
def test_cell_grid_query_is_exact():
    """The compiled grid finds exactly the points within r (moved points too), whatever the
    radius relative to the cell size, with centres inside and far outside the grid."""
    from shapeflow.sculpt.grid import CellGrid as _CellGrid

    rng = np.random.default_rng(9)
    P = rng.normal(size=(3000, 3)) * [1.0, 2.0, 0.3]
    for h in (1e-9, 0.05, 0.4, 50.0):
        g = _CellGrid(P, h)
        tau = 0.01
        V = P + rng.uniform(-1, 1, P.shape) * tau / np.sqrt(3)   # moved less than tau
        far = np.zeros(len(P), bool)
        far[::7] = True                                         # skipped: the caller checks them
        for c, r in [(P[5], 0.3), (P[11], 1e-12), (np.array([0.0, 0.0, 0.0]), 2.5),
                     (np.array([40.0, -3.0, 9.0]), 0.5), (np.array([40.0, 0.0, 0.0]), 45.0)]:
            S, d = g.query(V, far, c, r + tau, r)
            dist = np.linalg.norm(V - c, axis=1)
            brute = np.flatnonzero((dist <= r) & ~far)
            assert np.array_equal(np.sort(S), brute)
            assert np.allclose(d, dist[S], rtol=1e-15, atol=0)


def test_no_full_mesh_allocation_per_dab():
    """Peak memory of a dab does not grow with the mesh (no O(n) arrays per dab)."""
    peaks = []
    for n in (60, 240):
        mesh = _big_grid(n)
        b = sf.Brush(mesh, lam=-20.0, radius=4.0)
        c = mesh.vertices[(n // 2) * n + n // 2]
        b.dab(c)                                     # warm up (tree, imports)
        b.undo()
        tracemalloc.start()
        b.dab(c + [0.3, 0.2, 0])
        peaks.append(tracemalloc.get_traced_memory()[1])
        tracemalloc.stop()
    n_big = 240 * 240
    assert peaks[1] < 8 * n_big                      # less than one float per vertex
    assert peaks[1] < 1.5 * peaks[0] + 50_000


def _big_grid(n):
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    V = np.c_[i.ravel(), j.ravel(), 0.1 * np.sin(i.ravel() * 0.3) * np.cos(j.ravel() * 0.2)].astype(float)
    a = (i[:-1, :-1] * n + j[:-1, :-1]).ravel()
    F = np.stack([a, a + n, a + n + 1, a + 1], axis=1)
    return sf.Mesh(V, F)


# --- inflate ----------------------------------------------------------------------------------

@pytest.mark.parametrize("falloff", [None, "smooth"])
def test_inflate_moves_along_normals_inside_only(falloff):
    mesh = cube_sphere(10, mix=0.3)
    c = mesh.vertices[17]
    r = 0.5
    b = sf.InflateBrush(mesh, strength=0.1, radius=r, falloff=falloff)
    moved = b.dab(c)
    d = np.linalg.norm(mesh.vertices - c, axis=1)
    inside = d <= r
    assert set(moved.tolist()) <= set(np.flatnonzero(inside).tolist())
    disp = b.vertices - mesh.vertices
    assert not disp[~inside].any()
    N = vertex_normals(mesh)
    f = np.ones_like(d) if falloff is None else (1 - (d / r) ** 2) ** 2
    expect = (0.1 * r * f)[:, None] * N
    assert np.abs(disp[inside] - expect[inside]).max() <= 1e-14
    assert np.all(np.einsum("ij,ij->i", disp[moved], N[moved]) > 0)   # outward
    b.undo()
    assert np.array_equal(b.vertices, mesh.vertices)


def test_inflate_stroke_and_preview():
    mesh = icosphere(3)
    b = sf.InflateBrush(mesh, strength=-0.05, radius=0.4)
    b.preview(mesh.vertices[0])
    b.discard()
    assert np.array_equal(b.vertices, mesh.vertices)
    moved = b.stroke([mesh.vertices[0], mesh.vertices[1]], spacing=0.5)
    assert moved.size > 0
    assert np.linalg.norm(b.vertices[moved], axis=1).max() < 1.0 + 1e-12    # deflated


# --- parameters -------------------------------------------------------------------------------

@pytest.mark.parametrize("kw, match", [
    (dict(radius=0.0), "radius"),
    (dict(radius=float("nan")), "radius"),
    (dict(radius=1.0, lam=float("inf")), "lam"),
    (dict(radius=1.0, falloff="gauss"), "falloff"),
    (dict(radius=1.0, solver="cg"), "solver"),
    (dict(radius=1.0, scheme="xyz"), "scheme"),
    (dict(radius=1.0, weights=np.full(3, 0.5)), "weights"),
])
def test_bad_parameters(kw, match):
    with pytest.raises(sf.ParameterError, match=match):
        sf.Brush(icosphere(1), **kw)


def test_bad_centres_and_points():
    b = sf.Brush(icosphere(1), radius=0.5)
    with pytest.raises(sf.ParameterError):
        b.dab([0, 0])
    with pytest.raises(sf.ParameterError):
        b.dab([0, np.nan, 0])
    with pytest.raises(sf.ParameterError):
        b.stroke([[0, 0, 0], [1, 1]])
    with pytest.raises(sf.ParameterError):
        b.stroke([[0, 0, 0]], spacing=0)
    with pytest.raises(sf.ParameterError):
        sf.Brush(icosphere(1), radius=0.5, falloff=lambda t: 2.0 + 0 * t).dab([1, 0, 0])


# --- command line -------------------------------------------------------------------------------

def test_cli_brush_happy_path(tmp_path, capsys):
    mesh = icosphere(3)
    src = tmp_path / "in.obj"
    sf.save(src, mesh)
    stroke = {"lambda": -30, "radius": 0.5, "points": mesh.vertices[[0, 7]].tolist(), "falloff": "smooth",
              "spacing": 0.3}
    (tmp_path / "s.json").write_text(json.dumps(stroke))
    out = tmp_path / "out.ply"
    rc = main(["brush", str(src), str(out), "--stroke", str(tmp_path / "s.json")])
    err = capsys.readouterr().err
    assert rc == 0, err
    assert "dabs" in err
    got = sf.load(out)
    b = sf.Brush(sf.load(src), lam=-30, radius=0.5, falloff="smooth")
    b.stroke(mesh.vertices[[0, 7]], spacing=0.3)
    assert np.abs(got.vertices - b.vertices).max() <= 1e-12
    # the inflate brush
    stroke = {"brush": "inflate", "strength": 0.1, "radius": 0.5, "points": [mesh.vertices[0].tolist()]}
    (tmp_path / "i.json").write_text(json.dumps(stroke))
    rc = main(["brush", str(src), str(tmp_path / "i.obj"), "--stroke", str(tmp_path / "i.json"), "-q"])
    assert rc == 0 and capsys.readouterr().err == ""


@pytest.mark.parametrize("text, match", [
    ('{"lambda": -30, "radius": 0.5, "points": [[0, 0, 0]]', "not valid JSON"),
    ('[1, 2, 3]', "JSON object"),
    ('{"radius": 0.5, "points": [[0, 0, 0]]}', "missing \"lambda\""),
    ('{"lambda": -3, "radius": 0, "points": [[0, 0, 0]]}', "radius"),
    ('{"lambda": -3, "radius": 1, "points": [[0, 0]]}', "point 0"),
    ('{"lambda": -3, "radius": 1, "points": []}', "points"),
    ('{"lambda": "x", "radius": 1, "points": [[0, 0, 0]]}', "lambda"),
    ('{"lambda": -3, "radius": 1, "points": [[0, 0, 0]], "colour": 1}', "unknown key"),
    ('{"lambda": -3, "radius": 1, "points": [[0, 0, 0]], "falloff": "gauss"}', "falloff"),
    ('{"lambda": -3, "radius": 1, "points": [[0, 0, 0]], "brush": "pinch"}', "brush"),
])
def test_cli_brush_bad_json_exits_2(tmp_path, capsys, text, match):
    (tmp_path / "s.json").write_text(text)
    out = tmp_path / "out.obj"
    rc = main(["brush", "example:spot", str(out), "--stroke", str(tmp_path / "s.json")])
    err = capsys.readouterr().err
    assert rc == 2
    assert match in err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert not out.exists()


def test_cli_brush_missing_stroke_file(tmp_path, capsys):
    rc = main(["brush", "example:spot", str(tmp_path / "o.obj"), "--stroke", str(tmp_path / "nope.json")])
    assert rc == 2
    assert "nope.json" in capsys.readouterr().err


def test_unreferenced_vertices_and_meshes_without_faces():
    m = icosphere(2)
    mesh = sf.Mesh(np.vstack([m.vertices, [[0.1, 0.2, 0.3]]]), m.faces_as_lists())   # a lone vertex inside
    b = sf.Brush(mesh, lam=-10.0, radius=100.0)
    moved = b.dab([0, 0, 0])
    assert mesh.n_vertices - 1 not in moved
    ref = sf.flow(mesh, -10.0, solver="lu")
    assert np.abs(b.vertices - ref.vertices).max() <= _tol(mesh)
    bare = sf.Mesh(np.random.default_rng(0).random((5, 3)), [])
    for brush in (sf.Brush(bare, radius=1.0), sf.InflateBrush(bare, radius=1.0)):
        assert brush.dab([0.5, 0.5, 0.5]).size == 0
        assert np.array_equal(brush.mesh.vertices, bare.vertices)


@pytest.mark.parametrize("band", [30, 56, 60, 64, 65, 80])
def test_banded_solve_with_and_without_padding(band, monkeypatch):
    """Bands 56-64 go to LAPACK padded to 65 (its blocked code); the solution is the same system's."""
    from shapeflow.linalg import banded as B
    from shapeflow.linalg.local import LocalSolver

    rng = np.random.default_rng(band)
    k = 400
    # a random SPD band matrix: symmetric off-diagonals within `band`, dominant diagonal
    ri, ci = [], []
    for i in range(k):
        for j in rng.choice(np.arange(i + 1, min(k, i + band + 1)), size=min(4, k - i - 1), replace=False) \
                if i < k - 1 else []:
            ri.append(i)
            ci.append(int(j))
    ri.append(0)
    ci.append(band)                                   # the band is exactly `band`
    ri, ci = np.array(ri), np.array(ci)
    v = -rng.uniform(0.1, 1.0, ri.size)
    R, C, Vv = np.concatenate([ri, ci]), np.concatenate([ci, ri]), np.concatenate([v, v])
    o = np.lexsort((C, R))
    R, C, Vv = R[o], C[o], Vv[o]
    diag = np.bincount(R, np.abs(Vv), minlength=k) + 1.0
    rhs = rng.standard_normal((k, 3))
    A = np.zeros((k, k))
    A[R, C] = Vv
    A[np.arange(k), np.arange(k)] = diag
    expected = np.linalg.solve(A, rhs)

    seen = []
    real = B.banded_cholesky
    monkeypatch.setattr(sys.modules["shapeflow.linalg.local"], "banded_cholesky",
                        lambda *a: seen.append(a[-1]) or real(*a))
    solver = LocalSolver("banded")
    X, used, bw = solver.solve(k, R, C, Vv, diag, rhs)
    assert used == "banded" and bw == band                  # the report keeps the true band
    assert seen == [65 if 56 <= band <= 64 else band]
    np.testing.assert_allclose(X, expected, rtol=1e-10, atol=1e-12)
    # the band storage is reused: a second, smaller solve on the same brush (stale values in
    # the buffer must not leak into it) and the first one again
    half = (R < k // 2) & (C < k // 2)
    X2, _, _ = solver.solve(k // 2, R[half], C[half], Vv[half], diag[:k // 2], rhs[:k // 2])
    A2 = np.zeros((k // 2, k // 2))
    A2[R[half], C[half]] = Vv[half]
    A2[np.arange(k // 2), np.arange(k // 2)] = diag[:k // 2]
    np.testing.assert_allclose(X2, np.linalg.solve(A2, rhs[:k // 2]), rtol=1e-10, atol=1e-12)
    X3, _, _ = solver.solve(k, R, C, Vv, diag, rhs)
    np.testing.assert_array_equal(X3, X)


# --- the split solver: two banded halves on two threads, a dense separator ------------------

def _split_ready():
    from shapeflow.linalg.blas import split_routines

    return sf.accel.available() and split_routines() is not None


requires_split = pytest.mark.skipif(not _split_ready(), reason="needs numba and SciPy's OpenBLAS LAPACK pointers")


def _grid_system(w, h, seed, eight=True, shuffle=True):
    """An SPD system on a w x h grid graph (4- or 8-neighbour), rows grouped in increasing
    order, unknowns numbered at random: (k, ri, ci, vi, diag, rhs, dense A)."""
    rng = np.random.default_rng(seed)
    k = w * h
    idx = np.arange(k).reshape(h, w)
    steps = [(0, 1), (1, 0)] + ([(1, 1), (1, -1)] if eight else [])
    a, b = [], []
    for dy, dx in steps:
        src = idx[max(0, -dy):h - max(0, dy), max(0, -dx):w - max(0, dx)]
        dst = idx[max(0, dy):h + min(0, dy) or None, max(0, dx):w + min(0, dx) or None]
        a.append(src.ravel())
        b.append(dst.ravel())
    a, b = np.concatenate(a), np.concatenate(b)
    p = rng.permutation(k) if shuffle else np.arange(k)
    a, b = p[a], p[b]
    v = -rng.uniform(0.2, 1.0, a.size)
    R, C, V = np.concatenate([a, b]), np.concatenate([b, a]), np.concatenate([v, v])
    o = np.lexsort((rng.random(R.size), R))          # grouped by row, neighbours in any order
    R, C, V = R[o], C[o], V[o]
    diag = np.bincount(R, -V, minlength=k) + rng.uniform(1e-4, 1e-2, k)   # a Laplacian + a small mass
    rhs = rng.standard_normal((k, 3))
    A = np.zeros((k, k))
    A[R, C] = V
    A[np.arange(k), np.arange(k)] = diag
    return k, R, C, V, diag, rhs, A


@requires_split
@pytest.mark.parametrize("w, h, eight", [(40, 30, True), (36, 36, False), (60, 25, True), (70, 40, True)])
def test_split_solve_matches_a_dense_solve(w, h, eight, monkeypatch):
    from shapeflow.linalg import banded as B
    from shapeflow.linalg import compiled_split as K
    from shapeflow.linalg.local import LocalSolver

    k, R, C, V, diag, rhs, A = _grid_system(w, h, seed=w * h, eight=eight)
    seen = []
    real = K.split_solve
    # record perm and dims of every call
    monkeypatch.setattr(K, "split_solve", lambda *a: seen.append((a[-5].copy(), a[-3].copy())) or real(*a))
    solver = LocalSolver("auto")
    X, used, bw = solver.solve(k, R, C, V, diag, rhs)
    assert used == "split"
    np.testing.assert_allclose(X, np.linalg.solve(A, rhs), rtol=1e-9, atol=1e-11)
    # the order, checked from its definition
    (perm, dims), = seen
    nA, nB, nS, kdA, kdB, tA, tB = (int(x) for x in dims)
    assert nA + nB + nS == k and np.array_equal(np.sort(perm), np.arange(k))
    pos = np.empty(k, np.int64)
    pos[perm] = np.arange(k)
    i, j = pos[R], pos[C]
    part = np.where(i < nA, 0, np.where(i < nA + nB, 1, 2)), np.where(j < nA, 0, np.where(j < nA + nB, 1, 2))
    assert not ((part[0] == 0) & (part[1] == 1)).any()          # the halves are not coupled
    inA, inB = (part[0] == 0) & (part[1] == 0), (part[0] == 1) & (part[1] == 1)
    true_a, true_b = np.abs(i - j)[inA].max(), np.abs(i - j)[inB].max()
    assert bw == max(true_a, true_b)
    for true, kd in ((true_a, kdA), (true_b, kdB)):   # LAPACK sees the band, padded as BLOCKED_BAND says
        assert kd == (B.BLOCKED_BAND[1] if B.BLOCKED_BAND[0] <= true < B.BLOCKED_BAND[1] else true)
    toS = part[1] == 2
    assert (i[toS & (part[0] == 0)] >= nA - tA).all() and (i[toS & (part[0] == 1)] >= nA + nB - tB).all()
    assert 0 < tA <= nA and 0 < tB <= nB
    # halves balanced around the median level
    assert min(nA, nB) >= k // 5


@requires_split
def test_split_solver_falls_back_where_it_does_not_apply():
    import numba

    from shapeflow.linalg.local import LocalSolver

    k, R, C, V, diag, rhs, A = _grid_system(40, 30, seed=5)
    solver = LocalSolver("auto")
    ref = np.linalg.solve(A, rhs)
    # components: the largest is split, the others join the smaller half
    kk, Rk, Ck, Vk, dk, rk, Ak = _grid_system(12, 9, seed=8)
    R2, C2 = np.concatenate([R, Rk + k]), np.concatenate([C, Ck + k])
    V2, d2 = np.concatenate([V, Vk]), np.concatenate([diag, dk, [2.0]])   # + an isolated unknown
    rhs2 = np.vstack([rhs, rk, [[1.0, -2.0, 4.0]]])
    X, used, _ = solver.solve(k + kk + 1, R2, C2, V2, d2, rhs2)
    assert used == "split"
    np.testing.assert_allclose(X, np.vstack([ref, np.linalg.solve(Ak, rk), [[0.5, -1.0, 2.0]]]),
                               rtol=1e-9, atol=1e-11)
    # no balanced cut (a star: the median unknown's level holds all but two): not split
    ks = 1200
    Rs = np.concatenate([np.zeros(ks - 1, np.int64), np.arange(1, ks)])
    Cs = np.concatenate([np.arange(1, ks), np.zeros(ks - 1, np.int64)])
    o = np.argsort(Rs, kind="stable")
    Rs, Cs = Rs[o], Cs[o]
    Vs = -np.ones(Rs.size)
    ds = np.full(ks, 2.0)
    ds[0] = ks + 1.0
    As = np.diag(ds)
    As[Rs, Cs] = Vs
    X, used, _ = solver.solve(ks, Rs, Cs, Vs, ds, rhs[:ks])
    assert used != "split"
    np.testing.assert_allclose(X, np.linalg.solve(As, rhs[:ks]), rtol=1e-9, atol=1e-11)
    # not positive definite: LU takes over, the answer is still the system's
    bad = diag.copy()
    bad[::7] = -5.0
    A_bad = A.copy()
    A_bad[np.arange(k), np.arange(k)] = bad
    X, used, _ = solver.solve(k, R, C, V, bad, rhs)
    assert used in ("lu", "cholesky")
    np.testing.assert_allclose(A_bad @ X, rhs, rtol=1e-8, atol=1e-8)
    # one thread: the same split, the halves one after the other, the same bits
    X2, used2, _ = solver.solve(k, R, C, V, diag, rhs)
    old = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        X1, used1, _ = solver.solve(k, R, C, V, diag, rhs)
    finally:
        numba.set_num_threads(old)
    assert used1 == used2 == "split"
    np.testing.assert_array_equal(X1, X2)
    np.testing.assert_allclose(X1, ref, rtol=1e-9, atol=1e-11)
    # an explicit solver="banded" never splits; small systems do not either
    assert LocalSolver("banded").solve(k, R, C, V, diag, rhs)[1] == "banded"
    ks, Rs, Cs, Vs, ds, rs, As = _grid_system(20, 20, seed=6)
    assert solver.solve(ks, Rs, Cs, Vs, ds, rs)[1] == "banded"


@requires_split
def test_split_dabs_equal_one_band_dabs():
    """Dabs of ~1,500 unknowns on a bumpy grid: the split solver and the one-band solver agree."""
    mesh = _bumpy_grid(60, mix=0.3)
    c = mesh.vertices[np.argmin(np.linalg.norm(mesh.vertices - mesh.vertices.mean(0), axis=1))]
    a = sf.Brush(mesh, lam=-30.0, radius=0.38 * mesh.diagonal)
    b = sf.Brush(mesh, lam=-30.0, radius=0.38 * mesh.diagonal, solver="banded")
    for shift in (0.0, 0.1, -0.1):
        p = c + shift * mesh.diagonal
        a.dab(p)
        b.dab(p)
        assert a.last.solver == "split" and b.last.solver == "banded"
        assert a.last.indices.size >= 1000
        np.testing.assert_array_equal(a.last.indices, b.last.indices)
        assert np.abs(a.last.positions - b.last.positions).max() <= 1e-10 * mesh.diagonal


def test_a_fallback_from_the_split_solver_is_reported(monkeypatch):
    import shapeflow.linalg.local as B
    from shapeflow.linalg.blas import FALLBACKS

    if not sf.accel.available():
        pytest.skip("the split solver needs numba (the 'fast' extra)")
    monkeypatch.setattr(B, "split_routines", lambda: None)   # as on a SciPy without OpenBLAS's setter
    monkeypatch.setitem(FALLBACKS, "split", "the split solver is unavailable here")
    mesh = sf.load_example("spot")
    brush = sf.Brush(mesh, lam=-20.0, radius=0.9)
    brush.dab(mesh.vertices.mean(axis=0))
    assert brush.last.n_inside >= B.SPLIT_MIN
    assert brush.last.solver == "banded" and brush.last.notes == ["the split solver is unavailable here"]
