"""The sculpt brush's incremental cotangent cache over the operator's triangles."""

from __future__ import annotations

import numpy as np

from .. import accel
from ..linalg.ordering import row_ptr
from ..mesh import Mesh
from ..operators.cotan import REL_EDGE_TOL
from ..operators.pattern import operator_pattern
from .base import serialised
from .numbering import csr_by, csr_ranges

__all__ = ["CotanCache"]


class CotanCache:
    """The brush's incremental cotangent cache (a mixin of :class:`~shapeflow.sculpt.brush.Brush`).

    Per-triangle cotangent contributions, areas and degeneracy flags of every
    weighted triangle of the operator (a triangle face once, the corner
    triangles of a quad or n-gon, and for "tqlbo" n-gons their interior fan
    triangles), the pair weights ``w_ij`` and per-vertex lock counts: after
    a committed dab only the triangles of the faces touching moved vertices
    are recomputed, and the pair weights updated by their change (round-off
    drift over very many dabs is removed by :meth:`refresh`).  Cotangents
    come from :func:`shapeflow.geometry.cotangent.tri_geometry` (compiled:
    ``sculpt.compiled.brush_update_triangles``, the same formula), through the sculpt kernel family.
    """

    def _build(self) -> None:
        mesh = self._imesh          # internal numbering (RCM order: sorted unknowns have a narrow band)
        t = mesh.topology
        n = self._n
        pattern = operator_pattern(mesh, self.scheme)
        E = t.n_edges
        # unique vertex pairs: the operator's pair list may repeat a chord (once per
        # contribution); here every pair of vertices has one id
        keys = pattern.pairs[:, 0].astype(np.int64) * n + pattern.pairs[:, 1]   # pairs may be int32
        ukeys, uinv = np.unique(keys, return_inverse=True)
        P = ukeys.size
        upairs = np.stack([ukeys // n, ukeys % n], axis=1)
        self._upairs = upairs
        self._uedge = np.zeros(P + 1, dtype=bool)      # pairs that are mesh edges
        self._uedge[uinv[:E]] = True
        self._edge_uid = uinv[:E]
        T, self._tri_vertices, self._tri_pairs, self._tri_weight, self._tri_area_weight, tface = \
            self._triangles(mesh, pattern, ukeys, uinv)
        self._P, self._E = P, E
        self._ttri = np.zeros(T, dtype=bool)            # triangles that are whole triangle faces
        self._ttri[np.flatnonzero(t.face_sizes[tface] == 3)] = True
        # face -> its triangles (triangles are numbered face by face)
        self._ft_ptr = row_ptr(tface, t.n_faces)
        # vertex -> faces
        self._vf_ptr, order = csr_by(t.face_indices, n)
        self._vf_face = t.corner_face[order]
        self._vt_ptr = None   # vertex -> triangles, built when first needed (eq. 9 areas)
        # vertex -> face neighbours with the pair id (P = "no weight": face neighbours
        # that are not pairs, i.e. long chords of 6+-gons in scheme "blender")
        a = np.concatenate([upairs[:, 0], upairs[:, 1]])
        b = np.concatenate([upairs[:, 1], upairs[:, 0]])
        pid = np.concatenate([np.arange(P), np.arange(P)])
        extra = self._missing_face_pairs(mesh, upairs, n)
        if extra.size:
            a = np.concatenate([a, extra[:, 0], extra[:, 1]])
            b = np.concatenate([b, extra[:, 1], extra[:, 0]])
            pid = np.concatenate([pid, np.full(2 * extra.shape[0], P)])
        self._vn_ptr, order = csr_by(a, n)
        self._vn_nb = b[order]
        self._vn_pair = pid[order]
        # boundary (paper mode): vertices on a boundary edge; vertex -> boundary edges
        self._bmask = t.boundary_vertex_mask
        be = t.boundary_edges
        ba = np.concatenate([be[:, 0], be[:, 1]])
        self._vb_ptr, order = csr_by(ba, n)
        self._vb_nb = np.concatenate([be[:, 1], be[:, 0]])[order]
        # caches
        self._VT = np.ascontiguousarray(self._V.T)   # component-major copy of the positions
        self._tri_cot = np.zeros((3, T))      # w_t · cot_k (0 if degenerate), added to pair tri_pairs[k, t]
        self._tri_area = np.zeros(T)          # area weight · area (kept for eq. 9 only)
        self._tri_degenerate = np.zeros(T, dtype=bool)
        self._pshort = np.zeros(P + 1, dtype=bool)   # edges shorter than flow's relative threshold
        self._lock_count = np.zeros(n, dtype=np.int64)    # degenerate triangles + short edges at each vertex
        self._fstamp = np.zeros(t.n_faces, dtype=np.int64)
        self._tri_buf = None               # room for the moved triangles (the compiled update fills it)
        # mean edge length h (flow's "relative" thresholds), from the initial positions
        E_ = t.edges
        el2 = ((self._V[E_[:, 0]] - self._V[E_[:, 1]]) ** 2).sum(axis=1) if E else np.zeros(0)
        h = float(np.sqrt(el2).mean()) if E else 0.0
        self._h = h
        self._short2 = (REL_EDGE_TOL * h) ** 2
        self._pw = np.zeros(P + 1)         # pair weights w_ij, plus a zero for "no pair"
        self._update_triangles(np.arange(T), initial=True)
        self._pw[:P] = np.bincount(self._tri_pairs.reshape(-1), self._tri_cot.reshape(-1), minlength=P)[:P]
        short = el2 <= self._short2
        self._pshort[self._edge_uid] = short
        if short.any():
            self._lock_count += np.bincount(E_[short].reshape(-1), minlength=n)

    @staticmethod
    def _triangles(mesh: Mesh, pattern, ukeys: np.ndarray, uinv: np.ndarray):
        """Every weighted triangle of the operator, numbered face by face.

        A triangle face is one triangle with 3× its corner-triangle weight (its
        three corner triangles are the same triangle); a face with 4+ corners
        has its corner triangles (prev, curr, next), and for "tqlbo" n-gons
        the interior fan triangles of the operator structure.  Returns T,
        vertices (3, T), pair opposite each corner (3, T), cotangent weight,
        area weight and face of each triangle.  Pair ids index the sorted
        unique pair keys ``ukeys``; ``uinv`` maps the operator's pair ids to them.
        """
        t = mesh.topology
        sizes, offs = t.face_sizes, t.face_offsets
        fi, nxt, prv, ce = pattern.fi, pattern.nxt, pattern.prv, pattern.corner_edge
        c = fi.size
        cs = np.repeat(sizes, sizes)
        first = np.repeat(offs[:-1], sizes)
        mc = np.flatnonzero((cs > 3) | (np.arange(c) == first))
        mult = np.where(cs[mc] == 3, 3.0, 1.0)
        tri_vertices = [np.stack([fi[prv[mc]], fi[mc], fi[nxt[mc]]])]
        tri_pairs = [uinv[np.stack([ce[mc], pattern.skip_pair[mc], ce[prv[mc]]])]]
        tri_weight = [pattern.corner_w[mc] * mult]
        tri_area_weight = [pattern.corner_aw[mc] * mult]
        tf = [t.corner_face[mc]]
        if pattern.extra_tris.size:
            tri_vertices.append(pattern.extra_tris.T)
            tri_pairs.append(uinv[pattern.extra_pair].T)
            tri_weight.append(pattern.extra_w)
            tri_area_weight.append(pattern.extra_w)
            tf.append(pattern.extra_face)
        face = np.concatenate(tf)
        order = np.argsort(face, kind="stable")
        tri_vertices = np.ascontiguousarray(np.concatenate(tri_vertices, axis=1)[:, order].astype(np.int64))
        tri_pairs = np.ascontiguousarray(np.concatenate(tri_pairs, axis=1)[:, order].astype(np.int64))
        return (order.size, tri_vertices, tri_pairs, np.concatenate(tri_weight)[order],
                np.concatenate(tri_area_weight)[order], face[order])

    @staticmethod
    def _missing_face_pairs(mesh: Mesh, pairs: np.ndarray, n: int) -> np.ndarray:
        sizes = mesh.face_sizes
        big = np.flatnonzero(sizes >= 6)
        if big.size == 0:
            return np.zeros((0, 2), np.int64)
        out = []
        fi, off = mesh.face_indices, mesh.face_offsets
        for s in np.unique(sizes[big]):
            s = int(s)
            faces = big[sizes[big] == s]
            block = fi[off[faces][:, None] + np.arange(s)]
            iu, ju = np.triu_indices(s, 1)
            x, y = block[:, iu].reshape(-1), block[:, ju].reshape(-1)
            out.append(np.stack([np.minimum(x, y), np.maximum(x, y)], axis=1))
        allp = np.unique(np.concatenate(out), axis=0)
        have = pairs[:, 0] * n + pairs[:, 1]
        keys = allp[:, 0] * n + allp[:, 1]
        return allp[~np.isin(keys, have)]

    def _update_triangles(self, tris: np.ndarray, initial: bool = False) -> None:
        """Recompute the cache of triangles ``tris`` from the current positions.

        After the first call, the pair weights follow by adding each slot's
        change (new − old), and the locks (degenerate triangles, short edges)
        by counting flips.
        """
        flips = accel.kernels("sculpt", self._n).update_triangles(
            tris, self._tri_vertices, self._tri_pairs, self._tri_weight, self._tri_area_weight, self._VT,
            self._tri_cot, self._tri_area, not self.normalized or initial, self._tri_degenerate, self._lock_count,
            self._pw, self._ttri, self._pshort, self._short2, initial)
        if flips.size:
            self._flip_short(np.unique(flips))

    def _flip_short(self, pairs: np.ndarray) -> None:
        e = pairs[self._uedge[pairs]]
        if e.size == 0:
            return
        ends = self._upairs[e]
        d = self._V[ends[:, 0]] - self._V[ends[:, 1]]
        short = np.einsum("ij,ij->i", d, d) <= self._short2
        chg = short != self._pshort[e]
        if chg.any():
            self._pshort[e[chg]] = short[chg]
            np.add.at(self._lock_count, ends[chg].reshape(-1), np.repeat(np.where(short[chg], 1, -1), 2))

    def _moved(self, idx: np.ndarray) -> None:
        """Recompute the triangles of the faces touching ``idx``."""
        new = self._V.take(idx, axis=0, mode="clip")
        VT = self._VT
        for q in range(3):
            VT[q][idx] = new[:, q]
        if self._tri_buf is None:                # room for every triangle (an implementation may fill it)
            self._tri_buf = np.empty(self._tri_vertices.shape[1], dtype=np.int64)
        self._update_triangles(accel.kernels("sculpt", self._n).moved_triangles(
            idx, self._vf_ptr, self._vf_face, self._ft_ptr, self._fstamp, self._tri_buf))

    @serialised
    def refresh(self) -> None:
        """Recompute every cached weight from the current positions (O(n)).

        Pair weights are updated incrementally after each dab; this removes the
        (round-off sized) drift that many thousands of dabs may accumulate.
        """
        T = self._tri_vertices.shape[1]
        self._tri_cot[:] = 0.0
        self._tri_degenerate[:] = False
        self._lock_count[:] = 0
        self._update_triangles(np.arange(T), initial=True)
        P = self._P
        self._pw[:] = 0.0
        self._pw[:P] = np.bincount(self._tri_pairs.reshape(-1), self._tri_cot.reshape(-1), minlength=P)[:P]
        E_ = self._imesh.topology.edges
        d = self._V[E_[:, 0]] - self._V[E_[:, 1]]
        short = np.einsum("ij,ij->i", d, d) <= self._short2
        self._pshort[:] = False
        self._pshort[self._edge_uid] = short
        if short.any():
            self._lock_count += np.bincount(E_[short].reshape(-1), minlength=self._n)

    @serialised
    def pair_weights(self):
        """Current cotangent weights as ``(pairs, w)``: pairs (P, 2) of mesh vertex
        indices (each row sorted, rows sorted) and w_ij, from the cache."""
        pr = np.sort(self._perm[self._upairs], axis=1)
        order = np.lexsort((pr[:, 1], pr[:, 0]))
        return pr[order], self._pw[:self._P][order]

    @property
    @serialised
    def locked(self) -> np.ndarray:
        """(n,) bool: vertices touching a degenerate triangle or a too-short edge
        (kept fixed, as :func:`shapeflow.flow` does), at the current positions."""
        return self._lock_count[self._inv] > 0

    def _ring_areas(self, S: np.ndarray) -> np.ndarray:
        """Ring area (eq. 5) of vertices ``S`` from the cached triangle areas."""
        if self._vt_ptr is None:
            T = self._tri_vertices.shape[1]
            self._vt_ptr, order = csr_by(self._tri_vertices.reshape(-1), self._n)
            self._vt_tri = order % T
        te, tl = csr_ranges(self._vt_ptr, S)
        return np.bincount(np.repeat(np.arange(S.size), tl), self._tri_area[self._vt_tri[te]], minlength=S.size)
