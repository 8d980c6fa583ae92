"""Vertex normals, and the normal attributes kept in step with the positions."""

from __future__ import annotations

import numpy as np

from .measures import face_vector_areas, pow2_exponent

__all__ = ["vertex_normals", "NORMAL_ATTRIBUTES", "has_normals", "corner_normals", "refresh_normals"]


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


#: Vertex attributes that hold the surface normal (PLY's convention).  They are recomputed from
#: the surface whenever shapeflow moves the vertices, never carried over stale.
NORMAL_ATTRIBUTES = ("nx", "ny", "nz")


def has_normals(mesh) -> bool:
    """Whether the mesh carries normals (vertex attributes nx, ny, nz or the corner attribute "normal")."""
    return any(k in mesh.attributes for k in NORMAL_ATTRIBUTES) or "normal" in mesh.corner_attributes


def corner_normals(mesh, attr):
    """Split normals recomputed from the surface, keeping the file's splits (hard edges stay hard).

    For a table with per-corner indices (OBJ ``vn``), each entry becomes the unit sum of the vector
    areas of the faces whose corners use it; for plain per-corner values, each corner gets the
    area-weighted normal of its vertex.
    """
    from ..mesh.attributes import Indexed

    fa = face_vector_areas(mesh)
    t = mesh.topology
    if isinstance(attr, Indexed):
        per_corner = np.repeat(fa, t.face_sizes, axis=0)
        have = attr.index >= 0
        k = attr.values.shape[0]
        acc = np.stack([np.bincount(attr.index[have], per_corner[have, q], minlength=k) for q in range(3)], axis=1)
        ln = np.sqrt(np.einsum("ij,ij->i", acc, acc))
        keep = ln > 0
        out = np.array(attr.values, dtype=np.float64)
        out[keep] = acc[keep] / ln[keep, None]       # entries no corner uses keep their value
        return Indexed(out.astype(attr.values.dtype), attr.index)
    return vertex_normals(mesh)[t.face_indices].astype(np.asarray(attr).dtype)


def refresh_normals(mesh):
    """``mesh`` with its normals recomputed from its positions: the vertex attributes nx, ny, nz
    (each in its own type, unit area-weighted vertex normals, :func:`vertex_normals`) and the corner
    attribute ``"normal"`` (:func:`corner_normals`).  Returns the mesh unchanged when it has none.
    """
    out = mesh
    have = [k for k in NORMAL_ATTRIBUTES if k in mesh.attributes]
    if have:
        nrm = vertex_normals(mesh)
        out = out.with_attributes(**{k: nrm[:, NORMAL_ATTRIBUTES.index(k)].astype(mesh.attributes[k].dtype)
                                     for k in have})
    if "normal" in mesh.corner_attributes:
        out = out.with_corner_attributes(normal=corner_normals(mesh, mesh.corner_attributes["normal"]))
    return out
