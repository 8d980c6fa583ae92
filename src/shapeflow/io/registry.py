"""The format registry and the two entry points, :func:`load` and :func:`save`."""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass
from typing import Callable

from .. import params
from ..errors import DataLossWarning, MeshError, ParameterError
from ..mesh import Mesh
from ..mesh.convert import as_mesh
from ..types import PathLike
from .atomic import as_path, atomic_write, read_bytes

__all__ = ["Reader", "Writer", "MeshFormat", "FORMATS", "register_format", "as_path", "format_for", "load", "save"]


Reader = Callable[..., Mesh]  # reader(data, name[, external_files=...]) -> Mesh
Writer = Callable[..., None]  # writer(f: BinaryIO, mesh: Mesh, *, binary: bool | None)


@dataclass(frozen=True)
class MeshFormat:
    """One mesh file format of the registry.

    ``reader(data, name)`` turns the file's bytes into a :class:`Mesh` and
    raises :class:`MeshError` naming ``name``; ``writer(f, mesh, binary=...)``
    writes to a binary file object (``binary=None`` means the format's
    default).  A format whose files can refer to other files (glTF buffers
    and images, USD sublayers, references and payloads) has ``external=True``
    and its reader takes the keyword ``external_files`` (see :func:`load`).
    """

    name: str
    extensions: tuple[str, ...]
    reader: Reader
    writer: Writer
    attributes: bool = False  #: stores per-vertex attributes
    binary: bool = False  #: has a binary variant
    external: bool = False  #: its files can refer to other files; the reader takes ``external_files=``


#: extension (lower case, with the dot) -> format
FORMATS: dict[str, MeshFormat] = {}


def register_format(fmt: MeshFormat) -> None:
    """Add (or replace) a format for each of its extensions."""
    for ext in fmt.extensions:
        ext = ext.lower()
        FORMATS[ext if ext.startswith(".") else "." + ext] = fmt




def format_for(name: str, format: str | None) -> MeshFormat:
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

def load(path: PathLike, *, format: str | None = None, external_files: bool = True) -> Mesh:
    """Read a mesh file (format from the extension, or ``format="ply"`` etc.).

    ``external_files=False`` refuses a file that refers to any other file (a
    glTF buffer or image given by URI, USD sublayers, references, payloads,
    value clips and asset paths): for files from elsewhere (uploads).  With
    ``True`` (the default) such files are read, and USD layers are composed
    only from files inside the file's own folder.

    Raises
    ------
    MeshError
        The file is missing, unreadable, malformed, refers to files it may
        not, or does not fit in memory; the message names the file and the
        line (text) or element (binary PLY), and the exception that stopped
        the reader, if any, is its ``__cause__``.
    """
    external_files = params.flag("external_files", external_files)
    name = as_path(path)
    fmt = format_for(name, format)
    data = read_bytes(name)
    try:
        if fmt.external:
            return fmt.reader(data, name, external_files=external_files)
        return fmt.reader(data, name)
    except MeshError as exc:
        if str(exc).startswith(name):
            raise
        raise MeshError(f"{name}: {exc}") from exc
    except (ImportError, NameError, Warning):   # a missing extra, a bug, a warning turned into an error
        raise
    except MemoryError as exc:
        raise MeshError(f"{name}: the {fmt.name} file does not fit in memory ({len(data):,} bytes)") from exc
    except RecursionError as exc:
        raise MeshError(f"{name}: the {fmt.name} file is nested too deeply to read") from exc
    except OSError as exc:
        raise MeshError(f"{name}: a file the {fmt.name} file refers to cannot be read: "
                        f"{exc.strerror or exc} ({type(exc).__name__})") from exc
    except Exception as exc:  # safety net: whatever a reader or its library raised on this file
        text = " ".join(str(exc).split())
        text = text if len(text) <= 300 else text[:297] + "..."
        raise MeshError(f"{name}: malformed {fmt.name} file ({type(exc).__name__}: {text})") from exc


def save(path: PathLike, mesh: Mesh, *, format: str | None = None, binary: bool | None = None,
         force: bool = False) -> None:
    """Write ``mesh`` atomically (format from the extension, or ``format=``).

    ``binary`` applies to PLY (default True: binary little-endian; False:
    ASCII); asking for a binary OBJ or OFF is an error.  OBJ and OFF drop the
    mesh's attributes.  A path that cannot be written (no such folder,
    read-only file without ``force``, disk full...) raises
    :class:`~shapeflow.errors.OutputError` (a ``ValueError`` and an
    ``OSError``) naming ``path``; nothing is left behind and an existing file
    is not touched.  A symbolic link is followed: its target is replaced.
    """
    mesh = as_mesh(mesh, "save()'s mesh")
    if binary is not None:
        binary = params.flag("binary", binary)
    force = params.flag("force", force)
    name = as_path(path)
    fmt = format_for(name, format)
    if binary and not fmt.binary:
        raise MeshError(f"{name}: {fmt.name} has no binary variant")
    _warn_lost_creases(mesh, name, fmt)
    try:
        atomic_write(name, lambda f: fmt.writer(f, mesh, binary=binary), force=force)
    except MeshError as exc:  # writers' messages do not know the file name
        raise MeshError(f"{name}: {exc}") from None


def _warn_lost_creases(mesh: Mesh, name, fmt) -> None:
    """A DataLossWarning when ``mesh.creases`` (a subdivision's) has creased edges and the format is
    not OBJ, the one that keeps them (``t crease`` lines)."""
    creases = getattr(mesh, "creases", None)
    if creases is None or fmt.name == "OBJ":
        return
    import numpy as np

    n = int((np.asarray(creases[1]) > 0).sum())
    if n:
        warnings.warn(DataLossWarning(f"{name}: the mesh's {n} creased edges are not written ({fmt.name} cannot "
                                      "store creases; an OBJ keeps them as 't crease' lines)"), stacklevel=3)
