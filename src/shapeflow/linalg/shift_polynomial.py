"""A polynomial preconditioner that keeps a family of shifted systems shifts of one operator.

For ``(A + δ I) x = b`` over many δ ≥ 0 (A symmetric positive definite), a polynomial p of degree d
gives the operator ``B = A p(A)`` and, for every δ, the polynomial
``p_δ(t) = (t p(t) + β_δ) / (t + δ)`` with ``β_δ = δ p(−δ)``: the division is exact (the numerator
vanishes at t = −δ), so ``(A + δ I) p_δ(A) = B + β_δ I`` (Ahmad, Szyld and van Gijzen 2017).  Each
system becomes ``(B + β_δ I) y = b`` with ``x = p_δ(A) y``: shifts of the one operator B, solvable from
one Krylov space (:func:`~shapeflow.linalg.multishift.multishift_cg`), and the residual of y in its
system *is* the residual of x in the original one.  B's condition number is about that of A divided
by (d + 1)², so CG needs about d + 1 times fewer iterations (each with d + 1 products).

p is the Chebyshev one on an interval [lo, hi]: ``t p(t) = 1 − T_{d+1}(u(t)) / T_{d+1}(u(0))`` with
``u(t) = (hi + lo − 2t) / (hi − lo)``.  For even d, t p(t) > 0 for every t > 0 (beyond hi too), so B is
positive definite whatever the estimate of A's spectrum; β_δ = T_{d+1}(u(−δ)) / T_{d+1}(u(0)) − 1 > 0
grows with δ.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import scipy.linalg

from .. import accel
from ..errors import ParameterError
from .blas import SingleThreadBLAS
from .spare import Spare

if TYPE_CHECKING:
    from .multishift import ShiftedSystems

__all__ = ["chebyshev_residual_polynomial", "shifted_polynomials", "spectrum_upper_estimate",
           "LOWER_FRACTION", "LANCZOS_STEPS", "SeedPolynomial"]

#: the interval's lower end as a fraction of its upper one (the systems' smallest eigenvalue is not
#: estimated: on the seed system of figure 1's 48 members on Suzanne ×3, μ_min/μ_max ≈ 0.002, degree 2
#: took 92, 70, 69, 69, 70 and 73 iterations with the fractions 0.001, 0.002, 0.005, 0.01, 0.02 and
#: 0.05, 2026-11-26; 209 without the preconditioner)
LOWER_FRACTION = 0.01

#: Lanczos steps of :func:`spectrum_upper_estimate`: with 12 the shared CG of figure 1's 48 members took 69 and
#: 70 iterations on Suzanne ×3 and ×4, as with 16; with 8, 70 and 71 (2026-11-26)
LANCZOS_STEPS = 12


def chebyshev_residual_polynomial(degree: int, lo: float, hi: float) -> np.ndarray:
    """Monomial coefficients ``(p_0, …, p_d)`` of the degree-``degree`` p with
    ``t p(t) = 1 − T_{d+1}(u(t)) / T_{d+1}(u(0))``, ``u(t) = (hi + lo − 2t) / (hi − lo)``."""
    from numpy.polynomial import Chebyshev, Polynomial

    if degree < 1 or int(degree) != degree:
        raise ParameterError(f"degree must be a positive integer, got {degree!r}")
    if not (0.0 < lo < hi and np.isfinite(hi)):
        raise ParameterError(f"the interval must satisfy 0 < lo < hi, got lo={lo!r}, hi={hi!r}")
    T = Chebyshev.basis(int(degree) + 1, domain=[lo, hi]).convert(kind=Polynomial)   # T_{d+1}(−u(t)) in t
    q = T.coef / T(0.0)                   # (the sign (−1)^{d+1} cancels in the ratio)
    tp = -q
    tp[0] += 1.0                          # t p(t) = 1 − q(t): no constant term
    return np.ascontiguousarray(tp[1:])


def shifted_polynomials(coef: np.ndarray, deltas: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``β_δ = δ p(−δ)`` (k,) and the monomial coefficients (k, d + 1) of ``p_δ(t) = (t p(t) + β_δ)/(t + δ)``
    for each δ of ``deltas`` (synthetic division by t + δ, exact: its remainder is zero)."""
    coef = np.asarray(coef, dtype=np.float64)
    deltas = np.asarray(deltas, dtype=np.float64)
    d = coef.size - 1
    # t p(t) + β: coefficients n_0 = β, n_{j+1} = p_j; p(−δ) by Horner
    p_at = np.zeros_like(deltas)
    for j in range(d, -1, -1):                          # (over the degree: d + 1 steps)
        p_at = p_at * -deltas + coef[j]
    betas = deltas * p_at
    out = np.empty((deltas.size, d + 1))
    out[:, d] = coef[d]
    for i in range(d, 0, -1):                           # q_{i−1} = n_i − δ q_i
        out[:, i - 1] = coef[i - 1] - deltas * out[:, i]
    return betas, out


def spectrum_upper_estimate(A, seed: float, v: np.ndarray, steps: int = LANCZOS_STEPS) -> float:
    """An estimate from above of the largest eigenvalue of ``A + seed I`` (symmetric): ``steps`` Lanczos
    steps from ``v``, the largest Ritz value plus its residual norm (the distance within which an
    eigenvalue lies).  Not a bound in every case; :func:`chebyshev_residual_polynomial` of even degree
    stays positive definite when it falls short."""
    def dot(x, y):              # (einsum, not BLAS: a threaded BLAS's workers would spin beside the solve)
        return float(np.einsum("i,i->", x, y))

    def norm(x):                # (scaled by its largest entry: no overflow of the squares)
        m = float(np.max(np.abs(x), initial=0.0))
        return m * np.sqrt(dot(x / m, x / m)) if 0.0 < m < np.inf else m

    q = np.asarray(v, dtype=np.float64)
    nq = norm(q)
    if not (nq > 0 and np.isfinite(nq)):
        raise ParameterError("the start vector of the spectrum estimate must be finite and non-zero")
    q = q / nq
    q_prev = np.zeros_like(q)
    alphas, betas = [], []
    beta = 0.0
    for _ in range(int(steps)):                         # (over the steps: a few products)
        w = A @ q + seed * q - beta * q_prev
        a = dot(q, w)
        w -= a * q
        beta = norm(w)
        alphas.append(a)
        betas.append(beta)
        if not beta > 1e-12 * max(abs(a), 1e-300):      # an invariant subspace: the Ritz values are exact
            break
        q_prev, q = q, w / beta
    alphas, betas = np.array(alphas), np.array(betas)
    size = float(np.max(np.abs(np.r_[alphas, betas])))
    size = size if 0.0 < size < np.inf else 1.0        # (LAPACK's bisection squares the entries)
    with SingleThreadBLAS():
        ev, U = scipy.linalg.eigh_tridiagonal(alphas / size, betas[:-1] / size, select="i",
                                              select_range=(len(alphas) - 1, len(alphas) - 1))
    return float(size * (ev[-1] + abs(betas[-1] / size * U[-1, -1])))


class SeedPolynomial:
    """The polynomial preconditioner of :func:`~shapeflow.linalg.multishift.multishift_cg` (``degree``) on
    ``A₀ = A + seed I``: its coefficients ``coef`` (p_0 … p_d), the shifts of B = A₀ p(A₀) written into
    ``sh.delta`` in place of the original ones, and ``pis`` (k, d + 1): the coefficients of each shift's p_δ,
    in the sorted order of ``sh`` (a :class:`~shapeflow.linalg.multishift.ShiftedSystems`)."""

    def __init__(self, A, sh: ShiftedSystems, degree: int, coef: np.ndarray, betas: np.ndarray, pis: np.ndarray):
        self.A, self.seed, self.degree, self.coef, self.pis = A, sh.seed, degree, coef, pis
        sh.delta = np.ascontiguousarray(betas)

    @classmethod
    def fitting(cls, A, sh: ShiftedSystems, degree: int, rtol: float) -> SeedPolynomial | None:
        """The preconditioner of the highest degree up to ``degree`` whose monomial form is exact enough
        (rounding of Horner's scheme on the spectrum, ε Σ|p_j| hi^{j+1}, at most ``rtol``: it is that of
        the products CG iterates with) and whose coefficients, β_δ and p_δ are finite and p's non-zero
        (they scale as hi^{−j−1} and δ^{d+1}); None (no preconditioner) where none is."""
        start = sh.B[int(np.argmax(sh.rho))]
        hi = spectrum_upper_estimate(A, sh.seed, start)
        if not (hi > 0 and np.isfinite(hi)):
            raise ParameterError(f"A + {sh.seed:g} I is not positive definite (largest Ritz value {hi:g})")
        eps = np.finfo(np.float64).eps
        with np.errstate(over="ignore", under="ignore", invalid="ignore"):
            for d in range(degree, 0, -1):                  # (over the degrees)
                coef = chebyshev_residual_polynomial(d, LOWER_FRACTION * hi, hi)
                rounding = eps * float(np.sum(np.abs(coef) * hi ** np.arange(1, d + 2)))
                betas, pis = shifted_polynomials(coef, sh.delta)
                if (rounding <= rtol and np.all(coef != 0) and np.isfinite(betas).all()
                        and np.isfinite(pis).all()):
                    return cls(A, sh, d, coef, betas, pis)
        return None

    def recover(self, Y: np.ndarray, pis: np.ndarray) -> np.ndarray:
        """The solutions ``Σ_i pis[:, i] A₀^i Y`` of the rows of ``Y`` (k, n) (row s by its own p_δ)."""
        P = accel.kernels("linalg", Y.shape[1]).shifted_powers(self.A, self.seed, np.ascontiguousarray(Y.T),
                                                              self.degree)
        X = pis[:, :1] * Y
        for i in range(1, self.degree + 1):
            X += pis[:, i:i + 1] * P[i].T
        return X

    def extend(self, lefts: list, Ws: list, pis: np.ndarray, spare: list | None = None,
               post: tuple | None = None, scratch: np.ndarray | None = None) -> None:
        """The low-rank factors of the solutions from those of the y's, in place for each column j with
        factors (``lefts[j]`` (k, r), ``Ws[j]`` a 1-tuple of (n, r) vertex-major; None: skipped):
        ``[pis[:, 0] left, …, pis[:, d] left]`` and the pieces ``(W, A₀ W, …, A₀^d W)`` transformed by
        ``post`` = (scale, take) (the linalg kernel family's ``shifted_powers``), side by side in one
        (·, (d + 1) r) array, the new ``Ws[j]`` = (that array,), or the d + 1 pieces as a tuple where
        the kernel could not write into it.  They are written into ``spare`` (flat
        float64 buffers no longer needed, such as the slots of the seed's block of residuals that the
        solve wrote, whose pages are in memory already) while it lasts; the powers' scratch (n, r), one
        for all columns, in ``scratch`` (a flat float64 buffer) where it has room, else there too."""
        scale, take = post if post is not None else (None, None)
        memory = Spare(spare).take
        scratch = np.zeros(0) if scratch is None else scratch
        if any(W is not None and W[0].size > scratch.size for W in Ws):
            scratch = memory(1, max(W[0].size for W in Ws if W is not None)).reshape(-1)

        d = self.degree
        for j in range(len(Ws)):
            if Ws[j] is None:
                continue
            (W,) = Ws[j]
            n, r = W.shape
            wide = memory(n if take is None else take.size, (d + 1) * r)     # the pieces side by side
            mem = [wide[:, i * r:(i + 1) * r] for i in range(d + 1)] + [scratch[:n * r].reshape(n, r)]
            kern = accel.kernels("linalg", n)
            res = kern.shifted_powers(self.A, self.seed, W, d, mem, take, scale)
            Ws[j] = (wide,) if all(res[i] is mem[i] for i in range(d + 1)) else tuple(res)
            lefts[j] = np.ascontiguousarray(np.concatenate([pis[:, i:i + 1] * lefts[j]
                                                            for i in range(d + 1)], axis=1))
