"""The operator's kernel family: the sparse pattern, the corner cotangent sums, the matrix fill (NumPy reference).

The numba implementation is :class:`shapeflow.operators.compiled.OperatorNumba`;
:func:`shapeflow.accel.kernels` chooses (``accel.kernels("operators", n_vertices)``).
"""

from __future__ import annotations

import numpy as np

from ..accel import Family
from ..geometry.cotangent import corner_cotangents
from .cotan import BLENDER_MIN, FLT_EPSILON, REL_EDGE_TOL, REL_SHAPE_TOL
from .pattern import corner_weights, csr_pattern, ngon_fans

__all__ = ["OperatorKernels"]


class OperatorKernels(Family):
    """Kernels of :class:`~shapeflow.operators.pattern.OperatorPattern` and of the cotangent assembly."""

    family = "operators"

    def pattern_core(self, topology, scheme: str):
        """Which triangles weigh which vertex pairs: ``(pairs, skip_pair, extras, corner)``.

        ``pairs``: the unique edges, then one chord per skip pair of the faces of 4+ corners (a
        quad's two opposite corners share theirs), int32 when n allows; ``skip_pair``: the pair
        (prev, next) of each corner; ``extras``: the tqlbo n-gons' interior fan triangles
        ``(tris, weights, faces, pair opposite each corner)``; ``corner``: the corner triangles'
        ``(cotangent weights, area weights)``, or None when the pattern makes them on demand.
        """
        sizes, offs, fi = topology.face_sizes, topology.face_offsets, topology.face_indices
        nxt, prv, corner_edge, edges = topology.corner_next, topology.corner_prev, topology.corner_edge, topology.edges
        n = topology.n_vertices
        n_edges = edges.shape[0]
        c = fi.size
        cs = np.repeat(sizes, sizes)
        corner = corner_weights(cs, scheme)
        is_tri = cs == 3
        # --- chords: the skip pair (prev, next) of corners of faces with >= 4 corners
        local = np.arange(c) - np.repeat(offs[:-1], sizes)
        ch = np.flatnonzero(cs >= 4)
        primary = ch[~((cs[ch] == 4) & (local[ch] >= 2))]
        va, vb = fi[prv[primary]], fi[nxt[primary]]
        # --- extra fan triangles of tqlbo n-gons
        xt, xw, xf, xslot_keys, xslot_edge = (ngon_fans(sizes, offs, fi, corner_edge, n) if scheme == "tqlbo"
                                              else ([], [], [], [], []))
        # Chords are not deduplicated: a chord shared by two faces (or equal to an
        # edge) is simply two entries of the sparse pattern, which add up in any
        # product; direct solvers and cotan_weights() canonicalise a copy.
        n_primary = primary.size
        chord_ends = [np.stack([np.minimum(va, vb), np.maximum(va, vb)], axis=1)]
        xk = np.concatenate(xslot_keys) if xslot_keys else np.zeros((0, 3), np.int64)
        xmask = xk >= 0
        if xmask.any():
            k_ = xk[xmask]
            chord_ends.append(np.stack([k_ // n, k_ % n], axis=1))
        pairs = np.concatenate([edges] + chord_ends)
        if n < 2**31 - 1:
            pairs = pairs.astype(np.int32)   # as the compiled twin: half the bytes
        skip_pair = np.full(c, -1, dtype=np.int64)
        skip_pair[primary] = n_edges + np.arange(n_primary)
        sec = ch[(cs[ch] == 4) & (local[ch] >= 2)]
        skip_pair[sec] = skip_pair[sec - 2]                   # a quad's corners k, k+2 share a diagonal
        tri_c = np.flatnonzero(is_tri)
        skip_pair[tri_c] = corner_edge[nxt[tri_c]]            # a triangle's skip pair is an edge
        if xt:
            sp_ = np.concatenate(xslot_edge)
            sp_[xmask] = n_edges + n_primary + np.arange(int(xmask.sum()))
            extras = (np.concatenate(xt), np.concatenate(xw), np.concatenate(xf), sp_)
        else:
            extras = no_extras()
        return pairs, skip_pair, extras, corner

    def pair_pattern(self, pairs: np.ndarray, n: int):
        """Symmetric CSR pattern of ``pairs`` plus the diagonal, duplicates kept, columns sorted within a
        row (equal columns in the order (pairs as (p0, p1), pairs as (p1, p0), diagonal)): indptr, indices
        and the positions of every upper, lower and diagonal entry."""
        P = pairs.shape[0]
        rows = np.concatenate([pairs[:, 0], pairs[:, 1], np.arange(n)])
        cols = np.concatenate([pairs[:, 1], pairs[:, 0], np.arange(n)])
        indptr, indices, entry_at = csr_pattern(rows, cols, n)
        pos_of = np.empty_like(entry_at)
        pos_of[entry_at] = np.arange(entry_at.size)
        return indptr, indices, pos_of[:P], pos_of[P:2 * P], pos_of[2 * P:]

    def fill_symmetric(self, nnz: int, pos_diag, diag, pos_upper, pos_lower, off) -> np.ndarray:
        """The data array (nnz,) of a symmetric matrix on a pair pattern: ``diag`` at the diagonal
        positions, each pair's ``off`` at its upper and lower positions."""
        data = np.empty(nnz)
        data[pos_diag] = diag
        data[pos_upper] = off
        data[pos_lower] = off
        return data

    def locality(self, pattern):
        """A bandwidth-reducing order of an ``OperatorPattern`` and its CSR pattern in that order,
        ``(perm, inv, indptr, indices, source)`` (see ``OperatorPattern.locality``), where it pays:
        None here (NumPy's products do not gain from it)."""
        return None

    def assemble_corners(self, V: np.ndarray, pattern, topology, thresholds: str):
        """The corner triangles' part of ``operators.cotan.assemble``: pair weights (P,), ring areas
        (n,), locked vertices (n,) and the number of corner triangles excluded as degenerate."""
        fi = pattern.fi
        edges = topology.edges
        P, n = pattern.pairs.shape[0], topology.n_vertices
        cot_p, cot_c, cot_n, dbl, l_prev, l_next, l_skip = corner_cotangents(V, fi, pattern.nxt, pattern.prv)
        locked = np.zeros(n, dtype=bool)
        # edge lengths from the corners' half-edges (every edge has at least one corner)
        elen2 = np.empty(edges.shape[0])
        elen2[pattern.corner_edge] = l_next
        if thresholds == "relative":
            h = float(np.sqrt(elen2).mean()) if elen2.size else 0.0
            short = elen2 <= (REL_EDGE_TOL * h) ** 2
            bad = dbl <= REL_SHAPE_TOL * np.maximum(np.maximum(l_prev, l_next), l_skip)
            locked[edges[short].reshape(-1)] = True
            bc = np.flatnonzero(bad)
            locked[fi[bc]] = True
            locked[fi[pattern.prv[bc]]] = True
            locked[fi[pattern.nxt[bc]]] = True
        else:  # Blender's absolute rules
            locked[edges[elen2 < BLENDER_MIN ** 2].reshape(-1)] = True
            small = 0.5 * dbl < BLENDER_MIN
            locked[fi[small]] = True                      # the corner vertex of a corner triangle
            bad = ~(dbl > FLT_EPSILON)
        w = np.where(bad, 0.0, pattern.corner_w)
        # edge of corner k (curr -> next) gets cot at prev of triangle k and cot at next of triangle next(k)
        wc_n = w * cot_n
        h_edge = w * cot_p + wc_n[pattern.nxt]
        pw = np.bincount(pattern.corner_edge, h_edge, minlength=P) + np.bincount(pattern.skip_pair, w * cot_c,
                                                                                 minlength=P)
        # ring area: each corner triangle's (weighted) area to its three vertices
        ca = 0.5 * dbl * pattern.corner_aw
        ring = np.bincount(fi, ca + ca[pattern.nxt] + ca[pattern.prv], minlength=n)
        return pw, ring, locked, int(bad.sum())

    def pair_degree(self, pairs: np.ndarray, pw: np.ndarray, n: int) -> np.ndarray:
        """Σ of the pair weights at each vertex (the first ends' sums plus the second ends')."""
        return np.bincount(pairs[:, 0], pw, minlength=n) + np.bincount(pairs[:, 1], pw, minlength=n)


def no_extras():
    """The fan triangles of a pattern without any: ``(tris, weights, faces, pairs)``, all empty."""
    return np.zeros((0, 3), np.int64), np.zeros(0), np.zeros(0, np.int64), np.zeros((0, 3), np.int64)
