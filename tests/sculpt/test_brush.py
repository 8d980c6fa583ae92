"""The sculpt brush of section 4.3 (issue 8): shapeflow.Brush, InflateBrush, ``shapeflow brush``."""

from __future__ import annotations

import json
import tracemalloc

import numpy as np
import pytest
from conftest import MESHES, requires_shared
from meshgen import cube_sphere, grid, icosphere, ngon_disk, random_rotation

import shapeflow as sf
from shapeflow.cli import main
from shapeflow.geometry import vertex_normals
from shapeflow.operators.cotan import assemble as _assemble


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


@pytest.mark.parametrize("kernels", ["force", "off"])
def test_spatial_index_query_is_exact(kernels):
    """Both spatial indexes of the sculpt kernels (the compiled grid, SciPy's k-d tree) find exactly the
    points within r (moved points too), whatever the radius relative to the grid's cells, with centres
    inside and far outside the grid."""
    if kernels == "force" and not sf.accel.available():
        pytest.skip("numba (the 'fast' extra) not installed")
    with sf.accel.use(kernels=kernels):
        family = sf.accel.kernels("sculpt", 3000)
    rng = np.random.default_rng(9)
    P = rng.normal(size=(3000, 3)) * [1.0, 2.0, 0.3]
    for h in (1e-9, 0.05, 0.4, 50.0):
        g = family.spatial_index(P, h)
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
