"""Vertex normals, and the normal attributes kept in step with the positions."""

from __future__ import annotations

import numpy as np

from .measures import face_vector_areas, pow2_exponent

__all__ = ["vertex_normals", "NORMAL_ATTRIBUTES", "refresh_normals"]


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
