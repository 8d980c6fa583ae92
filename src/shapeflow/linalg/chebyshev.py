"""Several steps of a fixed SPD operator as one Chebyshev expansion (Clenshaw recurrence)."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .. import accel

__all__ = ["chebyshev_coefficients", "chebyshev_steps"]


def chebyshev_coefficients(f, a: float, b: float, max_degree: int = 2048):
    """Chebyshev coefficients of ``f`` on [a, b] and their tail sums.

    ``f`` maps t (array) to values; returns ``c`` (f ≈ Σ c_j T_j(x), t = mid +
    half·x) and ``tail`` with tail[j] = Σ_{i>j} |c_i|, the uniform bound of the
    error left after the terms 0..j.  The degree doubles from 64 until the last
    coefficients are at rounding level; coefficients below 2e-14 × Σ|c| (the
    interpolation's noise) are set to zero, so the tail of a resolved function
    reaches 0.  A function not resolved at ``max_degree`` gets ``tail = inf``
    everywhere: no degree has a known bound, so no caller truncates it.
    """
    from numpy.polynomial import chebyshev

    mid, half = 0.5 * (a + b), 0.5 * (b - a)
    degree = 64
    while True:
        c = chebyshev.chebinterpolate(lambda x: f(mid + half * x), degree)
        scale = np.abs(c).sum()
        resolved = np.abs(c[-8:]).max() <= 2e-14 * scale
        if resolved or degree >= max_degree:
            break
        degree *= 2
    if not resolved:
        return c, np.full(c.size, np.inf)
    c[np.abs(c) < 2e-14 * scale] = 0.0
    ac = np.abs(c)
    tail = np.concatenate([np.cumsum(ac[::-1])[::-1][1:], [0.0]])
    return c, tail


def chebyshev_steps(A: sp.csr_matrix, c: np.ndarray, X0: np.ndarray, G: np.ndarray, a: float, b: float,
                    coef_u, coef_h, rtol: float, max_degree: int, steps: int = 1, overwrite_g: bool = False):
    """X = f_u(C⁻¹A) X0 + f_h(C⁻¹A) C⁻¹G by Clenshaw's recurrence on three columns.

    ``A`` is symmetric with ``A − C`` positive semi-definite on the rows where
    ``c`` > 0 (the others must be zero in X0 and G), so the spectrum of
    C⁻¹A (similar to the symmetric C^-½ A C^-½) lies in [a, b].  ``coef_u``,
    ``coef_h`` are (coefficients, tails) from :func:`chebyshev_coefficients`.

    With Ã = (2C⁻¹A − (a+b))/(b − a) and H0 = C⁻¹G, the sum
    Σ_j T_j(Ã)(cu_j X0 + ch_j H0) is evaluated backwards,
    B_j = 2ÃB_{j+1} − B_{j+2} + cu_j X0 + ch_j H0 and X = ÃB_1 − B_2 + cu_0 X0 + ch_0 H0:
    one sparse product of three columns per degree.  The degree N is fixed
    beforehand: the smallest for which the uniform bound of the terms left out,
    tail_u[N]·‖X0‖ + tail_h[N]·‖H0‖ (norms weighted by C, the symmetric
    form's), is below ``rtol`` × an estimate of the C-norm of X − X0: the size
    of one explicit step times √``steps`` (the number of flow steps the
    expansion stands for; k similar steps move about k times one step, so the
    estimate errs low, which costs a degree or two, not a second pass).  The
    bound is then checked against the X − X0 found; if the estimate was too
    large the sum is evaluated once more at the degree the check asks for.
    Returns (X, degree), or (None, degree) if more than ``max_degree`` is needed.
    ``overwrite_g``: G (n, 3) float64 C-contiguous may be reused as storage.
    """
    n = A.shape[0]
    cu, tu = coef_u
    ch, th = coef_h
    m = min(cu.size, ch.size, max_degree + 1)
    cinv = np.divide(1.0, c, out=np.zeros_like(c), where=c > 0)
    X0 = np.ascontiguousarray(X0, dtype=np.float64)
    kern = accel.kernels("linalg", n)
    if overwrite_g and G.dtype == np.float64 and G.flags.c_contiguous and G.shape == X0.shape:
        H0 = np.multiply(G, cinv[:, None], out=G)
    else:
        H0 = np.ascontiguousarray(G * cinv[:, None])

    def cnorm(Y):
        """The C-weighted norm of each column."""
        return kern.weighted_col_norms(A, c, Y)

    nu = cnorm(X0)
    nh = cnorm(H0)
    bounds = tu[:m, None] * nu + th[:m, None] * nh            # (m, 3): bound after degree j
    alpha, beta = 2.0 / (b - a), (a + b) / (b - a)

    def step(B1, B2, f, cuj, chj):
        """B2 <- f·Ã B1 − B2 + cuj X0 + chj H0, in place."""
        kern.clenshaw_step(A, cinv, B1, B2, X0, H0, f, alpha, beta, cuj, chj)

    def degree_for(target):
        ok = np.all(bounds <= target, axis=1)
        return int(np.argmax(ok)) if ok.any() else None

    def evaluate(N):
        B1 = cu[N] * X0 + ch[N] * H0      # B_N (B_{N+1} = 0)
        B2 = np.zeros_like(B1)            # B_{N+1}
        for j in range(N - 1, 0, -1):
            step(B1, B2, 2.0, cu[j], ch[j])
            B1, B2 = B2, B1
        step(B1, B2, 1.0, cu[0], ch[0])   # N >= 1: X = ÃB_1 − B_2 + c_0
        return B2

    # size of one explicit step, C-norm of C⁻¹(G − (A − C)X0) = H0 + X0 − C⁻¹A X0:
    # one step with f = −1/α (f·ÃX0 = −C⁻¹A X0 + (β/α) X0)
    E = np.zeros_like(X0)
    step(X0, E, -1.0 / alpha, 1.0 - beta / alpha, 1.0)
    d_est = cnorm(E) * np.sqrt(max(steps, 1))
    floor = 1e-15 * (nu + nh)
    N = degree_for(np.maximum(rtol * d_est, floor))
    tried = set()
    while N is not None and N not in tried:
        tried.add(N)
        Y = evaluate(max(N, 1))
        change = cnorm(np.subtract(Y, X0, out=E))   # E is free again: no new array
        if np.all(bounds[N] <= np.maximum(rtol * change, floor)):
            return Y, max(N, 1)
        N = degree_for(np.maximum(0.5 * rtol * change, floor))
    return None, m - 1
