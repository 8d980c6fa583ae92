"""Sparse operators: cotangent weights W, degrees D, ring areas, Laplacians, curvature.

Sign convention (everywhere in shapeflow): Laplacians are **positive
semi-definite**.  With W the symmetric cotangent weights (w_ij >= 0 on
well-shaped meshes) and D = diag(Σ_j w_ij):

* ``K = D − W``            the cotangent "stiffness" matrix (PSD, zero row sums);
* ``L = I − D⁻¹W``         the normalised operator, eq. 10 of the paper;
* ``L = (D − W) / (2A)``   the area-normalised operator, eq. 9 (A = ring area).

So ``L @ V`` points *away* from the neighbour average, and the discrete
Laplace–Beltrami of the positions is ``Δx = −L_area @ V``.

Schemes (how a face contributes to W)
--------------------------------------
``"tqlbo"`` (default; the paper, section 4.1, with the ½ of case (c) of eq. 8 restored: docs/method.md)
    A triangle adds cot(opposite angle) to each of its edges.  A quad is the
    mean over its two triangulations: each of its 4 corner triangles adds
    ½·cot to every pair of that corner triangle (diagonals included).
    **N-gons** (beyond the paper): the mean over the n fan triangulations
    (one rooted at each corner), so each fan triangle adds cot/n.  This is
    exactly the paper on triangles (1 fan) and quads (the 4 fans are the two
    triangulations twice), and keeps linear precision on planar polygons
    because every triangulation of a planar polygon has it.  Ring areas
    (eq. 5) use the same weights: on a quad A(i) gets ½[A(t1)+A(t2)+A(t3)].
``"blender"`` (what Blender's Laplacian Smooth modifier computes)
    Every polygon corner triangle (prev, curr, next) adds ½·cot to its three
    pairs, for triangles, quads and n-gons alike (so a triangle counts 1.5×
    relative to a quad); its ring area adds the whole corner-triangle area to
    each of its three vertices.

Degenerate elements
-------------------
``thresholds="relative"`` (default): with h the mean edge length, an edge
shorter than ``1e-8·h`` is zero-length (both ends locked); a triangle with
twice-area ``≤ 1e-8 · (longest edge)²`` (flat or needle-like, |cot| would
exceed ~1e8) is excluded from W and its vertices are locked.  Both tests are
scale-invariant.  ``thresholds="blender"``: Blender's absolute rules (edge
shorter than 1e-5 locks both ends; a corner triangle of area below 1e-5 locks
its corner vertex; a cotangent is 0 when the cross product is below float32
epsilon).  No NaN or inf ever reaches W.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import scipy.sparse as sp

from . import kernels
from .errors import MeshError, ParameterError
from .geometry import pow2_exponent, triangle_cotangents, vertex_normals

__all__ = [
    "SCHEMES",
    "CotanWeights",
    "cotan_weights",
    "laplacian",
    "mean_curvature_normal",
    "mean_curvature",
    "vertex_areas",
]

SCHEMES = ("tqlbo", "blender")
THRESHOLDS = ("relative", "blender")

REL_EDGE_TOL = 1e-8   # zero-length edge: |e| <= REL_EDGE_TOL * mean edge length
REL_SHAPE_TOL = 1e-8  # flat triangle: 2*area <= REL_SHAPE_TOL * longest_edge**2
#: The most n-gon fan triangles (Σ s(s−4) over the faces of s >= 5 corners) the "tqlbo" scheme builds.
#: An s-gon's operator couples every pair of its corners, so its cost is quadratic in s by definition:
#: ~400 bytes and ~1-3 µs per fan triangle at peak (a 1,000-gon: 1 million, 0.45 GB, 1.6 s; a 3,000-gon:
#: 9 million, 3.5 GB, 30 s, refused).
FAN_TRIANGLES_MAX = 2_000_000
BLENDER_MIN = 1e-5    # Blender's absolute edge-length and corner-area threshold
FLT_EPSILON = float(np.finfo(np.float32).eps)


def _check_scheme(scheme: str) -> str:
    if scheme not in SCHEMES:
        raise ParameterError(f"unknown scheme {scheme!r}; choose one of {', '.join(SCHEMES)}")
    return scheme


# --------------------------------------------------------------------------
# structure: which triangles contribute, and the sparse pattern (per topology)
# --------------------------------------------------------------------------

@lru_cache(maxsize=64)
def _fan_interior_triangles(s: int):
    """Fan triangles of an s-gon (s >= 5) that are not corner triangles ("ears").

    The fan rooted at corner r holds the triangles (r, r+j, r+j+1), j = 1 … s−2.
    j = 1 and j = s−2 are ears (two polygon edges): each lies in exactly two
    fans, so the mean over the s fans gives it weight 2/s, and it is handled
    as a corner triangle.  Every other fan triangle has one polygon edge
    (r+j, r+j+1) and its apex r, so it lies in that one fan only: weight 1/s.
    Returns local corner indices (t, 3), in the order (r, then j), and
    weights (t,); t = s(s−4).  An s-gon's operator couples every pair of its
    corners, so this is quadratic in s by definition (vectorised, no Python
    loop: a 3,000-gon's 9 million triangles take well under a second).
    """
    if s < 5:
        return np.zeros((0, 3), np.int64), np.zeros(0)
    j = np.arange(2, s - 2, dtype=np.int64)
    r = np.repeat(np.arange(s, dtype=np.int64), j.size)
    jj = np.tile(j, s)
    tris = np.stack([r, (r + jj) % s, (r + jj + 1) % s], axis=1)
    return tris, np.full(tris.shape[0], 1.0 / s)


def corner_weights(sizes_per_corner: np.ndarray, scheme: str):
    """Cotangent and area weight of every corner triangle (prev, curr, next).

    ``"blender"``: ½·cot, whole area.  ``"tqlbo"``: a triangle is its own
    three corner triangles at 1/3 each (so it counts once); a quad's corner
    triangles weigh ½ (the mean of its two triangulations); an s-gon's ears
    2/s (the mean of its fan triangulations; the rest is in
    :func:`_fan_interior_triangles`).
    """
    cs = sizes_per_corner
    if scheme == "blender":
        return np.full(cs.size, 0.5), np.ones(cs.size)
    w = np.where(cs == 3, 1.0 / 3.0, 2.0 / cs)
    return w, w


class _Structure:
    """Everything about W that depends on the topology only (built once, cached).

    Contributions come from every polygon corner triangle (prev, curr, next)
    with weight ``corner_w`` and, for ``"tqlbo"`` n-gons, from ``extra``
    fan triangles (``extra_tris``, ``extra_w``, their ``extra_face`` and the
    pair opposite each corner, ``extra_pair``).  Vertex pairs are the unique mesh edges followed by the
    unique chords (quad diagonals, n-gon chords); every contribution has a
    precomputed pair index, and the symmetric CSR pattern (with diagonal)
    stores where each pair and each diagonal entry sits, so a matrix with new
    values costs one scatter.
    """

    def __init__(self, topo, scheme: str):
        n = topo.n_vertices
        sizes = topo.face_sizes
        offs = topo.face_offsets
        fi = topo.face_indices
        corner_edge = topo.corner_edge
        edges = topo.edges
        # a weak reference: the topology caches this structure, and a strong one would make a
        # cycle that only the cyclic garbage collector frees (fresh meshes piled up between its runs)
        self._topo_ref = weakref.ref(topo)
        self.scheme = scheme
        self._corner_w = None
        self._locality = None
        K = kernels.get(n)
        if K is not None and (scheme == "blender" or sizes.size == 0 or int(sizes.max()) <= 4):
            # no fan triangles: the compiled twin of the code below (corner weights made on demand)
            self.skip_pair, pairs = K.structure_core(fi, offs, corner_edge, edges, n)
            self.extra_tris = np.zeros((0, 3), np.int64)
            self.extra_w = np.zeros(0)
            self.extra_face = np.zeros(0, np.int64)
            self.extra_pair = np.zeros((0, 3), np.int64)
        else:
            pairs = self._numpy_core(scheme, n, sizes, offs, fi, topo.corner_next, topo.corner_prev,
                                     corner_edge, edges)
        self.pairs = pairs
        self.n = n
        self.corner_edge = corner_edge
        self.fi = fi
        # --- symmetric CSR pattern with diagonal (duplicates kept, columns sorted)
        P = pairs.shape[0]
        if K is not None and 2 * P + n < 2**31 - 1:
            indptr, indices, self.pos_upper, self.pos_lower, self.pos_diag = K.pair_pattern(pairs, n)
        else:
            rows = np.concatenate([pairs[:, 0], pairs[:, 1], np.arange(n)])
            cols = np.concatenate([pairs[:, 1], pairs[:, 0], np.arange(n)])
            indptr, indices, entry_at = _csr_pattern(rows, cols, n)
            pos_of = np.empty_like(entry_at)
            pos_of[entry_at] = np.arange(entry_at.size)
            self.pos_upper = pos_of[:P]
            self.pos_lower = pos_of[P:2 * P]
            self.pos_diag = pos_of[2 * P:]
        # shared by every matrix built on this pattern: read-only, so no scipy
        # operation can rewrite it in place for everyone
        indptr.flags.writeable = False
        indices.flags.writeable = False
        self.indptr = indptr
        self.indices = indices

    @property
    def _topo(self):
        topo = self._topo_ref()
        if topo is None:
            raise RuntimeError("the topology of this operator structure no longer exists")
        return topo

    @property
    def nxt(self) -> np.ndarray:
        """Next corner of each corner (the topology's ``corner_next``)."""
        return self._topo.corner_next

    @property
    def prv(self) -> np.ndarray:
        """Previous corner of each corner (the topology's ``corner_prev``)."""
        return self._topo.corner_prev

    def _weights(self):
        if self._corner_w is None:   # made on demand (the compiled assembly derives them per face)
            sizes = self._topo.face_sizes
            self._corner_w = corner_weights(np.repeat(sizes, sizes), self.scheme)
        return self._corner_w

    @property
    def corner_w(self) -> np.ndarray:
        """Cotangent weight of each corner triangle (depends on the face size only)."""
        return self._weights()[0]

    @property
    def corner_aw(self) -> np.ndarray:
        """Area weight of each corner triangle."""
        return self._weights()[1]

    def _numpy_core(self, scheme, n, sizes, offs, fi, nxt, prv, corner_edge, edges) -> np.ndarray:
        """Corner weights, chords, skip pairs and n-gon fan triangles; returns the pairs."""
        n_edges = edges.shape[0]
        c = fi.size
        cs = np.repeat(sizes, sizes)
        self._corner_w = corner_weights(cs, scheme)
        is_tri = cs == 3
        # --- chords: the skip pair (prev, next) of corners of faces with >= 4 corners
        local = np.arange(c) - np.repeat(offs[:-1], sizes)
        ch = np.flatnonzero(cs >= 4)
        primary = ch[~((cs[ch] == 4) & (local[ch] >= 2))]
        va, vb = fi[prv[primary]], fi[nxt[primary]]
        # --- extra fan triangles of tqlbo n-gons
        xt, xw, xf, xslot_keys, xslot_edge = [], [], [], [], []
        if scheme == "tqlbo":
            big = sizes >= 5
            fan = int((sizes[big] * (sizes[big] - 4)).sum())
            if fan > FAN_TRIANGLES_MAX:
                f = int(np.argmax(sizes))
                raise MeshError(f"face {f} has {int(sizes[f])} corners: the tqlbo operator of an n-gon is the mean "
                                f"of its fan triangulations and couples every pair of its corners; this mesh's "
                                f"n-gons need {fan:,} fan triangles (~{fan * 400 / 1e9:.1f} GB), at most "
                                f"{FAN_TRIANGLES_MAX:,}. Split the large faces, or use scheme='blender' "
                                "(corner triangles only, linear in the corners)")
            for s_ in np.unique(sizes[big]):
                s_ = int(s_)
                lt, lw = _fan_interior_triangles(s_)
                if lt.size == 0:
                    continue
                faces = np.flatnonzero(sizes == s_)
                corners = offs[faces][:, None, None] + lt[None]          # (m_s, t, 3)
                xt.append(fi[corners].reshape(-1, 3))
                xw.append(np.tile(lw, faces.size))
                xf.append(np.repeat(faces, lt.shape[0]))
                # pair opposite local corner k: an edge (adjacent corners) or a chord
                sl_edge = np.full((faces.size, lt.shape[0], 3), -1, dtype=np.int64)
                sl_key = np.full((faces.size, lt.shape[0], 3), -1, dtype=np.int64)
                for k in range(3):
                    a_ = lt[:, (k + 1) % 3]
                    b_ = lt[:, (k + 2) % 3]
                    ca = corners[:, :, (k + 1) % 3]
                    cb = corners[:, :, (k + 2) % 3]
                    fwd = (b_ - a_) % s_ == 1
                    bwd = (a_ - b_) % s_ == 1
                    sl_edge[:, fwd, k] = corner_edge[ca[:, fwd]]
                    sl_edge[:, bwd, k] = corner_edge[cb[:, bwd]]
                    chord = ~(fwd | bwd)
                    x, y = fi[ca[:, chord]], fi[cb[:, chord]]
                    sl_key[:, chord, k] = np.minimum(x, y) * n + np.maximum(x, y)
                xslot_edge.append(sl_edge.reshape(-1, 3))
                xslot_keys.append(sl_key.reshape(-1, 3))
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
        self.skip_pair = skip_pair
        if xt:
            self.extra_tris = np.concatenate(xt)
            self.extra_w = np.concatenate(xw)
            self.extra_face = np.concatenate(xf)
            sp_ = np.concatenate(xslot_edge)
            sp_[xmask] = n_edges + n_primary + np.arange(int(xmask.sum()))
            self.extra_pair = sp_
        else:
            self.extra_tris = np.zeros((0, 3), np.int64)
            self.extra_w = np.zeros(0)
            self.extra_face = np.zeros(0, np.int64)
            self.extra_pair = np.zeros((0, 3), np.int64)
        return pairs

    def matrix(self, diag: np.ndarray, off: np.ndarray, *, copy_pattern: bool = False) -> sp.csr_matrix:
        """Symmetric CSR matrix with the given diagonal and per-pair values.

        The index arrays are the shared, read-only pattern unless
        ``copy_pattern`` (needed before any in-place structural change).
        """
        K = kernels.get(self.n)
        if K is not None:
            data = K.fill_symmetric(self.indices.size, self.pos_diag, np.asarray(diag, np.float64),
                                    self.pos_upper, self.pos_lower, np.asarray(off, np.float64))
        else:
            data = np.empty(self.indices.size)
            data[self.pos_diag] = diag
            data[self.pos_upper] = off
            data[self.pos_lower] = off
        return self.matrix_from_data(data, copy_pattern=copy_pattern)

    def locality(self):
        """A bandwidth-reducing order of the vertices and the pattern in that order (kernels only).

        Returns ``(perm, inv, indptr, indices, source)``: reverse Cuthill–McKee
        order of the pattern's graph, its inverse, the permuted pattern and the
        original position of each permuted entry (permuted data = data[source]).
        Built once per topology (~30 ms at 126K vertices), for the many sparse
        products of the fixed-operator expansion: in this order a row's
        neighbours sit in nearby rows, so the products' gathers stay in cache
        (126K-vertex Suzanne: 2.1 -> 1.6 ms per product).  None without the
        compiled kernels.
        """
        K = kernels.get(self.n)
        if K is None:
            return None
        if self._locality is None:
            from scipy.sparse.csgraph import reverse_cuthill_mckee

            G = sp.csr_matrix((np.ones(self.indices.size), self.indices, self.indptr), shape=(self.n, self.n))
            perm = reverse_cuthill_mckee(G, symmetric_mode=True).astype(np.int64)
            ptr, idx, src = K.permute_pattern(self.indptr, self.indices, perm)
            inv = np.empty_like(perm)
            inv[perm] = np.arange(perm.size)
            self._locality = (perm, inv, ptr, idx, src)
        return self._locality

    def matrix_from_data(self, data: np.ndarray, *, copy_pattern: bool = False) -> sp.csr_matrix:
        """The CSR matrix with this pattern and the given ``data`` (one value per stored entry)."""
        idx, ptr = (self.indices.copy(), self.indptr.copy()) if copy_pattern else (self.indices, self.indptr)
        M = sp.csr_matrix((data, idx, ptr), shape=(self.n, self.n), copy=False)
        M.has_sorted_indices = True
        M.has_canonical_format = False  # a shared chord appears twice
        return M

    def triangles(self):
        """All weighted triangles: (tris (T, 3), cot weights, area weights, corner flag).

        Corner triangles come first as (prev, curr, next); ``corner`` is True
        for them.  Used by the non-hot paths (mixed areas, tests).
        """
        ct = np.stack([self.fi[self.prv], self.fi, self.fi[self.nxt]], axis=1)
        tris = np.concatenate([ct, self.extra_tris])
        return (tris, np.concatenate([self.corner_w, self.extra_w]),
                np.concatenate([self.corner_aw, self.extra_w]),
                np.r_[np.ones(ct.shape[0], bool), np.zeros(self.extra_tris.shape[0], bool)])


def _csr_pattern(rows: np.ndarray, cols: np.ndarray, n: int):
    """CSR layout of (rows, cols) without merging duplicates.

    Returns ``indptr``, ``indices`` (columns sorted within each row) and
    ``entry_at``: the input entry stored at each CSR position.  Uses SciPy's
    O(nnz) counting sort (``coo_tocsr``) and per-row sort; falls back to a
    NumPy lexsort if that internal routine is unavailable.
    """
    nnz = rows.size
    itype = np.int32 if max(n, nnz) < 2**31 - 1 else np.int64
    try:
        from scipy.sparse._sparsetools import coo_tocsr
    except ImportError:  # pragma: no cover - SciPy internals moved
        order = np.lexsort((cols, rows))
        indptr = np.zeros(n + 1, dtype=itype)
        np.cumsum(np.bincount(rows, minlength=n), out=indptr[1:])
        return indptr, cols[order].astype(itype), order
    indptr = np.empty(n + 1, dtype=itype)
    indices = np.empty(nnz, dtype=itype)
    ids = np.empty(nnz, dtype=np.int64)
    coo_tocsr(n, n, nnz, rows.astype(itype), cols.astype(itype), np.arange(nnz, dtype=np.int64),
              indptr, indices, ids)
    M = sp.csr_matrix((ids, indices, indptr), shape=(n, n), copy=False)
    M.sort_indices()  # per row, C++; permutes ids along
    return M.indptr, M.indices, M.data


def _structure(mesh, scheme: str) -> _Structure:
    topo = mesh.topology
    cache = topo.__dict__.setdefault("_shapeflow_structures", {})
    if scheme not in cache:
        cache[scheme] = _Structure(topo, scheme)
    return cache[scheme]


def corner_cotangents(V: np.ndarray, fi: np.ndarray, nxt: np.ndarray, prv: np.ndarray):
    """Cotangents of every corner triangle (prev, curr, next), from half-edge vectors.

    Returns ``cot_p, cot_c, cot_n`` (angles at prev, curr, next), twice the
    area ``dbl``, and the squared lengths ``l_prev`` (curr–prev), ``l_next``
    (curr–next), ``l_skip`` (prev–next).  Zero-area rows give 0, never inf.
    Computed component by component on contiguous arrays.
    """
    Vt = V.T
    ex, ey, ez = (Vt[k][fi[nxt]] - Vt[k][fi] for k in range(3))   # curr -> next, per corner
    px, py, pz = ex[prv], ey[prv], ez[prv]                          # prev -> curr
    l_next = ex * ex + ey * ey + ez * ez
    l_prev = l_next[prv]
    dot = -(px * ex + py * ey + pz * ez)                            # (prev - curr) · (next - curr)
    cx = py * ez - pz * ey
    cy = pz * ex - px * ez
    cz = px * ey - py * ex
    dbl = np.sqrt(cx * cx + cy * cy + cz * cz)
    inv = np.divide(1.0, dbl, out=np.zeros_like(dbl), where=dbl > 0)
    cot_c = dot * inv
    cot_p = (l_prev - dot) * inv
    cot_n = (l_next - dot) * inv
    l_skip = l_prev + l_next - 2.0 * dot
    return cot_p, cot_c, cot_n, dbl, l_prev, l_next, l_skip


# --------------------------------------------------------------------------
# weights
# --------------------------------------------------------------------------

@dataclass
class CotanWeights:
    """Cotangent weights of a mesh and what was done about degeneracy.

    Unpacks as ``W, ring_area = cotan_weights(mesh)``.

    Attributes
    ----------
    W : scipy.sparse.csr_matrix (n, n)
        Symmetric weights w_ij (zero diagonal).
    degree : (n,) float64
        D_i = Σ_j w_ij.
    ring_area : (n,) float64
        Ring area of each vertex (eq. 5 for ``"tqlbo"``; Blender's sum of
        corner-triangle areas for ``"blender"``).
    locked : (n,) bool
        Vertices touching a degenerate element; the flow keeps them fixed.
    n_degenerate : int
        Number of weighted triangles excluded from W.
    pairs, pair_weights : (P, 2), (P,)
        W as a pair list (a pair may repeat when two faces share a chord;
        repeated weights add up).
    """

    W: sp.csr_matrix
    degree: np.ndarray
    ring_area: np.ndarray
    locked: np.ndarray
    n_degenerate: int
    pairs: np.ndarray
    pair_weights: np.ndarray
    scheme: str

    def __iter__(self):
        yield self.W
        yield self.ring_area


def _assemble_corners_numpy(V, st, edges, P, n, thresholds):
    """The corner-triangle part of ``_assemble`` (reference for ``kernels.assemble_corners``)."""
    fi = st.fi
    cot_p, cot_c, cot_n, dbl, l_prev, l_next, l_skip = corner_cotangents(V, fi, st.nxt, st.prv)
    locked = np.zeros(n, dtype=bool)
    # edge lengths from the corners' half-edges (every edge has at least one corner)
    elen2 = np.empty(edges.shape[0])
    elen2[st.corner_edge] = l_next
    if thresholds == "relative":
        h = float(np.sqrt(elen2).mean()) if elen2.size else 0.0
        short = elen2 <= (REL_EDGE_TOL * h) ** 2
        bad = dbl <= REL_SHAPE_TOL * np.maximum(np.maximum(l_prev, l_next), l_skip)
        locked[edges[short].reshape(-1)] = True
        bc = np.flatnonzero(bad)
        locked[fi[bc]] = True
        locked[fi[st.prv[bc]]] = True
        locked[fi[st.nxt[bc]]] = True
    else:  # Blender's absolute rules
        locked[edges[elen2 < BLENDER_MIN ** 2].reshape(-1)] = True
        small = 0.5 * dbl < BLENDER_MIN
        locked[fi[small]] = True                      # the corner vertex of a corner triangle
        bad = ~(dbl > FLT_EPSILON)
    w = np.where(bad, 0.0, st.corner_w)
    # edge of corner k (curr -> next) gets cot at prev of triangle k and cot at next of triangle next(k)
    wc_n = w * cot_n
    h_edge = w * cot_p + wc_n[st.nxt]
    pw = np.bincount(st.corner_edge, h_edge, minlength=P) + np.bincount(st.skip_pair, w * cot_c, minlength=P)
    # ring area: each corner triangle's (weighted) area to its three vertices
    ca = 0.5 * dbl * st.corner_aw
    ring = np.bincount(fi, ca + ca[st.nxt] + ca[st.prv], minlength=n)
    return pw, ring, locked, int(bad.sum())


def _assemble(mesh, scheme: str, thresholds: str, vertices: np.ndarray | None = None):
    """Pair weights, degrees, ring areas, locked mask, #degenerate (no matrix)."""
    if thresholds not in THRESHOLDS:
        raise ParameterError(f"unknown thresholds {thresholds!r}; choose one of {', '.join(THRESHOLDS)}")
    st = _structure(mesh, _check_scheme(scheme))
    V = mesh.vertices if vertices is None else vertices
    # extreme scales (relative thresholds only: Blender's are absolute): an exact power-of-two copy
    k = pow2_exponent(V) if thresholds == "relative" else 0
    if k:
        V = np.ldexp(V, -k)
    n = mesh.n_vertices
    edges = mesh.topology.edges
    xcot, xdbl, xsq = triangle_cotangents(V, st.extra_tris)
    P = st.pairs.shape[0]
    K = kernels.get(n)
    if K is not None:
        pw, ring, locked, n_bad = K.assemble_corners(
            np.ascontiguousarray(V, dtype=np.float64), st.fi, mesh.topology.face_offsets, st.corner_edge,
            st.skip_pair, st.scheme == "tqlbo", edges, P, n, thresholds == "blender",
            REL_EDGE_TOL, REL_SHAPE_TOL, BLENDER_MIN, FLT_EPSILON)
    else:
        pw, ring, locked, n_bad = _assemble_corners_numpy(V, st, edges, P, n, thresholds)
    # the tqlbo fan triangles of n-gons (few)
    if thresholds == "relative":
        xbad = xdbl <= REL_SHAPE_TOL * xsq.max(axis=1) if xdbl.size else np.zeros(0, bool)
        locked[st.extra_tris[xbad].reshape(-1)] = True
    else:
        locked[st.extra_tris[0.5 * xdbl < BLENDER_MIN].reshape(-1)] = True
        xbad = ~(xdbl > FLT_EPSILON)
    n_bad = int(n_bad) + int(xbad.sum())
    if st.extra_tris.size:
        xv = (xcot * np.where(xbad, 0.0, st.extra_w)[:, None]).reshape(-1)
        pw += np.bincount(st.extra_pair.reshape(-1), xv, minlength=P)
    if K is not None:
        deg = K.pair_degree(st.pairs, pw, n)
    else:
        deg = np.bincount(st.pairs[:, 0], pw, minlength=n) + np.bincount(st.pairs[:, 1], pw, minlength=n)
    if st.extra_tris.size:
        xa = 0.5 * xdbl * st.extra_w
        ring += np.bincount(st.extra_tris.reshape(-1), np.repeat(xa, 3), minlength=n)
    if k:
        with np.errstate(over="ignore"):
            ring = np.ldexp(ring, 2 * k)
        if not np.isfinite(ring).all():
            raise ParameterError(f"the mesh's coordinates (up to {np.ldexp(1.0, k):.3g}) give areas beyond double "
                                 "precision; rescale it (the normalised flow does this itself)")
    return st, pw, deg, ring, locked, n_bad


@kernels.with_small_pages
def cotan_weights(mesh, scheme: str = "tqlbo", *, thresholds: str = "relative") -> CotanWeights:
    """Cotangent weights W and ring areas of a hybrid mesh.

    Parameters
    ----------
    mesh : Mesh
    scheme : {"tqlbo", "blender"}
        ``"tqlbo"``: the paper's hybrid operator (quads = mean of their two
        triangulations, n-gons = mean of their fan triangulations).
        ``"blender"``: ½·cot per polygon corner triangle, as Blender.
    thresholds : {"relative", "blender"}
        Degeneracy rule (module docstring).

    Returns
    -------
    CotanWeights
        ``W`` (symmetric, zero diagonal), ``degree``, ``ring_area``,
        ``locked`` vertices, ``n_degenerate``.  Unpacks as ``W, areas``.

    Examples
    --------
    >>> import shapeflow as sf
    >>> quad = sf.Mesh([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], [[0, 1, 2, 3]])
    >>> W, A = sf.cotan_weights(quad)
    >>> round(W[0, 1], 12), round(W[0, 2], 12), A.tolist()
    (1.0, 0.0, [0.75, 0.75, 0.75, 0.75])
    """
    st, pw, deg, ring, locked, n_bad = _assemble(mesh, scheme, thresholds)
    K = st.matrix(np.zeros(mesh.n_vertices), pw, copy_pattern=True)
    K.sum_duplicates()   # a chord shared by two faces becomes one entry
    K.eliminate_zeros()  # the explicit zero diagonal (and exact-zero weights)
    return CotanWeights(W=K, degree=deg, ring_area=ring, locked=locked, n_degenerate=n_bad,
                        pairs=st.pairs, pair_weights=pw, scheme=scheme)


@kernels.with_small_pages
def laplacian(mesh, normalized: bool = True, scheme: str = "tqlbo", *, thresholds: str = "relative") -> sp.csr_matrix:
    """The TQLBO Laplacian as a sparse matrix (positive semi-definite convention).

    ``normalized=True``: eq. 10, ``L = I − D⁻¹W`` (scale-invariant; the paper
    recommends it).  ``normalized=False``: eq. 9, ``L = (D − W) / (2A)`` with
    the ring area A of eq. 5.  Rows of vertices with D = 0 (isolated) or A = 0
    are zero.  ``L @ V`` is zero at interior vertices of planar meshes (linear
    precision) and points away from the neighbour average.
    """
    st, pw, deg, ring, _, _ = _assemble(mesh, scheme, thresholds)
    K = st.matrix(deg, -pw)
    denom = deg if normalized else 2.0 * ring
    with np.errstate(divide="ignore"):
        s = np.where(denom > 0, 1.0 / np.where(denom > 0, denom, 1.0), 0.0)
    return sp.csr_matrix(sp.diags(s) @ K)


def vertex_areas(mesh, kind: str = "ring", scheme: str = "tqlbo") -> np.ndarray:
    """Per-vertex area.

    ``"ring"``
        The paper's ring area (eq. 5): the whole area of the weighted
        triangles around the vertex, about 3× the area the vertex owns.
    ``"barycentric"``
        ``ring / 3``: on triangle meshes exactly the barycentric area (a third
        of each incident triangle); on quads and n-gons it splits each face's
        area among its corners in proportion to the operator's triangles, and
        the areas of a planar face's corners sum to the face area.  Because it
        comes from the same triangles as W it stays consistent on mixed
        meshes (curvature converges on randomly half-triangulated spheres,
        where a plain "face area / corners" split does not).
    ``"mixed"``
        Meyer et al.'s mixed Voronoi area, averaged over the operator's
        triangles with their weights (exactly Meyer's on triangle meshes).
    """
    st, _, _, ring, _, _ = _assemble(mesh, scheme, "relative")
    return _areas(mesh, st, ring, kind)


def _areas(mesh, st: _Structure, ring: np.ndarray, kind: str) -> np.ndarray:
    """Per-vertex areas of :func:`vertex_areas` from an assembled operator."""
    if kind == "ring":
        return ring
    if kind == "barycentric":
        return ring / 3.0
    if kind == "mixed":
        tris, _, area_w, _ = st.triangles()
        cot, dbl, sq = triangle_cotangents(mesh.vertices, tris)
        area = 0.5 * dbl
        vor = np.empty_like(cot)
        for k in range(3):
            a, b = (k + 1) % 3, (k + 2) % 3
            vor[:, k] = (sq[:, b] * cot[:, b] + sq[:, a] * cot[:, a]) / 8.0
        obtuse = cot < 0  # angle > 90° at that corner
        any_obtuse = obtuse.any(axis=1)
        vor[any_obtuse] = (area[any_obtuse, None] / 4.0) * np.where(obtuse[any_obtuse], 2.0, 1.0)
        vals = (vor * area_w[:, None]).reshape(-1)
        return np.bincount(tris.reshape(-1), vals, minlength=mesh.n_vertices)
    raise ParameterError(f"unknown area kind {kind!r}; choose 'ring', 'barycentric' or 'mixed'")


def mean_curvature_normal(mesh, *, area: str = "ring", scheme: str = "tqlbo") -> np.ndarray:
    """Mean curvature normal H·n per vertex (eq. 3/4/7), shape (n, 3).

    Computed as ``−Δx / 2 = (D − W) V / (4 A)``, with H the mean of the
    principal curvatures (1/r on a sphere of radius r) and n the outward
    normal of a consistently oriented closed surface.

    ``area="ring"`` uses the paper's ring area (eq. 5); since that area is
    about 3× the area a vertex owns, the paper's curvature is about 1/3 of
    the true value.  ``area="barycentric"`` or ``"mixed"`` (standard choices,
    see :func:`vertex_areas`) converge to H.
    Vertices with zero area get 0; values at boundary vertices are not
    curvature (no closed ring).
    """
    k = pow2_exponent(mesh.vertices)
    if k:   # H·n scales as 1/size: computed on an exact power-of-two copy (its areas stay in range)
        return np.ldexp(mean_curvature_normal(mesh.with_vertices(np.ldexp(mesh.vertices, -k)), area=area,
                                              scheme=scheme), -k)
    st, pw, deg, ring, _, _ = _assemble(mesh, scheme, "relative")
    A = _areas(mesh, st, ring, area)
    KV = st.matrix(deg, -pw) @ mesh.vertices
    with np.errstate(divide="ignore", invalid="ignore"):
        out = KV / (4.0 * A[:, None])
    out[~(A > 0)] = 0.0
    return out


def mean_curvature(mesh, *, area: str = "ring", scheme: str = "tqlbo") -> np.ndarray:
    """Signed mean curvature per vertex: H = (H·n) · n_vertex.

    Positive where the surface bends away from its normal (convex parts of a
    closed outward-oriented surface: +1/r on a sphere).  See
    :func:`mean_curvature_normal` for the area choices.
    """
    hn = mean_curvature_normal(mesh, area=area, scheme=scheme)
    return np.einsum("ij,ij->i", hn, vertex_normals(mesh))
