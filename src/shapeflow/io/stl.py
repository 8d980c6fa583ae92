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

Which one: a file of exactly 84 + 50·n bytes, n the count at byte 80, is binary even when its
header begins with "solid" (many exporters write that); other text beginning with "solid" and
without NUL bytes is ASCII, checked line by line against the grammar (keywords in any case; the
first line that does not fit is named); anything else is binary: missing facets are an error
naming the sizes, bytes after the declared facets are ignored as numpy-stl ignores them and named
in a DataLossWarning.  A file with no facets is an error.
"""

from __future__ import annotations

import warnings
from typing import BinaryIO

import numpy as np

from ..errors import DataLossWarning, MeshError
from ..geometry.measures import face_vector_areas, fan_triangles, pow2_exponent
from ..mesh import Mesh
from .float32 import as_float32
from .text import Text, ranges, strip_bom

__all__ = ["read_stl", "write_stl", "RECORD"]

#: one binary facet: normal, three vertices, attribute byte count
RECORD = np.dtype([("normal", "<f4", (3,)), ("v", "<f4", (3, 3)), ("attr", "<u2")])


def _looks_ascii(data: bytes) -> bool:
    """ASCII STL: starts with 'solid' (after a byte-order mark and blanks) and holds no NUL byte
    (binary facets nearly always do: a zero attribute word, a coordinate 0.0)."""
    return strip_bom(data).lstrip()[:5].lower() == b"solid" and b"\0" not in data


def _binary_count(data: bytes, name: str) -> int | None:
    """The facet count of a binary STL, or None if the data is ASCII STL.

    A file of exactly 84 + 50·n bytes, n its facet count, is binary whatever its header says
    (many exporters begin the header with "solid").  Otherwise text beginning with "solid" is
    ASCII; anything else is binary and must hold its n facets: extra bytes after them are ignored
    (as numpy-stl does) and named in a DataLossWarning, missing ones are an error."""
    if len(data) >= 84:
        count = int(np.frombuffer(data, "<u4", 1, 80)[0])
        if len(data) == 84 + 50 * count:
            return count
    if _looks_ascii(data):
        return None
    if len(data) < 84 or b"\0" not in data:
        sizes = (f"{len(data)} bytes, less than a binary header" if len(data) < 84 else
                 f"as binary its header's {count} facets need {84 + 50 * count} bytes, it has {len(data)}")
        raise MeshError(f"{name}: not an STL file: neither text beginning with 'solid' nor binary STL ({sizes})")
    want = 84 + 50 * count
    if len(data) < want:
        raise MeshError(f"{name}: binary STL is truncated: its header declares {count} facets "
                        f"(84 + 50 × {count} = {want} bytes) but the file has {len(data)} bytes")
    warnings.warn(DataLossWarning(f"{name}: {len(data) - want} bytes after the {count} facets the binary STL "
                                  f"header declares (84 + 50 × {count} = {want} bytes) are ignored"), stacklevel=4)
    return count


def read_stl(data: bytes, name: str) -> Mesh:
    count = _binary_count(data, name)
    if count is not None:
        if count == 0:
            raise MeshError(f"{name}: binary STL with no facets (its header declares 0)")
        rec = np.frombuffer(data, RECORD, count, 84)
        V = rec["v"].reshape(-1, 3).astype(np.float64)
        attr = rec["attr"].copy()
        header = data[:80].split(b"\0", 1)[0].decode("latin-1").strip()
        meta = {"header": header} if header else {}
        face = {"stl_attribute": attr} if attr.any() else {}
        bad = np.flatnonzero(~np.isfinite(V).all(axis=1))
        if bad.size:
            raise MeshError(f"{name}: facet {int(bad[0]) // 3} has a non-finite vertex")
    else:
        V, meta = _read_ascii(data, name)
        face = {}
    m = V.shape[0] // 3
    try:
        return Mesh.from_csr(V, np.full(m, 3), np.arange(3 * m), face_attributes=face,
                             metadata={"stl": meta})   # also marks the file as STL (z up)
    except MeshError as exc:
        raise MeshError(f"{name}: {exc}") from None


#: the ASCII grammar, one keyword line each: (first word, second word or None, tokens on the line)
_LINES = {b"facet": (b"normal", 5), b"outer": (b"loop", 2), b"vertex": (None, 4), b"endloop": (None, 1),
          b"endfacet": (None, 1)}
_FACET = [b"facet", b"outer", b"vertex", b"vertex", b"vertex", b"endloop", b"endfacet"]


def _read_ascii(data: bytes, name: str):
    """Facets of an ASCII STL: every line is checked against the grammar (keywords in any case)
    and the first one that does not fit is named."""
    txt = Text(strip_bom(data), name)
    if txt.n_records == 0:
        raise MeshError(f"{name}: empty file")
    a = np.frombuffer(txt.data.lower() + b"        ", np.uint8)
    s, e = txt.start, txt.end
    first = txt.rec_first

    def word(toks, w):
        hit = (e[toks] - s[toks]) == len(w)
        for j, ch in enumerate(w):
            hit &= a[s[toks] + j] == ch
        return hit

    keys = [b"solid", b"endsolid", *_LINES]
    kind = np.full(first.size, -1)
    for k, w in enumerate(keys):
        kind[word(first, w)] = k
    unknown = np.flatnonzero(kind < 0)
    if unknown.size:
        r = int(unknown[0])
        raise txt.error(first[r], f"{txt.token(first[r])} is not an ASCII STL keyword (solid, facet normal, "
                        "outer loop, vertex, endloop, endfacet, endsolid)")
    for k, (w, (second, n)) in enumerate(_LINES.items(), start=2):
        rows = np.flatnonzero(kind == k)
        bad = rows[txt.rec_count[rows] != n]
        if second is not None and bad.size == 0:
            bad = rows[~word(first[rows] + 1, second)]
        if bad.size:
            r = int(bad[0])
            form = f"'{w.decode()}{' ' + second.decode() if second else ''}'" + (
                " and three numbers" if n > 2 else "")
            raise txt.error(first[r], f"malformed '{w.decode()}' line: expected {form}")
    body = np.flatnonzero(kind >= 2)          # facet lines: the solid lines may come only between facets
    pattern = np.array([keys.index(w) for w in _FACET])
    pos = np.arange(body.size) % 7
    wrong = np.flatnonzero(kind[body] != pattern[pos])
    if wrong.size:
        r = int(body[wrong[0]])
        want = _FACET[int(pos[wrong[0]])].decode()
        raise txt.error(first[r], f"expected '{want}' here, found {txt.token(first[r])}")
    if body.size % 7:
        raise txt.error_at_end(f"file ends inside a facet (after '{_FACET[body.size % 7 - 1].decode()}')")
    solid_at = np.flatnonzero(kind < 2)
    inside = solid_at[(np.searchsorted(body, solid_at) % 7) != 0]
    if inside.size:
        raise txt.error(first[int(inside[0])], f"{txt.token(first[int(inside[0])])} inside a facet")
    depth = np.cumsum(np.where(kind[solid_at] == 0, 1, -1))
    unbalanced = np.flatnonzero((depth < 0) | (depth > 1))
    if unbalanced.size:
        r = int(solid_at[unbalanced[0]])
        raise txt.error(first[r], f"{txt.token(first[r])} without its "
                        f"{'endsolid' if kind[r] == 0 else 'solid'}")
    if depth[-1] != 0:
        raise txt.error_at_end("file ends without 'endsolid' (truncated?)")
    if body.size == 0:
        raise txt.error(first[0], "ASCII STL with no facets")
    normals = first[kind == keys.index(b"facet")] + 2
    txt.parse(ranges(normals, np.full(normals.size, 3)), np.float64, "facet normal component")
    vert = first[kind == keys.index(b"vertex")] + 1
    V = txt.parse(ranges(vert, np.full(vert.size, 3)), np.float64, "vertex coordinate").reshape(-1, 3)
    bad = np.flatnonzero(~np.isfinite(V).all(axis=1))
    if bad.size:
        raise txt.error(vert[int(bad[0])], "vertex coordinate is not finite")
    meta = {}
    if txt.rec_count[0] > 1:      # the solid's name: the rest of its line
        meta["name"] = txt.data[int(s[first[0] + 1]):int(e[first[0] + txt.rec_count[0] - 1])].decode("utf-8",
                                                                                                       "replace")
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
    as_float32(V, "STL")
    k = pow2_exponent(V)       # normals are scale-free: areas of extreme coordinates on an exact copy
    normals = face_vector_areas(Mesh.from_csr(np.ldexp(V, -k) if k else V, np.full(tris.shape[0], 3),
                                              tris.reshape(-1)))
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
