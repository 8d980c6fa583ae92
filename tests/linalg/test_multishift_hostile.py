"""Multi-shift CG (linalg.multishift) on hostile inputs, compiled kernels forced and off: every solution
reported converged meets its true residual (10 × rtol ‖b‖, checked here by sparse products), a column
whose seed breaks down is reported unconverged, bad arguments raise ParameterError naming them, and the
polynomial preconditioner neither overflows nor loses the tolerance to rounding at any scale or degree."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from meshgen import grid_laplacian

from shapeflow import accel
from shapeflow.errors import ParameterError
from shapeflow.linalg.multishift import multishift_cg


def lam_min(m: int) -> float:
    return 4.0 - 4.0 * np.cos(np.pi / (m + 1))


def claimed_residuals_hold(A, B, shifts, res, rtol):
    """Every (shift, column) reported converged meets ‖b − (A + s)x‖ ≤ 10 rtol ‖b‖; all values finite."""
    assert np.isfinite(res.X).all()
    for i, s in enumerate(shifts):
        for j in range(B.shape[0]):
            if res.converged[i, j]:
                x = res.X[j, i]
                r = np.linalg.norm(B[j] - A @ x - s * x)
                assert r <= 10 * rtol * np.linalg.norm(B[j]), (i, s, j, r)


def solved(A, columns: int, seed: int, shifts, kernels: str, **kw):
    """multishift_cg on ``columns`` random right-hand sides (rtol 1e-8) with the kernels given: its result,
    every solution it reports converged checked by :func:`claimed_residuals_hold`."""
    B = np.random.default_rng(seed).standard_normal((columns, A.shape[0]))
    with accel.use(kernels=kernels):
        res = multishift_cg(A, B, shifts, rtol=1e-8, **kw)
    claimed_residuals_hold(A, B, shifts, res, 1e-8)
    return res


@pytest.mark.parametrize("kernels", ["off", "force"])
@pytest.mark.parametrize("degree", [0, 2])
def test_hundreds_of_shifts_whose_recurrences_vanish(kernels, degree):
    # far-apart shifts: ζ of the largest underflows to 0, and the next ζ is 0 / 0 (NaN in NumPy: that
    # shift stops updating); the compiled seed must do the same, not raise ZeroDivisionError
    A = grid_laplacian(30)
    shifts = np.geomspace(1e-3, 1e3, 500)
    res = solved(A, 3, 1, shifts, kernels, degree=degree)
    assert res.converged.all()


@pytest.mark.parametrize("kernels", ["off", "force"])
@pytest.mark.parametrize("degree", [0, 1, 3])
def test_a_seed_that_breaks_down_is_not_converged(kernels, degree):
    # A − I is indefinite (λ_min(A) ≈ 0.044): CG on it meets pᵀAp ≤ 0 and stops without meeting rtol
    m = 20
    A = grid_laplacian(m)
    shifts = np.r_[-1.0, 0.0, np.geomspace(0.01, 10, 8)]
    res = solved(A, 3, 2, shifts, kernels, degree=degree)
    assert not res.converged[0].any()
    assert (res.iterations[~res.converged] == -1).all()


@pytest.mark.parametrize("kernels", ["off", "force"])
def test_a_singular_seed_is_not_converged(kernels):
    A = sp.csr_matrix((5, 5))                   # the zero matrix: A + 0 I is singular
    B = np.ones((1, 5))
    with accel.use(kernels=kernels):
        res = multishift_cg(A, B, [0.0, 2.0], rtol=1e-8)
    assert not res.converged.any()


@pytest.mark.parametrize("kernels", ["off", "force"])
def test_bad_arguments_raise_parameter_errors_naming_them(kernels):
    A = grid_laplacian(20)
    n = A.shape[0]
    B = np.random.default_rng(3).standard_normal((3, n))
    nan_b = B.copy()
    nan_b[1, 7] = np.nan
    inf_b = B.copy()
    inf_b[0, 0] = np.inf
    cases = [
        ("A", dict(B=B[:, :-5])),               # A larger than B's columns (the compiled seed would run off them)
        ("A", dict(A=grid_laplacian(19))),      # A smaller
        ("B", dict(B=nan_b)),
        ("B", dict(B=inf_b)),
        ("maxiter", dict(maxiter=-3)),
        ("maxiter", dict(maxiter=2.5)),
        ("rtol", dict(rtol=0.0)),
        ("rtol", dict(rtol=-0.5)),
        ("rtol", dict(rtol=np.nan)),
        ("rtol", dict(rtol=1.0)),
        ("degree", dict(degree=None)),
        ("degree", dict(degree=np.nan)),
        ("degree", dict(degree=True)),
        ("degree", dict(degree=-1)),
    ]
    for name, kw in cases:
        args = dict(A=A, B=B, shifts=np.geomspace(0.01, 1, 5)) | kw
        with accel.use(kernels=kernels), pytest.raises(ParameterError, match=name):
            multishift_cg(args.pop("A"), args.pop("B"), args.pop("shifts"), **args)


@pytest.mark.parametrize("kernels", ["off", "force"])
@pytest.mark.parametrize("degree", [0, 2])
def test_more_than_three_columns(kernels, degree):
    A = grid_laplacian(20)
    shifts = np.geomspace(0.01, 10, 12)
    res = solved(A, 5, 4, shifts, kernels, degree=degree)
    assert res.converged.all() and res.X.shape == (5, 12, A.shape[0])


@pytest.mark.parametrize("kernels", ["off", "force"])
@pytest.mark.parametrize("scale", [1e-200, 1e-100, 1e100, 1e200])
def test_polynomial_at_any_scale(kernels, scale):
    # the monomial coefficients of p scale as hi^(−j−1): at 1e±200 they leave double precision (the
    # Lanczos estimate's squares too), and the solve goes on without the polynomial
    m = 20
    A = grid_laplacian(m) * scale
    shifts = np.geomspace(0.01, 10, 12) * scale
    res = solved(A, 3, 5, shifts, kernels, degree=2)
    assert res.converged.all()


@pytest.mark.parametrize("kernels", ["off", "force"])
def test_polynomial_with_a_huge_shift(kernels):
    # β_δ = δ p(−δ) grows as δ^(d+1): 1e300³ overflows
    A = grid_laplacian(20)
    shifts = np.array([1e-9, 1.0, 1e6, 1e12, 1e300])
    res = solved(A, 3, 6, shifts, kernels, degree=2)
    assert res.converged.all()


@pytest.mark.parametrize("kernels", ["off", "force"])
@pytest.mark.parametrize("degree", [16, 24, 40])
def test_high_degrees_keep_the_tolerance(kernels, degree):
    # Horner's scheme on the monomial form amplifies rounding by Σ|p_j| hi^(j+1) (~4e11 at degree 16
    # with lo = hi/100): beyond rtol / ε the products are too inexact for the tolerance
    A = grid_laplacian(20)
    shifts = np.geomspace(0.01, 10, 12)
    res = solved(A, 3, 7, shifts, kernels, degree=degree)
    assert res.converged.all() and 1 <= res.degree < degree


@pytest.mark.parametrize("kernels", ["off", "force"])
@pytest.mark.parametrize("degree", [0, 2])
@pytest.mark.parametrize("factors", [False, True])
def test_post_takes_any_rows(kernels, degree, factors):
    # take a subset, repeats and negative indices (not a permutation): the rows (scale · x)[take], as
    # NumPy forms them from the solutions collected in X
    A = grid_laplacian(30)
    n = A.shape[0]
    rng = np.random.default_rng(8)
    B = rng.standard_normal((3, n))
    shifts = np.geomspace(0.01, 10, 6)
    scale = rng.uniform(0.5, 2.0, n)
    with accel.use(kernels=kernels):
        ref = multishift_cg(A, B, shifts, rtol=1e-10, degree=degree)
        for take in (np.arange(0, n, 3), rng.integers(-n, n, 2 * n), np.zeros(0, np.int64)):
            got = {}

            class Receiver:
                def __call__(self, idx, rows):
                    for q, i in enumerate(idx):
                        got[int(i)] = rows[:, q].copy()

            if factors:
                def whole(self, lefts, Ws):
                    for i in range(shifts.size):
                        got[i] = np.stack([lefts[j][i] @ np.concatenate(Ws[j], axis=1).T for j in range(3)])
                Receiver.factors = whole
            multishift_cg(A, B, shifts, rtol=1e-10, degree=degree, emit=Receiver(), post=(scale, take))
            whole_x = multishift_cg(A, B, shifts, rtol=1e-10, degree=degree, post=(scale, take)).X
            want = (ref.X * scale)[:, :, take]
            assert sorted(got) == list(range(shifts.size)) and whole_x.shape == want.shape
            for i in range(shifts.size):
                assert np.allclose(got[i], want[:, i], rtol=1e-9, atol=1e-9 * np.abs(want).max(initial=1.0))
                assert np.allclose(whole_x[:, i], want[:, i], rtol=1e-9, atol=1e-9 * np.abs(want).max(initial=1.0))


def test_bad_post_raises_parameter_errors():
    A = grid_laplacian(10)
    B = np.ones((1, A.shape[0]))
    for post in ((np.ones(7), None), (np.full(100, np.nan), None), (None, np.array([0, 100])),
                 (None, np.array([0.5, 1.0])), (None, np.ones((2, 2), int))):
        with pytest.raises(ParameterError, match="post"):
            multishift_cg(A, B, [0.1, 1.0], post=post)


# --------------------------------------------------------------------------
# the compiled seed on any number of threads (its passes share the rows out by blocks of
# linalg.compiled.BLOCK = 4,096 rows whose sums are added in block order)
# --------------------------------------------------------------------------

needs_numba = pytest.mark.skipif(not accel.numba_available(), reason="the compiled kernels need numba")


def path_laplacian(n: int) -> sp.csr_matrix:
    """The 1-D Laplacian of n unknowns with Dirichlet ends (int32 CSR): SPD, eigenvalues in (0, 4)."""
    A = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(n, n)).tocsr()
    A.indices = A.indices.astype(np.int32)
    A.indptr = A.indptr.astype(np.int32)
    return A


def on_threads(threads, fn, *args, **kw):
    """``fn`` under the compiled kernels with ``threads`` (through accel.heavy: the count reaches numba)."""
    with accel.use(kernels="force", threads=threads):
        return accel.heavy(fn)(*args, **kw)


@needs_numba
@pytest.mark.parametrize("n", [1, 2, 3, 4095, 4096, 4097, 8192, 8193, 20000])
@pytest.mark.parametrize("degree", [0, 2])
def test_the_same_bits_on_any_number_of_threads_at_every_block_boundary(n, degree):
    # fewer rows than threads, one block exactly, one row over, two blocks, two and one row, five;
    # 3 and 4 threads ask for more than the machine may have (NUMBA_NUM_THREADS caps them)
    A = path_laplacian(n)
    B = np.random.default_rng(n).standard_normal((3, n))
    shifts = np.r_[np.geomspace(0.05, 5.0, 6), 0.05]               # (a repeat)
    runs = [on_threads(t, multishift_cg, A, B, shifts, rtol=1e-9, degree=degree) for t in (1, 2, 3, 4)]
    for other in runs[1:]:
        assert other.krylov_iterations == runs[0].krylov_iterations
        assert np.array_equal(other.iterations, runs[0].iterations) and np.array_equal(other.X, runs[0].X)
    assert runs[0].converged.all()
    claimed_residuals_hold(A, B, shifts, runs[0], 1e-9)
    with accel.use(kernels="off"):
        ref = multishift_cg(A, B, shifts, rtol=1e-9, degree=degree)
    assert np.abs(runs[0].X - ref.X).max() <= 1e-10 * np.abs(ref.X).max()


class ResidualSpy:
    """The seed residuals the fold reads, block after block (``multishift.gemm`` with ``low_rank`` off is
    called per block and per column, the block's residuals (t1 − t0, n) its second argument), per column
    in iteration order."""

    def __init__(self, monkeypatch, columns: int):
        import shapeflow.linalg.multishift as ms

        self.columns, self.calls = columns, []
        real = ms.gemm

        def gemm(a, b, out, accumulate, **kw):
            self.calls.append(np.array(b))
            return real(a, b, out, accumulate, **kw)

        monkeypatch.setattr(ms, "gemm", gemm)

    def take(self) -> list[np.ndarray]:
        seqs = [np.concatenate(self.calls[j::self.columns]) for j in range(self.columns)]
        self.calls = []
        return seqs


@needs_numba
@pytest.mark.parametrize("degree", [0, 2])
def test_replayed_blocks_are_the_first_pass_bits_on_any_number_of_threads(monkeypatch, degree):
    # 10,000 unknowns (three blocks of rows: two threads split them); a block of residuals small enough
    # that the fold replays the seed from saved states several times
    A = grid_laplacian(100)
    B = np.random.default_rng(11).standard_normal((3, A.shape[0]))
    shifts = np.geomspace(0.01, 4.0, 12)
    small = 8 * 3 * A.shape[0] * (17 if degree == 0 else 7)
    spy = ResidualSpy(monkeypatch, 3)
    runs, seqs = {}, {}
    for threads in (1, 2):
        for bb in (None, small):
            kw = {} if bb is None else {"block_bytes": bb}
            runs[threads, bb] = on_threads(threads, multishift_cg, A, B, shifts, rtol=1e-8, degree=degree,
                                           low_rank=False, **kw)
            seqs[threads, bb] = spy.take()
    assert runs[1, None].flushes == 1 and runs[1, small].flushes > 3 and runs[2, small].replayed > 0
    assert seqs[1, None][0].shape == (runs[1, None].krylov_iterations, A.shape[0])      # r_0 … r_{m−1}
    for key in runs:                       # every residual the fold read: the first pass's, bit for bit
        assert all(np.array_equal(a, b) for a, b in zip(seqs[key], seqs[1, None], strict=True)), key
    for bb in (None, small):
        assert np.array_equal(runs[1, bb].X, runs[2, bb].X)
    assert np.abs(runs[2, small].X - runs[2, None].X).max() <= 1e-12 * np.abs(runs[2, None].X).max()


@needs_numba
@pytest.mark.parametrize("degree", [0, 2])
def test_many_columns_on_two_threads(degree):
    # more than the compiled seed's three columns: the reference seed runs them, the factor's powers
    # (degree 2) stay compiled and share their rows out
    A = grid_laplacian(95)                      # 9,025 unknowns: three blocks
    B = np.random.default_rng(12).standard_normal((5, A.shape[0]))
    shifts = np.geomspace(0.01, 4.0, 40)
    one, two = (on_threads(t, multishift_cg, A, B, shifts, rtol=1e-8, degree=degree) for t in (1, 2))
    assert np.array_equal(one.X, two.X) and two.converged.all()
    claimed_residuals_hold(A, B, shifts, two, 1e-8)


@needs_numba
@pytest.mark.parametrize("degree", [0, 2])
def test_multishift_cg_called_directly_takes_the_callers_threads(monkeypatch, degree):
    # a public entry point: accel.use(threads=...) reaches its compiled seed and powers without a
    # heavy caller around it, and the caller's numba setting comes back afterwards
    import numba

    import shapeflow.linalg.compiled_shift as cs

    seen = []
    real = cs.get_num_threads
    monkeypatch.setattr(cs, "get_num_threads", lambda: seen.append(real()) or seen[-1])
    A = grid_laplacian(100)
    B = np.random.default_rng(13).standard_normal((3, A.shape[0]))
    before = numba.get_num_threads()
    for threads in sorted({1, min(2, numba.config.NUMBA_NUM_THREADS)}):
        seen.clear()
        with accel.use(kernels="force", threads=threads):
            multishift_cg(A, B, np.geomspace(0.01, 4.0, 12), rtol=1e-8, degree=degree)
        assert seen and set(seen) == {threads}
        assert numba.get_num_threads() == before


def random_spd_csr(n: int, seed: int) -> sp.csr_matrix:
    """A symmetric int32 CSR matrix of n rows with 1 to ~20 entries a row and random values."""
    rng = np.random.default_rng(seed)
    rows = np.repeat(np.arange(n), rng.integers(0, 10, n))
    cols = rng.integers(0, n, rows.size)
    M = sp.coo_matrix((rng.standard_normal(rows.size), (rows, cols)), shape=(n, n))
    A = (M + M.T + sp.diags(rng.uniform(1.0, 2.0, n))).tocsr()
    A.sum_duplicates()
    A.indices, A.indptr = A.indices.astype(np.int32), A.indptr.astype(np.int32)
    return A


@needs_numba
@pytest.mark.parametrize("n", [5, 4095, 4097, 8193, 12289])
def test_the_seeds_fused_passes_give_the_same_bits_on_any_number_of_threads(n):
    # the seed's kernels fuse multiply-adds (fastmath "contract"): their parallel build (2–4 threads, or
    # one when the rows are fewer than a block) and the one-thread loops must fuse the same operations;
    # five replayed iterations (products, residuals, directions; with and without the polynomial) on
    # random rows of 1 to ~20 entries and random values, so that any difference in rounding shows
    import numba

    import shapeflow.linalg.compiled_shift as cs

    A = random_spd_csr(n, n)
    rng = np.random.default_rng(1)
    X = rng.standard_normal((n, 3))
    sa, sb = rng.uniform(0.01, 0.1, (6, 3)), rng.uniform(0.1, 0.5, (6, 3))
    before = numba.get_num_threads()
    runs = []
    try:
        for coef in (np.zeros(0), rng.standard_normal(3)):      # A₀ alone, and a degree-2 polynomial of it
            for nt in (1, 2, 3, 4):
                numba.set_num_threads(min(nt, numba.config.NUMBA_NUM_THREADS))
                P, R, AP, T, U, Rb = X.copy(), X[::-1].copy(), *(np.empty((n, 3)) for _ in range(3)), \
                    np.empty((3, 6, n))
                cs.replay(A.indptr, A.indices, A.data, 0.37, coef, P, AP, T, U, R, Rb, sa, sb, 0, 6, nt)
                runs.append((nt, [P, R, AP, Rb]))
    finally:
        numba.set_num_threads(before)
    for i, (nt, run) in enumerate(runs):
        first = runs[i - i % 4][1]
        assert all(np.array_equal(a, b) for a, b in zip(first, run, strict=True)), nt


# --------------------------------------------------------------------------
# the memory the solve lends its receiver (emit.scratch) and hands over (emit.spare)
# --------------------------------------------------------------------------

@pytest.mark.parametrize("kernels", ["off", "force"])
@pytest.mark.parametrize("degree", [0, 2])
@pytest.mark.parametrize("columns", [1, 3])
@pytest.mark.parametrize("block_bytes", [1, 2 ** 27], ids=["replayed", "one-block"])
@pytest.mark.parametrize("take", [None, "permutation", "repeats"])
def test_the_receivers_scratch_and_the_spare_buffers_are_free_when_lent(kernels, degree, columns, block_bytes, take):
    # A receiver that takes the factors owns its scratch once ``factors`` is called and the buffers handed
    # to ``spare`` once they arrive: both filled with NaN there (as the family writes its members over the
    # scratch and its true-residual check over the spare buffers), the solutions formed from the factors
    # are those multishift_cg collects in X; the pieces never share memory, the spare buffers are one per
    # column, disjoint, and come after the factors.
    A = grid_laplacian(50)
    n = A.shape[0]
    rng = np.random.default_rng(11)
    B = rng.standard_normal((columns, n))
    shifts = np.geomspace(0.01, 10, 80)                         # (every column factorised)
    post = (rng.uniform(0.5, 2.0, n), {None: None, "permutation": rng.permutation(n),
                                       "repeats": rng.integers(0, n, n + 5)}[take])
    calls = []

    class Receiver:
        def __init__(self):
            self.buf = np.full(shifts.size * n * 3, np.nan)     # the family's (k, n, 3) result
            self.rows = {}

        def scratch(self, size):
            calls.append("scratch")
            return self.buf[:size] if size <= self.buf.size else None

        def factors(self, lefts, Ws):
            calls.append("factors")
            self.buf[:] = np.nan
            pieces = [P for W in Ws for P in W]
            assert not any(np.shares_memory(P, Q) for i, P in enumerate(pieces) for Q in pieces[i + 1:])
            self.X = np.stack([lefts[j] @ np.concatenate(Ws[j], axis=1).T for j in range(columns)])

        def spare(self, buffers):
            calls.append("spare")
            assert len(buffers) == columns and not any(np.shares_memory(b, self.buf) for b in buffers)
            assert not any(np.shares_memory(a, b) for i, a in enumerate(buffers) for b in buffers[i + 1:])
            for b in buffers:
                b[:] = np.nan

        def __call__(self, idx, rows):
            for q, i in enumerate(idx):
                self.rows[int(i)] = rows[:, q].copy()

    with accel.use(kernels=kernels):
        want = multishift_cg(A, B, shifts, rtol=1e-10, degree=degree, post=post, block_bytes=block_bytes).X
        rec = Receiver()
        res = multishift_cg(A, B, shifts, rtol=1e-10, degree=degree, post=post, block_bytes=block_bytes, emit=rec)
    assert res.converged.all() and min(res.ranks) > 0 and (res.flushes > 1) == (block_bytes == 1)
    assert calls[-2:] == ["factors", "spare"] and calls.count("factors") == 1
    got = rec.X if not rec.rows else np.stack([rec.rows[i] for i in range(shifts.size)], axis=1)
    assert np.isfinite(got).all()
    assert np.allclose(got, want, rtol=1e-10, atol=1e-12 * np.abs(want).max())
