"""Compiled kernels (numba) for the hot paths; imported only through :mod:`shapeflow.kernels`.

Every kernel here has a NumPy/SciPy twin that stays the reference: the tests
run both and compare.  Kernels are compiled on first use and cached on disk
(``cache=True``), so a new process pays the compilation once per machine.

Large arrays are allocated by NumPy in the plain-Python wrappers and filled by
the compiled ``_`` functions, so every big allocation goes through NumPy,
whose page policy the callers set (:func:`shapeflow.kernels.small_pages`:
on the virtual machines we measure on, first-touch page faults cost more
than many of the loops).

Indices read from arrays are cast to ``np.uint64`` before they index another
array: numba tests every signed index for a negative value (wraparound), and
these gathers are the inner loops (measured: CSR product ~15% faster, corner
assembly ~25%).  Only indices that cannot be negative are cast.
"""

from __future__ import annotations

import numpy as np
from numba import get_num_threads, njit, prange


def _zeros(shape, dtype=np.float64):
    """np.zeros as np.empty + fill: the pages are first touched here, by one thread, not by
    both threads of a parallel loop (concurrent page faults contend for the memory map)."""
    a = np.empty(shape, dtype)
    a.fill(0)
    return a


# --------------------------------------------------------------------------
# Jacobi-preconditioned CG on k columns at once (k <= 3), one matrix pass
# --------------------------------------------------------------------------

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


@njit(parallel=True, cache=True, fastmath=False)
def _spmm_dot(indptr, indices, data, P, AP, k):
    """AP = A P (P, AP are (n, 3)); returns the k column dots pᵀAp."""
    n = indptr.size - 1
    s0 = 0.0
    s1 = 0.0
    s2 = 0.0
    for i in prange(n):
        a0, a1, a2 = _row_times3(indptr, indices, data, P, i)
        AP[i, 0] = a0
        AP[i, 1] = a1
        AP[i, 2] = a2
        s0 += a0 * P[i, 0]
        s1 += a1 * P[i, 1]
        s2 += a2 * P[i, 2]
    return np.array([s0, s1, s2])


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
    return np.array([s0, s1, s2])


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
    work = _zeros((2 if overwrite_b else 3, B.shape[0], 3))
    R = B if overwrite_b else work[2]
    return _pcg3(indptr, indices, data, minv, B, X, rtol, maxiter, work[0], work[1], R)


@njit(cache=True)
def _pcg3(indptr, indices, data, minv, B, X, rtol, maxiter, P, AP, R):
    """R may be B itself: B is read once, before R is written."""
    n = B.shape[0]
    k = 3
    _spmm_dot(indptr, indices, data, X, AP, k)
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

def edge_data(fi, offsets, n):
    """Same outputs as the NumPy ``Topology._edge_data``.

    Half-edges are bucketed by their low vertex (counting sort, stable in
    corner order), then each small bucket is insertion-sorted by the high
    vertex (stable), which is the order of a stable argsort of lo·n + hi;
    edges are numbered bucket by bucket.  Walks the faces (``offsets``), so
    the corner_next array is not needed.  The bucketing runs on all threads,
    each placing the half-edges of its own range of low vertices.
    """
    c = fi.size
    vt = np.int32 if n < 2**31 - 1 else np.int64
    lo = np.empty(c, vt)
    hi = np.empty(c, vt)
    order = np.empty(c, np.int64)
    start = _zeros(n + 1, np.int64)
    ucount = np.empty(n + 1, np.int64)
    n_e = _edge_sort(fi, offsets, n, lo, hi, order, start, ucount, get_num_threads())
    edges = np.empty((n_e, 2), np.int64)
    starts = np.empty(n_e + 1, np.int64)
    corner_edge = np.empty(c, np.int64)
    _edge_number(n, hi, order, start, ucount, corner_edge, starts, edges)
    return edges, corner_edge, starts, order


@njit(parallel=True, cache=True)
def _edge_sort(fi, offsets, n, lo, hi, order, start, ucount, nt):
    """Buckets of half-edges by low vertex, sorted by high vertex; returns the number of edges
    (``ucount[v]`` = edges of the buckets before v)."""
    c = fi.size
    m = offsets.size - 1
    for f in prange(m):
        o = offsets[f]
        e = offsets[f + 1]
        for k in range(o, e):
            a = fi[k]
            b = fi[k + 1] if k + 1 < e else fi[o]
            if a < b:
                lo[k] = a
                hi[k] = b
            else:
                lo[k] = b
                hi[k] = a
    # thread t counts and places the half-edges whose low end lies in its range [v0, v1),
    # scanning all corners in order (so every bucket stays in corner order)
    for t in prange(nt):
        v0 = t * n // nt
        w = np.uint64((t + 1) * n // nt - v0)
        for k in range(c):
            a = lo[k]
            if np.uint64(a - v0) < w:
                start[np.uint64(a + 1)] += 1
    for v in range(n):
        start[v + 1] += start[v]
    for t in prange(nt):
        v0 = t * n // nt
        v1 = (t + 1) * n // nt
        w = np.uint64(v1 - v0)
        fill = start[v0:v1].copy()
        for k in range(c):
            j = np.uint64(lo[k] - v0)
            if j < w:
                order[np.uint64(fill[j])] = k
                fill[j] += 1
    # insertion sort of each bucket by hi (stable), then its number of distinct edges
    for v in prange(n):
        s = start[v]
        e = start[v + 1]
        for q in range(s + 1, e):
            k = order[q]
            h = hi[np.uint64(k)]
            r = q - 1
            while r >= s and hi[np.uint64(order[r])] > h:
                order[r + 1] = order[r]
                r -= 1
            order[r + 1] = k
        u = 0
        prev = -1
        for q in range(s, e):
            h = hi[np.uint64(order[q])]
            if h != prev:
                u += 1
                prev = h
        ucount[v + 1] = u
    ucount[0] = 0
    for v in range(n):
        ucount[v + 1] += ucount[v]
    return ucount[n]


@njit(parallel=True, cache=True)
def _edge_number(n, hi, order, start, ucount, corner_edge, starts, edges):
    """Edge ids bucket by bucket: the edges (low, high), where each edge's corners start, each corner's edge."""
    for v in prange(n):
        s = start[v]
        e = start[v + 1]
        eid = ucount[v] - 1
        prev = -1
        for q in range(s, e):
            k = np.uint64(order[q])
            h = hi[k]
            if h != prev:
                eid += 1
                prev = h
                starts[eid] = q
                edges[eid, 0] = v
                edges[eid, 1] = h
            corner_edge[k] = eid
    starts[starts.size - 1] = order.size


def first_bad_face(fi, offsets, n):
    """Index of the first face with fewer than 3 corners, a vertex outside [0, n) or a vertex
    listed twice; -1 if none.  ``Mesh`` validation's fast path (the messages come from the
    NumPy checks, run only when this finds something)."""
    return int(_first_bad_face(fi, offsets, n, get_num_threads()))


@njit(parallel=True, cache=True)
def _first_bad_face(fi, offsets, n, nt):
    m = offsets.size - 1
    first = np.full(nt, m)
    for t in prange(nt):              # each thread scans its range of faces up to its first bad one
        f0 = t * m // nt
        f1 = (t + 1) * m // nt
        for f in range(f0, f1):
            s = offsets[f]
            e = offsets[f + 1]
            bad = e - s < 3
            for a in range(s, e):
                va = fi[a]
                if va < 0 or va >= n:
                    bad = True
            if not bad and e - s <= 16:      # small faces: compare the pairs
                for a in range(s, e):
                    for b in range(a + 1, e):
                        if fi[b] == fi[a]:
                            bad = True
            elif not bad:                    # large faces: sort a copy, O(k log k), not O(k²)
                srt = np.sort(fi[s:e])
                for a in range(srt.size - 1):
                    if srt[a] == srt[a + 1]:
                        bad = True
                        break
            if bad:
                first[t] = f
                break
    best = m
    for t in range(nt):
        best = min(best, first[t])
    return best if best < m else -1


# --------------------------------------------------------------------------
# the operator's sparse pattern (operators._Structure)
# --------------------------------------------------------------------------

def fill_symmetric(nnz, pos_diag, diag, pos_upper, pos_lower, off):
    """The data array of a matrix on a ``_Structure`` pattern."""
    data = np.empty(nnz)
    _fill_symmetric(data, pos_diag, diag, pos_upper, pos_lower, off)
    return data


@njit(cache=True)
def _fill_symmetric(data, pos_diag, diag, pos_upper, pos_lower, off):
    for i in range(pos_diag.size):
        data[pos_diag[i]] = diag[i]
    for p in range(pos_upper.size):
        data[pos_upper[p]] = off[p]
        data[pos_lower[p]] = off[p]


def interior_data(nnz, pos_diag, pos_upper, pos_lower, pairs, free, c, deg, pw):
    """Matrix data of the interior system (``FlowSolver._interior_system``) in one pass.

    Free rows: c + D on the diagonal, −w_ij where both ends are free; other
    rows are identity rows.  Returns the data array, the diagonal, the numbers
    of pairs with only their first / only their second end free (their terms
    go to the right-hand side; see :func:`interior_coupling`) and max D/c over
    the free rows with c ≠ 0 (for the κ estimate).
    """
    data = np.empty(nnz)
    diag = np.empty(pos_diag.size)
    n_a, n_b, ratio = _interior_data(pos_diag, pos_upper, pos_lower, pairs, free, c, deg, pw, data, diag)
    return data, diag, (int(n_a), int(n_b)), float(ratio)


def interior_coupling(pairs, free, pw, mixed):
    """The pairs with exactly one free end, as ``FlowSolver._interior_system`` lists them:
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
def _interior_data(pos_diag, pos_upper, pos_lower, pairs, free, c, deg, pw, data, diag):
    ratio = 0.0
    for i in range(pos_diag.size):
        if free[i]:
            d = c[i] + deg[i]
            if c[i] != 0.0:
                ratio = max(ratio, abs(deg[i] / c[i]))
            else:
                ratio = max(ratio, abs(deg[i]))
        else:
            d = 1.0
        diag[i] = d
        data[np.uint64(pos_diag[i])] = d
    n_a = 0
    n_b = 0
    for p in range(pos_upper.size):
        fa = free[np.uint64(pairs[p, 0])]
        fb = free[np.uint64(pairs[p, 1])]
        v = -pw[p] if (fa and fb) else 0.0
        if fa and not fb:
            n_a += 1
        elif fb and not fa:
            n_b += 1
        data[np.uint64(pos_upper[p])] = v
        data[np.uint64(pos_lower[p])] = v
    return n_a, n_b, ratio


# --------------------------------------------------------------------------
# assembly (operators.corner_cotangents and the scatters of operators._assemble)
# --------------------------------------------------------------------------

@njit(inline="always")
def _corner(ax, ay, az, bx, by, bz, dx, dy, dz):
    """Corner triangle (prev a, curr b, next d), as ``operators.corner_cotangents``:
    |b − a|², |d − b|², (a − b)·(d − b) and twice the area."""
    px = bx - ax
    py = by - ay
    pz = bz - az
    qx = dx - bx
    qy = dy - by
    qz = dz - bz
    lp = px * px + py * py + pz * pz
    ln = qx * qx + qy * qy + qz * qz
    dot = -(px * qx + py * qy + pz * qz)
    cx = py * qz - pz * qy
    cy = pz * qx - px * qz
    cz = px * qy - py * qx
    return lp, ln, dot, np.sqrt(cx * cx + cy * cy + cz * cz)


def assemble_corners(V, fi, offsets, corner_edge, skip_pair, tqlbo, edges,
                     P, n, blender_rules, rel_edge_tol, rel_shape_tol, blender_min, flt_eps):
    """``operators._assemble`` for the corner triangles in two passes, no per-corner temporaries.

    Same cotangent formulas and order of operations per corner as
    ``operators.corner_cotangents``, same locking rules; the pair weights and
    ring areas are summed in corner order instead of by ``bincount`` (equal to
    rounding).  Returns pair weights (P,), ring areas (n,), locked (n,) and
    the number of excluded corner triangles.
    """
    elen2 = np.empty(edges.shape[0])
    locked = _zeros(n, np.bool_)
    pw = _zeros(P)
    ring = _zeros(n)
    n_bad = _assemble_corners(V, fi, offsets, corner_edge, skip_pair, tqlbo, edges,
                              blender_rules, rel_edge_tol, rel_shape_tol, blender_min, flt_eps,
                              elen2, locked, pw, ring)
    return pw, ring, locked, int(n_bad)


@njit(cache=True)
def _assemble_corners(V, fi, offsets, corner_edge, skip_pair, tqlbo, edges,
                      blender_rules, rel_edge_tol, rel_shape_tol, blender_min, flt_eps,
                      elen2, locked, pw, ring):
    m = offsets.size - 1
    n_edges = elen2.size
    # pass 1: squared edge lengths, from each corner's half-edge curr -> next
    for f in range(m):
        o = offsets[f]
        e = offsets[f + 1]
        for k in range(o, e):
            a = np.uint64(fi[k])
            b = np.uint64(fi[k + 1] if k + 1 < e else fi[o])
            dx = V[b, 0] - V[a, 0]
            dy = V[b, 1] - V[a, 1]
            dz = V[b, 2] - V[a, 2]
            elen2[np.uint64(corner_edge[k])] = dx * dx + dy * dy + dz * dz
    if blender_rules:
        thr = blender_min * blender_min
        for e in range(n_edges):
            if elen2[e] < thr:
                locked[edges[e, 0]] = True
                locked[edges[e, 1]] = True
    else:
        h = 0.0
        for e in range(n_edges):
            h += np.sqrt(elen2[e])
        h = h / n_edges if n_edges else 0.0
        thr = (rel_edge_tol * h) ** 2
        for e in range(n_edges):
            if elen2[e] <= thr:
                locked[edges[e, 0]] = True
                locked[edges[e, 1]] = True
    # pass 2: per corner triangle (prev, curr, next), face by face (weights by face size)
    n_bad = 0
    for f in range(m):
        o = offsets[f]
        sz = offsets[f + 1] - o
        if tqlbo:
            wf = 1.0 / 3.0 if sz == 3 else 2.0 / sz
            awf = wf
        else:
            wf = 0.5
            awf = 1.0
        for j in range(sz):
            k = o + j
            kp = o + (j + sz - 1) % sz
            ia = np.uint64(fi[kp])
            ib = np.uint64(fi[k])
            ic = np.uint64(fi[o + (j + 1) % sz])
            lp, ln, dot, d = _corner(V[ia, 0], V[ia, 1], V[ia, 2], V[ib, 0], V[ib, 1], V[ib, 2],
                                     V[ic, 0], V[ic, 1], V[ic, 2])
            if blender_rules:
                if 0.5 * d < blender_min:
                    locked[ib] = True
                bad = not (d > flt_eps)
            else:
                ls = lp + ln - 2.0 * dot
                bad = d <= rel_shape_tol * max(max(lp, ln), ls)
                if bad:
                    locked[ia] = True
                    locked[ib] = True
                    locked[ic] = True
            ca = 0.5 * d * awf
            ring[ia] += ca
            ring[ib] += ca
            ring[ic] += ca
            if bad:
                n_bad += 1
                continue
            inv = 1.0 / d if d > 0.0 else 0.0
            pw[np.uint64(corner_edge[k])] += wf * ((lp - dot) * inv)     # angle at prev, opposite curr-next
            pw[np.uint64(corner_edge[kp])] += wf * ((ln - dot) * inv)    # angle at next, opposite prev-curr
            pw[np.uint64(skip_pair[k])] += wf * (dot * inv)              # angle at curr, opposite prev-next
    return n_bad


def pair_degree(pairs, pw, n):
    """Σ of the pair weights at each end (the two bincounts of ``_assemble``, added)."""
    deg0 = _zeros(n)
    deg1 = _zeros(n)
    _pair_degree(pairs, pw, deg0, deg1)
    deg0 += deg1
    return deg0


@njit(cache=True)
def _pair_degree(pairs, pw, deg0, deg1):
    for p in range(pw.size):
        deg0[np.uint64(pairs[p, 0])] += pw[p]
        deg1[np.uint64(pairs[p, 1])] += pw[p]


def pair_pattern(pairs, n):
    """Symmetric CSR pattern of ``pairs`` plus the diagonal, duplicates kept.

    Same layout as ``operators._csr_pattern`` on rows = (p0, p1, diag), cols =
    (p1, p0, diag): columns sorted within a row, equal columns in that entry
    order.  Returns indptr, indices (int32) and the positions of every upper
    entry, lower entry and diagonal entry.  Needs 2P + n < 2**31.
    """
    P = pairs.shape[0]
    nnz = 2 * P + n
    indptr = _zeros(n + 1, np.int32)
    indices = np.empty(nnz, np.int32)
    tag = np.empty(nnz, np.int32)
    pos_upper = np.empty(P, np.int32)
    pos_lower = np.empty(P, np.int32)
    pos_diag = np.empty(n, np.int32)
    _pair_pattern(pairs, n, indptr, indices, tag, pos_upper, pos_lower, pos_diag, np.empty(n, np.int32),
                  get_num_threads())
    return indptr, indices, pos_upper, pos_lower, pos_diag


@njit(parallel=True, cache=True)
def _pair_pattern(pairs, n, indptr, indices, tag, pos_upper, pos_lower, pos_diag, fill, nt):
    P = pairs.shape[0]
    for p in range(P):
        indptr[np.uint64(pairs[p, 0] + 1)] += 1
        indptr[np.uint64(pairs[p, 1] + 1)] += 1
    for i in range(n):
        indptr[i + 1] += indptr[i] + 1
    # thread t places the entries of its rows [v0, v1), scanning all pairs in order
    # (upper entries, then lower entries, then the diagonal: the entry order of the NumPy code)
    for t in prange(nt):
        v0 = t * n // nt
        v1 = (t + 1) * n // nt
        w = np.uint64(v1 - v0)
        for i in range(v0, v1):
            fill[i] = indptr[i]
        for p in range(P):
            r = pairs[p, 0]
            if np.uint64(r - v0) < w:
                q = fill[np.uint64(r)]
                indices[np.uint64(q)] = pairs[p, 1]
                tag[np.uint64(q)] = p
                fill[np.uint64(r)] = q + 1
        for p in range(P):
            r = pairs[p, 1]
            if np.uint64(r - v0) < w:
                q = fill[np.uint64(r)]
                indices[np.uint64(q)] = pairs[p, 0]
                tag[np.uint64(q)] = P + p
                fill[np.uint64(r)] = q + 1
        for i in range(v0, v1):
            q = fill[i]
            indices[q] = i
            tag[q] = 2 * P + i
    for i in prange(n):   # rows are independent: sort, then record where each entry went
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
                pos_upper[np.uint64(t)] = q
            elif t < 2 * P:
                pos_lower[np.uint64(t - P)] = q
            else:
                pos_diag[np.uint64(t - 2 * P)] = q


def structure_core(fi, offsets, corner_edge, edges, n):
    """Chord pairs and skip pairs of ``operators._Structure``.

    For meshes without tqlbo fan triangles (triangles and quads, or any
    polygon with the Blender scheme).  Returns skip_pair (int32 when the
    pairs allow) and pairs (int32 when the n vertices allow) = edges followed
    by the primary chords, in the order of the NumPy code.  (The corner weights depend on the face size
    only; ``assemble_corners`` computes them on the fly.)
    """
    sizes = np.diff(offsets)
    n_edges = edges.shape[0]
    n_primary = 2 * int(np.count_nonzero(sizes == 4)) + int(sizes[sizes > 4].sum())
    P = n_edges + n_primary
    pairs = np.empty((P, 2), np.int32 if n < 2**31 - 1 else np.int64)   # int32: half the bytes
    pairs[:n_edges] = edges
    skip_pair = np.empty(fi.size, np.int32 if P < 2**31 - 1 else np.int64)
    _structure_core(fi, offsets, corner_edge, n_edges, pairs, skip_pair)
    return skip_pair, pairs


@njit(cache=True)
def _structure_core(fi, offsets, corner_edge, n_edges, pairs, skip_pair):
    m = offsets.size - 1
    cnt = 0
    for f in range(m):
        o = offsets[f]
        s = offsets[f + 1] - o
        for j in range(s):
            k = o + j
            if s == 3:
                skip_pair[k] = corner_edge[o + (j + 1) % 3]
            elif s == 4 and j >= 2:
                skip_pair[k] = skip_pair[k - 2]
            else:
                a = fi[o + (j + s - 1) % s]
                b = fi[o + (j + 1) % s]
                pairs[n_edges + cnt, 0] = a if a < b else b
                pairs[n_edges + cnt, 1] = b if a < b else a
                skip_pair[k] = n_edges + cnt
                cnt += 1


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


def permute_pattern(indptr, indices, perm):
    """The symmetric pattern (indptr, indices) with rows and columns in the order ``perm``.

    Returns (indptr, indices) of the permuted pattern (columns sorted within a
    row, equal columns in their original order) and ``source``: the position
    in the original pattern of each permuted entry, so permuted data =
    data[source].
    """
    n = perm.size
    inv = np.empty(n, np.int64)
    inv[perm] = np.arange(n)
    ptr = np.zeros(n + 1, np.int32)
    np.cumsum(np.diff(indptr)[perm], out=ptr[1:])
    idx = np.empty(indices.size, np.int32)
    src = np.empty(indices.size, np.int32)
    _permute_pattern(indptr, indices, perm, inv, ptr, idx, src)
    return ptr, idx, src


@njit(parallel=True, cache=True)
def _permute_pattern(indptr, indices, perm, inv, ptr, idx, src):
    for r in prange(perm.size):
        o = perm[r]
        s = indptr[o]
        q0 = ptr[r]
        for t in range(indptr[o + 1] - s):
            col = inv[np.uint64(indices[s + t])]
            q = q0 + t
            while q > q0 and idx[q - 1] > col:      # insertion sort, stable
                idx[q] = idx[q - 1]
                src[q] = src[q - 1]
                q -= 1
            idx[q] = col
            src[q] = s + t


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


# --------------------------------------------------------------------------
# brush: the cache update after a dab (brush.Brush._update_triangles)
# --------------------------------------------------------------------------

@njit(cache=True)
def brush_update_triangles(tris, tv, tp, tw, taw, VT, tval, tarea, update_area, tbad, vlock, pw,
                           ttri, pshort, short2, shape_tol, flips):
    """Recompute triangles ``tris`` of the brush cache in one pass.

    Same formulas and order of operations per triangle as ``brush._tri_geometry``
    and the incremental branch of ``Brush._update_triangles``: pair weights
    change by (new − old), lock counts by degenerate flips.  Pairs whose
    "short edge" state may have flipped are written to ``flips``; returns
    their number (the caller re-checks them).
    """
    nf = 0
    for q in range(tris.size):
        t = tris[q]
        a = tv[0, t]
        b = tv[1, t]
        d = tv[2, t]
        sq2, sq0, dot, dbl = _corner(VT[0, a], VT[1, a], VT[2, a], VT[0, b], VT[1, b], VT[2, b],
                                     VT[0, d], VT[1, d], VT[2, d])
        sx = VT[0, d] - VT[0, a]       # the skip side from its own end points, as _tri_geometry
        sy = VT[1, d] - VT[1, a]
        sz = VT[2, d] - VT[2, a]
        sq1 = sx * sx + sy * sy + sz * sz
        inv = 1.0 / dbl if dbl > 0 else 0.0
        bad = dbl <= shape_tol * max(max(sq0, sq1), sq2)
        w = 0.0 if bad else tw[t]
        if update_area:
            tarea[t] = 0.5 * dbl * taw[t]
        new0 = ((sq2 - dot) * inv) * w
        new1 = (dot * inv) * w
        new2 = ((sq0 - dot) * inv) * w
        pw[tp[0, t]] += new0 - tval[0, t]
        pw[tp[1, t]] += new1 - tval[1, t]
        pw[tp[2, t]] += new2 - tval[2, t]
        tval[0, t] = new0
        tval[1, t] = new1
        tval[2, t] = new2
        if tbad[t] != bad:
            delta = 1 if bad else -1
            vlock[a] += delta
            vlock[b] += delta
            vlock[d] += delta
            tbad[t] = bad
        e = tp[0, t]
        if (sq0 <= short2) != pshort[e]:
            flips[nf] = e
            nf += 1
        if ttri[t]:
            e = tp[1, t]
            if (sq1 <= short2) != pshort[e]:
                flips[nf] = e
                nf += 1
            e = tp[2, t]
            if (sq2 <= short2) != pshort[e]:
                flips[nf] = e
                nf += 1
    return nf


@njit(cache=True)
def brush_moved_triangles(idx, vf_ptr, vf_face, ft_ptr, fstamp, out):
    """Triangles of the faces touching vertices ``idx``, each once (``Brush._moved``).

    ``fstamp`` (one int per face, values >= 0) is the scratch of
    ``brush._unique_stamp``: faces seen are marked −1 and reset to 0.  ``out``
    (a buffer kept by the brush, so a dab allocates nothing mesh-sized) must
    hold every triangle found; returns their number.
    """
    nt = 0
    for q in range(idx.size):
        v = idx[q]
        for e in range(vf_ptr[v], vf_ptr[v + 1]):
            f = vf_face[e]
            if fstamp[f] >= 0:
                fstamp[f] = -1
                for t in range(ft_ptr[f], ft_ptr[f + 1]):
                    out[nt] = t
                    nt += 1
    for q in range(idx.size):
        v = idx[q]
        for e in range(vf_ptr[v], vf_ptr[v + 1]):
            fstamp[vf_face[e]] = 0
    return nt


# --------------------------------------------------------------------------
# brush: the region of a dab (brush.Brush._classify and _solve_region)
# --------------------------------------------------------------------------

@njit(cache=True)
def brush_classify(S, slot, vn_ptr, vn_nb, vn_pair, pw, rim, deg):
    """Rim flags and degrees of the region ``S`` (``slot[S]`` = 0..ns−1, −1 elsewhere).

    As ``Brush._classify``: a vertex is on the rim when a face neighbour lies
    outside the region (or it has none); its degree is the sum of its pair
    weights in neighbour order (the order ``bincount`` adds them).  Returns
    the number of neighbour entries of the region.
    """
    total = 0
    for i in range(S.size):
        v = np.uint64(S[i])
        s = vn_ptr[v]
        e = vn_ptr[v + 1]
        r = e == s
        acc = 0.0
        for q in range(s, e):
            if slot[np.uint64(vn_nb[q])] < 0:
                r = True
            acc += pw[np.uint64(vn_pair[q])]
        rim[i] = r
        deg[i] = acc
        total += e - s
    return total


@njit(cache=True)
def brush_assemble(S, R, loc, slot, vn_ptr, vn_nb, vn_pair, pw, V, cdiag, bl, Xb, ri, ci, vi, rhs, VU):
    """The interior system of a dab, as ``Brush._solve_region``'s NumPy assembly.

    Rows are the free region rows ``R`` (increasing; ``loc`` maps a region row
    to its unknown, −1 if fixed).  Fills the off-diagonal entries (ri, ci,
    vi = −w) grouped by row in neighbour order, the positions ``VU`` and
    ``rhs`` = C·VU + Σ w·x over the fixed neighbours (their positions, or
    ``Xb[bl]`` for neighbours solved in the boundary step), the coupling sum
    formed first as ``bincount`` does.  Returns the number of entries.
    """
    m = 0
    for a in range(R.size):
        v = np.uint64(S[R[a]])
        s0 = 0.0
        s1 = 0.0
        s2 = 0.0
        for q in range(vn_ptr[v], vn_ptr[v + 1]):
            nb = np.uint64(vn_nb[q])
            sn = np.uint64(slot[nb])        # neighbours of free rows are inside the region
            w = pw[np.uint64(vn_pair[q])]
            c = loc[sn]
            if c >= 0:
                ri[m] = a
                ci[m] = c
                vi[m] = -w
                m += 1
            else:
                j = bl[sn]
                if j >= 0:
                    s0 += w * Xb[j, 0]
                    s1 += w * Xb[j, 1]
                    s2 += w * Xb[j, 2]
                else:
                    s0 += w * V[nb, 0]
                    s1 += w * V[nb, 1]
                    s2 += w * V[nb, 2]
        x0 = V[v, 0]
        x1 = V[v, 1]
        x2 = V[v, 2]
        VU[a, 0] = x0
        VU[a, 1] = x1
        VU[a, 2] = x2
        cd = cdiag[a]
        rhs[a, 0] = cd * x0 + s0
        rhs[a, 1] = cd * x1 + s1
        rhs[a, 2] = cd * x2 + s2
    return m


@njit(cache=True)
def grid_query(keys, starts, order, dims, lo, h, V, far, c0, c1, c2, R, r, out, dist):
    """Vertices within ``r`` of (c0, c1, c2) at the positions ``V``, from a uniform grid.

    The grid (cell size ``h`` from ``lo``, ``dims`` cells per axis; occupied
    cell keys ``keys`` sorted, their vertices ``order[starts[p]:starts[p+1]]``)
    holds positions that differ from ``V`` by at most R − r, except the
    vertices flagged in ``far``, which are skipped (the caller checks them).
    Writes the found vertices and their distances to ``out`` and ``dist``
    (distance² summed x, y, z, as the NumPy query); returns their number.
    """
    lo_ = np.empty(3, np.int64)
    hi_ = np.empty(3, np.int64)
    cc = (c0, c1, c2)
    for a in range(3):
        fl = np.floor((cc[a] - R - lo[a]) / h)
        fh = np.floor((cc[a] + R - lo[a]) / h)
        lo_[a] = int(min(max(fl, 0.0), float(dims[a])))
        hi_[a] = int(min(max(fh, -1.0), float(dims[a] - 1)))
    r2 = r * r
    n = 0
    if lo_[0] > hi_[0] or lo_[1] > hi_[1] or lo_[2] > hi_[2]:
        return 0
    columns = (hi_[0] - lo_[0] + 1) * (hi_[1] - lo_[1] + 1)
    if columns > keys.size:   # a sphere much larger than the cells: scan the occupied cells
        for p in range(keys.size):
            kz = keys[p] % dims[2]
            kxy = keys[p] // dims[2]
            ky = kxy % dims[1]
            kx = kxy // dims[1]
            if lo_[0] <= kx <= hi_[0] and lo_[1] <= ky <= hi_[1] and lo_[2] <= kz <= hi_[2]:
                n = _grid_cell(starts, order, V, far, c0, c1, c2, r2, out, dist, p, n)
        return n
    for i in range(lo_[0], hi_[0] + 1):
        for j in range(lo_[1], hi_[1] + 1):
            base = (i * dims[1] + j) * dims[2]
            kl = base + hi_[2]
            p = np.searchsorted(keys, base + lo_[2])
            while p < keys.size and keys[p] <= kl:
                n = _grid_cell(starts, order, V, far, c0, c1, c2, r2, out, dist, p, n)
                p += 1
    return n


@njit(inline="always")
def _grid_cell(starts, order, V, far, c0, c1, c2, r2, out, dist, p, n):
    for q in range(starts[p], starts[p + 1]):
        v = np.uint64(order[q])
        if far[v]:
            continue
        dx = V[v, 0] - c0
        dy = V[v, 1] - c1
        dz = V[v, 2] - c2
        d2 = dx * dx + dy * dy + dz * dz
        if d2 <= r2:
            out[n] = v
            dist[n] = np.sqrt(d2)
            n += 1
    return n


# --------------------------------------------------------------------------
# brush: the dab system split in two banded halves, factored on two threads
# --------------------------------------------------------------------------

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
    """``brush.Brush._local_rcm``'s order of a connected system: :func:`_cm_sweeps`
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
def split_solve(pbtrf, tbtrs, potrf, potrs, trsm, syrk, gemm, set_threads,
                ri, ci, vi, diag, rhs, perm, inv, dims, buf, X):
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
