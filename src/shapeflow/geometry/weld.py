"""Welding: one vertex for each group of coincident vertices, and back.

Formats and libraries that split vertices at UV or normal seams (glTF, STL triangle soups, pyvista
meshes) describe one surface with several copies of a vertex.  The operator must see one surface,
so :func:`weld` merges coincident vertices (within ``tol`` × the bounding-box diagonal) and keeps
the map; :func:`unweld` puts a result computed on the welded mesh back on the original layout, so
every copy of a vertex moves identically and the file's vertices, faces and attributes are
unchanged.

Examples
--------
>>> import numpy as np, shapeflow as sf
>>> soup = sf.Mesh(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0.]]),
...                [[0, 1, 2], [3, 4, 5]])
>>> w = sf.weld(soup)
>>> w.n_vertices, w.faces_as_lists()
(4, [[0, 1, 2], [1, 3, 2]])
"""

from __future__ import annotations

import numpy as np

from ..errors import MeshError, ParameterError
from ..mesh import Mesh
from ..mesh.attributes import Indexed, Labels
from ..mesh.convert import as_mesh
from .normals import refresh_normals

__all__ = ["WELD_TOL", "weld", "weld_map", "unweld", "needs_weld", "may_need_weld", "weld_if_split"]

#: default welding distance, relative to the bounding-box diagonal (float32 files round at ~6e-8)
WELD_TOL = 1e-7


def _unit_copy(vertices: np.ndarray) -> tuple[np.ndarray, float]:
    """The vertices translated to their bounding box's low corner and scaled by a power of two so
    that the box's diagonal lies in [1, 2) (exact apart from the translation, whose rounding is the
    same at every power-of-two scale), and that diagonal.  Works for any finite coordinates, 1e-300
    or 1e300 alike: nothing is squared before the rescaling, so nothing over- or underflows."""
    V = np.asarray(vertices, dtype=np.float64)
    if not np.isfinite(V).all():
        bad = int(np.flatnonzero(~np.isfinite(V).all(axis=1))[0])
        raise ParameterError(f"vertex {bad} has a non-finite coordinate ({V[bad].tolist()}); "
                             "coincident vertices cannot be found")
    m = max(float(V.max()), -float(V.min()))
    if m == 0.0:
        return np.zeros_like(V), 0.0
    V = np.ldexp(V, -int(np.frexp(m)[1]))          # max |V| in [0.5, 1): the box spans at most 2
    lo = V.min(axis=0)
    D = V - lo
    ext = D.max(axis=0)
    diag = float(np.sqrt(ext @ ext))   # ext >= 2^-53 of max |V| where nonzero: no underflow
    if diag == 0.0:
        return D, 0.0
    e = int(np.frexp(diag)[1]) - 1
    return np.ldexp(D, -e), float(np.ldexp(diag, -e))


def _row_groups(rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(labels, first): equal rows share a label (0 .. k-1, in no particular order) and ``first``
    (k,) holds one row index of each label; one sort of the rows' bytes (+0.0 and -0.0 differ: the
    callers' rows are >= +0.0)."""
    keys = np.ascontiguousarray(rows).view(np.dtype((np.void, rows.dtype.itemsize * rows.shape[1]))).ravel()
    order = np.argsort(keys)
    ks = keys[order]
    new = np.ones(ks.size, bool)
    new[1:] = ks[1:] != ks[:-1]
    labels = np.empty(ks.size, np.int64)
    labels[order] = np.cumsum(new) - 1
    return labels, order[new]


#: the neighbour search compares at most this many candidate pairs per distinct vertex (plus
#: MAX_PAIRS_BASE); a denser cluster of distinct positions within the welding distance is refused
MAX_PAIRS_PER_VERTEX, MAX_PAIRS_BASE = 64, 1 << 20


def weld_map(vertices: np.ndarray, tol: float, diagonal: float | None = None) -> np.ndarray:
    """(n,) the welded vertex of each vertex: groups of vertices joined by distances <= tol × the
    bounding-box diagonal, numbered in order of their first vertex.

    The neighbour search runs on a copy translated to the box's corner and scaled by a power of two
    to a diagonal in [1, 2), so coordinates of any finite magnitude (1e-300 .. 1e300, or ±1e308 whose
    diagonal overflows) weld as the same shape at scale 1 does: the same map.  ``diagonal`` (the
    caller's measure of it, which may have over- or underflowed) is not used; the diagonal is
    measured on the copy.  Coinciding vertices are merged first (one sort), so the search sees each
    position once and a million copies of one point cost what one does; the search's candidate
    pairs are bounded beforehand from a grid of the welding distance (27 × the sum of its cells'
    squared counts), and distinct positions packed more densely than
    ``MAX_PAIRS_PER_VERTEX`` pairs each raise a :class:`~shapeflow.errors.MeshError`.
    """
    del diagonal
    n = vertices.shape[0]
    if n == 0:
        return np.zeros(0, np.int64)
    D, diag = _unit_copy(vertices)
    same, first_of = _row_groups(D)                      # exact coincidence: one position each
    r = tol * diag
    if r > 0 and first_of.size > 1:
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components
        from scipy.spatial import cKDTree

        U = D[first_of]
        m = U.shape[0]
        # every pair within r lies in one cell of side c >= r or in two adjacent ones (27 per cell):
        # at most 27 × sum(count²) candidates, whatever the tree visits; c >= 2^-20 packs a cell's
        # three indices (U spans at most 2 per axis) into one int64
        c = max(r, 2.0 ** -20)
        ijk = np.floor(U / c).astype(np.int64)
        keys = np.sort((ijk[:, 0] << 42) | (ijk[:, 1] << 21) | ijk[:, 2])
        starts = np.flatnonzero(np.r_[True, keys[1:] != keys[:-1], True])
        bound = 27 * int(np.square(np.diff(starts)).sum())
        if bound > MAX_PAIRS_PER_VERTEX * m + MAX_PAIRS_BASE:
            raise MeshError(f"{m:,} distinct vertex positions lie in clusters closer than the welding distance "
                            f"({tol:g} × the bounding-box diagonal): welding would compare up to {bound:,} pairs, "
                            f"more than {MAX_PAIRS_PER_VERTEX} per position")
        pairs = cKDTree(U).query_pairs(r, output_type="ndarray")
        g = coo_matrix((np.ones(pairs.shape[0], np.int8), (pairs[:, 0], pairs[:, 1])), shape=(m, m))
        _, labels = connected_components(g, directed=False)
        labels = labels[same]
    else:   # exact coincidence only
        labels = same
    # renumber the groups by their first vertex (stable: welding a welded mesh changes nothing)
    first = np.full(labels.max() + 1, n, np.int64)
    np.minimum.at(first, labels, np.arange(n))
    order = np.argsort(first, kind="stable")
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    return rank[labels]


def needs_weld(mesh: Mesh, *, tol: float = WELD_TOL) -> bool:
    """Whether some vertices of ``mesh`` coincide (within ``tol`` × the diagonal): seams or a soup."""
    m = weld_map(mesh.vertices, tol)
    return bool(m.size) and int(m.max()) + 1 < mesh.n_vertices


def may_need_weld(mesh: Mesh) -> bool:
    """False for a mesh whose faces leave no boundary edge: a vertex split at a seam (or a soup) always
    leaves boundary edges along it, so a closed mesh has nothing to weld and skips the neighbour search
    (2.6 s for a 2M-vertex scan, 2026-11-24)."""
    return bool(mesh.n_faces) and bool(mesh.topology.boundary_edge_mask.any())


def weld_if_split(mesh: Mesh, *, tol: float = WELD_TOL) -> Mesh:
    """:func:`weld` where some vertices coincide (seams, a triangle soup), else ``mesh`` itself
    (``result is mesh`` tells which)."""
    mesh = as_mesh(mesh)
    if not may_need_weld(mesh):
        return mesh
    welded = weld(mesh, tol=tol)
    return mesh if welded.n_vertices == mesh.n_vertices else welded


def weld(mesh: Mesh, *, tol: float = WELD_TOL) -> Mesh:
    """``mesh`` with each group of coincident vertices merged into its first vertex.

    Faces keep their order; a face that the merge leaves with a repeated vertex (its corners
    coincided: no area) is dropped.  Per-vertex attributes take the first vertex's values; corner
    and face attributes follow their faces.  ``result.weld_map`` (n,) gives the welded vertex of
    each input vertex and ``result.weld_faces`` the input face of each welded face (for
    :func:`unweld`).
    """
    mesh = as_mesh(mesh)
    try:
        tol = float(tol)
    except (TypeError, ValueError):
        raise ParameterError(f"tol must be a number, got {tol!r}") from None
    if not (0.0 <= tol < 1.0):
        raise ParameterError(f"tol must be in [0, 1) (relative to the diagonal), got {tol!r}")
    wmap = weld_map(mesh.vertices, tol)
    k = int(wmap.max()) + 1 if wmap.size else 0
    first = np.full(k, mesh.n_vertices, np.int64)
    np.minimum.at(first, wmap, np.arange(mesh.n_vertices))
    t = mesh.topology
    fi = wmap[t.face_indices]
    # faces whose corners collapsed: some vertex repeated inside the face after the merge
    order = np.lexsort((fi, t.corner_face))
    dup = np.zeros(fi.size, bool)
    same = (fi[order][1:] == fi[order][:-1]) & (t.corner_face[order][1:] == t.corner_face[order][:-1])
    dup[order[1:][same]] = True
    bad_face = np.zeros(t.n_faces, bool)
    bad_face[t.corner_face[dup]] = True
    keep_face = np.flatnonzero(~bad_face)
    keep_corner = ~bad_face[t.corner_face]
    corner = {}
    for name, a in mesh.corner_attributes.items():
        corner[name] = (Indexed(a.values, a.index[keep_corner]) if isinstance(a, Indexed)
                        else np.asarray(a)[keep_corner])
    face = {name: (Labels(a.codes[keep_face], a.names) if isinstance(a, Labels) else np.asarray(a)[keep_face])
            for name, a in mesh.face_attributes.items()}
    out = Mesh.from_csr(mesh.vertices[first], t.face_sizes[keep_face], fi[keep_corner],
                        attributes={n: np.asarray(v)[first] for n, v in mesh.attributes.items()},
                        corner_attributes=corner, face_attributes=face, metadata=mesh.metadata)
    out.weld_map = wmap
    out.weld_faces = keep_face
    return out


def unweld(result: Mesh, original: Mesh, welded: Mesh) -> Mesh:
    """The positions of ``result`` (a mesh computed on ``welded = weld(original)``) on ``original``'s
    layout: every copy of a vertex gets its welded vertex's position.  Attributes are the
    original's (normals recomputed from the new surface)."""
    V = np.asarray(result.vertices)[welded.weld_map]
    return refresh_normals(original.with_vertices(V))
