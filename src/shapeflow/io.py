"""Reading and writing meshes: OBJ, PLY (ASCII and binary) and OFF.

Formats
-------
The format is chosen from the file extension (case-insensitive) through the
registry :data:`FORMATS` (extension -> :class:`MeshFormat`, as in meshio), or
given explicitly with ``format=``.

========  ==========================================  =====================
ext       read                                        write
========  ==========================================  =====================
``.obj``  ``v`` and ``f`` lines (see below)           ``v`` / ``f`` lines
``.ply``  ASCII, binary little- and big-endian        binary little-endian
                                                      (``binary=False``:
                                                      ASCII)
``.off``  ``OFF`` and ``[ST][C][N]OFF`` (ASCII)       ``OFF``
========  ==========================================  =====================

Every reader keeps the face structure exactly as written: faces are never
triangulated, face order and corner order are kept, triangles, quads and
n-gons may be interleaved in any order, and every vertex is kept in file order
(unreferenced ones included).  Writers print floats with Python's shortest
round-trip ``repr``, so text round trips are bit-exact; binary PLY stores
float64.

Vertex attributes (e.g. the ``"weight"`` attribute) are kept by PLY only:
every 1-D attribute is written as a ``double`` vertex property of the same
name, and every scalar vertex property other than ``x y z`` is read back as a
float64 attribute.  OBJ and OFF have no place for them: :func:`save` drops the
attributes silently (as it does multi-column attributes for PLY).  Weights can
also travel in side files (``.npy`` or ``.txt``, one number a line) with
:func:`load_weights` and :func:`save_weights`.

OBJ details: ``v x y z [w]`` and ``v x y z r g b [a]`` (x y z are used);
``f`` (and the old ``fo``) with ``a``, ``a/b``, ``a//c`` and ``a/b/c`` corners
and negative (relative) indices; ``#`` comments, blank lines and backslash line
continuations; every other tag (``vt vn vp o g s usemtl mtllib l p``,
OpenSubdiv's ``t crease ...``, ...) is skipped.  A file without any ``v`` line
is an error.  OFF details: ``#`` comments, the counts on the header line or the
next, ``k i1 .. ik [colour]`` faces, extra per-vertex values (colours,
normals, texture coordinates) ignored; binary OFF and 4D/nD OFF are not
supported.  ASCII PLY is read one element per line.

Errors
------
Anything wrong with a file raises :class:`~shapeflow.errors.MeshError` whose
message starts with the file name, then where: ``line N`` for text formats,
the element for binary PLY (``face 17``).  A missing or unreadable file is a
MeshError too (the OSError, e.g. FileNotFoundError, is named in the message
and chained as ``__cause__``).

Saving is atomic: the data go to a temporary file in the target directory,
which is flushed, fsync'ed and renamed onto the target; on any error the
temporary file is removed and an existing target is left untouched.

Parsing is vectorised: the text is tokenised with numpy, tokens are grouped
by line, and numbers are converted in bulk (90k vertices / 180k faces load in
about 0.2 s).  Binary PLY lists of mixed sizes need one light Python loop over
the records to find their boundaries; uniform lists (all triangles, all
quads) are read as strided arrays.
"""

from __future__ import annotations

import errno
import os
import re
import stat
import tempfile
import warnings
from dataclasses import dataclass
from functools import lru_cache
from typing import BinaryIO, Callable

import numpy as np

from . import params
from .errors import MeshError, OutputError, ParameterError
from .mesh import Mesh

__all__ = [
    "load", "save", "load_weights", "save_weights", "atomic_write", "output_target",
    "MeshFormat", "FORMATS", "register_format", "WEIGHT_EXTENSIONS",
]

Reader = Callable[[bytes, str], Mesh]
Writer = Callable[..., None]  # writer(f: BinaryIO, mesh: Mesh, *, binary: bool | None)


@dataclass(frozen=True)
class MeshFormat:
    """One mesh file format of the registry.

    ``reader(data, name)`` turns the file's bytes into a :class:`Mesh` and
    raises :class:`MeshError` naming ``name``; ``writer(f, mesh, binary=...)``
    writes to a binary file object (``binary=None`` means the format's
    default).
    """

    name: str
    extensions: tuple[str, ...]
    reader: Reader
    writer: Writer
    attributes: bool = False  #: stores per-vertex attributes
    binary: bool = False  #: has a binary variant


#: extension (lower case, with the dot) -> format
FORMATS: dict[str, MeshFormat] = {}


def register_format(fmt: MeshFormat) -> None:
    """Add (or replace) a format for each of its extensions."""
    for ext in fmt.extensions:
        ext = ext.lower()
        FORMATS[ext if ext.startswith(".") else "." + ext] = fmt


def _path(path, what: str = "path") -> str:
    """A file path (str, bytes or os.PathLike) as str; anything else is a ParameterError."""
    try:
        name = os.fspath(path)
    except TypeError:
        raise ParameterError(f"{what} must be a file path (str or os.PathLike), got {path!r}") from None
    return os.fsdecode(name)


def _format_for(name: str, format: str | None) -> MeshFormat:
    if format is not None and not isinstance(format, str):
        raise ParameterError(f"format must be a string such as 'ply' or '.obj', got {format!r}")
    if format is not None:
        ext = format.lower()
        ext = ext if ext.startswith(".") else "." + ext
    else:
        ext = os.path.splitext(name)[1].lower()
    fmt = FORMATS.get(ext)
    if fmt is None:
        what = f"format '{format}'" if format is not None else (
            f"extension '{ext}'" if ext else "file without an extension")
        raise MeshError(f"{name}: unknown mesh {what}; supported: {', '.join(sorted(FORMATS))}")
    return fmt


# --------------------------------------------------------------------------
# public API
# --------------------------------------------------------------------------

def load(path, *, format: str | None = None) -> Mesh:
    """Read a mesh file (format from the extension, or ``format="ply"`` etc.).

    Raises
    ------
    MeshError
        The file is missing, unreadable or malformed; the message names the
        file and the line (text) or element (binary PLY).
    """
    name = _path(path)
    fmt = _format_for(name, format)
    data = _read_bytes(name)
    try:
        return fmt.reader(data, name)
    except MeshError:
        raise
    except (ValueError, IndexError, TypeError, KeyError, OverflowError) as exc:  # safety net
        raise MeshError(f"{name}: malformed {fmt.name} file ({type(exc).__name__}: {exc})") from exc


def save(path, mesh: Mesh, *, format: str | None = None, binary: bool | None = None, force: bool = False) -> None:
    """Write ``mesh`` atomically (format from the extension, or ``format=``).

    ``binary`` applies to PLY (default True: binary little-endian; False:
    ASCII); asking for a binary OBJ or OFF is an error.  OBJ and OFF drop the
    mesh's attributes.  A path that cannot be written (no such folder,
    read-only file without ``force``, disk full...) raises
    :class:`~shapeflow.errors.OutputError` (a ``ValueError`` and an
    ``OSError``) naming ``path``; nothing is left behind and an existing file
    is not touched.  A symbolic link is followed: its target is replaced.
    """
    if not isinstance(mesh, Mesh):
        raise ParameterError(f"save() needs a shapeflow.Mesh, got {type(mesh).__name__}")
    if binary is not None:
        binary = params.flag("binary", binary)
    force = params.flag("force", force)
    name = _path(path)
    fmt = _format_for(name, format)
    if binary and not fmt.binary:
        raise MeshError(f"{name}: {fmt.name} has no binary variant")
    try:
        atomic_write(name, lambda f: fmt.writer(f, mesh, binary=binary), force=force)
    except MeshError as exc:  # writers' messages do not know the file name
        raise MeshError(f"{name}: {exc}") from None


#: side-file formats for weights
WEIGHT_EXTENSIONS = (".npy", ".txt")


def load_weights(path, n_vertices: int) -> np.ndarray:
    """Read per-vertex weights from ``.npy`` or ``.txt`` (one number a line).

    Checks there are ``n_vertices`` finite values in [0, 1]; returns float64.
    """
    name = _path(path)
    ext = os.path.splitext(name)[1].lower()
    if ext not in WEIGHT_EXTENSIONS:
        raise MeshError(f"{name}: unknown weights file extension '{ext}'; use .npy or .txt")
    lines = None
    if ext == ".npy":
        try:
            with open(name, "rb") as f:
                _check_npy_header(f, name, n_vertices)
                w = np.load(f, allow_pickle=False)
        except MeshError:
            raise
        except OSError as exc:
            raise _os_error(name, exc) from exc
        except (ValueError, EOFError) as exc:
            raise MeshError(f"{name}: not a valid .npy array file ({exc})") from exc
        if not isinstance(w, np.ndarray) or w.dtype.kind not in "biuf":
            raise MeshError(f"{name}: weights must be real numbers, got dtype {getattr(w, 'dtype', type(w))}")
        if w.ndim == 2 and w.shape[1] == 1:
            w = w[:, 0]
        if w.ndim != 1:
            raise MeshError(f"{name}: weights must be a 1-D array, got shape {w.shape}")
        w = w.astype(np.float64)
    else:
        txt = _Text(_read_bytes(name), name, comments=True)
        bad = np.flatnonzero(txt.rec_count != 1)
        if bad.size:
            r = int(bad[0])
            raise txt.error(txt.rec_first[r], f"expected one number a line, got {int(txt.rec_count[r])}")
        w = txt.parse(txt.rec_first, np.float64, "number")
        lines = txt.rec_first
    where = (lambda i: f"line {txt.lineno(lines[i])}") if lines is not None else (lambda i: f"value {i}")
    return _check_weights(name, w, n_vertices, where)


def _check_npy_header(f, name: str, n_vertices: int) -> None:
    """Check a .npy header against the file's size and the mesh before NumPy allocates anything; rewinds ``f``."""
    fmt = np.lib.format
    try:
        version = fmt.read_magic(f)
        if version not in ((1, 0), (2, 0)):
            raise ValueError(f".npy format version {version[0]}.{version[1]} is not supported; use 1.0 or 2.0")
        shape, _, dtype = (fmt.read_array_header_1_0 if version == (1, 0) else fmt.read_array_header_2_0)(f)
    except (ValueError, EOFError, SyntaxError, TypeError) as exc:
        raise MeshError(f"{name}: not a valid .npy array file ({exc})") from None
    if len(shape) not in (1, 2) or (len(shape) == 2 and shape[1] != 1):
        raise MeshError(f"{name}: weights must be a 1-D array, got shape {shape}")
    if shape[0] != n_vertices:
        raise MeshError(f"{name}: has {shape[0]} weights but the mesh has {n_vertices} vertices")
    left = os.fstat(f.fileno()).st_size - f.tell()
    if dtype.itemsize and shape[0] * dtype.itemsize > left:
        raise MeshError(f"{name}: the header declares {shape[0]} values of {dtype.itemsize} bytes, but only "
                        f"{left} bytes follow (truncated file)")
    f.seek(0)


def save_weights(path, weights, *, force: bool = False) -> None:
    """Write weights atomically to ``.npy`` or ``.txt`` (one number a line, exact); ``force`` as in :func:`save`."""
    name = _path(path)
    ext = os.path.splitext(name)[1].lower()
    if ext not in WEIGHT_EXTENSIONS:
        raise MeshError(f"{name}: unknown weights file extension '{ext}'; use .npy or .txt")
    try:
        w = np.asarray(weights, dtype=np.float64)
    except (TypeError, ValueError):
        raise MeshError(f"{name}: weights must be numbers") from None
    if w.ndim != 1:
        raise MeshError(f"{name}: weights must be a 1-D array, got shape {w.shape}")
    w = _check_weights(name, w, w.size, lambda i: f"value {i}")
    if ext == ".npy":
        atomic_write(name, lambda f: np.save(f, w, allow_pickle=False), force=force)
    else:
        atomic_write(name, lambda f: _write_rows(f, "%r\n", w[:, None]), force=force)


def _check_weights(name: str, w: np.ndarray, n: int, where) -> np.ndarray:
    if w.shape[0] != n:
        raise MeshError(f"{name}: has {w.shape[0]} weights but the mesh has {n} vertices")
    bad = np.flatnonzero(~np.isfinite(w))
    if bad.size:
        i = int(bad[0])
        raise MeshError(f"{name}: {where(i)}: weight of vertex {i} is not finite ({float(w[i])!r})")
    bad = np.flatnonzero((w < 0) | (w > 1))
    if bad.size:
        i = int(bad[0])
        raise MeshError(f"{name}: {where(i)}: weight of vertex {i} is {float(w[i])!r}, outside [0, 1] "
                        f"({bad.size} such values)")
    return w


# --------------------------------------------------------------------------
# files
# --------------------------------------------------------------------------

def _os_error(name: str, exc: OSError) -> MeshError:
    return MeshError(f"{name}: cannot read file: {exc.strerror or exc} ({type(exc).__name__})")


def _read_bytes(name: str) -> bytes:
    try:
        # /dev/zero, a FIFO...: no end to trust (and opening a FIFO waits for a writer): checked first
        mode = os.stat(name).st_mode
        if not stat.S_ISREG(mode) and not stat.S_ISDIR(mode):   # a directory: open() names it below
            raise MeshError(f"{name}: not a regular file (a device, pipe or socket); give a file")
        with open(name, "rb") as f:
            return f.read()
    except OSError as exc:
        raise _os_error(name, exc) from exc


def _umask() -> int:
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)  # no way to read it without setting it
    os.umask(mask)
    return mask


def _bundled_data_dir() -> str:
    return os.path.realpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "data"))


def output_target(path, *, force: bool = False) -> str:
    """Check that ``path`` can be written, before any work; returns the file a write replaces.

    A symbolic link is followed to its final target, which is what gets
    replaced (GNU's rule: the link stays a link).  Refused with an
    :class:`~shapeflow.errors.OutputError` naming ``path``: a missing folder,
    a directory, shapeflow's bundled example data (never written), a folder
    without write permission, and a read-only file unless ``force``.
    """
    name = _path(path)
    if not name:
        raise OutputError("the output path is empty")
    target = os.path.realpath(name)
    folder = os.path.dirname(target)
    if os.path.isdir(target):
        raise OutputError(f"{name}: is a directory, not a file")
    if not os.path.isdir(folder):
        shown = os.path.dirname(name) or folder
        raise OutputError(f"{name}: the output folder {shown!r} does not exist")
    if os.path.commonpath([folder, _bundled_data_dir()]) == _bundled_data_dir():
        raise OutputError(f"{name}: is shapeflow's bundled example data, which is never written; "
                          "choose another output path")
    try:
        st = os.stat(target)
    except FileNotFoundError:
        st = None
    except OSError as exc:
        raise OutputError(f"{name}: cannot write: {exc.strerror or exc}") from None
    if st is not None and not force and (not st.st_mode & 0o222 or not os.access(target, os.W_OK)):
        raise OutputError(f"{name}: is read-only; pass --force (force=True) to replace it")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise OutputError(f"{name}: cannot write in the folder {folder!r} (permission denied)")
    return target


def atomic_write(name: str, write: Callable[[BinaryIO], None], *, force: bool = False) -> None:
    """Write through ``write(f)`` to an unnamed temporary file, fsync, then rename it onto ``name``.

    The file is created with ``O_TMPFILE`` where the platform has it: it has
    no name until the data is complete, so even a killed process leaves
    nothing behind; it gets a hidden name for the instant of the rename.
    Elsewhere a named temporary file is removed on any exception (the CLI
    turns SIGTERM and SIGHUP into one).  Errors name ``name``, not the
    temporary file.
    """
    target = output_target(name, force=force)
    directory = os.path.dirname(target)
    try:
        mode = stat.S_IMODE(os.stat(target).st_mode)
    except OSError:
        mode = 0o666 & ~_umask()
    tmp = None
    try:
        fd = _unnamed_file(directory)
        if fd is None:
            fd, tmp = tempfile.mkstemp(prefix="." + os.path.basename(target) + ".", suffix=".tmp", dir=directory)
        with os.fdopen(fd, "wb") as f:
            write(f)
            f.flush()
            os.fchmod(f.fileno(), mode)
            os.fsync(f.fileno())
            if tmp is None:   # give the finished file a name, for the rename only
                tmp = _link_unnamed(f.fileno(), directory, os.path.basename(target))
        os.replace(tmp, target)
        tmp = None
    except OSError as exc:
        raise OutputError(f"{name}: cannot write: {exc.strerror or exc}") from exc
    finally:
        if tmp is not None:
            try:
                os.unlink(tmp)
            except OSError:
                pass
    try:  # make the rename durable (best effort, POSIX only)
        dfd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(dfd)
    except OSError:
        pass
    finally:
        os.close(dfd)


def _unnamed_file(directory: str) -> int | None:
    """A file descriptor of a new unnamed file in ``directory`` (Linux ``O_TMPFILE``), or None."""
    flag = getattr(os, "O_TMPFILE", None)
    if flag is None or not os.path.isdir("/proc/self/fd"):
        return None
    try:
        return os.open(directory, flag | os.O_WRONLY, 0o600)
    except OSError as exc:
        if exc.errno in (errno.EOPNOTSUPP, errno.EISDIR, errno.EINVAL, errno.ENOENT):
            return None   # the file system has no unnamed files: a named temporary file instead
        raise


def _link_unnamed(fd: int, directory: str, base: str) -> str:
    """Give the unnamed file ``fd`` a fresh hidden name in ``directory``; returns the name."""
    # linkat(..., AT_SYMLINK_FOLLOW): os.link takes that path only when given a dir_fd
    dfd = os.open(directory, os.O_RDONLY)
    try:
        for _ in range(100):
            tmp = os.path.join(directory, f".{base}.{os.urandom(6).hex()}.tmp")
            try:
                os.link(f"/proc/self/fd/{fd}", tmp, src_dir_fd=dfd, follow_symlinks=True)
                return tmp
            except FileExistsError:
                continue
    finally:
        os.close(dfd)
    raise FileExistsError(errno.EEXIST, "no free temporary name", directory)


# --------------------------------------------------------------------------
# vectorised text tokenising
# --------------------------------------------------------------------------

_WS = np.zeros(256, dtype=bool)
_WS[[9, 10, 11, 12, 13, 32]] = True  # the bytes bytes.split() splits on
_COMMENT_RE = re.compile(rb"#[^\n]*")
_CONTINUATION_RE = re.compile(rb"\\[ \t\x0b\x0c]*\n")
_NUMBER_RE = {
    "f": re.compile(rb"[+-]?(?:(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|nan|inf|infinity)", re.IGNORECASE),
    "i": re.compile(rb"[+-]?\d+"),
}


def _fromstring(buf: bytes, dtype) -> np.ndarray | None:
    """Whitespace-separated numbers -> array, or None if some text is not a number."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)  # "could not be read to its end"
        try:
            return np.fromstring(buf, dtype=dtype, sep=" ")
        except (ValueError, DeprecationWarning):
            return None


def _ranges(starts: np.ndarray, lens: np.ndarray) -> np.ndarray:
    """Concatenation of ``arange(s, s + l)`` for each start and length."""
    lens = np.asarray(lens, dtype=np.int64)
    total = int(lens.sum())
    if total == 0:
        return np.zeros(0, dtype=np.int64)
    before = np.cumsum(lens) - lens
    return np.repeat(np.asarray(starts, np.int64) - before, lens) + np.arange(total, dtype=np.int64)


class _Text:
    """Whitespace tokens of a text file, grouped into records (non-blank lines).

    ``start``/``end`` are the byte ranges of the tokens; record ``r`` is the
    tokens ``rec_first[r] .. rec_first[r] + rec_count[r] - 1``.  Line endings
    ``\\r\\n`` and ``\\r`` count as ``\\n``; ``comments`` removes ``#`` to the end
    of a line; ``continuations`` joins lines ending in a backslash (line
    numbers in messages stay those of the file).
    """

    def __init__(self, data: bytes, name: str, *, line_offset: int = 0,
                 comments: bool = False, continuations: bool = False):
        self.name = name
        self.line_offset = line_offset
        if b"\r" in data:
            data = data.replace(b"\r\n", b"\n").replace(b"\r", b"\n")
        if comments and b"#" in data:
            data = _COMMENT_RE.sub(b"", data)  # keeps the newlines, so line numbers
        joined = None
        if continuations and b"\\" in data:
            joined = np.array([m.end() - 1 for m in _CONTINUATION_RE.finditer(data)], dtype=np.int64)
            if joined.size:
                # blank the backslashes (same length), and do not break lines at ``joined``
                data = _CONTINUATION_RE.sub(lambda m: b" " + m.group()[1:], data)
        self.data = data
        a = np.frombuffer(data, dtype=np.uint8)
        edge = np.diff(_WS[a].view(np.int8), prepend=np.int8(1), append=np.int8(1))
        self.start = np.flatnonzero(edge == -1)
        self.end = np.flatnonzero(edge == 1)
        nl = np.flatnonzero(a == 10)
        if joined is not None and joined.size:
            nl = np.setdiff1d(nl, joined, assume_unique=True)
        line = np.searchsorted(nl, self.start)
        new = np.ones(line.size, dtype=bool)
        np.not_equal(line[1:], line[:-1], out=new[1:])
        self.rec_first = np.flatnonzero(new)
        self.rec_count = np.diff(np.append(self.rec_first, line.size))
        self._padded = None

    @property
    def n_records(self) -> int:
        return self.rec_first.size

    def lineno(self, tok) -> int:
        """Line number (1-based, in the file) of token ``tok``."""
        return self.line_offset + self.data.count(b"\n", 0, int(self.start[int(tok)])) + 1

    def last_lineno(self) -> int:
        d = self.data
        return self.line_offset + d.count(b"\n") + (0 if d.endswith(b"\n") or not d else 1)

    def token(self, tok, end=None) -> str:
        s = int(self.start[int(tok)])
        e = int(self.end[int(tok)]) if end is None else int(end)
        t = self.data[s:e].decode("latin-1")
        return repr(t if len(t) <= 40 else t[:37] + "...")

    def error(self, tok, msg: str) -> MeshError:
        return MeshError(f"{self.name}: line {self.lineno(tok)}: {msg}")

    def error_at_end(self, msg: str) -> MeshError:
        return MeshError(f"{self.name}: line {self.last_lineno()}: {msg}")

    def parse(self, toks: np.ndarray, dtype, what: str, ends: np.ndarray | None = None) -> np.ndarray:
        """Convert tokens ``toks`` (increasing indices) to numbers, in bulk.

        ``ends`` overrides the tokens' end bytes (to read a prefix of each).
        """
        dtype = np.dtype(dtype)
        toks = np.asarray(toks, dtype=np.int64)
        n = toks.size
        if n == 0:
            return np.zeros(0, dtype=dtype)
        s = self.start[toks]
        e = self.end[toks] if ends is None else ends
        if ends is None and int(toks[-1] - toks[0]) == n - 1:  # a contiguous run of tokens
            buf = self.data[int(s[0]):int(e[-1])]
        else:
            if self._padded is None:
                self._padded = np.append(np.frombuffer(self.data, dtype=np.uint8), np.uint8(32))
            lens = e - s + 1  # each token and one separator
            idx = _ranges(s, lens)
            idx[np.cumsum(lens) - 1] = self._padded.size - 1
            buf = self._padded[idx].tobytes()
        out = _fromstring(buf, dtype)
        if out is None or out.size != n:
            self._raise_bad_number(toks, ends, dtype, what)
        return out

    def _raise_bad_number(self, toks, ends, dtype, what):
        pattern = _NUMBER_RE["f" if dtype.kind == "f" else "i"]
        data = self.data
        for j, t in enumerate(toks.tolist()):
            e = self.end[t] if ends is None else ends[j]
            if not pattern.fullmatch(data, int(self.start[t]), int(e)):
                raise self.error(t, f"{self.token(t, e)} is not a valid {what}")
        raise self.error(toks[0], f"cannot read the {what}s starting here")  # pragma: no cover


def _strip_bom(data: bytes) -> bytes:
    """``data`` without a leading UTF-8 byte-order mark (written by some editors)."""
    return data[3:] if data.startswith(b"\xef\xbb\xbf") else data


def _text_data(data: bytes, name: str, kind: str) -> bytes:
    """Checks common to text formats: not empty, not binary; strips a BOM."""
    data = _strip_bom(data)
    if not data.strip():
        raise MeshError(f"{name}: empty file")
    nul = data.find(b"\x00")
    if nul >= 0:
        line = data.count(b"\n", 0, nul) + 1
        raise MeshError(f"{name}: line {line}: binary data (NUL byte) in a text {kind} file")
    return data


def _build(name: str, vertices, sizes, indices, *, attributes=None,
           where_vertex=None, where_face=None) -> Mesh:
    """Make the Mesh; its validation errors are re-raised naming the file and place."""
    try:
        return Mesh.from_csr(vertices, sizes, indices, attributes=attributes)
    except MeshError as exc:
        msg = str(exc)
        m = re.search(r"\b(face|vertex) (\d+)\b", msg)
        where = None
        if m:
            fn = where_face if m.group(1) == "face" else where_vertex
            where = fn(int(m.group(2))) if fn is not None else None
        raise MeshError(f"{name}: {where}: {msg}" if where else f"{name}: {msg}") from None


# --------------------------------------------------------------------------
# OBJ
# --------------------------------------------------------------------------

_TAG_START = np.zeros(256, dtype=bool)
_TAG_START[np.frombuffer(b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz_", np.uint8)] = True
_TAG_CHAR = _TAG_START.copy()
_TAG_CHAR[np.frombuffer(b"0123456789.-", np.uint8)] = True
_NUMBER_START = np.zeros(256, dtype=bool)
_NUMBER_START[np.frombuffer(b"0123456789.-+", np.uint8)] = True


def _read_obj(data: bytes, name: str) -> Mesh:
    data = _text_data(data, name, "OBJ")
    txt = _Text(data, name, comments=True, continuations=True)
    if txt.n_records == 0:
        raise MeshError(f"{name}: no vertices (the file has only comments or blank lines)")
    rf, rc = txt.rec_first, txt.rec_count
    a = np.frombuffer(txt.data + b"  ", dtype=np.uint8)
    s = txt.start[rf]
    tlen = txt.end[rf] - s
    c0, c1 = a[s], a[s + 1]
    is_v = (tlen == 1) & (c0 == ord("v"))
    is_f = ((tlen == 1) & (c0 == ord("f"))) | ((tlen == 2) & (c0 == ord("f")) & (c1 == ord("o")))
    common = (tlen == 2) & (c0 == ord("v")) & ((c1 == ord("t")) | (c1 == ord("n")))
    other = np.flatnonzero(~(is_v | is_f | common))   # other tags (g, o, s, usemtl...): skipped if tag-like
    if other.size:
        so, lo = s[other], tlen[other]
        # a tag must be a letter or '_' followed by letters, digits, '_', '.', '-'
        chars = a[_ranges(so, lo)]
        ok = _TAG_CHAR[chars]
        first_ok = _TAG_START[a[so]]
        tag_ok = first_ok & (np.add.reduceat(~ok, np.cumsum(lo) - lo) == 0 if chars.size else first_ok)
        # an element tag glued to its first number ('f1 2 3', 'v0.5 1 2') is a typo, not a new tag
        c1o = a[so + 1]
        k = np.where((a[so] == ord("v")) & np.isin(c1o, np.frombuffer(b"tnp", np.uint8)) & (lo > 2), 2, 1)
        glued = np.isin(a[so], np.frombuffer(b"vflp", np.uint8)) & (lo > k) & _NUMBER_START[a[so + k]]
        bad = np.flatnonzero(~tag_ok | glued)
        if bad.size:
            r = int(other[bad[0]])
            tok = txt.token(rf[r])
            hint = " (a space missing after the tag?)" if glued[bad[0]] else ""
            raise txt.error(rf[r], f"unrecognised line starting with {tok}{hint}")

    # vertices: x y z [w] or x y z r g b [a]
    vrec = np.flatnonzero(is_v)
    n = vrec.size
    if n == 0:
        raise MeshError(f"{name}: no vertices (no 'v' lines)")
    vfirst = rf[vrec]
    nval = rc[vrec] - 1
    if not (nval == 3).all():
        bad = np.flatnonzero(~np.isin(nval, (3, 4, 6, 7)))
        if bad.size:
            i = int(bad[0])
            raise txt.error(vfirst[i], f"vertex line has {int(nval[i])} values; expected x y z [w] or x y z r g b")
    vtok = (vfirst[:, None] + np.arange(1, 4)).reshape(-1)  # x y z, after the tag
    vertices = txt.parse(vtok, np.float64, "vertex coordinate").reshape(n, 3)

    # faces: f a a/b a//c a/b/c, 1-based or negative (relative to the vertices so far)
    frec = np.flatnonzero(is_f)
    ffirst = rf[frec]
    sizes = rc[frec] - 1
    small = np.flatnonzero(sizes < 3)
    if small.size:
        i = int(small[0])
        raise txt.error(ffirst[i], f"face has {int(sizes[i])} corners; a face needs at least 3")
    ftok = _ranges(ffirst + 1, sizes)
    ends = None
    if b"/" in txt.data and ftok.size:
        slashes = np.flatnonzero(a[:-2] == ord("/"))
        ts, te = txt.start[ftok], txt.end[ftok]
        j = np.searchsorted(slashes, ts)
        first_slash = np.append(slashes, a.size)[j]
        ends = np.minimum(te, first_slash)
        empty = np.flatnonzero(ends == ts)
        if empty.size:
            t = ftok[int(empty[0])]
            raise txt.error(t, f"face corner {txt.token(t)} has no vertex index")
    raw = txt.parse(ftok, np.int64, "vertex index", ends=ends)
    zero = np.flatnonzero(raw == 0)
    if zero.size:
        raise txt.error(ftok[int(zero[0])], "vertex index 0 (OBJ indices start at 1)")
    idx = raw - 1
    neg = raw < 0
    if neg.any():
        defined = np.repeat(np.searchsorted(vrec, frec), sizes)  # 'v' lines before each face line
        idx = np.where(neg, defined + raw, idx)
        bad = np.flatnonzero(neg & (idx < 0))
        if bad.size:
            c = int(bad[0])
            raise txt.error(ftok[c], f"relative vertex index {int(raw[c])} reaches before the first vertex "
                            f"(only {int(defined[c])} defined before this line)")
    bad = np.flatnonzero(idx >= n)
    if bad.size:
        c = int(bad[0])
        raise txt.error(ftok[c], f"vertex index {int(raw[c])} out of range: the file has {n} vertices")
    return _build(name, vertices, sizes, idx,
                  where_vertex=lambda i: f"line {txt.lineno(vfirst[i])}",
                  where_face=lambda f: f"line {txt.lineno(ffirst[f])}")


@lru_cache(maxsize=None)
def _face_template(prefix: str, k: int) -> str:
    return prefix + " %d" * k + "\n"


def _write_rows(f: BinaryIO, row_format: str, rows: np.ndarray, chunk: int = 65536) -> None:
    """Write a float array row by row with a %-format (``%r`` = exact repr)."""
    for i in range(0, rows.shape[0], chunk):
        block = rows[i:i + chunk]
        f.write(((row_format * block.shape[0]) % tuple(block.ravel().tolist())).encode("ascii"))


def _write_faces_text(f: BinaryIO, mesh: Mesh, prefix: str, base: int, with_size: bool,
                      chunk: int = 65536) -> None:
    sizes = mesh.face_sizes
    offsets = mesh.face_offsets
    indices = mesh.face_indices
    for i in range(0, sizes.size, chunk):
        ks = sizes[i:i + chunk].tolist()
        fmt = "".join([_face_template(f"{prefix}{k}" if with_size else prefix, k) for k in ks])
        corners = indices[offsets[i]:offsets[min(i + chunk, sizes.size)]]
        f.write((fmt % tuple((corners + base).tolist())).encode("ascii"))


def _write_obj(f: BinaryIO, mesh: Mesh, *, binary: bool | None = None) -> None:
    f.write(f"# shapeflow: {mesh.n_vertices} vertices, {mesh.n_faces} faces\n".encode())
    _write_rows(f, "v %r %r %r\n", mesh.vertices)
    _write_faces_text(f, mesh, "f", 1, with_size=False)


# --------------------------------------------------------------------------
# OFF
# --------------------------------------------------------------------------

_OFF_RE = re.compile(rb"(ST)?(C)?(N)?(4)?(n)?OFF")


def _read_off(data: bytes, name: str) -> Mesh:
    data = _text_data(data, name, "OFF")
    txt = _Text(data, name, comments=True)
    rf, rc = txt.rec_first, txt.rec_count
    if txt.n_records == 0:
        raise MeshError(f"{name}: empty file (only comments)")
    head = rf[0]
    m = _OFF_RE.fullmatch(txt.data, int(txt.start[head]), int(txt.end[head]))
    if not m:
        raise txt.error(head, f"not an OFF file: the header is {txt.token(head)}, expected 'OFF' (or COFF, NOFF...)")
    if m.group(4) or m.group(5):
        raise txt.error(head, "4D and nD OFF files are not supported")
    if rc[0] > 1:  # counts on the header line
        if txt.data[txt.start[head + 1]:txt.end[head + 1]] == b"BINARY":
            raise txt.error(head, "binary OFF is not supported")
        ctoks, nctok, first_data = head + 1 + np.arange(rc[0] - 1), rc[0] - 1, 1
    else:
        if txt.n_records < 2:
            raise txt.error_at_end("file ends before the vertex/face counts line")
        ctoks, nctok, first_data = rf[1] + np.arange(rc[1]), rc[1], 2
    if nctok not in (2, 3):
        raise txt.error(ctoks[0], f"expected the counts 'vertices faces [edges]', got {nctok} values")
    counts = txt.parse(ctoks, np.int64, "count")
    if (counts < 0).any():
        raise txt.error(ctoks[0], f"negative count in {counts.tolist()}")
    nv, nf = int(counts[0]), int(counts[1])
    have = txt.n_records - first_data
    if have < nv + nf:
        got_v = min(have, nv)
        what = (f"{got_v} of {nv} vertices" if got_v < nv else f"{have - nv} of {nf} faces")
        raise txt.error_at_end(f"file ends after {what} (truncated, or wrong counts in the header)")
    if have > nv + nf:
        r = first_data + nv + nf
        raise txt.error(rf[r], f"unexpected data after the last face (the header says {nv} vertices, "
                        f"{nf} faces)")
    vr = np.arange(first_data, first_data + nv)
    few = np.flatnonzero(rc[vr] < 3)
    if few.size:
        r = int(vr[few[0]])
        raise txt.error(rf[r], f"vertex line has {int(rc[r])} values, needs at least 3 (x y z)")
    vfirst = rf[vr]
    vertices = txt.parse((vfirst[:, None] + np.arange(3)).reshape(-1), np.float64,
                         "vertex coordinate").reshape(nv, 3)
    fr = np.arange(first_data + nv, first_data + nv + nf)
    ffirst = rf[fr]
    sizes = txt.parse(ffirst, np.int64, "face size")
    small = np.flatnonzero(sizes < 3)
    if small.size:
        i = int(small[0])
        raise txt.error(ffirst[i], f"face has {int(sizes[i])} corners; a face needs at least 3")
    short = np.flatnonzero(rc[fr] - 1 < sizes)
    if short.size:
        i = int(short[0])
        raise txt.error(ffirst[i], f"face line says {int(sizes[i])} corners but lists {int(rc[fr[i]] - 1)} values")
    ftok = _ranges(ffirst + 1, sizes)
    idx = txt.parse(ftok, np.int64, "vertex index")
    bad = np.flatnonzero((idx < 0) | (idx >= nv))
    if bad.size:
        c = int(bad[0])
        raise txt.error(ftok[c], f"vertex index {int(idx[c])} out of range [0, {nv})")
    return _build(name, vertices, sizes, idx,
                  where_vertex=lambda i: f"line {txt.lineno(vfirst[i])}",
                  where_face=lambda f: f"line {txt.lineno(ffirst[f])}")


def _write_off(f: BinaryIO, mesh: Mesh, *, binary: bool | None = None) -> None:
    f.write(f"OFF\n{mesh.n_vertices} {mesh.n_faces} 0\n".encode())
    _write_rows(f, "%r %r %r\n", mesh.vertices)
    _write_faces_text(f, mesh, "", 0, with_size=True)


# --------------------------------------------------------------------------
# PLY
# --------------------------------------------------------------------------

_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}
_PLY_FORMATS = {"ascii": None, "binary_little_endian": "<", "binary_big_endian": ">"}
_END_HEADER_RE = re.compile(rb"^end_header[ \t]*(?:\r?\n|$)", re.MULTILINE)
_FACE_LISTS = ("vertex_indices", "vertex_index")


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
    order = False
    elements: list[_Element] = []
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
            twin = next((el for el in elements if el.name == words[1]), None)
            if twin is not None:
                raise err(f"a second '{words[1]}' element (the first is on line {twin.line}); "
                          "which one holds the mesh is ambiguous")
            elements.append(_Element(words[1], int(words[2]), ln, []))
        elif key == "property":
            if not elements:
                raise err("property before any element")
            if len(words) >= 3 and any(p.name == words[-1] for p in elements[-1].props):
                raise err(f"property '{words[-1]}' of element '{elements[-1].name}' is declared twice; "
                          "which one holds the values is ambiguous")
            if len(words) == 3 and words[1] in _PLY_TYPES:
                elements[-1].props.append(_Prop(words[2], np.dtype(_PLY_TYPES[words[1]])))
            elif (len(words) == 5 and words[1] == "list" and words[2] in _PLY_TYPES
                  and words[3] in _PLY_TYPES and _PLY_TYPES[words[2]][0] in "iu"):
                elements[-1].props.append(
                    _Prop(words[4], np.dtype(_PLY_TYPES[words[3]]), np.dtype(_PLY_TYPES[words[2]])))
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


def _read_ascii_element(txt: _Text, r0: int, el: _Element, name: str):
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
        vals = txt.parse(_ranges(first, have), np.float64, f"{el.name} value").reshape(n, k)
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
            out[p.name] = (c, txt.parse(_ranges(cur + 1, c), kind, f"'{p.name}' value"))
            cur = cur + 1 + c
    extra = np.flatnonzero(cur != stop)
    if extra.size:
        i = int(extra[0])
        raise txt.error(first[i], f"'{el.name}' line has {int(stop[i] - cur[i])} values too many")
    return out


def _read_ply(data: bytes, name: str) -> Mesh:
    if not data.strip():
        raise MeshError(f"{name}: empty file")
    data = _strip_bom(data)   # the header is text even when the body is binary
    first_line = data.split(b"\n", 1)[0].strip()
    if first_line != b"ply":
        raise MeshError(f"{name}: line 1: not a PLY file (the first line must be 'ply')")
    m = _END_HEADER_RE.search(data)
    if not m:
        raise MeshError(f"{name}: PLY header has no 'end_header' line (truncated or not a PLY file)")
    try:   # comments and obj_info may hold any UTF-8 text; keywords are checked to be ASCII
        header = data[:m.start()].decode("utf-8").replace("\r", "")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise MeshError(f"{name}: line {line}: PLY header is not UTF-8 text") from None
    order, elements = _parse_ply_header(header, name)
    body = data[m.end():]
    found: dict[str, dict] = {}
    if order is None:  # ASCII
        if b"\x00" in body:
            line = data.count(b"\n", 0, m.end() + body.find(b"\x00")) + 1
            raise MeshError(f"{name}: line {line}: binary data (NUL byte) in an ASCII PLY file")
        txt = _Text(body, name, line_offset=data.count(b"\n", 0, m.end()))
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
    else:
        arr = np.frombuffer(body, dtype=np.uint8)
        pos = 0
        for el in elements:
            values, pos = _read_binary_element(body, arr, pos, el, name)
            found.setdefault(el.name, values)
        if pos < len(body) and body[pos:].strip():
            last = elements[-1].name if elements else "header"
            raise MeshError(f"{name}: {len(body) - pos} bytes of unexpected data after the last element "
                            f"('{last}'); wrong counts in the header?")
        vloc = floc = None  # messages name "vertex i" / "face f" already

    vel = next((el for el in elements if el.name == "vertex"), None)
    if vel is None:
        raise MeshError(f"{name}: PLY file has no 'vertex' element")
    vals = found["vertex"]
    scal = {p.name: p for p in vel.props if not p.is_list}
    for axis in "xyz":
        if axis not in scal:
            raise MeshError(f"{name}: line {vel.line}: the vertex element has no scalar '{axis}' property")
    vertices = np.column_stack([np.asarray(vals[a], dtype=np.float64) for a in "xyz"])
    # attributes keep the file's type (ASCII integers are parsed as float64, checked, then cast back)
    attributes = {}
    for p in vel.props:
        if p.is_list or p.name in ("x", "y", "z"):
            continue
        v = np.asarray(vals[p.name])
        dt = p.dtype.newbyteorder("=")
        if dt.kind in "iu" and v.dtype.kind == "f":
            info = np.iinfo(dt)
            bad = np.flatnonzero((v != np.rint(v)) | (v < info.min) | (v > info.max))
            if bad.size:
                i = int(bad[0])
                raise MeshError(_at(name, vloc(i) if vloc else f"vertex {i}",
                                    f"property '{p.name}' is {np.dtype(dt).name} but has the value {v[i]!r}"))
        # ASCII floats keep the text's precision (parsed as float64); everything else its declared type
        attributes[p.name] = v if (dt.kind == "f" and v.dtype == np.float64) else v.astype(dt)
    nv = vertices.shape[0]
    fel = next((el for el in elements if el.name == "face"), None)
    if fel is None:
        sizes, idx = np.zeros(0, np.int64), np.zeros(0, np.int64)
    else:
        lists = [p for p in fel.props if p.is_list]
        named = [p for p in lists if p.name in _FACE_LISTS]
        plist = named[0] if named else (lists[0] if len(lists) == 1 else None)
        if plist is None:
            raise MeshError(f"{name}: line {fel.line}: the face element has no 'vertex_indices' list")
        if plist.dtype.kind not in "iu":
            raise MeshError(f"{name}: line {fel.line}: face '{plist.name}' must be an integer list")
        sizes, idx = found["face"][plist.name]
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
    return _build(name, vertices, sizes, idx, attributes=attributes, where_vertex=vloc, where_face=floc)


def _at(name: str, where: str | None, msg: str) -> str:
    return f"{name}: {where}: {msg}" if where else f"{name}: {msg}"


def _first_record(elements: list[_Element], which: str) -> int:
    r = 0
    for el in elements:
        if el.name == which:
            return r
        r += el.count
    return r  # pragma: no cover


def _ply_attributes(mesh: Mesh) -> dict[str, np.ndarray]:
    """The attributes PLY can store: 1-D ones with a name that is one word."""
    out = {}
    for key, values in mesh.attributes.items():
        if values.ndim != 1:
            continue  # multi-column attributes are not written (documented)
        if not key or any(ch.isspace() for ch in key) or not key.isascii() or key in ("x", "y", "z"):
            raise MeshError(f"attribute name {key!r} cannot be a PLY property name")
        out[key] = values
    return out


#: NumPy type -> PLY type name: _PLY_TYPES read backwards, the classic names (char, uchar, ...) winning
_PLY_NAMES = {code: name for name, code in reversed(list(_PLY_TYPES.items()))}


def _ply_type(values: np.ndarray) -> np.dtype:
    dt = values.dtype
    if dt.kind in "iu" and dt.itemsize == 8:
        fits = values.size == 0 or (int(values.min()) >= -2**31 and int(values.max()) < 2**31)
        return np.dtype("i4") if fits else np.dtype("f8")
    key = f"{dt.kind}{dt.itemsize}"
    return np.dtype(key) if key in _PLY_NAMES else np.dtype("f8")


def _write_ply(f: BinaryIO, mesh: Mesh, *, binary: bool | None = None, byteorder: str = "<") -> None:
    binary = True if binary is None else bool(binary)
    attrs = _ply_attributes(mesh)
    types = {k: _ply_type(v) for k, v in attrs.items()}
    sizes = mesh.face_sizes
    count_type = "uchar" if sizes.size == 0 or int(sizes.max()) <= 255 else "int"
    fmt = ("binary_little_endian" if byteorder == "<" else "binary_big_endian") if binary else "ascii"
    head = ["ply", f"format {fmt} 1.0", "comment written by shapeflow",
            f"element vertex {mesh.n_vertices}",
            "property double x", "property double y", "property double z"]
    head += [f"property {_PLY_NAMES[f'{types[k].kind}{types[k].itemsize}']} {k}" for k in attrs]
    head += [f"element face {mesh.n_faces}", f"property list {count_type} int vertex_indices", "end_header"]
    f.write(("\n".join(head) + "\n").encode("ascii"))
    if not binary:   # integers exactly as %d (every PLY integer type fits a double exactly)
        columns = np.column_stack([mesh.vertices] + [v.astype(np.float64)[:, None] for v in attrs.values()])
        fmts = ["%r"] * 3 + ["%d" if types[k].kind in "iu" else "%r" for k in attrs]
        _write_rows(f, " ".join(fmts) + "\n", columns)
        _write_faces_text(f, mesh, "", 0, with_size=True)
        return
    rec = np.empty(mesh.n_vertices, dtype=[("xyz", byteorder + "f8", (3,))]
                   + [(f"a{i}", types[k].newbyteorder(byteorder)) for i, k in enumerate(attrs)])
    rec["xyz"] = mesh.vertices
    for i, (k, v) in enumerate(attrs.items()):
        rec[f"a{i}"] = v
    f.write(rec.tobytes())
    cdt = np.dtype(byteorder + ("u1" if count_type == "uchar" else "i4"))
    idt = np.dtype(byteorder + "i4")
    offsets, indices = mesh.face_offsets, mesh.face_indices
    chunk = 1 << 18
    for f0 in range(0, sizes.size, chunk):
        f1 = min(f0 + chunk, sizes.size)
        s = sizes[f0:f1]
        c0, c1 = int(offsets[f0]), int(offsets[f1])
        m, ncorner = f1 - f0, c1 - c0
        csz, isz = cdt.itemsize, idt.itemsize
        out = np.empty(m * csz + ncorner * isz, dtype=np.uint8)
        face_at = (offsets[f0:f1] - c0) * isz + np.arange(m) * csz
        out[face_at[:, None] + np.arange(csz)] = s.astype(cdt).view(np.uint8).reshape(m, csz)
        corner_face = np.repeat(np.arange(m), s)
        corner_at = np.arange(ncorner) * isz + (corner_face + 1) * csz
        out[corner_at[:, None] + np.arange(isz)] = indices[c0:c1].astype(idt).view(np.uint8).reshape(ncorner, isz)
        f.write(out.tobytes())


register_format(MeshFormat("OBJ", (".obj",), _read_obj, _write_obj))
register_format(MeshFormat("OFF", (".off",), _read_off, _write_off))
register_format(MeshFormat("PLY", (".ply",), _read_ply, _write_ply, attributes=True, binary=True))
