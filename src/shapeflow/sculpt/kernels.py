"""The brushes' kernel family: the cotangent cache update, a dab's region and system, the spatial index
(NumPy/SciPy reference).

Every size (``min_size = 0``): a dab's work is small whatever the mesh.  The numba implementation
is :class:`shapeflow.sculpt.compiled.SculptNumba`; :func:`shapeflow.accel.kernels` chooses
(``accel.kernels("sculpt", n_vertices)``).  A dab asks once and uses that implementation for its
region and its system (:meth:`SculptKernels.classify` hands :meth:`SculptKernels.assemble` what it
found).
"""

from __future__ import annotations

import numpy as np

from ..accel import Family
from ..geometry.cotangent import tri_geometry
from ..operators.cotan import REL_SHAPE_TOL
from .grid import KDIndex
from .numbering import csr_ranges, unique_stamp

__all__ = ["SculptKernels"]


class SculptKernels(Family):
    """Kernels of :class:`~shapeflow.sculpt.cotan_cache.CotanCache`, :class:`~shapeflow.sculpt.dab.DabSystem`
    and the brushes' spatial queries."""

    family = "sculpt"
    min_size = 0

    def update_triangles(self, tris, tri_vertices, tri_pairs, tri_weight, tri_area_weight, VT, tri_cot, tri_area,
                         update_area, tri_degenerate, lock_count, pw, ttri, pshort, short2, initial=False):
        """Recompute the cached triangles ``tris`` (cotangent terms, areas when ``update_area``,
        degeneracy) from the positions ``VT`` (3, n), in place.

        ``initial``: fill the cache (the pair weights are summed afterwards).  Otherwise the pair
        weights ``pw`` change by each slot's (new − old) and the lock counts by the degenerate
        flips.  Returns the pairs whose "short edge" state may have flipped (the caller re-checks
        them; a pair may repeat).
        """
        tvs = tuple(tri_vertices[q].take(tris, mode="clip") for q in range(3))
        cot, dbl, sq = tri_geometry(VT, tvs)
        bad = dbl <= REL_SHAPE_TOL * np.maximum(np.maximum(sq[0], sq[1]), sq[2])
        w = tri_weight.take(tris, mode="clip")
        anybad = bad.any()
        if anybad:
            w = np.where(bad, 0.0, w)
        if update_area:
            tri_area[tris] = 0.5 * dbl * tri_area_weight[tris]
        if initial:
            for k in range(3):
                tri_cot[k][tris] = cot[k] * w
            tri_degenerate[tris] = bad
            if anybad:
                lock_count += np.bincount(np.concatenate([v[bad] for v in tvs]), minlength=lock_count.size)
            return np.zeros(0, tri_pairs.dtype)
        tps = []
        for k in range(3):
            new = cot[k] * w
            row = tri_cot[k]
            old = row.take(tris, mode="clip")
            row[tris] = new
            tpk = tri_pairs[k].take(tris, mode="clip")
            tps.append(tpk)
            np.add.at(pw, tpk, new - old)
        chg = tri_degenerate.take(tris, mode="clip") != bad
        if chg.any():
            delta = np.where(bad[chg], 1, -1)
            np.add.at(lock_count, np.concatenate([v[chg] for v in tvs]), np.tile(delta, 3))
            tri_degenerate[tris[chg]] = bad[chg]
        # short edges: side 0 of every triangle is an edge or a chord, the sides of
        # triangle faces are edges; flips are rare
        flips = [tps[0][(sq[0] <= short2) != pshort.take(tps[0], mode="clip")]]
        tri3 = ttri.take(tris, mode="clip")
        if tri3.any():
            for k in (1, 2):
                e = tps[k][tri3]
                flips.append(e[(sq[k][tri3] <= short2) != pshort[e]])
        return np.concatenate(flips) if len(flips) > 1 else flips[0]

    def moved_triangles(self, idx, vf_ptr, vf_face, ft_ptr, fstamp, buf) -> np.ndarray:
        """The triangles of the faces touching vertices ``idx``, each once, in first-seen order
        (``fstamp``: the scratch of :func:`~shapeflow.sculpt.numbering.unique_stamp`; ``buf``: room
        for every triangle, which an implementation may return a part of)."""
        ent, _ = csr_ranges(vf_ptr, idx)
        faces = unique_stamp(vf_face.take(ent, mode="clip"), fstamp)
        tris, _ = csr_ranges(ft_ptr, faces)
        return tris

    def classify(self, S, slot, vn_ptr, vn_nb, vn_pair, pw):
        """Rim flags and degrees of the region ``S`` (``slot[S]`` = 0..ns−1, −1 elsewhere): a vertex is on
        the rim when a face neighbour lies outside the region (or it has none); its degree is the sum
        of its pair weights in neighbour order.  Returns ``(rim, degree, neighbours)``; ``neighbours``
        is what :meth:`assemble` of the same implementation takes."""
        ns = S.size
        ent, lens = csr_ranges(vn_ptr, S)
        rowid = np.repeat(np.arange(ns), lens)
        nb = vn_nb.take(ent, mode="clip")
        pwe = pw.take(vn_pair.take(ent, mode="clip"), mode="clip")
        snb = slot.take(nb, mode="clip")
        rim = np.bincount(rowid[snb < 0], minlength=ns) > 0
        rim |= lens == 0
        deg = np.bincount(rowid, pwe, minlength=ns)
        return rim, deg, (rowid, snb, pwe)

    def assemble(self, S, R, loc, slot, vn_ptr, vn_nb, vn_pair, pw, V, cdiag, Rb, Xb, neighbours):
        """The interior system of a dab: the free region rows ``R`` (``loc`` maps a region row to its
        unknown, −1 if fixed); off-diagonal entries ``(ri, ci, vi = −w)`` grouped by row in neighbour
        order, ``rhs`` = C·VU + Σ w·x over the fixed neighbours (their positions ``V``, or ``Xb`` for
        the region rows ``Rb`` solved before) and the positions ``VU``: ``(ri, ci, vi, rhs, VU)``."""
        ns, k = S.size, R.size
        rowid, snb, pwe = neighbours
        lr = loc.take(rowid, mode="clip")
        sel = np.flatnonzero(lr >= 0)
        r_loc = lr.take(sel, mode="clip")
        nbr = snb.take(sel, mode="clip")      # neighbours of free rows are all inside
        c_loc = loc.take(nbr, mode="clip")
        w_e = pwe.take(sel, mode="clip")
        inm = c_loc >= 0
        VU = V.take(S[R], axis=0, mode="clip")
        rhs = cdiag[:, None] * VU
        cp = np.flatnonzero(~inm)
        if cp.size:
            rows_c = r_loc[cp]
            Xn = V.take(S[nbr[cp]], axis=0, mode="clip")
            if Rb.size:
                # neighbours solved on the boundary enter with their new (pre-sign) value
                bl = np.full(ns, -1, dtype=np.int64)
                bl[Rb] = np.arange(Rb.size)
                j = bl[nbr[cp]]
                hit = j >= 0
                if hit.any():
                    Xn[hit] = Xb[j[hit]]
            wc = w_e[cp]
            for q in range(3):
                rhs[:, q] += np.bincount(rows_c, wc * Xn[:, q], minlength=k)
        m = np.flatnonzero(inm)
        return r_loc.take(m, mode="clip"), c_loc.take(m, mode="clip"), -w_e.take(m, mode="clip"), rhs, VU

    def spatial_index(self, P: np.ndarray, h: float):
        """An index of the fixed positions ``P`` for queries of radius about ``h``
        (:class:`~shapeflow.sculpt.grid.KDIndex`: SciPy's k-d tree)."""
        return KDIndex(P)
