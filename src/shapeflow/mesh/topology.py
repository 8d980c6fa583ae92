"""Derived connectivity of a face layout (corners, edges, boundary) and the mesh diagnostics.

Everything here is computed lazily, vectorised, and cached on the
:class:`Topology`, which every mesh made with ``Mesh.with_vertices`` shares.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, Callable, Hashable

import numpy as np

from .. import accel

__all__ = ["Topology", "Diagnostics", "component_count", "duplicate_faces", "nonmanifold_vertices"]


class Topology:
    """Derived connectivity of a face layout, computed lazily and cached.

    Corners are numbered as in ``face_indices``.  The half-edge of corner k
    goes from its vertex to the vertex of the next corner of the same face.
    """

    def __init__(self, face_indices: np.ndarray, face_offsets: np.ndarray, n_vertices: int):
        self.face_indices = face_indices
        self.face_offsets = face_offsets
        self.n_vertices = int(n_vertices)
        self._derived: dict = {}
        self._derived_lock = threading.Lock()

    def __getstate__(self) -> dict:
        """Pickled without its caches and lock (a mesh read by a child process travels this way)."""
        return {"face_indices": self.face_indices, "face_offsets": self.face_offsets, "n_vertices": self.n_vertices}

    def __setstate__(self, state: dict) -> None:
        self.__init__(state["face_indices"], state["face_offsets"], state["n_vertices"])

    def derived(self, key: Hashable, build: Callable[[], Any]) -> Any:
        """A structure that a higher layer derives from this connectivity alone, built once and cached.

        ``build()`` is called the first time ``key`` is asked for (under a
        lock, so concurrent callers share one build); later calls return the
        same object.  :func:`shapeflow.operators.operator_pattern` keeps the
        operator's sparse pattern here, per scheme, so every mesh sharing this
        topology (``Mesh.with_vertices``) reuses it.
        """
        with self._derived_lock:
            if key not in self._derived:
                self._derived[key] = build()
            return self._derived[key]

    # --- per face / per corner -------------------------------------------
    @cached_property
    def face_sizes(self) -> np.ndarray:
        s = np.diff(self.face_offsets)
        s.flags.writeable = False
        return s

    @property
    def n_faces(self) -> int:
        return self.face_offsets.size - 1

    @property
    def n_corners(self) -> int:
        return self.face_indices.size

    @cached_property
    def corner_face(self) -> np.ndarray:
        """Face of each corner."""
        return np.repeat(np.arange(self.n_faces, dtype=np.int64), self.face_sizes)

    @cached_property
    def corner_next(self) -> np.ndarray:
        """Index of the next corner in the same face (loop order)."""
        nxt = np.arange(1, self.n_corners + 1, dtype=np.int64)
        if self.n_faces:
            nxt[self.face_offsets[1:] - 1] = self.face_offsets[:-1]
        return nxt

    @cached_property
    def corner_prev(self) -> np.ndarray:
        """Index of the previous corner in the same face."""
        prv = np.arange(-1, self.n_corners - 1, dtype=np.int64)
        if self.n_faces:
            prv[self.face_offsets[:-1]] = self.face_offsets[1:] - 1
        return prv

    @cached_property
    def corner_vertices(self) -> np.ndarray:
        """(c, 3) array of (prev, curr, next) vertex of every corner."""
        fi = self.face_indices
        return np.stack([fi[self.corner_prev], fi, fi[self.corner_next]], axis=1)

    # --- edges -----------------------------------------------------------
    @property
    def index_dtype(self) -> type:
        """Integer type of the derived edge arrays: int32 while every count fits (half the bytes of
        int64; a scan of 50M vertices holds ~1.5 billion such entries), else int64."""
        return np.int32 if max(self.n_corners, self.n_vertices) < 2**31 - 1 else np.int64

    @cached_property
    def _edge_data(self):
        return accel.kernels("mesh", self.n_vertices).edge_data(self)

    @property
    def edges(self) -> np.ndarray:
        """(E, 2) unique undirected edges, each row sorted (low, high)."""
        return self._edge_data[0]

    @property
    def n_edges(self) -> int:
        return self.edges.shape[0]

    @property
    def corner_edge(self) -> np.ndarray:
        """Edge id of the half-edge leaving each corner (corner -> next corner)."""
        return self._edge_data[1]

    @property
    def edge_corner_offsets(self) -> np.ndarray:
        """CSR offsets into :attr:`edge_corners` (E + 1)."""
        return self._edge_data[2]

    @property
    def edge_corners(self) -> np.ndarray:
        """Corners whose half-edge is the edge, grouped edge by edge."""
        return self._edge_data[3]

    @cached_property
    def edge_face_count(self) -> np.ndarray:
        """Number of faces using each edge."""
        return np.diff(self.edge_corner_offsets)

    def edge_faces(self, e: int) -> np.ndarray:
        """Faces using edge ``e``."""
        o = self.edge_corner_offsets
        return self.corner_face[self.edge_corners[o[e]:o[e + 1]]]

    @cached_property
    def boundary_edge_mask(self) -> np.ndarray:
        """True for edges used by exactly one face."""
        return self.edge_face_count == 1

    @cached_property
    def boundary_edges(self) -> np.ndarray:
        return self.edges[self.boundary_edge_mask]

    @cached_property
    def nonmanifold_edge_mask(self) -> np.ndarray:
        """True for edges used by more than two faces."""
        return self.edge_face_count > 2

    @cached_property
    def boundary_vertex_mask(self) -> np.ndarray:
        """True for vertices on a boundary edge."""
        m = np.zeros(self.n_vertices, dtype=bool)
        m[self.boundary_edges.reshape(-1)] = True
        return m

    @cached_property
    def boundary_vertices(self) -> np.ndarray:
        return np.flatnonzero(self.boundary_vertex_mask)

    @cached_property
    def vertex_edge_count(self) -> np.ndarray:
        """Number of edges incident to each vertex."""
        return np.bincount(self.edges.reshape(-1), minlength=self.n_vertices)

    @cached_property
    def vertex_corner_count(self) -> np.ndarray:
        """Number of face corners at each vertex (= incident faces)."""
        return np.bincount(self.face_indices, minlength=self.n_vertices)

    @cached_property
    def inconsistent_edge_mask(self) -> np.ndarray:
        """Two-face edges whose faces traverse it in the same direction."""
        two = np.flatnonzero(self.edge_face_count == 2)
        c0 = self.edge_corners[self.edge_corner_offsets[two]]
        c1 = self.edge_corners[self.edge_corner_offsets[two] + 1]
        fi = self.face_indices
        same = fi[c0] == fi[c1]  # both half-edges start at the same vertex
        m = np.zeros(self.n_edges, dtype=bool)
        m[two[same]] = True
        return m

    @cached_property
    def boundary_loop_count(self) -> int:
        """Number of connected chains of boundary edges."""
        be = self.boundary_edges
        if be.size == 0:
            return 0
        return component_count(be, self.n_vertices, only=np.unique(be))

    @cached_property
    def vertex_components(self) -> tuple[int, np.ndarray]:
        """(count, label per vertex) of connected components over edges (isolated vertices count)."""
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components

        e = self.edges
        n = self.n_vertices
        g = coo_matrix((np.ones(e.shape[0], dtype=np.int8), (e[:, 0], e[:, 1])), shape=(n, n))
        return connected_components(g, directed=False)

    @cached_property
    def euler_characteristic(self) -> int:
        """V - E + F, counting referenced vertices only."""
        nref = int(np.count_nonzero(self.vertex_corner_count))
        return nref - self.n_edges + self.n_faces


def component_count(edges: np.ndarray, n: int, only: np.ndarray) -> int:
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    g = coo_matrix((np.ones(edges.shape[0], dtype=np.int8), (edges[:, 0], edges[:, 1])), shape=(n, n))
    _, labels = connected_components(g, directed=False)
    return int(np.unique(labels[only]).size)


@dataclass
class Diagnostics:
    """Legal but suspicious properties of a mesh (reported, never rejected)."""

    nonmanifold_edges: int = 0
    nonmanifold_vertices: int = 0
    unreferenced_vertices: int = 0
    duplicate_faces: int = 0
    zero_area_faces: int = 0
    inconsistent_orientation_edges: int = 0
    examples: dict = field(default_factory=dict)

    def warnings(self) -> list[str]:
        out = []
        labels = {
            "nonmanifold_edges": "non-manifold edges (used by 3+ faces)",
            "nonmanifold_vertices": "non-manifold vertices (more than one fan of faces)",
            "unreferenced_vertices": "unreferenced vertices",
            "duplicate_faces": "duplicate faces (same vertex set as an earlier face)",
            "zero_area_faces": "zero-area faces",
            "inconsistent_orientation_edges": "edges with inconsistent face orientation",
        }
        for key, text in labels.items():
            count = getattr(self, key)
            if count:
                ex = self.examples.get(key)
                extra = f", e.g. {ex}" if ex is not None else ""
                out.append(f"{count} {text}{extra}")
        return out


def duplicate_faces(t: Topology) -> np.ndarray:
    """Faces whose vertex set equals an earlier face's."""
    sizes = t.face_sizes
    dups = []
    for s in np.unique(sizes):
        same_size = np.flatnonzero(sizes == s)
        block = np.sort(t.face_indices[t.face_offsets[same_size][:, None] + np.arange(s)], axis=1)
        _, first = np.unique(block, axis=0, return_index=True)
        is_first = np.zeros(same_size.size, dtype=bool)
        is_first[first] = True
        dups.append(same_size[~is_first])
    return np.sort(np.concatenate(dups)) if dups else np.zeros(0, np.int64)


def nonmanifold_vertices(t: Topology) -> np.ndarray:
    """Vertices whose incident faces form more than one edge-connected fan.

    Counted as: number of incident faces minus the number of interior
    (two-face) edges at the vertex must be 0 (closed fan) or 1 (open fan);
    anything more means several fans meeting at one vertex.
    """
    two = t.edge_face_count == 2
    n_int = np.bincount(t.edges[two].reshape(-1), minlength=t.n_vertices)
    fans = t.vertex_corner_count - n_int
    bad = fans > 1
    # vertices touching non-manifold edges are reported with the edges
    bad[t.edges[t.nonmanifold_edge_mask].reshape(-1)] = False
    return np.flatnonzero(bad)
