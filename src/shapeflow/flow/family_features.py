"""The family's shared solve with feature curves: one multi-shift BiCG for every λ.

With sharp edges (:mod:`shapeflow.flow.features`) one step of the flow solves the curves, then the
surface with the curves' new positions as boundary values.  Over all free vertices (curve rows
first) that is one block lower-triangular system,

    [σ C_c + K_c      0     ] [Δ_c]   [r_c]
    [   K_sc      σ C_s + K_s] [Δ_s] = [r_s],      σ = 1/|λ|,

for the displacements Δ = X − V, whose right-hand side (the couplings to fixed vertices minus K V)
does not depend on λ.  Scaled by C^{-1/2} it is ``(σI + M) Y = b`` with one matrix M and one
right-hand side b for every member: the shift structure holds, but M is not symmetric (the curves
do not feel the surface).  Krylov spaces are invariant under shifts whatever the symmetry, so the
bi-conjugate gradient method (BiCG: residuals and shadow residuals of the Lanczos
biorthogonalisation) solves all shifts at once exactly as CG-M does for symmetric M: the shifted
residuals are the seed's times the same scalars ζ_σ (Jegerlehner 1996; Frommer 2003), so
:func:`~shapeflow.linalg.multishift.shifted_coefficients`, the recorded scalars and the members'
coefficients over the stored seed residuals (:class:`~shapeflow.linalg.multishift.ShiftedSystems`)
carry over; BiCG's residuals are not orthogonal, so the iterates are formed without the low-rank
factorisation.  An iteration costs a
product with M and one with Mᵀ.  Each member stops on its own residual; at the end every member's
true residual is checked, and a member short of ``rtol`` (BiCG's recurrences may drift, or break
down) is reported unconverged and solved separately by the caller.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..linalg.multishift import NumpySeed, Records, ShiftedSystems, shifted_coefficients

__all__ = ["coupled_seed_system", "multishift_bicg", "BiCGResult"]


def coupled_seed_system(interior_sys, curve_sys, S: np.ndarray, V: np.ndarray, X: np.ndarray, ax: np.ndarray):
    """The shared solve's scaled right-hand sides, matrix and transpose for the coupled curves + surface
    system at the seed λ (see the module docstring), and the columns (axes) solved.

    ``S`` = C_1^{-1/2} on the free rows of both blocks, 1 elsewhere; ``X``: positions with the
    boundary block solved.  Rows of no block are identity rows with a zero residual.
    """
    n = V.shape[0]
    free_c = curve_sys.free
    c = np.zeros(n)
    c[curve_sys.idx] = curve_sys.c
    if interior_sys is not None:
        A = interior_sys.A.tocsr()
        c += interior_sys.c
        free = interior_sys.free | free_c
    else:
        A = sp.identity(n, format="csr")
        free = free_c
    # the curve rows replace their identity rows; the surface rows' terms on curve vertices enter the matrix
    Ac = curve_sys.A.tocoo()
    idx = curve_sys.idx
    rows = [idx[Ac.row], idx]
    cols = [idx[Ac.col], idx]
    vals = [Ac.data, -np.ones(idx.size)]
    rhs = np.where(free[:, None], c[:, None] * V, X)
    if interior_sys is not None:
        r, s, e = interior_sys.coupling
        inner = free_c[s]
        rows.append(r[inner])
        cols.append(s[inner])
        vals.append(-e[inner])
        r, s, e = r[~inner], s[~inner], e[~inner]
    else:
        r = s = np.zeros(0, np.int64)
        e = np.zeros(0)
    rc, sc, ec = curve_sys.coupling
    r, s, e = np.concatenate([r, rc]), np.concatenate([s, sc]), np.concatenate([e, ec])
    for j in range(3):
        rhs[:, j] += np.bincount(r, e * X[s, j], minlength=n)
    T = (A + sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                           shape=(n, n))).tocsr()
    cols_ax = np.flatnonzero(ax)
    R0 = np.empty((cols_ax.size, n))
    for t, j in enumerate(cols_ax):
        R0[t] = (rhs[:, j] - T @ X[:, j]) * S
    Ts = (sp.diags(S) @ T @ sp.diags(S)).tocsr()
    return R0, Ts, Ts.T.tocsr(), cols_ax


@dataclass
class BiCGResult:
    """As :class:`~shapeflow.linalg.multishift.MultiShiftResult`: ``X[j, i]`` column j of shift i."""

    X: np.ndarray
    iterations: np.ndarray
    converged: np.ndarray
    krylov_iterations: int


def multishift_bicg(A, AT, B: np.ndarray, shifts, *, rtol: float, maxiter: int, progress=None) -> BiCGResult:
    """Solve ``(A + s_i I) X_i = B`` for every shift with one BiCG run on the smallest shift.

    ``A`` need not be symmetric (``AT`` is its transpose); ``B`` (c, n) holds the columns.  Every
    (shift, column) stops when its recurrence residual ``|ζ_s| ‖r‖`` falls below ``rtol ‖b‖``;
    ``converged`` then also requires the true residual ``‖b − (A + s) x‖`` below ``10·rtol ‖b‖``.
    """
    sh = ShiftedSystems(B, shifts, rtol, maxiter)
    if sh.result is not None:
        r = sh.result
        return BiCGResult(r.X, r.iterations, r.converged, 0)
    seed_bicg = BiCGSeed(A, sh.B, sh.seed, sh.block_slots(BLOCK_BYTES), AT=AT)
    res = sh.solve(seed_bicg, None, progress)
    Xs, iterations = res.X, res.iterations
    B, tol2, shifts = sh.B, sh.tol2, np.asarray(shifts, dtype=np.float64).ravel()
    converged = res.converged & (iterations > 0) | (iterations == 0)
    for j in range(sh.c):                            # the true residual of every member
        for i in np.flatnonzero(converged[:, j] & (iterations[:, j] > 0)):
            r = B[j] - A @ Xs[j, i] - shifts[i] * Xs[j, i]
            converged[i, j] = bool(r @ r <= 100.0 * tol2[j])
    return BiCGResult(Xs, iterations, converged, res.krylov_iterations)


#: memory for the stored seed residuals of the BiCG
BLOCK_BYTES = 64 * 2 ** 20


class BiCGSeed(NumpySeed):
    """The seed's BiCG: the first pass (records of the shifted recurrences, the first block of
    residuals, the states where later blocks start); later blocks are replayed as CG's (the residual
    and direction recurrences r −= α A p, p = r + β p are the same, with the recorded α, β)."""

    def __init__(self, A, B: np.ndarray, seed: float, cap: int, *, AT=None):
        super().__init__(A, B, seed, cap)
        self.AT = AT

    def first_pass(self, rec: Records, sh: ShiftedSystems, report) -> int:
        A, AT, seed, c, cap = self.A, self.AT, self.seed, self.c, self.cap
        self.rec = rec
        delta, tol2, active, iterations = sh.delta[:, None], sh.tol2, sh.active, sh.iterations
        r, p, Ap = self.r, self.p, self.Ap
        shadow, p_shadow, Atp = r.copy(), r.copy(), np.zeros_like(r)
        rho = np.einsum("ij,ij->i", shadow, r)
        k = sh.k
        zeta, zeta_prev = np.ones((k, c)), np.ones((k, c))
        alpha_prev, beta_prev = np.ones(c), np.zeros(c)
        done = report(None)
        it = 0
        with np.errstate(divide="ignore", invalid="ignore", over="ignore", under="ignore"):
            while it < sh.maxiter:
                if it + 1 >= rec.sa.shape[0]:
                    rec.grow()
                run = active.any(axis=0)
                it += 1
                for j in np.flatnonzero(run):
                    Ap[j] = A @ p[j]
                    Atp[j] = AT @ p_shadow[j] + seed * p_shadow[j]
                if seed != 0.0:
                    Ap += seed * p
                pAp = np.einsum("ij,ij->i", p_shadow, Ap)
                ok = run & (pAp != 0) & (rho != 0) & np.isfinite(pAp)
                alpha = np.where(ok, rho / np.where(ok, pAp, 1.0), 0.0)
                r -= alpha[:, None] * Ap
                if it < cap:
                    self.Rb[:, it] = r
                shadow -= Atp * alpha[:, None]
                rho_new = np.einsum("ij,ij->i", shadow, r)
                beta = np.where(ok, rho_new / np.where(ok, rho, 1.0), 0.0)
                rec.sa[it, :c], rec.sb[it, :c] = alpha, beta
                zeta_new, upd, alpha_s, beta_s = shifted_coefficients(zeta, zeta_prev, alpha, alpha_prev, beta,
                                                                      beta_prev, delta, active & ok)
                zeta_prev = np.where(upd, zeta, zeta_prev)
                zeta = np.where(upd, zeta_new, zeta)
                rec.ra[:, :, it], rec.rb[:, :, it], rec.rz[:, :, it] = alpha_s.T, beta_s.T, zeta.T
                newly = upd & (zeta * zeta * np.einsum("ij,ij->i", r, r) <= tol2)
                iterations[newly] = it
                active &= ~newly & (ok | ~run)          # a column whose seed broke down is finished
                done = report(done)
                if not active.any():
                    break
                p *= beta[:, None]
                p += r
                p_shadow *= beta[:, None]
                p_shadow += shadow
                rho = np.where(ok, rho_new, rho)
                alpha_prev = np.where(ok, alpha, alpha_prev)
                beta_prev = np.where(ok, beta, beta_prev)
                if it % cap == 0:
                    self.saved[it // cap] = (r.copy(), p.copy())
        return it
