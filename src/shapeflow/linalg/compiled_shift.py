"""Compiled multi-shift CG: the seed's iterations and the shifted recurrences of
:func:`shapeflow.linalg.multishift.multishift_cg` in one loop (:class:`CompiledSeed`, which
:meth:`shapeflow.linalg.compiled.LinalgNumba.multishift_seed` hands out).

With a polynomial preconditioner (:mod:`~shapeflow.linalg.shift_polynomial`) the product is
``A₀ p(A₀) P`` by Horner's scheme, d + 1 passes over the rows.
The NumPy twin is :class:`~shapeflow.linalg.multishift.NumpySeed`, the linalg family's reference
(same formulas in the same order; the sums differ in rounding only); ``tests/linalg/test_multishift.py``
compares the two.  Up to three columns, stored (n, 3) as the flow's CG does (an unused column is
zero and never iterates).  An iteration is d + 3 passes over the rows (the product's d + 1, the
last with its dots; the residual update with its dots and its copy into the block; the direction
update; d = 0 without the polynomial) and O(shifts × block) scalar work; the block's GEMMs stay in NumPy (BLAS).

Each pass over the rows uses numba's threads for the call: ``accel.use(threads=1)`` (or 2, …;
``"auto"``, the default, takes the cores free when the call starts, ``NUMBA_NUM_THREADS`` caps it),
applied by the heavy entry points (``family()``, ``multishift_cg``).  The rows are shared out by
blocks, whose sums are added in block order, so the result has the same bits on any number of
threads (``tests/linalg/test_multishift.py``).  Unlike the flow's symmetric Gauss–Seidel sweeps, which
are sequential, the seed's products split: 48 members (λ = 0 … −235) on Suzanne ×3 take ~0.75× their
one-thread time when both cores are free (docs/performance.md).
The seed's kernels are compiled with ``fastmath={"contract"}`` alone: a multiply and the add that
follows become one fused multiply-add (a product of Suzanne ×3's matrix with three columns 0.34 ms
against 0.40 ms without, the seed's iterations ~96 against ~109 ms on one thread, 2026-11-26), and
nothing is reassociated, so the
sums keep their order and the same bits on any number of threads (their parallel and one-thread builds
fuse the same operations: ``tests/linalg/test_multishift.py``).  :func:`rows_product` is compiled without
it: its parallel build and its sequential twin fused differently (measured), and it gained nothing.
Conventions of all compiled kernels: :mod:`shapeflow.accel`.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from numba import get_num_threads, njit, prange

# what :func:`run` returns: every (shift, column) finished, a block boundary passed (save the
# state), a shift finished in every column (report progress), the iteration cap, the records are
# full (grow them)
from ..accel import sequential
from .compiled import BLOCK, entries_times3, int32_csr, sum_blocks, thread_rows
from .multishift import CAPPED, CHECKPOINT, DONE, GROW, PROGRESS, NumpySeed, Records, ShiftedSystems

__all__ = ["CompiledSeed", "run", "replay", "shifted_powers", "rows_product", "rows_product_seq", "DONE", "CAPPED",
           "PROGRESS_EVERY"]

#: the seed's kernels' ``fastmath``: multiply-adds fused, nothing reassociated (see the module's docstring)
FUSED = {"contract"}

#: iterations between two returns to report finished shifts (each return and report costs ~0.1 ms;
#: the last shifts are reported when the pass ends)
PROGRESS_EVERY = 8


@njit(cache=True, fastmath=FUSED)
def _product(indptr, indices, data, seed, P, AP, nt):
    """AP = (A + seed I) P for the three columns of P (n, 3); returns pᵀAp per column."""
    return _apply_dot(indptr, indices, data, seed, P, P, AP, nt)


@njit(inline="always")
def _shifted_row(indptr, indices, data, seed, X, i):
    """Row i of (A + seed I) X, three columns."""
    a0, a1, a2 = entries_times3(indptr[i], indptr[i + 1], indices, data, X)
    return a0 + seed * X[i, 0], a1 + seed * X[i, 1], a2 + seed * X[i, 2]


# The passes over the rows below share them out between ``nt`` threads as runs of whole blocks of
# ``linalg.compiled.BLOCK`` rows; their sums are partial sums per block, added in block order, so a
# pass gives the same bits on any number of threads.  On one thread plain loops run instead (the
# same sums): a loop from row 0 is ~8 % faster than a thread's run of blocks on one thread (0.44 vs
# 0.48 ms per product on Suzanne ×3), and a block's sums kept in its own loop ~40 % faster than
# stored at its last row (the residual's update: 0.069 vs 0.107 ms).

@njit(inline="always")
def _combine_row(indptr, indices, data, seed, X, sx, P, sp_, Y, i):
    a0, a1, a2 = _shifted_row(indptr, indices, data, seed, X, i)
    Y[i, 0] = sx * a0 + sp_ * P[i, 0]
    Y[i, 1] = sx * a1 + sp_ * P[i, 1]
    Y[i, 2] = sx * a2 + sp_ * P[i, 2]


@njit(inline="always")
def _direction_row(P, R, b0, b1, b2, i):
    P[i, 0] = R[i, 0] + b0 * P[i, 0]
    P[i, 1] = R[i, 1] + b1 * P[i, 1]
    P[i, 2] = R[i, 2] + b2 * P[i, 2]


@njit(inline="always")
def _apply_block(indptr, indices, data, seed, X, P, AP, part, b):
    """Rows of block b of AP = (A + seed I) X; its partial sums of pᵀAp into part[b]."""
    s0 = 0.0
    s1 = 0.0
    s2 = 0.0
    for i in range(b * BLOCK, min(indptr.size - 1, (b + 1) * BLOCK)):
        a0, a1, a2 = _shifted_row(indptr, indices, data, seed, X, i)
        AP[i, 0] = a0
        AP[i, 1] = a1
        AP[i, 2] = a2
        s0 += P[i, 0] * a0
        s1 += P[i, 1] * a1
        s2 += P[i, 2] * a2
    part[b, 0] = s0
    part[b, 1] = s1
    part[b, 2] = s2


@njit(inline="always")
def _residual_block(R, AP, a0, a1, a2, Rb, slot, c, store, part, b):
    """Rows of block b of R −= αAP (copied into Rb[:, slot] when ``store``); partial sums of rᵀr into part[b]."""
    s0 = 0.0
    s1 = 0.0
    s2 = 0.0
    for i in range(b * BLOCK, min(R.shape[0], (b + 1) * BLOCK)):
        r0 = R[i, 0] - a0 * AP[i, 0]
        r1 = R[i, 1] - a1 * AP[i, 1]
        r2 = R[i, 2] - a2 * AP[i, 2]
        R[i, 0] = r0
        R[i, 1] = r1
        R[i, 2] = r2
        s0 += r0 * r0
        s1 += r1 * r1
        s2 += r2 * r2
        if store:
            Rb[0, slot, i] = r0
            if c > 1:
                Rb[1, slot, i] = r1
                if c > 2:
                    Rb[2, slot, i] = r2
    part[b, 0] = s0
    part[b, 1] = s1
    part[b, 2] = s2


@njit(parallel=True, cache=True, fastmath=FUSED)
def _combine_par(indptr, indices, data, seed, X, sx, P, sp_, Y, nt):
    n = indptr.size - 1
    nb = (n + BLOCK - 1) // BLOCK
    nt = max(1, min(nt, nb))
    for t in prange(nt):
        i0, i1 = thread_rows(t, nt, nb, n)
        for i in range(i0, i1):
            _combine_row(indptr, indices, data, seed, X, sx, P, sp_, Y, i)


@njit(cache=True, fastmath=FUSED)
def _combine(indptr, indices, data, seed, X, sx, P, sp_, Y, nt):
    """Y = sx (A + seed I) X + sp P (three columns)."""
    if nt > 1:
        _combine_par(indptr, indices, data, seed, X, sx, P, sp_, Y, nt)
        return
    for i in range(indptr.size - 1):
        _combine_row(indptr, indices, data, seed, X, sx, P, sp_, Y, i)


@njit(parallel=True, cache=True, fastmath=FUSED)
def _apply_dot_par(indptr, indices, data, seed, X, P, AP, part, nt):
    nb = part.shape[0]
    nt = max(1, min(nt, nb))
    for t in prange(nt):
        for b in range(t * nb // nt, (t + 1) * nb // nt):      # (thread_rows' run, as blocks)
            _apply_block(indptr, indices, data, seed, X, P, AP, part, b)


@njit(cache=True, fastmath=FUSED)
def _apply_dot(indptr, indices, data, seed, X, P, AP, nt):
    """AP = (A + seed I) X for the three columns of X (n, 3); returns pᵀ(AP) per column, p from P."""
    part = np.zeros(((indptr.size - 1 + BLOCK - 1) // BLOCK, 3))
    if nt > 1:
        _apply_dot_par(indptr, indices, data, seed, X, P, AP, part, nt)
    else:
        for b in range(part.shape[0]):
            _apply_block(indptr, indices, data, seed, X, P, AP, part, b)
    return sum_blocks(part)


@njit(parallel=True, cache=True, fastmath=FUSED)
def _residual_par(R, AP, alpha, Rb, slot, c, part, nt):
    nb = part.shape[0]
    nt = max(1, min(nt, nb))
    store = slot < Rb.shape[1]
    for t in prange(nt):
        for b in range(t * nb // nt, (t + 1) * nb // nt):      # (thread_rows' run, as blocks)
            _residual_block(R, AP, alpha[0], alpha[1], alpha[2], Rb, slot, c, store, part, b)


@njit(cache=True, fastmath=FUSED)
def _residual(R, AP, alpha, Rb, slot, c, nt):
    """R −= αAP (three columns), its first ``c`` columns copied into ``Rb[:, slot]`` when ``slot`` is
    inside the block; returns rᵀr per column."""
    part = np.zeros(((R.shape[0] + BLOCK - 1) // BLOCK, 3))
    if nt > 1:
        _residual_par(R, AP, alpha, Rb, slot, c, part, nt)
    else:
        store = slot < Rb.shape[1]
        for b in range(part.shape[0]):
            _residual_block(R, AP, alpha[0], alpha[1], alpha[2], Rb, slot, c, store, part, b)
    return sum_blocks(part)


@njit(parallel=True, cache=True, fastmath=FUSED)
def _direction_par(P, R, beta, nt):
    n = P.shape[0]
    nb = (n + BLOCK - 1) // BLOCK
    nt = max(1, min(nt, nb))
    for t in prange(nt):
        i0, i1 = thread_rows(t, nt, nb, n)
        for i in range(i0, i1):
            _direction_row(P, R, beta[0], beta[1], beta[2], i)


@njit(cache=True, fastmath=FUSED)
def _direction(P, R, beta, nt):
    """P = R + βP (three columns)."""
    if nt > 1:
        _direction_par(P, R, beta, nt)
        return
    b0 = beta[0]
    b1 = beta[1]
    b2 = beta[2]
    for i in range(P.shape[0]):
        _direction_row(P, R, b0, b1, b2, i)


@njit(cache=True, fastmath=FUSED)
def _poly_product(indptr, indices, data, seed, coef, P, AP, T, U, nt):
    """AP = A₀ p(A₀) P (A₀ = A + seed I, p of degree ≥ 1 with monomial coefficients ``coef``) by
    Horner's scheme, as ``NumpySeed.poly_product``: T and U scratch (n, 3); returns pᵀAp per column."""
    d = coef.size - 1
    _combine(indptr, indices, data, seed, P, coef[d], P, coef[d - 1], T, nt)
    src = T
    dst = U
    for j in range(d - 2, -1, -1):
        _combine(indptr, indices, data, seed, src, 1.0, P, coef[j], dst, nt)
        src, dst = dst, src
    return _apply_dot(indptr, indices, data, seed, src, P, AP, nt)


@njit(cache=True, fastmath=FUSED)
def _seed_product(indptr, indices, data, seed, coef, P, AP, T, U, nt):
    """The seed's operator applied to P: A₀ P when ``coef`` is empty, else :func:`_poly_product`."""
    if coef.size == 0:
        return _product(indptr, indices, data, seed, P, AP, nt)
    return _poly_product(indptr, indices, data, seed, coef, P, AP, T, U, nt)


# (error_model: x / 0 is ±inf or NaN, as in NumpySeed: ζ of a finished shift)
@njit(cache=True, error_model="numpy", fastmath=FUSED)
def run(indptr, indices, data, seed, coef, P, AP, T, U, R, Rb, delta, zeta, zeta_prev, rho, alpha_prev, beta_prev,
        tol2, active, live, iterations, ra, rb, rz, sa, sb, srho, state, maxiter, nt):
    """The first pass of ``NumpySeed.first_pass`` until a block boundary, a finished shift, the end,
    the cap or full records (the returned code); ``state[0]`` counts the iterations, ``state[1]`` is the
    last one that returned ``PROGRESS`` (at most one every :data:`PROGRESS_EVERY` iterations).

    P, AP, R: the seed's direction, product and residual (n, 3), ``coef`` the polynomial
    preconditioner's coefficients (empty: none) and T, U its scratch (n, 3); Rb (c, cap, n) the first block of
    residuals (r_t in slot t); ζ, ``active`` (not yet within the tolerance) and ``live`` (recurrence
    still running) per (shift, column); ρ, α, β per column (3,);
    the records ``ra, rb, rz`` (c, k, L) and ``sa, sb, srho`` (L, 3) are filled at each iteration.
    """
    c = Rb.shape[0]
    cap = Rb.shape[1]
    k = delta.size
    alpha = np.zeros(3)
    beta = np.zeros(3)
    ok = np.zeros(3, np.bool_)
    cols = np.zeros(3, np.bool_)
    while state[0] < maxiter:
        if state[0] + 1 >= sa.shape[0]:
            return GROW
        state[0] += 1
        it = state[0]
        for j in range(3):
            cols[j] = False
        for s in range(k):
            for j in range(c):
                if active[s, j]:
                    cols[j] = True
        pap = _seed_product(indptr, indices, data, seed, coef, P, AP, T, U, nt)
        for j in range(3):
            ok[j] = cols[j] and pap[j] > 0.0
            alpha[j] = rho[j] / pap[j] if ok[j] else 0.0
        rho_new = _residual(R, AP, alpha, Rb, it, c, nt)
        for j in range(3):
            beta[j] = rho_new[j] / rho[j] if (ok[j] and rho[j] > 0.0) else 0.0
            sa[it, j] = alpha[j]
            sb[it, j] = beta[j]
            srho[it, j] = rho_new[j]
        finished = False
        for s in range(k):
            d = delta[s]
            for j in range(c):
                a_s = 0.0
                b_s = 0.0
                if live[s, j] and ok[j]:
                    zt = zeta[s, j]
                    zp = zeta_prev[s, j]
                    den = (alpha_prev[j] * zp * (1.0 + alpha[j] * d)
                           + alpha[j] * beta_prev[j] * (zp - zt))
                    zn = zt * zp * alpha_prev[j] / den
                    ratio = zn / zt
                    if np.isfinite(ratio):
                        a_s = alpha[j] * ratio
                        b_s = beta[j] * ratio * ratio
                        zeta_prev[s, j] = zt
                        zeta[s, j] = zn
                        if active[s, j] and zn * zn * rho_new[j] <= tol2[j]:
                            iterations[s, j] = it
                            active[s, j] = False
                            finished = True
                ra[j, s, it] = a_s
                rb[j, s, it] = b_s
                rz[j, s, it] = zeta[s, j]
        running = False
        for j in range(c):
            if cols[j] and not ok[j]:          # a column whose seed broke down is finished
                for s in range(k):
                    active[s, j] = False
                    live[s, j] = False
            if ok[j]:
                rho[j] = rho_new[j]
                alpha_prev[j] = alpha[j]
                beta_prev[j] = beta[j]
            for s in range(k):
                if active[s, j]:
                    running = True
        if not running:
            return DONE
        _direction(P, R, beta, nt)
        if it % cap == 0:
            return CHECKPOINT
        if finished and it - state[1] >= PROGRESS_EVERY:
            state[1] = it
            return PROGRESS
    return CAPPED


@njit(cache=True, fastmath=FUSED)
def replay(indptr, indices, data, seed, coef, P, AP, T, U, R, Rb, sa, sb, t0, t1, nt):
    """The residuals r_t0 … r_{t1−1} into ``Rb[:, 0 … t1−t0−1]`` from R = r_t0, P = p_t0 (the state
    saved after iteration t0) with the recorded α and β: the first pass's arithmetic, so the same bits."""
    c = Rb.shape[0]
    n = R.shape[0]
    for j in range(c):
        for i in range(n):
            Rb[j, 0, i] = R[i, j]
    for t in range(t0 + 1, t1):
        _seed_product(indptr, indices, data, seed, coef, P, AP, T, U, nt)
        _residual(R, AP, sa[t], Rb, t - t0, c, nt)
        _direction(P, R, sb[t], nt)


class CompiledSeed(NumpySeed):
    """The seed's CG of :class:`~shapeflow.linalg.multishift.NumpySeed` compiled ((n, 3) vectors,
    unused columns 0): :func:`run` and :func:`replay`."""

    def __init__(self, A, B: np.ndarray, seed: float, cap: int, coef: np.ndarray | None = None):
        self.A, self.seed, self.cap = A, seed, cap
        self.c, self.n = B.shape
        self.coef = np.zeros(0) if coef is None else np.ascontiguousarray(coef, dtype=np.float64)
        d = max(self.coef.size - 1, 0)                 # the polynomial's scratch: none, T, or T and U
        self.T = np.empty((self.n if d >= 1 else 0, 3))
        self.U = np.empty((self.n, 3)) if d >= 2 else self.T
        self.indptr = A.indptr.astype(np.int32, copy=False)
        self.indices = A.indices.astype(np.int32, copy=False)
        self.data = np.ascontiguousarray(A.data, dtype=np.float64)
        self.Rb = np.empty((self.c, cap, self.n))
        self.Rb[:, 0] = B
        self.P = np.zeros((self.n, 3))
        self.P[:, :self.c] = B.T
        self.R = self.P.copy()
        self.AP = np.empty((self.n, 3))
        self.saved = {}
        self.replayed = 0
        self.rec = None

    def release(self) -> None:
        self.Rb = self.P = self.R = self.AP = self.T = self.U = None
        self.saved = {}

    def first_pass(self, rec: Records, sh: ShiftedSystems, report) -> int:
        c = self.c
        self.rec = rec
        delta, rho, tol2, active, iterations = sh.delta, sh.rho, sh.tol2, sh.active, sh.iterations
        k = delta.size
        zeta, zeta_prev = np.ones((k, c)), np.ones((k, c))
        rho3, tol3 = np.zeros(3), np.zeros(3)
        rho3[:c], tol3[:c] = rho, tol2
        alpha_prev, beta_prev = np.ones(3), np.zeros(3)
        state = np.zeros(2, np.int64)
        done = report(None)
        while True:
            st = run(self.indptr, self.indices, self.data, self.seed, self.coef, self.P, self.AP, self.T, self.U,
                     self.R, self.Rb, delta, zeta, zeta_prev, rho3, alpha_prev, beta_prev, tol3, active, sh.live,
                     iterations, rec.ra, rec.rb, rec.rz, rec.sa, rec.sb, rec.srho, state, sh.maxiter,
                     get_num_threads())
            done = report(done)
            if st == GROW:
                rec.grow()
            elif st == CHECKPOINT:
                self.saved[int(state[0]) // self.cap] = (self.R.copy(), self.P.copy())
            elif st != PROGRESS:
                return int(state[0])

    def replay(self, b: int, t0: int, t1: int) -> None:
        self.R, self.P = self.saved.pop(b)
        replay(self.indptr, self.indices, self.data, self.seed, self.coef, self.P, self.AP, self.T, self.U,
               self.R, self.Rb, self.rec.sa, self.rec.sb, t0, t1, get_num_threads())
        self.replayed += t1 - t0 - 1


def shifted_powers(A, seed, Y, degree, out=None, take=None, scale=None):
    """``LinalgKernels.shifted_powers`` compiled for an int32 CSR matrix and ``take`` None or a
    permutation: each power in one pass over the matrix (:func:`rows_product`), its rows written scaled
    and in place; None where it does not apply (the caller falls back to the reference)."""
    n = Y.shape[0]
    pos = np.arange(n) if take is None else None
    if take is not None and take.size == n:
        pos = np.full(n, -1, np.int64)
        pos[take] = np.arange(n)            # row s goes to row pos[s]
        if (pos < 0).any():
            pos = None                      # not a permutation: the reference gathers
    if (not (sp.issparse(A) and A.format == "csr" and int32_csr(A)) or Y.dtype != np.float64
            or pos is None or degree < 1):
        return None
    data = np.ascontiguousarray(A.data, dtype=np.float64)
    out = list(out or [])
    mem = [out[i] if i < len(out) else np.empty(Y.shape) for i in range(degree + 2)]
    sc = _NO_SCALE if scale is None else np.ascontiguousarray(scale, dtype=np.float64)
    res = [mem[i] for i in range(degree + 1)]
    scratch = [mem[degree + 1], np.empty(Y.shape) if degree > 2 else None]
    src = np.ascontiguousarray(Y)
    nt = get_num_threads()
    for i in range(1, degree + 1):          # each power in the solve's order too, for the next one
        keep = scratch[(i - 1) % 2] if i < degree else res[i]      # (not stored after the last)
        (rows_product if nt > 1 else rows_product_seq)(A.indptr, A.indices, data, float(seed), src, keep,
                                                       i < degree, res[i], pos, sc,
                                                       res[0] if i == 1 else _NO_ROWS2, nt)
        src = keep
    return res


#: ``rows_product``'s empty arguments: no scale, no copy of the input rows
_NO_SCALE = np.zeros(0)
_NO_ROWS2 = np.zeros((0, 1))


@njit(parallel=True, cache=True)
def rows_product(indptr, indices, data, seed, Y, Z, store, Zt, pos, sc, Yt, nt):
    """For Y (n, r) C-contiguous of any width r, one pass over the matrix for all r columns: row s of
    (A + seed I) Y into row s of Z (when ``store``) and, times ``sc[s]`` (``sc`` empty: 1), into row
    ``pos[s]`` of ``Zt``; with ``Yt`` non-empty, row s of Y times ``sc[s]`` into its row ``pos[s]``.
    The rows are shared out between ``nt`` threads as runs of whole blocks (no sums: the same bits
    on any number of threads)."""
    n = indptr.size - 1
    r = Y.shape[1]
    scaled = sc.size > 0
    copy = Yt.shape[0] > 0
    nb = (n + BLOCK - 1) // BLOCK
    nt = max(1, min(nt, nb))
    for th in prange(nt):
        acc = np.empty(r)
        i0, i1 = thread_rows(th, nt, nb, n)
        for i in range(i0, i1):
            for t in range(r):
                acc[t] = seed * Y[i, t]
            for q in range(indptr[i], indptr[i + 1]):
                j = np.uint64(indices[q])
                v = data[q]
                for t in range(r):
                    acc[t] += v * Y[j, t]
            if store:
                for t in range(r):
                    Z[i, t] = acc[t]
            o = pos[i]
            s = sc[i] if scaled else 1.0
            for t in range(r):
                Zt[o, t] = acc[t] * s
            if copy:
                for t in range(r):
                    Yt[o, t] = Y[i, t] * s


rows_product_seq = sequential(rows_product)
