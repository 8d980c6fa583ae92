"""The hybrid polygon mesh type.

A :class:`Mesh` holds vertex positions ``vertices`` (n, 3) float64 and its faces
in CSR form: ``face_indices`` lists every face corner in loop order, face after
face, and ``face_offsets`` (m + 1) says where each face starts (the layout of
Blender loops, VTK cells and libigl's ``I, C`` polygon arrays).  Triangles,
quads and n-gons mix freely; nothing is ever padded or triangulated.

Meshes are immutable: arrays are read-only, and derived topology (corner
neighbours, unique edges, edge -> faces, boundary...) is computed on first use,
vectorised, cached, and shared by every mesh made with :meth:`Mesh.with_vertices`.

Accepted face inputs (only at this boundary, through :func:`normalize_faces`):
a list of lists (ragged), an (m, k) integer array (k >= 3), or a CSR pair via
:meth:`Mesh.from_csr`.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from functools import cached_property
from typing import Iterable, Mapping

import numpy as np

from . import kernels
from .errors import MeshError

__all__ = ["Mesh", "Topology", "Diagnostics", "normalize_faces", "WEIGHT"]

#: Name of the per-vertex weight attribute (values in [0, 1]).
WEIGHT = "weight"


# --------------------------------------------------------------------------
# normalisation and validation (the only place face layouts are accepted)
# --------------------------------------------------------------------------

def _as_vertices(vertices) -> np.ndarray:
    try:
        v = np.asarray(vertices)
    except Exception as exc:  # ragged input etc.
        raise MeshError(f"vertices are not an (n, 3) array of numbers: {exc}") from None
    if v.dtype == object or not (np.issubdtype(v.dtype, np.number) or v.dtype == bool):
        raise MeshError(f"vertices must be numbers, got dtype {v.dtype}")
    if np.iscomplexobj(v):
        raise MeshError("vertices must be real numbers, got complex values")
    if v.ndim != 2 or v.shape[1] != 3:
        raise MeshError(f"vertices must have shape (n, 3), got {v.shape}")
    v = np.array(v, dtype=np.float64, order="C", copy=True)
    if np.isfinite(v).all():    # one flat pass; the per-vertex detail only for the message
        return v
    bad = ~np.isfinite(v).all(axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise MeshError(
            f"vertex {i} has a non-finite coordinate {v[i].tolist()} "
            f"({int(bad.sum())} such vertices)"
        )
    return v


def _as_index_array(a, what: str) -> np.ndarray:
    arr = np.asarray(a)
    if arr.size == 0:
        return np.zeros(0, dtype=np.int64)
    if arr.dtype == object or not np.issubdtype(arr.dtype, np.integer):
        if np.issubdtype(arr.dtype, np.floating) and np.all(np.isfinite(arr)) and np.all(arr == np.round(arr)):
            return arr.astype(np.int64).reshape(-1)
        raise MeshError(f"{what} must be integers, got dtype {arr.dtype}")
    return arr.astype(np.int64, copy=False).reshape(-1)


def normalize_faces(faces) -> tuple[np.ndarray, np.ndarray]:
    """Turn any accepted face layout into ``(face_indices, face_offsets)``.

    Accepts a list (or tuple) of index sequences of any lengths, or an (m, k)
    integer array.  Structural checks (face sizes, index range, repeated
    vertices) are done by :class:`Mesh`, which knows the vertex count.
    """
    if isinstance(faces, np.ndarray) and faces.dtype != object:
        if faces.ndim != 2:
            if faces.size == 0:
                return np.zeros(0, np.int64), np.zeros(1, np.int64)
            raise MeshError(
                f"a face array must have shape (m, k) with k >= 3, got {faces.shape}; "
                "use a list of lists or Mesh.from_csr for mixed face sizes"
            )
        m, k = faces.shape
        if m and k < 3:
            raise MeshError(f"a face array must have shape (m, k) with k >= 3, got {faces.shape}")
        idx = _as_index_array(faces, "face indices")
        return idx, np.arange(m + 1, dtype=np.int64) * k
    try:
        seq = list(faces)
    except TypeError:
        raise MeshError(f"faces must be a list of index lists or an (m, k) array, got {type(faces).__name__}") from None
    sizes = np.empty(len(seq), dtype=np.int64)
    try:
        for i, f in enumerate(seq):
            sizes[i] = len(f)
    except TypeError:
        raise MeshError(f"face {i} is not a sequence of vertex indices: {f!r}") from None
    flat = list(itertools.chain.from_iterable(seq))
    idx = _as_index_array(flat, "face indices")
    offsets = np.zeros(len(seq) + 1, dtype=np.int64)
    np.cumsum(sizes, out=offsets[1:])
    return idx, offsets


def _validate_csr(indices: np.ndarray, offsets: np.ndarray, n: int) -> None:
    if offsets.ndim != 1 or offsets.size < 1 or offsets[0] != 0 or offsets[-1] != indices.size:
        raise MeshError(
            f"face offsets must start at 0 and end at the number of corners ({indices.size}); "
            f"got {offsets.size} offsets"
        )
    K = kernels.get(n)
    if K is not None and K.first_bad_face(indices, offsets, n) < 0:
        return   # one compiled pass found nothing; otherwise the checks below say what is wrong
    sizes = np.diff(offsets)
    small = np.flatnonzero(sizes < 3)
    if small.size:
        f = int(small[0])
        raise MeshError(f"face {f} has {int(sizes[f])} corners; a face needs at least 3 ({small.size} such faces)")
    if indices.size and (indices.min() < 0 or indices.max() >= n):
        bad = np.flatnonzero((indices < 0) | (indices >= n))
        c = int(bad[0])
        f = int(np.searchsorted(offsets, c, side="right") - 1)
        raise MeshError(
            f"face {f} refers to vertex {int(indices[c])}, out of range [0, {n}) "
            f"({bad.size} such corners)"
        )
    # a vertex repeated inside one face: sort each face's corners, per face size
    for s in np.unique(sizes):
        faces_s = np.flatnonzero(sizes == s)
        block = indices[offsets[faces_s][:, None] + np.arange(s)]
        block.sort(axis=1)
        rep = (block[:, 1:] == block[:, :-1]).any(axis=1)
        if rep.any():
            f = int(faces_s[np.flatnonzero(rep)[0]])
            corners = indices[offsets[f]:offsets[f + 1]].tolist()
            raise MeshError(f"face {f} repeats a vertex: {corners}")


def _as_attribute(name: str, values, n: int) -> np.ndarray:
    """A copy of ``values`` as an attribute: integer and float32 arrays keep their type (a file's
    ``uchar`` colours stay ``uchar``), anything else becomes float64; weights are always float64."""
    try:
        a = np.array(values, copy=True)
        if a.dtype.kind not in "iufbO":   # strings, bytes, complex...: not real numbers
            raise TypeError
        if a.dtype.kind == "O" and any(isinstance(v, (str, bytes, complex)) for v in a.reshape(-1)):
            raise TypeError
        if name == WEIGHT or a.dtype.kind not in "iuf" or a.dtype.itemsize > 8:
            a = a.astype(np.float64)
        elif not a.dtype.isnative:
            a = a.astype(a.dtype.newbyteorder("="))
    except (TypeError, ValueError, OverflowError):
        raise MeshError(f"attribute '{name}' must be real numbers, got dtype {np.asarray(values).dtype}") from None
    if a.ndim == 0 or a.shape[0] != n:
        raise MeshError(f"attribute '{name}' must have one value per vertex ({n}), got shape {a.shape}")
    if not np.isfinite(a).all():
        i = int(np.flatnonzero(~np.isfinite(a.reshape(n, -1)).all(axis=1))[0])
        raise MeshError(f"attribute '{name}' has a non-finite value at vertex {i}")
    if name == WEIGHT:
        if a.ndim != 1:
            raise MeshError(f"weights must have shape ({n},), got {a.shape}")
        out = np.flatnonzero((a < 0) | (a > 1))
        if out.size:
            i = int(out[0])
            raise MeshError(f"weights must lie in [0, 1]; vertex {i} has {float(a[i])!r} ({out.size} such vertices)")
    a.flags.writeable = False
    return a


# --------------------------------------------------------------------------
# topology
# --------------------------------------------------------------------------

class Topology:
    """Derived connectivity of a face layout, computed lazily and cached.

    Corners are numbered as in ``face_indices``.  The half-edge of corner k
    goes from its vertex to the vertex of the next corner of the same face.
    """

    def __init__(self, face_indices: np.ndarray, face_offsets: np.ndarray, n_vertices: int):
        self.face_indices = face_indices
        self.face_offsets = face_offsets
        self.n_vertices = int(n_vertices)

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
    @cached_property
    def _edge_data(self):
        fi = self.face_indices
        K = kernels.get(self.n_vertices)
        if K is not None:
            return K.edge_data(fi, self.face_offsets, self.n_vertices)
        a = fi
        b = fi[self.corner_next]
        lo = np.minimum(a, b)
        hi = np.maximum(a, b)
        key = lo * np.int64(self.n_vertices) + hi
        order = np.argsort(key, kind="stable")
        sk = key[order]
        new = np.empty(sk.size, dtype=bool)
        if sk.size:
            new[0] = True
            np.not_equal(sk[1:], sk[:-1], out=new[1:])
        eid_sorted = np.cumsum(new) - 1
        corner_edge = np.empty(sk.size, dtype=np.int64)
        corner_edge[order] = eid_sorted
        starts = np.flatnonzero(new)
        first = order[starts]
        edges = np.stack([lo[first], hi[first]], axis=1)
        offsets = np.append(starts, sk.size).astype(np.int64)
        return edges, corner_edge, offsets, order

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
        return _component_count(be, self.n_vertices, only=np.unique(be))

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


def _component_count(edges: np.ndarray, n: int, only: np.ndarray) -> int:
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    g = coo_matrix((np.ones(edges.shape[0], dtype=np.int8), (edges[:, 0], edges[:, 1])), shape=(n, n))
    _, labels = connected_components(g, directed=False)
    return int(np.unique(labels[only]).size)


# --------------------------------------------------------------------------
# diagnostics: legal but suspicious
# --------------------------------------------------------------------------

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


# --------------------------------------------------------------------------
# the mesh
# --------------------------------------------------------------------------

class Mesh:
    """An immutable hybrid polygon mesh (triangles, quads and n-gons).

    Parameters
    ----------
    vertices : array_like, shape (n, 3)
        Vertex positions (stored as float64).
    faces : list of index lists, or (m, k) integer array
        Faces, each listed by its corners in loop order.  Use
        :meth:`from_csr` for the flat CSR layout.
    weights : array_like, shape (n,), optional
        Per-vertex weights in [0, 1] (stored as the ``"weight"`` attribute).
    attributes : mapping of name -> array with n rows, optional
        Other per-vertex attributes: integer and float32 arrays keep their type, anything else
        becomes float64.

    Raises
    ------
    MeshError
        Wrong shapes, non-finite coordinates, indices out of range, faces with
        fewer than 3 corners, a vertex repeated inside one face, weights
        outside [0, 1].

    Examples
    --------
    >>> import shapeflow as sf
    >>> m = sf.Mesh([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0, 0]],
    ...             [[0, 1, 2, 3], [1, 4, 2]])
    >>> m.face_sizes.tolist()
    [4, 3]
    """

    __slots__ = ("_vertices", "_topology", "_attributes", "__dict__")

    @kernels.with_small_pages
    def __init__(self, vertices, faces, *, weights=None, attributes: Mapping | None = None,
                 _csr: tuple[np.ndarray, np.ndarray] | None = None,
                 _topology: Topology | None = None):
        v = _as_vertices(vertices)
        v.flags.writeable = False
        self._vertices = v
        n = v.shape[0]
        if _topology is not None:
            if _topology.n_vertices != n:
                raise MeshError(f"expected {_topology.n_vertices} vertices for this topology, got {n}")
            self._topology = _topology
        else:
            if _csr is not None:
                indices, offsets = _csr
            else:
                indices, offsets = normalize_faces(faces)
            _validate_csr(indices, offsets, n)
            indices = np.ascontiguousarray(indices, dtype=np.int64)
            offsets = np.ascontiguousarray(offsets, dtype=np.int64)
            indices.flags.writeable = False
            offsets.flags.writeable = False
            self._topology = Topology(indices, offsets, n)
        attrs = {}
        for name, values in (attributes or {}).items():
            attrs[str(name)] = _as_attribute(str(name), values, n)
        if weights is not None:
            attrs[WEIGHT] = _as_attribute(WEIGHT, weights, n)
        self._attributes = attrs

    # --- construction ----------------------------------------------------
    @classmethod
    def from_csr(cls, vertices, face_sizes, face_indices, **kw) -> "Mesh":
        """Build from flat arrays: ``face_sizes`` (m,) and ``face_indices`` (Σ sizes,).

        This is the layout of Blender loops and of the fixtures
        (``face_sizes``, ``face_indices`` in ``*.npz``).
        """
        sizes = _as_index_array(face_sizes, "face sizes")
        idx = _as_index_array(face_indices, "face indices")
        if (sizes < 0).any():
            f = int(np.flatnonzero(sizes < 0)[0])
            raise MeshError(f"face {f} has a negative size {int(sizes[f])}")
        offsets = np.zeros(sizes.size + 1, dtype=np.int64)
        np.cumsum(sizes, out=offsets[1:])
        if offsets[-1] != idx.size:
            raise MeshError(
                f"face sizes add up to {int(offsets[-1])} corners but {idx.size} face indices were given"
            )
        return cls(vertices, None, _csr=(idx, offsets), **kw)

    def with_vertices(self, vertices, *, attributes: Mapping | None = None, keep_attributes: bool = True) -> "Mesh":
        """A mesh with the same faces (and shared cached topology), new positions."""
        attrs = dict(self._attributes) if keep_attributes else {}
        if attributes:
            attrs.update(attributes)
        return Mesh(vertices, None, attributes=attrs, _topology=self._topology)

    def _with_own_vertices(self, V: np.ndarray) -> "Mesh":
        """``with_vertices(V)`` for an array the caller hands over (not copied).

        For library code that made ``V`` itself: float64 (n, 3) C-contiguous,
        not referenced elsewhere.  Falls back to the validating constructor
        if it is anything else or holds a non-finite value.
        """
        if (V.dtype != np.float64 or V.ndim != 2 or V.shape != self._vertices.shape
                or not V.flags.c_contiguous or not V.flags.owndata or not np.isfinite(V).all()):
            return self.with_vertices(V)
        out = Mesh.__new__(Mesh)
        V.flags.writeable = False
        out._vertices = V
        out._topology = self._topology
        out._attributes = dict(self._attributes)
        return out

    def with_attributes(self, **attributes) -> "Mesh":
        """A mesh with extra or replaced per-vertex attributes (``None`` removes one)."""
        attrs = dict(self._attributes)
        for k, val in attributes.items():
            if val is None:
                attrs.pop(k, None)
            else:
                attrs[k] = val
        return Mesh(self._vertices, None, attributes=attrs, _topology=self._topology)

    def with_weights(self, weights) -> "Mesh":
        """A mesh with the given vertex weights (``None`` removes them)."""
        return self.with_attributes(**{WEIGHT: weights})

    # --- data ------------------------------------------------------------
    @property
    def vertices(self) -> np.ndarray:
        """(n, 3) float64 positions (read-only)."""
        return self._vertices

    @property
    def topology(self) -> Topology:
        return self._topology

    @property
    def face_indices(self) -> np.ndarray:
        """Every face corner's vertex, in loop order, face after face."""
        return self._topology.face_indices

    @property
    def face_offsets(self) -> np.ndarray:
        """(m + 1,) start of each face in :attr:`face_indices`."""
        return self._topology.face_offsets

    @property
    def face_sizes(self) -> np.ndarray:
        """(m,) number of corners of each face."""
        return self._topology.face_sizes

    @property
    def n_vertices(self) -> int:
        return self._vertices.shape[0]

    @property
    def n_faces(self) -> int:
        return self._topology.n_faces

    @property
    def n_corners(self) -> int:
        return self._topology.n_corners

    @property
    def attributes(self) -> Mapping[str, np.ndarray]:
        """Per-vertex attributes (read-only view)."""
        from types import MappingProxyType

        return MappingProxyType(self._attributes)

    @property
    def weights(self) -> np.ndarray | None:
        """Per-vertex weights in [0, 1], or None."""
        return self._attributes.get(WEIGHT)

    def face(self, f: int) -> np.ndarray:
        """Vertex indices of face ``f`` in loop order."""
        if not -self.n_faces <= f < self.n_faces:
            raise IndexError(f"face {f} out of range [0, {self.n_faces})")
        f %= self.n_faces
        o = self.face_offsets
        return self.face_indices[o[f]:o[f + 1]]

    def faces_as_lists(self) -> list[list[int]]:
        """Faces as a list of Python lists (slow for big meshes; for interop)."""
        idx = self.face_indices.tolist()
        o = self.face_offsets.tolist()
        return [idx[o[i]:o[i + 1]] for i in range(self.n_faces)]

    def faces_as_array(self) -> np.ndarray:
        """Faces as an (m, k) array; only when every face has k corners."""
        s = self.face_sizes
        if s.size and (s != s[0]).any():
            raise MeshError(f"faces have mixed sizes {np.unique(s).tolist()}; use face_indices/face_offsets")
        k = int(s[0]) if s.size else 3
        return self.face_indices.reshape(-1, k)

    # --- geometry summaries ------------------------------------------------
    @property
    def bounding_box(self) -> tuple[np.ndarray, np.ndarray]:
        if self.n_vertices == 0:
            z = np.zeros(3)
            return z, z
        return self._vertices.min(axis=0), self._vertices.max(axis=0)

    @property
    def diagonal(self) -> float:
        """Length of the bounding-box diagonal."""
        lo, hi = self.bounding_box
        return float(np.linalg.norm(hi - lo))

    def face_count_by_size(self) -> dict[int, int]:
        sizes, counts = np.unique(self.face_sizes, return_counts=True)
        return {int(s): int(c) for s, c in zip(sizes, counts)}

    def diagnostics(self, *, rel_area_tol: float = 1e-12) -> Diagnostics:
        """Report legal but suspicious properties (see :class:`Diagnostics`)."""
        from .geometry import face_vector_areas

        t = self._topology
        d = Diagnostics()
        nm = np.flatnonzero(t.nonmanifold_edge_mask)
        d.nonmanifold_edges = int(nm.size)
        if nm.size:
            d.examples["nonmanifold_edges"] = t.edges[nm[0]].tolist()
        nmv = _nonmanifold_vertices(t)
        d.nonmanifold_vertices = int(nmv.size)
        if nmv.size:
            d.examples["nonmanifold_vertices"] = int(nmv[0])
        unref = np.flatnonzero(t.vertex_corner_count == 0)
        d.unreferenced_vertices = int(unref.size)
        if unref.size:
            d.examples["unreferenced_vertices"] = int(unref[0])
        dup = _duplicate_faces(t)
        d.duplicate_faces = int(dup.size)
        if dup.size:
            d.examples["duplicate_faces"] = int(dup[0])
        if self.n_faces:
            area = np.linalg.norm(face_vector_areas(self), axis=1)
            tol = rel_area_tol * max(self.diagonal, np.finfo(float).tiny) ** 2
            z = np.flatnonzero(area <= tol)
            d.zero_area_faces = int(z.size)
            if z.size:
                d.examples["zero_area_faces"] = int(z[0])
        inc = np.flatnonzero(t.inconsistent_edge_mask)
        d.inconsistent_orientation_edges = int(inc.size)
        if inc.size:
            d.examples["inconsistent_orientation_edges"] = t.edges[inc[0]].tolist()
        return d

    def __repr__(self) -> str:
        by = ", ".join(f"{c}×{s}" for s, c in self.face_count_by_size().items())
        attrs = f", attributes={list(self._attributes)}" if self._attributes else ""
        return f"Mesh(n_vertices={self.n_vertices}, n_faces={self.n_faces} [{by}]{attrs})"

    def __eq__(self, other) -> bool:  # structural equality, handy in tests
        if not isinstance(other, Mesh):
            return NotImplemented
        return (
            np.array_equal(self.vertices, other.vertices)
            and np.array_equal(self.face_indices, other.face_indices)
            and np.array_equal(self.face_offsets, other.face_offsets)
            and self._attributes.keys() == other._attributes.keys()
            and all(np.array_equal(self._attributes[k], other._attributes[k]) for k in self._attributes)
        )

    __hash__ = None  # mutable-looking container semantics: not hashable


def _duplicate_faces(t: Topology) -> np.ndarray:
    """Faces whose vertex set equals an earlier face's."""
    sizes = t.face_sizes
    dups = []
    for s in np.unique(sizes):
        fs = np.flatnonzero(sizes == s)
        block = np.sort(t.face_indices[t.face_offsets[fs][:, None] + np.arange(s)], axis=1)
        _, first = np.unique(block, axis=0, return_index=True)
        is_first = np.zeros(fs.size, dtype=bool)
        is_first[first] = True
        dups.append(fs[~is_first])
    return np.sort(np.concatenate(dups)) if dups else np.zeros(0, np.int64)


def _nonmanifold_vertices(t: Topology) -> np.ndarray:
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


def concatenate(meshes: Iterable[Mesh]) -> Mesh:
    """Join meshes into one (vertex and face numbering in order)."""
    meshes = list(meshes)
    if not meshes:
        raise MeshError("nothing to concatenate")
    vs, idx, sizes = [], [], []
    base = 0
    for m in meshes:
        vs.append(m.vertices)
        idx.append(m.face_indices + base)
        sizes.append(m.face_sizes)
        base += m.n_vertices
    return Mesh.from_csr(np.concatenate(vs), np.concatenate(sizes), np.concatenate(idx))
