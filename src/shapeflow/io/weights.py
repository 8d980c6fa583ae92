"""Per-vertex weight side files (``.npy`` or ``.txt``)."""

from __future__ import annotations

import os

import numpy as np

from ..errors import MeshError
from ..mesh.weights import check_weights
from ..types import ArrayLike, PathLike
from .atomic import as_path, atomic_write, os_error, read_bytes
from .text import Text, write_rows

__all__ = ["WEIGHT_EXTENSIONS", "load_weights", "save_weights", "check_npy_header", "check_weights"]


#: side-file formats for weights
WEIGHT_EXTENSIONS = (".npy", ".txt")


def load_weights(path: PathLike, n_vertices: int) -> np.ndarray:
    """Read per-vertex weights from ``.npy`` or ``.txt`` (one number a line).

    Checks there are ``n_vertices`` finite values in [0, 1]; returns float64.
    """
    name = as_path(path)
    ext = os.path.splitext(name)[1].lower()
    if ext not in WEIGHT_EXTENSIONS:
        raise MeshError(f"{name}: unknown weights file extension '{ext}'; use .npy or .txt")
    lines = None
    if ext == ".npy":
        try:
            with open(name, "rb") as f:
                check_npy_header(f, name, n_vertices)
                w = np.load(f, allow_pickle=False)
        except MeshError:
            raise
        except OSError as exc:
            raise os_error(name, exc) from exc
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
        txt = Text(read_bytes(name), name, comments=True)
        bad = np.flatnonzero(txt.rec_count != 1)
        if bad.size:
            r = int(bad[0])
            raise txt.error(txt.rec_first[r], f"expected one number a line, got {int(txt.rec_count[r])}")
        w = txt.parse(txt.rec_first, np.float64, "number")
        lines = txt.rec_first
    where = (lambda i: f"line {txt.lineno(lines[i])}") if lines is not None else (lambda i: f"value {i}")
    return check_weights(name, w, n_vertices, where)


def check_npy_header(f, name: str, n_vertices: int) -> None:
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


def save_weights(path: PathLike, weights: ArrayLike, *, force: bool = False) -> None:
    """Write weights atomically to ``.npy`` or ``.txt`` (one number a line, exact); ``force`` as in :func:`save`."""
    name = as_path(path)
    ext = os.path.splitext(name)[1].lower()
    if ext not in WEIGHT_EXTENSIONS:
        raise MeshError(f"{name}: unknown weights file extension '{ext}'; use .npy or .txt")
    try:
        w = np.asarray(weights, dtype=np.float64)
    except (TypeError, ValueError):
        raise MeshError(f"{name}: weights must be numbers") from None
    if w.ndim != 1:
        raise MeshError(f"{name}: weights must be a 1-D array, got shape {w.shape}")
    w = check_weights(name, w, w.size, lambda i: f"value {i}")
    if ext == ".npy":
        atomic_write(name, lambda f: np.save(f, w, allow_pickle=False), force=force)
    else:
        atomic_write(name, lambda f: write_rows(f, "%r\n", w[:, None]), force=force)

