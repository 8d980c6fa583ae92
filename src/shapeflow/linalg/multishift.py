"""Multi-shift conjugate gradients: ``(A + s_i I) X_i = B`` for many shifts from one Krylov space."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..errors import ParameterError
from .spd import DEFAULT_RTOL

__all__ = ["BLOCK_BYTES", "MultiShiftResult", "multishift_cg"]


#: memory for the block of stored seed residuals (the rest is O(k·n))
BLOCK_BYTES = 128 * 2 ** 20


@dataclass
class MultiShiftResult:
    """Solutions of :func:`multishift_cg`.

    ``X[j, i]`` is column ``j`` of the solution for shift ``i`` (component-major,
    shifts in the order given); ``iterations[i, j]`` the iteration after which it
    met the tolerance (``-1``: never), ``converged[i, j]`` whether it did.
    ``flushes`` counts the GEMMs folding a block of residuals into the iterates.
    """

    X: np.ndarray
    iterations: np.ndarray
    converged: np.ndarray
    krylov_iterations: int
    flushes: int


def multishift_cg(A, B: np.ndarray, shifts, *, rtol: float = DEFAULT_RTOL, maxiter: int | None = None,
                  block_bytes: int = BLOCK_BYTES,
                  progress: Callable[[np.ndarray], None] | None = None) -> MultiShiftResult:
    """Solve ``(A + s_i I) X_i = B`` for every shift ``s_i`` with one Krylov space.

    Parameters
    ----------
    A : sparse matrix (n, n) or anything with ``A @ vector``, symmetric, such
        that ``A + min(shifts) I`` is positive definite.
    B : (c, n) right-hand-side columns, component-major (one row per column).
    shifts : (k,) real.
    rtol : every (shift, column) stops when its residual ``‖b − (A + s)x‖``
        (the recursively updated one, ``|ζ_s| ‖r‖``, as CG's) fell below
        ``rtol × ‖b‖`` (the initial residual; the start is x = 0), and is no
        longer updated after that.
    maxiter : cap on the shared iterations (default ``max(200, 10·√n + 100)``,
        as :class:`~shapeflow.linalg.spd.SPDSolver`).
    block_bytes : memory for the stored seed residuals; the shifted iterates
        are built from them with one GEMM per block.
    progress : called with the (k,) bool array "shift converged in every
        column" whenever it changes.

    Notes
    -----
    CG-M (Jegerlehner 1996; Frommer 2003): CG runs on the smallest shift (the
    seed); the residual of shift ``s`` is ``ζ_s r`` with ζ from a three-term
    scalar recurrence, its search direction is ``p_s ← ζ_s r + β_s p_s`` and
    its iterate ``x_s ← x_s + α_s p_s``.  Here ``p_s`` and ``x_s`` are carried
    as coefficients over the stored residuals of the current block (plus the
    block-start direction ``P_s`` after the first block), so an iteration
    costs the seed's matrix-vector product and vector updates plus
    O(k × block) scalars; the k shifted vectors are formed by a GEMM when the
    block is full or the run ends (one GEMM in all when the residuals fit in
    ``block_bytes``).  Columns are independent CG runs (their own α, β), as
    in the repository's CG.
    """
    B = np.ascontiguousarray(np.atleast_2d(np.asarray(B, dtype=np.float64)))
    c, n = B.shape
    shifts = np.asarray(shifts, dtype=np.float64).ravel()
    k = shifts.size
    if k == 0:
        return MultiShiftResult(np.zeros((c, 0, n)), np.zeros((0, c), np.int64), np.zeros((0, c), bool), 0, 0)
    if not np.all(np.isfinite(shifts)):
        raise ParameterError("shifts must be finite")
    order = np.argsort(shifts, kind="stable")           # hardest (smallest shift) first
    inv = np.argsort(order)
    s_sorted = shifts[order]
    seed = float(s_sorted[0])
    delta = (s_sorted - seed)[:, None]                  # (k, 1) >= 0
    if maxiter is None:
        maxiter = max(200, 10 * int(np.sqrt(n)) + 100)
    cap = int(max(8, min(maxiter + 1, block_bytes // max(1, 8 * c * n))))

    rho = np.einsum("ij,ij->i", B, B)                   # (c,)
    tol2 = rtol * rtol * rho
    active = np.broadcast_to(rho > tol2, (k, c)).copy()  # (shift, column) still iterating
    iterations = np.where(active, -1, 0)
    if not active.any():
        return MultiShiftResult(np.zeros((c, k, n)), iterations[inv], ~active[inv], 0, 0)
    X = np.empty((c, k, n))                             # written by the first flush
    Rb = np.empty((c, cap, n))                          # the block's seed residuals; r is always Rb[:, used-1]
    Rb[:, 0] = B
    used = 1
    r_spare = np.empty_like(B)                          # the new residual when the block is full
    p = B.copy()
    Ap = np.zeros_like(B)                               # stays 0 in columns that never run
    P = None                                            # block-start directions P_s (c, kp, n), after a first block
    Cf = np.zeros((c, k, cap))                          # p_s = a_s P_s + Σ_t Cf[t] Rb[t]
    Xf = np.zeros((c, k, cap))                          # x_s = X_s + xa_s P_s + Σ_t Xf[t] Rb[t]
    a = np.zeros((c, k))
    xa = np.zeros((c, k))
    Cf[:, :, 0] = 1.0                                   # p_s(0) = r(0) for every shift
    zeta = np.ones((k, c))
    zeta_prev = np.ones((k, c))
    alpha_prev = np.ones(c)
    beta_prev = np.zeros(c)
    flushes = 0
    done_prev = ~active.any(axis=1)
    if progress is not None and done_prev.any():
        progress(done_prev[inv])

    def flush(kx: int, ka: int) -> None:
        """Fold the block into X (shifts [:kx], all that were active in it) and P ([:ka], still active)."""
        nonlocal P, flushes
        flushes += 1
        Rv = Rb[:, :used]
        for j in range(c):
            if flushes == 1:                             # X is still empty: write, don't accumulate
                np.matmul(Xf[j, :kx, :used], Rv[j], out=X[j, :kx])
                X[j, kx:] = 0.0
                continue
            if P is not None:
                for s_ in np.flatnonzero(xa[j, :kx]):
                    X[j, s_] += xa[j, s_] * P[j, s_]
            X[j, :kx] += Xf[j, :kx, :used] @ Rv[j]
        if ka:
            if P is None:
                P = np.empty((c, ka, n))
                for j in range(c):
                    np.matmul(Cf[j, :ka, :used], Rv[j], out=P[j])
            else:
                for j in range(c):
                    P[j, :ka] *= a[j, :ka, None]
                    P[j, :ka] += Cf[j, :ka, :used] @ Rv[j]

    it = 0
    k_blk = k                                           # shifts active at the start of the block
    with np.errstate(divide="ignore", invalid="ignore", over="ignore", under="ignore"):
        while it < maxiter:
            cols = active.any(axis=0)                    # columns still running
            ka = int(np.flatnonzero(active.any(axis=1)).max()) + 1   # active shifts: (about) a prefix
            it += 1
            r = Rb[:, used - 1]
            for j in np.flatnonzero(cols):               # (per column: faster than SciPy's multi-vector product)
                Ap[j] = A @ p[j]
            if seed != 0.0:
                Ap += seed * p
            pAp = np.einsum("ij,ij->i", p, Ap)
            ok = cols & (pAp > 0)
            alpha = np.where(ok, rho / np.where(ok, pAp, 1.0), 0.0)
            r_new = Rb[:, used] if used < cap else r_spare
            np.multiply(Ap, alpha[:, None], out=r_new)
            np.subtract(r, r_new, out=r_new)
            rho_new = np.einsum("ij,ij->i", r_new, r_new)
            beta = np.where(ok & (rho > 0), rho_new / np.where(rho > 0, rho, 1.0), 0.0)
            # shifted recurrences (k, c): ζ_{i+1}, α_s, β_s
            den = alpha_prev * zeta_prev * (1.0 + alpha * delta) + alpha * beta_prev * (zeta_prev - zeta)
            zeta_new = zeta * zeta_prev * alpha_prev / den
            ratio = zeta_new / zeta
            upd = active & ok & np.isfinite(ratio)
            alpha_s = np.where(upd, alpha * ratio, 0.0)
            beta_s = np.where(upd, beta * ratio * ratio, 0.0)
            # x_s += α_s p_s ;  p_s ← β_s p_s (+ ζ_s r_new below): coefficients only
            aT = alpha_s[:ka].T                          # (c, ka)
            Xf[:, :ka, :used] += aT[:, :, None] * Cf[:, :ka, :used]
            xa[:, :ka] += aT * a[:, :ka]
            bT = beta_s[:ka].T
            Cf[:, :ka, :used] *= bT[:, :, None]
            a[:, :ka] *= bT
            # convergence of each (shift, column) after this iteration
            zeta_prev = np.where(upd, zeta, zeta_prev)
            zeta = np.where(upd, zeta_new, zeta)
            newly = upd & (zeta * zeta * rho_new <= tol2)
            iterations[newly] = it
            active &= ~newly
            active &= ok | ~cols                         # a column whose seed broke down is finished
            if progress is not None:
                done = ~active.any(axis=1)
                if (done != done_prev).any():
                    progress(done[inv])
                    done_prev = done
            if not active.any():
                break
            ka = int(np.flatnonzero(active.any(axis=1)).max()) + 1
            if used == cap:                              # block full: fold it into X and P, start a new one
                flush(k_blk, ka)
                k_blk = ka
                Cf[:] = 0.0
                Xf[:] = 0.0
                a[:] = 1.0
                xa[:] = 0.0
                used = 0
                Rb[:, 0] = r_spare
            Cf[:, :ka, used] = zeta[:ka].T
            used += 1
            p *= beta[:, None]
            p += Rb[:, used - 1]
            rho = np.where(ok, rho_new, rho)
            alpha_prev = np.where(ok, alpha, alpha_prev)
            beta_prev = np.where(ok, beta, beta_prev)
    flush(k_blk, 0)
    return MultiShiftResult(X[:, inv], iterations[inv], ~active[inv], it, flushes)
