"""Per-element measures: polygon vector areas, enclosed volume, mean edge length, and exact rescaling.

Pure, vectorised functions of positions and index arrays; no sparse assembly
here (that lives in :mod:`shapeflow.operators`).
"""

from __future__ import annotations

import numpy as np

__all__ = ["SCALE_LO", "SCALE_HI", "pow2_exponent", "face_vector_areas", "signed_volume", "mean_edge_length",
           "fan_triangles"]

#: Coordinates whose largest magnitude lies outside [SCALE_LO, SCALE_HI] are computed on a copy
#: scaled by a power of two (exact in binary floating point), so that no square, cross product or
#: area over- or underflows; results are scaled back exactly (cotangents are scale-free).
SCALE_LO, SCALE_HI = 2.0 ** -100, 2.0 ** 100


def pow2_exponent(V: np.ndarray) -> int:
    """0 for coordinates within [SCALE_LO, SCALE_HI], else k with max|V| = f·2^k, f in [0.5, 1)."""
    m = max(float(V.max()), -float(V.min())) if V.size else 0.0     # max |V| without a copy (NaN stays NaN)
    if m == 0.0 or SCALE_LO <= m <= SCALE_HI:
        return 0
    return int(np.frexp(m)[1])


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


def mean_edge_length(mesh, vertices: np.ndarray | None = None) -> float:
    """Mean length of the unique edges (0 for a mesh without faces)."""
    e = mesh.topology.edges
    if e.size == 0:
        return 0.0
    v = mesh.vertices if vertices is None else vertices
    return float(np.linalg.norm(v[e[:, 0]] - v[e[:, 1]], axis=1).mean())


def fan_triangles(mesh) -> np.ndarray:
    """(T, 3) triangles of the faces, each face as a fan from its first corner (for formats that
    store triangles only)."""
    t = mesh.topology
    fi = t.face_indices
    first = np.repeat(t.face_offsets[:-1], t.face_sizes)
    k = np.arange(t.n_corners)
    use = (k != first) & (t.corner_next != first)
    return np.stack([fi[first[use]], fi[k[use]], fi[t.corner_next[use]]], axis=1)
