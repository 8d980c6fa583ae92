"""Compiled split solver of small SPD systems: two banded halves factored on two threads.

:class:`LocalNumba` is the numba implementation of the local family; the NumPy/SciPy reference is
:class:`shapeflow.linalg.kernels.LocalKernels` (which has no split solve), and the tests compare the two.
Conventions of all compiled kernels: :mod:`shapeflow.accel`.
"""

from __future__ import annotations

import numpy as np
from numba import get_num_threads, njit, prange

from .banded import lapack_band
from .blas import FALLBACKS, SingleThreadBLAS, split_routines
from .kernels import LocalKernels
from .ordering import row_ptr

__all__ = ["cm_order", "split_order", "split_solve", "split_work_size", "get_num_threads", "LocalNumba"]


@njit(cache=True)
def _bfs_levels(ptr, adj, start, order, lev):
    """Breadth-first order and levels from ``start``; ``lev`` is -1 on entry for
    every vertex (left set for the vertices reached).  Returns the number reached."""
    order[0] = start
    lev[start] = 0
    head = 0
    tail = 1
    while head < tail:
        v = order[head]
        head += 1
        lv = lev[v] + 1
        for q in range(ptr[v], ptr[v + 1]):
            u = adj[q]
            if lev[u] < 0:
                lev[u] = lv
                order[tail] = u
                tail += 1
    return tail


@njit(cache=True)
def _order_band(ri, ci, order, inv, lev):
    """Band of the entries (ri, ci) in rows with ``lev`` >= 0, numbered by ``order``
    (which lists exactly those rows); leaves their ``inv`` = position in ``order``."""
    for i in range(order.size):
        inv[order[i]] = i
    bw = 0
    for q in range(ri.size):
        if lev[ri[q]] < 0:
            continue
        d = inv[ri[q]] - inv[ci[q]]
        if d > bw:
            bw = d
    return bw


@njit(cache=True)
def _cm_sweeps(ptr, ri, ci, u, m, o1, o2, lev1, lev2, inv):
    """The two Cuthill–McKee sweeps over the m vertices of u's component: from u,
    then from w, the last vertex reached from u, into o1 and o2; returns
    (order, levels, True when it is w's) of the one with the narrower band,
    u's on a tie (``inv`` is scratch)."""
    lev1[:] = -1
    _bfs_levels(ptr, ci, u, o1, lev1)
    lev2[:] = -1
    _bfs_levels(ptr, ci, o1[m - 1], o2, lev2)
    if _order_band(ri, ci, o2[:m], inv, lev2) < _order_band(ri, ci, o1[:m], inv, lev1):
        return o2, lev2, True
    return o1, lev1, False


@njit(cache=True)
def cm_order(ptr, ri, ci, perm, inv, o2, lev1, lev2):
    """:func:`shapeflow.linalg.ordering.local_order`'s order of a connected system: :func:`_cm_sweeps`
    from u, the last vertex reached from vertex 0.  Writes ``perm`` and its
    inverse ``inv``; returns False (nothing usable written) when the graph
    (ptr, ci) is disconnected."""
    k = perm.size
    lev1[:] = -1
    if _bfs_levels(ptr, ci, 0, perm, lev1) < k:
        return False
    if _cm_sweeps(ptr, ri, ci, perm[k - 1], k, perm, o2, lev1, lev2, inv)[2]:
        perm[:] = o2
    for i in range(k):
        inv[perm[i]] = i
    return True


@njit(cache=True)
def split_order(ptr, ri, ci, min_half, perm, inv, o1, o2, lev1, lev2, dims):
    """Order for :func:`split_solve`: [A, B, S].

    Cuthill–McKee level structures of the largest connected component from a
    pseudo-peripheral vertex (u, the last vertex reached from the
    component's first vertex, and w, the last reached from u; the order with
    the narrower band is kept, u's on a tie), cut at the level S holding the
    component's median vertex: A = the levels before it in CM order, B = the
    levels after it in reversed CM order, so that the vertices coupled to S
    come last in both halves.  Other components (not coupled to anything
    else) go first into the smaller half, each in breadth-first order.
    Writes ``dims`` = (nA, nB, nS, band of A, band of B, tA, tB), t = how
    many trailing rows of a half are coupled to S.  Returns 0, or -2 when a
    half would hold fewer than ``min_half`` vertices.
    """
    k = perm.size
    # connected components, in breadth-first order each, into `rest`
    rest = np.empty(k, np.int64)
    lev2[:] = -1
    pos = 0
    mpos = 0
    msize = 0
    for v in range(k):
        if lev2[v] < 0:
            c = _bfs_levels(ptr, ci, v, rest[pos:], lev2)
            if c > msize:
                mpos = pos
                msize = c
            pos += c
    # from the last vertex reached from the component's first
    o, lev, _ = _cm_sweeps(ptr, ri, ci, rest[mpos + msize - 1], msize, o1, o2, lev1, lev2, inv)
    m = msize
    s = lev[o[m // 2]]
    a0 = m // 2
    while a0 > 0 and lev[o[a0 - 1]] == s:
        a0 -= 1
    a1 = m // 2
    while a1 < m and lev[o[a1]] == s:
        a1 += 1
    nS = a1 - a0
    n_rest = k - m
    into_a = a0 <= m - a1
    nA = a0 + (n_rest if into_a else 0)
    nB = m - a1 + (0 if into_a else n_rest)
    if nA < min_half or nB < min_half:
        return -2
    p = 0 if into_a else nA
    for i in range(k):
        v = rest[i]
        if lev[v] < 0:              # not in the largest component
            perm[p] = v
            p += 1
    p = nA - a0
    for i in range(a0):
        perm[p + i] = o[i]
    p = nA + nB - (m - a1)
    for i in range(m - a1):
        perm[p + i] = o[m - 1 - i]
    for i in range(nS):
        perm[nA + nB + i] = o[a0 + i]
    for i in range(k):
        inv[perm[i]] = i
    e = nA + nB
    bwA = 0
    bwB = 0
    fA = nA
    fB = e
    for q in range(ri.size):
        i = inv[ri[q]]
        j = inv[ci[q]]
        if i < j:
            i, j = j, i
        if i < nA:
            if i - j > bwA:
                bwA = i - j
        elif j >= nA and i < e:
            if i - j > bwB:
                bwB = i - j
        elif i >= e and j < e:
            if j < nA:
                if j < fA:
                    fA = j
            elif j < fB:
                fB = j
    dims[0] = nA
    dims[1] = nB
    dims[2] = nS
    dims[3] = bwA
    dims[4] = bwB
    dims[5] = nA - fA
    dims[6] = e - fB
    if dims[5] < 1 or dims[6] < 1:
        return -2                   # a half not coupled to S (the cut is not in the middle)
    return 0


@njit(cache=True)
def _half_size(n, kd, t, nS):
    """Doubles of a half's work space in :func:`split_solve`: band, right-hand sides, W, T."""
    return (kd + 1) * n + 3 * n + t * nS + t * t


@njit(inline="always")
def _half_views(buf, p, n, kd, t, nS):
    """A half's work space from ``buf[p:]``: band storage (ldab = kd + 1), y (n x 3, F), W (t x nS, F), T (t x t)."""
    a = p + (kd + 1) * n
    b = a + 3 * n
    c = b + t * nS
    return buf[p:a], buf[a:b], buf[b:c], buf[c:c + t * t]


@njit(inline="always")
def _half_ints(iv, n, kd, t, nS):
    """The integer arguments of a half's LAPACK/BLAS calls: n, kd, ldab, nrhs, t, nS (iv[6]: info)."""
    iv[0] = n
    iv[1] = kd
    iv[2] = kd + 1
    iv[3] = 3
    iv[4] = t
    iv[5] = nS
    iv[6] = 0


@njit(parallel=True, cache=True)
def split_solve(pbtrf, tbtrs, potrf, potrs, trsm, syrk, gemm, set_threads,  # long: one compiled kernel whose
                ri, ci, vi, diag, rhs, perm, inv, dims, buf, X):         # two prange phases share the halves' buffers
    """Solve the SPD system (off-diagonal entries ``(ri, ci, vi)``, both triangles;
    diagonal ``diag``; three right-hand sides) in the order of :func:`split_order`.

    The two halves are independent banded systems, each factored by LAPACK's
    ``dpbtrf`` (lower band storage) on its own thread, which also runs its
    forward substitution and W = T⁻¹ C, T the trailing t × t block of its
    factor and C its coupling to the separator S; then, on one thread, the
    separator's Schur complement S − W_Aᵀ W_A − W_Bᵀ W_B (dense, ``dpotrf``);
    then each half's back substitution on its thread.  ``dims`` = (nA, nB,
    nS, kdA, kdB, tA, tB), the bands as stored (kd ≥ the true band).  The
    LAPACK and BLAS routines come as ctypes pointers (SciPy's
    ``cython_lapack``/``cython_blas``); ``set_threads`` is OpenBLAS's
    thread-local thread count, set to 1 in both threads.  ``buf`` is work
    space (see :func:`split_work_size`).  Writes X (k, 3); returns 0, or the
    LAPACK info of a failed step (not positive definite).
    """
    nA = dims[0]
    nB = dims[1]
    nS = dims[2]
    e = nA + nB
    Lc = np.array([76], np.uint8)   # 'L'
    Nc = np.array([78], np.uint8)   # 'N'
    Tc = np.array([84], np.uint8)   # 'T'
    one = np.ones(1)
    mone = -np.ones(1)
    ints = np.zeros((2, 8), np.int32)
    info = np.zeros(2, np.int64)
    offs = np.empty(3, np.int64)    # start of each half's work space; S's
    offs[0] = 0
    for h in range(2):
        offs[h + 1] = offs[h] + _half_size(dims[h], dims[3 + h], dims[5 + h], nS)
    o = offs[2]
    SS = buf[o:o + nS * nS]
    rS = buf[o + nS * nS:o + nS * nS + 3 * nS]
    for h in prange(2):
        set_threads(1)
        n = dims[h]
        kd = dims[3 + h]
        t = dims[5 + h]
        lo = 0 if h == 0 else nA         # the half's rows in the [A, B, S] order
        ld = kd + 1
        ab, y, W, Tm = _half_views(buf, offs[h], n, kd, t, nS)
        ab[:] = 0.0
        W[:] = 0.0
        Tm[:] = 0.0
        for i in range(n):
            v = perm[lo + i]
            ab[ld * i] = diag[v]
            y[i] = rhs[v, 0]
            y[i + n] = rhs[v, 1]
            y[i + 2 * n] = rhs[v, 2]
        w0 = lo + n - t                  # first row coupled to S
        for q in range(ri.size):
            i = inv[ri[q]]
            j = inv[ci[q]]
            if i <= j or j < lo or j >= lo + n:
                continue                 # lower triangle, column in this half
            if i < lo + n:
                ab[(i - j) + ld * (j - lo)] = vi[q]
            elif i >= e:
                W[(j - w0) + t * (i - e)] = vi[q]
        iv = ints[h]
        _half_ints(iv, n, kd, t, nS)
        pbtrf(Lc.ctypes, iv[0:1].ctypes, iv[1:2].ctypes, ab.ctypes, iv[2:3].ctypes, iv[6:7].ctypes)
        if iv[6] != 0:
            info[h] = iv[6]
            continue
        tbtrs(Lc.ctypes, Nc.ctypes, Nc.ctypes, iv[0:1].ctypes, iv[1:2].ctypes, iv[3:4].ctypes, ab.ctypes,
              iv[2:3].ctypes, y.ctypes, iv[0:1].ctypes, iv[6:7].ctypes)
        for jj in range(t):              # trailing t x t block of the factor, dense lower
            j = n - t + jj
            for ii in range(jj, min(t, jj + kd + 1)):
                Tm[ii + t * jj] = ab[(ii - jj) + ld * j]
        trsm(Lc.ctypes, Lc.ctypes, Nc.ctypes, Nc.ctypes, iv[4:5].ctypes, iv[5:6].ctypes, one.ctypes, Tm.ctypes,
             iv[4:5].ctypes, W.ctypes, iv[4:5].ctypes)
        if iv[6] != 0:
            info[h] = iv[6]
    if info[0] != 0:
        return info[0]
    if info[1] != 0:
        return info[1]
    # the separator: Schur complement, one thread
    SS[:] = 0.0
    for i in range(nS):
        v = perm[e + i]
        SS[i + nS * i] = diag[v]
        rS[i] = rhs[v, 0]
        rS[i + nS] = rhs[v, 1]
        rS[i + 2 * nS] = rhs[v, 2]
    for q in range(ri.size):
        i = inv[ri[q]]
        j = inv[ci[q]]
        if j >= e and i > j:
            SS[(i - e) + nS * (j - e)] = vi[q]
    jv = ints[0]
    jv[0] = nS
    jv[1] = 3
    jv[2] = 0
    for g in range(2):
        n_ = dims[g]
        t_ = dims[5 + g]
        _, y_, W_, _ = _half_views(buf, offs[g], n_, dims[3 + g], t_, nS)
        jv[3] = t_
        jv[4] = n_
        syrk(Lc.ctypes, Tc.ctypes, jv[0:1].ctypes, jv[3:4].ctypes, mone.ctypes, W_.ctypes, jv[3:4].ctypes,
             one.ctypes, SS.ctypes, jv[0:1].ctypes)
        gemm(Tc.ctypes, Nc.ctypes, jv[0:1].ctypes, jv[1:2].ctypes, jv[3:4].ctypes, mone.ctypes, W_.ctypes,
             jv[3:4].ctypes, y_[n_ - t_:].ctypes, jv[4:5].ctypes, one.ctypes, rS.ctypes, jv[0:1].ctypes)
    potrf(Lc.ctypes, jv[0:1].ctypes, SS.ctypes, jv[0:1].ctypes, jv[2:3].ctypes)
    if jv[2] != 0:
        return jv[2]
    potrs(Lc.ctypes, jv[0:1].ctypes, jv[1:2].ctypes, SS.ctypes, jv[0:1].ctypes, rS.ctypes, jv[0:1].ctypes,
          jv[2:3].ctypes)
    for i in range(nS):
        v = perm[e + i]
        X[v, 0] = rS[i]
        X[v, 1] = rS[i + nS]
        X[v, 2] = rS[i + 2 * nS]
    # back substitution of both halves
    for h in prange(2):
        n = dims[h]
        kd = dims[3 + h]
        t = dims[5 + h]
        lo = 0 if h == 0 else nA
        ab, y, W, _ = _half_views(buf, offs[h], n, kd, t, nS)
        iv = ints[h]
        _half_ints(iv, n, kd, t, nS)
        gemm(Nc.ctypes, Nc.ctypes, iv[4:5].ctypes, iv[3:4].ctypes, iv[5:6].ctypes, mone.ctypes, W.ctypes,
             iv[4:5].ctypes, rS.ctypes, iv[5:6].ctypes, one.ctypes, y[n - t:].ctypes, iv[0:1].ctypes)
        tbtrs(Lc.ctypes, Tc.ctypes, Nc.ctypes, iv[0:1].ctypes, iv[1:2].ctypes, iv[3:4].ctypes, ab.ctypes,
              iv[2:3].ctypes, y.ctypes, iv[0:1].ctypes, iv[6:7].ctypes)
        for i in range(n):
            v = perm[lo + i]
            X[v, 0] = y[i]
            X[v, 1] = y[i + n]
            X[v, 2] = y[i + 2 * n]
    return 0


def split_work_size(dims) -> int:
    """Doubles of work space :func:`split_solve` needs for ``dims``."""
    nA, nB, nS, kdA, kdB, tA, tB = (int(x) for x in dims)
    return _half_size(nA, kdA, tA, nS) + _half_size(nB, kdB, tB, nS) + nS * nS + 3 * nS


class LocalNumba(LocalKernels):
    """The local family compiled: the Cuthill–McKee searches without a CSR matrix, and the split solve."""

    backend = "numba"

    def local_order(self, k, ri, ci, grouped=True):
        if grouped:   # the same searches, compiled (they need the rows grouped)
            perm, inv = np.empty(k, np.int64), np.empty(k, np.int64)
            o2, lev1, lev2 = np.empty((3, k), np.int64)
            if cm_order(row_ptr(ri, k), ri, ci, perm, inv, o2, lev1, lev2):
                return perm, inv
        return super().local_order(k, ri, ci, grouped)

    def split_solve(self, solver, k, ri, ci, vi, diag, rhs, notes=None):
        fns = split_routines()
        if fns is None:
            if notes is not None:
                notes.append(FALLBACKS.get("split", "split solver unavailable"))
            return None
        # one thread too: the halves are then factored one after the other, with the same arithmetic,
        # so a dab's result does not depend on how many threads the machine can give it
        perm, inv, o1, o2, lev1, lev2 = np.empty((6, k), np.int64)
        dims = np.empty(7, np.int64)
        if split_order(row_ptr(ri, k), ri, ci, max(64, k // 5), perm, inv, o1, o2, lev1, lev2, dims) != 0:
            return None
        band = int(max(dims[3], dims[4]))
        for h in range(2):
            dims[3 + h] = lapack_band(int(dims[3 + h]), int(dims[h]))
        buf = solver.work(split_work_size(dims))
        X = np.empty((k, 3))
        with SingleThreadBLAS():
            status = split_solve(*fns, ri, ci, np.ascontiguousarray(vi, dtype=np.float64),
                                 np.ascontiguousarray(diag, dtype=np.float64),
                                 np.ascontiguousarray(rhs, dtype=np.float64), perm, inv, dims, buf, X)
        if status != 0:
            return None
        return X, "split", band
