"""Stanford PLY (ASCII and binary, either byte order), with per-vertex attributes."""

from __future__ import annotations

import re
import warnings
from dataclasses import dataclass

import numpy as np

from ..errors import DataLossWarning, MeshError
from ..mesh import Mesh
from .text import Text, build_mesh, ranges, strip_bom

__all__ = ["read_ply", "PLY_TYPES", "OWN_COMMENT", "MAX_HEADER_BYTES", "front_comment", "front_from_comments"]


PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}
_PLY_FORMATS = {"ascii": None, "binary_little_endian": "<", "binary_big_endian": ">"}
_END_HEADER_RE = re.compile(rb"^end_header[ \t]*(?:\r?\n|$)", re.MULTILINE)
_FACE_LISTS = ("vertex_indices", "vertex_index")
OWN_COMMENT = "written by shapeflow"
#: the header (the text before ``end_header``) is at most this long: ~700,000 property lines, where
#: real files have tens; it is parsed in one pass either way
MAX_HEADER_BYTES = 16 << 20
#: the comment that keeps ``metadata["front"]`` (the axis the model faces, for the renderer's views):
#: ``comment shapeflow front -z`` in PLY, ``# shapeflow front -z`` in OBJ; only this exact form is read
_FRONT = re.compile(r"shapeflow front ([+-][xyz])")


def front_comment(mesh: Mesh) -> list[str]:
    """The comment text that keeps ``mesh.metadata["front"]`` (one of +x, -x, +y, -y, +z, -z), or none."""
    front = mesh.metadata.get("front")
    return [f"shapeflow front {front}"] if isinstance(front, str) and _FRONT.fullmatch(f"shapeflow front {front}") \
        else []


def front_from_comments(comments: list[str]) -> tuple[str | None, list[str]]:
    """The front a file's comments declare (the last ``shapeflow front AXIS``), and the other comments."""
    found = [_FRONT.fullmatch(c.rstrip()) for c in comments]
    fronts = [m.group(1) for m in found if m]
    return (fronts[-1] if fronts else None), [c for c, m in zip(comments, found) if not m]


@dataclass
class _Prop:
    name: str
    dtype: np.dtype  # item type (with byte order in binary files)
    count_dtype: np.dtype | None = None  # list length type; None for a scalar

    @property
    def is_list(self) -> bool:
        return self.count_dtype is not None


@dataclass
class _Element:
    name: str
    count: int
    line: int
    props: list


def _parse_ply_header(header: str, name: str) -> tuple[str | None, list[_Element]]:
    """The byte order (None: ASCII) and the elements; one pass, each name looked up in a dict."""
    order = False
    elements: list[_Element] = []
    element_line: dict[str, int] = {}          # element name -> its line
    prop_names: set[str] = set()               # the current element's property names
    seen_format = False
    for ln, line in enumerate(header.split("\n"), start=1):
        words = line.split()
        if ln == 1:
            if words != ["ply"]:
                raise MeshError(f"{name}: line 1: not a PLY file (the first line must be 'ply')")
            continue
        if not words or words[0] in ("comment", "obj_info"):
            continue
        key = words[0]
        if not line.isascii():
            raise MeshError(f"{name}: line {ln}: non-ASCII text outside a comment in the PLY header")
        err = lambda msg: MeshError(f"{name}: line {ln}: {msg}")  # noqa: E731
        if key == "format":
            if len(words) != 3 or words[1] not in _PLY_FORMATS:
                raise err(f"bad format line {line.strip()!r}; expected 'format ascii|binary_little_endian|"
                          "binary_big_endian 1.0'")
            order, seen_format = _PLY_FORMATS[words[1]], True
        elif key == "element":
            if len(words) != 3 or not words[2].isascii() or not words[2].isdigit():
                raise err(f"bad element line {line.strip()!r}; expected 'element NAME COUNT'")
            if words[1] in element_line:
                raise err(f"a second '{words[1]}' element (the first is on line {element_line[words[1]]}); "
                          "which one holds the mesh is ambiguous")
            element_line[words[1]] = ln
            prop_names = set()
            elements.append(_Element(words[1], int(words[2]), ln, []))
        elif key == "property":
            if not elements:
                raise err("property before any element")
            if len(words) >= 3 and words[-1] in prop_names:
                raise err(f"property '{words[-1]}' of element '{elements[-1].name}' is declared twice; "
                          "which one holds the values is ambiguous")
            prop_names.add(words[-1])
            if len(words) == 3 and words[1] in PLY_TYPES:
                elements[-1].props.append(_Prop(words[2], np.dtype(PLY_TYPES[words[1]])))
            elif (len(words) == 5 and words[1] == "list" and words[2] in PLY_TYPES
                  and words[3] in PLY_TYPES and PLY_TYPES[words[2]][0] in "iu"):
                elements[-1].props.append(
                    _Prop(words[4], np.dtype(PLY_TYPES[words[3]]), np.dtype(PLY_TYPES[words[2]])))
            else:
                raise err(f"bad property line {line.strip()!r}")
        else:
            raise err(f"unknown header keyword {key!r}")
    if not seen_format:
        raise MeshError(f"{name}: PLY header has no 'format' line")
    if order:
        for el in elements:
            for p in el.props:
                p.dtype = p.dtype.newbyteorder(order)
                if p.count_dtype is not None:
                    p.count_dtype = p.count_dtype.newbyteorder(order)
    return order, elements


def _gather(buf: np.ndarray, offsets: np.ndarray, dtype: np.dtype) -> np.ndarray:
    """Values of ``dtype`` at byte ``offsets`` of ``buf`` (uint8)."""
    if offsets.size == 0:
        return np.zeros(0, dtype=dtype)
    raw = buf[offsets[:, None] + np.arange(dtype.itemsize)]
    return np.ascontiguousarray(raw).view(dtype).reshape(-1)


def _read_binary_element(buf: bytes, arr: np.ndarray, pos: int, el: _Element, name: str):
    """Read element ``el`` at byte ``pos``: ({prop: values or (counts, items)}, end)."""
    n, L = el.count, len(buf)
    props = el.props
    trunc = lambda i: MeshError(f"{name}: {el.name} {i}: file is truncated "  # noqa: E731
                                f"(header says {n} {el.name} elements)")
    if n == 0:
        return {p.name: (np.zeros(0, np.int64), np.zeros(0, p.dtype)) if p.is_list else np.zeros(0, p.dtype)
                for p in props}, pos
    # never allocate from the declared count more than the bytes left can hold: every record
    # takes at least its scalars and its lists' counts
    least = sum(p.count_dtype.itemsize if p.is_list else p.dtype.itemsize for p in props)
    if least and n > (L - pos) // least:
        raise trunc(max(L - pos, 0) // least)
    if not any(p.is_list for p in props):
        dt = np.dtype([(f"p{i}", p.dtype) for i, p in enumerate(props)])   # n records fit: checked above
        rec = np.frombuffer(buf, dtype=dt, count=n, offset=pos)
        return {p.name: rec[f"p{i}"] for i, p in enumerate(props)}, pos + n * dt.itemsize
    counts = _binary_list_counts(buf, pos, el, name, trunc)
    # per-record byte offsets of every property, vectorised
    fixed = sum(p.dtype.itemsize for p in props if not p.is_list)
    sizes = np.full(n, fixed, dtype=np.int64)
    lists = [p for p in props if p.is_list]
    for j, p in enumerate(lists):
        sizes += p.count_dtype.itemsize + counts[:, j] * p.dtype.itemsize
    ends = pos + np.cumsum(sizes)
    if ends[-1] > L:
        raise trunc(int(np.searchsorted(ends, L, side="right")))
    cur = ends - sizes
    out = {}
    j = 0
    for p in props:
        if not p.is_list:
            out[p.name] = _gather(arr, cur, p.dtype)
            cur = cur + p.dtype.itemsize
        else:
            c = counts[:, j]
            data_at = cur + p.count_dtype.itemsize
            k = int(c[0])
            stride = int(data_at[1] - data_at[0]) if n > 1 else 0
            if (c == k).all() and (n == 1 or (np.diff(data_at) == stride).all()):
                # same length, evenly spaced (all triangles...): one strided view
                items = np.ndarray((n, k), dtype=p.dtype, buffer=buf, offset=int(data_at[0]),
                                   strides=(stride, p.dtype.itemsize)).reshape(-1)
            else:
                items = _gather(arr, _list_item_offsets(data_at, c, p.dtype.itemsize), p.dtype)
            out[p.name] = (c, items)
            cur = data_at + c * p.dtype.itemsize
            j += 1
    return out, int(ends[-1])


def _list_item_offsets(data_at: np.ndarray, c: np.ndarray, itemsize: int) -> np.ndarray:
    """Byte offset of every item of lists starting at ``data_at`` with lengths ``c``."""
    within = np.arange(int(c.sum()), dtype=np.int64) - np.repeat(np.cumsum(c) - c, c)
    return np.repeat(data_at, c) + within * itemsize


def _binary_list_counts(buf: bytes, pos: int, el: _Element, name: str, trunc) -> np.ndarray:
    """(n, n_lists) list lengths of a binary element (records have variable size)."""
    n, L = el.count, len(buf)
    props = el.props
    lists = [p for p in props if p.is_list]
    # fast path: one list and every record as long as the first (all triangles, all quads...)
    if len(lists) == 1:
        li = props.index(lists[0])
        p = lists[0]
        pre = sum(q.dtype.itemsize for q in props[:li])
        post = sum(q.dtype.itemsize for q in props[li + 1:])
        csz = p.count_dtype.itemsize
        if pos + pre + csz > L:
            raise trunc(0)
        k0 = int(np.frombuffer(buf, p.count_dtype, 1, pos + pre)[0])
        rec = pre + csz + k0 * p.dtype.itemsize + post
        if k0 >= 0 and pos + n * rec <= L:
            c = np.ndarray((n,), dtype=p.count_dtype, buffer=buf, offset=pos + pre, strides=(rec,))
            if (c == k0).all():
                return np.full((n, 1), k0, dtype=np.int64)
    # general case: walk the records (a light Python loop; record boundaries are sequential)
    steps = []  # ("skip", nbytes) or ("list", count_size, signed, byteorder, item_size)
    for q in props:
        if not q.is_list:
            if steps and steps[-1][0] == "skip":
                steps[-1] = ("skip", steps[-1][1] + q.dtype.itemsize)
            else:
                steps.append(("skip", q.dtype.itemsize))
        else:
            order = "big" if q.count_dtype.byteorder == ">" else "little"
            steps.append(("list", q.count_dtype.itemsize, q.count_dtype.kind == "i", order, q.dtype.itemsize))
    counts = np.empty((n, len(lists)), dtype=np.int64)
    from_bytes = int.from_bytes
    if len(steps) <= 3 and sum(s[0] == "list" for s in steps) == 1:
        # the usual face layout: [scalars] list [scalars]
        pre = steps[0][1] if steps[0][0] == "skip" else 0
        lst = steps[1] if pre else steps[0]
        post = steps[-1][1] if steps[-1][0] == "skip" and steps[-1] is not steps[0] else 0
        _, csz, signed, order, isz = lst
        ks = [0] * n
        p_ = pos
        if csz == 1 and not signed:
            for i in range(n):
                q = p_ + pre
                if q >= L:  # record i - 1 overran the end, or record i is missing
                    raise trunc(i - 1 if p_ > L else i)
                k = ks[i] = buf[q]
                p_ = q + 1 + k * isz + post
        else:
            for i in range(n):
                q = p_ + pre
                if q + csz > L:
                    raise trunc(i - 1 if p_ > L else i)
                k = ks[i] = from_bytes(buf[q:q + csz], order, signed=signed)
                if k < 0:
                    raise MeshError(f"{name}: {el.name} {i}: negative list length {k}")
                p_ = q + csz + k * isz + post
        counts[:, 0] = ks
        return counts
    p_ = pos
    for i in range(n):
        if p_ > L:
            raise trunc(i - 1)
        j = 0
        for st in steps:
            if st[0] == "skip":
                p_ += st[1]
            else:
                _, csz, signed, order, isz = st
                if p_ + csz > L:
                    raise trunc(i)
                k = from_bytes(buf[p_:p_ + csz], order, signed=signed)
                if k < 0:
                    raise MeshError(f"{name}: {el.name} {i}: negative list length {k}")
                counts[i, j] = k
                j += 1
                p_ += csz + k * isz
    return counts


def _read_ascii_element(txt: Text, r0: int, el: _Element, name: str):
    """Read element ``el`` from records r0 .. r0 + count - 1 of the ASCII body."""
    n = el.count
    if r0 + n > txt.n_records:
        raise txt.error_at_end(f"file ends after {txt.n_records - r0} of {n} '{el.name}' lines "
                               "(truncated, or wrong counts in the header)")
    recs = np.arange(r0, r0 + n)
    first = txt.rec_first[recs]
    have = txt.rec_count[recs]
    props = el.props
    out = {}
    if n == 0:
        return {p.name: (np.zeros(0, np.int64), np.zeros(0, np.float64)) if p.is_list else np.zeros(0)
                for p in props}
    if not any(p.is_list for p in props):
        k = len(props)
        bad = np.flatnonzero(have != k)
        if bad.size:
            i = int(bad[0])
            raise txt.error(first[i], f"'{el.name}' line has {int(have[i])} values, expected {k}")
        vals = txt.parse(ranges(first, have), np.float64, f"{el.name} value").reshape(n, k)
        return {p.name: vals[:, i] for i, p in enumerate(props)}
    stop = first + have
    cur = first.copy()

    def need(what):
        bad = np.flatnonzero(cur >= stop)
        if bad.size:
            i = int(bad[0])
            raise txt.error(first[i], f"'{el.name}' line has too few values (no {what})")

    for p in props:
        need(p.name)
        if not p.is_list:
            out[p.name] = txt.parse(cur, np.float64, f"'{p.name}' value")
            cur = cur + 1
        else:
            c = txt.parse(cur, np.int64, f"'{p.name}' list length")
            neg = np.flatnonzero(c < 0)
            if neg.size:
                raise txt.error(cur[int(neg[0])], f"negative list length {int(c[neg[0]])}")
            over = np.flatnonzero(cur + 1 + c > stop)
            if over.size:
                i = int(over[0])
                raise txt.error(first[i], f"'{el.name}' line is too short: '{p.name}' says {int(c[i])} "
                                f"values, {int(stop[i] - cur[i] - 1)} follow")
            kind = np.int64 if p.dtype.kind in "iu" else np.float64
            out[p.name] = (c, txt.parse(ranges(cur + 1, c), kind, f"'{p.name}' value"))
            cur = cur + 1 + c
    extra = np.flatnonzero(cur != stop)
    if extra.size:
        i = int(extra[0])
        raise txt.error(first[i], f"'{el.name}' line has {int(stop[i] - cur[i])} values too many")
    return out


def read_ply(data: bytes, name: str) -> Mesh:
    if not data.strip():
        raise MeshError(f"{name}: empty file")
    data = strip_bom(data)   # the header is text even when the body is binary
    first_line = data.split(b"\n", 1)[0].strip()
    if first_line != b"ply":
        raise MeshError(f"{name}: line 1: not a PLY file (the first line must be 'ply')")
    m = _END_HEADER_RE.search(data, 0, MAX_HEADER_BYTES + len("end_header\r\n"))
    if not m and len(data) > MAX_HEADER_BYTES:
        raise MeshError(f"{name}: no 'end_header' line in the first {MAX_HEADER_BYTES >> 20} MiB: a PLY header "
                        f"is at most {MAX_HEADER_BYTES >> 20} MiB (about 700,000 property lines)")
    if not m:
        raise MeshError(f"{name}: PLY header has no 'end_header' line (truncated or not a PLY file)")
    try:   # comments and obj_info may hold any UTF-8 text; keywords are checked to be ASCII
        header = data[:m.start()].decode("utf-8").replace("\r", "")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise MeshError(f"{name}: line {line}: PLY header is not UTF-8 text") from None
    order, elements = _parse_ply_header(header, name)
    if order is None:
        found, vloc, floc = _read_ascii_body(data, m.end(), elements, name)
    else:
        found, vloc, floc = _read_binary_body(data[m.end():], elements, name)
    vel = next((el for el in elements if el.name == "vertex"), None)
    if vel is None:
        raise MeshError(f"{name}: PLY file has no 'vertex' element")
    vertices, attributes, vlists = _vertex_data(vel, found["vertex"], name, vloc)
    fel = next((el for el in elements if el.name == "face"), None)
    corner, face, flists = {}, {}, {}
    if fel is None:
        sizes, idx = np.zeros(0, np.int64), np.zeros(0, np.int64)
    else:
        sizes, idx = _face_data(fel, found["face"], vertices.shape[0], name, floc)
        face, corner, flists = _face_extras(fel, found["face"], sizes, name, floc)
    lost = [f"element '{el.name}' ({el.count})" for el in elements if el.name not in ("vertex", "face")]
    if lost:
        warnings.warn(DataLossWarning(f"{name}: not kept: {', '.join(lost)}"), stacklevel=3)
    meta = {key: [ln.split(None, 1)[1] if len(ln.split(None, 1)) > 1 else "" for ln in header.split("\n")
                  if ln.split(None, 1)[:1] == [key]] for key in ("comment", "obj_info")}
    front, meta["comment"] = front_from_comments([c for c in meta["comment"] if c != OWN_COMMENT])
    # what writing it back needs: each property's type, in the file's order, and the list properties
    # that are not the faces' corners or texture coordinates (valid while vertices and faces stay)
    meta["types"] = {el.name: {p.name: (p.count_dtype.newbyteorder("=").str[1:], p.dtype.newbyteorder("=").str[1:])
                               if p.is_list else p.dtype.newbyteorder("=").str[1:] for p in el.props}
                     for el in (vel, fel) if el is not None}
    if vlists or flists:
        meta["lists"] = {"vertex": vlists, "face": flists}
        meta["lists_of"] = (vertices.shape[0], idx)
    return build_mesh(name, vertices, sizes, idx, attributes=attributes, corner_attributes=corner,
                      face_attributes=face, metadata={"ply": meta, **({"front": front} if front else {})},
                      where_vertex=vloc, where_face=floc)


def _face_extras(fel: _Element, vals: dict, sizes: np.ndarray, name: str, floc):
    """Face properties besides the vertex list: scalars as face attributes (in their type), a
    'texcoord' list of two values per corner as the corner attribute "uv", other lists as they are
    ({name: (counts, items)}, kept for writing back)."""
    face, corner, lists = {}, {}, {}
    vlist = next((p for p in fel.props if p.is_list and p.name in _FACE_LISTS), None) or \
        next((p for p in fel.props if p.is_list), None)
    where = floc if floc is not None else (lambda f: f"face {f}")
    for p in fel.props:
        if p is vlist:
            continue
        if not p.is_list:
            face[p.name] = _typed(vals[p.name], p, name, where, np.arange(len(vals[p.name])))
        elif p.name in ("texcoord", "texcoords") and np.array_equal(np.asarray(vals[p.name][0]), 2 * sizes):
            corner["uv"] = np.asarray(vals[p.name][1], dtype=np.float64).reshape(-1, 2)
        else:
            counts, items = vals[p.name]
            counts = np.asarray(counts, np.int64)
            owner = np.repeat(np.arange(counts.size), counts)
            lists[p.name] = (counts, _typed(items, p, name, where, owner))
    return face, corner, lists


def _typed(v, p: _Prop, name: str, where, owner: np.ndarray) -> np.ndarray:
    """Values in the property's declared type; ASCII numbers (parsed as float64) are checked to fit
    an integer type (``owner[i]``: the element value i belongs to, for the message), and ASCII floats
    keep the text's precision (float64)."""
    v = np.asarray(v)
    dt = p.dtype.newbyteorder("=")
    if dt.kind in "iu" and v.dtype.kind == "f":
        info = np.iinfo(dt)
        bad = np.flatnonzero((v != np.rint(v)) | (v < info.min) | (v > info.max))
        if bad.size:
            i = int(bad[0])
            raise MeshError(_at(name, where(int(owner[i])),
                                f"property '{p.name}' is {np.dtype(dt).name} but has the value {float(v[i]):.17g}"))
    return v if (dt.kind == "f" and v.dtype == np.float64) else v.astype(dt)


def _read_ascii_body(data: bytes, start: int, elements: list[_Element], name: str):
    """Values of every element of an ASCII body, and where-functions for vertex and face messages."""
    body = data[start:]
    if b"\x00" in body:
        line = data.count(b"\n", 0, start + body.find(b"\x00")) + 1
        raise MeshError(f"{name}: line {line}: binary data (NUL byte) in an ASCII PLY file")
    txt = Text(body, name, line_offset=data.count(b"\n", 0, start))
    found: dict[str, dict] = {}
    r = 0
    for el in elements:
        values = _read_ascii_element(txt, r, el, name)
        found.setdefault(el.name, values)
        r += el.count
    if r < txt.n_records:
        raise txt.error(txt.rec_first[r], "unexpected data after the last element "
                        "(wrong counts in the header?)")
    vloc = lambda i: f"line {txt.lineno(txt.rec_first[_first_record(elements, 'vertex') + i])}"  # noqa: E731
    floc = lambda f: f"line {txt.lineno(txt.rec_first[_first_record(elements, 'face') + f])}"  # noqa: E731
    return found, vloc, floc


def _read_binary_body(body: bytes, elements: list[_Element], name: str):
    """Values of every element of a binary body (messages name "vertex i" / "face f" already)."""
    found: dict[str, dict] = {}
    arr = np.frombuffer(body, dtype=np.uint8)
    pos = 0
    for el in elements:
        values, pos = _read_binary_element(body, arr, pos, el, name)
        found.setdefault(el.name, values)
    if pos < len(body) and body[pos:].strip():
        last = elements[-1].name if elements else "header"
        raise MeshError(f"{name}: {len(body) - pos} bytes of unexpected data after the last element "
                        f"('{last}'); wrong counts in the header?")
    return found, None, None


def _vertex_data(vel: _Element, vals: dict, name: str, vloc):
    """Positions, the other scalar properties as attributes (in their types) and the list
    properties ({name: (counts, items)})."""
    scal = {p.name: p for p in vel.props if not p.is_list}
    for axis in "xyz":
        if axis not in scal:
            raise MeshError(f"{name}: line {vel.line}: the vertex element has no scalar '{axis}' property")
    vertices = np.column_stack([np.asarray(vals[a], dtype=np.float64) for a in "xyz"])
    where = vloc if vloc is not None else (lambda i: f"vertex {i}")
    attributes, lists = {}, {}
    for p in vel.props:
        if p.name in ("x", "y", "z"):
            continue
        if p.is_list:
            counts = np.asarray(vals[p.name][0], np.int64)
            lists[p.name] = (counts, _typed(vals[p.name][1], p, name, where, np.repeat(np.arange(counts.size), counts)))
        else:
            attributes[p.name] = _typed(vals[p.name], p, name, where, np.arange(vertices.shape[0]))
    return vertices, attributes, lists


def _face_data(fel: _Element, vals: dict, nv: int, name: str, floc):
    """Sizes and vertex indices of the face element's vertex list, checked."""
    lists = [p for p in fel.props if p.is_list]
    named = [p for p in lists if p.name in _FACE_LISTS]
    plist = named[0] if named else (lists[0] if len(lists) == 1 else None)
    if plist is None:
        raise MeshError(f"{name}: line {fel.line}: the face element has no 'vertex_indices' list")
    if plist.dtype.kind not in "iu":
        raise MeshError(f"{name}: line {fel.line}: face '{plist.name}' must be an integer list")
    sizes, idx = vals[plist.name]
    sizes = np.asarray(sizes, dtype=np.int64)
    idx = np.asarray(idx, dtype=np.int64)
    where = floc if floc is not None else (lambda f: None)
    small = np.flatnonzero(sizes < 3)
    if small.size:
        f = int(small[0])
        raise MeshError(_at(name, where(f), f"face {f} has {int(sizes[f])} corners; a face needs at least 3"))
    bad = np.flatnonzero((idx < 0) | (idx >= nv))
    if bad.size:
        c = int(bad[0])
        f = int(np.searchsorted(np.cumsum(sizes), c, side="right"))
        raise MeshError(_at(name, where(f), f"face {f} refers to vertex {int(idx[c])}, "
                            f"out of range [0, {nv})"))
    return sizes, idx


def _at(name: str, where: str | None, msg: str) -> str:
    return f"{name}: {where}: {msg}" if where else f"{name}: {msg}"


def _first_record(elements: list[_Element], which: str) -> int:
    r = 0
    for el in elements:
        if el.name == which:
            return r
        r += el.count
    return r  # pragma: no cover
