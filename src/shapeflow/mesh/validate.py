"""Normalisation and validation of vertex, face and attribute input (the only place face layouts are accepted).

Accepted face inputs: a list of lists (ragged), an (m, k) integer array
(k >= 3), or a CSR pair (``face_indices`` + ``face_offsets``).  Everything
that is not a valid mesh raises :class:`~shapeflow.errors.MeshError` naming
the offending face, vertex or attribute.
"""

from __future__ import annotations

import itertools

import numpy as np

from .. import accel
from ..errors import MeshError
from ..types import Faces
from .weights import WEIGHT, check_weights

__all__ = ["WEIGHT", "as_vertices", "as_index_array", "normalize_faces", "validate_csr", "as_attribute"]


def as_vertices(vertices) -> np.ndarray:
    try:
        v = np.asarray(vertices)
    except Exception as exc:  # ragged input etc.
        raise MeshError(f"vertices are not an (n, 3) array of numbers: {exc}") from None
    if v.dtype == object or not (np.issubdtype(v.dtype, np.number) or v.dtype == bool):
        raise MeshError(f"vertices must be numbers, got dtype {v.dtype}")
    if np.iscomplexobj(v):
        raise MeshError("vertices must be real numbers, got complex values")
    if v.ndim != 2 or v.shape[1] != 3:
        raise MeshError(f"vertices must have shape (n, 3), got {v.shape}")
    v = np.array(v, dtype=np.float64, order="C", copy=True)
    if np.isfinite(v).all():    # one flat pass; the per-vertex detail only for the message
        return v
    bad = ~np.isfinite(v).all(axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise MeshError(
            f"vertex {i} has a non-finite coordinate {v[i].tolist()} "
            f"({int(bad.sum())} such vertices)"
        )
    return v


def as_index_array(a, what: str) -> np.ndarray:
    arr = np.asarray(a)
    if arr.size == 0:
        return np.zeros(0, dtype=np.int64)
    if arr.dtype == object or not np.issubdtype(arr.dtype, np.integer):
        if np.issubdtype(arr.dtype, np.floating) and np.all(np.isfinite(arr)) and np.all(arr == np.round(arr)):
            return arr.astype(np.int64).reshape(-1)
        raise MeshError(f"{what} must be integers, got dtype {arr.dtype}")
    return arr.astype(np.int64, copy=False).reshape(-1)


def normalize_faces(faces: Faces) -> tuple[np.ndarray, np.ndarray]:
    """Turn any accepted face layout into ``(face_indices, face_offsets)``.

    Accepts a list (or tuple) of index sequences of any lengths, or an (m, k)
    integer array.  Structural checks (face sizes, index range, repeated
    vertices) are done by :class:`Mesh`, which knows the vertex count.
    """
    if isinstance(faces, np.ndarray) and faces.dtype != object:
        if faces.ndim != 2:
            if faces.size == 0:
                return np.zeros(0, np.int64), np.zeros(1, np.int64)
            raise MeshError(
                f"a face array must have shape (m, k) with k >= 3, got {faces.shape}; "
                "use a list of lists or Mesh.from_csr for mixed face sizes"
            )
        m, k = faces.shape
        if m and k < 3:
            raise MeshError(f"a face array must have shape (m, k) with k >= 3, got {faces.shape}")
        idx = as_index_array(faces, "face indices")
        return idx, np.arange(m + 1, dtype=np.int64) * k
    try:
        seq = list(faces)
    except TypeError:
        raise MeshError(f"faces must be a list of index lists or an (m, k) array, got {type(faces).__name__}") from None
    sizes = np.empty(len(seq), dtype=np.int64)
    try:
        for i, f in enumerate(seq):
            sizes[i] = len(f)
    except TypeError:
        raise MeshError(f"face {i} is not a sequence of vertex indices: {f!r}") from None
    flat = list(itertools.chain.from_iterable(seq))
    idx = as_index_array(flat, "face indices")
    offsets = np.zeros(len(seq) + 1, dtype=np.int64)
    np.cumsum(sizes, out=offsets[1:])
    return idx, offsets


def validate_csr(indices: np.ndarray, offsets: np.ndarray, n: int) -> None:
    if offsets.ndim != 1 or offsets.size < 1 or offsets[0] != 0 or offsets[-1] != indices.size:
        raise MeshError(
            f"face offsets must start at 0 and end at the number of corners ({indices.size}); "
            f"got {offsets.size} offsets"
        )
    accel.kernels("mesh", n).check_faces(indices, offsets, n)


def as_attribute(name: str, values, n: int) -> np.ndarray:
    """A copy of ``values`` as an attribute: integer and float32 arrays keep their type (a file's
    ``uchar`` colours stay ``uchar``), anything else becomes float64; weights are always float64."""
    try:
        a = np.array(values, copy=True)
        if a.dtype.kind not in "iufbO":   # strings, bytes, complex...: not real numbers
            raise TypeError
        if a.dtype.kind == "O" and any(isinstance(v, (str, bytes, complex)) for v in a.reshape(-1)):
            raise TypeError
        if name == WEIGHT or a.dtype.kind not in "iuf" or a.dtype.itemsize > 8:
            a = a.astype(np.float64)
        elif not a.dtype.isnative:
            a = a.astype(a.dtype.newbyteorder("="))
    except (TypeError, ValueError, OverflowError):
        raise MeshError(f"attribute '{name}' must be real numbers, got dtype {np.asarray(values).dtype}") from None
    if a.ndim == 0 or a.shape[0] != n:
        raise MeshError(f"attribute '{name}' must have one value per vertex ({n}), got shape {a.shape}")
    if not np.isfinite(a).all():
        i = int(np.flatnonzero(~np.isfinite(a.reshape(n, -1)).all(axis=1))[0])
        raise MeshError(f"attribute '{name}' has a non-finite value at vertex {i}")
    if name == WEIGHT:
        check_weights("weights", a, n)
    a.flags.writeable = False
    return a
