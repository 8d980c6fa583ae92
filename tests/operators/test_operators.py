"""The TQLBO operator (issue 3): weights, Laplacians, curvature, degeneracy."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from conftest import requires_shared, shared_mesh_paths
from meshgen import cube_sphere, grid, icosphere, ngon_disk, random_rotation

import shapeflow as sf

# --- independent slow reference implementations -----------------------------

def slow_cotmatrix(V, tris, n, weight=1.0):
    """Classic cotangent weights by a plain loop: w_ij += weight * cot(opposite angle)."""
    W = np.zeros((n, n))
    for t in tris:
        for k in range(3):
            i, j, o = t[(k + 1) % 3], t[(k + 2) % 3], t[k]
            a = V[i] - V[o]
            b = V[j] - V[o]
            cot = np.dot(a, b) / np.linalg.norm(np.cross(a, b))
            W[i, j] += weight * cot
            W[j, i] += weight * cot
    return W


def dense(W):
    return W.toarray() if sp.issparse(W) else W


# --- triangles and quads ------------------------------------------------------

def test_triangle_mesh_equals_classic_cotangent_matrix():
    m = icosphere(1)
    V = m.vertices + 0.05 * np.random.default_rng(1).standard_normal(m.vertices.shape)
    m = m.with_vertices(V)
    W, _ = sf.cotan_weights(m)
    ref = slow_cotmatrix(m.vertices, m.faces_as_lists(), m.n_vertices)
    np.testing.assert_allclose(dense(W), ref, atol=1e-12)


def test_triangle_mesh_matches_libigl():
    import igl  # a test dependency (the test extra): an independent implementation
    m = icosphere(2)
    W, _ = sf.cotan_weights(m)
    C = igl.cotmatrix(m.vertices, m.faces_as_array())  # libigl: C_ij = ½(cot a + cot b), negative definite
    off = dense(C) - np.diag(np.diag(dense(C)))
    np.testing.assert_allclose(dense(W), 2 * off, atol=1e-10)


def test_quad_mesh_equals_mean_of_its_two_triangulations():
    m = grid(5, 4, jitter=0.2, z=lambda x, y: 0.3 * np.sin(x) * np.cos(y), seed=3)
    quads = m.faces_as_array()
    t1 = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])  # cut along 0-2
    t2 = np.concatenate([quads[:, [0, 1, 3]], quads[:, [1, 2, 3]]])  # cut along 1-3
    ref = 0.5 * (slow_cotmatrix(m.vertices, t1, m.n_vertices) + slow_cotmatrix(m.vertices, t2, m.n_vertices))
    W, A = sf.cotan_weights(m)
    np.testing.assert_allclose(dense(W), ref, atol=1e-12)
    # ring area (eq. 5): a quad gives each corner ½[A(t1) + A(t2) + A(t3)] = ½ (quad area + corner tri)
    def area(p, q, r):
        return 0.5 * np.linalg.norm(np.cross(m.vertices[q] - m.vertices[p], m.vertices[r] - m.vertices[p]))
    ref_a = np.zeros(m.n_vertices)
    for q in quads:
        for k in range(4):
            i, j, jp, j1 = q[k], q[(k + 1) % 4], q[(k + 2) % 4], q[(k + 3) % 4]
            ref_a[i] += 0.5 * (area(i, j, jp) + area(i, jp, j1) + area(i, j, j1))
    np.testing.assert_allclose(A, ref_a, rtol=1e-12)


def test_blender_scheme_is_half_cot_per_corner_triangle():
    m = ngon_disk(6, 3)  # hexagon, quads and triangles
    corner_tris = np.array([[f[k - 1], f[k], f[(k + 1) % len(f)]] for f in m.faces_as_lists() for k in range(len(f))])
    ref = slow_cotmatrix(m.vertices, corner_tris, m.n_vertices, weight=0.5)
    W, _ = sf.cotan_weights(m, scheme="blender")
    np.testing.assert_allclose(dense(W), ref, atol=1e-12)


def test_ngon_scheme_is_mean_of_fan_triangulations():
    m = ngon_disk(7, 1)
    f = m.faces_as_lists()[0]
    s = len(f)
    ref = np.zeros((m.n_vertices, m.n_vertices))
    for r in range(s):
        fan = [[f[r], f[(r + j) % s], f[(r + j + 1) % s]] for j in range(1, s - 1)]
        ref += slow_cotmatrix(m.vertices, fan, m.n_vertices, weight=1.0 / s)
    others = [g for g in m.faces_as_lists()[1:]]
    quads = np.array(others)
    t1 = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    t2 = np.concatenate([quads[:, [0, 1, 3]], quads[:, [1, 2, 3]]])
    ref += 0.5 * (slow_cotmatrix(m.vertices, t1, m.n_vertices) + slow_cotmatrix(m.vertices, t2, m.n_vertices))
    W, _ = sf.cotan_weights(m)
    np.testing.assert_allclose(dense(W), ref, atol=1e-12)


# --- linear precision -------------------------------------------------------------

@pytest.mark.parametrize("make", [
    lambda: grid(7, jitter=0.3, mix=1.0, seed=1),        # triangles
    lambda: grid(7, jitter=0.3, seed=2),                 # quads
    lambda: grid(8, jitter=0.3, mix=0.5, seed=3),        # mixed
    lambda: ngon_disk(5, 4),                             # pentagon + quads + triangles
    lambda: ngon_disk(9, 4),                             # 9-gon
], ids=["tri", "quad", "mixed", "pentagon", "9-gon"])
@pytest.mark.parametrize("normalized", [True, False])
def test_linear_precision_on_planar_meshes(make, normalized):
    m = make()
    R = random_rotation(5)
    m = m.with_vertices(m.vertices @ R.T + [1.0, -2.0, 3.0])  # a plane in general position
    L = sf.laplacian(m, normalized=normalized)
    interior = ~m.topology.boundary_vertex_mask
    assert interior.any()
    assert np.abs((L @ m.vertices)[interior]).max() < 1e-12


def test_blender_scheme_loses_linear_precision_on_mixed_planar_meshes():
    # documented Blender behaviour (triangles weigh 1.5x quads): check it is real, so
    # the linear-precision test above can fail
    m = grid(8, jitter=0.3, mix=0.5, seed=3)
    L = sf.laplacian(m, scheme="blender")
    interior = ~m.topology.boundary_vertex_mask
    assert np.abs((L @ m.vertices)[interior]).max() > 1e-3


# --- algebraic properties on real meshes --------------------------------------------

@requires_shared
@pytest.mark.parametrize("path", shared_mesh_paths(), ids=lambda p: p.stem)
@pytest.mark.parametrize("scheme", ["tqlbo", "blender"])
def test_symmetry_rowsums_and_psd_on_shared_meshes(path, scheme):
    m = sf.load(path)
    cw = sf.cotan_weights(m, scheme)
    W = cw.W
    assert np.isfinite(W.data).all()
    assert abs(W - W.T).max() <= 1e-12 * max(1.0, abs(W).max())
    K = sp.diags(cw.degree) - W
    assert np.abs(K @ np.ones(m.n_vertices)).max() < 1e-9 * max(1.0, cw.degree.max())
    # PSD: K + εI has an LDLᵀ factorisation with positive pivots (Sylvester's law of
    # inertia; SuperLU with a symmetric ordering and no pivoting gives exactly those)
    from scipy.sparse.linalg import splu

    eps = 1e-9 * float(np.mean(np.abs(cw.degree)))
    lu = splu((K + eps * sp.identity(m.n_vertices)).tocsc(), permc_spec="MMD_AT_PLUS_A",
              diag_pivot_thresh=0.0, options=dict(SymmetricMode=True))
    assert (lu.U.diagonal() > 0).all()
    # ... and the check can fail: K − 10ε I is indefinite (K has the eigenvalue 0)
    lu = splu((K - 10 * eps * sp.identity(m.n_vertices)).tocsc(), permc_spec="MMD_AT_PLUS_A",
              diag_pivot_thresh=0.0, options=dict(SymmetricMode=True))
    assert (lu.U.diagonal() < 0).any()
    if m.n_vertices < 3000:  # cross-check with the smallest eigenvalues
        from scipy.sparse.linalg import eigsh

        vals = eigsh(K.tocsc() / cw.degree.max(), k=2, sigma=-1e-3, which="LM", return_eigenvectors=False)
        assert vals.min() > -1e-9


# --- curvature convergence ------------------------------------------------------------

def _mean_edge(m):
    e = m.topology.edges
    return float(np.linalg.norm(m.vertices[e[:, 0]] - m.vertices[e[:, 1]], axis=1).mean())


def _slope(h, err):
    return float(np.polyfit(np.log(h), np.log(err), 1)[0])


R_SPHERE = 2.0
SPHERES = {
    "quad": lambda: [cube_sphere(k, R_SPHERE) for k in (4, 8, 16, 32)],
    "ico": lambda: [icosphere(lv, R_SPHERE) for lv in (2, 3, 4)],  # level 1 is exact by symmetry
    "mixed": lambda: [cube_sphere(k, R_SPHERE, mix=0.5, seed=k) for k in (4, 8, 16, 32)],
}


@pytest.mark.parametrize("area", ["barycentric", "mixed"])
@pytest.mark.parametrize("family", ["quad", "ico"])
def test_mean_curvature_of_regular_spheres_converges_pointwise(family, area):
    meshes = SPHERES[family]()
    h = np.array([_mean_edge(m) for m in meshes])
    med = np.array([np.median(np.abs(sf.mean_curvature(m, area=area) - 1 / R_SPHERE)) for m in meshes])
    # the typical vertex converges quadratically (the 8 valence-3 corners of the cube
    # sphere keep an O(1) error: extraordinary vertices do not converge pointwise)
    assert _slope(h, med) > 1.5, med
    assert med[-1] < 1e-3 / R_SPHERE
    # the paper's ring-area curvature is ~1/3 of it on these regular meshes
    H_ring = sf.mean_curvature(meshes[-1], area="ring")
    assert abs(np.median(H_ring) * R_SPHERE - 1 / 3) < 2e-3


def test_mean_curvature_of_mixed_sphere_converges():
    # Randomly half-triangulated quad spheres are irregular meshes, on which no
    # cotangent operator converges pointwise at every vertex (Xu 2004; Wardetzky et
    # al. 2007); the integrated mean curvature (weak form) does, quadratically, and
    # the typical pointwise error still falls.
    meshes = SPHERES["mixed"]()
    h = np.array([_mean_edge(m) for m in meshes])
    exact = 4 * np.pi * R_SPHERE  # ∫ H dA = (1/r) 4πr²
    integ = []
    med = []
    for m in meshes:
        A = sf.vertex_areas(m, "mixed")
        H = sf.mean_curvature(m, area="mixed")
        integ.append(abs((A * H).sum() - exact) / exact)
        med.append(np.median(np.abs(H - 1 / R_SPHERE)))
    assert _slope(h, np.array(integ)) > 1.8, integ
    assert integ[-1] < 1e-3
    assert _slope(h, np.array(med)) > 0.4, med


def test_mean_curvature_sign_follows_orientation():
    m = icosphere(2)
    flipped = sf.Mesh(m.vertices, [f[::-1] for f in m.faces_as_lists()])
    assert (sf.mean_curvature(m) > 0).all()
    assert (sf.mean_curvature(flipped) < 0).all()


# --- invariances --------------------------------------------------------------------------

def test_rigid_motion_and_scale_invariance():
    m = grid(6, jitter=0.2, mix=0.5, z=lambda x, y: 0.2 * x * y, seed=7)
    R = random_rotation(11)
    moved = m.with_vertices(m.vertices @ R.T + [5.0, -1.0, 2.0])
    scaled = m.with_vertices(4.0 * m.vertices)
    L = sf.laplacian(m)
    np.testing.assert_allclose(dense(sf.laplacian(moved)), dense(L), atol=1e-12)
    np.testing.assert_allclose(dense(sf.laplacian(scaled)), dense(L), atol=1e-12)
    La = sf.laplacian(m, normalized=False)
    np.testing.assert_allclose(dense(sf.laplacian(moved, normalized=False)), dense(La), atol=1e-11)
    # the area-normalised operator is not scale-invariant: it scales by 1/s²
    np.testing.assert_allclose(dense(sf.laplacian(scaled, normalized=False)), dense(La) / 16.0, atol=1e-12)


# --- degeneracy -----------------------------------------------------------------------------

def test_degenerate_elements_are_excluded_and_locked():
    m = grid(5, jitter=0.1, seed=2)
    V = m.vertices.copy()
    V[12] = V[13]            # a zero-length edge (12-13 are neighbours in the grid)
    V[6] = 0.5 * (V[1] + V[7])  # quad [1, 6, 7, 2] gets a 180° corner: flat corner triangle (1, 6, 7)
    bad = m.with_vertices(V)
    cw = sf.cotan_weights(bad)
    assert np.isfinite(cw.W.data).all() and np.isfinite(cw.degree).all()
    assert cw.locked[[12, 13, 6, 1, 7]].all()
    assert cw.n_degenerate > 0
    L = sf.laplacian(bad)
    assert np.isfinite(L.data).all()


@pytest.mark.parametrize("scale", [1e-6, 1.0, 1e6])
def test_relative_thresholds_do_not_depend_on_scale(scale):
    m = grid(6, jitter=0.2, seed=4).with_vertices(grid(6, jitter=0.2, seed=4).vertices * scale)
    cw = sf.cotan_weights(m)
    assert not cw.locked.any()
    # Blender's absolute thresholds lock everything on a tiny model
    cwb = sf.cotan_weights(m, "blender", thresholds="blender")
    assert cwb.locked.all() == (scale < 1e-3)


def test_bad_scheme_is_a_value_error():
    with pytest.raises(ValueError, match="scheme"):
        sf.cotan_weights(grid(3), scheme="nope")


def test_cached_pattern_survives_user_facing_calls():
    # regression: cotan_weights once rewrote the cached CSR pattern in place
    m = cube_sphere(5, mix=0.5, seed=3)
    before = sf.flow(m, -5.0).vertices
    fresh = sf.Mesh(m.vertices, m.faces_as_lists())
    for _ in range(2):
        sf.cotan_weights(m)
        sf.laplacian(m)
        sf.mean_curvature(m)
        sf.vertex_areas(m, "mixed")
    np.testing.assert_array_equal(sf.flow(m, -5.0).vertices, before)
    np.testing.assert_array_equal(sf.flow(fresh, -5.0).vertices, before)


@pytest.mark.parametrize("use", ["cotan_weights", "flow", "brush"])
def test_no_reference_cycle_keeps_a_mesh_alive(use):
    """Operator structures are cached on the topology: they must not point back to it, or every
    fresh mesh would wait for the cyclic garbage collector (memory piled up between its runs)."""
    import gc
    import weakref

    m0 = cube_sphere(6)
    was = gc.isenabled()
    gc.disable()
    try:
        m = sf.Mesh.from_csr(m0.vertices, m0.face_sizes, m0.face_indices)
        if use == "cotan_weights":
            sf.cotan_weights(m)
        elif use == "flow":
            sf.flow(m, 1.0, iterations=2)
        else:
            sf.Brush(m, radius=0.5).dab(m.vertices[0])
        ref = weakref.ref(m.topology)
        del m
        assert ref() is None
    finally:
        if was:
            gc.enable()
