"""Multi-shift CG (linalg.multishift): its members against direct solves, the compiled seed against its
NumPy twin (NumpySeed), the low-rank fold against the full one, blocks replayed against one block, and
the true residuals of a block of solutions against dense products."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as sla

from shapeflow import accel
from shapeflow.linalg.multishift import multishift_cg, shifted_residuals


def grid_laplacian(m: int) -> sp.csr_matrix:
    """The 5-point Laplacian of an m × m grid with Dirichlet rows (SPD, condition ~m²)."""
    T = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(m, m))
    eye = sp.eye(m)
    A = (sp.kron(T, eye) + sp.kron(eye, T)).tocsr()
    A.indices = A.indices.astype(np.int32)
    A.indptr = A.indptr.astype(np.int32)
    return A


#: many shifts out of order (the low-rank fold applies), a repeated one, the hardest not first
SHIFTS = np.random.default_rng(7).permutation(np.r_[np.geomspace(0.004, 4.0, 40), 0.004])
HARDEST = np.flatnonzero(SHIFTS == 0.004)


def direct(A, B, shifts):
    n = A.shape[0]
    out = np.empty((B.shape[0], len(shifts), n))
    for i, s in enumerate(shifts):
        lu = sla.splu((A + s * sp.eye(n)).tocsc())
        for j in range(B.shape[0]):
            out[j, i] = lu.solve(B[j])
    return out


@pytest.fixture(scope="module")
def problem():
    A = grid_laplacian(60)                       # 3,600 unknowns
    rng = np.random.default_rng(3)
    B = rng.standard_normal((3, A.shape[0]))
    return A, B, direct(A, B, SHIFTS)


@pytest.mark.parametrize("kernels", ["off", "force"])
@pytest.mark.parametrize("low_rank", [True, False])
def test_members_match_direct_solves(problem, kernels, low_rank):
    A, B, ref = problem
    with accel.use(kernels=kernels):
        res = multishift_cg(A, B, SHIFTS, rtol=1e-8, low_rank=low_rank)
    assert res.converged.all()
    assert (max(res.ranks) > 0) == low_rank         # the factorisation ran where asked
    for i in range(SHIFTS.size):
        for j in range(3):
            x = ref[j, i]
            assert np.abs(res.X[j, i] - x).max() <= 1e-6 * np.abs(x).max(), (i, j)
    # the hardest shift took the most iterations, repeats took the same
    its = res.iterations[:, 0]
    assert its[HARDEST[0]] == its[HARDEST[1]] == its.max()


def test_compiled_seed_is_the_numpy_twin(problem):
    """Same formulas in the same order: the same iterations, iterates equal to rounding."""
    A, B, _ = problem
    with accel.use(kernels="off"):
        ref = multishift_cg(A, B[:2], SHIFTS, rtol=1e-8)
    with accel.use(kernels="force"):
        got = multishift_cg(A, B[:2], SHIFTS, rtol=1e-8)
    assert got.krylov_iterations == ref.krylov_iterations
    assert np.array_equal(got.iterations, ref.iterations)
    assert np.abs(got.X - ref.X).max() <= 1e-11 * np.abs(ref.X).max()


@pytest.mark.parametrize("kernels", ["off", "force"])
def test_replayed_blocks_equal_one_block(problem, kernels):
    """Residual blocks beyond the first are recomputed from saved states: the result does not change."""
    A, B, _ = problem
    with accel.use(kernels=kernels):
        one = multishift_cg(A, B, SHIFTS, rtol=1e-8)
        many = multishift_cg(A, B, SHIFTS, rtol=1e-8, block_bytes=8 * 3 * A.shape[0] * 23)
    assert one.flushes == 1 and many.flushes > 3 and many.replayed > 0
    assert np.abs(many.X - one.X).max() <= 1e-12 * np.abs(one.X).max()


def test_emit_hands_over_every_member_transformed(problem):
    """``emit`` with ``post=(scale, take)``: every shift once, as (scale · x)[take]."""
    A, B, _ = problem
    n = A.shape[0]
    rng = np.random.default_rng(4)
    scale, take = rng.uniform(0.5, 2.0, n), rng.permutation(n)
    full = multishift_cg(A, B, SHIFTS, rtol=1e-8)
    seen = np.zeros((3, SHIFTS.size, n))
    count = np.zeros(SHIFTS.size, int)

    def emit(shifts, rows):
        seen[:, shifts] = rows
        count[shifts] += 1

    res = multishift_cg(A, B, SHIFTS, rtol=1e-8, emit=emit, post=(scale, take))
    assert res.X is None and (count == 1).all()
    want = (full.X * scale)[:, :, take]
    assert np.abs(seen - want).max() <= 1e-12 * np.abs(want).max()


def test_shifted_residuals_are_the_dense_ones(problem):
    """‖b_j − (A + s_q I) y_qj‖ and ‖y_qj‖ of a block of (perturbed) solutions, against dense products
    column by column; the direct solutions leave residuals at rounding level."""
    A, B, ref = problem
    n, q = A.shape[0], 7
    rng = np.random.default_rng(5)
    Y = np.ascontiguousarray(ref[:, :q].transpose(2, 1, 0))             # (n, q, c)
    Y[:, 3] += 1e-6 * rng.standard_normal((n, 3))
    Ad = A.toarray()
    want = np.array([[np.linalg.norm(B[j] - (Ad + SHIFTS[i] * np.eye(n)) @ Y[:, i, j]) for j in range(3)]
                     for i in range(q)])
    ynorm = np.linalg.norm(Y, axis=0)
    res, got_norm = shifted_residuals(A, B, SHIFTS[:q], Y.copy())
    assert np.allclose(res, want, rtol=1e-10, atol=1e-13 * np.abs(B).max())
    assert np.allclose(got_norm, ynorm, rtol=1e-14)
    rel = res / np.linalg.norm(B, axis=1)
    assert (rel[3] > 1e-7).all() and (np.delete(rel, 3, axis=0) < 1e-12).all()
