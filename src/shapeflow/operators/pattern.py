"""Which triangles contribute to W, and the operator's sparse pattern (per topology, cached).

A face contributes through its corner triangles (prev, curr, next) and, in
the ``"tqlbo"`` scheme, through the interior fan triangles of its n-gons
(:func:`fan_interior_triangles`).  :class:`OperatorPattern` numbers every
vertex pair those triangles weight and lays out the symmetric CSR pattern, so
that a matrix with new values costs one scatter.  :func:`operator_pattern`
returns the one cached on the mesh's topology.
"""

from __future__ import annotations

import threading
import weakref
from functools import lru_cache

import numpy as np
import scipy.sparse as sp

from .. import accel
from ..errors import MeshError, ParameterError

__all__ = ["SCHEMES", "FAN_TRIANGLES_MAX", "check_scheme", "fan_interior_triangles", "corner_weights",
           "OperatorPattern", "ngon_fans", "csr_pattern", "operator_pattern"]


SCHEMES = ("tqlbo", "blender")


#: The most n-gon fan triangles (Σ s(s−4) over the faces of s >= 5 corners) the "tqlbo" scheme builds.
#: An s-gon's operator couples every pair of its corners, so its cost is quadratic in s by definition:
#: ~400 bytes and ~1-3 µs per fan triangle at peak (a 1,000-gon: 1 million, 0.45 GB, 1.6 s; a 3,000-gon:
#: 9 million, 3.5 GB, 30 s, refused).
FAN_TRIANGLES_MAX = 2_000_000


def check_scheme(scheme: str) -> str:
    if scheme not in SCHEMES:
        raise ParameterError(f"unknown scheme {scheme!r}; choose one of {', '.join(SCHEMES)}")
    return scheme


@lru_cache(maxsize=64)
def fan_interior_triangles(s: int):
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
    :func:`fan_interior_triangles`).
    """
    cs = sizes_per_corner
    if scheme == "blender":
        return np.full(cs.size, 0.5), np.ones(cs.size)
    w = np.where(cs == 3, 1.0 / 3.0, 2.0 / cs)
    return w, w


class OperatorPattern:
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
        fi = topo.face_indices
        corner_edge = topo.corner_edge
        # a weak reference: the topology caches this structure, and a strong one would make a
        # cycle that only the cyclic garbage collector frees (fresh meshes piled up between its runs)
        self._topo_ref = weakref.ref(topo)
        self.scheme = scheme
        self._locality = {}        # per implementation (the reference has none)
        (pairs, self.skip_pair, (self.extra_tris, self.extra_w, self.extra_face, self.extra_pair),
         self._corner_w) = accel.kernels("operators", n).pattern_core(topo, scheme)
        self.pairs = pairs
        self.n = n
        self.corner_edge = corner_edge
        self.fi = fi
        self._csr = None
        self._csr_lock = threading.Lock()

    def _csr_arrays(self):
        """The symmetric CSR pattern with diagonal (duplicates kept, columns sorted), built on first use:
        ``(indptr, indices, pos_upper, pos_lower, pos_diag)``.  The flow's lean layout for very large
        meshes (:class:`~shapeflow.linalg.pairs.PairMatrix`) never asks for it."""
        with self._csr_lock:
            if self._csr is None:
                pairs, n = self.pairs, self.n
                indptr, indices, pos_upper, pos_lower, pos_diag = accel.kernels("operators", n).pair_pattern(pairs, n)
                # shared by every matrix built on this pattern: read-only, so no scipy
                # operation can rewrite it in place for everyone
                indptr.flags.writeable = False
                indices.flags.writeable = False
                self._csr = (indptr, indices, pos_upper, pos_lower, pos_diag)
            return self._csr

    @property
    def csr_built(self) -> bool:
        """Whether the CSR pattern has been built (the lean flow layout never builds it)."""
        return self._csr is not None

    @property
    def indptr(self) -> np.ndarray:
        return self._csr_arrays()[0]

    @property
    def indices(self) -> np.ndarray:
        return self._csr_arrays()[1]

    @property
    def pos_upper(self) -> np.ndarray:
        """Position in ``indices`` of each pair's (first, second) entry."""
        return self._csr_arrays()[2]

    @property
    def pos_lower(self) -> np.ndarray:
        """Position in ``indices`` of each pair's (second, first) entry."""
        return self._csr_arrays()[3]

    @property
    def pos_diag(self) -> np.ndarray:
        """Position in ``indices`` of each diagonal entry."""
        return self._csr_arrays()[4]

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

    def matrix(self, diag: np.ndarray, off: np.ndarray, *, copy_pattern: bool = False) -> sp.csr_matrix:
        """Symmetric CSR matrix with the given diagonal and per-pair values.

        The index arrays are the shared, read-only pattern unless
        ``copy_pattern`` (needed before any in-place structural change).
        """
        data = accel.kernels("operators", self.n).fill_symmetric(self.indices.size, self.pos_diag, diag, self.pos_upper,
                                                                 self.pos_lower, off)
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
        k = accel.kernels("operators", self.n)
        if k.backend not in self._locality:
            self._locality[k.backend] = k.locality(self)
        return self._locality[k.backend]

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


def ngon_fans(sizes, offs, fi, corner_edge, n: int):
    """The interior fan triangles of every n-gon (s >= 5) of the "tqlbo" scheme, grouped by size.

    Returns lists (one entry per size) of triangles (t, 3), weights, faces,
    and for each triangle corner the pair opposite it: ``slot_keys`` (a chord's
    key ``min·n + max``, -1 for an edge) and ``slot_edge`` (an edge's id, -1
    for a chord).
    """
    xt, xw, xf, xslot_keys, xslot_edge = [], [], [], [], []
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
        lt, lw = fan_interior_triangles(s_)
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
    return xt, xw, xf, xslot_keys, xslot_edge


def csr_pattern(rows: np.ndarray, cols: np.ndarray, n: int):
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


def operator_pattern(mesh, scheme: str) -> OperatorPattern:
    """The :class:`OperatorPattern` of ``mesh`` for ``scheme``, cached on its topology."""
    topo = mesh.topology
    return topo.derived(("operator_pattern", scheme), lambda: OperatorPattern(topo, scheme))
