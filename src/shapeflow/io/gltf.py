"""glTF 2.0 (``.gltf`` with its buffers, ``.glb``), through pygltflib (the ``gltf`` extra).

Reading: every triangle primitive of every mesh becomes part of one :class:`~shapeflow.mesh.Mesh`
(the face attribute ``"primitive"`` says which), placed where the default scene shows it (the
world transform of the first node that shows the mesh: node matrices or translation, rotation and
scale, parents first; normals by the inverse transpose), with ``TEXCOORD_0`` as the corner attribute
``"uv"``, ``NORMAL`` as the corner attribute ``"normal"`` and ``COLOR_0`` as the vertex attribute
``"color"``.  glTF splits vertices at UV and normal seams; the commands weld them for the
operator (:func:`shapeflow.weld`) and write the result in the file's layout.

Writing a mesh read from a glTF file with its faces unchanged (smoothing, enhancement, the
brush) writes the file back with new positions and normals only, in each mesh's own coordinates
again: materials, textures, nodes, animations and every other accessor pass through unchanged.
Any other mesh is written as a new single-mesh file, in world coordinates.  Positions are float32
in glTF.
"""

from __future__ import annotations

import copy
import warnings
from typing import BinaryIO

import numpy as np

from ..errors import DataLossWarning, MeshError, OptionalDependencyError
from ..geometry.placement import place, place_normals, unplace, unplace_normals
from ..mesh import Mesh

__all__ = ["read_gltf", "write_gltf", "write_glb", "mesh_placements"]

_COMPONENT = {5120: "i1", 5121: "u1", 5122: "i2", 5123: "u2", 5125: "u4", 5126: "f4"}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}
TRIANGLES = 4


def _lib():
    try:
        import pygltflib
    except Exception as exc:   # not installed, or installed and broken
        raise OptionalDependencyError("pygltflib", "gltf", "reading and writing glTF", exc) from exc
    return pygltflib


def _blob(gltf, buffer_index: int, name: str) -> bytes:
    buf = gltf.buffers[buffer_index]
    if buf.uri is None:
        data = gltf.binary_blob()
    else:
        data = gltf.get_data_from_buffer_uri(buf.uri)
    if data is None:
        raise MeshError(f"{name}: buffer {buffer_index} cannot be read")
    return data


def _accessor(gltf, index: int, name: str, blobs: dict) -> np.ndarray:
    acc = gltf.accessors[index]
    if acc.bufferView is None:
        return np.zeros((acc.count, _WIDTH[acc.type]), _COMPONENT[acc.componentType])
    view = gltf.bufferViews[acc.bufferView]
    if view.buffer not in blobs:
        blobs[view.buffer] = _blob(gltf, view.buffer, name)
    dt = np.dtype("<" + _COMPONENT[acc.componentType])
    width = _WIDTH[acc.type]
    stride = view.byteStride or dt.itemsize * width
    start = (view.byteOffset or 0) + (acc.byteOffset or 0)
    raw = np.frombuffer(blobs[view.buffer], np.uint8)
    need = start + stride * (acc.count - 1) + dt.itemsize * width if acc.count else start
    if need > raw.size:
        raise MeshError(f"{name}: accessor {index} runs past the end of its buffer")
    rows = np.lib.stride_tricks.as_strided(raw[start:], (acc.count, dt.itemsize * width), (stride, 1))
    out = np.ascontiguousarray(rows).view(dt).reshape(acc.count, width)
    if acc.normalized and dt.kind in "iu":
        out = out.astype(np.float64) / np.iinfo(dt).max
    return out


def _load(data: bytes, name: str):
    lib = _lib()
    try:
        if data[:4] == b"glTF":
            return lib.GLTF2.load_from_bytes(data)
        return lib.GLTF2.load(name)            # from its path: external buffers are resolved beside it
    except Exception as exc:  # pygltflib raises many kinds on a malformed file
        raise MeshError(f"{name}: not a readable glTF file ({type(exc).__name__}: {exc})") from None


def _node_matrix(node) -> np.ndarray:
    """A node's local transform (its ``matrix``, column-major, or T·R·S)."""
    if node.matrix is not None and len(node.matrix) == 16:
        return np.asarray(node.matrix, np.float64).reshape(4, 4).T
    M = np.eye(4)
    if node.scale is not None:
        M = np.diag([*np.asarray(node.scale, np.float64), 1.0])
    if node.rotation is not None:
        x, y, z, w = np.asarray(node.rotation, np.float64) / (np.linalg.norm(node.rotation) or 1.0)
        R = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                      [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                      [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
        M = np.block([[R, np.zeros((3, 1))], [np.zeros((1, 3)), np.ones((1, 1))]]) @ M
    if node.translation is not None:
        T = np.eye(4)
        T[:3, 3] = node.translation
        M = T @ M
    return M


def mesh_placements(gltf) -> tuple[dict, dict]:
    """World transform of the first node that shows each mesh in the default scene (depth first,
    parents before children), and how many nodes show it.  Meshes no node shows are absent."""
    first: dict = {}
    count: dict = {}
    nodes = gltf.nodes or []
    scene = (gltf.scenes or [None])[gltf.scene or 0] if gltf.scenes else None
    roots = list(scene.nodes or []) if scene is not None else list(range(len(nodes)))
    stack = [(r, np.eye(4), 0) for r in reversed(roots)]
    while stack:                       # over the nodes of the scene graph (a few), never vertices
        i, parent, depth = stack.pop()
        if not 0 <= i < len(nodes) or depth > len(nodes):
            continue                   # a bad index or a cycle: that branch is not followed
        M = parent @ _node_matrix(nodes[i])
        if nodes[i].mesh is not None:
            first.setdefault(nodes[i].mesh, M)
            count[nodes[i].mesh] = count.get(nodes[i].mesh, 0) + 1
        stack.extend((c, M, depth + 1) for c in reversed(nodes[i].children or []))
    return first, count


def read_gltf(data: bytes, name: str) -> Mesh:
    gltf = _load(data, name)
    blobs: dict = {}
    placement, shown = mesh_placements(gltf)
    V, F, S, uv, nrm, col, prim, skipped = [], [], [], [], [], [], [], 0
    base = 0
    layout = []
    for mi, mesh in enumerate(gltf.meshes or []):
        for pi, p in enumerate(mesh.primitives):
            if (p.mode if p.mode is not None else TRIANGLES) != TRIANGLES or p.attributes.POSITION is None:
                skipped += 1
                continue
            M = placement.get(mi, np.eye(4))
            if abs(np.linalg.det(M[:3, :3])) < 1e-300:
                raise MeshError(f"{name}: mesh {mi} is shown by a node whose transform is singular (scale 0)")
            pos = place(_accessor(gltf, p.attributes.POSITION, name, blobs).astype(np.float64), M)
            n = pos.shape[0]
            idx = (_accessor(gltf, p.indices, name, blobs).reshape(-1).astype(np.int64) if p.indices is not None
                   else np.arange(n))
            if idx.size % 3 or (idx.size and (idx.min() < 0 or idx.max() >= n)):
                raise MeshError(f"{name}: mesh {mi} primitive {pi}: indices are not triangles of its vertices")
            V.append(pos)
            F.append(idx + base)
            S.append(np.full(idx.size // 3, 3))
            prim.append(np.full(idx.size // 3, len(layout)))
            per_corner = lambda a: a[idx]   # noqa: E731  (glTF attributes are per vertex: per corner here)
            uv.append(per_corner(_accessor(gltf, p.attributes.TEXCOORD_0, name, blobs))
                      if p.attributes.TEXCOORD_0 is not None else None)
            nrm.append(place_normals(per_corner(_accessor(gltf, p.attributes.NORMAL, name, blobs)), M)
                       if p.attributes.NORMAL is not None else None)
            col.append(_accessor(gltf, p.attributes.COLOR_0, name, blobs) if p.attributes.COLOR_0 is not None
                       else None)
            layout.append({"mesh": mi, "primitive": pi, "vertices": n, "position": p.attributes.POSITION,
                           "normal": p.attributes.NORMAL, "matrix": M})
            base += n
    if not V:
        raise MeshError(f"{name}: no triangle mesh in the glTF file")
    repeated = sorted(m for m, k in shown.items() if k > 1)
    if repeated:
        warnings.warn(DataLossWarning(f"{name}: mesh(es) {repeated} are shown by several nodes; each is read "
                                      "once, placed by its first node (written back, every instance changes alike)"),
                      stacklevel=3)
    if skipped:
        warnings.warn(DataLossWarning(f"{name}: {skipped} primitive(s) that are not triangles are not kept"),
                      stacklevel=3)
    corner, attrs = {}, {}
    if all(u is not None for u in uv):
        corner["uv"] = np.concatenate(uv).astype(np.float64)
    if all(x is not None for x in nrm):
        corner["normal"] = np.concatenate(nrm).astype(np.float64)
    if all(c is not None for c in col):
        attrs["color"] = np.concatenate([c[:, :3] if c.shape[1] >= 3 else c for c in col]).astype(np.float64)
    face = {"primitive": np.concatenate(prim)} if len(layout) > 1 else {}
    try:
        return Mesh.from_csr(np.concatenate(V), np.concatenate(S), np.concatenate(F), attributes=attrs,
                             corner_attributes=corner, face_attributes=face,
                             metadata={"gltf": {"document": gltf, "layout": layout, "faces": np.concatenate(F)}})
    except MeshError as exc:
        raise MeshError(f"{name}: {exc}") from None


def write_glb(f: BinaryIO, mesh: Mesh, *, binary: bool | None = None) -> None:
    """GLB: the binary container (``binary=False`` writes glTF JSON with embedded buffers)."""
    write_gltf(f, mesh, binary=True if binary is None else binary)


def write_gltf(f: BinaryIO, mesh: Mesh, *, binary: bool | None = None) -> None:
    """glTF JSON with the buffers embedded as data URIs (``binary=True``: GLB)."""
    lib = _lib()
    meta = mesh.metadata.get("gltf", {})
    same = "document" in meta and np.array_equal(meta.get("faces", np.zeros(0)), mesh.face_indices)
    if same:
        gltf = copy.deepcopy(meta["document"])
        blob = bytearray(_single_blob(gltf))
        _update(gltf, blob, meta["layout"], mesh)
    else:
        if "document" in meta:
            warnings.warn(DataLossWarning("the faces changed (subdivision?): the glTF scene, materials and textures "
                                          "of the input are not written, only this mesh"), stacklevel=4)
        gltf, blob = _new_document(lib, mesh)
    gltf.set_binary_blob(bytes(blob))
    if binary:
        f.write(b"".join(gltf.save_to_bytes()))
    else:
        gltf.convert_buffers(lib.BufferFormat.DATAURI)
        f.write(gltf.to_json().encode("utf-8"))


def _single_blob(gltf) -> bytes:
    if len(gltf.buffers) != 1:
        raise MeshError("glTF files with several buffers are written back only as new documents")
    return gltf.binary_blob() if gltf.buffers[0].uri is None else gltf.get_data_from_buffer_uri(gltf.buffers[0].uri)


def _write_accessor(gltf, blob: bytearray, index: int, values: np.ndarray) -> None:
    acc = gltf.accessors[index]
    view = gltf.bufferViews[acc.bufferView]
    start = (view.byteOffset or 0) + (acc.byteOffset or 0)
    vals = np.ascontiguousarray(values, "<f4")
    stride = view.byteStride or vals.shape[1] * 4
    out = np.frombuffer(blob, np.uint8)
    for k in range(vals.shape[1]):   # a column at a time (strided layouts too)
        at = start + stride * np.arange(vals.shape[0]) + 4 * k
        out[at[:, None] + np.arange(4)] = np.ascontiguousarray(vals[:, k]).view(np.uint8).reshape(-1, 4)
    acc.min = vals.min(axis=0).astype(float).tolist()
    acc.max = vals.max(axis=0).astype(float).tolist()


def _update(gltf, blob: bytearray, layout: list, mesh: Mesh) -> None:
    """New positions (and normals: per-vertex from the new surface) into the input's accessors."""
    from ..geometry.normals import vertex_normals

    nrm = vertex_normals(mesh)
    base = 0
    for item in layout:
        n = item["vertices"]
        M = np.asarray(item.get("matrix", np.eye(4)))    # back into the mesh's own coordinates
        _write_accessor(gltf, blob, item["position"], unplace(mesh.vertices[base:base + n], M))
        if item["normal"] is not None:
            _write_accessor(gltf, blob, item["normal"], unplace_normals(nrm[base:base + n], M))
        base += n
    gltf.buffers[0].uri = None
    gltf.buffers[0].byteLength = len(blob)


def _split_vertices(mesh: Mesh, corner: dict):
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


def _new_document(lib, mesh: Mesh):
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
    src, corner_vertex, values = _split_vertices(mesh, corner)
    tris = corner_vertex[_fan_corners(mesh)].astype("<u4")
    arrays = [("POSITION", np.ascontiguousarray(mesh.vertices[src], "<f4"), "VEC3")]
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
    return gltf, bytearray(blob)


def _fan_corners(mesh: Mesh) -> np.ndarray:
    """(T, 3) corner indices of the fan triangles (as :func:`fan_triangles` lists their vertices)."""
    t = mesh.topology
    first = np.repeat(t.face_offsets[:-1], t.face_sizes)
    k = np.arange(t.n_corners)
    use = (k != first) & (t.corner_next != first)
    return np.stack([first[use], k[use], t.corner_next[use]], axis=1)
