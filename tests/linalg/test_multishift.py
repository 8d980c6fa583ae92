"""Multi-shift CG (linalg.multishift): its members against direct solves, the compiled seed against its
NumPy twin (NumpySeed), the low-rank fold against the full one, blocks replayed against one block, and
the true residuals of a block of solutions against dense products."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as sla
from meshgen import grid_laplacian

from shapeflow import accel
from shapeflow.linalg.multishift import multishift_cg, shifted_residuals

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
@pytest.mark.parametrize("degree", [0, 2])
def test_members_match_direct_solves(problem, kernels, low_rank, degree):
    A, B, ref = problem
    with accel.use(kernels=kernels):
        res = multishift_cg(A, B, SHIFTS, rtol=1e-8, low_rank=low_rank, degree=degree)
    assert res.converged.all() and res.degree == degree
    if degree == 0 or not low_rank:                 # (degree 2 on 41 shifts: full rank, see below)
        assert (max(res.ranks) > 0) == low_rank     # the factorisation ran where asked
    for i in range(SHIFTS.size):
        for j in range(3):
            x = ref[j, i]
            assert np.abs(res.X[j, i] - x).max() <= 1e-6 * np.abs(x).max(), (i, j)
    # the hardest shift took the most iterations, repeats took the same
    its = res.iterations[:, 0]
    assert its[HARDEST[0]] == its[HARDEST[1]] == its.max()


#: enough shifts that the factorisation pays with the polynomial preconditioner's shorter Krylov space
MANY = np.geomspace(0.004, 4.0, 80)


@pytest.mark.parametrize("kernels", ["off", "force"])
def test_low_rank_members_of_the_polynomial_preconditioner_match_direct_solves(problem, kernels):
    A, B, _ = problem
    with accel.use(kernels=kernels):
        res = multishift_cg(A, B, MANY, rtol=1e-8, degree=2)
    assert res.converged.all() and min(res.ranks) > 0
    some = np.arange(0, MANY.size, 9)
    ref = direct(A, B, MANY[some])
    for q, i in enumerate(some):
        for j in range(3):
            x = ref[j, q]
            assert np.abs(res.X[j, i] - x).max() <= 1e-6 * np.abs(x).max(), (i, j)


@pytest.mark.parametrize("degree", [0, 2])
def test_compiled_seed_is_the_numpy_twin(problem, degree):
    """Same formulas in the same order: the same iterations, iterates equal to rounding."""
    A, B, _ = problem
    with accel.use(kernels="off"):
        ref = multishift_cg(A, B[:2], SHIFTS, rtol=1e-8, degree=degree)
    with accel.use(kernels="force"):
        got = multishift_cg(A, B[:2], SHIFTS, rtol=1e-8, degree=degree)
    assert got.krylov_iterations == ref.krylov_iterations
    assert np.array_equal(got.iterations, ref.iterations)
    assert np.abs(got.X - ref.X).max() <= 1e-11 * np.abs(ref.X).max()


@pytest.mark.parametrize("kernels", ["off", "force"])
@pytest.mark.parametrize("degree", [0, 2])
def test_replayed_blocks_equal_one_block(problem, kernels, degree):
    """Residual blocks beyond the first are recomputed from saved states: the result does not change."""
    A, B, _ = problem
    with accel.use(kernels=kernels):
        one = multishift_cg(A, B, SHIFTS, rtol=1e-8, degree=degree)
        many = multishift_cg(A, B, SHIFTS, rtol=1e-8, degree=degree,
                             block_bytes=8 * 3 * A.shape[0] * (23 if degree == 0 else 9))
    assert one.flushes == 1 and many.flushes > 3 and many.replayed > 0
    assert np.abs(many.X - one.X).max() <= 1e-12 * np.abs(one.X).max()


@pytest.mark.parametrize("degree", [0, 2])
def test_emit_hands_over_every_member_transformed(problem, degree):
    """``emit`` with ``post=(scale, take)``: every shift once, as (scale · x)[take]; an ``emit`` with a
    ``factors`` method gets the low-rank factors, whose product is the same."""
    A, B, _ = problem
    n = A.shape[0]
    rng = np.random.default_rng(4)
    scale, take = rng.uniform(0.5, 2.0, n), rng.permutation(n)
    shifts = SHIFTS if degree == 0 else MANY
    full = multishift_cg(A, B, shifts, rtol=1e-8, degree=degree)
    seen = np.zeros((3, shifts.size, n))
    count = np.zeros(shifts.size, int)

    def emit(shifts, rows):
        seen[:, shifts] = rows
        count[shifts] += 1

    res = multishift_cg(A, B, shifts, rtol=1e-8, emit=emit, post=(scale, take), degree=degree)
    assert res.X is None and (count == 1).all()
    want = (full.X * scale)[:, :, take]
    assert np.abs(seen - want).max() <= 1e-12 * np.abs(want).max()

    class Receiver:
        def __call__(self, shifts, rows):
            raise AssertionError("rows handed over although every column was factorised")

        def factors(self, lefts, Ws):
            for j in range(3):
                seen[j] = (np.hstack(Ws[j]) @ lefts[j].T).T

    seen[:] = 0.0
    res = multishift_cg(A, B, shifts, rtol=1e-8, emit=Receiver(), post=(scale, take), degree=degree)
    assert min(res.ranks) > 0
    assert np.abs(seen - want).max() <= 1e-12 * np.abs(want).max()


def test_polynomial_preconditioner_cuts_the_iterations(problem):
    """Degree 2 (three products an iteration) against none on the grid's shifted systems: at most half
    the iterations (theory: about a third), the hardest shift still the last to converge."""
    A, B, _ = problem
    its = {d: multishift_cg(A, B, SHIFTS, rtol=1e-8, degree=d) for d in (0, 2)}
    assert its[2].krylov_iterations <= 0.5 * its[0].krylov_iterations
    assert its[2].iterations[HARDEST[0], 0] == its[2].iterations[:, 0].max()


def test_degree_must_be_a_non_negative_integer(problem):
    A, B, _ = problem
    for bad in (-1, 1.5):
        with pytest.raises(ValueError, match="degree"):
            multishift_cg(A, B, SHIFTS, degree=bad)


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


@pytest.mark.skipif(not accel.numba_available(), reason="the compiled kernels need numba")
@pytest.mark.parametrize("degree", [0, 2])
def test_compiled_seed_gives_the_same_bits_on_any_number_of_threads(degree):
    """The seed's passes share the rows out between threads by blocks whose sums are added in block
    order: one thread and two give the same iterations and the same solutions, bit for bit (10,000
    unknowns: three blocks, so two threads do split the rows)."""
    A = grid_laplacian(100)
    B = np.random.default_rng(4).standard_normal((3, A.shape[0]))
    runs = {}
    for threads in (1, 2):
        with accel.use(kernels="force", threads=threads):
            runs[threads] = multishift_cg(A, B, SHIFTS, rtol=1e-8, degree=degree)   # (a heavy entry point)
    one, two = runs[1], runs[2]
    assert one.krylov_iterations == two.krylov_iterations
    assert np.array_equal(one.iterations, two.iterations)
    assert np.array_equal(one.X, two.X)
    with accel.use(kernels="off"):
        ref = multishift_cg(A, B, SHIFTS, rtol=1e-8, degree=degree)
    assert one.krylov_iterations == ref.krylov_iterations
    assert np.abs(one.X - ref.X).max() <= 1e-11 * np.abs(ref.X).max()


class FactorSink:
    """An ``emit`` receiving the low-rank factors, with a ``scratch`` buffer of garbage (NaN) to offer."""

    def __init__(self, scratch_size: int | None):
        self.buf = None if scratch_size is None else np.full(scratch_size, np.nan)
        self.asked = []

    def __call__(self, shifts, rows):                  # (not called when every column has factors)
        raise AssertionError("rows were formed")

    def scratch(self, size):
        self.asked.append(size)
        return None if self.buf is None or size > self.buf.size else self.buf[:size]

    def factors(self, lefts, Ws):
        self.lefts, self.Ws = lefts, Ws


@pytest.mark.parametrize("kernels", ["off", "force"])
@pytest.mark.parametrize("scratch", [None, 10**7])
def test_factors_are_padded_to_a_multiple_of_eight_and_formed_in_the_receivers_scratch(problem, kernels, scratch):
    """With the polynomial preconditioner the factor's width is padded with zero columns to a multiple of
    ``RANK_MULTIPLE`` (its powers' loop then has no remainder); the ranks reported are the truncation's;
    the y's factor is formed in the receiver's ``scratch`` when it offers one (filled with NaN here: it
    must be zeroed first), and the members are the same either way, equal to direct solves."""
    from shapeflow.linalg.multishift import RANK_MULTIPLE
    A, B, _ = problem
    sink = FactorSink(scratch)
    with accel.use(kernels=kernels):
        res = multishift_cg(A, B, MANY, rtol=1e-8, degree=2, emit=sink)
    assert res.converged.all() and res.X is None
    n = A.shape[0]
    widths = [-(-r // RANK_MULTIPLE) * RANK_MULTIPLE for r in res.ranks]
    assert sink.asked == [n * sum(widths) + n * max(widths)]          # the factor, then the powers' scratch
    if scratch is not None:
        assert not np.isnan(sink.buf[:n * sum(widths)]).any()      # used (zeroed, then the factor)
    some = np.arange(0, MANY.size, 9)
    ref = direct(A, B, MANY[some])
    for j in range(3):
        r = res.ranks[j]
        width = -(-r // RANK_MULTIPLE) * RANK_MULTIPLE
        (wide,) = sink.Ws[j]
        assert wide.shape == (n, 3 * width) and sink.lefts[j].shape == (MANY.size, 3 * width)
        for piece in range(3):                      # the padded columns: zero in the left factor
            assert not sink.lefts[j][:, piece * width + r:(piece + 1) * width].any()
            assert sink.lefts[j][:, piece * width + r - 1].any()       # (the ranks reported are not padded)
        X = sink.lefts[j] @ wide.T
        for q, i in enumerate(some):
            x = ref[j, q]
            assert np.abs(X[i] - x).max() <= 1e-6 * np.abs(x).max(), (i, j)


def test_padded_factors_keep_the_product():
    from shapeflow.linalg.multishift import RANK_MULTIPLE, padded_factors
    rng = np.random.default_rng(5)
    for r in (1, 7, 8, 9, 15, 16):
        L, R = rng.normal(size=(11, r)), rng.normal(size=(30, r))
        Lp, Rp = padded_factors(L, R)
        assert Lp.shape[1] == Rp.shape[1] == -(-r // RANK_MULTIPLE) * RANK_MULTIPLE
        assert np.array_equal(Lp[:, :r], L) and np.array_equal(Rp[:, :r], R)
        assert np.array_equal(Lp @ Rp.T, L @ R.T)
