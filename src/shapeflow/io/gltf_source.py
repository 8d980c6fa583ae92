"""The bytes of a glTF file: its JSON (``.gltf`` or the GLB container), its buffers and images.

Nothing here reaches outside the file's own folder.  A URI is either a ``data:`` URI (base64,
decoded strictly; it lies inside the file, so it is never larger than the file) or a relative file
name resolved inside the folder of the glTF file: absolute paths, schemes (``file:``, ``http:``),
``..`` escapes, symbolic links leading out of the folder, ``/proc``, ``/sys`` and ``/dev``, and
anything that is not a regular file (devices, FIFOs, sockets) are refused by name.  Read with
``folder=None`` (a file that came alone, e.g. an upload), every URI that is not ``data:`` is
refused.  JSON numbers must be finite and every field used is checked for its type and range.
"""

from __future__ import annotations

import base64
import binascii
import json
import math
import os
import re
import stat
import struct
from urllib.parse import unquote

from ..budget import check_memory
from ..errors import MeshError, ParameterError

__all__ = ["parse_container", "source_folder", "resolve_uri", "read_file", "load_buffers", "check_images",
           "check_extensions", "load_image", "is_int", "field_int", "entry", "items", "room", "shown"]

GLB_MAGIC = b"glTF"
JSON_CHUNK = 0x4E4F534A
BIN_CHUNK = 0x004E4942
_SCHEME = re.compile(r"^[A-Za-z][A-Za-z0-9+.\-]*:")
_PSEUDO = ("/proc", "/sys", "/dev")
#: required extensions that change nothing shapeflow reads (materials, textures, lights pass through)
READABLE_EXTENSIONS = frozenset({
    "KHR_mesh_quantization", "KHR_texture_transform", "KHR_texture_basisu", "EXT_texture_webp",
    "EXT_texture_avif", "KHR_lights_punctual", "KHR_materials_variants"})


def shown(uri: str) -> str:
    """A URI as named in messages (long data URIs cut)."""
    return repr(uri if len(uri) <= 80 else uri[:60] + "…")


def is_int(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def field_int(obj: dict, key: str, where: str, name: str, *, lo: int = 0, hi: int | None = None,
              default: int | None = None, required: bool = False) -> int | None:
    """``obj[key]``: an integer in [lo, hi], or ``default`` when absent; anything else is a MeshError."""
    v = obj.get(key)
    if v is None:
        if required:
            raise MeshError(f"{name}: {where} has no {key}")
        return default
    if not is_int(v) or v < lo or (hi is not None and v > hi):
        bound = f"from {lo} to {hi}" if hi is not None else f"of at least {lo}"
        raise MeshError(f"{name}: {where}: {key} {v!r} is not an integer {bound}")
    return v


def items(doc: dict, key: str, name: str) -> list:
    """The top-level array ``key`` (absent: empty)."""
    v = doc.get(key)
    if v is None:
        return []
    if not isinstance(v, list):
        raise MeshError(f"{name}: '{key}' is not an array")
    return v


def entry(doc: dict, key: str, index, name: str, what: str) -> dict:
    """``doc[key][index]``, an object; an index out of range is a MeshError naming ``what``."""
    arr = items(doc, key, name)
    if not is_int(index) or not 0 <= index < len(arr):
        raise MeshError(f"{name}: {what} refers to {key[:-1]} {index!r}, which does not exist "
                        f"(the file has {len(arr)})")
    obj = arr[index]
    if not isinstance(obj, dict):
        raise MeshError(f"{name}: {key[:-1]} {index} is not an object")
    return obj


def room(name: str, what: str, need: float) -> None:
    """Refuse (MeshError with the estimate) what cannot fit in the memory available."""
    try:
        check_memory(what, float(min(need, 10 ** 30)), parameter=name)
    except ParameterError as exc:
        raise MeshError(str(exc)) from None


def _number(text: str) -> float:
    x = float(text)
    if not math.isfinite(x):
        raise ValueError(f"the number {text[:40]} is beyond double precision")
    return x


def _constant(text: str):
    raise ValueError(f"{text} is not a JSON number")


def _parse_json(raw: bytes, name: str) -> dict:
    try:
        text = raw.decode("utf-8")
        doc = json.loads(text[1:] if text.startswith("\ufeff") else text,
                         parse_float=_number, parse_constant=_constant)
    except UnicodeDecodeError as exc:
        raise MeshError(f"{name}: the glTF JSON is not UTF-8 (byte {exc.start})") from None
    except RecursionError:
        raise MeshError(f"{name}: the glTF JSON is nested too deeply") from None
    except ValueError as exc:   # json.JSONDecodeError, numbers out of range, 5,000-digit integers
        raise MeshError(f"{name}: not a glTF file: {exc}") from None
    if not isinstance(doc, dict):
        raise MeshError(f"{name}: not a glTF file: the JSON is not an object")
    asset = doc.get("asset")
    version = asset.get("version") if isinstance(asset, dict) else None
    if version is not None and not (isinstance(version, str) and version.startswith("2.")):
        raise MeshError(f"{name}: glTF version {version!r}; shapeflow reads glTF 2.0")
    return doc


def parse_container(data: bytes, name: str) -> tuple[dict, bytes | None]:
    """The JSON document and the GLB binary chunk (None for ``.gltf`` JSON or a GLB without one)."""
    if data[:4] != GLB_MAGIC:
        return _parse_json(data, name), None
    if len(data) < 20:
        raise MeshError(f"{name}: GLB file of {len(data)} bytes: too short for its header")
    version, length = struct.unpack_from("<II", data, 4)
    if version != 2:
        raise MeshError(f"{name}: GLB version {version}; shapeflow reads glTF 2.0")
    if length > len(data):
        raise MeshError(f"{name}: the GLB header declares {length} bytes, the file has {len(data)} (truncated?)")
    chunks, at = [], 12
    while at < length and len(chunks) < 2:      # JSON, then BIN; later chunks are ignored (spec)
        if at + 8 > length:
            raise MeshError(f"{name}: GLB chunk header at byte {at} runs past the end ({length} bytes)")
        size, kind = struct.unpack_from("<II", data, at)
        if size > length - at - 8:
            raise MeshError(f"{name}: GLB chunk at byte {at} declares {size} bytes; {length - at - 8} remain")
        chunks.append((kind, data[at + 8:at + 8 + size]))
        at += 8 + size
    if not chunks or chunks[0][0] != JSON_CHUNK:
        raise MeshError(f"{name}: the first GLB chunk is not JSON")
    binary = chunks[1][1] if len(chunks) > 1 and chunks[1][0] == BIN_CHUNK else None
    return _parse_json(chunks[0][1], name), binary


def source_folder(name: str) -> str:
    """The folder a file's relative URIs resolve in (the folder the file is named in)."""
    return os.path.dirname(os.path.abspath(name))


def _within(path: str, folder: str) -> bool:
    return path == folder or path.startswith(folder.rstrip(os.sep) + os.sep)


def resolve_uri(uri: str, folder: str | None, name: str, what: str) -> str:
    """The real path of the relative file URI ``uri`` inside ``folder``; everything else is refused."""
    if folder is None:
        raise MeshError(f"{name}: {what} refers to the file {shown(uri)}; a file read on its own (an upload) "
                        "may hold only data: URIs: embed it, or send a GLB")
    scheme = _SCHEME.match(uri)
    if scheme:
        raise MeshError(f"{name}: {what} {shown(uri)} is a URI with a scheme ({scheme.group(0)}); "
                        "only file names relative to the glTF file and data: URIs are read")
    try:
        path = unquote(uri, errors="strict")
    except UnicodeDecodeError:
        raise MeshError(f"{name}: {what} {shown(uri)} is not a valid percent-encoded UTF-8 file name") from None
    if not path or "\x00" in path:
        raise MeshError(f"{name}: {what} {shown(uri)} is not a file name")
    if path.startswith(("/", "\\")) or os.path.isabs(path):
        raise MeshError(f"{name}: {what} {shown(uri)} is an absolute path; only files beside the glTF file are read")
    here = os.path.realpath(folder)
    if not _within(os.path.normpath(os.path.join(here, path)), here):
        raise MeshError(f"{name}: {what} {shown(uri)} leaves the glTF file's folder ('..'); "
                        "only files beside it are read")
    real = os.path.realpath(os.path.join(here, path))
    if not _within(real, here):
        raise MeshError(f"{name}: {what} {shown(uri)} is a symbolic link leading outside the glTF file's "
                        f"folder (to {real}); only files beside it are read")
    pseudo = [p for p in _PSEUDO if _within(real, p) and not _within(here, p)]
    if pseudo:
        raise MeshError(f"{name}: {what} {shown(uri)} resolves to {real}, in {pseudo[0]}, which holds "
                        "no ordinary files")
    return real


def read_file(path: str, uri: str, name: str, what: str, length: int | None = None) -> bytes:
    """The first ``length`` bytes (None: all) of the regular file ``path`` (from :func:`resolve_uri`)."""
    flags = os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(path, flags)     # non-blocking: a FIFO put there opens at once and is refused below
        with os.fdopen(fd, "rb") as f:
            st = os.fstat(f.fileno())
            if not stat.S_ISREG(st.st_mode):
                raise MeshError(f"{name}: {what} {shown(uri)} is not a regular file "
                                "(a directory, device, FIFO or socket)")
            size = st.st_size if length is None else length
            if st.st_size < size:
                raise MeshError(f"{name}: {what} {shown(uri)} holds {st.st_size} bytes; {size} are declared")
            room(name, f"{what} ({size} bytes)", size)
            data = f.read(size)
    except OSError as exc:
        raise MeshError(f"{name}: {what} {shown(uri)} cannot be read: {exc.strerror or exc}") from None
    if len(data) < size:
        raise MeshError(f"{name}: {what} {shown(uri)} ended after {len(data)} of {size} bytes")
    return data


def decode_data_uri(uri: str, name: str, what: str) -> tuple[bytes, str]:
    """The bytes and media type of a ``data:...;base64,...`` URI (strict base64; other encodings refused)."""
    head, comma, payload = uri.partition(",")
    if not comma or not head.lower().endswith(";base64"):
        raise MeshError(f"{name}: {what} {shown(uri)} is a data: URI that is not base64")
    try:
        data = base64.b64decode(payload, validate=True)
    except (binascii.Error, ValueError) as exc:
        raise MeshError(f"{name}: {what} is a data: URI whose base64 is broken ({exc})") from None
    return data, head[5:-7]


def load_buffers(doc: dict, binary: bytes | None, folder: str | None, name: str) -> list[bytes]:
    """Every buffer's bytes (exactly its byteLength), from the GLB chunk, data: URIs or files beside."""
    out = []
    for i, buf in enumerate(items(doc, "buffers", name)):
        what = f"buffer {i}"
        if not isinstance(buf, dict):
            raise MeshError(f"{name}: {what} is not an object")
        length = field_int(buf, "byteLength", what, name, required=True)
        uri = buf.get("uri")
        if uri is None:
            if i != 0 or binary is None:
                raise MeshError(f"{name}: {what} has no uri, and only the first buffer of a GLB file may be "
                                "its binary chunk" + ("" if i else " (this file has none)"))
            blob = binary
        elif not isinstance(uri, str):
            raise MeshError(f"{name}: {what}: uri is not a string")
        elif uri[:5].lower() == "data:":
            blob = decode_data_uri(uri, name, what)[0]
        else:
            blob = read_file(resolve_uri(uri, folder, name, what), uri, name, what, length)
        if len(blob) < length:
            raise MeshError(f"{name}: {what} holds {len(blob)} bytes; its byteLength is {length}")
        out.append(blob if len(blob) == length else blob[:length])
    return out


def check_images(doc: dict, folder: str | None, name: str) -> None:
    """Every image URI names a data: URI or a regular file inside the folder (not read here)."""
    for k, img in enumerate(items(doc, "images", name)):
        if not isinstance(img, dict):
            raise MeshError(f"{name}: image {k} is not an object")
        uri = img.get("uri")
        if uri is None:
            continue
        if not isinstance(uri, str):
            raise MeshError(f"{name}: image {k}: uri is not a string")
        if uri[:5].lower() != "data:":
            path = resolve_uri(uri, folder, name, f"image {k}")
            try:
                mode = os.stat(path).st_mode
            except OSError:
                continue            # a missing texture: the mesh reads; writing names it
            if not stat.S_ISREG(mode):
                raise MeshError(f"{name}: image {k} {shown(uri)} is not a regular file "
                                "(a directory, device, FIFO or socket)")


def load_image(uri: str, folder: str | None, name: str, what: str) -> bytes:
    """An image file beside the glTF file, checked as on reading (for embedding it when writing)."""
    return read_file(resolve_uri(uri, folder, name, what), uri, name, what)


def check_extensions(doc: dict, name: str) -> None:
    """Refuse files that require an extension shapeflow cannot read (Draco, meshopt, instancing...)."""
    required = items(doc, "extensionsRequired", name)
    if not all(isinstance(e, str) for e in required):
        raise MeshError(f"{name}: extensionsRequired holds something other than names")
    bad = [e for e in required if e not in READABLE_EXTENSIONS and not e.startswith("KHR_materials_")]
    if bad:
        raise MeshError(f"{name}: the file requires the glTF extension(s) {', '.join(bad)}, which shapeflow "
                        "cannot read (it reads KHR_mesh_quantization; material and texture extensions pass through)")
