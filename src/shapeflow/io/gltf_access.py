"""glTF accessors, checked with Python integers before any array is made.

Every accessor is checked against the spec before a byte is read: its componentType and type
for its role (KHR_mesh_quantization's integer positions, normals and texture coordinates
included), byteOffset, count, the bufferView's byteOffset, byteLength and byteStride (4 to 252,
a multiple of 4, at least one element), the bufferView inside its buffer and every element inside
the bufferView.  Only then is an array made, by numpy's own bounds-checked constructor.  Sparse
accessors are read as the spec says (their values over the base or zeros, indices strictly
increasing and inside the accessor); accessors without a bufferView (zeros, or zeros under sparse
values) hold at most max(65,536, 16 × the bytes of the file and the buffers it loaded) elements in
all, per file (:class:`ZeroBudget`), and within that by the memory available.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import MeshError
from .gltf_source import entry, field_int, is_int, room

__all__ = ["COMPONENT", "WIDTH", "ROLES", "Span", "Accessor", "ZeroBudget", "accessor", "read_raw", "read_float",
           "dequantize", "view_span"]

COMPONENT = {5120: "i1", 5121: "u1", 5122: "i2", 5123: "u2", 5125: "u4", 5126: "f4"}
WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
_F, _I8, _U8, _I16, _U16, _U32 = 5126, 5120, 5121, 5122, 5123, 5125
#: role -> (allowed types, allowed (componentType, normalized)); core glTF 2.0 and KHR_mesh_quantization
ROLES = {
    "POSITION": (("VEC3",), {(_F, False)} | {(c, n) for c in (_I8, _U8, _I16, _U16) for n in (False, True)}),
    "NORMAL": (("VEC3",), {(_F, False), (_I8, True), (_I16, True)}),
    "TEXCOORD_0": (("VEC2",), {(_F, False), (_U8, True), (_U16, True), (_I8, True), (_I16, True),
                               (_I8, False), (_U8, False), (_I16, False), (_U16, False)}),
    "COLOR_0": (("VEC3", "VEC4"), {(_F, False), (_U8, True), (_U16, True)}),
    "indices": (("SCALAR",), {(_U8, False), (_U16, False), (_U32, False)}),
}


@dataclass(frozen=True)
class Span:
    """Where the elements of an accessor (or a bufferView) lie: ``count`` elements of ``elem`` bytes,
    ``stride`` apart, from byte ``start`` of buffer ``buffer``."""

    buffer: int
    start: int
    stride: int
    elem: int
    count: int

    @property
    def end(self) -> int:
        return self.start + self.stride * (self.count - 1) + self.elem if self.count else self.start


@dataclass(frozen=True)
class Accessor:
    """A checked accessor: its dtype, width, normalization, where its dense part lies (None: zeros)
    and its sparse part (indices span, values span, index dtype) if any."""

    index: int
    dtype: str
    width: int
    count: int
    normalized: bool
    span: Span | None
    sparse: tuple | None


class ZeroBudget:
    """The elements a file may declare in accessors without a bufferView (zeros: nothing in the
    file backs them): max(ZERO_MIN, ZERO_PER_BYTE × ``nbytes``) in all, each accessor counted once,
    so a few hundred bytes cannot ask for 30 million vertices."""

    ZERO_MIN, ZERO_PER_BYTE = 65_536, 16

    def __init__(self, name: str, nbytes: int):
        self.name, self.nbytes = name, int(nbytes)
        self.limit = max(self.ZERO_MIN, self.ZERO_PER_BYTE * self.nbytes)
        self.taken: dict = {}
        self.total = 0

    def take(self, i: int, count: int, what: str) -> None:
        if i in self.taken:
            return
        self.taken[i] = count
        self.total += count
        if self.total > self.limit:
            before = self.total - count
            raise MeshError(f"{self.name}: accessor {i} ({what}) has no bufferView: its {count:,} elements (zeros) "
                            + (f"and the {before:,} of earlier such accessors " if before else "")
                            + f"exceed the {self.limit:,} a file may declare without bytes behind them "
                            f"(max({self.ZERO_MIN:,}, {self.ZERO_PER_BYTE} × the {self.nbytes:,} bytes of the file "
                            "and the buffers it loaded))")


def view_span(doc: dict, buffers: list, vi, name: str, what: str) -> tuple[int, int, int, int | None]:
    """(buffer, byteOffset, byteLength, byteStride or None) of bufferView ``vi``, checked."""
    view = entry(doc, "bufferViews", vi, name, what)
    where = f"bufferView {vi}"
    b = field_int(view, "buffer", where, name, required=True)
    entry(doc, "buffers", b, name, where)
    if b >= len(buffers):
        raise MeshError(f"{name}: {where}: buffer {b} was not loaded")
    off = field_int(view, "byteOffset", where, name, default=0)
    length = field_int(view, "byteLength", where, name, lo=1, required=True)
    if off + length > len(buffers[b]):
        raise MeshError(f"{name}: {where} (bytes {off} to {off + length}) runs past the end of buffer {b} "
                        f"({len(buffers[b])} bytes)")
    stride = view.get("byteStride")
    if stride is not None and (not is_int(stride) or not 4 <= stride <= 252 or stride % 4):
        raise MeshError(f"{name}: {where}: byteStride {stride!r} is not a multiple of 4 from 4 to 252")
    return b, off, length, stride


def _element(acc: dict, i: int, name: str, role: str) -> tuple[str, int, bool]:
    where = f"accessor {i} ({role})"
    ct, kind, norm = acc.get("componentType"), acc.get("type"), acc.get("normalized", False)
    if not is_int(ct) or ct not in COMPONENT:
        raise MeshError(f"{name}: {where}: componentType {ct!r} is not a glTF component type")
    if not isinstance(kind, str) or kind not in WIDTH:
        raise MeshError(f"{name}: {where}: type {kind!r} is not a glTF accessor type")
    if not isinstance(norm, bool):
        raise MeshError(f"{name}: {where}: normalized {norm!r} is not true or false")
    types, pairs = ROLES.get(role, (tuple(WIDTH), {(c, n) for c in COMPONENT for n in (False, True)}))
    if kind not in types or (ct, norm) not in pairs:
        raise MeshError(f"{name}: {where} holds {kind} of componentType {ct}{' normalized' if norm else ''}, "
                        f"which glTF does not allow for {role}")
    return COMPONENT[ct], WIDTH[kind], norm


def _dense_span(doc, buffers, acc, i, name, role, elem, itemsize, count) -> Span | None:
    where = f"accessor {i} ({role})"
    off = field_int(acc, "byteOffset", where, name, default=0)
    vi = acc.get("bufferView")
    if vi is None:
        return None
    b, voff, vlen, stride = view_span(doc, buffers, vi, name, where)
    stride = stride or elem
    if stride < elem:
        raise MeshError(f"{name}: {where}: byteStride {stride} is less than one element ({elem} bytes)")
    if off % itemsize:
        raise MeshError(f"{name}: {where}: byteOffset {off} is not a multiple of its component size {itemsize}")
    span = Span(b, voff + off, stride, elem, count)
    if count and span.end > voff + vlen:
        raise MeshError(f"{name}: {where}: {count} elements of {elem} bytes, {stride} apart from byte {off}, "
                        f"run past the end of bufferView {vi} ({vlen} bytes)")
    return span


def _sparse(doc, buffers, acc, i, name, role, elem, count) -> tuple | None:
    sp = acc.get("sparse")
    if sp is None:
        return None
    where = f"accessor {i} ({role}) sparse"
    if not isinstance(sp, dict) or not isinstance(sp.get("indices"), dict) or not isinstance(sp.get("values"), dict):
        raise MeshError(f"{name}: {where}: not an object with indices and values")
    k = field_int(sp, "count", where, name, lo=1, hi=count, required=True)
    ind, val = sp["indices"], sp["values"]
    ct = ind.get("componentType")
    if ct not in (_U8, _U16, _U32) or not is_int(ct):
        raise MeshError(f"{name}: {where}: indices componentType {ct!r} is not 5121, 5123 or 5125")
    spans = []
    for part, size in ((ind, np.dtype(COMPONENT[ct]).itemsize), (val, elem)):
        label = f"{where} {'indices' if part is ind else 'values'}"
        b, voff, vlen, stride = view_span(doc, buffers, field_int(part, "bufferView", label, name, required=True),
                                          name, label)
        if stride is not None:
            raise MeshError(f"{name}: {label}: its bufferView has a byteStride, which sparse data may not have")
        off = field_int(part, "byteOffset", label, name, default=0)
        if off + k * size > vlen:
            raise MeshError(f"{name}: {label}: {k} elements of {size} bytes from byte {off} run past the end "
                            f"of their bufferView ({vlen} bytes)")
        spans.append(Span(b, voff + off, size, size, k))
    return spans[0], spans[1], COMPONENT[ct]


def accessor(doc: dict, buffers: list, i, name: str, role: str, *, budget: bool = True,
             zeros: ZeroBudget | None = None) -> Accessor:
    """Accessor ``i``, checked for the role ``role`` (a key of :data:`ROLES`; any other role allows
    every type) and its bounds; ``budget``: refuse zeros that cannot fit in memory; ``zeros``: the
    file's budget of elements without a bufferView."""
    acc = entry(doc, "accessors", i, name, role)
    dtype, width, norm = _element(acc, i, name, role)
    count = field_int(acc, "count", f"accessor {i} ({role})", name, lo=1, required=True)
    itemsize = np.dtype(dtype).itemsize
    elem = itemsize * width
    span = _dense_span(doc, buffers, acc, i, name, role, elem, itemsize, count)
    sparse = _sparse(doc, buffers, acc, i, name, role, elem, count)
    if span is None and zeros is not None:
        zeros.take(i, count, f"{role}: {acc['type']}")
    if span is None and budget:
        room(name, f"accessor {i} ({role}: {count} {acc['type']} without a bufferView)", 32 * count * width)
    return Accessor(i, dtype, width, count, norm, span, sparse)


def _gather(blob, span: Span, dtype: str, width: int) -> np.ndarray:
    if not span.count:
        return np.zeros((0, width), dtype)
    rows = np.ndarray((span.count, span.elem), np.uint8, buffer=blob, offset=span.start, strides=(span.stride, 1))
    return rows.copy().view("<" + dtype).reshape(span.count, width).astype(dtype)


def read_raw(buffers: list, a: Accessor, name: str) -> np.ndarray:
    """The accessor's (count, width) values in its own component type, sparse values applied."""
    out = (_gather(buffers[a.span.buffer], a.span, a.dtype, a.width) if a.span is not None
           else np.zeros((a.count, a.width), a.dtype))
    if a.sparse is not None:
        ispan, vspan, idt = a.sparse
        idx = _gather(buffers[ispan.buffer], ispan, idt, 1).reshape(-1).astype(np.int64)
        if (idx >= a.count).any() or (np.diff(idx) <= 0).any():
            raise MeshError(f"{name}: accessor {a.index}: its sparse indices are not strictly increasing "
                            f"indices below its count {a.count}")
        out[idx] = _gather(buffers[vspan.buffer], vspan, a.dtype, a.width)
    return out


def dequantize(raw: np.ndarray, normalized: bool) -> np.ndarray:
    """Float64 values of raw components (normalized integers as the spec maps them to [-1, 1] or [0, 1])."""
    out = raw.astype(np.float64)
    if normalized and raw.dtype.kind in "iu":
        info = np.iinfo(raw.dtype)
        out /= info.max
        if info.min < 0:
            np.maximum(out, -1.0, out=out)
    return out


def read_float(doc: dict, buffers: list, i, name: str, role: str) -> np.ndarray:
    """Accessor ``i`` checked for ``role`` and read as float64 (count, width)."""
    a = accessor(doc, buffers, i, name, role)
    return dequantize(read_raw(buffers, a, name), a.normalized)
