"""Smoothing and shape enhancement, eq. 11 (issue 4)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from conftest import (
    MESHES,
    fixture_cases,
    load_fixture_case,
    load_fixture_mesh,
    need,
    requires_shared,
    shared_mesh_paths,
)
from meshgen import cube_sphere, grid, icosphere, random_rotation

import shapeflow as sf

# --- Blender compatibility ------------------------------------------------------

@requires_shared
@pytest.mark.parametrize("case", fixture_cases("smooth_"))
def test_blender_fixture(case):
    c = load_fixture_case(case)
    p = c["params"]
    mesh = load_fixture_mesh(c["mesh"])
    out = sf.flow(mesh, p["lambda_factor"], lam_border=p["lambda_border"], iterations=p["iterations"],
                  normalized=p["use_normalized"], preserve_volume=p["use_volume_preserve"],
                  axes=(p["use_x"], p["use_y"], p["use_z"]), weights=c.get("weights"),
                  invert_weights=p["invert_vertex_group"], compat="blender")
    err = np.abs(out.vertices - c["result"]).max()
    assert err <= 1e-5 * mesh.diagonal, err / mesh.diagonal


def test_fixture_count():
    if MESHES is None:
        pytest.skip("shared/ not found")
    assert len(fixture_cases("smooth_")) == 81


# --- an independent dense implementation of eq. 11 (paper mode) ---------------

def dense_flow(mesh, lam, weights=None, lam_border=0.0, normalized=True):
    """(I + |λ| W_p L) V' = V solved densely in the printed (unsymmetric) form."""
    n = mesh.n_vertices
    V = mesh.vertices
    w = np.ones(n) if weights is None else np.asarray(weights, float)
    L = sf.laplacian(mesh, normalized=normalized).toarray()
    b = mesh.topology.boundary_vertex_mask
    A = np.eye(n) + abs(lam) * w[:, None] * L
    # boundary rows: scale-dependent umbrella over boundary edges, own λ_b
    A[b] = 0.0
    A[b, b] = 1.0
    if lam_border:
        be = mesh.topology.boundary_edges
        Lb = np.zeros((n, n))
        for i, j in be:
            e = 1.0 / np.linalg.norm(V[i] - V[j])
            Lb[i, j] -= e
            Lb[j, i] -= e
            Lb[i, i] += e
            Lb[j, j] += e
        Lb[b] /= np.diag(Lb)[b][:, None]
        A[b] = np.eye(n)[b] + abs(lam_border) * w[b, None] * Lb[b]
    X = np.linalg.solve(A, V)
    s = np.where(b, np.sign(lam_border) or 1.0, np.sign(lam) or 1.0)
    return V + s[:, None] * (X - V)


@pytest.mark.parametrize("lam", [3.0, -7.0])
@pytest.mark.parametrize("normalized", [True, False])
def test_paper_mode_matches_dense_solve_closed(lam, normalized):
    m = cube_sphere(5, mix=0.4, seed=2)
    rng = np.random.default_rng(0)
    m = m.with_vertices(m.vertices * [1.0, 0.7, 1.3] + 0.02 * rng.standard_normal(m.vertices.shape))
    w = rng.uniform(0, 1, m.n_vertices)
    w[:10] = 0.0
    out = sf.flow(m, lam, weights=w, normalized=normalized)
    ref = dense_flow(m, lam, weights=w, normalized=normalized)
    np.testing.assert_allclose(out.vertices, ref, atol=1e-9 * m.diagonal)


@pytest.mark.parametrize("lam_border", [0.0, 2.0, -1.5])
def test_paper_mode_matches_dense_solve_open(lam_border):
    m = grid(9, jitter=0.2, mix=0.3, seed=5, z=lambda x, y: 0.1 * (x - 4) ** 2 - 0.05 * y * x)
    out = sf.flow(m, -4.0, lam_border=lam_border)
    ref = dense_flow(m, -4.0, lam_border=lam_border)
    np.testing.assert_allclose(out.vertices, ref, atol=1e-9 * m.diagonal)
    b = m.topology.boundary_vertex_mask
    if lam_border == 0.0:
        assert np.array_equal(out.vertices[b], m.vertices[b])


@pytest.mark.parametrize("solver", ["cg", "lu", "cholesky"])
def test_solvers_agree(solver):
    if solver == "cholesky":
        need("cholespy", "cholespy (the 'cholesky' extra)")
    m = cube_sphere(6, mix=0.5, seed=1)
    ref = sf.flow(m, -30.0, iterations=3, solver="lu")
    out = sf.flow(m, -30.0, iterations=3, solver=solver, rtol=1e-12)
    np.testing.assert_allclose(out.vertices, ref.vertices, atol=1e-9 * m.diagonal)
    # at the default tolerance CG is within 1e-7 of the displacement
    d = np.abs(ref.vertices - m.vertices).max()
    np.testing.assert_allclose(sf.flow(m, -30.0, iterations=3, solver=solver).vertices, ref.vertices, atol=1e-7 * d)
    assert out.report.solver == solver


# --- invariants --------------------------------------------------------------------

def test_lambda_zero_and_no_axes_and_zero_weights_return_input():
    m = icosphere(2)
    for kw in [dict(lam=0.0), dict(lam=-5.0, axes=""), dict(lam=-5.0, weights=np.zeros(m.n_vertices)),
               dict(lam=-5.0, iterations=0)]:
        lam = kw.pop("lam")
        out = sf.flow(m, lam, **kw)
        assert np.array_equal(out.vertices, m.vertices)
        assert out.n_faces == m.n_faces


def test_weight_zero_vertices_do_not_move_and_weights_scale_motion():
    m = cube_sphere(6)
    m = m.with_vertices(m.vertices * [1, 1, 1.5])
    w = np.clip(m.vertices[:, 0], 0, 1)  # 0 on one half
    out = sf.flow(m, -10.0, weights=w, iterations=2)
    fixed = w == 0
    assert np.array_equal(out.vertices[fixed], m.vertices[fixed])
    assert np.abs(out.vertices[~fixed] - m.vertices[~fixed]).max() > 1e-3
    inv = sf.flow(m, -10.0, weights=w, invert_weights=True)
    assert np.array_equal(inv.vertices[w == 1], m.vertices[w == 1])


def test_weights_from_attribute_name():
    m = icosphere(2)
    w = np.linspace(0, 1, m.n_vertices)
    a = sf.flow(m.with_weights(w), -3.0, weights="weight")
    b = sf.flow(m, -3.0, weights=w)
    assert np.array_equal(a.vertices, b.vertices)


def test_axes_restrict_motion():
    m = cube_sphere(5)
    out = sf.flow(m, -8.0, axes="xz")
    assert np.array_equal(out.vertices[:, 1], m.vertices[:, 1])
    assert np.abs(out.vertices[:, 0] - m.vertices[:, 0]).max() > 1e-3


@pytest.mark.parametrize("compat", [None, "blender"])
def test_rigid_motion_equivariance(compat):
    m = grid(8, jitter=0.2, mix=0.4, seed=3, z=lambda x, y: 0.05 * x * y)
    R = random_rotation(4)
    t = np.array([3.0, -2.0, 0.5])
    moved = m.with_vertices(m.vertices @ R.T + t)
    a = sf.flow(m, -6.0, lam_border=1.0, iterations=2, compat=compat)
    b = sf.flow(moved, -6.0, lam_border=1.0, iterations=2, compat=compat)
    assert a.report.locked == 0  # (Blender pulls boundary vertices next to locked ones toward the origin)
    np.testing.assert_allclose(b.vertices, a.vertices @ R.T + t, atol=1e-9 * m.diagonal)


def dirichlet_energy(m):
    K = sf.cotan_weights(m)
    pw = K.pair_weights
    p = K.pairs
    d = m.vertices[p[:, 0]] - m.vertices[p[:, 1]]
    return float(0.5 * np.sum(pw * np.einsum("ij,ij->i", d, d)))


def test_smoothing_lowers_dirichlet_energy_and_enhancement_raises_curvature():
    rng = np.random.default_rng(2)
    m = cube_sphere(8, mix=0.3, seed=2)
    m = m.with_vertices(m.vertices * [1.0, 0.8, 1.4] + 0.01 * rng.standard_normal(m.vertices.shape))
    smoothed = sf.smooth(m, 2.0)
    assert dirichlet_energy(smoothed) < dirichlet_energy(m)
    enhanced = sf.enhance(m, 5.0)
    H0 = np.mean(np.abs(sf.mean_curvature(m))) * m.diagonal
    H1 = np.mean(np.abs(sf.mean_curvature(enhanced))) * enhanced.diagonal
    # enhancement exaggerates differences of curvature: normalised by size, mean |H| grows
    assert H1 > H0


@pytest.mark.parametrize("lam", [-20.0, 10.0])
def test_volume_preserved_on_closed_meshes(lam):
    m = cube_sphere(6, mix=0.5, seed=0)
    m = m.with_vertices(m.vertices * [1.0, 0.6, 1.5])
    vol0 = sf.geometry.signed_volume(m)
    out = sf.flow(m, lam, iterations=3, preserve_volume=True)
    vol1 = sf.geometry.signed_volume(out)
    assert abs(vol1 - vol0) <= 1e-9 * abs(vol0)
    plain = sf.flow(m, lam, iterations=3)
    assert abs(sf.geometry.signed_volume(plain) - vol0) > 1e-3 * abs(vol0)


def test_update_recompute_differs_after_first_iteration():
    m = cube_sphere(6)
    m = m.with_vertices(m.vertices * [1, 1, 2])
    a1 = sf.flow(m, -5.0, update="fixed")
    b1 = sf.flow(m, -5.0, update="recompute")
    np.testing.assert_allclose(a1.vertices, b1.vertices, atol=1e-12)
    a3 = sf.flow(m, -5.0, iterations=3, update="fixed")
    b3 = sf.flow(m, -5.0, iterations=3, update="recompute")
    assert np.abs(a3.vertices - b3.vertices).max() > 1e-4


def test_flow_solver_reuses_operator():
    m = cube_sphere(6)
    s = sf.FlowSolver(m)
    a = s.run(-5.0)
    op = s.operator()
    b = s.run(-5.0, iterations=2)
    assert s.operator() is op
    np.testing.assert_allclose(a.vertices, sf.flow(m, -5.0).vertices, atol=1e-12)
    np.testing.assert_allclose(b.vertices, sf.flow(m, -5.0, iterations=2).vertices, atol=1e-12)


def test_locked_vertices_never_move_and_are_reported():
    m = grid(7, jitter=0.1, seed=1, z=lambda x, y: 0.1 * x * y)
    V = m.vertices.copy()
    V[17] = V[18]  # zero-length edge
    bad = m.with_vertices(V)
    out = sf.flow(bad, -20.0, lam_border=1.0, iterations=2)
    assert out.report.locked >= 2
    assert np.array_equal(out.vertices[[17, 18]], V[[17, 18]])
    assert np.isfinite(out.vertices).all()


# --- figure 7: triangle, quad and mixed versions of one surface --------------------

@requires_shared
def test_triangle_quad_and_mixed_versions_look_alike():
    quad = sf.load(MESHES / "spot_quad.obj")
    tri = sf.load(MESHES / "spot_tri.obj")
    assert np.array_equal(quad.vertices, tri.vertices)
    rng = np.random.default_rng(7)
    faces = []
    for f in quad.faces_as_lists():
        if rng.random() < 0.5:
            faces += [[f[0], f[1], f[2]], [f[0], f[2], f[3]]]
        else:
            faces.append(f)
    mixed = sf.Mesh(quad.vertices, faces)
    res = [sf.flow(m, 7.0, iterations=2).vertices for m in (tri, quad, mixed)]
    d = quad.diagonal
    moved = np.abs(res[1] - quad.vertices).max() / d
    for a in range(3):
        for b in range(a + 1, 3):
            diff = np.linalg.norm(res[a] - res[b], axis=1)
            assert np.median(diff) / d < 0.1 * moved, (a, b)
            assert diff.max() / d < 0.01


# --- large |λ| --------------------------------------------------------------------------

def spikiness(m, V):
    """Largest distance of a vertex from its 1-ring centroid, in units of the median edge length.

    A spike (one vertex shooting out of its neighbourhood) makes this large; a
    uniformly inflated or smoothed surface keeps it about where it was.
    """
    e = m.topology.edges
    n = m.n_vertices
    A = sp.coo_matrix((np.ones(2 * len(e)), (np.r_[e[:, 0], e[:, 1]], np.r_[e[:, 1], e[:, 0]])), shape=(n, n)).tocsr()
    deg = np.maximum(np.asarray(A.sum(axis=1)).ravel(), 1)
    off = np.linalg.norm(V - (A @ V) / deg[:, None], axis=1)
    h = np.median(np.linalg.norm(V[e[:, 0]] - V[e[:, 1]], axis=1))
    return float(off.max() / h)


@requires_shared
@pytest.mark.parametrize("path", shared_mesh_paths(), ids=lambda p: p.stem)
def test_large_negative_lambda_is_finite_and_spike_free(path):
    m = sf.load(path)
    out = sf.flow(m, -400.0)
    assert np.isfinite(out.vertices).all()
    assert out.diagonal < 10 * m.diagonal
    before = spikiness(m, m.vertices)
    assert spikiness(m, out.vertices) < before + 0.75
    # the measure does see a spike: one vertex pushed out by 5 edge lengths
    V = out.vertices.copy()
    e = m.topology.edges
    V[e[0, 0]] += 5 * np.median(np.linalg.norm(V[e[:, 0]] - V[e[:, 1]], axis=1)) * np.array([0.6, 0.0, 0.8])
    assert spikiness(m, V) > before + 0.75


# --- errors --------------------------------------------------------------------------------

@pytest.mark.parametrize("kw,match", [
    (dict(lam=float("nan")), "finite"),
    (dict(lam="big"), "number"),
    (dict(lam=1.0, iterations=-1), ">= 0"),
    (dict(lam=1.0, iterations=1.5), "integer"),
    (dict(lam=1.0, weights=np.ones(3)), "shape"),
    (dict(lam=1.0, weights="nope"), "attribute"),
    (dict(lam=1.0, axes="xw"), "axes"),
    (dict(lam=1.0, compat="maya"), "compat"),
    (dict(lam=1.0, update="sometimes"), "update"),
    (dict(lam=1.0, solver="magic"), "solver"),
    (dict(lam=1.0, compat="blender", scheme="tqlbo"), "scheme"),
    (dict(lam=1.0, compat="blender", update="recompute"), "fixed"),
])
def test_bad_parameters_raise_value_errors(kw, match):
    m = icosphere(1)
    lam = kw.pop("lam")
    with pytest.raises(ValueError, match=match):
        sf.flow(m, lam, **kw)


def test_bad_weights_range():
    m = icosphere(1)
    w = np.ones(m.n_vertices)
    w[3] = 1.5
    with pytest.raises(ValueError, match="vertex 3"):
        sf.flow(m, 1.0, weights=w)


def test_strength_must_be_non_negative():
    with pytest.raises(ValueError, match="strength"):
        sf.enhance(icosphere(1), -2.0)
    m = icosphere(2)
    np.testing.assert_array_equal(sf.enhance(m, 3.0).vertices, sf.flow(m, -3.0).vertices)
    np.testing.assert_array_equal(sf.smooth(m, 3.0).vertices, sf.flow(m, 3.0).vertices)


# --- several fixed-operator steps as one Chebyshev expansion ----------------------------

def _iterate_one_by_one(monkeypatch, mesh, lam, **kw):
    """The reference: the same flow with the Chebyshev shortcut switched off (one CG solve per step)."""
    with monkeypatch.context() as mp:
        mp.setattr(__import__("sys").modules["shapeflow.flow.solver"], "fixed_steps", lambda *a, **k: None)
        return sf.flow(mesh, lam, **kw)


@pytest.mark.parametrize("lam", [2.0, -3.0])
@pytest.mark.parametrize("case", ["closed_mixed", "open_fixed_rim", "weights_axes"])
def test_fixed_steps_chebyshev_equals_iterating(monkeypatch, case, lam):
    if case == "closed_mixed":
        mesh, kw = cube_sphere(8, mix=0.4, seed=5), {}
    elif case == "open_fixed_rim":          # boundary held: a constant coupling term g
        mesh, kw = grid(14, 11, jitter=0.2, seed=6, mix=0.3), {}
        mesh = mesh.with_vertices(mesh.vertices + np.c_[0 * mesh.vertices[:, :2], np.sin(mesh.vertices[:, 0] * 3)])
    else:
        mesh = cube_sphere(8, seed=7)
        w = np.linspace(0.5, 1.0, mesh.n_vertices)
        w[::7] = 0.0
        kw = dict(weights=w, axes="xz")
    kw["solver"] = "chebyshev"   # small meshes would pick a reused LU factorisation under "auto"
    out = sf.flow(mesh, lam, iterations=6, rtol=1e-9, **kw)
    assert out.report.solver == "chebyshev"
    ref = _iterate_one_by_one(monkeypatch, mesh, lam, iterations=6, rtol=1e-12, **kw)
    assert ref.report.solver != "chebyshev"
    diag = np.linalg.norm(np.ptp(mesh.vertices, axis=0))
    disp = np.abs(ref.vertices - mesh.vertices).max()
    assert disp > 1e-3 * diag
    assert np.abs(out.vertices - ref.vertices).max() < 1e-8 * disp
    if "axes" in kw:
        np.testing.assert_array_equal(out.vertices[:, 1], mesh.vertices[:, 1])
        still = np.flatnonzero(kw["weights"] == 0)
        np.testing.assert_array_equal(out.vertices[still], mesh.vertices[still])


def test_fixed_steps_not_used_when_steps_are_not_one_linear_map():
    mesh = grid(10, 10, jitter=0.1, seed=8)
    mesh = mesh.with_vertices(mesh.vertices + np.c_[0 * mesh.vertices[:, :2], np.sin(mesh.vertices[:, 0] * 3)])
    assert sf.flow(mesh, 1.0, iterations=4, solver="chebyshev").report.solver == "chebyshev"
    assert sf.flow(mesh, 1.0, iterations=4, solver="cg").report.solver == "cg"      # asked for plain CG
    assert sf.flow(mesh, 1.0, iterations=4, lam_border=0.5, solver="chebyshev").report.solver == "cg"
    sphere = cube_sphere(6)
    assert sf.flow(sphere, 1.0, iterations=4, preserve_volume=True, solver="chebyshev").report.solver == "cg"
    assert sf.flow(sphere, 1.0, iterations=4, update="recompute", solver="chebyshev").report.solver == "cg"
    assert sf.flow(sphere, 1.0, iterations=1, solver="chebyshev").report.solver == "cg"


def test_chebyshev_coefficients_bound_the_error():
    from numpy.polynomial import chebyshev

    from shapeflow.linalg import chebyshev_coefficients

    f = lambda t: (2.0 - 1.0 / t) ** 5      # noqa: E731
    c, tail = chebyshev_coefficients(f, 1.0, 9.0)
    x = np.linspace(-1, 1, 2001)
    for m in (5, 10, 20):
        err = np.abs(chebyshev.chebval(x, c[:m + 1]) - f(5.0 + 4.0 * x)).max()
        assert err <= tail[m] * (1 + 1e-9) + 1e-13
    assert tail[-1] == 0.0


def test_chebyshev_steps_degree_checked_against_the_displacement():
    """A displacement estimate far too large picks too low a degree: the check catches it and
    the sum is redone; both agree with the dense reference f(C⁻¹A) applied exactly."""
    import scipy.sparse as sp

    from shapeflow.linalg import chebyshev_coefficients, chebyshev_steps

    m = cube_sphere(5, seed=2)
    W = sf.cotan_weights(m).W
    d = np.asarray(W.sum(axis=1)).ravel()
    c = d / 0.7                                      # C = D/λ, λ = 0.7
    A = (sp.diags(c + d) - W).tocsr()
    X0 = m.vertices.copy()
    G = np.zeros_like(X0)
    Ad = A.toarray()
    b = float(np.max(np.abs(Ad).sum(axis=1) / c))    # Gershgorin bound of C⁻¹A
    k = 4
    fu = lambda t: (1.0 / t) ** k                    # noqa: E731
    cu = chebyshev_coefficients(fu, 1.0, b)
    ch = chebyshev_coefficients(lambda t: 0.0 * t, 1.0, b)
    Mi = np.linalg.solve(Ad, np.diag(c))             # one step: x <- A⁻¹ C x
    ref = np.linalg.matrix_power(Mi, k) @ X0
    disp = np.abs(ref - X0).max()
    for steps in (k, 10**12):                        # 10**12: the estimate is far too large
        Y, deg = chebyshev_steps(A, c, X0, G, 1.0, b, cu, ch, 1e-10, 200, steps=steps)
        assert Y is not None and deg >= 3
        assert np.abs(Y - ref).max() < 1e-8 * disp
