"""Writing Stanford PLY: vertex properties in their types, face properties, texcoord lists."""

from __future__ import annotations

import warnings
from typing import BinaryIO

import numpy as np

from ..errors import DataLossWarning, MeshError
from ..mesh import Mesh
from .ply import OWN_COMMENT, PLY_TYPES
from .text import write_faces_text, write_rows

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


def write_ply(f: BinaryIO, mesh: Mesh, *, binary: bool | None = None, byteorder: str = "<") -> None:
    binary = True if binary is None else bool(binary)
    attrs = _ply_attributes(mesh)
    types = {k: _ply_type(v) for k, v in attrs.items()}
    scalars, uv, lost = _face_columns(mesh)
    if lost:
        warnings.warn(DataLossWarning("PLY cannot store: " + ", ".join(lost)), stacklevel=4)
    ftypes = {k: _ply_type(v) for k, v in scalars.items()}
    sizes = mesh.face_sizes
    count_type = "uchar" if sizes.size == 0 or 2 * int(sizes.max()) <= 255 else "int"
    fmt = ("binary_little_endian" if byteorder == "<" else "binary_big_endian") if binary else "ascii"
    meta = mesh.metadata.get("ply", {})
    head = ["ply", f"format {fmt} 1.0", f"comment {OWN_COMMENT}"]
    head += [f"comment {c}" for c in meta.get("comment", [])] + [f"obj_info {c}" for c in meta.get("obj_info", [])]
    head += [f"element vertex {mesh.n_vertices}", "property double x", "property double y", "property double z"]
    head += [f"property {_PLY_NAMES[f'{types[k].kind}{types[k].itemsize}']} {k}" for k in attrs]
    head += [f"element face {mesh.n_faces}", f"property list {count_type} int vertex_indices"]
    head += [f"property {_PLY_NAMES[f'{ftypes[k].kind}{ftypes[k].itemsize}']} {k}" for k in scalars]
    head += [f"property list {count_type} float texcoord"] if uv is not None else []
    f.write(("\n".join(head + ["end_header"]) + "\n").encode("utf-8"))
    if not binary:   # integers exactly as %d (every PLY integer type fits a double exactly)
        columns = np.column_stack([mesh.vertices] + [v.astype(np.float64)[:, None] for v in attrs.values()])
        fmts = ["%r"] * 3 + ["%d" if types[k].kind in "iu" else "%r" for k in attrs]
        write_rows(f, " ".join(fmts) + "\n", columns)
        if scalars or uv is not None:
            _write_faces_ascii(f, mesh, scalars, ftypes, uv)
        else:
            write_faces_text(f, mesh, "", 0, with_size=True)
        return
    rec = np.empty(mesh.n_vertices, dtype=[("xyz", byteorder + "f8", (3,))]
                   + [(f"a{i}", types[k].newbyteorder(byteorder)) for i, k in enumerate(attrs)])
    rec["xyz"] = mesh.vertices
    for i, (k, v) in enumerate(attrs.items()):
        rec[f"a{i}"] = v
    f.write(rec.tobytes())
    _write_faces_binary(f, mesh, byteorder, count_type, scalars, ftypes, uv)


def _write_faces_ascii(f: BinaryIO, mesh: Mesh, scalars: dict, ftypes: dict, uv, chunk: int = 65536) -> None:
    """Face lines with their extra properties: k i1 .. ik [scalars] [2k u1 v1 .. uk vk]."""
    sizes, offsets, idx = mesh.face_sizes, mesh.face_offsets, mesh.face_indices
    sfmt = "".join(" %d" if ftypes[k].kind in "iu" else " %r" for k in scalars)
    cols = [np.asarray(v, np.float64) for v in scalars.values()]
    for i in range(0, sizes.size, chunk):
        j = min(i + chunk, sizes.size)
        ks = sizes[i:j].tolist()
        fmt = "".join([("%d" + " %d" * k + sfmt + (" %d" + " %r" * (2 * k) if uv is not None else "") + "\n")
                       for k in ks])
        lo, hi = int(offsets[i]), int(offsets[j])
        # one flat row of values per face, in the order of the format: laid out with offsets
        per = 1 + sizes[i:j] + len(cols) + ((1 + 2 * sizes[i:j]) if uv is not None else 0)
        start = np.cumsum(per) - per
        vals = np.empty(int(per.sum()))
        vals[start] = sizes[i:j]
        local = np.arange(hi - lo) - np.repeat(offsets[i:j] - lo, sizes[i:j])
        cstart = np.repeat(start, sizes[i:j])
        vals[cstart + 1 + local] = idx[lo:hi]
        for q, c in enumerate(cols):
            vals[start + 1 + sizes[i:j] + q] = c[i:j]
        if uv is not None:
            t0 = start + 1 + sizes[i:j] + len(cols)
            vals[t0] = 2 * sizes[i:j]
            ct0 = np.repeat(t0, sizes[i:j]) + 1 + 2 * local
            vals[ct0] = uv[lo:hi, 0]
            vals[ct0 + 1] = uv[lo:hi, 1]
        f.write((fmt % tuple(vals.tolist())).encode("ascii"))


def _write_faces_binary(f: BinaryIO, mesh: Mesh, byteorder: str, count_type: str, scalars: dict, ftypes: dict,
                        uv, chunk: int = 1 << 18) -> None:
    """Face records: the count and indices, then each scalar property, then the texcoord list."""
    sizes, offsets, indices = mesh.face_sizes, mesh.face_offsets, mesh.face_indices
    cdt = np.dtype(byteorder + ("u1" if count_type == "uchar" else "i4"))
    idt, fdt = np.dtype(byteorder + "i4"), np.dtype(byteorder + "f4")
    sdts = [ftypes[k].newbyteorder(byteorder) for k in scalars]
    extra = sum(d.itemsize for d in sdts)
    csz, isz = cdt.itemsize, idt.itemsize

    def put(out, at, values, dt):
        raw = np.ascontiguousarray(values, dt).view(np.uint8).reshape(-1, dt.itemsize)
        out[at[:, None] + np.arange(dt.itemsize)] = raw

    for f0 in range(0, sizes.size, chunk):
        f1 = min(f0 + chunk, sizes.size)
        s = sizes[f0:f1]
        c0, c1 = int(offsets[f0]), int(offsets[f1])
        rec_len = csz + s * isz + extra + ((csz + 2 * s * fdt.itemsize) if uv is not None else 0)
        face_at = np.cumsum(rec_len) - rec_len
        out = np.empty(int(rec_len.sum()), dtype=np.uint8)
        put(out, face_at, s, cdt)
        local = np.arange(c1 - c0) - np.repeat(offsets[f0:f1] - c0, s)
        corner_face = np.repeat(np.arange(f1 - f0), s)
        put(out, face_at[corner_face] + csz + local * isz, indices[c0:c1], idt)
        at = face_at + csz + s * isz
        for (k, v), dt in zip(scalars.items(), sdts):
            put(out, at, v[f0:f1], dt)
            at = at + dt.itemsize
        if uv is not None:
            put(out, at, 2 * s, cdt)
            base = at[corner_face] + csz + 2 * local * fdt.itemsize
            put(out, base, uv[c0:c1, 0], fdt)
            put(out, base + fdt.itemsize, uv[c0:c1, 1], fdt)
        f.write(out.tobytes())
