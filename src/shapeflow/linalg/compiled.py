"""Compiled linear algebra: the three-column Jacobi CG and the Chebyshev (Clenshaw) step.

The NumPy/SciPy reference is :mod:`shapeflow.linalg.spd` and :mod:`shapeflow.linalg.chebyshev`; the
tests compare the two.
Conventions of all compiled kernels: :mod:`shapeflow.accel`.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from ..accel import zeros


@njit(inline="always")
def _row_times3(indptr, indices, data, B, i):
    """Row i of A times the three columns of B (A in CSR)."""
    a0 = 0.0
    a1 = 0.0
    a2 = 0.0
    for q in range(indptr[i], indptr[i + 1]):
        j = np.uint64(indices[q])   # unsigned: no negative-index wraparound test per access
        v = data[q]
        a0 += v * B[j, 0]
        a1 += v * B[j, 1]
        a2 += v * B[j, 2]
    return a0, a1, a2


#: rows per block of the dot products: partial sums per block, added in block order, so the result
#: does not depend on the number of threads (a parallel reduction's order would)
BLOCK = 4096


@njit(cache=True)
def _sum_blocks(part):
    out = np.zeros(3)
    for b in range(part.shape[0]):
        out[0] += part[b, 0]
        out[1] += part[b, 1]
        out[2] += part[b, 2]
    return out


@njit(parallel=True, cache=True, fastmath=False)
def _spmm_dot(indptr, indices, data, P, AP, k):
    """AP = A P (P, AP are (n, 3)); returns the k column dots pᵀAp (the same bits on any number of threads)."""
    n = indptr.size - 1
    nb = (n + BLOCK - 1) // BLOCK
    part = np.zeros((nb, 3))
    for b in prange(nb):
        s0 = 0.0
        s1 = 0.0
        s2 = 0.0
        for i in range(b * BLOCK, min(n, (b + 1) * BLOCK)):
            a0, a1, a2 = _row_times3(indptr, indices, data, P, i)
            AP[i, 0] = a0
            AP[i, 1] = a1
            AP[i, 2] = a2
            s0 += a0 * P[i, 0]
            s1 += a1 * P[i, 1]
            s2 += a2 * P[i, 2]
        part[b, 0] = s0
        part[b, 1] = s1
        part[b, 2] = s2
    return _sum_blocks(part)


@njit(parallel=True, cache=True, fastmath=False)
def _update_xr(X, R, P, AP, minv, alpha):
    """X += αP, R −= αAP; returns the column dots rᵀM⁻¹r of the new residual (blocked, as _spmm_dot)."""
    n = X.shape[0]
    a0 = alpha[0]
    a1 = alpha[1]
    a2 = alpha[2]
    nb = (n + BLOCK - 1) // BLOCK
    part = np.zeros((nb, 3))
    for b in prange(nb):
        s0 = 0.0
        s1 = 0.0
        s2 = 0.0
        for i in range(b * BLOCK, min(n, (b + 1) * BLOCK)):
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
        part[b, 0] = s0
        part[b, 1] = s1
        part[b, 2] = s2
    return _sum_blocks(part)


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


def pcg3(indptr, indices, data, minv, B, X, rtol, maxiter, overwrite_b=False):
    """Jacobi-PCG on the columns of B (n, 3), X (n, 3) warm start, updated in place.

    Same algorithm and stopping rule as ``SPDSolver._cg``: a column stops
    (α = 0, β = 1) once its preconditioned residual norm fell below ``rtol`` ×
    its initial value.  Returns the iteration count.  ``overwrite_b``: B
    becomes the residual's storage (one (n, 3) array less to allocate).
    """
    # first touched here, not from both threads inside the loops
    work = zeros((2 if overwrite_b else 3, B.shape[0], 3))
    R = B if overwrite_b else work[2]
    return _pcg3(False, indptr, indices, data, _NO_PAIRS, _NO_F8, _NO_FREE, _NO_F8, minv, B, X, rtol, maxiter,
                 work[0], work[1], R)


_NO_PAIRS = np.zeros((0, 2), np.int32)
_NO_F8 = np.zeros(0)
_NO_FREE = np.zeros(0, np.bool_)
_NO_INT = np.zeros(1, np.int32)


@njit(inline="always")
def _product(use_pairs, indptr, indices, data, pairs, w, free, d, P, AP):
    if use_pairs:
        return _spmm_pairs_dot(pairs, w, free, d, P, AP)
    return _spmm_dot(indptr, indices, data, P, AP, 3)


@njit(cache=True)
def _pcg3(use_pairs, indptr, indices, data, pairs, w, free, d, minv, B, X, rtol, maxiter, P, AP, R):
    """R may be B itself: B is read once, before R is written.  The product is A's CSR
    (``indptr, indices, data``) or, with ``use_pairs``, a PairMatrix (``pairs, w, free, d``)."""
    n = B.shape[0]
    _product(use_pairs, indptr, indices, data, pairs, w, free, d, X, AP)
    rz = np.zeros(3)
    for i in range(n):
        m = minv[i]
        for c in range(3):
            r = B[i, c] - AP[i, c]
            R[i, c] = r
            P[i, c] = r * m
            rz[c] += r * r * m
    tol2 = rz * (rtol * rtol)
    alpha = np.zeros(3)
    beta = np.ones(3)
    it = 0
    while it < maxiter:
        active = False
        for c in range(3):
            if rz[c] > tol2[c]:
                active = True
        if not active:
            break
        it += 1
        pap = _product(use_pairs, indptr, indices, data, pairs, w, free, d, P, AP)
        for c in range(3):
            alpha[c] = rz[c] / pap[c] if (pap[c] > 0.0 and rz[c] > tol2[c]) else 0.0
        rz_new = _update_xr(X, R, P, AP, minv, alpha)
        for c in range(3):
            beta[c] = rz_new[c] / rz[c] if rz[c] > 0.0 else 0.0
            if alpha[c] == 0.0:
                rz_new[c] = rz[c]
                beta[c] = 1.0
        rz = rz_new
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
        a0, a1, a2 = _row_times3(indptr, indices, data, B1, i)
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
    return _pcg3(True, _NO_INT, _NO_INT, _NO_F8, pairs, w, free, d, minv, B, X, rtol, maxiter, work[0], work[1], R)
