"""Writing Stanford PLY: every property in its type, face properties, texcoord and other lists.

A mesh read from a PLY file remembers each property's type and the file's order of properties
(``mesh.metadata["ply"]["types"]``): writing it back keeps both (``float`` coordinates stay
``float``, a ``double`` stays ``double``, ``uchar`` colours ``uchar``, the face list's count and
index types) whenever the values still fit the type; otherwise, and for a mesh from elsewhere,
the type follows the values (``double`` coordinates, ``int`` indices).  The list properties other
than the faces' corners and texture coordinates (``mesh.metadata["ply"]["lists"]``) are written
back as they were read while the vertices and faces are the input's; after subdivision they are
named in a :class:`~shapeflow.errors.DataLossWarning`.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from functools import lru_cache
from typing import BinaryIO

import numpy as np

from ..errors import DataLossWarning, MeshError
from ..mesh import Mesh
from .ply import OWN_COMMENT, PLY_TYPES, front_comment
from .text import write_rows

__all__ = ["write_ply"]


def _ply_attributes(mesh: Mesh) -> dict[str, np.ndarray]:
    """The vertex attributes as PLY properties: 1-D ones as they are, a (n, k) one as k properties
    (``color`` as red, green, blue[, alpha]; others as NAME_0 .. NAME_k-1)."""
    out = {}
    for key, values in mesh.attributes.items():
        if not key or any(ch.isspace() for ch in key) or not key.isascii() or key in ("x", "y", "z"):
            raise MeshError(f"attribute name {key!r} cannot be a PLY property name")
        if values.ndim == 1:
            out[key] = values
            continue
        cols = values.reshape(values.shape[0], -1)
        names = (["red", "green", "blue", "alpha"][:cols.shape[1]] if key == "color" and cols.shape[1] in (3, 4)
                 else [f"{key}_{i}" for i in range(cols.shape[1])])   # one property per column
        for i, nm in enumerate(names):
            out[nm] = cols[:, i]
    return out


#: NumPy type -> PLY type name: PLY_TYPES read backwards, the classic names (char, uchar, ...) winning
_PLY_NAMES = {code: name for name, code in reversed(list(PLY_TYPES.items()))}


def _ply_type(values: np.ndarray) -> np.dtype:
    dt = values.dtype
    if dt.kind in "iu" and dt.itemsize == 8:
        fits = values.size == 0 or (int(values.min()) >= -2**31 and int(values.max()) < 2**31)
        return np.dtype("i4") if fits else np.dtype("f8")
    key = f"{dt.kind}{dt.itemsize}"
    return np.dtype(key) if key in _PLY_NAMES else np.dtype("f8")


def _face_columns(mesh: Mesh):
    """What the face element carries besides the vertex list: numeric face attributes (one column
    each) and the corner attribute "uv" (a 'texcoord' list); what it cannot carry is named."""
    from ..mesh.attributes import Labels, expand

    scalars, lost = {}, []
    for k, v in mesh.face_attributes.items():
        if isinstance(v, Labels) or np.asarray(v).ndim != 1:
            lost.append(f"face attribute '{k}' (PLY face properties are numbers)")
        elif not k or any(ch.isspace() for ch in k) or not k.isascii() or k == "vertex_indices":
            lost.append(f"face attribute '{k}' (not a PLY property name)")
        else:
            scalars[k] = np.asarray(v)
    uv = mesh.corner_attributes.get("uv")
    uv = None if uv is None else np.asarray(expand(uv), dtype=np.float64)
    if uv is not None and (uv.ndim != 2 or uv.shape[1] != 2 or not np.isfinite(uv).all()):
        lost.append("corner attribute 'uv' (PLY texcoord lists hold two values for every corner)")
        uv = None
    lost += [f"corner attribute '{k}'" for k in mesh.corner_attributes if k != "uv"]
    return scalars, uv, lost


def _fits(values: np.ndarray, dt: np.dtype) -> bool:
    """Whether ``values`` are held exactly (integers) or in range (floats) by the type ``dt``."""
    v = np.asarray(values)
    if v.size == 0:
        return True
    if dt.kind in "iu":
        if v.dtype.kind == "f" and not (np.isfinite(v).all() and (v == np.rint(v)).all()):
            return False
        if v.dtype.kind not in "iuf":
            return False
        info = np.iinfo(dt)
        return bool(v.min() >= info.min and v.max() <= info.max)
    if dt.kind == "f" and dt.itemsize == 4 and v.dtype.kind == "f":
        finite = v[np.isfinite(v)]
        return bool(finite.size == 0 or np.abs(finite).max() <= np.finfo(np.float32).max)
    return dt.kind == "f"


def _type(values: np.ndarray, recorded, natural: np.dtype) -> np.dtype:
    """The recorded type when the values fit it, else the natural one."""
    if isinstance(recorded, str) and recorded in _PLY_NAMES and _fits(values, np.dtype(recorded)):
        return np.dtype(recorded)
    return natural


@dataclass
class _Field:
    """One property of an element: scalar values, or a list's counts and items."""

    name: str
    values: np.ndarray
    dtype: np.dtype
    counts: np.ndarray | None = None
    count_dtype: np.dtype | None = None

    def header(self) -> str:
        if self.counts is None:
            return f"property {_PLY_NAMES[self.dtype.str[1:]]} {self.name}"
        return f"property list {_PLY_NAMES[self.count_dtype.str[1:]]} {_PLY_NAMES[self.dtype.str[1:]]} {self.name}"


def _scalar(name: str, values, recorded, natural=None) -> _Field:
    values = np.asarray(values)
    dt = _type(values, recorded, natural if natural is not None else _ply_type(values))
    return _Field(name, values.astype(dt) if dt.kind in "iu" or dt.itemsize == 4 else values, dt)


def _list(name: str, counts, items, recorded, natural_item: np.dtype | None = None) -> _Field:
    counts, items = np.asarray(counts, np.int64), np.asarray(items)
    rc, ri = recorded if isinstance(recorded, tuple) else (None, None)
    cdt = _type(counts, rc, np.dtype("u1") if counts.size == 0 or counts.max() <= 255 else np.dtype("i4"))
    idt = _type(items, ri, natural_item if natural_item is not None else _ply_type(items))
    return _Field(name, items.astype(idt) if idt.kind in "iu" or idt.itemsize == 4 else items, idt,
                  counts.astype(cdt), cdt)


def _ordered(fields: list[_Field], recorded: dict) -> list[_Field]:
    """The file's order of properties for those it had, the others after them."""
    order = {k: i for i, k in enumerate(recorded)}
    return sorted(fields, key=lambda fl: order.get(fl.name, len(order)))


def _kept_lists(mesh: Mesh, meta: dict):
    """The input's extra list properties, {element: [(name, counts, items)]}, while its vertices and
    faces are this mesh's; otherwise none, and what is not written."""
    lists = meta.get("lists") or {}
    if not any(lists.values()):
        return {}, []
    n, idx = meta.get("lists_of", (None, None))
    if n == mesh.n_vertices and idx is not None and np.array_equal(idx, mesh.face_indices):
        return lists, []
    return {}, [f"{el} list '{k}' (its {el} numbering changed)" for el, d in lists.items() for k in d]


def write_ply(f: BinaryIO, mesh: Mesh, *, binary: bool | None = None, byteorder: str = "<") -> None:
    binary = True if binary is None else bool(binary)
    meta = mesh.metadata.get("ply", {})
    types = meta.get("types", {})
    vtypes, ftypes = types.get("vertex", {}), types.get("face", {})
    attrs = _ply_attributes(mesh)
    scalars, uv, lost = _face_columns(mesh)
    lists, lost_lists = _kept_lists(mesh, meta)
    if lost or lost_lists:
        warnings.warn(DataLossWarning("PLY cannot store: " + ", ".join(lost + lost_lists)), stacklevel=4)
    f8 = np.dtype("f8")
    vfields = [_scalar(a, mesh.vertices[:, i], vtypes.get(a), f8) for i, a in enumerate("xyz")]
    vfields += [_scalar(k, v, vtypes.get(k)) for k, v in attrs.items()]
    vfields += [_list(k, c, items, vtypes.get(k)) for k, (c, items) in lists.get("vertex", {}).items()]
    corners = next((k for k in ftypes if k in ("vertex_indices", "vertex_index")), "vertex_indices")
    ffields = [_list(corners, mesh.face_sizes, mesh.face_indices, ftypes.get(corners), np.dtype("i4"))]
    ffields += [_scalar(k, v, ftypes.get(k)) for k, v in scalars.items()]
    if uv is not None:
        tc = next((k for k in ftypes if k in ("texcoord", "texcoords")), "texcoord")
        ffields.append(_list(tc, 2 * mesh.face_sizes, uv.reshape(-1), ftypes.get(tc), np.dtype("f4")))
    ffields += [_list(k, c, items, ftypes.get(k)) for k, (c, items) in lists.get("face", {}).items()]
    vfields, ffields = _ordered(vfields, vtypes), _ordered(ffields, ftypes)
    fmt = ("binary_little_endian" if byteorder == "<" else "binary_big_endian") if binary else "ascii"
    head = ["ply", f"format {fmt} 1.0", f"comment {OWN_COMMENT}"]
    head += [f"comment {c}" for c in front_comment(mesh) + meta.get("comment", [])]
    head += [f"obj_info {c}" for c in meta.get("obj_info", [])]
    head += [f"element vertex {mesh.n_vertices}"] + [fl.header() for fl in vfields]
    head += [f"element face {mesh.n_faces}"] + [fl.header() for fl in ffields]
    f.write(("\n".join(head + ["end_header"]) + "\n").encode("utf-8"))
    for fields, n in ((vfields, mesh.n_vertices), (ffields, mesh.n_faces)):
        if binary:
            _write_binary(f, fields, n, byteorder)
        else:
            _write_ascii(f, fields, n)


def _write_binary(f: BinaryIO, fields: list[_Field], n: int, byteorder: str, chunk: int = 1 << 18) -> None:
    """An element's records: its properties in order, lists as their count then their items."""
    if all(fl.counts is None for fl in fields):     # fixed-size records: one structured array
        rec = np.empty(n, dtype=[(f"p{i}", fl.dtype.newbyteorder(byteorder)) for i, fl in enumerate(fields)])
        for i, fl in enumerate(fields):
            rec[f"p{i}"] = fl.values
        f.write(rec.tobytes())
        return
    starts = [None if fl.counts is None else np.concatenate([[0], np.cumsum(fl.counts, dtype=np.int64)])
              for fl in fields]

    def put(out, at, values, dt):
        raw = np.ascontiguousarray(values, dt.newbyteorder(byteorder)).view(np.uint8).reshape(-1, dt.itemsize)
        out[at[:, None] + np.arange(dt.itemsize)] = raw

    for r0 in range(0, n, chunk):
        r1 = min(r0 + chunk, n)
        size = np.zeros(r1 - r0, np.int64)
        for fl in fields:
            size += fl.dtype.itemsize if fl.counts is None else (
                fl.count_dtype.itemsize + fl.counts[r0:r1].astype(np.int64) * fl.dtype.itemsize)
        at = np.cumsum(size) - size
        out = np.empty(int(size.sum()), dtype=np.uint8)
        for fl, st in zip(fields, starts):
            if fl.counts is None:
                put(out, at, fl.values[r0:r1], fl.dtype)
                at = at + fl.dtype.itemsize
                continue
            c = fl.counts[r0:r1].astype(np.int64)
            put(out, at, c, fl.count_dtype)
            lo, hi = int(st[r0]), int(st[r1])
            local = np.arange(hi - lo) - np.repeat(st[r0:r1] - lo, c)
            put(out, np.repeat(at + fl.count_dtype.itemsize, c) + local * fl.dtype.itemsize, fl.values[lo:hi],
                fl.dtype)
            at = at + fl.count_dtype.itemsize + c * fl.dtype.itemsize
        f.write(out.tobytes())


def _write_ascii(f: BinaryIO, fields: list[_Field], n: int, chunk: int = 65536) -> None:
    """An element's lines: integers as %d, floats as their shortest round-trip repr (float32 values
    exactly as stored)."""
    conv = ["%d" if fl.dtype.kind in "iu" else "%r" for fl in fields]
    if all(fl.counts is None for fl in fields):
        write_rows(f, " ".join(conv) + "\n", np.column_stack([fl.values.astype(np.float64) for fl in fields])
                   if fields else np.zeros((n, 0)))
        return
    starts = [None if fl.counts is None else np.concatenate([[0], np.cumsum(fl.counts, dtype=np.int64)])
              for fl in fields]

    @lru_cache(maxsize=None)
    def line(counts: tuple) -> str:     # the format of a line whose lists have these lengths
        it = iter(counts)
        return " ".join(cv if fl.counts is None else " ".join(["%d"] + [cv] * next(it)) for fl, cv in
                        zip(fields, conv)) + "\n"

    lists = [fl for fl in fields if fl.counts is not None]
    for r0 in range(0, n, chunk):
        r1 = min(r0 + chunk, n)
        per = np.zeros(r1 - r0, np.int64)
        for fl in fields:
            per += 1 if fl.counts is None else 1 + fl.counts[r0:r1].astype(np.int64)
        at = np.cumsum(per) - per
        vals = np.empty(int(per.sum()))
        for fl, st in zip(fields, starts):
            if fl.counts is None:
                vals[at] = fl.values[r0:r1]
                at = at + 1
                continue
            c = fl.counts[r0:r1].astype(np.int64)
            vals[at] = c
            lo, hi = int(st[r0]), int(st[r1])
            local = np.arange(hi - lo) - np.repeat(st[r0:r1] - lo, c)
            vals[np.repeat(at + 1, c) + local] = fl.values[lo:hi]
            at = at + 1 + c
        keys = zip(*[fl.counts[r0:r1].tolist() for fl in lists])   # one format per line: by its list lengths
        f.write(("".join([line(k) for k in keys]) % tuple(vals.tolist())).encode("ascii"))
