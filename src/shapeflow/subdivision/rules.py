"""Options, sharpness and the per-vertex rules of Catmull–Clark subdivision (OpenSubdiv's Sdc conventions)."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..errors import ParameterError
from ..mesh import Mesh, Topology
from ..mesh.convert import as_mesh

__all__ = ["SCHEMES", "BOUNDARY_RULES", "WEIGHT_RULES", "EDGE_ORDERS", "INF", "SMOOTH", "DART", "CREASE", "CORNER",
           "BYTES_PER_FACE", "check_choice", "check_levels", "check_output_size", "check_threads", "as_topology",
           "nonmanifold_edge_mask", "multi_fan_vertices", "base_sharpness", "vertex_rules", "edge_point_order",
           "face_point_matrix", "SHARPNESS_INFINITE", "crease_sharpness", "sharpness_crease", "decremented"]

#: accepted values of ``scheme``
SCHEMES = ("catmull-clark", "simple")
#: accepted values of ``boundary``
BOUNDARY_RULES = ("smooth", "keep-corners")
#: accepted values of ``weights_rule``
WEIGHT_RULES = ("linear", "smooth")
#: accepted values of ``edge_order``
EDGE_ORDERS = ("blender", "sorted")

INF = np.inf

#: vertex rules (the numbers are OpenSubdiv's Sdc::Crease::Rule masks)
SMOOTH, DART, CREASE, CORNER = 1, 2, 4, 8


def check_choice(name: str, value, choices) -> str:
    if not isinstance(value, str) or value not in choices:
        opts = ", ".join(repr(c) for c in choices)
        raise ParameterError(f"{name} must be one of {opts}; got {value!r}")
    return value


def check_levels(levels) -> int:
    if isinstance(levels, bool) or not isinstance(levels, (int, np.integer)):
        raise ParameterError(f"levels must be a non-negative integer; got {levels!r}")
    if levels < 0:
        raise ParameterError(f"levels must be a non-negative integer; got {levels!r}")
    return int(levels)


#: peak bytes per output face of subdivide() (measured: 370-500 B on 0.19-3 million output quads)
BYTES_PER_FACE = 500


def check_output_size(mesh: Mesh, levels: int) -> None:
    """Refuse, before any work, a subdivision whose output cannot fit in memory.

    Level 1 turns every face into as many quads as it has corners; each
    further level multiplies the quads by 4.
    """
    if levels == 0:
        return
    t = as_topology(mesh)
    faces = float(t.face_indices.size) * 4.0 ** min(levels - 1, 200)   # 4^200 already exceeds any memory
    from ..budget import check_memory

    count = f"{faces:,.0f}" if faces < 1e15 else f"{faces:.3g}" if levels <= 201 else "more than 1e120"
    check_memory(f"{levels} levels of subdivision ({t.n_faces:,} faces -> {count} quads)",
                 faces * BYTES_PER_FACE, parameter="levels")


def check_threads(threads) -> int:
    if isinstance(threads, bool) or not isinstance(threads, (int, np.integer)) or threads < 1:
        raise ParameterError(f"blender_threads must be a positive integer; got {threads!r}")
    return int(threads)


def as_topology(mesh) -> Topology:
    if not isinstance(mesh, Topology):
        mesh = as_mesh(mesh)
    if isinstance(mesh, Mesh):
        return mesh.topology
    if isinstance(mesh, Topology):
        return mesh
    raise ParameterError(f"expected a shapeflow Mesh, got {type(mesh).__name__}")


def nonmanifold_edge_mask(t: Topology) -> np.ndarray:
    """Edges with 3+ faces, or 2 faces traversing them in the same direction."""
    return (t.edge_face_count > 2) | t.inconsistent_edge_mask


def multi_fan_vertices(t: Topology, manifold_edge: np.ndarray) -> np.ndarray:
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


def base_sharpness(t: Topology, boundary: str, creases: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Per-edge and per-vertex sharpness of the input mesh: inf where the topology makes it sharp,
    else the creases' sharpness (OpenSubdiv units, :func:`crease_sharpness`; None: 0)."""
    n = t.n_vertices
    efc = t.edge_face_count
    boundary_edge = efc < 2
    nonman_edge = nonmanifold_edge_mask(t)
    edge_sharp = np.zeros(t.n_edges) if creases is None else creases.copy()
    edge_sharp[boundary_edge | nonman_edge] = INF

    e = t.edges
    n_faces = t.vertex_corner_count
    n_edges = t.vertex_edge_count
    n_bnd = np.bincount(e[boundary_edge].ravel(), minlength=n)
    n_nm = np.bincount(e[nonman_edge].ravel(), minlength=n)

    nonman_vertex = n_nm > 0
    nonman_vertex |= multi_fan_vertices(t, ~boundary_edge & ~nonman_edge)
    # an interior non-manifold crease (fins along a pair of edges) is not sharpened
    interior_crease = (n_nm == 2) & (n_bnd == 0) & (n_faces > n_edges)
    vertex_sharp = np.zeros(n)
    vertex_sharp[nonman_vertex & ~interior_crease] = INF
    if boundary == "keep-corners":
        vertex_sharp[(n_faces == 1) & (n_edges == 2)] = INF
    return edge_sharp, vertex_sharp


#: OpenSubdiv's infinite sharpness (Sdc::Crease::SHARPNESS_INFINITE): a crease of 1 in Blender
SHARPNESS_INFINITE = 10.0


def crease_sharpness(c: np.ndarray) -> np.ndarray:
    """Blender's edge crease c in [0, 1] as OpenSubdiv's sharpness, 10·c² (Blender's
    ``crease_to_sharpness``); 10 and more is infinitely sharp (inf here)."""
    s = 10.0 * np.square(np.asarray(c, dtype=np.float64))
    return np.where(s >= SHARPNESS_INFINITE, INF, s)


def sharpness_crease(s: np.ndarray) -> np.ndarray:
    """The inverse of :func:`crease_sharpness`: sqrt(s/10), 1 for infinite sharpness."""
    return np.sqrt(np.minimum(np.asarray(s, dtype=np.float64), SHARPNESS_INFINITE) / SHARPNESS_INFINITE)


def decremented(s: np.ndarray) -> np.ndarray:
    """The sharpness of an edge's halves one level down (OpenSubdiv's uniform rule): s − 1, 0 from
    s <= 1 on, inf stays inf."""
    return np.where(s > 1.0, s - 1.0, 0.0)


def vertex_rules(t: Topology, edge_sharp: np.ndarray, vertex_sharp: np.ndarray) -> np.ndarray:
    """OpenSubdiv's vertex-vertex rule: corner if the vertex is sharp, else by
    the number of sharp incident edges (0 smooth, 1 dart, 2 crease, 3+ corner)."""
    n = t.n_vertices
    n_sharp = np.bincount(t.edges[edge_sharp > 0].ravel(), minlength=n)
    rule = np.where(n_sharp == 0, SMOOTH, np.where(n_sharp == 1, DART, np.where(n_sharp == 2, CREASE, CORNER)))
    rule[vertex_sharp > 0] = CORNER
    rule[t.vertex_corner_count == 0] = CORNER  # unreferenced vertices stay where they are
    return rule


def edge_point_order(t: Topology, edge_order: str, threads: int) -> np.ndarray:
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


def face_point_matrix(t: Topology) -> sp.csr_matrix:
    """(F, n) centroid of each face."""
    inv = 1.0 / t.face_sizes
    return sp.csr_matrix(
        (np.repeat(inv, t.face_sizes), t.face_indices.copy(), t.face_offsets.copy()),
        shape=(t.n_faces, t.n_vertices),
    )
