"""The hybrid polygon mesh type.

A :class:`Mesh` holds vertex positions ``vertices`` (n, 3) float64 and its faces
in CSR form: ``face_indices`` lists every face corner in loop order, face after
face, and ``face_offsets`` (m + 1) says where each face starts (the layout of
Blender loops, VTK cells and libigl's ``I, C`` polygon arrays).  Triangles,
quads and n-gons mix freely; nothing is ever padded or triangulated.

Meshes are immutable: arrays are read-only, and derived topology (corner
neighbours, unique edges, edge -> faces, boundary...) is computed on first use,
vectorised, cached, and shared by every mesh made with :meth:`Mesh.with_vertices`.
"""

from __future__ import annotations

from types import MappingProxyType
from typing import Iterable, Mapping

import numpy as np

from .. import accel
from ..errors import MeshError
from ..types import ArrayLike, Faces
from .attributes import as_corner_attribute, as_face_attribute
from .topology import Diagnostics, Topology, duplicate_faces, nonmanifold_vertices
from .validate import WEIGHT, as_attribute, as_index_array, as_vertices, normalize_faces, validate_csr

__all__ = ["Mesh", "concatenate"]


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
    corner_attributes : mapping of name -> (c, ...) array or :class:`~shapeflow.mesh.attributes.Indexed`, optional
        One value per face corner (``face_indices`` order): texture coordinates (``"uv"``), split
        normals (``"normal"``).
    face_attributes : mapping of name -> (m, ...) array or :class:`~shapeflow.mesh.attributes.Labels`, optional
        One value per face: numbers, or names (``"material"``, ``"group"``, ``"object"``, ``"smooth"``).
    metadata : mapping, optional
        File-level data kept for writing back (``mtllib`` lines, comments, PLY ``obj_info``...).

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

    __slots__ = ("_vertices", "_topology", "_attributes", "_corner", "_face", "_meta", "__dict__")

    @accel.heavy
    def __init__(self, vertices: ArrayLike, faces: Faces, *, weights: ArrayLike | None = None,
                 attributes: Mapping | None = None, corner_attributes: Mapping | None = None,
                 face_attributes: Mapping | None = None, metadata: Mapping | None = None,
                 _csr: tuple[np.ndarray, np.ndarray] | None = None,
                 _topology: Topology | None = None):
        v = as_vertices(vertices)
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
            validate_csr(indices, offsets, n)
            indices = np.ascontiguousarray(indices, dtype=np.int64)
            offsets = np.ascontiguousarray(offsets, dtype=np.int64)
            indices.flags.writeable = False
            offsets.flags.writeable = False
            self._topology = Topology(indices, offsets, n)
        attrs = {}
        for name, values in (attributes or {}).items():
            attrs[str(name)] = as_attribute(str(name), values, n)
        if weights is not None:
            attrs[WEIGHT] = as_attribute(WEIGHT, weights, n)
        self._attributes = attrs
        t = self._topology
        self._corner = {str(k): as_corner_attribute(str(k), v, t.n_corners)
                        for k, v in (corner_attributes or {}).items()}
        self._face = {str(k): as_face_attribute(str(k), v, t.n_faces) for k, v in (face_attributes or {}).items()}
        self._meta = dict(metadata or {})

    def __reduce__(self):
        """Pickled as its arrays and mappings; read back read-only, as built (a mesh read by a child
        process travels this way)."""
        return (_unpickle, (self._vertices, self._topology, self._attributes, self._corner, self._face, self._meta,
                            dict(self.__dict__)))

    # --- construction ----------------------------------------------------
    @classmethod
    def from_csr(cls, vertices, face_sizes, face_indices, **kw) -> "Mesh":
        """Build from flat arrays: ``face_sizes`` (m,) and ``face_indices`` (Σ sizes,).

        This is the layout of Blender loops and of the fixtures
        (``face_sizes``, ``face_indices`` in ``*.npz``).
        """
        sizes = as_index_array(face_sizes, "face sizes")
        idx = as_index_array(face_indices, "face indices")
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

    # --- other libraries' objects (shapeflow.mesh.convert, shapeflow.interop) -------------------------
    @classmethod
    def from_trimesh(cls, obj: object) -> "Mesh":
        """A mesh from a ``trimesh.Trimesh`` (vertex colours as the attribute ``color``)."""
        from .convert import as_mesh

        return as_mesh(obj)

    @classmethod
    def from_pyvista(cls, obj: object) -> "Mesh":
        """A mesh from a ``pyvista.PolyData`` (quads and n-gons kept; point data as attributes)."""
        from .convert import as_mesh

        return as_mesh(obj)

    @classmethod
    def from_meshio(cls, obj: object) -> "Mesh":
        """A mesh from a ``meshio.Mesh`` (triangle, quad and polygon blocks; point data as attributes)."""
        from .convert import as_mesh

        return as_mesh(obj)

    @classmethod
    def from_open3d(cls, obj: object) -> "Mesh":
        """A mesh from an ``open3d.geometry.TriangleMesh`` (vertex colours as ``color``)."""
        from .convert import as_mesh

        return as_mesh(obj)

    def to_trimesh(self) -> object:
        """:func:`shapeflow.interop.to_trimesh`."""
        from .convert import to_trimesh

        return to_trimesh(self)

    def to_pyvista(self) -> object:
        """:func:`shapeflow.interop.to_pyvista`."""
        from .convert import to_pyvista

        return to_pyvista(self)

    def to_meshio(self) -> object:
        """:func:`shapeflow.interop.to_meshio`."""
        from .convert import to_meshio

        return to_meshio(self)

    def to_open3d(self) -> object:
        """:func:`shapeflow.interop.to_open3d`."""
        from .convert import to_open3d

        return to_open3d(self)

    def with_vertices(self, vertices: ArrayLike, *, attributes: Mapping | None = None,
                      keep_attributes: bool = True) -> "Mesh":
        """A mesh with the same faces (and shared cached topology), new positions."""
        attrs = dict(self._attributes) if keep_attributes else {}
        if attributes:
            attrs.update(attributes)
        return Mesh(vertices, None, attributes=attrs, _topology=self._topology, **self._carried(keep_attributes))

    def _carried(self, keep: bool = True) -> dict:
        """The corner and face attributes and metadata, for a mesh with the same faces."""
        if not keep:
            return {}
        return dict(corner_attributes=self._corner, face_attributes=self._face, metadata=self._meta)

    def with_own_vertices(self, V: np.ndarray) -> "Mesh":
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
        out._corner, out._face, out._meta = dict(self._corner), dict(self._face), dict(self._meta)
        return out

    def with_attributes(self, **attributes) -> "Mesh":
        """A mesh with extra or replaced per-vertex attributes (``None`` removes one)."""
        attrs = dict(self._attributes)
        for k, val in attributes.items():
            if val is None:
                attrs.pop(k, None)
            else:
                attrs[k] = val
        return Mesh(self._vertices, None, attributes=attrs, _topology=self._topology, **self._carried())

    def with_corner_attributes(self, **attributes) -> "Mesh":
        """A mesh with extra or replaced corner attributes (``None`` removes one)."""
        return self._with("_corner", "corner_attributes", attributes)

    def with_face_attributes(self, **attributes) -> "Mesh":
        """A mesh with extra or replaced face attributes (``None`` removes one)."""
        return self._with("_face", "face_attributes", attributes)

    def with_metadata(self, **metadata) -> "Mesh":
        """A mesh with extra or replaced file-level data (``None`` removes an entry)."""
        return self._with("_meta", "metadata", metadata)

    def _with(self, slot: str, keyword: str, changes: dict) -> "Mesh":
        kept = self._carried()
        new = dict(getattr(self, slot))
        for k, val in changes.items():
            if val is None:
                new.pop(k, None)
            else:
                new[k] = val
        kept[keyword] = new
        return Mesh(self._vertices, None, attributes=self._attributes, _topology=self._topology, **kept)

    def with_weights(self, weights: ArrayLike | None) -> "Mesh":
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
        return MappingProxyType(self._attributes)

    @property
    def corner_attributes(self) -> Mapping[str, object]:
        """Per-corner attributes (read-only view): (c, ...) arrays or ``Indexed`` tables."""
        return MappingProxyType(self._corner)

    @property
    def face_attributes(self) -> Mapping[str, object]:
        """Per-face attributes (read-only view): (m, ...) arrays or ``Labels``."""
        return MappingProxyType(self._face)

    @property
    def metadata(self) -> Mapping[str, object]:
        """File-level data kept for writing back (read-only view)."""
        return MappingProxyType(self._meta)

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
        """Length of the bounding-box diagonal (inf only where it exceeds the largest double)."""
        lo, hi = self.bounding_box
        with np.errstate(over="ignore"):    # ±1e308 both signs: the diagonal is inf, not an error
            d = hi - lo
            return float(np.hypot(np.hypot(d[0], d[1]), d[2]))      # no square: 1e-300 .. 1e300 alike

    def face_count_by_size(self) -> dict[int, int]:
        sizes, counts = np.unique(self.face_sizes, return_counts=True)
        return {int(s): int(c) for s, c in zip(sizes, counts)}

    def diagnostics(self, *, rel_area_tol: float = 1e-12) -> Diagnostics:
        """Report legal but suspicious properties (see :class:`Diagnostics`)."""
        from ..geometry.measures import face_vector_areas, pow2_exponent  # the one upward import (architecture.md)

        t = self._topology
        d = Diagnostics()
        nm = np.flatnonzero(t.nonmanifold_edge_mask)
        d.nonmanifold_edges = int(nm.size)
        if nm.size:
            d.examples["nonmanifold_edges"] = t.edges[nm[0]].tolist()
        nmv = nonmanifold_vertices(t)
        d.nonmanifold_vertices = int(nmv.size)
        if nmv.size:
            d.examples["nonmanifold_vertices"] = int(nmv[0])
        unref = np.flatnonzero(t.vertex_corner_count == 0)
        d.unreferenced_vertices = int(unref.size)
        if unref.size:
            d.examples["unreferenced_vertices"] = int(unref[0])
        dup = duplicate_faces(t)
        d.duplicate_faces = int(dup.size)
        if dup.size:
            d.examples["duplicate_faces"] = int(dup[0])
        if self.n_faces:
            k = pow2_exponent(self._vertices)     # areas of extreme coordinates on an exact power-of-two copy
            V = np.ldexp(self._vertices, -k) if k else self._vertices
            area = np.linalg.norm(face_vector_areas(self, V), axis=1)
            ext = V.max(axis=0) - V.min(axis=0)
            tol = rel_area_tol * max(float(np.sqrt(ext @ ext)), np.finfo(float).tiny) ** 2
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
            and self._corner.keys() == other._corner.keys() and self._face.keys() == other._face.keys()
            and all(_same(self._corner[k], other._corner[k]) for k in self._corner)
            and all(_same(self._face[k], other._face[k]) for k in self._face)
        )

    __hash__ = None  # mutable-looking container semantics: not hashable


def _unpickle(vertices, topology, attributes, corner, face, meta, extra) -> Mesh:
    m = Mesh.__new__(Mesh)
    for a in (vertices, topology.face_indices, topology.face_offsets):
        a.flags.writeable = False
    m._vertices, m._topology, m._attributes, m._corner, m._face, m._meta = (
        vertices, topology, attributes, corner, face, meta)
    m.__dict__.update(extra)
    return m


def _same(a, b) -> bool:
    if isinstance(a, np.ndarray) and isinstance(b, np.ndarray):
        return np.array_equal(a, b)
    return a == b


def concatenate(meshes: Iterable[Mesh]) -> Mesh:
    """Join meshes into one (vertex and face numbering in order).

    Attributes every input has (per vertex, per corner, per face, with matching shapes) are joined
    too: ``Indexed`` tables are stacked with their indices shifted, ``Labels`` merge their names.
    Attributes only some inputs have are named in a :class:`~shapeflow.errors.DataLossWarning`.
    """
    import warnings

    from ..errors import DataLossWarning
    from .attributes import Indexed, Labels

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
    kinds = {"vertex": lambda m: m.attributes, "corner": lambda m: m.corner_attributes,
             "face": lambda m: m.face_attributes}
    joined, lost = {}, []
    for kind, get in kinds.items():
        names = dict.fromkeys(k for m in meshes for k in get(m))
        joined[kind] = {}
        for k in names:
            parts = [get(m).get(k) for m in meshes]
            try:
                joined[kind][k] = _join(parts, Indexed, Labels)
            except (TypeError, ValueError):
                lost.append(f"{kind} attribute '{k}'")
    if lost:
        warnings.warn(DataLossWarning("concatenate: not every mesh has (or shapes alike) " + ", ".join(lost)
                                      + "; not kept"), stacklevel=2)
    return Mesh.from_csr(np.concatenate(vs), np.concatenate(sizes), np.concatenate(idx),
                         attributes=joined["vertex"], corner_attributes=joined["corner"],
                         face_attributes=joined["face"])


def _join(parts: list, Indexed, Labels):
    """One attribute of several meshes joined; TypeError/ValueError when they cannot be."""
    if any(p is None for p in parts):
        raise TypeError("missing")
    if all(isinstance(p, Indexed) for p in parts):
        offs = np.cumsum([0] + [p.values.shape[0] for p in parts[:-1]])
        return Indexed(np.concatenate([p.values for p in parts]),
                       np.concatenate([np.where(p.index >= 0, p.index + o, -1) for p, o in zip(parts, offs)]))
    if all(isinstance(p, Labels) for p in parts):
        return Labels.from_values(np.concatenate([p.values() for p in parts]))
    if any(isinstance(p, (Indexed, Labels)) for p in parts):
        raise TypeError("mixed kinds")
    return np.concatenate([np.asarray(p) for p in parts])
