"""Writing a glTF document back with new positions and normals, without corrupting anything else.

* Each accessor written gets one value per element: accessors shared by several placements (two
  meshes at two nodes using the same POSITION accessor) take the mean of the copies that use the
  element (a DataLossWarning says when the copies moved differently); elements no primitive uses
  keep their bytes.
* Written in place, in the accessor's own type, through its byteStride (interleaved attributes keep
  their neighbours' bytes): float32, or KHR_mesh_quantization's integers re-quantized with the
  spec's rounding.  An accessor is re-encoded as a new float32 accessor in a new bufferView at the
  end of buffer 0 instead (nothing else changes) when writing in place could hurt: its bytes are
  also read by another accessor, an image or an extension; it is sparse or has no bufferView; or
  its new values leave its integer range.
* min/max of every POSITION accessor written (and of others that had them) are recomputed.
* Every buffer keeps its index and bytes: GLB output carries buffer 0 in its binary chunk and the
  others as data: URIs; .gltf output carries them all as data: URIs.  Images that were files beside
  the input are embedded as data: URIs, so the output stands alone in any folder; an image that
  cannot be read then is named in a DataLossWarning.
"""

from __future__ import annotations

import base64
import json
import struct
import warnings

import numpy as np

from ..errors import DataLossWarning, MeshError
from ..geometry.placement import unplace, unplace_normals
from ..mesh import Mesh
from .float32 import F32_MAX
from .gltf_access import Span, accessor, dequantize, read_raw, view_span
from .gltf_source import BIN_CHUNK, GLB_MAGIC, JSON_CHUNK, items, load_image

__all__ = ["write_back", "pack", "MAX_PAIRS"]

#: above this many (accessor written, byte reader) pairs to compare, every accessor is re-encoded
MAX_PAIRS = 2_000_000


def _contributions(meta: dict, mesh: Mesh) -> dict:
    """accessor -> (role, [(values, mask, who)]): what each block / primitive wants written."""
    from ..geometry.normals import vertex_normals

    V, fi = mesh.vertices, mesh.face_indices
    used = np.zeros(mesh.n_vertices, bool)
    used[fi] = True
    blocks = meta["blocks"]
    out: dict = {}
    for b in blocks:
        sl = slice(b["base"], b["base"] + b["vertices"])
        with np.errstate(over="ignore", invalid="ignore"):    # beyond float32: refused by _encode
            part = (unplace(V[sl], b["matrix"]), used[sl], f"mesh {b['mesh']}")
        out.setdefault(b["position"], ("POSITION", []))[1].append(part)
    positions = {b["position"] for b in blocks}
    masks: dict = {}
    for p in meta["primitives"]:
        if p["normal"] is None:
            continue
        b = blocks[p["block"]]
        m = masks.setdefault((p["block"], p["normal"]), np.zeros(b["vertices"], bool))
        m[fi[p["corners"][0]:p["corners"][1]] - b["base"]] = True
    nrm = vertex_normals(mesh) if masks else None
    skipped = sorted({a for _, a in masks if a in positions})
    if skipped:
        warnings.warn(DataLossWarning(f"accessor(s) {skipped} serve as both POSITION and NORMAL: they get the "
                                      "new positions, not normals"), stacklevel=5)
    for (k, a), m in masks.items():
        if a in positions:
            continue
        b = blocks[k]
        sl = slice(b["base"], b["base"] + b["vertices"])
        out.setdefault(a, ("NORMAL", []))[1].append((unplace_normals(nrm[sl], b["matrix"]), m, f"mesh {b['mesh']}"))
    return out


def _combine(a: int, role: str, parts: list) -> tuple[np.ndarray, np.ndarray]:
    """One value per element: the mean of the parts that use it (renormalized for normals)."""
    if len(parts) == 1:
        return parts[0][0], parts[0][1]
    total = np.zeros_like(parts[0][0])
    count = np.zeros(total.shape[0])
    for values, mask, _ in parts:
        total[mask] += values[mask]
        count += mask
    mask = count > 0
    mean = np.zeros_like(total)
    mean[mask] = total[mask] / count[mask, None]
    if role == "NORMAL":
        ln = np.linalg.norm(mean, axis=1, keepdims=True)
        mean = np.divide(mean, ln, out=np.zeros_like(mean), where=ln > 0)
    spread = max(float(np.abs(v[m] - mean[m]).max(initial=0.0)) for v, m, _ in parts)
    scale = float(np.ptp(mean[mask], axis=0).max(initial=0.0)) if role == "POSITION" and mask.any() else 1.0
    if spread > 1e-6 * max(scale, 1e-300):
        who = ", ".join(sorted({w for _, _, w in parts}))
        warnings.warn(DataLossWarning(f"accessor {a} ({role}) is shared by {who}, which moved differently (by up "
                                      f"to {spread:.3g}); it holds their mean"), stacklevel=5)
    return mean, mask


def _readers(doc: dict, blobs: list, name: str) -> list:
    """(owner, Span) of everything in the document that reads buffer bytes."""
    out = []
    for i, acc in enumerate(items(doc, "accessors", name)):
        try:
            a = accessor(doc, blobs, i, name, "any", budget=False)
        except MeshError:          # not read by shapeflow: its whole bufferView counts as read
            vi = acc.get("bufferView") if isinstance(acc, dict) else None
            out += _whole_view(doc, blobs, vi, name, ("accessor", i))
            continue
        if a.span is not None:
            out.append((("accessor", i), a.span))
        if a.sparse is not None:
            out += [(("sparse", i), a.sparse[0]), (("sparse", i), a.sparse[1])]
    for k, img in enumerate(items(doc, "images", name)):
        out += _whole_view(doc, blobs, img.get("bufferView") if isinstance(img, dict) else None, name, ("image", k))
    stack = [(k, v) for k, v in doc.items() if k not in ("accessors", "images", "bufferViews", "buffers")]
    while stack:                   # bufferViews named anywhere else (extensions): read whole
        key, v = stack.pop()
        if key == "bufferView":
            out += _whole_view(doc, blobs, v, name, ("other", key))
        elif isinstance(v, dict):
            stack.extend(v.items())
        elif isinstance(v, list):
            stack.extend((None, x) for x in v)
    return out


def _whole_view(doc, blobs, vi, name, owner) -> list:
    try:
        b, off, length, _ = view_span(doc, blobs, vi, name, "")
    except MeshError:
        return []
    return [(owner, Span(b, off, length, length, 1))]


def _disjoint(a: Span, b: Span) -> bool:
    """Whether two spans share no byte (same stride: their windows within a stride do not meet)."""
    if a.buffer != b.buffer or a.end <= b.start or b.end <= a.start:
        return True
    if a.stride != b.stride:
        return False
    d = (b.start - a.start) % a.stride
    return a.elem <= d and d + b.elem <= a.stride


def _in_place(doc: dict, blobs: list, written: dict, name: str) -> set:
    """The written accessors whose bytes no one else reads (the others are re-encoded)."""
    readers = _readers(doc, blobs, name)
    dense = {i: a for i, a in written.items() if a.span is not None and a.sparse is None}
    if len(dense) * len(readers) > MAX_PAIRS:
        return set()
    return {i for i, a in dense.items()
            if all(owner == ("accessor", i) or _disjoint(a.span, s) for owner, s in readers)}


def _encode(values: np.ndarray, mask: np.ndarray, dtype: str, normalized: bool) -> np.ndarray | None:
    """Values in the accessor's component type; None if they leave its range."""
    if dtype == "f4":
        if not (np.abs(values[mask]) <= F32_MAX).all():
            raise MeshError("new positions leave float32, the widest glTF component type")
        return np.where(mask[:, None], values, 0.0).astype("<f4")
    info = np.iinfo(dtype)
    lo = -info.max if normalized and info.min < 0 else info.min
    q = np.rint(values * info.max if normalized else values)
    if (q[mask] < lo).any() or (q[mask] > info.max).any():
        return None
    return np.clip(np.where(mask[:, None], q, 0), lo, info.max).astype("<" + dtype)


def _write(blob: bytearray, a, values: np.ndarray, mask: np.ndarray) -> bool:
    enc = _encode(values, mask, a.dtype, a.normalized)
    if enc is None:
        return False
    s = a.span
    rows = np.ndarray((s.count, s.elem), np.uint8, buffer=blob, offset=s.start, strides=(s.stride, 1))
    rows[mask] = enc.view(np.uint8).reshape(s.count, s.elem)[mask]
    return True


def _relocate(doc: dict, blobs: list, i: int, values: np.ndarray) -> None:
    """Accessor ``i`` as float32 ``values`` in a new bufferView at the end of buffer 0."""
    arr = np.ascontiguousarray(values, "<f4")
    if not blobs:
        doc["buffers"] = [{"byteLength": 0}]
        blobs.append(bytearray())
    blob = blobs[0]
    blob += b"\0" * (-len(blob) % 4)
    views = doc.setdefault("bufferViews", [])
    views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": arr.nbytes, "target": 34962})
    blob += arr.tobytes()
    acc = doc["accessors"][i]
    for key in ("byteOffset", "normalized", "sparse"):
        acc.pop(key, None)
    acc.update(bufferView=len(views) - 1, componentType=5126)


def _bounds(doc: dict, blobs: list, i: int, role: str, name: str) -> None:
    acc = doc["accessors"][i]
    if role != "POSITION" and "min" not in acc and "max" not in acc:
        return
    raw = read_raw(blobs, accessor(doc, blobs, i, name, role), name)
    if not np.isfinite(raw).all():     # elements no primitive uses may hold anything: bounds left as they were
        return
    cast = float if raw.dtype.kind == "f" else int
    acc["min"] = [cast(x) for x in raw.min(axis=0)]
    acc["max"] = [cast(x) for x in raw.max(axis=0)]


def _copy(doc: dict) -> dict:
    """A copy of what writing changes (accessors, bufferViews, buffers, images; one level deep);
    the rest, however deeply nested, is shared with the read document."""
    out = dict(doc)
    for key in ("accessors", "bufferViews", "buffers", "images"):
        if isinstance(doc.get(key), list):
            out[key] = [dict(x) if isinstance(x, dict) else x for x in doc[key]]
    return out


def write_back(meta: dict, mesh: Mesh) -> tuple[dict, list]:
    """The input document and buffers with ``mesh``'s positions and normals (see the module)."""
    doc = _copy(meta["document"])
    blobs = [bytearray(b) for b in meta["buffers"]]
    name = meta.get("source", "the glTF input")
    items(doc, "bufferViews", name)         # a list (or absent): new bufferViews may be added
    wanted = {a: (role, *_combine(a, role, parts)) for a, (role, parts) in _contributions(meta, mesh).items()}
    written = {a: accessor(doc, blobs, a, name, role, budget=False) for a, (role, _, _) in wanted.items()}
    # every value first (reading before any byte changes), then the writes
    full = {}
    for a, (role, values, mask) in wanted.items():
        old = dequantize(read_raw(blobs, written[a], name), written[a].normalized)
        full[a] = np.where(mask[:, None], values, old)
    here = _in_place(doc, blobs, written, name)
    for a in sorted(wanted):
        role, values, mask = wanted[a]
        if a not in here or not _write(blobs[written[a].span.buffer], written[a], values, mask):
            _relocate(doc, blobs, a, full[a])
    for a, (role, _, _) in wanted.items():
        _bounds(doc, blobs, a, role, name)
    _embed_images(doc, meta.get("folder"), name)
    return doc, blobs


def _mime(data: bytes) -> str:
    for head, mime in ((b"\x89PNG", "image/png"), (b"\xff\xd8\xff", "image/jpeg"), (b"\xabKTX 20", "image/ktx2")):
        if data.startswith(head):
            return mime
    return "image/webp" if data[:4] == b"RIFF" and data[8:12] == b"WEBP" else "application/octet-stream"


def _embed_images(doc: dict, folder: str | None, name: str) -> None:
    lost = []
    for k, img in enumerate(items(doc, "images", name)):
        uri = img.get("uri") if isinstance(img, dict) else None
        if not isinstance(uri, str) or uri[:5].lower() == "data:":
            continue
        try:
            data = load_image(uri, folder, name, f"image {k}")
        except MeshError as exc:
            lost.append(f"image {k} {uri!r} ({str(exc).split(': ', 1)[-1]})")
            continue
        mime = img.get("mimeType") if isinstance(img.get("mimeType"), str) else _mime(data)
        img["uri"] = f"data:{mime};base64," + base64.b64encode(data).decode("ascii")
    if lost:
        warnings.warn(DataLossWarning(f"{name}: the written file refers to {', '.join(lost)} by its relative URI, "
                                      "which works only beside a copy of that file"), stacklevel=5)


def pack(doc: dict, blobs: list, binary: bool) -> bytes:
    """The document as GLB (buffer 0 in the binary chunk) or glTF JSON (buffers as data: URIs)."""
    for i, buf in enumerate(doc.get("buffers") or []):
        buf["byteLength"] = len(blobs[i])
        if binary and i == 0:
            buf.pop("uri", None)
        else:
            buf["uri"] = "data:application/octet-stream;base64," + base64.b64encode(bytes(blobs[i])).decode("ascii")
    try:
        text = json.dumps(doc, separators=(",", ":"), ensure_ascii=False, allow_nan=False).encode("utf-8")
    except RecursionError:
        raise MeshError("the glTF document is nested too deeply to be written") from None
    if not binary:
        return text
    text += b" " * (-len(text) % 4)
    chunks = [struct.pack("<II", len(text), JSON_CHUNK), text]
    if blobs:
        data = bytes(blobs[0]) + b"\0" * (-len(blobs[0]) % 4)
        chunks += [struct.pack("<II", len(data), BIN_CHUNK), data]
    body = b"".join(chunks)
    return GLB_MAGIC + struct.pack("<II", 2, 12 + len(body)) + body
