"""The polynomial preconditioner that keeps shifted systems shifts of one operator
(linalg.shift_polynomial): the identity (A + δ) p_δ(A) = A p(A) + β_δ I on dense matrices, the
Chebyshev residual polynomial against its closed form, positivity, the spectrum estimate against
dense eigenvalues, and the compiled powers against SciPy's products."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from meshgen import grid_laplacian

from shapeflow import accel
from shapeflow.linalg.shift_polynomial import (
    chebyshev_residual_polynomial,
    shifted_polynomials,
    spectrum_upper_estimate,
)


def poly_matrix(coef, A):
    """Σ_j coef[j] A^j, dense, by repeated products (no Horner: an independent evaluation)."""
    out = np.zeros_like(A)
    P = np.eye(A.shape[0])
    for c in coef:
        out += c * P
        P = P @ A
    return out


def chebyshev(k, x):
    """T_k(x) for |x| ≥ 1 by cosh (and for |x| ≤ 1 by cos)."""
    x = np.asarray(x, dtype=np.float64)
    inside = np.abs(x) <= 1
    out = np.empty_like(x)
    out[inside] = np.cos(k * np.arccos(x[inside]))
    xo = x[~inside]
    out[~inside] = np.sign(xo) ** k * np.cosh(k * np.arccosh(np.abs(xo)))
    return out


@pytest.mark.parametrize("degree", [1, 2, 3, 4])
def test_residual_polynomial_is_chebyshevs(degree):
    lo, hi = 0.02, 2.0
    coef = chebyshev_residual_polynomial(degree, lo, hi)
    assert coef.shape == (degree + 1,)
    t = np.linspace(0.0, 3.0, 301)
    u = lambda s: (hi + lo - 2 * s) / (hi - lo)        # noqa: E731
    want = 1.0 - chebyshev(degree + 1, u(t)) / chebyshev(degree + 1, u(0.0))
    got = t * np.polyval(coef[::-1], t)
    assert np.allclose(got, want, rtol=1e-12, atol=1e-12)
    inside = (t >= lo) & (t <= hi)
    bound = 1.0 / chebyshev(degree + 1, np.array([u(0.0)]))[0]
    assert np.all(np.abs(got[inside] - 1.0) <= bound * (1 + 1e-12))
    if degree % 2 == 0:                     # even degree: positive for every t > 0, beyond hi too
        assert np.all(got[1:] > 0)


@pytest.mark.parametrize("degree", [1, 2, 3])
def test_shifted_polynomials_keep_the_systems_shifts_of_one_operator(degree):
    rng = np.random.default_rng(2)
    Q, _ = np.linalg.qr(rng.normal(size=(30, 30)))
    A = Q @ np.diag(np.geomspace(0.01, 2.0, 30)) @ Q.T
    coef = chebyshev_residual_polynomial(degree, 0.02, 2.1)
    deltas = np.array([0.0, 1e-4, 0.05, 0.3, 2.0])
    betas, pis = shifted_polynomials(coef, deltas)
    Bm = A @ poly_matrix(coef, A)
    assert betas[0] == 0.0 and np.all(np.diff(betas) > 0)
    for d, b, pi in zip(deltas, betas, pis):
        lhs = (A + d * np.eye(30)) @ poly_matrix(pi, A)
        assert np.allclose(lhs, Bm + b * np.eye(30), rtol=0, atol=1e-11 * np.abs(Bm).max())


def test_parameters_are_checked():
    with pytest.raises(ValueError, match="degree"):
        chebyshev_residual_polynomial(0, 0.1, 1.0)
    with pytest.raises(ValueError, match="lo"):
        chebyshev_residual_polynomial(2, 1.0, 0.5)
    with pytest.raises(ValueError, match="start vector"):
        spectrum_upper_estimate(sp.eye(5, format="csr"), 0.0, np.zeros(5))


def test_spectrum_estimate_is_near_the_largest_eigenvalue_from_above():
    A = grid_laplacian(30)
    rng = np.random.default_rng(1)
    lmax = np.linalg.eigvalsh(A.toarray())[-1] + 0.5
    est = spectrum_upper_estimate(A, 0.5, rng.normal(size=A.shape[0]))
    assert lmax <= est <= 1.1 * lmax
    # a start vector in an invariant subspace: the estimate is that subspace's eigenvalue, exactly
    est1 = spectrum_upper_estimate(sp.diags([1.0, 3.0, 7.0]).tocsr(), 0.0, np.array([0.0, 1.0, 0.0]))
    assert est1 == pytest.approx(3.0, rel=1e-14)


@pytest.mark.parametrize("kernels", ["off", "force"])
@pytest.mark.parametrize("degree", [1, 2, 3])
def test_shifted_powers_are_repeated_products(kernels, degree):
    """(scale · [Y, A₀Y, …])[take] against SciPy's products, in the given memory or not, with rows taken
    by a permutation (the compiled kernel scatters them), by an index that is not one (the reference
    gathers) and as they are; the input is left as it was."""
    A = grid_laplacian(40)
    n = A.shape[0]
    rng = np.random.default_rng(3)
    Y = rng.normal(size=(n, 7))
    Y0 = Y.copy()
    A0 = A + 0.3 * sp.eye(n)
    want = [Y0]
    for _ in range(degree):
        want.append(A0 @ want[-1])
    perm = rng.permutation(n)
    some = rng.integers(0, n, n)
    scale = rng.uniform(0.5, 2.0, n)
    with accel.use(kernels=kernels):
        kern = accel.kernels("linalg", n)
        for take in (None, perm, some):
            for sc in (None, scale):
                outs = [np.empty_like(Y) for _ in range(degree + 2)]
                for mem in (None, outs, outs[:2]):
                    got = kern.shifted_powers(A, 0.3, Y, degree, mem, take, sc)
                    assert len(got) == degree + 1 and got[0] is not Y
                    for g, w in zip(got, want):
                        w = w if sc is None else w * sc[:, None]
                        w = w if take is None else w[take]
                        assert np.allclose(g, w, rtol=1e-13, atol=1e-13 * np.abs(w).max())
                assert got[1] is outs[1] and got[0] is outs[0]
                assert np.array_equal(Y, Y0)


@pytest.mark.skipif(not accel.numba_available(), reason="the compiled kernels need numba")
def test_shifted_powers_give_the_same_bits_on_any_number_of_threads():
    """The compiled powers share the rows out between threads (10,000 rows: three blocks); each row is
    computed alone, so one thread and two give the same bits."""
    A = grid_laplacian(100)
    n = A.shape[0]
    rng = np.random.default_rng(5)
    Y = rng.normal(size=(n, 16))
    perm = rng.permutation(n)
    scale = rng.uniform(0.5, 2.0, n)
    got = {}
    for threads in (1, 2):
        with accel.use(kernels="force", threads=threads):
            powers = accel.heavy(accel.kernels("linalg", n).shifted_powers)      # (heavy: the threads applied)
            got[threads] = powers(A, 0.3, Y, 2, None, perm, scale)
    for one, two in zip(got[1], got[2]):
        assert np.array_equal(one, two)


@pytest.mark.parametrize("kernels", ["off", "force"])
def test_extend_writes_the_pieces_side_by_side_into_the_spare_slabs_while_they_last(kernels):
    """``SeedPolynomial.extend``: per column the pieces [W, A₀W, A₀²W] (scaled, rows taken) side by side
    in one array, in the first spare slab with room (first fit; new memory once none has), the left factor
    [π₀L, π₁L, π₂L] — the same values with or without spare memory, against SciPy's products."""
    import types

    from shapeflow.linalg.shift_polynomial import SeedPolynomial
    A = grid_laplacian(40)
    n, r, k, seed = A.shape[0], 8, 5, 0.3
    rng = np.random.default_rng(4)
    Ws = [rng.normal(size=(n, r)) for _ in range(3)]
    lefts = [rng.normal(size=(k, r)) for _ in range(3)]
    pis = rng.normal(size=(k, 3))
    perm, scale = rng.permutation(n), rng.uniform(0.5, 2.0, n)
    A0 = A + seed * sp.eye(n)
    poly = SeedPolynomial(A, types.SimpleNamespace(seed=seed), 2, np.array([1.0, 0.5, 0.1]), np.zeros(k), pis)
    # slab 0 holds one column's pieces and scratch (4 n r), slab 1 one more, slab 2 too small
    slabs = [np.full(4 * n * r + 5, np.nan), np.full(4 * n * r, np.nan), np.full(n * r - 1, np.nan)]
    got = {}
    with accel.use(kernels=kernels):
        for spare in (None, slabs):
            L, W = [x.copy() for x in lefts], [(x.copy(),) for x in Ws]
            poly.extend(L, W, pis, spare, (scale, perm))
            got[spare is None] = (L, W)
    for j in range(3):
        (wide,) = got[False][1][j]
        assert wide.shape == (n, 3 * r)
        assert np.shares_memory(wide, slabs[j]) if j < 2 else not any(np.shares_memory(wide, s) for s in slabs)
        want = [Ws[j]]
        for _ in range(2):
            want.append(A0 @ want[-1])
        want = np.hstack([(w * scale[:, None])[perm] for w in want])
        for spare_none in (True, False):
            assert np.allclose(got[spare_none][1][j][0], want, rtol=1e-13, atol=1e-13 * np.abs(want).max())
            assert np.array_equal(got[spare_none][0][j], np.hstack([pis[:, i:i + 1] * lefts[j] for i in range(3)]))
