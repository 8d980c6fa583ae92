"""Compiled linear algebra: the three-column CGs (Jacobi, symmetric Gauss–Seidel) and the Chebyshev (Clenshaw) step.

:class:`LinalgNumba` is the numba implementation of the linalg family; the NumPy/SciPy reference
is :class:`shapeflow.linalg.kernels.LinalgKernels`, and the tests compare the two.
Conventions of all compiled kernels: :mod:`shapeflow.accel`.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from numba import get_num_threads, njit, prange

from ..accel import sequential, zeros
from .kernels import LinalgKernels
from .pairs import PairMatrix


@njit(inline="always")
def entries_times3(q0, q1, indices, data, B):
    """The CSR entries q0 … q1 − 1 of a row of A times the three columns of B."""
    a0 = 0.0
    a1 = 0.0
    a2 = 0.0
    for q in range(q0, q1):
        j = np.uint64(indices[q])   # unsigned: no negative-index wraparound test per access
        v = data[q]
        a0 += v * B[j, 0]
        a1 += v * B[j, 1]
        a2 += v * B[j, 2]
    return a0, a1, a2


#: rows per block of the dot products: partial sums per block, added in block order, so the result
#: does not depend on the number of threads (a parallel reduction's order would)
BLOCK = 4096


@njit(inline="always")
def thread_rows(t, nt, nb, n):
    """Rows i0 … i1 − 1 of thread t's run when the n rows, ``nb`` blocks of :data:`BLOCK`, are shared out
    between ``nt`` threads as runs of whole blocks (the blocks b0 … b1 − 1, b0 = i0 / BLOCK)."""
    return (t * nb // nt) * BLOCK, min(n, ((t + 1) * nb // nt) * BLOCK)


@njit(cache=True)
def sum_blocks(part):
    out = np.zeros(3)
    for b in range(part.shape[0]):
        out[0] += part[b, 0]
        out[1] += part[b, 1]
        out[2] += part[b, 2]
    return out


@njit(inline="always")
def _flush(part, i, i1, s0, s1, s2):
    """At the last row of a block (or of a thread's run, ``i1``), store the block's partial sums and
    start the next block from zero."""
    if (i + 1) % BLOCK == 0 or i + 1 == i1:
        b = i // BLOCK
        part[b, 0] = s0
        part[b, 1] = s1
        part[b, 2] = s2
        return 0.0, 0.0, 0.0
    return s0, s1, s2


@njit(parallel=True, cache=True, fastmath=False)
def _spmm_dot(indptr, indices, data, P, AP, nt):
    """AP = A P (P, AP are (n, 3)); returns the column dots pᵀAp (the same bits on any number ``nt`` of threads).

    Each thread takes a run of whole blocks and walks its rows in one loop, keeping the end of
    the last row for the start of the next (one ``indptr`` read per row) and storing its partial
    sums at every block boundary.  On one thread the sequential build runs (``_spmm_dot_seq``):
    1.61 ms per product on Suzanne 126K triangulated against 1.75 ms for the previous layout (one
    parallel iteration per block, nested row loop) on one thread (2026-11-24).
    """
    n = indptr.size - 1
    nb = (n + BLOCK - 1) // BLOCK
    part = np.zeros((nb, 3))
    nt = max(1, min(nt, nb))
    for t in prange(nt):
        i0, i1 = thread_rows(t, nt, nb, n)
        s0 = 0.0
        s1 = 0.0
        s2 = 0.0
        q0 = indptr[i0] if i0 < i1 else 0
        for i in range(i0, i1):
            q1 = indptr[i + 1]
            a0, a1, a2 = entries_times3(q0, q1, indices, data, P)
            q0 = q1
            AP[i, 0] = a0
            AP[i, 1] = a1
            AP[i, 2] = a2
            s0 += a0 * P[i, 0]
            s1 += a1 * P[i, 1]
            s2 += a2 * P[i, 2]
            s0, s1, s2 = _flush(part, i, i1, s0, s1, s2)
    return sum_blocks(part)


@njit(parallel=True, cache=True, fastmath=False)
def _update_xr(X, R, P, AP, minv, alpha, nt):
    """X += αP, R −= αAP; returns the column dots rᵀM⁻¹r of the new residual (blocked, as _spmm_dot)."""
    n = X.shape[0]
    a0 = alpha[0]
    a1 = alpha[1]
    a2 = alpha[2]
    nb = (n + BLOCK - 1) // BLOCK
    part = np.zeros((nb, 3))
    nt = max(1, min(nt, nb))
    for t in prange(nt):
        i0, i1 = thread_rows(t, nt, nb, n)
        s0 = 0.0
        s1 = 0.0
        s2 = 0.0
        for i in range(i0, i1):
            m = minv[i]
            X[i, 0] += a0 * P[i, 0]
            X[i, 1] += a1 * P[i, 1]
            X[i, 2] += a2 * P[i, 2]
            r0 = R[i, 0] - a0 * AP[i, 0]
            r1 = R[i, 1] - a1 * AP[i, 1]
            r2 = R[i, 2] - a2 * AP[i, 2]
            R[i, 0] = r0
            R[i, 1] = r1
            R[i, 2] = r2
            s0 += r0 * r0 * m
            s1 += r1 * r1 * m
            s2 += r2 * r2 * m
            s0, s1, s2 = _flush(part, i, i1, s0, s1, s2)
    return sum_blocks(part)


@njit(parallel=True, cache=True, fastmath=False)
def _update_p(P, R, minv, beta):
    n = P.shape[0]
    b0 = beta[0]
    b1 = beta[1]
    b2 = beta[2]
    for i in prange(n):
        m = minv[i]
        P[i, 0] = R[i, 0] * m + b0 * P[i, 0]
        P[i, 1] = R[i, 1] * m + b1 * P[i, 1]
        P[i, 2] = R[i, 2] * m + b2 * P[i, 2]


# one thread: the sequential builds (same sums in the same order, so the same bits; see accel.sequential)
_spmm_dot_seq = sequential(_spmm_dot)
_update_xr_seq = sequential(_update_xr)
_update_p_seq = sequential(_update_p)


def pcg3(indptr, indices, data, minv, B, X, rtol, maxiter, overwrite_b=False):
    """Jacobi-PCG on the columns of B (n, 3), X (n, 3) warm start, updated in place.

    Same algorithm and stopping rule as ``LinalgKernels.cg``: a column stops
    (α = 0, β = 1) once its preconditioned residual norm fell below ``rtol`` ×
    its initial value.  Returns the iteration count.  ``overwrite_b``: B
    becomes the residual's storage (one (n, 3) array less to allocate).
    """
    # first touched here, not from both threads inside the loops
    work = zeros((2 if overwrite_b else 3, B.shape[0], 3))
    R = B if overwrite_b else work[2]
    return _pcg3(False, indptr, indices, data, _NO_PAIRS, _NO_F8, _NO_FREE, _NO_F8, minv, B, X, rtol, maxiter,
                 work[0], work[1], R, get_num_threads())


_NO_PAIRS = np.zeros((0, 2), np.int32)
_NO_F8 = np.zeros(0)
_NO_FREE = np.zeros(0, np.bool_)
_NO_INT = np.zeros(1, np.int32)


@njit(inline="always")
def _product(use_pairs, indptr, indices, data, pairs, w, free, d, P, AP, nt):
    if use_pairs:
        return _spmm_pairs_dot(pairs, w, free, d, P, AP)
    if nt == 1:
        return _spmm_dot_seq(indptr, indices, data, P, AP, nt)
    return _spmm_dot(indptr, indices, data, P, AP, nt)


@njit(cache=True)
def _start(U, V, s, R, P):
    """R = U − V (the first residual; R may be U), P = s R (the first direction, s the preconditioner's
    diagonal); returns rᵀs r per column (row order)."""
    rz = np.zeros(3)
    for i in range(R.shape[0]):
        m = s[i]
        for c in range(3):
            r = U[i, c] - V[i, c]
            R[i, c] = r
            P[i, c] = r * m
            rz[c] += r * r * m
    return rz


@njit(cache=True)
def _active(rz, tol2):
    """Whether some column's preconditioned residual is still above its tolerance."""
    for c in range(3):
        if rz[c] > tol2[c]:
            return True
    return False


@njit(cache=True)
def _step_sizes(rz, pap, tol2, alpha):
    """α = rᵀz / pᵀAp per column; 0 for a column that has stopped (or a non-positive pᵀAp)."""
    for c in range(3):
        alpha[c] = rz[c] / pap[c] if (pap[c] > 0.0 and rz[c] > tol2[c]) else 0.0


@njit(cache=True)
def _directions(rz, rz_new, alpha, beta):
    """β = new rᵀz / old rᵀz per column; a stopped column (α = 0) keeps its rᵀz with β = 1.
    Returns the rᵀz to carry on with."""
    for c in range(3):
        beta[c] = rz_new[c] / rz[c] if rz[c] > 0.0 else 0.0
        if alpha[c] == 0.0:
            rz_new[c] = rz[c]
            beta[c] = 1.0
    return rz_new


@njit(cache=True)
def _pcg3(use_pairs, indptr, indices, data, pairs, w, free, d, minv, B, X, rtol, maxiter, P, AP, R, nt):
    """R may be B itself: B is read once, before R is written.  The product is A's CSR
    (``indptr, indices, data``) or, with ``use_pairs``, a PairMatrix (``pairs, w, free, d``)."""
    _product(use_pairs, indptr, indices, data, pairs, w, free, d, X, AP, nt)
    rz = _start(B, AP, minv, R, P)
    tol2 = rz * (rtol * rtol)
    alpha = np.zeros(3)
    beta = np.ones(3)
    it = 0
    while it < maxiter and _active(rz, tol2):
        it += 1
        pap = _product(use_pairs, indptr, indices, data, pairs, w, free, d, P, AP, nt)
        _step_sizes(rz, pap, tol2, alpha)
        if nt == 1:
            rz_new = _update_xr_seq(X, R, P, AP, minv, alpha, nt)
        else:
            rz_new = _update_xr(X, R, P, AP, minv, alpha, nt)
        rz = _directions(rz, rz_new, alpha, beta)
        if nt == 1:
            _update_p_seq(P, R, minv, beta)
        else:
            _update_p(P, R, minv, beta)
    return it


@njit(cache=True)
def weighted_col_norms2(c, X):
    """Σ_i c_i X_ij² for the three columns of X (n, 3), in row order."""
    s0 = 0.0
    s1 = 0.0
    s2 = 0.0
    for i in range(X.shape[0]):
        ci = c[i]
        s0 += ci * X[i, 0] * X[i, 0]
        s1 += ci * X[i, 1] * X[i, 1]
        s2 += ci * X[i, 2] * X[i, 2]
    return np.array([s0, s1, s2])


@njit(parallel=True, cache=True, fastmath=False)
def clenshaw_step(indptr, indices, data, cinv, B1, B2, X0, H0, f, alpha, beta, cu, ch):
    """One step of ``solvers.chebyshev_steps``: B2 <- f·Ã B1 − B2 + cu X0 + ch H0 (in place), fused."""
    n = indptr.size - 1
    for i in prange(n):
        a0, a1, a2 = entries_times3(indptr[i], indptr[i + 1], indices, data, B1)
        ci = cinv[i] * alpha
        B2[i, 0] = f * (ci * a0 - beta * B1[i, 0]) - B2[i, 0] + cu * X0[i, 0] + ch * H0[i, 0]
        B2[i, 1] = f * (ci * a1 - beta * B1[i, 1]) - B2[i, 1] + cu * X0[i, 1] + ch * H0[i, 1]
        B2[i, 2] = f * (ci * a2 - beta * B1[i, 2]) - B2[i, 2] + cu * X0[i, 2] + ch * H0[i, 2]


@njit(cache=True)
def _spmm_pairs_dot(pairs, w, free, d, P, AP):
    """AP = A P for a :class:`~shapeflow.linalg.pairs.PairMatrix` (diagonal, then the free pairs in
    order); returns the column dots pᵀAp, summed in row order."""
    n = P.shape[0]
    for i in range(n):
        di = d[i]
        AP[i, 0] = di * P[i, 0]
        AP[i, 1] = di * P[i, 1]
        AP[i, 2] = di * P[i, 2]
    for p in range(pairs.shape[0]):
        a = np.uint64(pairs[p, 0])
        b = np.uint64(pairs[p, 1])
        if free[a] and free[b]:
            wp = w[p]
            AP[a, 0] -= wp * P[b, 0]
            AP[a, 1] -= wp * P[b, 1]
            AP[a, 2] -= wp * P[b, 2]
            AP[b, 0] -= wp * P[a, 0]
            AP[b, 1] -= wp * P[a, 1]
            AP[b, 2] -= wp * P[a, 2]
    out = np.zeros(3)
    for i in range(n):
        out[0] += AP[i, 0] * P[i, 0]
        out[1] += AP[i, 1] * P[i, 1]
        out[2] += AP[i, 2] * P[i, 2]
    return out


def pcg3_pairs(pairs, w, free, d, minv, B, X, rtol, maxiter, overwrite_b=False):
    """:func:`pcg3` on a :class:`~shapeflow.linalg.pairs.PairMatrix` (its pairs, weights, free mask and
    diagonal): the same iteration and stopping rule, the product by a sequential scatter (one thread,
    so the same bits on any machine)."""
    work = zeros((2 if overwrite_b else 3, B.shape[0], 3))
    R = B if overwrite_b else work[2]
    return _pcg3(True, _NO_INT, _NO_INT, _NO_F8, pairs, w, free, d, minv, B, X, rtol, maxiter, work[0], work[1], R,
                 get_num_threads())


def row_splits(indptr, indices):
    """Per row, where its strictly lower and strictly upper parts end and start: ``(lo_end, up_start)``
    with columns ``< i`` in ``[indptr[i], lo_end[i])`` and ``> i`` in ``[up_start[i], indptr[i+1])``;
    None when some row's columns are not sorted (duplicates allowed)."""
    n = indptr.size - 1
    lo_end = np.empty(n, np.int64)
    up_start = np.empty(n, np.int64)
    return (lo_end, up_start) if _row_splits(indptr, indices, lo_end, up_start) else None


@njit(cache=True)
def _row_splits(indptr, indices, lo_end, up_start):
    for i in range(indptr.size - 1):
        e = indptr[i + 1]
        a = e
        b = e
        prev = -1
        for q in range(indptr[i], e):
            j = indices[q]
            if j < prev:
                return False
            prev = j
            if j >= i and a == e:
                a = q
            if j > i and b == e:
                b = q
        lo_end[i] = a
        up_start[i] = b
    return True


@njit(inline="always")
def _minus_row(q0, q1, indices, data, Y, s0, s1, s2):
    """(s0, s1, s2) − Σ a_q Y[j_q] over the entries q0 … q1 − 1 of a row (three columns)."""
    for q in range(q0, q1):
        j = np.uint64(indices[q])
        v = data[q]
        s0 -= v * Y[j, 0]
        s1 -= v * Y[j, 1]
        s2 -= v * Y[j, 2]
    return s0, s1, s2


def sgs_pcg3(indptr, indices, data, splits, d, B, X, rtol, maxiter, overwrite_b=False):
    """Conjugate gradients preconditioned by symmetric Gauss–Seidel on the columns of B (n, 3); X (n, 3)
    warm start, updated in place.  Returns the iteration count.

    With A = L + D + U (strictly lower, diagonal ``d`` > 0, strictly upper), E = D + L and
    F = D + U = Eᵀ, the preconditioner is M = E D⁻¹ F.  CG runs on the symmetric system
    E⁻¹ A F⁻¹ y = E⁻¹ b (x = F⁻¹ y) with the inner product of D, in Eisenstat's form: A = E + F − D
    makes its product E⁻¹ A F⁻¹ p = t + E⁻¹(p − D t) with t = F⁻¹ p, one backward and one forward
    sweep over half of A each — the cost of one product by A, with no separate product.  The
    stopping rule is ``SPDSolver``'s: a column stops (α = 0, β = 1) once rᵀM⁻¹r (= r̂ᵀD r̂ with
    r̂ = E⁻¹r) fell below ``rtol``² × its initial value.  The sweeps are sequential, so the result
    has the same bits on any number of threads.  ``splits``: :func:`row_splits` of A.
    ``overwrite_b``: B becomes the storage of r̂ (the caller rebuilds B as E r̂ + A X if needed).
    """
    n = B.shape[0]
    work = np.empty((3 if overwrite_b else 4, n, 3))
    R = B if overwrite_b else work[3]
    dinv = 1.0 / d
    return _sgs_pcg3(indptr, indices, data, splits[0], splits[1], d, dinv, B, X, rtol, maxiter,
                     work[0], work[1], work[2], R)


@njit(cache=True)
def _sgs_pcg3(indptr, indices, data, lo_end, up_start, d, dinv, B, X, rtol, maxiter, P, T, W, R):
    """R may be B itself: row i of B is read before row i of R is written."""
    _sgs_start(indptr, indices, data, lo_end, up_start, dinv, B, X, R)
    rz = _start(R, X, d, R, P)          # r̂0 = E⁻¹(b − U x0) − x0, p0 = D r̂0
    tol2 = rz * (rtol * rtol)
    alpha = np.zeros(3)
    beta = np.ones(3)
    it = 0
    while it < maxiter and _active(rz, tol2):
        it += 1
        _sgs_backward(indptr, indices, data, up_start, d, dinv, R, P, T, beta, it > 1)
        pq = _sgs_forward(indptr, indices, data, lo_end, d, dinv, P, T, W)
        _step_sizes(rz, pq, tol2, alpha)
        rz = _directions(rz, _sgs_update(d, alpha, T, W, X, R), alpha, beta)
    return it


@njit(cache=True)
def _sgs_start(indptr, indices, data, lo_end, up_start, dinv, B, X, R):
    """R = E⁻¹(b − U x0), a forward sweep (r̂0 = R − x0, as E⁻¹ A x0 = x0 + E⁻¹ U x0)."""
    for i in range(B.shape[0]):
        s0 = B[i, 0]
        s1 = B[i, 1]
        s2 = B[i, 2]
        s0, s1, s2 = _minus_row(up_start[i], indptr[i + 1], indices, data, X, s0, s1, s2)
        s0, s1, s2 = _minus_row(indptr[i], lo_end[i], indices, data, R, s0, s1, s2)
        m = dinv[i]
        R[i, 0] = s0 * m
        R[i, 1] = s1 * m
        R[i, 2] = s2 * m


@njit(cache=True)
def _sgs_backward(indptr, indices, data, up_start, d, dinv, R, P, T, beta, update_p):
    """Backward sweep t = F⁻¹ p; with ``update_p``, p = D r̂ + β p is formed row by row first."""
    b0 = beta[0]
    b1 = beta[1]
    b2 = beta[2]
    for i in range(R.shape[0] - 1, -1, -1):
        if update_p:
            di = d[i]
            P[i, 0] = di * R[i, 0] + b0 * P[i, 0]
            P[i, 1] = di * R[i, 1] + b1 * P[i, 1]
            P[i, 2] = di * R[i, 2] + b2 * P[i, 2]
        s0 = P[i, 0]
        s1 = P[i, 1]
        s2 = P[i, 2]
        s0, s1, s2 = _minus_row(up_start[i], indptr[i + 1], indices, data, T, s0, s1, s2)
        m = dinv[i]
        T[i, 0] = s0 * m
        T[i, 1] = s1 * m
        T[i, 2] = s2 * m


@njit(cache=True)
def _sgs_forward(indptr, indices, data, lo_end, d, dinv, P, T, W):
    """Forward sweep w = E⁻¹(p − D t); returns pᵀq for the product q = t + w (row order)."""
    pq0 = 0.0
    pq1 = 0.0
    pq2 = 0.0
    for i in range(P.shape[0]):
        di = d[i]
        s0 = P[i, 0] - di * T[i, 0]
        s1 = P[i, 1] - di * T[i, 1]
        s2 = P[i, 2] - di * T[i, 2]
        s0, s1, s2 = _minus_row(indptr[i], lo_end[i], indices, data, W, s0, s1, s2)
        m = dinv[i]
        w0 = s0 * m
        w1 = s1 * m
        w2 = s2 * m
        W[i, 0] = w0
        W[i, 1] = w1
        W[i, 2] = w2
        pq0 += P[i, 0] * (T[i, 0] + w0)
        pq1 += P[i, 1] * (T[i, 1] + w1)
        pq2 += P[i, 2] * (T[i, 2] + w2)
    return np.array([pq0, pq1, pq2])


@njit(cache=True)
def _sgs_update(d, alpha, T, W, X, R):
    """x += α t (x = F⁻¹ y), r̂ −= α (t + w); returns r̂ᵀD r̂ per column (row order)."""
    a0 = alpha[0]
    a1 = alpha[1]
    a2 = alpha[2]
    s0 = 0.0
    s1 = 0.0
    s2 = 0.0
    for i in range(X.shape[0]):
        di = d[i]
        t0 = T[i, 0]
        t1 = T[i, 1]
        t2 = T[i, 2]
        X[i, 0] += a0 * t0
        X[i, 1] += a1 * t1
        X[i, 2] += a2 * t2
        r0 = R[i, 0] - a0 * (t0 + W[i, 0])
        r1 = R[i, 1] - a1 * (t1 + W[i, 1])
        r2 = R[i, 2] - a2 * (t2 + W[i, 2])
        R[i, 0] = r0
        R[i, 1] = r1
        R[i, 2] = r2
        s0 += r0 * r0 * di
        s1 += r1 * r1 * di
        s2 += r2 * r2 * di
    return np.array([s0, s1, s2])


class LinalgNumba(LinalgKernels):
    """The linalg family compiled: CG on three columns at once in an (n, 3) layout, the Clenshaw step fused."""

    backend = "numba"
    auto_preconditioner = "sgs"     # a compiled Gauss–Seidel sweep costs about one product

    def cg(self, solver, B, X0, overwrite_b=False):
        """Jacobi (all cores) or symmetric Gauss–Seidel (one core; ``preconditioner`` "auto" on a CSR
        matrix with sorted columns and a positive diagonal, or "sgs"), up to three columns of a
        :class:`PairMatrix` or an int32-indexed CSR matrix; the reference otherwise."""
        A = solver.A
        squeeze = B.ndim == 1
        k = 1 if squeeze else B.shape[1]
        lean = isinstance(A, PairMatrix)
        if k > 3 or not (lean or (A.indices.dtype == np.int32 and A.indptr.dtype == np.int32)):
            return super().cg(solver, B, X0, overwrite_b)
        n = A.shape[0]
        if k == 3:   # B is C-contiguous float64 (solve() made it so); the kernel only reads it
            B3 = B
            X = np.array(X0, dtype=np.float64, order="C") if X0 is not None else np.zeros((n, 3))
        else:
            B3 = np.zeros((n, 3))
            B3[:, :k] = B.reshape(n, k)
            X = np.zeros((n, 3))
            if X0 is not None:
                X[:, :k] = np.asarray(X0, dtype=np.float64).reshape(n, k)
        maxiter = solver.iteration_cap(n)
        reused = overwrite_b or B3 is not B
        sgs = False
        if lean:
            its = pcg3_pairs(A.pairs, A.weights, A.free, A.d, solver.minv, B3, X, solver.rtol, maxiter,
                             overwrite_b=reused)
        else:
            pre = solver.preconditioner
            if pre != "jacobi" and solver.positive and solver.splits is None:
                solver.splits = row_splits(A.indptr, A.indices)
                if solver.splits is None and pre == "sgs":   # unsorted columns: a sorted copy
                    solver.A = A = A.sorted_indices()
                    solver.splits = row_splits(A.indptr, A.indices)
            sgs = pre != "jacobi" and solver.positive and solver.splits is not None
            data = np.ascontiguousarray(A.data, dtype=np.float64)
            if sgs:
                its = sgs_pcg3(A.indptr, A.indices, data, solver.splits, solver.diagonal, B3, X, solver.rtol,
                               maxiter, overwrite_b=reused)
            else:
                its = pcg3(A.indptr, A.indices, data, solver.minv, B3, X, solver.rtol, maxiter, overwrite_b=reused)
        solver.stats.preconditioner = "sgs" if sgs else "jacobi"
        solver.stats.iterations = int(its)
        # the kernel stops at convergence or at the cap: reaching the cap counts as not converged
        converged = solver.stats.iterations < maxiter and bool(np.all(np.isfinite(X)))
        if not converged and reused and B3 is B:   # B holds the residual: rebuild B
            # Jacobi: r = B − A X; SGS: r̂ = E⁻¹ r with E = D + L, the lower triangle of A
            B = (sp.tril(A, 0, format="csr") @ B3 if sgs else B3) + A @ X
        Xk = X[:, 0].copy() if squeeze else (X if k == 3 else X[:, :k].copy())
        return Xk, converged, B

    def multishift_seed(self, A, B, seed, cap, coef=None):
        """The seed's CG compiled (:class:`~shapeflow.linalg.compiled_shift.CompiledSeed`) for a CSR
        matrix and up to three columns; the reference otherwise."""
        if B.shape[0] > 3 or not (sp.issparse(A) and A.format == "csr"):
            return super().multishift_seed(A, B, seed, cap, coef)
        from .compiled_shift import CompiledSeed

        return CompiledSeed(A, B, seed, cap, coef)

    def shifted_powers(self, A, seed, Y, degree, out=None, take=None, scale=None):
        from .compiled_shift import shifted_powers

        res = shifted_powers(A, seed, Y, degree, out, take, scale)
        return super().shifted_powers(A, seed, Y, degree, out, take, scale) if res is None else res

    def weighted_col_norms(self, A, c, Y):
        if not (int32_csr(A) and Y.shape[1] == 3 and Y.flags.c_contiguous):
            return super().weighted_col_norms(A, c, Y)
        return np.sqrt(weighted_col_norms2(c, Y))

    def clenshaw_step(self, A, cinv, B1, B2, X0, H0, f, alpha, beta, cuj, chj):
        if not int32_csr(A):
            return super().clenshaw_step(A, cinv, B1, B2, X0, H0, f, alpha, beta, cuj, chj)
        clenshaw_step(A.indptr, A.indices, np.ascontiguousarray(A.data, dtype=np.float64), cinv, B1, B2, X0, H0,
                      f, alpha, beta, cuj, chj)


def int32_csr(A) -> bool:
    """Whether the CSR matrix A has int32 index arrays (what the compiled products take)."""
    return A.indices.dtype == np.int32 and A.indptr.dtype == np.int32
