"""STL, binary and ASCII.

STL stores separate triangles: each facet lists its own three vertices, so a file read as it is
is a triangle soup (the commands weld it for the operator, :func:`shapeflow.weld`, and write the
result back in the file's layout).  Kept: the facets in order, their 16-bit attribute words
(some tools store a colour there) as the face attribute ``"stl_attribute"``, and the solid's name
(``mesh.metadata["stl"]["name"]``); facet normals are recomputed from the surface on writing.
Quads and n-gons are written as fans of triangles, and attributes STL has no place for are named
in a :class:`~shapeflow.errors.DataLossWarning`.

The format is a fixed 50-byte record per facet (binary) or a keyword grammar (ASCII): both are
read with NumPy in bulk (a structured array; the ASCII tokens through the text tokeniser).
"""

from __future__ import annotations

import warnings
from typing import BinaryIO

import numpy as np

from ..errors import DataLossWarning, MeshError
from ..geometry.measures import face_vector_areas, fan_triangles
from ..mesh import Mesh
from .text import Text, ranges, strip_bom

__all__ = ["read_stl", "write_stl", "RECORD"]

#: one binary facet: normal, three vertices, attribute byte count
RECORD = np.dtype([("normal", "<f4", (3,)), ("v", "<f4", (3, 3)), ("attr", "<u2")])


def _is_binary(data: bytes) -> bool:
    if len(data) < 84:
        return False
    count = int(np.frombuffer(data, "<u4", 1, 80)[0])
    return len(data) == 84 + 50 * count


def read_stl(data: bytes, name: str) -> Mesh:
    if _is_binary(data):
        count = int(np.frombuffer(data, "<u4", 1, 80)[0])
        rec = np.frombuffer(data, RECORD, count, 84)
        V = rec["v"].reshape(-1, 3).astype(np.float64)
        attr = rec["attr"].copy()
        header = data[:80].split(b"\0", 1)[0].decode("latin-1").strip()
        meta = {"header": header} if header else {}
        face = {"stl_attribute": attr} if attr.any() else {}
    else:
        V, meta = _read_ascii(data, name)
        face = {}
    if not np.isfinite(V).all():
        f = int(np.flatnonzero(~np.isfinite(V).all(axis=1))[0]) // 3
        raise MeshError(f"{name}: facet {f} has a non-finite vertex")
    m = V.shape[0] // 3
    try:
        return Mesh.from_csr(V, np.full(m, 3), np.arange(3 * m), face_attributes=face,
                             metadata={"stl": meta})   # also marks the file as STL (z up)
    except MeshError as exc:
        raise MeshError(f"{name}: {exc}") from None


def _read_ascii(data: bytes, name: str):
    data = strip_bom(data)
    if not data.lstrip().startswith(b"solid"):
        raise MeshError(f"{name}: not an STL file (neither 'solid' text nor a binary facet count that "
                        "matches the file size)")
    txt = Text(data, name)
    a = np.frombuffer(txt.data + b"        ", np.uint8)
    s, e = txt.start, txt.end
    word = lambda w: (e - s == len(w)) & np.logical_and.reduce([a[s + j] == c for j, c in enumerate(w)])  # noqa: E731
    vert = np.flatnonzero(word(b"vertex"))
    facet = np.flatnonzero(word(b"facet"))
    endfacet = np.flatnonzero(word(b"endfacet"))
    if facet.size != endfacet.size:
        raise MeshError(f"{name}: {facet.size} 'facet' but {endfacet.size} 'endfacet' keywords")
    per = np.searchsorted(vert, endfacet) - np.searchsorted(vert, facet)
    bad = np.flatnonzero(per != 3)
    if bad.size:
        raise txt.error(facet[int(bad[0])], f"facet has {int(per[bad[0]])} vertices; STL facets are triangles")
    if vert.size != 3 * facet.size:
        raise txt.error(vert[0] if vert.size else 0, "'vertex' outside a facet")
    V = txt.parse(ranges(vert + 1, np.full(vert.size, 3)), np.float64, "vertex coordinate").reshape(-1, 3)
    solid = np.flatnonzero(word(b"solid"))
    meta = {}
    if solid.size and solid[0] + 1 < (facet[0] if facet.size else s.size):
        first = int(solid[0]) + 1
        last = int(facet[0]) if facet.size else s.size
        meta["name"] = txt.data[int(s[first]):int(e[last - 1])].decode("utf-8", "replace")
    return V, meta


def _warn_losses(mesh: Mesh) -> None:
    lost = []
    ngons = int((mesh.face_sizes > 3).sum())
    if ngons:
        lost.append(f"{ngons} faces of 4+ corners (written as triangle fans)")
    lost += [f"vertex attribute '{k}'" for k in mesh.attributes]
    lost += [f"corner attribute '{k}'" for k in mesh.corner_attributes]
    lost += [f"face attribute '{k}'" for k in mesh.face_attributes if k != "stl_attribute"]
    if lost:
        warnings.warn(DataLossWarning("STL keeps triangles and positions only; not kept: " + ", ".join(lost)),
                      stacklevel=4)


def write_stl(f: BinaryIO, mesh: Mesh, *, binary: bool | None = None) -> None:
    _warn_losses(mesh)
    tris = fan_triangles(mesh)
    V = mesh.vertices
    normals = face_vector_areas(Mesh.from_csr(V, np.full(tris.shape[0], 3), tris.reshape(-1)))
    ln = np.linalg.norm(normals, axis=1)
    normals = np.divide(normals, ln[:, None], out=np.zeros_like(normals), where=ln[:, None] > 0)
    attr = mesh.face_attributes.get("stl_attribute")
    meta = mesh.metadata.get("stl", {})
    if binary is None or binary:
        rec = np.zeros(tris.shape[0], RECORD)
        rec["normal"] = normals
        rec["v"] = V[tris]
        if attr is not None and (mesh.face_sizes == 3).all():
            rec["attr"] = np.asarray(attr, np.uint16)
        head = (meta.get("header") or "binary STL written by shapeflow").encode("latin-1", "replace")[:80]
        f.write(head.ljust(80, b" "))
        f.write(np.uint32(tris.shape[0]).tobytes())
        f.write(rec.tobytes())
        return
    solid = meta.get("name", "shapeflow")
    f.write(f"solid {solid}\n".encode("utf-8"))
    rows = np.concatenate([normals, V[tris].reshape(-1, 9)], axis=1)
    fmt = ("facet normal %r %r %r\n outer loop\n  vertex %r %r %r\n  vertex %r %r %r\n  vertex %r %r %r\n"
           " endloop\nendfacet\n")
    for i in range(0, rows.shape[0], 16384):
        block = rows[i:i + 16384]
        f.write(((fmt * block.shape[0]) % tuple(block.ravel().tolist())).encode("ascii"))
    f.write(f"endsolid {solid}\n".encode("utf-8"))
