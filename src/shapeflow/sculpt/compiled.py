"""Compiled brush kernels: the cotangent cache update, the dab's region and system, the grid query.

:class:`SculptNumba` is the numba implementation of the sculpt family; the NumPy/SciPy reference
is :class:`shapeflow.sculpt.kernels.SculptKernels`, and the tests compare the two.
Conventions of all compiled kernels: :mod:`shapeflow.accel`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..geometry.compiled import corner_triangle
from ..operators.cotan import REL_SHAPE_TOL
from .grid import CellGrid
from .kernels import SculptKernels


@njit(cache=True)
def brush_update_triangles(tris, tri_vertices, tri_pairs, tri_weight, tri_area_weight, VT, tri_cot, tri_area,
                           update_area, tri_degenerate, lock_count, pw, ttri, pshort, short2, shape_tol, flips):
    """Recompute triangles ``tris`` of the brush cache in one pass.

    Same formulas and order of operations per triangle as ``geometry.cotangent.tri_geometry``
    and the incremental branch of ``SculptKernels.update_triangles``: pair weights
    change by (new − old), lock counts by degenerate flips.  Pairs whose
    "short edge" state may have flipped are written to ``flips``; returns
    their number (the caller re-checks them).
    """
    nf = 0
    for q in range(tris.size):
        t = tris[q]
        a = tri_vertices[0, t]
        b = tri_vertices[1, t]
        d = tri_vertices[2, t]
        sq2, sq0, dot, dbl = corner_triangle(VT[0, a], VT[1, a], VT[2, a], VT[0, b], VT[1, b], VT[2, b],
                                     VT[0, d], VT[1, d], VT[2, d])
        sx = VT[0, d] - VT[0, a]       # the skip side from its own end points, as _tri_geometry
        sy = VT[1, d] - VT[1, a]
        sz = VT[2, d] - VT[2, a]
        sq1 = sx * sx + sy * sy + sz * sz
        inv = 1.0 / dbl if dbl > 0 else 0.0
        bad = dbl <= shape_tol * max(max(sq0, sq1), sq2)
        w = 0.0 if bad else tri_weight[t]
        if update_area:
            tri_area[t] = 0.5 * dbl * tri_area_weight[t]
        new0 = ((sq2 - dot) * inv) * w
        new1 = (dot * inv) * w
        new2 = ((sq0 - dot) * inv) * w
        pw[tri_pairs[0, t]] += new0 - tri_cot[0, t]
        pw[tri_pairs[1, t]] += new1 - tri_cot[1, t]
        pw[tri_pairs[2, t]] += new2 - tri_cot[2, t]
        tri_cot[0, t] = new0
        tri_cot[1, t] = new1
        tri_cot[2, t] = new2
        if tri_degenerate[t] != bad:
            delta = 1 if bad else -1
            lock_count[a] += delta
            lock_count[b] += delta
            lock_count[d] += delta
            tri_degenerate[t] = bad
        e = tri_pairs[0, t]
        if (sq0 <= short2) != pshort[e]:
            flips[nf] = e
            nf += 1
        if ttri[t]:
            e = tri_pairs[1, t]
            if (sq1 <= short2) != pshort[e]:
                flips[nf] = e
                nf += 1
            e = tri_pairs[2, t]
            if (sq2 <= short2) != pshort[e]:
                flips[nf] = e
                nf += 1
    return nf


@njit(cache=True)
def brush_moved_triangles(idx, vf_ptr, vf_face, ft_ptr, fstamp, out):
    """Triangles of the faces touching vertices ``idx``, each once (``SculptKernels.moved_triangles``).

    ``fstamp`` (one int per face, values >= 0) is the scratch of
    ``sculpt.numbering.unique_stamp``: faces seen are marked −1 and reset to 0.  ``out``
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


@njit(cache=True)
def brush_classify(S, slot, vn_ptr, vn_nb, vn_pair, pw, rim, deg):
    """Rim flags and degrees of the region ``S`` (``slot[S]`` = 0..ns−1, −1 elsewhere).

    As ``SculptKernels.classify``: a vertex is on the rim when a face neighbour lies
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
    """The interior system of a dab, as ``SculptKernels.assemble``.

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


class CompiledGrid(CellGrid):
    """The uniform grid, queried compiled (:func:`grid_query`)."""

    def query(self, V, far, c, R, r):
        """The vertices not flagged in ``far`` within ``r`` of ``c`` at the positions ``V`` (which differ
        from the indexed ones by at most R − r for them), and their distances."""
        m = grid_query(self.keys, self.starts, self.order, self.dims, self.lo, self.h, V, far,
                       float(c[0]), float(c[1]), float(c[2]), float(R), float(r), self.out, self.dist)
        return self.out[:m].copy(), self.dist[:m].copy()


class SculptNumba(SculptKernels):
    """The sculpt family compiled: each kernel one pass, the spatial index a uniform grid."""

    backend = "numba"

    def update_triangles(self, tris, tri_vertices, tri_pairs, tri_weight, tri_area_weight, VT, tri_cot, tri_area,
                         update_area, tri_degenerate, lock_count, pw, ttri, pshort, short2, initial=False):
        if initial:
            return super().update_triangles(tris, tri_vertices, tri_pairs, tri_weight, tri_area_weight, VT,
                                            tri_cot, tri_area, update_area, tri_degenerate, lock_count, pw, ttri,
                                            pshort, short2, initial)
        flips = np.empty(3 * tris.size, tri_pairs.dtype)
        nf = brush_update_triangles(tris, tri_vertices, tri_pairs, tri_weight, tri_area_weight, VT, tri_cot,
                                    tri_area, update_area, tri_degenerate, lock_count, pw, ttri, pshort, short2,
                                    REL_SHAPE_TOL, flips)
        return flips[:nf]

    def moved_triangles(self, idx, vf_ptr, vf_face, ft_ptr, fstamp, buf):
        return buf[:brush_moved_triangles(idx, vf_ptr, vf_face, ft_ptr, fstamp, buf)]

    def classify(self, S, slot, vn_ptr, vn_nb, vn_pair, pw):
        rim = np.empty(S.size, dtype=bool)
        deg = np.empty(S.size)
        brush_classify(S, slot, vn_ptr, vn_nb, vn_pair, pw, rim, deg)
        return rim, deg, None       # assemble walks the neighbours again

    def assemble(self, S, R, loc, slot, vn_ptr, vn_nb, vn_pair, pw, V, cdiag, Rb, Xb, neighbours):
        ns, k = S.size, R.size
        U = S[R]
        bl = np.full(ns, -1, dtype=np.int64)
        if Rb.size:
            bl[Rb] = np.arange(Rb.size)
        nent = int(vn_ptr.take(U + 1, mode="clip").sum() - vn_ptr.take(U, mode="clip").sum())
        ri = np.empty(nent, np.int64)
        ci = np.empty(nent, np.int64)
        vi = np.empty(nent)
        rhs = np.empty((k, 3))
        VU = np.empty((k, 3))
        m = brush_assemble(S, R, loc, slot, vn_ptr, vn_nb, vn_pair, pw, V, cdiag, bl,
                           np.ascontiguousarray(Xb, dtype=np.float64), ri, ci, vi, rhs, VU)
        return ri[:m], ci[:m], vi[:m], rhs, VU

    def spatial_index(self, P, h):
        return CompiledGrid(P, h)
