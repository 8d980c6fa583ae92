"""Meshes from the objects other libraries pass around, read by their attributes (no import of them).

Accepted by :func:`as_mesh` and so by every public function that takes a mesh:

* trimesh ``Trimesh`` and anything with ``vertices`` and ``faces`` arrays (open3d's
  ``TriangleMesh`` has ``vertices`` and ``triangles``);
* pyvista ``PolyData`` (``points`` and its VTK polygons: quads and n-gons are kept);
* meshio ``Mesh`` (``points`` and ``cells``: every polygon block — triangle, quad, polygon —
  in block order; other cell types are skipped);
* a shapeflow :class:`~shapeflow.mesh.Mesh` (returned as it is).

Per-vertex data travel along where the source has a place for them (trimesh's vertex colours,
pyvista's point data, meshio's point data).
"""

from __future__ import annotations

import numpy as np

from ..errors import ParameterError
from .core import Mesh

__all__ = ["as_mesh", "from_vtk_polys"]


def from_vtk_polys(points, polys) -> Mesh:
    """A mesh from VTK polygons (a ``vtkCellArray``: offsets and connectivity)."""
    from vtkmodules.util.numpy_support import vtk_to_numpy

    offsets = vtk_to_numpy(polys.GetOffsetsArray()).astype(np.int64)
    conn = vtk_to_numpy(polys.GetConnectivityArray()).astype(np.int64)
    return Mesh.from_csr(np.asarray(points, np.float64), np.diff(offsets), conn)


def _point_data(obj, n: int) -> dict:
    out = {}
    data = getattr(obj, "point_data", None)
    if data is None:
        return out
    for k in list(data.keys()):
        v = np.asarray(data[k])
        if v.shape[:1] == (n,) and v.dtype.kind in "iuf" and k not in ("Normals",):
            out[str(k)] = v
    return out


def as_mesh(obj: object, what: str = "mesh") -> Mesh:
    """``obj`` as a shapeflow Mesh (see the module docstring for what is accepted)."""
    if isinstance(obj, Mesh):
        return obj
    if hasattr(obj, "GetPolys") and hasattr(obj, "points"):                 # pyvista PolyData
        pts = np.asarray(obj.points, np.float64)
        return Mesh.from_csr(pts, *_csr_of(from_vtk_polys(pts, obj.GetPolys())),
                             attributes=_point_data(obj, pts.shape[0]))
    if hasattr(obj, "points") and hasattr(obj, "cells"):                    # meshio
        pts = np.asarray(obj.points, np.float64)
        if pts.ndim == 2 and pts.shape[1] == 2:
            pts = np.column_stack([pts, np.zeros(pts.shape[0])])
        sizes, idx = [], []
        for block in obj.cells:
            data = block.data
            if block.type in ("triangle", "quad") or block.type.startswith("polygon"):
                d = np.asarray(data, np.int64)
                sizes.append(np.full(d.shape[0], d.shape[1]))
                idx.append(d.reshape(-1))
        if not sizes:
            raise ParameterError(f"{what}: the meshio mesh has no triangle, quad or polygon cells")
        return Mesh.from_csr(pts, np.concatenate(sizes), np.concatenate(idx),
                             attributes=_point_data(obj, pts.shape[0]))
    verts = getattr(obj, "vertices", None)
    faces = getattr(obj, "faces", None)
    if faces is None:
        faces = getattr(obj, "triangles", None)                             # open3d
    if verts is not None and faces is not None:
        V = np.asarray(verts, np.float64)
        F = faces if isinstance(faces, (list, tuple)) else np.asarray(faces, np.int64)   # ragged lists allowed
        attrs = {}
        colors = getattr(getattr(obj, "visual", None), "vertex_colors", None)   # trimesh
        if colors is not None and np.asarray(colors).shape[:1] == (V.shape[0],):
            attrs["color"] = np.asarray(colors)[:, :3]
        vc = getattr(obj, "vertex_colors", None)                                # open3d
        if vc is not None and not attrs and np.asarray(vc).shape == V.shape:
            attrs["color"] = np.asarray(vc, np.float64)
        return Mesh(V, F, attributes=attrs)
    raise ParameterError(f"{what} must be a shapeflow.Mesh or an object with vertices and faces (trimesh, "
                         f"open3d), points and faces (pyvista) or points and cells (meshio); "
                         f"got {type(obj).__name__}")


def _csr_of(mesh: Mesh):
    return mesh.face_sizes, mesh.face_indices
