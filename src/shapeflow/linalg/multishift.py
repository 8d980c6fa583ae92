"""Multi-shift conjugate gradients: ``(A + s_i I) X_i = B`` for many shifts from one Krylov space."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..errors import ParameterError
from .spd import DEFAULT_RTOL

__all__ = ["BLOCK_BYTES", "MultiShiftResult", "multishift_cg", "shifted_coefficients", "ShiftedBlock"]


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
    seed = float(shifts[order][0])
    delta = (shifts[order] - seed)[:, None]             # (k, 1) >= 0
    if maxiter is None:
        maxiter = max(200, 10 * int(np.sqrt(n)) + 100)
    cap = int(max(8, min(maxiter + 1, block_bytes // max(1, 8 * c * n))))

    rho = np.einsum("ij,ij->i", B, B)                   # (c,)
    tol2 = rtol * rtol * rho
    active = np.broadcast_to(rho > tol2, (k, c)).copy()  # (shift, column) still iterating
    iterations = np.where(active, -1, 0)
    if not active.any():
        return MultiShiftResult(np.zeros((c, k, n)), iterations[inv], ~active[inv], 0, 0)
    blk = ShiftedBlock(B, k, cap)
    p = B.copy()
    Ap = np.zeros_like(B)                               # stays 0 in columns that never run
    zeta = np.ones((k, c))
    zeta_prev = np.ones((k, c))
    alpha_prev = np.ones(c)
    beta_prev = np.zeros(c)
    done_prev = report_progress(progress, active, inv, None)

    it = 0
    k_blk = k                                           # shifts active at the start of the block
    with np.errstate(divide="ignore", invalid="ignore", over="ignore", under="ignore"):
        while it < maxiter:
            cols = active.any(axis=0)                    # columns still running
            ka = int(np.flatnonzero(active.any(axis=1)).max()) + 1   # active shifts: (about) a prefix
            it += 1
            r = blk.Rb[:, blk.used - 1]
            for j in np.flatnonzero(cols):               # (per column: faster than SciPy's multi-vector product)
                Ap[j] = A @ p[j]
            if seed != 0.0:
                Ap += seed * p
            pAp = np.einsum("ij,ij->i", p, Ap)
            ok = cols & (pAp > 0)
            alpha = np.where(ok, rho / np.where(ok, pAp, 1.0), 0.0)
            r_new = blk.next_slot()
            np.multiply(Ap, alpha[:, None], out=r_new)
            np.subtract(r, r_new, out=r_new)
            rho_new = np.einsum("ij,ij->i", r_new, r_new)
            beta = np.where(ok & (rho > 0), rho_new / np.where(rho > 0, rho, 1.0), 0.0)
            zeta_new, upd, alpha_s, beta_s = shifted_coefficients(zeta, zeta_prev, alpha, alpha_prev, beta,
                                                                  beta_prev, delta, active & ok)
            blk.advance(alpha_s, beta_s, ka)
            # convergence of each (shift, column) after this iteration
            zeta_prev = np.where(upd, zeta, zeta_prev)
            zeta = np.where(upd, zeta_new, zeta)
            newly = upd & (zeta * zeta * rho_new <= tol2)
            iterations[newly] = it
            active &= ~newly
            active &= ok | ~cols                         # a column whose seed broke down is finished
            done_prev = report_progress(progress, active, inv, done_prev)
            if not active.any():
                break
            ka = int(np.flatnonzero(active.any(axis=1)).max()) + 1
            if blk.used == blk.cap:                      # block full: fold it into X and P, start a new one
                blk.flush(k_blk, ka)
                k_blk = ka
                blk.restart()
            blk.append(zeta, ka)
            p *= beta[:, None]
            p += blk.Rb[:, blk.used - 1]
            rho = np.where(ok, rho_new, rho)
            alpha_prev = np.where(ok, alpha, alpha_prev)
            beta_prev = np.where(ok, beta, beta_prev)
    blk.flush(k_blk, 0)
    return MultiShiftResult(blk.X[:, inv], iterations[inv], ~active[inv], it, blk.flushes)


def report_progress(progress, active: np.ndarray, inv: np.ndarray, before: np.ndarray | None) -> np.ndarray:
    """Call ``progress`` when the set of finished shifts changed (first call: when any is); returns that set."""
    done = ~active.any(axis=1)
    if progress is not None and (done.any() if before is None else (done != before).any()):
        progress(done[inv])
    return done


def shifted_coefficients(zeta, zeta_prev, alpha, alpha_prev, beta, beta_prev, delta, live):
    """The shifted recurrences (k, c) of CG-M: ζ_{i+1}, which (shift, column) update, α_s and β_s.

    ``live``: (shift, column) still iterating whose seed column did not break down.
    """
    den = alpha_prev * zeta_prev * (1.0 + alpha * delta) + alpha * beta_prev * (zeta_prev - zeta)
    zeta_new = zeta * zeta_prev * alpha_prev / den
    ratio = zeta_new / zeta
    upd = live & np.isfinite(ratio)
    alpha_s = np.where(upd, alpha * ratio, 0.0)
    beta_s = np.where(upd, beta * ratio * ratio, 0.0)
    return zeta_new, upd, alpha_s, beta_s


class ShiftedBlock:
    """The shifted iterates of :func:`multishift_cg` as coefficients over a block of stored seed residuals.

    ``p_s = a_s P_s + Σ_t Cf[t] Rb[t]`` and ``x_s = X_s + xa_s P_s + Σ_t Xf[t] Rb[t]``
    (per column); :meth:`flush` folds the block into ``X`` and ``P`` with one
    GEMM per column.  ``r`` of the seed is always ``Rb[:, used - 1]``.
    """

    def __init__(self, B: np.ndarray, k: int, cap: int):
        c, n = B.shape
        self.c, self.n, self.cap = c, n, cap
        self.X = np.empty((c, k, n))                    # written by the first flush
        self.Rb = np.empty((c, cap, n))                 # the block's seed residuals
        self.Rb[:, 0] = B
        self.used = 1
        self.r_spare = np.empty_like(B)                 # the new residual when the block is full
        self.P = None                                   # block-start directions P_s (c, kp, n), after a first block
        self.Cf = np.zeros((c, k, cap))
        self.Xf = np.zeros((c, k, cap))
        self.a = np.zeros((c, k))
        self.xa = np.zeros((c, k))
        self.Cf[:, :, 0] = 1.0                          # p_s(0) = r(0) for every shift
        self.flushes = 0

    def next_slot(self) -> np.ndarray:
        """Where the next seed residual goes."""
        return self.Rb[:, self.used] if self.used < self.cap else self.r_spare

    def advance(self, alpha_s: np.ndarray, beta_s: np.ndarray, ka: int) -> None:
        """x_s += α_s p_s ;  p_s ← β_s p_s (+ ζ_s r_new in :meth:`append`): coefficients only."""
        used = self.used
        aT = alpha_s[:ka].T                              # (c, ka)
        self.Xf[:, :ka, :used] += aT[:, :, None] * self.Cf[:, :ka, :used]
        self.xa[:, :ka] += aT * self.a[:, :ka]
        bT = beta_s[:ka].T
        self.Cf[:, :ka, :used] *= bT[:, :, None]
        self.a[:, :ka] *= bT

    def append(self, zeta: np.ndarray, ka: int) -> None:
        """The new seed residual joins the block with coefficient ζ_s in every p_s."""
        self.Cf[:, :ka, self.used] = zeta[:ka].T
        self.used += 1

    def restart(self) -> None:
        """A new block starting with the spare residual (after :meth:`flush`)."""
        self.Cf[:] = 0.0
        self.Xf[:] = 0.0
        self.a[:] = 1.0
        self.xa[:] = 0.0
        self.used = 0
        self.Rb[:, 0] = self.r_spare

    def flush(self, kx: int, ka: int) -> None:
        """Fold the block into X (shifts [:kx], all that were active in it) and P ([:ka], still active)."""
        self.flushes += 1
        Rv = self.Rb[:, :self.used]
        Xf, Cf, X, P = self.Xf, self.Cf, self.X, self.P
        for j in range(self.c):
            if self.flushes == 1:                        # X is still empty: write, don't accumulate
                np.matmul(Xf[j, :kx, :self.used], Rv[j], out=X[j, :kx])
                X[j, kx:] = 0.0
                continue
            if P is not None:
                for s_ in np.flatnonzero(self.xa[j, :kx]):
                    X[j, s_] += self.xa[j, s_] * P[j, s_]
            X[j, :kx] += Xf[j, :kx, :self.used] @ Rv[j]
        if ka:
            if P is None:
                self.P = P = np.empty((self.c, ka, self.n))
                for j in range(self.c):
                    np.matmul(Cf[j, :ka, :self.used], Rv[j], out=P[j])
            else:
                for j in range(self.c):
                    P[j, :ka] *= self.a[j, :ka, None]
                    P[j, :ka] += Cf[j, :ka, :self.used] @ Rv[j]
