"""Compiled operator assembly: the sparse pattern, the corner cotangent sums and the matrix fill.

:class:`OperatorNumba` is the numba implementation of the operators family; the NumPy/SciPy
reference is :class:`shapeflow.operators.kernels.OperatorKernels`, and the tests compare the two.
Conventions of all compiled kernels: :mod:`shapeflow.accel`.
"""

from __future__ import annotations

import numpy as np
from numba import get_num_threads, njit, prange

from ..accel import zeros
from ..geometry.compiled import corner_triangle
from .cotan import BLENDER_MIN, FLT_EPSILON, REL_EDGE_TOL, REL_SHAPE_TOL
from .kernels import OperatorKernels, no_extras


def fill_symmetric(nnz, pos_diag, diag, pos_upper, pos_lower, off):
    """The data array of a matrix on an ``OperatorPattern``."""
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


def assemble_corners(V, fi, offsets, corner_edge, skip_pair, tqlbo, edges,
                     P, n, blender_rules, rel_edge_tol, rel_shape_tol, blender_min, flt_eps):
    """``operators.cotan.assemble`` for the corner triangles in two passes, no per-corner temporaries.

    Same cotangent formulas and order of operations per corner as
    ``operators.corner_cotangents``, same locking rules; the pair weights and
    ring areas are summed in corner order instead of by ``bincount``, and a
    triangle's three corner triangles (the triangle itself) are computed once
    and weighted by 3 (equal to rounding).  Returns pair weights (P,), ring areas (n,), locked (n,) and
    the number of excluded corner triangles.
    """
    elen2 = np.empty(edges.shape[0])
    locked = zeros(n, np.bool_)
    pw = zeros(P)
    ring = zeros(n)
    _lock_short_edges(V, edges, blender_rules, rel_edge_tol, blender_min, elen2, locked)
    n_bad = _assemble_corners(V, fi, offsets, corner_edge, skip_pair, tqlbo, blender_rules, rel_shape_tol,
                              blender_min, flt_eps, locked, pw, ring)
    return pw, ring, locked, int(n_bad)


@njit(cache=True)
def _lock_short_edges(V, edges, blender_rules, rel_edge_tol, blender_min, elen2, locked):
    """Lock both ends of every edge shorter than the rule's threshold."""
    n_edges = elen2.size
    # squared edge lengths, edge by edge (low end to high end: the same bits as from either half-edge)
    for e in range(n_edges):
        a = np.uint64(edges[e, 0])
        b = np.uint64(edges[e, 1])
        dx = V[b, 0] - V[a, 0]
        dy = V[b, 1] - V[a, 1]
        dz = V[b, 2] - V[a, 2]
        elen2[e] = dx * dx + dy * dy + dz * dz
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


@njit(cache=True)
def _assemble_corners(V, fi, offsets, corner_edge, skip_pair, tqlbo, blender_rules, rel_shape_tol,
                      blender_min, flt_eps, locked, pw, ring):
    """Per corner triangle (prev, curr, next), face by face (weights by face size): the pair weights,
    ring areas, locks of bad corner triangles; returns their number."""
    m = offsets.size - 1
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
        if sz == 3:
            # a triangle's three corner triangles are the triangle itself: its cotangents and area once,
            # from the corner triangle of corner o + 1 (prev o, next o + 2), weighted by 3 (equal to the
            # corner-by-corner sums to rounding, a third of the work).  Written out here: a helper
            # function, even inlined, made this loop three times slower.
            ia = np.uint64(fi[o])
            ib = np.uint64(fi[o + 1])
            ic = np.uint64(fi[o + 2])
            lp, ln, dot, d = corner_triangle(V[ia, 0], V[ia, 1], V[ia, 2], V[ib, 0], V[ib, 1], V[ib, 2],
                                             V[ic, 0], V[ic, 1], V[ic, 2])
            if blender_rules:
                if 0.5 * d < blender_min:
                    locked[ia] = True
                    locked[ib] = True
                    locked[ic] = True
                bad = not (d > flt_eps)
            else:
                ls = lp + ln - 2.0 * dot
                bad = d <= rel_shape_tol * max(max(lp, ln), ls)
                if bad:
                    locked[ia] = True
                    locked[ib] = True
                    locked[ic] = True
            ca = 1.5 * d * awf
            ring[ia] += ca
            ring[ib] += ca
            ring[ic] += ca
            if bad:
                n_bad += 3
                continue
            inv = 3.0 * wf / d if d > 0.0 else 0.0
            pw[np.uint64(corner_edge[o + 1])] += (lp - dot) * inv    # angle at a, opposite b-c
            pw[np.uint64(corner_edge[o])] += (ln - dot) * inv        # angle at c, opposite a-b
            pw[np.uint64(skip_pair[o + 1])] += dot * inv             # angle at b, opposite a-c
            continue
        for j in range(sz):
            k = o + j
            kp = k - 1 if j > 0 else o + sz - 1          # no integer division in the corner loop
            ia = np.uint64(fi[kp])
            ib = np.uint64(fi[k])
            ic = np.uint64(fi[k + 1 if j + 1 < sz else o])
            lp, ln, dot, d = corner_triangle(V[ia, 0], V[ia, 1], V[ia, 2], V[ib, 0], V[ib, 1], V[ib, 2],
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
    deg0 = zeros(n)
    deg1 = zeros(n)
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

    Same layout as ``operators.pattern.csr_pattern`` on rows = (p0, p1, diag), cols =
    (p1, p0, diag): columns sorted within a row, equal columns in that entry
    order.  Returns indptr, indices (int32) and the positions of every upper
    entry, lower entry and diagonal entry.  Needs 2P + n < 2**31.
    """
    P = pairs.shape[0]
    nnz = 2 * P + n
    indptr = zeros(n + 1, np.int32)
    indices = np.empty(nnz, np.int32)
    pos_upper = np.empty(P, np.int32)
    pos_lower = np.empty(P, np.int32)
    pos_diag = np.empty(n, np.int32)
    if strictly_sorted(pairs):     # the edges of a mesh without chords: every row is in order as placed
        _sorted_pair_pattern(pairs, n, indptr, indices, pos_upper, pos_lower, pos_diag, zeros(n + 1, np.int32),
                             zeros(n, np.int32), get_num_threads())
    else:
        _pair_pattern(pairs, n, indptr, indices, np.empty(nnz, np.int32), pos_upper, pos_lower, pos_diag,
                      np.empty(n, np.int32), get_num_threads())
    return indptr, indices, pos_upper, pos_lower, pos_diag


@njit(cache=True)
def strictly_sorted(pairs):
    """Every pair (a, b) has a < b and the pairs increase lexicographically (no duplicates)."""
    pa = -1
    pb = -1
    for p in range(pairs.shape[0]):
        a = pairs[p, 0]
        b = pairs[p, 1]
        if a >= b or a < pa or (a == pa and b <= pb):
            return False
        pa = a
        pb = b
    return True


@njit(parallel=True, cache=True)
def _sorted_pair_pattern(pairs, n, indptr, indices, pos_upper, pos_lower, pos_diag, up, fill, nt):
    """``_pair_pattern`` for strictly sorted pairs: row i holds its lower entries (the pairs (a, i),
    in pair order, so by ascending a), its diagonal, then its upper entries (the pairs (i, b), which
    are consecutive and by ascending b): no sorting, no duplicates to order."""
    P = pairs.shape[0]
    for p in range(P):
        up[np.uint64(pairs[p, 0] + 1)] += 1
        fill[np.uint64(pairs[p, 1])] += 1
    for i in range(n):
        indptr[i + 1] = indptr[i] + fill[i] + 1 + up[i + 1]
        up[i + 1] += up[i]                   # up[i]: the first pair of row i
    for i in prange(n):
        q = indptr[i] + fill[i]
        indices[q] = i
        pos_diag[i] = q
        fill[i] = indptr[i]                  # from here: where row i's next lower entry goes
    for p in prange(P):
        a = np.uint64(pairs[p, 0])
        q = indptr[a + 1] - up[a + 1] + p     # the upper entries close their row, in pair order
        indices[q] = pairs[p, 1]
        pos_upper[p] = q
    for t in prange(nt):                     # thread t places the lower entries of its rows, in pair order
        v0 = t * n // nt
        w = np.uint64((t + 1) * n // nt - v0)
        for p in range(P):
            b = pairs[p, 1]
            if np.uint64(b - v0) < w:
                q = fill[np.uint64(b)]
                indices[np.uint64(q)] = pairs[p, 0]
                pos_lower[p] = q
                fill[np.uint64(b)] = q + 1


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
    """Chord pairs and skip pairs of ``operators.pattern.OperatorPattern``.

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


class OperatorNumba(OperatorKernels):
    """The operators family compiled."""

    backend = "numba"

    def pattern_core(self, topology, scheme):
        sizes = topology.face_sizes
        if not (scheme == "blender" or sizes.size == 0 or int(sizes.max()) <= 4):
            return super().pattern_core(topology, scheme)      # fan triangles of tqlbo n-gons
        # the corner weights depend on the face size only: the pattern makes them on demand
        skip_pair, pairs = structure_core(topology.face_indices, topology.face_offsets, topology.corner_edge,
                                          topology.edges, topology.n_vertices)
        return pairs, skip_pair, no_extras(), None

    def pair_pattern(self, pairs, n):
        if 2 * pairs.shape[0] + n >= 2**31 - 1:
            return super().pair_pattern(pairs, n)
        return pair_pattern(pairs, n)

    def fill_symmetric(self, nnz, pos_diag, diag, pos_upper, pos_lower, off):
        return fill_symmetric(nnz, pos_diag, np.asarray(diag, np.float64), pos_upper, pos_lower,
                              np.asarray(off, np.float64))

    def locality(self, pattern):
        """Reverse Cuthill–McKee order of the pattern's graph (scipy), the pattern permuted compiled."""
        import scipy.sparse as sp
        from scipy.sparse.csgraph import reverse_cuthill_mckee

        indptr, indices, n = pattern.indptr, pattern.indices, pattern.n
        G = sp.csr_matrix((np.ones(indices.size), indices, indptr), shape=(n, n))
        perm = reverse_cuthill_mckee(G, symmetric_mode=True).astype(np.int64)
        ptr, idx, src = permute_pattern(indptr, indices, perm)
        inv = np.empty_like(perm)
        inv[perm] = np.arange(perm.size)
        return perm, inv, ptr, idx, src

    def assemble_corners(self, V, pattern, topology, thresholds):
        return assemble_corners(np.ascontiguousarray(V, dtype=np.float64), pattern.fi, topology.face_offsets,
                                pattern.corner_edge, pattern.skip_pair, pattern.scheme == "tqlbo", topology.edges,
                                pattern.pairs.shape[0], topology.n_vertices, thresholds == "blender",
                                REL_EDGE_TOL, REL_SHAPE_TOL, BLENDER_MIN, FLT_EPSILON)

    def pair_degree(self, pairs, pw, n):
        return pair_degree(pairs, pw, n)
