"""Meshes from and for the objects other libraries pass around.

From them, read by their attributes (no import of them): accepted by :func:`as_mesh` and so by
every public function that takes a mesh:

* trimesh ``Trimesh`` and anything with ``vertices`` and ``faces`` arrays (open3d's
  ``TriangleMesh`` has ``vertices`` and ``triangles``);
* pyvista ``PolyData`` (``points`` and its VTK polygons: quads and n-gons are kept);
* meshio ``Mesh`` (``points`` and ``cells``: every polygon block — triangle, quad, polygon —
  in block order; other cell types are skipped);
* a shapeflow :class:`~shapeflow.mesh.Mesh` (returned as it is).

Per-vertex data travel along where the source has a place for them (trimesh's vertex colours,
pyvista's point data, meshio's point data).

For them: :func:`to_trimesh`, :func:`to_pyvista`, :func:`to_meshio`, :func:`to_open3d` (each library
imported on first use; the public face is :mod:`shapeflow.interop`).  Quads and n-gons are kept where
the target has them (pyvista, meshio); trimesh and open3d hold triangles, so faces of 4+ corners
become fans, and a :class:`~shapeflow.errors.DataLossWarning` says so.
"""

from __future__ import annotations

import warnings

import numpy as np

from ..errors import DataLossWarning, OptionalDependencyError, ParameterError
from .core import Mesh

__all__ = ["as_mesh", "from_vtk_polys", "to_trimesh", "to_pyvista", "to_meshio", "to_open3d"]


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


# --- meshes for other libraries ---------------------------------------------------------------

def _need(module: str, extra: str):
    import importlib

    try:
        return importlib.import_module(module)
    except Exception as exc:   # not only a missing package: a broken one (a missing system library) too
        raise OptionalDependencyError(module.split(".")[0], extra, f"conversion to {module.split('.')[0]}",
                                      exc) from exc


def _triangles_only(mesh: Mesh, target: str) -> np.ndarray:
    from ..geometry.measures import fan_triangles  # an upward import (docs/architecture.md)

    big = int((mesh.face_sizes > 3).sum())
    if big:
        warnings.warn(DataLossWarning(f"{target} holds triangles: {big} faces of 4+ corners split into fans"),
                      stacklevel=3)
    return fan_triangles(mesh)


def to_trimesh(mesh) -> object:
    """A ``trimesh.Trimesh`` (triangles; vertex order kept, no merging or reordering)."""
    trimesh = _need("trimesh", "interop")
    mesh = as_mesh(mesh)
    tm = trimesh.Trimesh(vertices=mesh.vertices.copy(), faces=_triangles_only(mesh, "trimesh"), process=False)
    color = mesh.attributes.get("color")
    if color is not None and color.ndim == 2 and color.shape[1] in (3, 4):
        c = np.asarray(color, np.float64)
        tm.visual.vertex_colors = np.clip(np.rint(c * 255 if c.max() <= 1.0 else c), 0, 255).astype(np.uint8)
    return tm


def to_pyvista(mesh) -> object:
    """A ``pyvista.PolyData`` with the same polygons (quads and n-gons kept) and the vertex attributes
    as point data."""
    pv = _need("pyvista", "interop")
    mesh = as_mesh(mesh)
    sizes = mesh.face_sizes
    flat = np.empty(sizes.size + mesh.n_corners, np.int64)
    head = mesh.face_offsets[:-1] + np.arange(sizes.size)
    flat[head] = sizes
    keep = np.ones(flat.size, bool)
    keep[head] = False
    flat[keep] = mesh.face_indices
    poly = pv.PolyData(mesh.vertices.copy(), faces=flat)
    for k, v in mesh.attributes.items():
        poly.point_data[k] = np.asarray(v)
    return poly


def to_meshio(mesh) -> object:
    """A ``meshio.Mesh``: one cell block per face size (triangle, quad, polygon), in size order,
    and the vertex attributes as point data."""
    meshio = _need("meshio", "interop")
    mesh = as_mesh(mesh)
    cells = []
    for k in np.unique(mesh.face_sizes):
        faces = np.flatnonzero(mesh.face_sizes == k)
        block = mesh.face_indices[mesh.face_offsets[faces][:, None] + np.arange(k)]
        cells.append(({3: "triangle", 4: "quad"}.get(int(k), "polygon"), block))
    if (np.diff(mesh.face_sizes) < 0).any():
        warnings.warn(DataLossWarning("meshio groups faces by size: the face order is not kept"), stacklevel=2)
    return meshio.Mesh(mesh.vertices.copy(), cells, point_data={k: np.asarray(v) for k, v in mesh.attributes.items()})


def to_open3d(mesh) -> object:
    """An ``open3d.geometry.TriangleMesh`` (triangles; vertex colours when the mesh has ``color``)."""
    o3d = _need("open3d", "interop")
    mesh = as_mesh(mesh)
    out = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(mesh.vertices.copy()),
                                    o3d.utility.Vector3iVector(_triangles_only(mesh, "open3d").astype(np.int32)))
    color = mesh.attributes.get("color")
    if color is not None and color.ndim == 2 and color.shape[1] == 3:
        out.vertex_colors = o3d.utility.Vector3dVector(np.array(color, np.float64))   # a copy: open3d needs it writable
    return out
