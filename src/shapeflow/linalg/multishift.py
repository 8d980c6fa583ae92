"""Multi-shift conjugate gradients: ``(A + s_i I) X_i = B`` for many shifts from one Krylov space."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
import scipy.linalg
from scipy.linalg.blas import dgemm

from .. import accel, params
from ..errors import ParameterError
from .blas import SingleThreadBLAS
from .shift_polynomial import SeedPolynomial
from .spare import factor_memory
from .spd import DEFAULT_RTOL

__all__ = ["BLOCK_BYTES", "RANK_TOL", "TRUE_RESIDUAL_FACTOR", "MultiShiftResult", "multishift_cg",
           "shifted_coefficients", "member_coefficients", "low_rank_factors", "shifted_residuals",
           "ShiftedSystems", "SeedPolynomial", "NumpySeed", "Records"]


#: memory for the block of stored seed residuals (beyond it, later blocks are replayed)
BLOCK_BYTES = 128 * 2 ** 20

#: the members' coefficients are factorised (truncated SVD) with this error per member, relative to
#: ``rtol`` and to the member's own size (see :func:`low_rank_factors`)
RANK_TOL = 1e-3

#: a solution passes the true-residual check (:func:`shifted_residuals`) when its true residual is at most
#: this many times ``rtol ‖b‖`` (plus as many times what rounding the solution to the working precision
#: alone leaves): the recurrence stops at ``rtol``, and the true residual departs from it by rounding
#: (~ε·κ, κ the condition number) and by the low-rank fold (:data:`RANK_TOL` × ``rtol`` of each member's
#: size, times at most κ); on the figure-1 families it stays below 1.0 × ``rtol``
TRUE_RESIDUAL_FACTOR = 10.0

#: the factorisation is used when its two GEMMs need at most this fraction of the flops of one
LOW_RANK_GAIN = 0.7

#: what a pass over the seed's iterations stops for (the compiled kernel's codes too)
DONE, CHECKPOINT, PROGRESS, CAPPED, GROW = 0, 1, 2, 3, 4


@dataclass
class MultiShiftResult:
    """Solutions of :func:`multishift_cg`.

    ``X[j, i]`` is column ``j`` of the solution for shift ``i`` (component-major,
    shifts in the order given); ``iterations[i, j]`` the iteration after which it
    met the tolerance (``-1``: never), ``converged[i, j]`` whether it did.
    ``flushes`` counts the blocks of seed residuals folded into the iterates,
    ``replayed`` the seed iterations run again for the blocks after the first,
    ``ranks[j]`` the rank of column j's factorised coefficients (0: not factorised), ``degree`` that of
    the polynomial preconditioner (0: none; each iteration then took ``degree + 1`` products).
    """

    X: np.ndarray
    iterations: np.ndarray
    converged: np.ndarray
    krylov_iterations: int
    flushes: int
    replayed: int = 0
    ranks: tuple = ()
    degree: int = 0


@accel.heavy        # (a public entry point: the call's threads reach the compiled seed)
def multishift_cg(A, B: np.ndarray, shifts, *, rtol: float = DEFAULT_RTOL, maxiter: int | None = None,
                  block_bytes: int = BLOCK_BYTES, low_rank: bool = True,
                  progress: Callable[[np.ndarray], None] | None = None,
                  emit: Callable[[np.ndarray, np.ndarray], None] | None = None,
                  post: tuple | None = None, degree: int = 0) -> MultiShiftResult:
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
    block_bytes : memory for the stored seed residuals; when they do not all fit,
        the seed's iterations after the first block are run again from saved states.
    low_rank : form the iterates through a truncated factorisation of their
        coefficients where it saves flops (:func:`low_rank_factors`).
    progress : called with the (k,) bool array "shift converged in every
        column" whenever it changes.
    emit : when given, the iterates are not collected in ``X`` (which is then None) but
        handed over as they are formed: ``emit(shifts, rows)`` with ``rows[j, q]`` column ``j``
        of the solution for shift ``shifts[q]`` (a buffer reused after the call returns).  An
        ``emit`` with a ``factors`` method is handed the low-rank factors instead when every column
        was factorised: ``emit.factors(lefts, Ws)``, column j of every solution being
        ``lefts[j] @ Ws[j]ᵀ`` ((k, r_j) in the order of ``shifts``; Ws[j] a tuple of (n, ·) vertex-major
        pieces side by side, transformed by ``post``).  Such an ``emit`` may also have a
        ``scratch(size)`` method giving a flat float64 buffer of at least ``size`` values (or None)
        that is free until ``emit.factors`` is called: with a polynomial preconditioner the y's
        factors are formed there (memory whose pages the receiver will touch anyway); and a
        ``spare(buffers)`` method, handed afterwards the solve's flat buffers it no longer needs
        (their pages touched already) for the receiver's own scratch — the pieces given to
        ``factors`` live in them, so a receiver must form what it needs from the pieces before it
        writes into those buffers.
    post : ``(scale, take)``, either may be None: every solution column x is returned (or
        emitted) as ``(scale * x)[take]`` (applied to the low-rank factor, before the rows are formed).
    degree : a polynomial preconditioner of this degree that keeps the systems shifts of one
        operator (:mod:`~shapeflow.linalg.shift_polynomial`; 0: none).  CG then runs on
        ``B = A₀ p(A₀)`` (A₀ = A + min(shifts) I, p Chebyshev's on [hi/100, hi], hi from 12 Lanczos
        steps) with the shifts ``β_δ = δ p(−δ)``, and each solution is ``p_δ(A₀) y``: about
        ``degree + 1`` times fewer iterations of ``degree + 1`` products each, as many fewer residuals
        stored, and ``degree`` products per row of the low-rank factor to form the solutions.  The
        residuals tested against ``rtol`` are those of the original systems (the same vectors).
        Even degrees keep B positive definite however the spectrum's estimate falls.

    Notes
    -----
    CG-M (Jegerlehner 1996; Frommer 2003): CG runs on the smallest shift (the
    seed); the residual of shift ``s`` is ``ζ_s r`` with ζ from a three-term
    scalar recurrence, its search direction is ``p_s ← ζ_s r + β_s p_s`` and
    its iterate ``x_s ← x_s + α_s p_s``.  So ``x_s = Σ_t c_st r_t`` over the
    seed's residuals, and the coefficients follow from the recorded scalars
    afterwards (:func:`member_coefficients`).  An iteration costs the seed's
    product and vector updates plus O(k) scalars; the seed residuals are
    stored in a block and folded into the k iterates by GEMMs at the end.
    Columns are independent CG runs (their own α, β), as in the repository's
    CG.  The seed's iterations are the linalg kernel family's
    (``accel.kernels("linalg", n).multishift_seed``): :class:`NumpySeed`, or compiled
    (:mod:`~shapeflow.linalg.compiled_shift`, a CSR matrix, up to three columns) with the same
    formulas in the same order.

    With ``degree`` the same runs on B = A₀ p(A₀) (:class:`SeedPolynomial`): the stored residuals
    are those of the y's, the factor W of their low-rank fold (n × r) is extended to
    ``[W, A₀W, …, A₀^d W]`` (the linalg kernel family's ``shifted_powers``, written into the
    block of residuals that the fold no longer needs) and each shift's left factor to
    ``[π_0 L, …, π_d L]`` with p_δ's coefficients π: the solutions' factors, of rank (d + 1) r.

    """
    degree = params.integer("degree", degree)
    rtol = params.rtol(rtol)
    sh = ShiftedSystems(B, shifts, rtol, maxiter)
    shape = getattr(A, "shape", None)
    if shape is not None and tuple(shape) != (sh.n, sh.n):
        raise ParameterError(f"A must be ({sh.n}, {sh.n}) for B's columns of {sh.n} entries, got {tuple(shape)}")
    post = check_post(post, sh.n)
    if sh.result is not None:
        return sh.result
    poly = SeedPolynomial.fitting(A, sh, degree, rtol) if degree else None
    seed_cg = accel.kernels("linalg", sh.n).multishift_seed(A, sh.B, sh.seed, sh.block_slots(block_bytes),
                                                            None if poly is None else poly.coef)
    return sh.solve(seed_cg, rtol if low_rank else None, progress, emit, post, poly)


def check_post(post, n: int) -> tuple:
    """``post`` as ``(scale, take)``: scale None or (n,) finite, take None or int64 row indices in [0, n)."""
    scale, take = (None, None) if post is None else post
    scale = None if scale is None else np.ascontiguousarray(scale, dtype=np.float64)
    if scale is not None and (scale.shape != (n,) or not np.isfinite(scale).all()):
        raise ParameterError(f"post's scale must be {n} finite numbers (one per row), got shape {scale.shape}")
    take = None if take is None else np.asarray(take)
    if take is not None and (take.ndim != 1 or take.dtype.kind not in "iu" or (
            take.size and not -n <= take.min() <= take.max() < n)):
        raise ParameterError(f"post's take must be a 1-D array of row indices in [-{n}, {n})")
    return scale, None if take is None else np.where(take < 0, take + n, take).astype(np.int64)


class ShiftedSystems:
    """The set-up shared by the multi-shift solvers (CG here, BiCG in ``flow.family_features``): shifts
    sorted hardest (smallest) first, the seed, the tolerances, which (shift, column) iterate;
    ``result`` is the answer already when nothing iterates."""

    def __init__(self, B, shifts, rtol: float, maxiter: int | None):
        self.B = B = np.ascontiguousarray(np.atleast_2d(np.asarray(B, dtype=np.float64)))
        self.c, self.n = c, n = B.shape
        shifts = np.asarray(shifts, dtype=np.float64).ravel()
        self.k = k = shifts.size
        self.result = None
        if k and not np.all(np.isfinite(shifts)):
            raise ParameterError("shifts must be finite")
        if not np.all(np.isfinite(B)):
            raise ParameterError(f"B must be finite (column {int(np.argmin(np.isfinite(B).all(axis=1)))} is not)")
        maxiter = None if maxiter is None else params.integer("maxiter", maxiter)
        self.order = np.argsort(shifts, kind="stable")      # hardest (smallest shift) first
        self.inv = np.argsort(self.order)
        self.shifts = shifts[self.order]
        self.seed = float(self.shifts[0]) if k else 0.0
        self.delta = np.ascontiguousarray(self.shifts - self.seed)   # (k,) >= 0
        self.maxiter = max(200, 10 * int(np.sqrt(n)) + 100) if maxiter is None else maxiter
        self.rho = np.einsum("ij,ij->i", B, B)                # (c,)
        self.tol2 = rtol * rtol * self.rho
        self.active = np.broadcast_to(self.rho > self.tol2, (k, c)).copy()  # (shift, column) not yet within rtol
        self.live = self.active.copy()          # its recurrence still runs (past rtol too, until the seed stops)
        self.iterations = np.where(self.active, -1, 0)
        if not self.active.any():
            self.result = MultiShiftResult(np.zeros((c, k, n)), self.iterations[self.inv],
                                           self.iterations[self.inv] >= 0, 0, 0)

    def block_slots(self, block_bytes: int) -> int:
        """Seed residuals stored in the first block (and in every replayed one)."""
        return int(max(8, min(self.maxiter + 1, block_bytes // max(1, 8 * self.c * self.n))))

    def solve(self, seed_cg, rtol: float | None, progress, emit=None, post=None, poly=None) -> MultiShiftResult:
        """The first pass of ``seed_cg``, the members' coefficients, the fold (low rank with ``rtol``);
        the iterates into ``X`` or handed to ``emit`` (see :func:`multishift_cg`); with ``poly``
        (:class:`SeedPolynomial`) the iterates are the y's, mapped to the solutions in the fold."""
        rec = Records(self.c, self.k, min(self.maxiter + 1, 256))
        rec.srho[0, :self.c] = self.rho
        m = seed_cg.first_pass(rec, self, lambda done: report_progress(progress, self.active, self.inv, done))
        stop = np.where(self.iterations >= 0, self.iterations, m).T   # (c, k): where each shift met rtol
        X = None
        if emit is None:
            X = np.empty((self.c, self.k, self.n if post is None or post[1] is None else post[1].size))

            def emit(shifts, rows):
                X[:, shifts] = rows
        flushes, ranks = fold(seed_cg, rec, m, stop, self.inv, rtol, emit, post, poly)
        # converged: met rtol (a column whose seed broke down stops without meeting it)
        return MultiShiftResult(X, self.iterations[self.inv], self.iterations[self.inv] >= 0, m, flushes,
                                seed_cg.replayed, ranks, 0 if poly is None else poly.degree)


#: shifts formed at a time when the iterates are handed out row by row (``emit``)
EMIT_ROWS = 16


def fold(seed_cg, rec: Records, m: int, stop: np.ndarray, inv: np.ndarray, rtol: float | None, emit,
         post=None, poly=None):
    """The iterates x_s = Σ_t C[s, t] r_t from the blocks of seed residuals (the first one stored, the
    others replayed), transformed by ``post`` and handed to ``emit(shifts, rows)`` (shifts in the
    caller's order, ``rows`` (c, shifts, n) a reused buffer); returns (blocks, ranks).  With ``poly``
    (:class:`SeedPolynomial`) the iterates are y_s, and the solutions ``p_δs(A₀) y_s`` are formed
    from them before ``post`` (on the low-rank factors: :meth:`SeedPolynomial.extend`).

    Per column, with ``rtol``, through :func:`low_rank_factors` of the coefficients of the recurrences
    run to the seed's last iteration, where that saves flops; otherwise one GEMM per block with the
    coefficients of the iterates as they were when each shift met its tolerance (``stop``).
    """
    c, k = stop.shape
    n, cap = seed_cg.n, seed_cg.cap
    scale, take = post if post is not None else (None, None)
    factors = [None] * c
    if rtol is not None and 20 * min(k, m) < n:
        C = member_coefficients(rec.ra, rec.rb, rec.rz, m)
        factors = [low_rank_factors(C[j], rec.srho[:m, j], RANK_TOL * rtol) for j in range(c)]
    ranks = tuple(0 if f is None else f[0].shape[1] for f in factors)
    if poly is not None:
        factors = [None if f is None else padded_factors(*f) for f in factors]
    full = [j for j in range(c) if factors[j] is None]
    X = np.empty((len(full), k, n)) if full else None
    Cp = {}
    if full:
        C = member_coefficients(rec.ra, rec.rb, rec.rz, m, stop)
        Cp = {j: np.ascontiguousarray(C[j][inv]) for j in full}
    factored = not full                                 # (the receiver may then form the rows itself)
    widths = [None if f is None else f[0].shape[1] for f in factors]
    extra = n * max((w for w in widths if w is not None), default=0) if poly is not None else 0
    W, zbuf = factor_memory(n, widths, emit if poly is not None and factored else None, extra)  # (+ powers' scratch)
    nblocks = -(-m // cap) if m else 0
    for b in range(nblocks):
        t0, t1 = b * cap, min(m, (b + 1) * cap)
        if b:
            seed_cg.replay(b, t0, t1)
        Rv = seed_cg.Rb[:, :t1 - t0]
        for j in range(c):
            if factors[j] is not None:
                gemm(Rv[j], factors[j][1][t0:t1], W[j], True, trans_a=True)
            else:
                gemm(Cp[j][:, t0:t1], Rv[j], X[full.index(j)], b > 0)
    used = cap if nblocks > 1 else max(1, min(m, cap))  # the slots written (their pages are in memory:
    spare = [seed_cg.Rb[j, :used].reshape(-1) for j in range(c)]    # the powers go there)
    seed_cg.release()
    if not nblocks and X is not None:
        X[:] = 0.0
    lefts = [None if f is None else f[0][inv] for f in factors]     # rows in the caller's order
    W = [None if w is None else (w,) for w in W]       # the factor's pieces, side by side
    if poly is not None:
        pis = poly.pis[inv]
        poly.extend(lefts, W, pis, spare, post, zbuf)   # the pieces transformed by post
        for t in range(len(full)):
            X[t] = poly.recover(X[t], pis)
    for j in range(c):
        if factors[j] is None or poly is not None:
            continue
        (P,) = W[j]                                     # rows of W are vertices: the transform is linear
        if scale is not None:
            P *= scale[:, None]
        W[j] = (P if take is None else P[take],)
    if factored and hasattr(emit, "factors"):
        emit.factors(lefts, W)                          # the receiver forms the rows itself
        if hasattr(emit, "spare"):
            emit.spare(spare)                           # (memory in use no longer, its pages touched)
        return nblocks, ranks
    for j in range(c):
        if factors[j] is not None:
            W[j] = W[j][0] if len(W[j]) == 1 else np.concatenate(W[j], axis=1)
    chunk = min(EMIT_ROWS, k)
    buf = np.empty((c, chunk, n if take is None else take.size))    # buf[j]: contiguous rows, one GEMM's output
    for s0 in range(0, k, chunk):
        q = min(chunk, k - s0)
        for j in range(c):
            if factors[j] is not None:
                gemm(lefts[j][s0:s0 + q], W[j], buf[j, :q], trans_b=True)
                continue
            rows = X[full.index(j), s0:s0 + q]
            if scale is not None:
                rows = rows * scale
            buf[j, :q] = rows if take is None else rows[:, take]
        emit(np.arange(s0, s0 + q), buf[:, :q])
    return nblocks, ranks


#: the factor's width is padded with zero columns to a multiple of this before its powers are formed
#: (:meth:`~shapeflow.linalg.shift_polynomial.SeedPolynomial.extend`): the compiled product's loop over
#: the columns then has no scalar remainder (Suzanne ×3's matrix, one thread: 15 columns 1.98 ms,
#: 16 columns 1.39 ms, 2026-11-26)
RANK_MULTIPLE = 8


def padded_factors(left: np.ndarray, right: np.ndarray) -> tuple:
    """(L, R) of :func:`low_rank_factors` with zero columns appended up to a multiple of
    :data:`RANK_MULTIPLE` (L Rᵀ unchanged: the terms added are 0 × 0)."""
    r = left.shape[1]
    pad = -r % RANK_MULTIPLE
    if pad == 0 or r == 0:
        return left, right
    return (np.concatenate([left, np.zeros((left.shape[0], pad))], axis=1),
            np.concatenate([right, np.zeros((right.shape[0], pad))], axis=1))


def gemm(A: np.ndarray, B: np.ndarray, out: np.ndarray, accumulate: bool = False, *, trans_a: bool = False,
         trans_b: bool = False) -> None:
    """``out = op(A) @ op(B)`` (``out +=`` with ``accumulate``; op transposes with ``trans_a``/``trans_b``)
    for C-contiguous ``out``, ``A`` and ``B`` (a transposed operand is read in place), by SciPy's
    BLAS on one thread (:class:`~shapeflow.linalg.blas.SingleThreadBLAS`): OpenBLAS's threads keep
    spinning after a call, which on two shared cores slowed the seed's compiled iterations that
    follow by up to 2× (and the GEMMs themselves are short)."""
    if out.size == 0:
        return
    if A.shape[0 if trans_a else 1] == 0:               # (BLAS refuses empty operands)
        if not accumulate:
            out[:] = 0.0
        return
    with SingleThreadBLAS():                            # outᵀ = op(B)ᵀ op(A)ᵀ on the Fortran views
        r = dgemm(1.0, B.T, A.T, beta=1.0 if accumulate else 0.0, c=out.T, trans_a=int(trans_b),
                  trans_b=int(trans_a), overwrite_c=True)
    if not np.shares_memory(r, out):                    # (a copy where the layout asked for one)
        out[:] = r.T


def low_rank_factors(C: np.ndarray, rho: np.ndarray, tol: float):
    """(L, R) with ``C ≈ L Rᵀ`` (k × r, m × r), or None when the two GEMMs would not save flops.

    ``C`` (k × m) are the coefficients of the k iterates over the seed residuals r_t, whose squared
    norms are ``rho`` (m,).  CG's residuals are mutually orthogonal, so on the normalised residuals
    the coefficient rows *are* the iterates (up to rounding); each row is scaled to norm 1 and the
    SVD truncated after the singular values above ``tol``: every iterate then changes by at most
    ``tol`` × its own norm.  The coefficients of one seed residual vary smoothly with the shift
    (they sample 1/(σ + μ) on the spectrum), so the rank is small (13 of 47 members on the
    figure-1 family at rtol = 1e-8).
    """
    k, m = C.shape
    nr = np.sqrt(np.maximum(rho, 0.0))
    Cn = C * nr
    big = np.max(np.abs(Cn), axis=1, initial=0.0)
    big = np.where(big > 0, big, 1.0)                   # (rows scaled by their largest entry first: the
    Cn /= big[:, None]                                  # squares of iterates ~1e155 and beyond overflow)
    size = np.linalg.norm(Cn, axis=1)
    size = np.where(size > 0, size, 1.0)
    with SingleThreadBLAS():      # a small SVD: OpenBLAS's threads only wait for each other
        U, S, Vt = scipy.linalg.svd(Cn / size[:, None], full_matrices=False, check_finite=False)
    size *= big
    r = int(np.count_nonzero(S > tol))
    if r * (m + k) > LOW_RANK_GAIN * k * m:
        return None
    left = (size[:, None] * U[:, :r]) * S[:r]
    right = Vt[:r].T / np.where(nr > 0, nr, np.inf)[:, None]
    return np.ascontiguousarray(left), np.ascontiguousarray(right)


def member_coefficients(ra: np.ndarray, rb: np.ndarray, rz: np.ndarray, m: int,
                        stop: np.ndarray | None = None) -> np.ndarray:
    """The coefficients (c, k, m) of the seed residuals r_0 … r_{m−1} in each shift's iterate.

    From the recorded α_s(t), β_s(t) and ζ_s(t) (0 where the shift did not move):
    ``p_s(t) = ζ_s(t) r_t + β_s(t) p_s(t−1)`` and ``x_s = Σ_t α_s(t) p_s(t−1)``, so the
    coefficient of r_t is ``ζ_s(t) G_s(t)`` with ``G_s(t) = α_s(t+1) + β_s(t+1) G_s(t+1)``,
    ``G_s(m) = 0``.  ``stop`` (c, k): the iterates after that many iterations (the recurrences
    recorded beyond it are left out).
    """
    c, k = ra.shape[:2]
    ra, rb = ra[:, :, :m + 1], rb[:, :, :m + 1]
    if stop is not None:
        keep = np.arange(m + 1) <= stop[:, :, None]
        ra, rb = ra * keep, rb * keep
    C = np.empty((c, k, m))
    G = np.zeros((c, k))
    for t in range(m - 1, -1, -1):
        G *= rb[:, :, t + 1]
        G += ra[:, :, t + 1]
        np.multiply(rz[:, :, t], G, out=C[:, :, t])
    return C


class Records:
    """The scalars of the first pass: per (column, shift, iteration) α_s, β_s, ζ_s; per
    iteration the seed's α, β and ρ = rᵀr (at least three columns, unused ones 0).  Grown on demand."""

    def __init__(self, c: int, k: int, size: int):
        self.ra = np.zeros((c, k, size))
        self.rb = np.zeros((c, k, size))
        self.rz = np.zeros((c, k, size))
        self.rz[:, :, 0] = 1.0                          # p_s(0) = r_0 for every shift
        self.sa = np.zeros((size, max(3, c)))
        self.sb = np.zeros((size, max(3, c)))
        self.srho = np.zeros((size, max(3, c)))

    def grow(self) -> None:
        for name in ("ra", "rb", "rz"):
            a = getattr(self, name)
            setattr(self, name, np.concatenate([a, np.zeros_like(a)], axis=2))
        for name in ("sa", "sb", "srho"):
            a = getattr(self, name)
            setattr(self, name, np.concatenate([a, np.zeros_like(a)], axis=0))


class NumpySeed:
    """The seed's CG in NumPy (component-major (c, n) vectors): the first pass (records, the first
    block of residuals, the states where later blocks start) and the replay of a later block."""

    def __init__(self, A, B: np.ndarray, seed: float, cap: int, coef: np.ndarray | None = None):
        self.A, self.seed, self.cap, self.coef = A, seed, cap, coef
        self.c, self.n = B.shape
        self.Rb = np.empty((self.c, cap, self.n))       # the block's seed residuals
        self.Rb[:, 0] = B
        self.r = B.copy()
        self.p = B.copy()
        self.Ap = np.zeros_like(B)                      # stays 0 in columns that never run
        self.saved: dict = {}                           # block -> (r, p) at its first iteration
        self.replayed = 0
        self.rec = None

    def release(self) -> None:
        self.Rb = self.r = self.p = self.Ap = None
        self.saved = {}

    def product(self, cols) -> None:
        """Ap = A₀ p (A₀ = A + seed I), or A₀ p(A₀) p with the polynomial's coefficients ``coef``."""
        if self.coef is not None:
            for j in cols:
                self.Ap[j] = self.poly_product(self.p[j])
            return
        for j in cols:                                  # (per column: faster than SciPy's multi-vector product)
            self.Ap[j] = self.A @ self.p[j]
        if self.seed != 0.0:
            self.Ap += self.seed * self.p

    def poly_product(self, v: np.ndarray) -> np.ndarray:
        """A₀ p(A₀) v by Horner's scheme, as the compiled kernel: y = p_d A₀ v + p_{d−1} v, then
        y = A₀ y + p_j v down to j = 0, then A₀ y."""
        coef, A, seed = self.coef, self.A, self.seed
        d = coef.size - 1
        y = coef[d] * (A @ v + seed * v) + coef[d - 1] * v
        for j in range(d - 2, -1, -1):                  # (over the degree)
            y = (A @ y + seed * y) + coef[j] * v
        return A @ y + seed * y

    def first_pass(self, rec: Records, sh: ShiftedSystems, report) -> int:
        c, cap = self.c, self.cap
        self.rec = rec
        delta, rho, tol2, active, live, iterations = sh.delta, sh.rho, sh.tol2, sh.active, sh.live, sh.iterations
        zeta = np.ones((delta.size, c))
        zeta_prev = np.ones((delta.size, c))
        alpha_prev = np.ones(c)
        beta_prev = np.zeros(c)
        done = report(None)
        it = 0
        with np.errstate(divide="ignore", invalid="ignore", over="ignore", under="ignore"):
            while it < sh.maxiter:
                if it + 1 >= rec.sa.shape[0]:
                    rec.grow()
                cols = active.any(axis=0)               # columns still running
                it += 1
                self.product(np.flatnonzero(cols))
                pAp = np.einsum("ij,ij->i", self.p, self.Ap)
                ok = cols & (pAp > 0)
                alpha = np.where(ok, rho / np.where(ok, pAp, 1.0), 0.0)
                self.r -= alpha[:, None] * self.Ap
                if it < cap:
                    self.Rb[:, it] = self.r
                rho_new = np.einsum("ij,ij->i", self.r, self.r)
                beta = np.where(ok & (rho > 0), rho_new / np.where(rho > 0, rho, 1.0), 0.0)
                rec.sa[it, :c], rec.sb[it, :c], rec.srho[it, :c] = alpha, beta, rho_new
                zeta_new, upd, alpha_s, beta_s = shifted_coefficients(zeta, zeta_prev, alpha, alpha_prev, beta,
                                                                      beta_prev, delta[:, None], live & ok)
                zeta_prev = np.where(upd, zeta, zeta_prev)
                zeta = np.where(upd, zeta_new, zeta)
                rec.ra[:, :, it], rec.rb[:, :, it], rec.rz[:, :, it] = alpha_s.T, beta_s.T, zeta.T
                newly = upd & active & (zeta * zeta * rho_new <= tol2)
                iterations[newly] = it
                active &= ~newly
                active &= ok | ~cols                     # a column whose seed broke down is finished
                live &= ok | ~cols
                rho = np.where(ok, rho_new, rho)
                alpha_prev = np.where(ok, alpha, alpha_prev)
                beta_prev = np.where(ok, beta, beta_prev)
                done = report(done)
                if not active.any():
                    break
                self.p *= beta[:, None]
                self.p += self.r
                if it % cap == 0:
                    self.saved[it // cap] = (self.r.copy(), self.p.copy())
        return it

    def replay(self, b: int, t0: int, t1: int) -> None:
        """The residuals r_t0 … r_{t1−1} into the block, from the state saved at t0 (the recorded α and β)."""
        r, p = self.saved.pop(b)
        self.r, self.p = r, p
        self.Rb[:, 0] = r
        cols = np.flatnonzero(self.rec.sa[t0 + 1:t1, :self.c].any(axis=0))
        for t in range(t0 + 1, t1):
            self.product(cols)
            self.r -= self.rec.sa[t, :self.c, None] * self.Ap
            self.Rb[:, t - t0] = self.r
            self.p *= self.rec.sb[t, :self.c, None]
            self.p += self.r
        self.replayed += t1 - t0 - 1


def shifted_residuals(A, B: np.ndarray, shifts: np.ndarray, Y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The true residuals ``‖b_j − (A + s_q I) y_qj‖`` (q, c) of a block of solutions, and ``‖y_qj‖``.

    ``B`` (c, n) the right-hand-side columns (component-major, as :func:`multishift_cg`), ``shifts``
    (q,), ``Y`` (n, q, c) C-contiguous: column j of the solution for ``shifts[q]`` in ``Y[:, q, j]``;
    ``Y`` serves as scratch space (its values are undefined afterwards).  One sparse product for the
    whole block (``A @ Y`` as an (n, q·c) matrix) and five passes over (n, q·c) arrays.
    """
    n, q, c = Y.shape
    Y2 = Y.reshape(n, q * c)
    ynorm = np.sqrt(np.einsum("ij,ij->j", Y2, Y2)).reshape(q, c)
    R = np.asarray(A @ Y2)
    Y2 *= np.repeat(np.asarray(shifts, dtype=np.float64), c)
    R += Y2
    R.reshape(n, q, c)[...] -= B.T[:, None, :]
    return np.sqrt(np.einsum("ij,ij->j", R, R)).reshape(q, c), ynorm


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
