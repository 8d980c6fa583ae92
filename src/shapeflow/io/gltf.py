"""glTF 2.0 (``.gltf`` with its buffers, ``.glb``).

Reading: every triangle primitive of every mesh becomes part of one :class:`~shapeflow.mesh.Mesh`
(the face attribute ``"primitive"`` says which), placed where the default scene shows it (the
world transform of the first node that shows the mesh: node matrices or translation, rotation and
scale, parents first; normals by the inverse transpose), with ``TEXCOORD_0`` as the corner attribute
``"uv"``, ``NORMAL`` as the corner attribute ``"normal"`` and ``COLOR_0`` as the vertex attribute
``"color"``.  Primitives that share a POSITION accessor and a placement share their vertices.
KHR_mesh_quantization's integer attributes are read; files that require another extension that
changes geometry (Draco, meshopt, GPU instancing) are refused by name.  glTF splits vertices at UV
and normal seams; the commands weld them for the operator (:func:`shapeflow.weld`) and write the
result in the file's layout.

Hostile files: the reader never reaches outside the file's own folder, never reads outside a
buffer and never walks a node twice (:mod:`~shapeflow.io.gltf_source`,
:mod:`~shapeflow.io.gltf_access`, :mod:`~shapeflow.io.gltf_scene` say how); every failure is a
:class:`~shapeflow.errors.MeshError` naming the file.  ``read_gltf(data, name,
external_files=False)`` (a file read on its own, e.g. uploaded) refuses every URI that is not
``data:``.  The reader needs NumPy only; pygltflib (the ``gltf`` extra) builds new documents.

Writing a mesh read from a glTF file with its faces unchanged (smoothing, enhancement, the
brush) writes the file back with new positions and normals only, in each mesh's own coordinates
again: materials, textures, nodes, animations and every other accessor pass through unchanged
(:mod:`~shapeflow.io.gltf_write` says how shared, quantized and interleaved accessors and several
buffers are written).  Any other mesh is written as a new single-mesh file, in world coordinates,
with float32 positions.
"""

from __future__ import annotations

import warnings
from typing import BinaryIO

import numpy as np

from ..errors import DataLossWarning, OptionalDependencyError
from ..mesh import Mesh
from .gltf_new import new_document
from .gltf_read import read_gltf
from .gltf_scene import mesh_placements
from .gltf_write import pack, write_back

__all__ = ["read_gltf", "write_gltf", "write_glb", "mesh_placements"]


def _lib():
    try:
        import pygltflib
    except Exception as exc:   # not installed, or installed and broken
        raise OptionalDependencyError("pygltflib", "gltf", "writing new glTF documents", exc) from exc
    return pygltflib


def write_glb(f: BinaryIO, mesh: Mesh, *, binary: bool | None = None) -> None:
    """GLB: the binary container (``binary=False`` writes glTF JSON with embedded buffers)."""
    write_gltf(f, mesh, binary=True if binary is None else binary)


def write_gltf(f: BinaryIO, mesh: Mesh, *, binary: bool | None = None) -> None:
    """glTF JSON with the buffers embedded as data URIs (``binary=True``: GLB)."""
    meta = mesh.metadata.get("gltf", {})
    same = ("document" in meta and "blocks" in meta and mesh.n_vertices == sum(b["vertices"] for b in meta["blocks"])
            and np.array_equal(meta.get("faces", np.zeros(0)), mesh.face_indices))
    if same:
        doc, blobs = write_back(meta, mesh)
    else:
        if "document" in meta:
            warnings.warn(DataLossWarning("the faces changed (subdivision?): the glTF scene, materials and textures "
                                          "of the input are not written, only this mesh"), stacklevel=4)
        doc, blobs = new_document(_lib(), mesh)
    f.write(pack(doc, blobs, bool(binary)))
