"""Meshes for other libraries: trimesh, pyvista, meshio, open3d (each imported on first use).

The other way round needs no function: every shapeflow call accepts those libraries' objects
directly (:func:`shapeflow.mesh.convert.as_mesh`), as do ``Mesh.from_trimesh`` and friends.
Quads and n-gons are kept where the target has them (pyvista, meshio); trimesh and open3d hold
triangles, so faces of 4+ corners become fans, and the :class:`~shapeflow.errors.DataLossWarning`
says so.  Per-vertex attributes travel as point data (pyvista, meshio) or vertex colours.
The conversions live beside :func:`~shapeflow.mesh.convert.as_mesh` in :mod:`shapeflow.mesh.convert`,
where ``Mesh.to_trimesh()`` and friends call them; this module is their public face.

Examples
--------
>>> import shapeflow as sf
>>> spot = sf.load_example("spot")
>>> poly = sf.interop.to_pyvista(spot)            # doctest: +SKIP
>>> sf.flow(poly, -5.0).n_faces == spot.n_faces   # doctest: +SKIP
True
"""

from __future__ import annotations

from .mesh.convert import as_mesh, to_meshio, to_open3d, to_pyvista, to_trimesh

__all__ = ["to_trimesh", "to_pyvista", "to_meshio", "to_open3d", "as_mesh"]
