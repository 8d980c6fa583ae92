"""The lean layout of the flow's interior system (:class:`PairMatrix`) against CSR and dense references."""

from __future__ import annotations

import numpy as np
import pytest
from meshgen import cube_sphere, grid, icosphere

import shapeflow as sf
from shapeflow import accel
from shapeflow.flow import FlowSolver, system
from shapeflow.linalg import PairMatrix, SPDSolver, spd


def random_pair_matrix(n=60, m=200, seed=0):
    rng = np.random.default_rng(seed)
    pairs = np.sort(rng.integers(0, n, (m, 2)), axis=1).astype(np.int32)
    pairs = pairs[pairs[:, 0] != pairs[:, 1]]
    w = rng.uniform(0.1, 1.0, pairs.shape[0])
    free = rng.random(n) < 0.8
    deg = np.bincount(pairs[:, 0], w, minlength=n) + np.bincount(pairs[:, 1], w, minlength=n)
    d = np.where(free, deg + rng.uniform(0.5, 1.0, n), 1.0)
    return pairs, w, free, d


def dense(pairs, w, free, d):
    """The matrix entry by entry, from its definition."""
    A = np.diag(d)
    both = free[pairs[:, 0]] & free[pairs[:, 1]]
    np.subtract.at(A, (pairs[both, 0], pairs[both, 1]), w[both])
    np.subtract.at(A, (pairs[both, 1], pairs[both, 0]), w[both])
    return A


def test_product_and_csr_equal_the_definition():
    pairs, w, free, d = random_pair_matrix()
    M = PairMatrix(pairs, w, free, d)
    A = dense(pairs, w, free, d)
    X = np.random.default_rng(1).standard_normal((d.size, 3))
    np.testing.assert_allclose(M @ X, A @ X, rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(M @ X[:, 0], A @ X[:, 0], rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(M.tocsr().toarray(), A, rtol=0, atol=1e-15)
    assert np.array_equal(M.diagonal(), np.diag(A))


@pytest.mark.parametrize("kernels", ["off", "force"])
def test_solver_on_pairs_meets_tolerance_and_falls_back(kernels):
    pairs, w, free, d = random_pair_matrix(seed=2)
    A = dense(pairs, w, free, d)
    B = np.random.default_rng(3).standard_normal((d.size, 3))
    exact = np.linalg.solve(A, B)
    with accel.use(kernels=kernels):
        X = SPDSolver(PairMatrix(pairs, w, free, d), "cg", rtol=1e-12).solve(B.copy())
        np.testing.assert_allclose(X, exact, rtol=1e-9, atol=1e-9)
        capped = SPDSolver(PairMatrix(pairs, w, free, d), "cg", rtol=1e-12, maxiter=2)
        X = capped.solve(B.copy(), overwrite_b=True)
        assert capped.stats.fallback and capped.method == "lu"
        np.testing.assert_allclose(X, exact, rtol=1e-10, atol=1e-10)


@pytest.mark.skipif(not accel.available(), reason="the lean layout needs the compiled kernels (numba)")
@pytest.mark.parametrize("make", [lambda: icosphere(3), lambda: cube_sphere(10, mix=0.4),
                                  lambda: grid(14, jitter=0.2, mix=0.5, z=lambda x, y: 0.1 * x * y)],
                         ids=["triangles", "hybrid", "open-hybrid"])
def test_lean_flow_equals_the_csr_flow(make, monkeypatch):
    """From LEAN_FROM vertices on, the flow solves on the operator's pairs: the same result to rounding,
    and no CSR pattern is ever built.  (The lean layout has Jacobi only: so has the CSR reference here.)"""
    monkeypatch.setattr(spd, "DEFAULT_PRECONDITIONER", "jacobi")
    mesh = make()
    rng = np.random.default_rng(0)
    kw = dict(lam_border=0.5, weights=rng.uniform(0.2, 1.0, mesh.n_vertices), solver="cg")
    with accel.use(kernels="force"):
        for lam in (1.0, -30.0):
            ref = sf.flow(mesh, lam, **kw)
            monkeypatch.setattr(system, "LEAN_FROM", 0)
            fresh = sf.Mesh.from_csr(mesh.vertices, mesh.face_sizes, mesh.face_indices)   # no cached pattern
            solver = FlowSolver(fresh, lam_border=0.5, weights=kw["weights"], solver="cg")
            lean = solver.run(lam)
            monkeypatch.setattr(system, "LEAN_FROM", 8_000_000)
            assert not solver.operator().pattern.csr_built
            scale = np.abs(ref.vertices - mesh.vertices).max()
            assert np.abs(lean.vertices - ref.vertices).max() <= 1e-9 * scale
            assert lean.report.cg_iterations == ref.report.cg_iterations
