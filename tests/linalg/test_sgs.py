"""Symmetric Gauss–Seidel preconditioned CG (``SPDSolver(preconditioner=...)``, ``compiled.sgs_pcg3``).

References, made here: the exact solution (SciPy's SuperLU) and Jacobi-PCG on the same system.  The
systems are the flow's normalised step (1 + λ)D − λW built from cotangent weights, with some rows held
(identity rows), on triangle, quad and mixed meshes.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as sla
from meshgen import cube_sphere, grid, icosphere

import shapeflow as sf
from shapeflow import accel
from shapeflow.errors import ParameterError
from shapeflow.linalg import PairMatrix, SPDSolver

needs_kernels = pytest.mark.skipif(not accel.numba_available(), reason="the compiled kernels need numba")

MESHES = {
    "triangles": lambda: icosphere(3),
    "quads": lambda: cube_sphere(8),
    "mixed-open": lambda: grid(16, jitter=0.2, mix=0.5, z=lambda x, y: 0.05 * x * y),
}


def system(mesh: sf.Mesh, lam: float, held_every: int = 7):
    """(A, B, X0): the flow's step (1 + λ)D − λW for the vertex positions, every ``held_every``-th row
    held (identity row, its value on the right-hand side of its neighbours)."""
    W, _ = sf.cotan_weights(mesh)
    W = sp.csr_matrix(W)
    d = np.asarray(W.sum(axis=1)).ravel()
    n = mesh.n_vertices
    held = np.zeros(n, bool)
    held[::held_every] = True
    V = mesh.vertices
    A = (sp.diags((1.0 + lam) * d) - lam * W).tocsr()
    B = d[:, None] * V
    # held rows: identity; their columns move to the right-hand side of the free rows
    B = B - A[:, held] @ V[held]
    B[held] = V[held]
    keep = sp.diags((~held).astype(float))
    A = (keep @ A @ keep + sp.diags(held.astype(float))).tocsr()
    A.sort_indices()
    A.indices = A.indices.astype(np.int32)
    A.indptr = A.indptr.astype(np.int32)
    return A, np.ascontiguousarray(B), V.copy()


def solve(A, B, X0, *, kernels: str, preconditioner: str, **kw):
    with accel.use(kernels=kernels, min_size=0):
        s = SPDSolver(A, "cg", preconditioner=preconditioner, **kw)
        X = s.solve(B.copy(), X0)
    return X, s.stats


@needs_kernels
@pytest.mark.parametrize("lam", [1.0, 20.0])
@pytest.mark.parametrize("name", MESHES)
def test_kernel_equals_its_numpy_twin_and_meets_rtol(name, lam):
    A, B, X0 = system(MESHES[name](), lam)
    exact = sla.spsolve(A.tocsc(), B)
    disp = np.abs(exact - X0).max()
    fast, fs = solve(A, B, X0, kernels="force", preconditioner="sgs")
    slow, ss = solve(A, B, X0, kernels="off", preconditioner="sgs")
    assert fs.preconditioner == ss.preconditioner == "sgs"
    assert fs.iterations == ss.iterations                       # same formulas: same stopping step
    assert np.abs(fast - slow).max() <= 1e-11 * disp            # ... up to rounding
    assert np.abs(fast - exact).max() <= 1e-7 * disp            # rtol = 1e-8 on the residual
    jac, js = solve(A, B, X0, kernels="force", preconditioner="jacobi")
    assert js.preconditioner == "jacobi"
    assert np.abs(jac - exact).max() <= 1e-7 * disp
    assert fs.iterations < 0.7 * js.iterations, (fs.iterations, js.iterations)


@needs_kernels
def test_auto_takes_sgs_compiled_and_jacobi_with_numpy():
    A, B, X0 = system(MESHES["mixed-open"](), 1.0)
    assert solve(A, B, X0, kernels="force", preconditioner="auto")[1].preconditioner == "sgs"
    assert solve(A, B, X0, kernels="off", preconditioner="auto")[1].preconditioner == "jacobi"


@needs_kernels
def test_same_bits_on_any_number_of_threads_and_per_column():
    A, B, X0 = system(MESHES["quads"](), 5.0)
    with accel.use(threads=1):
        one, _ = solve(A, B, X0, kernels="force", preconditioner="sgs")
    with accel.use(threads=2):
        two, _ = solve(A, B, X0, kernels="force", preconditioner="sgs")
    assert np.array_equal(one, two)
    # the columns are independent: one column alone is solved as in the (n, 3) solve
    for k in range(3):
        col, _ = solve(A, np.ascontiguousarray(B[:, k]), X0[:, k].copy(), kernels="force", preconditioner="sgs")
        np.testing.assert_allclose(col, one[:, k], rtol=0, atol=1e-14 * np.abs(one).max())


@needs_kernels
def test_unsorted_columns():
    A, B, X0 = system(MESHES["triangles"](), 3.0)
    sorted_x, _ = solve(A, B, X0, kernels="force", preconditioner="sgs")
    # the same matrix with every row's entries reversed
    U = A.copy()
    for i in range(U.shape[0]):
        s, e = U.indptr[i], U.indptr[i + 1]
        U.indices[s:e] = U.indices[s:e][::-1].copy()
        U.data[s:e] = U.data[s:e][::-1].copy()
    U.has_sorted_indices = False
    x, st = solve(U, B, X0, kernels="force", preconditioner="sgs")      # asked for: on a sorted copy
    assert st.preconditioner == "sgs"
    np.testing.assert_allclose(x, sorted_x, rtol=0, atol=1e-14 * np.abs(sorted_x).max())
    U2 = A.copy()
    U2.indices[U2.indptr[5]:U2.indptr[6]] = U2.indices[U2.indptr[5]:U2.indptr[6]][::-1].copy()
    U2.data[U2.indptr[5]:U2.indptr[6]] = U2.data[U2.indptr[5]:U2.indptr[6]][::-1].copy()
    U2.has_sorted_indices = False
    assert solve(U2, B, X0, kernels="force", preconditioner="auto")[1].preconditioner == "jacobi"


@needs_kernels
@pytest.mark.parametrize("overwrite", [False, True])
def test_short_of_rtol_falls_back_to_lu(overwrite):
    """Two iterations cannot reach 1e-12: LU takes over, with B intact (rebuilt from r̂ = E⁻¹r)."""
    A, B, X0 = system(MESHES["mixed-open"](), 50.0)
    exact = sla.spsolve(A.tocsc(), B)
    with accel.use(kernels="force", min_size=0):
        s = SPDSolver(A, "cg", rtol=1e-12, maxiter=2, preconditioner="sgs")
        X = s.solve(B.copy(), X0, overwrite_b=overwrite)
    assert s.stats.fallback and s.method == "lu"
    np.testing.assert_allclose(X, exact, rtol=1e-9, atol=1e-9 * np.abs(exact).max())


def test_refusals():
    A, B, X0 = system(MESHES["triangles"](), 1.0)
    with pytest.raises(ParameterError, match="preconditioner"):
        SPDSolver(A, "cg", preconditioner="ilu")
    pairs = np.array([[0, 1]], np.int32)
    P = PairMatrix(pairs, np.array([0.5]), np.ones(2, bool), np.array([2.0, 2.0]))
    with pytest.raises(ParameterError, match="PairMatrix"):
        SPDSolver(P, "cg", preconditioner="sgs").solve(np.ones((2, 3)))
    Z = A.tolil()
    Z[3, 3] = 0.0
    Z = Z.tocsr()
    with pytest.raises(ParameterError, match="positive diagonal"):
        SPDSolver(Z, "cg", preconditioner="sgs").solve(B.copy(), X0)


@needs_kernels
def test_diagonal_positions_given_or_found_alike():
    """The operator pattern's diagonal positions spare the pass that finds them: same bits."""
    A, B, X0 = system(MESHES["quads"](), 2.0)
    rows = np.repeat(np.arange(A.shape[0]), np.diff(A.indptr))
    pos = np.flatnonzero(A.indices == rows)
    found, _ = solve(A, B, X0, kernels="force", preconditioner="sgs")
    given, st = solve(A, B, X0, kernels="force", preconditioner="sgs", diagonal_positions=pos)
    assert st.preconditioner == "sgs"
    assert np.array_equal(found, given)


@needs_kernels
def test_the_flow_report_names_the_preconditioner():
    m = cube_sphere(12)
    with accel.use(kernels="force"):
        fast = sf.flow(m, 2.0, solver="cg")
    with accel.use(kernels="off"):
        slow = sf.flow(m, 2.0, solver="cg")
    direct = sf.flow(m, 2.0, solver="lu")
    assert (fast.report.preconditioner, slow.report.preconditioner, direct.report.preconditioner) == \
        ("sgs", "jacobi", "")
    assert "(sgs)" in fast.report.summary() and "(jacobi)" in slow.report.summary()
    assert fast.report.cg_iterations[0] < slow.report.cg_iterations[0]
    disp = np.abs(direct.vertices - m.vertices).max()
    for r in (fast, slow):
        assert np.abs(r.vertices - direct.vertices).max() <= 1e-7 * disp
