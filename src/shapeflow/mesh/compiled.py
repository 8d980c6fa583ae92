"""Compiled topology: unique edges and the first face with a repeated vertex.

:class:`MeshNumba` is the numba implementation of the mesh family; the NumPy/SciPy reference is
:class:`shapeflow.mesh.kernels.MeshKernels`, and the tests compare the two.
Conventions of all compiled kernels: :mod:`shapeflow.accel`.
"""

from __future__ import annotations

import numpy as np
from numba import get_num_threads, njit, prange

from ..accel import zeros
from .kernels import MeshKernels


def edge_data(fi, offsets, n, it=np.int64):
    """Same outputs as the NumPy ``MeshKernels.edge_data`` (index arrays of type ``it``).

    Half-edges are bucketed by their low vertex (counting sort, stable in
    corner order), then each small bucket is insertion-sorted by the high
    vertex (stable), which is the order of a stable argsort of lo·n + hi;
    edges are numbered bucket by bucket.  Walks the faces (``offsets``), so
    the corner_next array is not needed.  The bucketing runs on all threads,
    each placing the half-edges of its own range of low vertices, and stores
    each half-edge's high vertex beside its place in the buckets, so that the
    sort and the numbering read them in order rather than through ``order``.
    """
    c = fi.size
    vt = np.int32 if n < 2**31 - 1 else np.int64
    lo = np.empty(c, vt)
    hi = np.empty(c, vt)
    order = np.empty(c, it)
    start = zeros(n + 1, np.int64)
    ucount = np.empty(n + 1, np.int64)
    bh = np.empty(c, vt)
    n_e = _edge_sort(fi, offsets, n, lo, hi, bh, order, start, ucount, get_num_threads())
    del lo, hi
    edges = np.empty((n_e, 2), it)
    starts = np.empty(n_e + 1, it)
    corner_edge = np.empty(c, it)
    _edge_number(n, bh, order, start, ucount, corner_edge, starts, edges)
    return edges, corner_edge, starts, order


@njit(parallel=True, cache=True)
def _edge_sort(fi, offsets, n, lo, hi, bh, order, start, ucount, nt):
    """Buckets of half-edges by low vertex, sorted by high vertex; returns the number of edges
    (``ucount[v]`` = edges of the buckets before v).  ``lo``, ``hi``: each corner's half-edge;
    ``bh``: the high vertices in bucket order (``bh[q]`` belongs to corner ``order[q]``)."""
    c = fi.size
    m = offsets.size - 1
    for f in prange(m):
        o = offsets[f]
        e = offsets[f + 1]
        if e - o == 3:                  # triangles, written out: most faces of most meshes
            a = fi[o]
            b = fi[o + 1]
            d = fi[o + 2]
            lo[o] = min(a, b)
            hi[o] = max(a, b)
            lo[o + 1] = min(b, d)
            hi[o + 1] = max(b, d)
            lo[o + 2] = min(d, a)
            hi[o + 2] = max(d, a)
            continue
        for k in range(o, e):
            a = fi[k]
            b = fi[k + 1] if k + 1 < e else fi[o]
            lo[k] = min(a, b)
            hi[k] = max(a, b)
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
                q = np.uint64(fill[j])
                order[q] = k
                bh[q] = hi[k]
                fill[j] += 1
    # insertion sort of each bucket by its high vertices (stable), then its number of distinct edges
    for v in prange(n):
        s = start[v]
        e = start[v + 1]
        for q in range(s + 1, e):
            k = order[q]
            h = bh[q]
            r = q - 1
            while r >= s and bh[r] > h:
                order[r + 1] = order[r]
                bh[r + 1] = bh[r]
                r -= 1
            order[r + 1] = k
            bh[r + 1] = h
        u = 0
        prev = -1
        for q in range(s, e):
            h = bh[q]
            if h != prev:
                u += 1
                prev = h
        ucount[v + 1] = u
    ucount[0] = 0
    for v in range(n):
        ucount[v + 1] += ucount[v]
    return ucount[n]


@njit(parallel=True, cache=True)
def _edge_number(n, bh, order, start, ucount, corner_edge, starts, edges):
    """Edge ids bucket by bucket: the edges (low, high), where each edge's corners start, each corner's edge.
    ``bh``: the high vertices in bucket order."""
    for v in prange(n):
        s = start[v]
        e = start[v + 1]
        eid = ucount[v] - 1
        prev = -1
        for q in range(s, e):
            h = bh[q]
            if h != prev:
                eid += 1
                prev = h
                starts[eid] = q
                edges[eid, 0] = v
                edges[eid, 1] = h
            corner_edge[np.uint64(order[q])] = eid
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
            if e - s == 3:                   # triangles, written out: most faces of most meshes
                va = fi[s]
                vb = fi[s + 1]
                vc = fi[s + 2]
                if (np.uint64(va) >= np.uint64(n) or np.uint64(vb) >= np.uint64(n) or np.uint64(vc) >= np.uint64(n)
                        or va == vb or vb == vc or va == vc):
                    first[t] = f
                    break
                continue
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


class MeshNumba(MeshKernels):
    """The mesh family compiled: the edges in one bucketed pass, the faces checked in one pass."""

    backend = "numba"

    def edge_data(self, topology):
        return edge_data(topology.face_indices, topology.face_offsets, topology.n_vertices, topology.index_dtype)

    def check_faces(self, indices, offsets, n):
        if first_bad_face(indices, offsets, n) >= 0:     # the reference says what is wrong
            super().check_faces(indices, offsets, n)
