"""Meshes for other libraries: trimesh, pyvista, meshio, open3d (each imported on first use).

The other way round needs no function: every shapeflow call accepts those libraries' objects
directly (:func:`shapeflow.mesh.convert.as_mesh`), as do ``Mesh.from_trimesh`` and friends.
Quads and n-gons are kept where the target has them (pyvista, meshio); trimesh and open3d hold
triangles, so faces of 4+ corners become fans, and the :class:`~shapeflow.errors.DataLossWarning`
says so.  Per-vertex attributes travel as point data (pyvista, meshio) or vertex colours.

Examples
--------
>>> import shapeflow as sf
>>> spot = sf.load_example("spot")
>>> poly = sf.interop.to_pyvista(spot)            # doctest: +SKIP
>>> sf.flow(poly, -5.0).n_faces == spot.n_faces   # doctest: +SKIP
True
"""

from __future__ import annotations

import warnings

import numpy as np

from .errors import DataLossWarning, OptionalDependencyError
from .geometry.measures import fan_triangles
from .mesh import Mesh
from .mesh.convert import as_mesh

__all__ = ["to_trimesh", "to_pyvista", "to_meshio", "to_open3d", "as_mesh"]


def _need(module: str, extra: str):
    import importlib

    try:
        return importlib.import_module(module)
    except Exception as exc:   # not only a missing package: a broken one (a missing system library) too
        raise OptionalDependencyError(module.split(".")[0], extra, f"conversion to {module.split('.')[0]}",
                                      exc) from exc


def _triangles_only(mesh: Mesh, target: str) -> np.ndarray:
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
