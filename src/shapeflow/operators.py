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
``"tqlbo"`` (default; the paper, section 4.1, with NOTES.md's correction)
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

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import scipy.sparse as sp

from .errors import ParameterError
from .geometry import triangle_cotangents, vertex_normals

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
BLENDER_MIN = 1e-5    # Blender's absolute edge-length and corner-area threshold
FLT_EPSILON = float(np.finfo(np.float32).eps)


def _check_scheme(scheme: str) -> str:
    if scheme not in SCHEMES:
        raise ParameterError(f"unknown scheme {scheme!r}; choose one of {', '.join(SCHEMES)}")
    return scheme


# --------------------------------------------------------------------------
# per-face-size templates: which triangles of a face contribute, with weights
# --------------------------------------------------------------------------

@lru_cache(maxsize=None)
def _template(s: int, scheme: str):
    """Local triangles (t, 3), cot weights (t,), area weights (t,) of an s-gon.

    The middle entry of each blender-scheme triangle is its corner vertex.
    """
    if scheme == "blender":
        k = np.arange(s)
        tris = np.stack([(k - 1) % s, k, (k + 1) % s], axis=1)
        return tris, np.full(s, 0.5), np.ones(s)
    if s == 3:
        return np.array([[2, 0, 1]]), np.ones(1), np.ones(1)
    # mean over the s fan triangulations; identical triangles merged
    acc: dict[tuple, list] = {}
    for r in range(s):
        for j in range(1, s - 1):
            tri = (r, (r + j) % s, (r + j + 1) % s)
            key = tuple(sorted(tri))
            if key in acc:
                acc[key][1] += 1.0 / s
            else:
                acc[key] = [tri, 1.0 / s]
    tris = np.array([v[0] for v in acc.values()])
    w = np.array([v[1] for v in acc.values()])
    return tris, w, w.copy()


class _Structure:
    """Everything about W that depends on topology only (built once, cached).

    * ``tris`` (T, 3), ``cot_w``/``area_w`` (T,): the weighted triangles;
    * ``slot_pair`` (T, 3): the vertex pair opposite each triangle corner;
    * ``pairs`` (P, 2): unique vertex pairs (mesh edges first, then chords);
    * a CSR pattern for symmetric n×n matrices with diagonal, and the data
      positions of every pair (both triangles) and of the diagonal, so a new
      matrix on this pattern costs one gather.
    """

    def __init__(self, topo, scheme: str):
        n = topo.n_vertices
        sizes = topo.face_sizes
        offs = topo.face_offsets
        fi = topo.face_indices
        corner_edge = topo.corner_edge
        edges = topo.edges
        n_edges = edges.shape[0]
        tris_l, cw_l, aw_l, slot_l, mid_l = [], [], [], [], []
        chord_keys_l, chord_slot_pos = [], []
        n_slots = 0
        for s in np.unique(sizes):
            s = int(s)
            faces = np.flatnonzero(sizes == s)
            base = offs[faces]
            lt, lcw, law = _template(s, scheme)
            t = lt.shape[0]
            corners = base[:, None, None] + lt[None, :, :]          # (m_s, t, 3) global corners
            tris_l.append(fi[corners].reshape(-1, 3))
            cw_l.append(np.tile(lcw, faces.size))
            aw_l.append(np.tile(law, faces.size))
            # pair opposite local corner k of each template triangle
            slot = np.empty((faces.size, t, 3), dtype=np.int64)
            for k in range(3):
                a = lt[:, (k + 1) % 3]
                b = lt[:, (k + 2) % 3]
                fwd = (b - a) % s == 1   # a -> b is the half-edge of corner a
                bwd = (a - b) % s == 1
                for q in range(t):
                    if fwd[q]:
                        slot[:, q, k] = corner_edge[base + a[q]]
                    elif bwd[q]:
                        slot[:, q, k] = corner_edge[base + b[q]]
                    else:  # a chord: resolved below
                        va = fi[base + a[q]]
                        vb = fi[base + b[q]]
                        chord_keys_l.append(np.minimum(va, vb) * n + np.maximum(va, vb))
                        flat = n_slots + (np.arange(faces.size) * t + q) * 3 + k
                        chord_slot_pos.append(flat)
                        slot[:, q, k] = -1
            slot_l.append(slot.reshape(-1, 3))
            n_slots += faces.size * t * 3
        self.tris = np.concatenate(tris_l) if tris_l else np.zeros((0, 3), np.int64)
        self.cot_w = np.concatenate(cw_l) if cw_l else np.zeros(0)
        self.area_w = np.concatenate(aw_l) if aw_l else np.zeros(0)
        slot_pair = np.concatenate(slot_l).reshape(-1) if slot_l else np.zeros(0, np.int64)
        pairs = edges
        if chord_keys_l:
            keys = np.concatenate(chord_keys_l)
            pos = np.concatenate(chord_slot_pos)
            ukeys, inv = np.unique(keys, return_inverse=True)
            ekeys = edges[:, 0] * n + edges[:, 1]        # sorted (edges are sorted by key)
            j = np.minimum(np.searchsorted(ekeys, ukeys), max(n_edges - 1, 0))
            is_edge = (ekeys[j] == ukeys) if n_edges else np.zeros(ukeys.size, bool)
            new = ~is_edge
            ids = np.empty(ukeys.size, dtype=np.int64)
            ids[is_edge] = j[is_edge]
            ids[new] = n_edges + np.arange(int(new.sum()))
            slot_pair[pos] = ids[inv]
            extra = np.stack([ukeys[new] // n, ukeys[new] % n], axis=1)
            pairs = np.concatenate([edges, extra])
        self.slot_pair = slot_pair.reshape(-1, 3)
        self.pairs = pairs
        self.n = n
        # symmetric CSR pattern with diagonal; data[k] = id of the entry at k
        P = pairs.shape[0]
        rows = np.concatenate([pairs[:, 0], pairs[:, 1], np.arange(n)])
        cols = np.concatenate([pairs[:, 1], pairs[:, 0], np.arange(n)])
        ids = np.arange(1, 2 * P + n + 1, dtype=np.float64)
        pat = sp.csr_matrix((ids, (rows, cols)), shape=(n, n))
        pat.sort_indices()
        entry_at = pat.data.astype(np.int64) - 1          # CSR position -> entry id
        self.indptr = pat.indptr
        self.indices = pat.indices
        pos_of = np.empty_like(entry_at)
        pos_of[entry_at] = np.arange(entry_at.size)
        self.pos_upper = pos_of[:P]
        self.pos_lower = pos_of[P:2 * P]
        self.pos_diag = pos_of[2 * P:]
        self.csr_rows = np.repeat(np.arange(n), np.diff(self.indptr))

    def matrix(self, diag: np.ndarray, off: np.ndarray) -> sp.csr_matrix:
        """Symmetric CSR matrix with the given diagonal and per-pair values."""
        data = np.empty(self.indices.size)
        data[self.pos_diag] = diag
        data[self.pos_upper] = off
        data[self.pos_lower] = off
        return sp.csr_matrix((data, self.indices, self.indptr), shape=(self.n, self.n))


def _structure(mesh, scheme: str) -> _Structure:
    topo = mesh.topology
    cache = topo.__dict__.setdefault("_shapeflow_structures", {})
    if scheme not in cache:
        cache[scheme] = _Structure(topo, scheme)
    return cache[scheme]


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
    pair_weights : (P,) float64 and pairs (P, 2): W as a pair list.
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


def _assemble(mesh, scheme: str, thresholds: str, vertices: np.ndarray | None = None):
    """Pair weights, degrees, ring areas, locked mask, #degenerate (no matrix)."""
    if thresholds not in THRESHOLDS:
        raise ParameterError(f"unknown thresholds {thresholds!r}; choose one of {', '.join(THRESHOLDS)}")
    st = _structure(mesh, _check_scheme(scheme))
    V = mesh.vertices if vertices is None else vertices
    n = mesh.n_vertices
    cot, dbl, sq = triangle_cotangents(V, st.tris)
    locked = np.zeros(n, dtype=bool)
    edges = mesh.topology.edges
    elen = np.linalg.norm(V[edges[:, 0]] - V[edges[:, 1]], axis=1) if edges.size else np.zeros(0)
    if thresholds == "relative":
        h = float(elen.mean()) if elen.size else 0.0
        short = elen <= REL_EDGE_TOL * h
        bad = dbl <= REL_SHAPE_TOL * sq.max(axis=1) if st.tris.size else np.zeros(0, bool)
        locked[edges[short].reshape(-1)] = True
        locked[st.tris[bad].reshape(-1)] = True
        cot[bad] = 0.0
        n_bad = int(bad.sum())
    else:  # Blender's absolute rules
        short = elen < BLENDER_MIN
        locked[edges[short].reshape(-1)] = True
        small = 0.5 * dbl < BLENDER_MIN
        if scheme == "blender":
            locked[st.tris[small, 1]] = True       # the corner vertex of a corner triangle
        else:
            locked[st.tris[small].reshape(-1)] = True
        flat = ~(dbl > FLT_EPSILON)
        cot[flat] = 0.0
        n_bad = int(flat.sum())
    vals = (cot * st.cot_w[:, None]).reshape(-1)
    P = st.pairs.shape[0]
    pw = np.bincount(st.slot_pair.reshape(-1), vals, minlength=P)
    deg = np.bincount(st.pairs[:, 0], pw, minlength=n) + np.bincount(st.pairs[:, 1], pw, minlength=n)
    tri_area = 0.5 * dbl * st.area_w
    ring = np.bincount(st.tris.reshape(-1), np.repeat(tri_area, 3), minlength=n)
    return st, pw, deg, ring, locked, n_bad


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
    K = st.matrix(np.zeros(mesh.n_vertices), pw)
    K.setdiag(0.0)
    K.eliminate_zeros()
    return CotanWeights(W=K, degree=deg, ring_area=ring, locked=locked, n_degenerate=n_bad,
                        pairs=st.pairs, pair_weights=pw, scheme=scheme)


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
    if kind == "ring":
        return ring
    if kind == "barycentric":
        return ring / 3.0
    if kind == "mixed":
        cot, dbl, sq = triangle_cotangents(mesh.vertices, st.tris)
        area = 0.5 * dbl
        vor = np.empty_like(cot)
        for k in range(3):
            a, b = (k + 1) % 3, (k + 2) % 3
            vor[:, k] = (sq[:, b] * cot[:, b] + sq[:, a] * cot[:, a]) / 8.0
        obtuse = cot < 0  # angle > 90° at that corner
        any_obtuse = obtuse.any(axis=1)
        vor[any_obtuse] = (area[any_obtuse, None] / 4.0) * np.where(obtuse[any_obtuse], 2.0, 1.0)
        vals = (vor * st.area_w[:, None]).reshape(-1)
        return np.bincount(st.tris.reshape(-1), vals, minlength=mesh.n_vertices)
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
    st, pw, deg, ring, _, _ = _assemble(mesh, scheme, "relative")
    A = ring if area == "ring" else vertex_areas(mesh, area, scheme)
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
