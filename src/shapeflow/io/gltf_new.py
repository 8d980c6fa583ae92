"""A new glTF document of one triangle mesh, for meshes that are not a read document with its faces."""

from __future__ import annotations

import json
import warnings

import numpy as np

from ..errors import DataLossWarning
from ..mesh import Mesh
from .float32 import as_float32

__all__ = ["new_document", "split_vertices", "fan_corners"]


def split_vertices(mesh: Mesh, corner: dict):
    """glTF attributes are per vertex: one glTF vertex per distinct (vertex, corner values) of the
    corners, so UV and normal seams split vertices as glTF expects.  Returns (source vertex of each
    glTF vertex, glTF vertex of each corner, the per-glTF-vertex values of each corner attribute)."""
    keys = [mesh.face_indices[:, None].astype(np.float64)] + [np.asarray(v, np.float64).reshape(mesh.n_corners, -1)
                                                              for v in corner.values()]
    table = np.concatenate(keys, axis=1)
    uniq, first, inverse = np.unique(table, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first)                          # glTF vertices in order of first use
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    corner_vertex = rank[inverse.reshape(-1)]
    src_corner = first[order]
    return (mesh.face_indices[src_corner], corner_vertex,
            {k: np.asarray(v, np.float64).reshape(mesh.n_corners, -1)[src_corner] for k, v in corner.items()})


def new_document(lib, mesh: Mesh) -> tuple[dict, list]:
    """A glTF document of one triangle mesh (quads and n-gons as fans), with TEXCOORD_0 and NORMAL
    from the corner attributes uv and normal (vertices split at their seams) and COLOR_0 from the
    vertex attribute color."""
    from ..mesh.attributes import expand

    corner = {k: expand(mesh.corner_attributes[k]) for k in ("uv", "normal") if k in mesh.corner_attributes}
    corner = {k: v for k, v in corner.items() if np.isfinite(v).all()}
    color = mesh.attributes.get("color")
    lost = [f"vertex attribute '{k}'" for k in mesh.attributes if k != "color"]
    lost += [f"corner attribute '{k}'" for k in mesh.corner_attributes if k not in corner]
    lost += [f"face attribute '{k}'" for k in mesh.face_attributes]
    if (mesh.face_sizes > 3).any():
        lost.append(f"{int((mesh.face_sizes > 3).sum())} faces of 4+ corners (written as triangle fans)")
    if lost:
        warnings.warn(DataLossWarning("a new glTF document holds triangles, positions, UVs, normals and colours; "
                                      "not kept: " + ", ".join(lost)), stacklevel=5)
    src, corner_vertex, values = split_vertices(mesh, corner)
    tris = corner_vertex[fan_corners(mesh)].astype("<u4")
    arrays = [("POSITION", as_float32(mesh.vertices[src], "glTF"), "VEC3")]
    if "normal" in values:
        n = values["normal"]
        ln = np.linalg.norm(n, axis=1, keepdims=True)
        arrays.append(("NORMAL", np.ascontiguousarray(np.divide(n, ln, out=np.zeros_like(n), where=ln > 0), "<f4"),
                       "VEC3"))
    if "uv" in values:
        arrays.append(("TEXCOORD_0", np.ascontiguousarray(values["uv"][:, :2], "<f4"), "VEC2"))
    if color is not None and color.ndim == 2 and color.shape[1] in (3, 4):
        c = np.asarray(color, np.float64)[src]
        arrays.append(("COLOR_0", np.ascontiguousarray(np.clip(c / 255.0 if c.max() > 1 else c, 0, 1), "<f4"),
                       "VEC3" if c.shape[1] == 3 else "VEC4"))
    blob, views, accessors, offset = b"", [], [], 0
    for k, (name, arr, kind) in enumerate(arrays + [("indices", tris.reshape(-1), "SCALAR")]):
        views.append(lib.BufferView(buffer=0, byteOffset=offset, byteLength=arr.nbytes,
                                    target=34963 if name == "indices" else 34962))
        acc = lib.Accessor(bufferView=k, componentType=5125 if name == "indices" else 5126,
                           count=arr.shape[0], type=kind)
        if name == "POSITION":
            acc.min, acc.max = arr.min(axis=0).tolist(), arr.max(axis=0).tolist()
        accessors.append(acc)
        blob += arr.tobytes()
        offset += arr.nbytes
    attributes = lib.Attributes(**{name: k for k, (name, _, _) in enumerate(arrays)})
    gltf = lib.GLTF2(
        scene=0, scenes=[lib.Scene(nodes=[0])], nodes=[lib.Node(mesh=0)],
        meshes=[lib.Mesh(primitives=[lib.Primitive(attributes=attributes, indices=len(arrays))])],
        accessors=accessors, bufferViews=views, buffers=[lib.Buffer(byteLength=len(blob))])
    return json.loads(gltf.to_json()), [bytearray(blob)]


def fan_corners(mesh: Mesh) -> np.ndarray:
    """(T, 3) corner indices of the fan triangles (as :func:`fan_triangles` lists their vertices)."""
    t = mesh.topology
    first = np.repeat(t.face_offsets[:-1], t.face_sizes)
    k = np.arange(t.n_corners)
    use = (k != first) & (t.corner_next != first)
    return np.stack([first[use], k[use], t.corner_next[use]], axis=1)
