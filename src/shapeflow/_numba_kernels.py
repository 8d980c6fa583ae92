"""Compiled kernels (numba) for the hot paths; imported only through :mod:`shapeflow.kernels`.

Every kernel here has a NumPy/SciPy twin that stays the reference: the tests
run both and compare.  Kernels are compiled on first use and cached on disk
(``cache=True``), so a new process pays the compilation once per machine.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange


# --------------------------------------------------------------------------
# Jacobi-preconditioned CG on k columns at once (k <= 3), one matrix pass
# --------------------------------------------------------------------------

@njit(parallel=True, cache=True, fastmath=False)
def _spmm_dot(indptr, indices, data, P, AP, k):
    """AP = A P (P, AP are (n, 3)); returns the k column dots pᵀAp."""
    n = indptr.size - 1
    s0 = 0.0
    s1 = 0.0
    s2 = 0.0
    for i in prange(n):
        a0 = 0.0
        a1 = 0.0
        a2 = 0.0
        for q in range(indptr[i], indptr[i + 1]):
            j = indices[q]
            v = data[q]
            a0 += v * P[j, 0]
            a1 += v * P[j, 1]
            a2 += v * P[j, 2]
        AP[i, 0] = a0
        AP[i, 1] = a1
        AP[i, 2] = a2
        s0 += a0 * P[i, 0]
        s1 += a1 * P[i, 1]
        s2 += a2 * P[i, 2]
    out = np.empty(3)
    out[0] = s0
    out[1] = s1
    out[2] = s2
    return out


@njit(parallel=True, cache=True, fastmath=False)
def _update_xr(X, R, P, AP, minv, alpha):
    """X += αP, R −= αAP; returns the column dots rᵀM⁻¹r of the new residual."""
    n = X.shape[0]
    s0 = 0.0
    s1 = 0.0
    s2 = 0.0
    a0 = alpha[0]
    a1 = alpha[1]
    a2 = alpha[2]
    for i in prange(n):
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
    out = np.empty(3)
    out[0] = s0
    out[1] = s1
    out[2] = s2
    return out


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


@njit(cache=True)
def pcg3(indptr, indices, data, minv, B, X, rtol, maxiter):
    """Jacobi-PCG on the columns of B (n, 3), X (n, 3) warm start, updated in place.

    Same algorithm and stopping rule as ``SPDSolver._cg``: a column stops
    (α = 0, β = 1) once its preconditioned residual norm fell below ``rtol`` ×
    its initial value.  Returns the iteration count.
    """
    n = B.shape[0]
    k = 3
    P = np.empty((n, 3))
    AP = np.empty((n, 3))
    R = np.empty((n, 3))
    _spmm_dot(indptr, indices, data, X, R, k)
    rz = np.zeros(3)
    for i in range(n):
        m = minv[i]
        for c in range(3):
            r = B[i, c] - R[i, c]
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
        pap = _spmm_dot(indptr, indices, data, P, AP, k)
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


# --------------------------------------------------------------------------
# topology: unique edges (Topology._edge_data)
# --------------------------------------------------------------------------

@njit(cache=True)
def edge_data(fi, nxt, n):
    """Same outputs as the NumPy ``Topology._edge_data``.

    Half-edges are bucketed by their low vertex (counting sort, stable in
    corner order), then each small bucket is insertion-sorted by the high
    vertex (stable), which is the order of a stable argsort of lo·n + hi.
    """
    c = fi.size
    lo = np.empty(c, np.int64)
    hi = np.empty(c, np.int64)
    start = np.zeros(n + 1, np.int64)
    for k in range(c):
        a = fi[k]
        b = fi[nxt[k]]
        if a < b:
            lo[k] = a
            hi[k] = b
        else:
            lo[k] = b
            hi[k] = a
        start[lo[k] + 1] += 1
    for v in range(n):
        start[v + 1] += start[v]
    fill = start[:-1].copy()
    order = np.empty(c, np.int64)
    for k in range(c):
        v = lo[k]
        order[fill[v]] = k
        fill[v] += 1
    # insertion sort of each bucket by hi (stable)
    for v in range(n):
        s = start[v]
        e = start[v + 1]
        for q in range(s + 1, e):
            k = order[q]
            h = hi[k]
            r = q - 1
            while r >= s and hi[order[r]] > h:
                order[r + 1] = order[r]
                r -= 1
            order[r + 1] = k
    corner_edge = np.empty(c, np.int64)
    n_e = 0
    firsts = np.empty(c, np.int64)
    starts = np.empty(c + 1, np.int64)
    prev_lo = -1
    prev_hi = -1
    for q in range(c):
        k = order[q]
        if lo[k] != prev_lo or hi[k] != prev_hi:
            firsts[n_e] = k
            starts[n_e] = q
            n_e += 1
            prev_lo = lo[k]
            prev_hi = hi[k]
        corner_edge[k] = n_e - 1
    starts[n_e] = c
    edges = np.empty((n_e, 2), np.int64)
    for e in range(n_e):
        edges[e, 0] = lo[firsts[e]]
        edges[e, 1] = hi[firsts[e]]
    return edges, corner_edge, starts[:n_e + 1].copy(), order


@njit(cache=True)
def first_repeated_vertex_face(fi, offsets):
    """Index of the first face that lists a vertex twice, or -1."""
    m = offsets.size - 1
    for f in range(m):
        s = offsets[f]
        e = offsets[f + 1]
        for a in range(s, e):
            va = fi[a]
            for b in range(a + 1, e):
                if fi[b] == va:
                    return f
    return -1


# --------------------------------------------------------------------------
# the operator's sparse pattern (operators._Structure)
# --------------------------------------------------------------------------

@njit(cache=True)
def fill_symmetric(nnz, pos_diag, diag, pos_upper, pos_lower, off):
    """The data array of a matrix on a ``_Structure`` pattern."""
    data = np.empty(nnz)
    for i in range(pos_diag.size):
        data[pos_diag[i]] = diag[i]
    for p in range(pos_upper.size):
        data[pos_upper[p]] = off[p]
        data[pos_lower[p]] = off[p]
    return data


# --------------------------------------------------------------------------
# assembly (operators.corner_cotangents and the scatters of operators._assemble)
# --------------------------------------------------------------------------

@njit(cache=True)
def corner_cotangents(V, fi, nxt, prv):
    """Same formulas, same order of operations as ``operators.corner_cotangents``."""
    c = fi.size
    ex = np.empty(c)
    ey = np.empty(c)
    ez = np.empty(c)
    for k in range(c):
        a = fi[k]
        b = fi[nxt[k]]
        ex[k] = V[b, 0] - V[a, 0]
        ey[k] = V[b, 1] - V[a, 1]
        ez[k] = V[b, 2] - V[a, 2]
    cot_p = np.empty(c)
    cot_c = np.empty(c)
    cot_n = np.empty(c)
    dbl = np.empty(c)
    l_prev = np.empty(c)
    l_next = np.empty(c)
    l_skip = np.empty(c)
    for k in range(c):
        j = prv[k]
        px = ex[j]
        py = ey[j]
        pz = ez[j]
        qx = ex[k]
        qy = ey[k]
        qz = ez[k]
        ln = qx * qx + qy * qy + qz * qz
        lp = px * px + py * py + pz * pz
        dot = -(px * qx + py * qy + pz * qz)
        cx = py * qz - pz * qy
        cy = pz * qx - px * qz
        cz = px * qy - py * qx
        d = np.sqrt(cx * cx + cy * cy + cz * cz)
        inv = 1.0 / d if d > 0.0 else 0.0
        cot_c[k] = dot * inv
        cot_p[k] = (lp - dot) * inv
        cot_n[k] = (ln - dot) * inv
        dbl[k] = d
        l_prev[k] = lp
        l_next[k] = ln
        l_skip[k] = lp + ln - 2.0 * dot
    return cot_p, cot_c, cot_n, dbl, l_prev, l_next, l_skip


@njit(cache=True)
def corner_scatter(w, cot_p, cot_c, cot_n, dbl, aw, nxt, prv, fi, corner_edge, skip_pair, P, n):
    """Pair weights (edge part + skip part), ring areas, as ``_assemble``'s bincounts."""
    c = fi.size
    pe = np.zeros(P)
    ps = np.zeros(P)
    ring = np.zeros(n)
    for k in range(c):
        pe[corner_edge[k]] += w[k] * cot_p[k] + w[nxt[k]] * cot_n[nxt[k]]
        ps[skip_pair[k]] += w[k] * cot_c[k]
    for k in range(c):
        ring[fi[k]] += 0.5 * dbl[k] * aw[k] + 0.5 * dbl[nxt[k]] * aw[nxt[k]] + 0.5 * dbl[prv[k]] * aw[prv[k]]
    return pe + ps, ring


@njit(cache=True)
def pair_degree(pairs, pw, n):
    deg0 = np.zeros(n)
    deg1 = np.zeros(n)
    for p in range(pw.size):
        deg0[pairs[p, 0]] += pw[p]
        deg1[pairs[p, 1]] += pw[p]
    return deg0 + deg1


@njit(cache=True)
def pair_pattern(pairs, n):
    """Symmetric CSR pattern of ``pairs`` plus the diagonal, duplicates kept.

    Same layout as ``operators._csr_pattern`` on rows = (p0, p1, diag), cols =
    (p1, p0, diag): columns sorted within a row, equal columns in that entry
    order.  Returns indptr, indices (int32) and the positions of every upper
    entry, lower entry and diagonal entry.
    """
    P = pairs.shape[0]
    indptr = np.zeros(n + 1, np.int32)
    for p in range(P):
        indptr[pairs[p, 0] + 1] += 1
        indptr[pairs[p, 1] + 1] += 1
    for i in range(n):
        indptr[i + 1] += indptr[i] + 1
    nnz = indptr[n]
    fill = indptr[:-1].copy()
    indices = np.empty(nnz, np.int32)
    tag = np.empty(nnz, np.int64)
    for p in range(P):
        r = pairs[p, 0]
        q = fill[r]
        indices[q] = pairs[p, 1]
        tag[q] = p
        fill[r] = q + 1
    for p in range(P):
        r = pairs[p, 1]
        q = fill[r]
        indices[q] = pairs[p, 0]
        tag[q] = P + p
        fill[r] = q + 1
    for i in range(n):
        q = fill[i]
        indices[q] = i
        tag[q] = 2 * P + i
    pos_upper = np.empty(P, np.int64)
    pos_lower = np.empty(P, np.int64)
    pos_diag = np.empty(n, np.int64)
    for i in range(n):
        s = indptr[i]
        e = indptr[i + 1]
        for q in range(s + 1, e):
            col = indices[q]
            t = tag[q]
            r = q - 1
            while r >= s and indices[r] > col:
                indices[r + 1] = indices[r]
                tag[r + 1] = tag[r]
                r -= 1
            indices[r + 1] = col
            tag[r + 1] = t
        for q in range(s, e):
            t = tag[q]
            if t < P:
                pos_upper[t] = q
            elif t < 2 * P:
                pos_lower[t - P] = q
            else:
                pos_diag[t - 2 * P] = q
    return indptr, indices, pos_upper, pos_lower, pos_diag


@njit(cache=True)
def structure_core(fi, offsets, nxt, prv, corner_edge, edges, tqlbo):
    """Corner weights, chord pairs and skip pairs of ``operators._Structure``.

    For meshes without tqlbo fan triangles (triangles and quads, or any
    polygon with the Blender scheme).  Returns corner_w, corner_aw,
    skip_pair and pairs = edges followed by the primary chords, in the
    order of the NumPy code.
    """
    m = offsets.size - 1
    c = fi.size
    n_edges = edges.shape[0]
    n_primary = 0
    for f in range(m):
        s = offsets[f + 1] - offsets[f]
        if s == 4:
            n_primary += 2
        elif s > 4:
            n_primary += s
    pairs = np.empty((n_edges + n_primary, 2), np.int64)
    pairs[:n_edges] = edges
    corner_w = np.empty(c)
    corner_aw = np.empty(c)
    skip_pair = np.empty(c, np.int64)
    cnt = 0
    for f in range(m):
        o = offsets[f]
        s = offsets[f + 1] - o
        if tqlbo:
            wv = 1.0 / 3.0 if s == 3 else 2.0 / s
            aw = wv
        else:
            wv = 0.5
            aw = 1.0
        for j in range(s):
            k = o + j
            corner_w[k] = wv
            corner_aw[k] = aw
            if s == 3:
                skip_pair[k] = corner_edge[nxt[k]]
            elif s == 4 and j >= 2:
                skip_pair[k] = skip_pair[k - 2]
            else:
                a = fi[prv[k]]
                b = fi[nxt[k]]
                pairs[n_edges + cnt, 0] = a if a < b else b
                pairs[n_edges + cnt, 1] = b if a < b else a
                skip_pair[k] = n_edges + cnt
                cnt += 1
    return corner_w, corner_aw, skip_pair, pairs


@njit(parallel=True, cache=True, fastmath=False)
def chebyshev_step(indptr, indices, data, cinv, Zcur, Zprev, Y, X0, cw, alpha, beta, cu, ch):
    """One degree of ``solvers.chebyshev_steps`` (see there), fused; returns Σ cw·(Y − X0)² per column."""
    n = indptr.size - 1
    s0 = 0.0
    s1 = 0.0
    s2 = 0.0
    for i in prange(n):
        a0 = 0.0
        a1 = 0.0
        a2 = 0.0
        a3 = 0.0
        a4 = 0.0
        a5 = 0.0
        for q in range(indptr[i], indptr[i + 1]):
            j = indices[q]
            v = data[q]
            a0 += v * Zcur[j, 0]
            a1 += v * Zcur[j, 1]
            a2 += v * Zcur[j, 2]
            a3 += v * Zcur[j, 3]
            a4 += v * Zcur[j, 4]
            a5 += v * Zcur[j, 5]
        ci = cinv[i] * alpha
        z0 = 2.0 * (ci * a0 - beta * Zcur[i, 0]) - Zprev[i, 0]
        z1 = 2.0 * (ci * a1 - beta * Zcur[i, 1]) - Zprev[i, 1]
        z2 = 2.0 * (ci * a2 - beta * Zcur[i, 2]) - Zprev[i, 2]
        z3 = 2.0 * (ci * a3 - beta * Zcur[i, 3]) - Zprev[i, 3]
        z4 = 2.0 * (ci * a4 - beta * Zcur[i, 4]) - Zprev[i, 4]
        z5 = 2.0 * (ci * a5 - beta * Zcur[i, 5]) - Zprev[i, 5]
        Zprev[i, 0] = z0
        Zprev[i, 1] = z1
        Zprev[i, 2] = z2
        Zprev[i, 3] = z3
        Zprev[i, 4] = z4
        Zprev[i, 5] = z5
        y0 = Y[i, 0] + cu * z0 + ch * z3
        y1 = Y[i, 1] + cu * z1 + ch * z4
        y2 = Y[i, 2] + cu * z2 + ch * z5
        Y[i, 0] = y0
        Y[i, 1] = y1
        Y[i, 2] = y2
        w = cw[i]
        d0 = y0 - X0[i, 0]
        d1 = y1 - X0[i, 1]
        d2 = y2 - X0[i, 2]
        s0 += w * d0 * d0
        s1 += w * d1 * d1
        s2 += w * d2 * d2
    out = np.empty(3)
    out[0] = s0
    out[1] = s1
    out[2] = s2
    return out
