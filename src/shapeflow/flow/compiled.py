"""Compiled parts of the flow's systems: the interior matrix, its couplings and permuted gathers.

:class:`FlowNumba` is the numba implementation of the flow family; the NumPy/SciPy reference is
:class:`shapeflow.flow.kernels.FlowKernels`, and the tests compare the two.
Conventions of all compiled kernels: :mod:`shapeflow.accel`.
"""

from __future__ import annotations

import numpy as np
from numba import get_num_threads, njit, prange

from ..linalg.compiled import int32_csr
from ..linalg.spare import Spare
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


#: members per block of :func:`member_residuals` (their displacements (n, 3 × block) stay in cache)
RESIDUAL_MEMBERS = 16

#: rows per block of :func:`member_residuals`' partial sums (added in block order)
ROWS = 2048


def member_residuals(indptr, indices, data, R0, out, base, inv_scale, cols, members, signs, deltas, spare=()):
    """``FlowKernels.member_residuals`` compiled: per block of :data:`RESIDUAL_MEMBERS` members, their
    displacements in one (n, 3 × block) array, then one pass over the matrix for all of them.  The
    rows are shared out between numba's threads for the call (``accel.use(threads=…)``, applied by
    ``family()``) by blocks of :data:`ROWS` rows, whose partial sums are added in block order, so the
    result has the same bits on any number of threads.  The displacements' array is taken from ``spare``
    (flat float64 buffers free for scratch, :class:`~shapeflow.linalg.spare.Spare`) where one has room."""
    c, n = cols.size, base.shape[0]
    cols3 = np.empty(3, np.int64)
    cols3[:] = cols[0]
    cols3[:c] = cols
    R3 = np.zeros((3, n))
    R3[:c] = R0
    members = np.asarray(members, np.int64)
    signs = np.asarray(signs, np.float64)
    deltas = np.asarray(deltas, np.float64)
    nb = (n + ROWS - 1) // ROWS
    q = min(RESIDUAL_MEMBERS, members.size)
    Y = Spare(spare).take(n, 3 * q)
    part_r = np.empty((nb, 3 * q))
    part_y = np.empty((nb, 3 * q))
    res = np.empty((members.size, c))
    ynorm = np.empty((members.size, c))
    for s0 in range(0, members.size, q):
        s1 = min(members.size, s0 + q)
        w = 3 * (s1 - s0)
        _displacements(out, base, inv_scale, cols3, members[s0:s1], signs[s0:s1], Y[:, :w])
        _shifted_norms(indptr, indices, data, R3, deltas[s0:s1], Y[:, :w], part_r[:, :w], part_y[:, :w])
        res[s0:s1] = np.sqrt(part_r[:, :w].sum(axis=0)).reshape(s1 - s0, 3)[:, :c]
        ynorm[s0:s1] = np.sqrt(part_y[:, :w].sum(axis=0)).reshape(s1 - s0, 3)[:, :c]
    return res, ynorm


@njit(parallel=True, cache=True)
def _displacements(out, base, inv_scale, cols, members, signs, Y):
    """Y[i, 3p + t] = signs[p] (out[members[p], i, cols[t]] − base[i, cols[t]]) · inv_scale[i]."""
    for i in prange(Y.shape[0]):                # row i of Y written at once
        s = inv_scale[i]
        for p in range(members.size):
            m = members[p]
            sg = signs[p]
            for t in range(3):
                j = cols[t]
                Y[i, 3 * p + t] = sg * (out[m, i, j] - base[i, j]) * s


@njit(parallel=True, cache=True)
def _shifted_norms(indptr, indices, data, R0, deltas, Y, part_r, part_y):
    """Per block of :data:`ROWS` rows, Σ e² with e = (A Y)[i, u] + δ_p Y[i, u] − R0[t, i] (u = 3p + t) and Σ Y²."""
    n, w = Y.shape
    for b in prange(part_r.shape[0]):
        acc = np.empty(w)
        rr = np.zeros(w)
        yy = np.zeros(w)
        for i in range(b * ROWS, min(n, (b + 1) * ROWS)):
            for u in range(w):
                acc[u] = 0.0
            for k in range(indptr[i], indptr[i + 1]):
                v = data[k]
                j = np.uint64(indices[k])
                for u in range(w):
                    acc[u] += v * Y[j, u]
            b0 = R0[0, i]
            b1 = R0[1, i]
            b2 = R0[2, i]
            for p in range(w // 3):
                d = deltas[p]
                u = 3 * p
                y0 = Y[i, u]
                y1 = Y[i, u + 1]
                y2 = Y[i, u + 2]
                e0 = acc[u] + d * y0 - b0
                e1 = acc[u + 1] + d * y1 - b1
                e2 = acc[u + 2] + d * y2 - b2
                rr[u] += e0 * e0
                rr[u + 1] += e1 * e1
                rr[u + 2] += e2 * e2
                yy[u] += y0 * y0
                yy[u + 1] += y1 * y1
                yy[u + 2] += y2 * y2
        part_r[b] = rr
        part_y[b] = yy


def scatter_members(out, base, cols, i0, rows, members, shift_of, signs):
    """``FlowKernels.scatter_members`` compiled: one pass per member over its block of positions."""
    bad = np.zeros(rows.shape[1], np.bool_)
    _scatter_members(out, base, np.asarray(cols, np.int64), i0, rows, np.asarray(members, np.int64),
                     np.asarray(shift_of, np.int64), np.asarray(signs, np.float64), bad)
    return ~bad


@njit(cache=True)
def _scatter_members(out, base, cols, i0, rows, members, shift_of, signs, bad):
    c, _, w = rows.shape
    for p in range(members.size):               # one member's rows: a run of its positions
        o = out[members[p]]
        q = shift_of[p]
        sg = signs[p]
        flag = False
        for i in range(w):
            x0 = base[i0 + i, 0]
            x1 = base[i0 + i, 1]
            x2 = base[i0 + i, 2]
            for t in range(c):
                v = rows[t, q, i]
                if v * 0.0 != 0.0:              # NaN once a value is not finite (a test, not a chain of sums)
                    flag = True
                j = cols[t]
                if j == 0:
                    x0 += sg * v
                elif j == 1:
                    x1 += sg * v
                else:
                    x2 += sg * v
            o[i0 + i, 0] = x0
            o[i0 + i, 1] = x1
            o[i0 + i, 2] = x2
        if flag:
            bad[q] = True


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


def step_rhs(c, V, X, held, r, s, e):
    """``FlowKernels.step_rhs`` in one pass over the rows (and one over the couplings)."""
    n = V.shape[0]
    out = np.empty((n, 3))
    if r.size:
        acc = np.zeros((n, 3))       # calloc: pages of rows without a coupling are never touched
        _coupling_sums(r, s, e, X, acc)
        _step_rhs(c, V, X, held, r, acc, 0.0, out)
    else:
        _step_rhs(c, V, X, held, r, _NO_ROWS3, -0.0, out)
    return out


_NO_ROWS3 = np.zeros((0, 3))


@njit(cache=True)
def _coupling_sums(r, s, e, X, acc):
    """acc[r_q] += e_q X[s_q], in coupling order (``np.bincount``'s order)."""
    for q in range(r.size):
        i = np.uint64(r[q])
        j = np.uint64(s[q])
        acc[i, 0] += e[q] * X[j, 0]
        acc[i, 1] += e[q] * X[j, 1]
        acc[i, 2] += e[q] * X[j, 2]


@njit(cache=True)
def _step_rhs(c, V, X, held, r, acc, zero, out):
    """out = C·V, X on the held rows, then + ``zero`` everywhere (NumPy adds a bincount's 0.0 to the rows
    without a coupling: x + 0.0, which turns −0.0 into +0.0; ``zero`` = −0.0 without couplings, a no-op)
    and + ``acc`` on the coupled rows (their sums; a sum started at +0.0 is never −0.0)."""
    for i in range(V.shape[0]):
        ci = c[i]
        out[i, 0] = ci * V[i, 0] + zero
        out[i, 1] = ci * V[i, 1] + zero
        out[i, 2] = ci * V[i, 2] + zero
    for q in range(held.size):
        h = np.uint64(held[q])
        out[h, 0] = X[h, 0] + zero
        out[h, 1] = X[h, 1] + zero
        out[h, 2] = X[h, 2] + zero
    for q in range(r.size):        # each coupled row gets its sums once: later visits add 0.0 to a value
        i = np.uint64(r[q])           # that is not −0.0, which changes nothing
        out[i, 0] += acc[i, 0]
        out[i, 1] += acc[i, 1]
        out[i, 2] += acc[i, 2]
        acc[i, 0] = 0.0
        acc[i, 1] = 0.0
        acc[i, 2] = 0.0


def step_result(X, V, factor, flip, axes, out):
    """``FlowKernels.step_result`` in one pass."""
    f = np.ones(0) if factor is None else np.ascontiguousarray(factor, dtype=np.float64)
    keep = np.array([0.0 if not a else 1.0 for a in axes])
    return int(_step_result(X, V, f, -1.0 if flip else 1.0, keep, out))


@njit(cache=True)
def _step_result(X, V, factor, f0, keep, out):
    """out = V + f·(X − V) row by row (the reference's operations: X − V, times ±1, 0 on dropped axes,
    then V +), a row with a non-finite value taken as V; returns the number of such rows."""
    n_bad = 0
    per_row = factor.size > 0
    for i in range(V.shape[0]):
        v0 = V[i, 0]
        v1 = V[i, 1]
        v2 = V[i, 2]
        x0 = X[i, 0]
        x1 = X[i, 1]
        x2 = X[i, 2]
        if not (np.isfinite(x0) and np.isfinite(x1) and np.isfinite(x2)):
            n_bad += 1
            x0 = v0
            x1 = v1
            x2 = v2
        f = factor[i] if per_row else f0
        d0 = x0 - v0
        d1 = x1 - v1
        d2 = x2 - v2
        if per_row:
            d0 *= f
            d1 *= f
            d2 *= f
        elif f < 0.0:
            d0 = -d0
            d1 = -d1
            d2 = -d2
        if keep[0] == 0.0:
            d0 = 0.0
        if keep[1] == 0.0:
            d1 = 0.0
        if keep[2] == 0.0:
            d2 = 0.0
        out[i, 0] = v0 + d0
        out[i, 1] = v1 + d1
        out[i, 2] = v2 + d2
    return n_bad


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

    def step_rhs(self, c, V, X, held, r, s, e):
        if not (V.dtype == X.dtype == c.dtype == np.float64 and V.ndim == X.ndim == 2 and V.shape[1] == 3):
            return super().step_rhs(c, V, X, held, r, s, e)
        return step_rhs(c, V, X, held, r, s, e)

    def step_result(self, X, V, factor, flip, axes, out):
        if not (X.dtype == V.dtype == out.dtype == np.float64 and V.ndim == 2 and V.shape[1] == 3):
            return super().step_result(X, V, factor, flip, axes, out)
        return step_result(X, V, factor, flip, axes, out)

    def member_residuals(self, As, R0, out, base, inv_scale, cols, members, signs, deltas, spare=()):
        if not (getattr(As, "format", None) == "csr" and int32_csr(As) and out.dtype == base.dtype == np.float64
                and out.ndim == 3 and out.shape[2] == 3 and base.shape[1] == 3 and out.flags.c_contiguous
                and 1 <= cols.size <= 3):
            return super().member_residuals(As, R0, out, base, inv_scale, cols, members, signs, deltas)
        return member_residuals(As.indptr, As.indices, np.ascontiguousarray(As.data, dtype=np.float64), R0, out,
                                base, np.ascontiguousarray(inv_scale, dtype=np.float64), cols, members, signs, deltas,
                                spare)

    def scatter_members(self, out, base, cols, i0, rows, members, shift_of, signs):
        if not (out.dtype == rows.dtype == base.dtype == np.float64 and out.ndim == 3 and rows.ndim == 3
                and out.shape[2] == 3 and base.shape[1] == 3):
            return super().scatter_members(out, base, cols, i0, rows, members, shift_of, signs)
        return scatter_members(out, base, cols, i0, rows, members, shift_of, signs)

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
