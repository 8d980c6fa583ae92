"""Catmull–Clark and simple (linear) subdivision as sparse matrices.

One subdivision step maps the ``n`` old vertices to ``n + E + F`` new ones:

* the old vertices first (same indices),
* then one *edge point* per edge,
* then one *face point* per face (in face order),

and every face of size ``s`` becomes ``s`` quads
``[v_c, edge_point(c -> next), face_point, edge_point(prev -> c)]``,
corner after corner, face after face.  The map is linear, so each level is a
sparse matrix ``S`` (new × old) built once from the topology and applied to
positions and to every per-vertex attribute (``S @ X``); an animated cage then
costs one sparse product per frame.

Rules (those of OpenSubdiv, which Blender's Subdivision Surface modifier uses,
with ``use_limit_surface=False`` and ``use_creases=False``):

* face point: centroid of the face;
* edge point: ``(a + b)/4 + (f0 + f1)/4`` for a smooth edge (two consistently
  oriented faces), the midpoint ``(a + b)/2`` for a *sharp* edge;
* vertex point, by rule:

  - *smooth* (fewer than two sharp edges): ``(k-2)/k v + 1/k² Σ neighbours
    + 1/k² Σ face points``, ``k`` = number of incident edges;
  - *crease* (exactly two sharp edges): ``3/4 v + 1/8 (a + b)`` with ``a``,
    ``b`` the other ends of the two sharp edges: the cubic B-spline curve rule
    along boundaries;
  - *corner* (a sharp vertex, or more than two sharp edges): the vertex stays.

Sharpness, as OpenSubdiv sets it on the input mesh (the *base level*):

* boundary edges (one face) and non-manifold edges (three or more faces, or two
  faces traversing the edge in the same direction) are infinitely sharp;
* non-manifold vertices (incident to a non-manifold edge, or whose faces form
  more than one edge-connected fan, e.g. two cones touching at a tip) are
  infinitely sharp, i.e. they stay put — except a vertex on an *interior
  non-manifold crease* (exactly two non-manifold edges, no boundary edge and
  more faces than edges), which follows the crease rule along those edges;
* with ``boundary="keep-corners"`` (Blender's ``PRESERVE_CORNERS``, OpenSubdiv's
  ``VTX_BOUNDARY_EDGE_AND_CORNER``) a vertex with exactly one face and two
  edges is infinitely sharp too; with ``boundary="smooth"`` (Blender's ``ALL``,
  ``VTX_BOUNDARY_EDGE_ONLY``) it follows the crease rule like any boundary
  vertex.
* So a boundary vertex with more than two boundary edges (several boundary
  loops touching) is a corner and stays put.

These rules were compared with Blender 5.0.1 (``bpy``) on a bowtie, two closed
fans touching at a vertex, a fin of three faces on one edge, a box with an
inner wall, a quad wound the wrong way and two squares touching at a corner:
the same points at levels 1 to 3.

On refined levels sharpness is inherited, not re-derived: the two halves of a
sharp edge are sharp, the new edges inside a face are smooth, old vertices keep
their sharpness and new vertices have none.  (Semi-sharp creases would enter
here: a finite per-edge sharpness, decremented per level, blending the smooth
and crease rules; only 0 and ∞ are used for now.)

``scheme="simple"`` keeps the same connectivity with edge midpoints, face
centroids and the old vertices unmoved (Blender's ``SIMPLE``).  Vertex weights
in Blender follow that linear rule in both schemes (``weights_rule="linear"``).

Vertex order: Blender builds the mesh's edges from the face list
(``BKE_mesh_calc_edges``): edges in order of first use walking the faces'
corners (edge ``prev -> corner``), split over hash maps by the parity bits of
the lower vertex index when the mesh has 1000 faces or more and Blender runs on
several threads.  With ``edge_order="blender"`` edge points are numbered like
that, so one level reproduces the vertex and face order of Blender's modifier
exactly (for meshes whose edges Blender computed from the faces);
``blender_threads`` picks the number of hash maps Blender used.  Several levels
are applied one after the other here, while Blender evaluates a grid per face;
the points and faces are the same but listed in a different order.
"""

from __future__ import annotations

from typing import Callable

import numpy as np
import scipy.sparse as sp

from . import kernels, params
from .errors import ParameterError
from .geometry import refresh_normals
from .mesh import WEIGHT, Mesh, Topology

__all__ = ["subdivide", "subdivision_matrix", "SCHEMES", "BOUNDARY_RULES", "WEIGHT_RULES"]

#: accepted values of ``scheme``
SCHEMES = ("catmull-clark", "simple")
#: accepted values of ``boundary``
BOUNDARY_RULES = ("smooth", "keep-corners")
#: accepted values of ``weights_rule``
WEIGHT_RULES = ("linear", "smooth")
#: accepted values of ``edge_order``
EDGE_ORDERS = ("blender", "sorted")

_INF = np.inf

# vertex rules (the numbers are OpenSubdiv's Sdc::Crease::Rule masks)
_SMOOTH, _DART, _CREASE, _CORNER = 1, 2, 4, 8


# --------------------------------------------------------------------------
# parameter checks
# --------------------------------------------------------------------------

def _check_choice(name: str, value, choices) -> str:
    if not isinstance(value, str) or value not in choices:
        opts = ", ".join(repr(c) for c in choices)
        raise ParameterError(f"{name} must be one of {opts}; got {value!r}")
    return value


def _check_levels(levels) -> int:
    if isinstance(levels, bool) or not isinstance(levels, (int, np.integer)):
        raise ParameterError(f"levels must be a non-negative integer; got {levels!r}")
    if levels < 0:
        raise ParameterError(f"levels must be a non-negative integer; got {levels!r}")
    return int(levels)


#: peak bytes per output face of subdivide() (measured: 370-500 B on 0.19-3 million output quads)
BYTES_PER_FACE = 500


def _check_output_size(mesh: Mesh, levels: int) -> None:
    """Refuse, before any work, a subdivision whose output cannot fit in memory.

    Level 1 turns every face into as many quads as it has corners; each
    further level multiplies the quads by 4.
    """
    if levels == 0:
        return
    t = _as_topology(mesh)
    faces = float(t.face_indices.size) * 4.0 ** min(levels - 1, 200)   # 4^200 already exceeds any memory
    from .budget import check_memory

    count = f"{faces:,.0f}" if faces < 1e15 else f"{faces:.3g}" if levels <= 201 else "more than 1e120"
    check_memory(f"{levels} levels of subdivision ({t.n_faces:,} faces -> {count} quads)",
                 faces * BYTES_PER_FACE, parameter="levels")


def _check_threads(threads) -> int:
    if isinstance(threads, bool) or not isinstance(threads, (int, np.integer)) or threads < 1:
        raise ParameterError(f"blender_threads must be a positive integer; got {threads!r}")
    return int(threads)


def _as_topology(mesh) -> Topology:
    if isinstance(mesh, Mesh):
        return mesh.topology
    if isinstance(mesh, Topology):
        return mesh
    raise ParameterError(f"expected a shapeflow Mesh, got {type(mesh).__name__}")


# --------------------------------------------------------------------------
# sharpness of the base level (what OpenSubdiv derives from the topology)
# --------------------------------------------------------------------------

def _nonmanifold_edge_mask(t: Topology) -> np.ndarray:
    """Edges with 3+ faces, or 2 faces traversing them in the same direction."""
    return (t.edge_face_count > 2) | t.inconsistent_edge_mask


def _multi_fan_vertices(t: Topology, manifold_edge: np.ndarray) -> np.ndarray:
    """Mask of vertices whose corners do not form a single edge-connected fan.

    Corners at the same vertex are linked across each manifold (two-face,
    consistently oriented) edge; a vertex is a single fan when all its corners
    end up in one connected component.
    """
    from scipy.sparse.csgraph import connected_components

    n, C = t.n_vertices, t.n_corners
    bad = np.zeros(n, dtype=bool)
    if C == 0:
        return bad
    me = np.flatnonzero(manifold_edge)
    o = t.edge_corner_offsets
    c0 = t.edge_corners[o[me]]       # half-edge a -> b in one face
    c1 = t.edge_corners[o[me] + 1]   # half-edge b -> a in the other
    nxt = t.corner_next
    # at a: corner c0 and the corner after c1; at b: the corner after c0 and c1
    src = np.concatenate([c0, nxt[c0]])
    dst = np.concatenate([nxt[c1], c1])
    g = sp.coo_matrix((np.ones(src.size, dtype=np.int8), (src, dst)), shape=(C, C)).tocsr()
    _, label = connected_components(g, directed=False)
    fi = t.face_indices
    first = np.full(n, -1, dtype=np.int64)
    first[fi[::-1]] = label[::-1]  # any representative label per vertex
    bad[fi[label != first[fi]]] = True
    return bad


def _base_sharpness(t: Topology, boundary: str) -> tuple[np.ndarray, np.ndarray]:
    """Per-edge and per-vertex sharpness (0 or inf) of the input mesh.

    This is where user creases would be merged in (``max`` with given edge and
    vertex sharpness) once semi-sharp creases are supported.
    """
    n = t.n_vertices
    efc = t.edge_face_count
    boundary_edge = efc < 2
    nonman_edge = _nonmanifold_edge_mask(t)
    edge_sharp = np.zeros(t.n_edges)
    edge_sharp[boundary_edge | nonman_edge] = _INF

    e = t.edges
    n_faces = t.vertex_corner_count
    n_edges = t.vertex_edge_count
    n_bnd = np.bincount(e[boundary_edge].ravel(), minlength=n)
    n_nm = np.bincount(e[nonman_edge].ravel(), minlength=n)

    nonman_vertex = n_nm > 0
    nonman_vertex |= _multi_fan_vertices(t, ~boundary_edge & ~nonman_edge)
    # an interior non-manifold crease (fins along a pair of edges) is not sharpened
    interior_crease = (n_nm == 2) & (n_bnd == 0) & (n_faces > n_edges)
    vertex_sharp = np.zeros(n)
    vertex_sharp[nonman_vertex & ~interior_crease] = _INF
    if boundary == "keep-corners":
        vertex_sharp[(n_faces == 1) & (n_edges == 2)] = _INF
    return edge_sharp, vertex_sharp


def _vertex_rules(t: Topology, edge_sharp: np.ndarray, vertex_sharp: np.ndarray) -> np.ndarray:
    """OpenSubdiv's vertex-vertex rule: corner if the vertex is sharp, else by
    the number of sharp incident edges (0 smooth, 1 dart, 2 crease, 3+ corner)."""
    n = t.n_vertices
    n_sharp = np.bincount(t.edges[edge_sharp > 0].ravel(), minlength=n)
    rule = np.where(n_sharp == 0, _SMOOTH, np.where(n_sharp == 1, _DART, np.where(n_sharp == 2, _CREASE, _CORNER)))
    rule[vertex_sharp > 0] = _CORNER
    rule[t.vertex_corner_count == 0] = _CORNER  # unreferenced vertices stay where they are
    return rule


# --------------------------------------------------------------------------
# one level
# --------------------------------------------------------------------------

def _edge_order(t: Topology, edge_order: str, threads: int) -> np.ndarray:
    """Permutation: position of each edge point -> edge id of ``t.edges``."""
    if edge_order == "sorted" or t.n_edges == 0:
        return np.arange(t.n_edges, dtype=np.int64)
    # first corner c whose edge (prev(c) -> c) is the edge: the corner after the
    # first corner whose half-edge (c -> next(c)) is the edge
    first = t.corner_next[t.edge_corners[t.edge_corner_offsets[:-1]]]
    maps = 1
    if t.n_faces >= 1000:
        maps = 1 << (min(8, threads).bit_length() - 1)  # largest power of two <= min(8, threads)
    if maps > 1:
        key = (t.edges[:, 0] & (maps - 1)) * np.int64(t.n_corners) + first
    else:
        key = first
    return np.argsort(key, kind="stable")


def _face_point_matrix(t: Topology) -> sp.csr_matrix:
    """(F, n) centroid of each face."""
    inv = 1.0 / t.face_sizes
    return sp.csr_matrix(
        (np.repeat(inv, t.face_sizes), t.face_indices.copy(), t.face_offsets.copy()),
        shape=(t.n_faces, t.n_vertices),
    )


class _Level:
    """Connectivity of one subdivision step: numbering, new faces, sharpness."""

    def __init__(self, t: Topology, edge_sharp: np.ndarray, vertex_sharp: np.ndarray,
                 edge_order: str, threads: int):
        self.t = t
        self.edge_sharp = edge_sharp
        self.vertex_sharp = vertex_sharp
        n, E, F = t.n_vertices, t.n_edges, t.n_faces
        self.n, self.E, self.F = n, E, F
        self.n_new = n + E + F
        self.eorder = _edge_order(t, edge_order, threads)
        erank = np.empty(E, dtype=np.int64)
        erank[self.eorder] = np.arange(E, dtype=np.int64)
        self.erank = erank

    # --- new faces -------------------------------------------------------
    def new_topology(self) -> Topology:
        t = self.t
        n, E = self.n, self.E
        C = t.n_corners
        sizes = t.face_sizes
        ep = n + self.erank[t.corner_edge]          # edge point of c -> next(c)
        cols = (t.face_indices, ep, n + E + t.corner_face, ep[t.corner_prev])
        # Blender lays a quad's four children out on one grid: child k starts at
        # its k-th vertex (same quads, same orientation, rotated vertex lists);
        # the children of other faces start at the old vertex
        if C and (sizes == 4).all():
            rot = np.arange(C, dtype=np.int64) & 3
        elif C and (sizes == 4).any():
            local = np.arange(C, dtype=np.int64) - np.repeat(t.face_offsets[:-1], sizes)
            rot = np.where(np.repeat(sizes == 4, sizes), local, 0)
        else:
            rot = None
        quads = np.empty((C, 4), dtype=np.int64)
        for j in range(4):
            quads[:, j] = cols[j] if rot is None else np.choose((j - rot) & 3, cols)
        idx = quads.reshape(-1)
        off = np.arange(C + 1, dtype=np.int64) * 4
        idx.flags.writeable = False
        off.flags.writeable = False
        return Topology(idx, off, self.n_new)

    def child_sharpness(self, child: Topology) -> tuple[np.ndarray, np.ndarray]:
        """Inherited sharpness on the refined level (see the module docstring)."""
        n, E = self.n, self.E
        ce = child.edges
        lo, hi = ce[:, 0], ce[:, 1]
        # halves of an old edge join an old vertex (lo < n) to its edge point
        half = (lo < n) & (hi >= n) & (hi < n + E)
        es = np.zeros(child.n_edges)
        es[half] = self.edge_sharp[self.eorder[hi[half] - n]]
        vs = np.zeros(self.n_new)
        vs[:n] = self.vertex_sharp
        return es, vs

    # --- matrices --------------------------------------------------------
    def simple_matrix(self) -> sp.csr_matrix:
        t = self.t
        n, E = self.n, self.E
        e = t.edges[self.eorder]
        top = sp.identity(n, format="csr")
        mid = sp.csr_matrix((np.full(2 * E, 0.5), e.reshape(-1), np.arange(E + 1) * 2), shape=(E, n))
        return sp.vstack([top, mid, _face_point_matrix(t)], format="csr")

    def catmull_clark_matrix(self) -> sp.csr_matrix:
        P, Q = self.catmull_clark_factors()
        return P @ Q  # no duplicates; column indices not sorted within rows

    def catmull_clark_factors(self) -> tuple[sp.csr_matrix, sp.csr_matrix]:
        """S = P @ Q: P has rows over the new points and columns over [old
        vertices, face points]; Q = [I; face-point matrix]."""
        t = self.t
        n, E, F = self.n, self.E, self.F
        rule = _vertex_rules(t, self.edge_sharp, self.vertex_sharp)
        edges = t.edges
        a, b = edges[:, 0], edges[:, 1]
        sharp_e = self.edge_sharp > 0
        rows, cols, vals = [], [], []

        # vertex points ----------------------------------------------------
        k = t.vertex_edge_count.astype(np.float64)
        smooth_v = (rule == _SMOOTH) | (rule == _DART)
        crease_v = rule == _CREASE
        ids = np.arange(n, dtype=np.int64)
        diag = np.ones(n)
        diag[crease_v] = 0.75
        with np.errstate(divide="ignore", invalid="ignore"):
            ks = np.where(smooth_v, k, 1.0)
            diag[smooth_v] = (ks[smooth_v] - 2.0) / ks[smooth_v]
            inv_k2 = 1.0 / (ks * ks)
        rows.append(ids); cols.append(ids); vals.append(diag)
        # smooth: every neighbour 1/k², every incident face point 1/k²
        for p, q in ((a, b), (b, a)):
            m = smooth_v[p]
            rows.append(p[m]); cols.append(q[m]); vals.append(inv_k2[p[m]])
            # crease: the other ends of the two sharp edges, 1/8 each
            m = crease_v[p] & sharp_e
            rows.append(p[m]); cols.append(q[m]); vals.append(np.full(int(m.sum()), 0.125))
        fi = t.face_indices
        m = smooth_v[fi]
        rows.append(fi[m]); cols.append(n + t.corner_face[m]); vals.append(inv_k2[fi[m]])

        # edge points ------------------------------------------------------
        erow = n + self.erank
        smooth_e = ~sharp_e & (t.edge_face_count == 2)
        w = np.where(smooth_e, 0.25, 0.5)
        rows += [erow, erow]; cols += [a, b]; vals += [w, w]
        se = np.flatnonzero(smooth_e)
        o = t.edge_corner_offsets
        f0 = t.corner_face[t.edge_corners[o[se]]]
        f1 = t.corner_face[t.edge_corners[o[se] + 1]]
        q = np.full(se.size, 0.25)
        rows += [erow[se], erow[se]]; cols += [n + f0, n + f1]; vals += [q, q]
        # an edge that is neither sharp nor two-faced cannot occur: one-face and
        # 3+-face edges are always sharp.

        # face points ------------------------------------------------------
        fr = np.arange(F, dtype=np.int64)
        rows.append(n + E + fr); cols.append(n + fr); vals.append(np.ones(F))

        idx = np.int32 if self.n_new + F < 2**31 - 1 else np.int64
        r = np.concatenate(rows).astype(idx, copy=False)
        c = np.concatenate(cols).astype(idx, copy=False)
        v = np.concatenate(vals)
        del rows, cols, vals
        P = sp.coo_matrix((v, (r, c)), shape=(self.n_new, n + F)).tocsr()
        del r, c, v
        Q = sp.vstack([sp.identity(n, format="csr"), _face_point_matrix(t)], format="csr")
        return P, Q


# --------------------------------------------------------------------------
# public API
# --------------------------------------------------------------------------

class _Factored:
    """A sparse matrix kept as a product of sparse factors, applied factor by
    factor (cheaper than forming the product when it is used once)."""

    def __init__(self, *factors):
        self.factors = factors
        self.shape = (factors[0].shape[0], factors[-1].shape[1])

    def __matmul__(self, X):
        for f in reversed(self.factors):
            X = f @ X
        return X


def _levels(mesh, levels, schemes, boundary, edge_order, threads, factored=False):
    """Yield (matrices by scheme, new topology) for each level."""
    t = _as_topology(mesh)
    smooth = "catmull-clark" in schemes
    if smooth and levels:
        edge_sharp, vertex_sharp = _base_sharpness(t, boundary)
    else:
        edge_sharp = vertex_sharp = None
    for level in range(levels):
        lev = _Level(t, edge_sharp, vertex_sharp, edge_order, threads)
        mats = {}
        for s in schemes:
            if s == "simple":
                mats[s] = lev.simple_matrix()
            elif factored:
                mats[s] = _Factored(*lev.catmull_clark_factors())
            else:
                mats[s] = lev.catmull_clark_matrix()
        child = lev.new_topology()
        if smooth and level + 1 < levels:
            edge_sharp, vertex_sharp = lev.child_sharpness(child)
        yield mats, child
        t = child


@kernels.with_small_pages
def subdivision_matrix(mesh, *, levels: int = 1, scheme: str = "catmull-clark",
                       boundary: str = "smooth", edge_order: str = "blender",
                       blender_threads: int = 1) -> tuple[sp.csr_matrix, Topology]:
    """The sparse subdivision matrix of ``levels`` steps, and the new faces.

    Parameters
    ----------
    mesh : Mesh or Topology
        The cage; only its connectivity matters.
    levels : int, default 1
        Number of subdivision steps (0 gives the identity and the same faces).
    scheme : {"catmull-clark", "simple"}
        Catmull–Clark, or simple (linear: midpoints and centroids, old vertices
        unmoved; same connectivity).
    boundary : {"smooth", "keep-corners"}
        Boundary vertices follow the cubic B-spline curve rule; with
        ``"keep-corners"`` vertices with one face and two edges stay put
        (Blender's ``ALL`` and ``PRESERVE_CORNERS``).  No effect on ``"simple"``.
    edge_order : {"blender", "sorted"}
        Numbering of the edge points: Blender's (see the module docstring) or
        the order of ``mesh.topology.edges``.
    blender_threads : int, default 1
        Threads of the Blender whose edge order is reproduced (matters only for
        meshes with 1000 faces or more).

    Returns
    -------
    S : scipy.sparse.csr_matrix, shape (n_new, n)
        New vertices as combinations of the old ones (rows sum to 1), the
        product of the per-level matrices.
    topology : Topology
        The new faces (``face_indices``, ``face_offsets``, ``face_sizes``), all
        quads when ``levels >= 1``; reuse it for many meshes with
        ``subdivide(...).with_vertices(S @ V)``.

    Examples
    --------
    >>> import numpy as np, shapeflow as sf
    >>> quad = sf.Mesh([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], [[0, 1, 2, 3]])
    >>> S, topo = subdivision_matrix(quad)
    >>> S.shape, topo.n_faces
    ((9, 4), 4)
    """
    levels = _check_levels(levels)
    _check_output_size(mesh, levels)
    scheme = _check_choice("scheme", scheme, SCHEMES)
    boundary = _check_choice("boundary", boundary, BOUNDARY_RULES)
    edge_order = _check_choice("edge_order", edge_order, EDGE_ORDERS)
    threads = _check_threads(blender_threads)
    t = _as_topology(mesh)
    S = sp.identity(t.n_vertices, format="csr")
    topo = t
    for mats, child in _levels(t, levels, (scheme,), boundary, edge_order, threads):
        S = mats[scheme] @ S
        topo = child
    return S.tocsr(), topo


@kernels.with_small_pages
def subdivide(mesh: Mesh, levels: int = 1, *, scheme: str = "catmull-clark",
              boundary: str = "smooth", weights_rule: str = "linear",
              edge_order: str = "blender", blender_threads: int = 1,
              progress: Callable[[int, int], None] | None = None) -> Mesh:
    """Subdivide a mesh ``levels`` times, carrying its per-vertex attributes.

    Works on any mix of triangles, quads and n-gons, open or closed; after one
    Catmull–Clark or simple step every face is a quad (a face of size ``s``
    becomes ``s`` quads).  Positions and every attribute other than the
    weights follow ``scheme``; the weights (attribute ``"weight"``) follow
    ``weights_rule``: ``"linear"`` (what Blender does: old vertices keep their
    weight, edge points get the edge mean, face points the face mean) or
    ``"smooth"`` (the Catmull–Clark stencil, for smoother influence zones).
    Weights stay in [0, 1] either way.

    Parameters
    ----------
    mesh : Mesh
    levels : int, default 1
        Number of steps, >= 0 (0 returns an equal mesh).
    scheme : {"catmull-clark", "simple"}
    boundary : {"smooth", "keep-corners"}
        See :func:`subdivision_matrix`.
    weights_rule : {"linear", "smooth"}
    edge_order, blender_threads
        Numbering of the new vertices, see :func:`subdivision_matrix`.
    progress : callable(done, total), optional
        Called after each level.  The output's memory is estimated before
        the first level, and a subdivision that cannot fit is refused.

    Returns
    -------
    Mesh
        ``n + E + F`` vertices per level (old vertices first, with unchanged
        indices), all-quad faces.

    Raises
    ------
    ParameterError
        A bad ``levels``, ``scheme``, ``boundary`` or ``weights_rule``.

    Examples
    --------
    >>> import shapeflow as sf
    >>> cube = sf.Mesh([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)],
    ...                [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]])
    >>> fine = subdivide(cube, 2)
    >>> fine.n_vertices, fine.n_faces
    (98, 96)
    """
    if not isinstance(mesh, Mesh):
        raise ParameterError(f"expected a shapeflow Mesh, got {type(mesh).__name__}")
    levels = _check_levels(levels)
    _check_output_size(mesh, levels)
    scheme = _check_choice("scheme", scheme, SCHEMES)
    boundary = _check_choice("boundary", boundary, BOUNDARY_RULES)
    weights_rule = _check_choice("weights_rule", weights_rule, WEIGHT_RULES)
    edge_order = _check_choice("edge_order", edge_order, EDGE_ORDERS)
    threads = _check_threads(blender_threads)
    params.progress(progress)

    attrs: dict[str, np.ndarray] = {k: np.asarray(v) for k, v in mesh.attributes.items()}
    types = {k: v.dtype for k, v in attrs.items()}
    weights = attrs.pop(WEIGHT, None)
    w_scheme = "simple" if weights_rule == "linear" else "catmull-clark"
    schemes = (scheme,) if weights is None or w_scheme == scheme else (scheme, w_scheme)

    X = mesh.vertices
    topo = mesh.topology
    # each level's matrix is applied as its two factors (S = P @ Q), which is
    # cheaper than forming S for a single use; subdivision_matrix() forms it
    for done, (mats, child) in enumerate(_levels(mesh, levels, schemes, boundary, edge_order, threads,
                                                 factored=True), start=1):
        S = mats[scheme]
        X = S @ X
        attrs = {k: (S @ v.reshape(v.shape[0], -1)).reshape((S.shape[0],) + v.shape[1:])
                 for k, v in attrs.items()}
        if weights is not None:
            weights = mats[w_scheme] @ weights
        topo = child
        if progress is not None:
            progress(done, levels)
    if levels == 0:
        return mesh.with_vertices(mesh.vertices)
    if weights is not None:
        attrs[WEIGHT] = np.clip(weights, 0.0, 1.0)  # convex combinations; clip round-off
    for k, v in attrs.items():   # every attribute in its own type: integers rounded into their range
        dt = types[k]
        if dt.kind in "iu":
            info = np.iinfo(dt)
            attrs[k] = np.clip(np.rint(v), info.min, info.max).astype(dt)
        elif dt != v.dtype:
            attrs[k] = v.astype(dt)
    # normals (nx, ny, nz) were averaged like the rest: recomputed from the new surface, in their type
    return refresh_normals(Mesh(X, None, attributes=attrs, _topology=topo))
