"""Per-element geometry: triangle cotangents and areas, polygon areas, volume.

Pure, vectorised functions of positions and index arrays; no sparse assembly
here (that lives in :mod:`shapeflow.operators`).
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "triangle_cotangents",
    "face_vector_areas",
    "signed_volume",
    "vertex_normals",
    "mean_edge_length",
]


#: Coordinates whose largest magnitude lies outside [SCALE_LO, SCALE_HI] are computed on a copy
#: scaled by a power of two (exact in binary floating point), so that no square, cross product or
#: area over- or underflows; results are scaled back exactly (cotangents are scale-free).
SCALE_LO, SCALE_HI = 2.0 ** -100, 2.0 ** 100


def pow2_exponent(V: np.ndarray) -> int:
    """0 for coordinates within [SCALE_LO, SCALE_HI], else k with max|V| = f·2^k, f in [0.5, 1)."""
    m = float(np.abs(V).max()) if V.size else 0.0
    if m == 0.0 or SCALE_LO <= m <= SCALE_HI:
        return 0
    return int(np.frexp(m)[1])



def triangle_cotangents(vertices: np.ndarray, tris: np.ndarray):
    """Cotangents of the three angles of each triangle, and twice its area.

    Parameters
    ----------
    vertices : (n, 3) float64
    tris : (T, 3) int vertex indices

    Returns
    -------
    cot : (T, 3) float64
        ``cot[t, k]`` is the cotangent of the angle at corner ``k`` of
        triangle ``t`` (opposite the pair of the other two corners).  Rows of
        triangles with zero area are 0 (never inf or NaN).
    dbl_area : (T,) float64
        ``|e1 × e2|`` = twice the triangle area.
    sq_len : (T, 3) float64
        Squared length of the edge opposite each corner.
    """
    p0 = vertices[tris[:, 0]]
    p1 = vertices[tris[:, 1]]
    p2 = vertices[tris[:, 2]]
    e0 = p2 - p1  # opposite corner 0
    e1 = p0 - p2  # opposite corner 1
    e2 = p1 - p0  # opposite corner 2
    cr = np.cross(e2, -e1)
    dbl = np.sqrt(np.einsum("ij,ij->i", cr, cr))
    dots = np.empty((tris.shape[0], 3))
    dots[:, 0] = -np.einsum("ij,ij->i", e1, e2)
    dots[:, 1] = -np.einsum("ij,ij->i", e2, e0)
    dots[:, 2] = -np.einsum("ij,ij->i", e0, e1)
    sq = np.empty((tris.shape[0], 3))
    sq[:, 0] = np.einsum("ij,ij->i", e0, e0)
    sq[:, 1] = np.einsum("ij,ij->i", e1, e1)
    sq[:, 2] = np.einsum("ij,ij->i", e2, e2)
    with np.errstate(divide="ignore", invalid="ignore"):
        cot = dots / dbl[:, None]
    cot[~(dbl > 0)] = 0.0
    return cot, dbl, sq


def face_vector_areas(mesh, vertices: np.ndarray | None = None) -> np.ndarray:
    """(m, 3) vector area of every polygon (½ Σ (v_k − v_0) × (v_{k+1} − v_0)).

    Its length is the area of a planar polygon; it is translation-exact
    because it is computed relative to each face's first corner.  Computed
    component by component on contiguous arrays.
    """
    t = mesh.topology
    v = mesh.vertices if vertices is None else vertices
    if t.n_faces == 0:
        return np.zeros((0, 3))
    fi = t.face_indices
    sizes = t.face_sizes
    k0 = int(sizes[0])
    if k0 in (3, 4) and (sizes == k0).all():
        # uniform meshes: a triangle's edges, or a quad's diagonals (exact for any quad)
        f = fi.reshape(-1, k0)
        i, j, p, q = (0, 1, 0, 2) if k0 == 3 else (0, 2, 1, 3)
        a = [v[:, k][f[:, j]] - v[:, k][f[:, i]] for k in range(3)]
        b = [v[:, k][f[:, q]] - v[:, k][f[:, p]] for k in range(3)]
        return 0.5 * np.stack([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]], axis=1)
    first = np.repeat(fi[t.face_offsets[:-1]], sizes)
    nxt = fi[t.corner_next]
    a = [v[:, k][fi] - v[:, k][first] for k in range(3)]
    b = [v[:, k][nxt] - v[:, k][first] for k in range(3)]
    starts = t.face_offsets[:-1]
    out = np.empty((t.n_faces, 3))
    # every face has >= 3 corners, so no reduceat segment is empty
    out[:, 0] = np.add.reduceat(a[1] * b[2] - a[2] * b[1], starts)
    out[:, 1] = np.add.reduceat(a[2] * b[0] - a[0] * b[2], starts)
    out[:, 2] = np.add.reduceat(a[0] * b[1] - a[1] * b[0], starts)
    return 0.5 * out


def signed_volume(mesh, vertices: np.ndarray | None = None, center: np.ndarray | None = None) -> float:
    """Signed enclosed volume: Σ over fan triangles of det(a−c, b−c, d−c)/6.

    Each face is fan-triangulated from its first corner.  For a closed,
    consistently oriented mesh the result does not depend on ``center``
    (default: the vertex centroid); outward orientation gives a positive value.
    """
    t = mesh.topology
    v = mesh.vertices if vertices is None else vertices
    if t.n_faces == 0:
        return 0.0
    c = v.mean(axis=0) if center is None else np.asarray(center, dtype=np.float64)
    fi = t.face_indices
    first_corner = np.repeat(t.face_offsets[:-1], t.face_sizes)
    # fan triangles (first, k, k+1) for every corner k that is neither the first nor the last
    k = np.arange(t.n_corners)
    nxt = t.corner_next
    use = (k != first_corner) & (nxt != first_corner)
    a = v[fi[first_corner[use]]] - c
    b = v[fi[k[use]]] - c
    d = v[fi[nxt[use]]] - c
    return float(np.einsum("ij,ij->", a, np.cross(b, d)) / 6.0)


def vertex_normals(mesh, vertices: np.ndarray | None = None) -> np.ndarray:
    """Unit area-weighted vertex normals ((0,0,0) where undefined)."""
    t = mesh.topology
    v = mesh.vertices if vertices is None else vertices
    k = pow2_exponent(v)
    if k:   # normals are scale-free: an exact power-of-two copy keeps the areas in range
        v = np.ldexp(v, -k)
    fa = face_vector_areas(mesh, v)
    n = v.shape[0]
    nrm = np.empty((n, 3))
    for k in range(3):
        nrm[:, k] = np.bincount(t.face_indices, np.repeat(fa[:, k], t.face_sizes), minlength=n)
    ln = np.sqrt(np.einsum("ij,ij->i", nrm, nrm))
    ok = ln > 0
    nrm[ok] /= ln[ok, None]
    return nrm


def mean_edge_length(mesh, vertices: np.ndarray | None = None) -> float:
    """Mean length of the unique edges (0 for a mesh without faces)."""
    e = mesh.topology.edges
    if e.size == 0:
        return 0.0
    v = mesh.vertices if vertices is None else vertices
    return float(np.linalg.norm(v[e[:, 0]] - v[e[:, 1]], axis=1).mean())


#: Vertex attributes that hold the surface normal (PLY's convention).  They are recomputed from
#: the surface whenever shapeflow moves the vertices, never carried over stale.
NORMAL_ATTRIBUTES = ("nx", "ny", "nz")


def refresh_normals(mesh):
    """``mesh`` with its normal attributes (nx, ny, nz), if it has them, recomputed from its positions.

    Unit area-weighted vertex normals (:func:`vertex_normals`), each attribute
    in its own type.  Returns the mesh unchanged when it has none of them.
    """
    have = [k for k in NORMAL_ATTRIBUTES if k in mesh.attributes]
    if not have:
        return mesh
    nrm = vertex_normals(mesh)
    return mesh.with_attributes(**{k: nrm[:, NORMAL_ATTRIBUTES.index(k)].astype(mesh.attributes[k].dtype)
                                   for k in have})

