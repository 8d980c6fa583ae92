"""Compiled parts of the flow's systems: the interior matrix, its couplings and permuted gathers.

:class:`FlowNumba` is the numba implementation of the flow family; the NumPy/SciPy reference is
:class:`shapeflow.flow.kernels.FlowKernels`, and the tests compare the two.
Conventions of all compiled kernels: :mod:`shapeflow.accel`.
"""

from __future__ import annotations

import numpy as np
from numba import get_num_threads, njit, prange

from .kernels import FlowKernels, no_coupling


def interior_data(nnz, pos_diag, pos_upper, pos_lower, pairs, free, c, deg, pw):
    """Matrix data of the interior system (``FlowKernels.interior_matrix``) in one pass.

    Free rows: c + D on the diagonal, −w_ij where both ends are free; other
    rows are identity rows.  Returns the data array, the diagonal, the numbers
    of pairs with only their first / only their second end free (their terms
    go to the right-hand side; see :func:`interior_coupling`) and max D/c over
    the free rows with c ≠ 0 (for the κ estimate).
    """
    data = np.empty(nnz)
    diag = np.empty(free.size)
    n_a, n_b, ratio = _interior_data(True, pos_diag, pos_upper, pos_lower, pairs, free, c, deg, pw, data, diag)
    return data, diag, (int(n_a), int(n_b)), float(ratio)


_NO_POS = np.zeros(0, np.int32)
_NO_DATA = np.zeros(0)


def interior_diag(pairs, free, c, deg, pw):
    """:func:`interior_data` without the matrix: the diagonal, the two counts of pairs with one free
    end, and max D/c (for the lean layout, :class:`~shapeflow.linalg.pairs.PairMatrix`)."""
    diag = np.empty(free.size)
    n_a, n_b, ratio = _interior_data(False, _NO_POS, _NO_POS, _NO_POS, pairs, free, c, deg, pw, _NO_DATA, diag)
    return diag, (int(n_a), int(n_b)), float(ratio)


def interior_coupling(pairs, free, pw, mixed):
    """The pairs with exactly one free end, as ``FlowKernels.interior_coupling`` lists them:
    (free end, other end, weight), first the pairs whose first end is free, then the others,
    each group in pair order.  ``mixed`` = the two counts from :func:`interior_data`."""
    n_a, n_b = mixed
    r = np.empty(n_a + n_b, np.int64)
    s = np.empty(n_a + n_b, np.int64)
    e = np.empty(n_a + n_b)
    _interior_coupling(pairs, free, pw, n_a, r, s, e)
    return r, s, e


@njit(cache=True)
def _interior_coupling(pairs, free, pw, n_a, r, s, e):
    qa = 0
    qb = n_a
    for p in range(pw.size):
        a = pairs[p, 0]
        b = pairs[p, 1]
        fa = free[np.uint64(a)]
        fb = free[np.uint64(b)]
        if fa and not fb:
            r[qa] = a
            s[qa] = b
            e[qa] = pw[p]
            qa += 1
        elif fb and not fa:
            r[qb] = b
            s[qb] = a
            e[qb] = pw[p]
            qb += 1


@njit(cache=True)
def _interior_data(fill, pos_diag, pos_upper, pos_lower, pairs, free, c, deg, pw, data, diag):
    """``fill``: also write the matrix entries into ``data`` at the pattern's positions."""
    ratio = 0.0
    for i in range(free.size):
        if free[i]:
            d = c[i] + deg[i]
            if c[i] != 0.0:
                ratio = max(ratio, abs(deg[i] / c[i]))
            else:
                ratio = max(ratio, abs(deg[i]))
        else:
            d = 1.0
        diag[i] = d
        if fill:
            data[np.uint64(pos_diag[i])] = d
    n_a = 0
    n_b = 0
    for p in range(pairs.shape[0]):
        fa = free[np.uint64(pairs[p, 0])]
        fb = free[np.uint64(pairs[p, 1])]
        v = -pw[p] if (fa and fb) else 0.0
        if fa and not fb:
            n_a += 1
        elif fb and not fa:
            n_b += 1
        if fill:
            data[np.uint64(pos_upper[p])] = v
            data[np.uint64(pos_lower[p])] = v
    return n_a, n_b, ratio


def scaled_abs_row_max(indptr, indices, data, s):
    """max over rows with s_i > 0 of s_i Σ_j |a_ij| s_j (a Gershgorin bound of SAS)."""
    return float(_scaled_abs_row_max(indptr, indices, data, s, get_num_threads()))


@njit(parallel=True, cache=True)
def _scaled_abs_row_max(indptr, indices, data, s, nt):
    n = indptr.size - 1
    part = np.zeros(nt)
    for t in prange(nt):            # each thread its range of rows; the max of maxima is exact
        best = 0.0
        for i in range(t * n // nt, (t + 1) * n // nt):
            si = s[i]
            if si > 0.0:
                acc = 0.0
                for q in range(indptr[i], indptr[i + 1]):
                    acc += abs(data[q]) * s[np.uint64(indices[q])]
                best = max(best, si * acc)
        part[t] = best
    return part.max()


def take(a, idx):
    """``a[idx]`` for a 1-D or (n, 3) float64 array and non-negative indices, on all threads
    (NumPy's fancy indexing converts int32 indices to a new intp array first)."""
    out = np.empty((idx.size,) + a.shape[1:], a.dtype)
    if a.ndim == 1:
        _take1(a, idx, out)
    else:
        _take3(a, idx, out)
    return out


@njit(parallel=True, cache=True)
def _take1(a, idx, out):
    for i in prange(idx.size):
        out[i] = a[np.uint64(idx[i])]


@njit(parallel=True, cache=True)
def _take3(a, idx, out):
    for i in prange(idx.size):
        j = np.uint64(idx[i])
        out[i, 0] = a[j, 0]
        out[i, 1] = a[j, 1]
        out[i, 2] = a[j, 2]


@njit(parallel=True, cache=True)
def take_free(V, perm, free, out):
    """out[i] = V[perm[i]] where free[perm[i]], else 0 (rows of (n, 3) arrays)."""
    for i in prange(perm.size):
        j = np.uint64(perm[i])
        f = free[j]
        out[i, 0] = V[j, 0] if f else 0.0
        out[i, 1] = V[j, 1] if f else 0.0
        out[i, 2] = V[j, 2] if f else 0.0


@njit(parallel=True, cache=True)
def untake_free(Y, inv, free, V, out):
    """out[v] = Y[inv[v]] where free[v], else V[v] (rows of (n, 3) arrays)."""
    for v in prange(inv.size):
        if free[v]:
            j = np.uint64(inv[v])
            out[v, 0] = Y[j, 0]
            out[v, 1] = Y[j, 1]
            out[v, 2] = Y[j, 2]
        else:
            out[v, 0] = V[v, 0]
            out[v, 1] = V[v, 1]
            out[v, 2] = V[v, 2]


@njit(cache=True)
def max_row_distance(A, B):
    """max_i |A_i − B_i| over the rows of two (n, 3) arrays, in one pass without temporaries."""
    best = 0.0
    for i in range(A.shape[0]):
        d0 = A[i, 0] - B[i, 0]
        d1 = A[i, 1] - B[i, 1]
        d2 = A[i, 2] - B[i, 2]
        s = d0 * d0 + d1 * d1 + d2 * d2
        if s > best or s != s:
            best = s
    return np.sqrt(best)


class FlowNumba(FlowKernels):
    """The flow family compiled: the interior system in one pass, and the lean layout."""

    backend = "numba"
    lean_layout = True

    def interior_matrix(self, pattern, free, c, deg, pw):
        data, diag, mixed, ratio = interior_data(pattern.indices.size, pattern.pos_diag, pattern.pos_upper,
                                                 pattern.pos_lower, pattern.pairs, free, c, deg, pw)
        return pattern.matrix_from_data(data), diag, mixed, ratio

    def interior_diag(self, pairs, free, c, deg, pw):
        return interior_diag(pairs, free, c, deg, pw)

    def interior_coupling(self, pairs, free, pw, mixed):
        if mixed is None:
            return super().interior_coupling(pairs, free, pw, mixed)
        if not sum(mixed):
            return no_coupling()
        return interior_coupling(pairs, free, pw, mixed)

    def scaled_abs_row_max(self, A, s, free):
        return scaled_abs_row_max(A.indptr, A.indices, A.data, s)

    def take(self, a, idx):
        return take(a, idx)

    def take_free(self, V, perm, free, out):
        take_free(V, perm, free, out)

    def untake_free(self, Y, inv, free, V, out):
        untake_free(Y, inv, free, V, out)

    def max_row_distance(self, A, B, chunk=4096):
        if not (A.dtype == B.dtype == np.float64 and A.ndim == B.ndim == 2 and A.shape[1] == 3):
            return super().max_row_distance(A, B, chunk)
        return float(max_row_distance(A, B))
