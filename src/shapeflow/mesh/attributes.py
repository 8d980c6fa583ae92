"""Per-corner and per-face attributes, and the two compact kinds they come in.

A mesh carries, besides its per-vertex attributes:

* **corner attributes** (one value per face corner, in ``face_indices`` order):
  texture coordinates and split normals.  Either a plain ``(c, k)`` array, or
  :class:`Indexed` — a table of values and one index per corner (the layout of
  OBJ's ``vt``/``vn`` and of glTF's split vertices), so a file's tables and
  their sharing come back unchanged;
* **face attributes** (one value per face): numbers (``(m,)`` or ``(m, k)``
  arrays, e.g. a PLY face property) or :class:`Labels` — a name per face from a
  small table (OBJ ``usemtl``, ``g``, ``o``, ``s``).

Smoothing, enhancement and the brush move vertices and keep every attribute;
subdivision interpolates corner values (face-varying, linear) and gives each
new face its parent's face attributes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import MeshError

__all__ = ["Indexed", "Labels", "as_corner_attribute", "as_face_attribute", "expand"]


@dataclass(frozen=True, eq=False)
class Indexed:
    """Values shared through an index: ``values`` (t, k) and ``index`` (c,), -1 where a corner has none."""

    values: np.ndarray
    index: np.ndarray

    def expand(self, fill: float = np.nan) -> np.ndarray:
        """The (c, k) array of per-corner values (``fill`` where a corner has none)."""
        out = np.full((self.index.size,) + self.values.shape[1:], fill, dtype=self.values.dtype
                      if np.issubdtype(self.values.dtype, np.floating) else np.float64)
        have = self.index >= 0
        out[have] = self.values[self.index[have]]
        return out

    def __eq__(self, other) -> bool:
        return (isinstance(other, Indexed) and np.array_equal(self.values, other.values)
                and np.array_equal(self.index, other.index))

    __hash__ = None


@dataclass(frozen=True, eq=False)
class Labels:
    """A name per face: ``codes`` (m,) into ``names``, -1 for none."""

    codes: np.ndarray
    names: tuple

    def values(self) -> np.ndarray:
        """The (m,) array of names ('' for none)."""
        table = np.array(list(self.names) + [""], dtype=object)
        return table[np.where(self.codes >= 0, self.codes, len(self.names))]

    @classmethod
    def from_values(cls, values) -> "Labels":
        """Labels from a sequence of names (None or '' for none)."""
        arr = np.array(["" if v is None else str(v) for v in values], dtype=object)
        names, codes = np.unique(arr, return_inverse=True)
        names = list(names)
        if "" in names:
            empty = names.index("")
            codes = np.where(codes == empty, -1, codes - (codes > empty))
            names.pop(empty)
        return cls(codes.astype(np.int32), tuple(names))

    def __eq__(self, other) -> bool:
        return isinstance(other, Labels) and np.array_equal(self.values(), other.values())

    __hash__ = None


def expand(attr) -> np.ndarray:
    """Per-corner values of a corner attribute (plain arrays are returned as they are)."""
    return attr.expand() if isinstance(attr, Indexed) else attr


def _real(name: str, values, where: str) -> np.ndarray:
    try:
        a = np.array(values, copy=True)
        if a.dtype.kind not in "iuf":
            a = a.astype(np.float64)
        elif not a.dtype.isnative:
            a = a.astype(a.dtype.newbyteorder("="))
    except (TypeError, ValueError, OverflowError):
        raise MeshError(f"{where} attribute '{name}' must be real numbers") from None
    if a.ndim == 0:
        raise MeshError(f"{where} attribute '{name}' must be an array, got a scalar")
    if a.dtype.kind == "f" and not np.isfinite(a).all():
        raise MeshError(f"{where} attribute '{name}' has a non-finite value")
    a.flags.writeable = False
    return a


def as_corner_attribute(name: str, values, n_corners: int):
    """A validated, read-only corner attribute (a (c, ...) array or :class:`Indexed`)."""
    if isinstance(values, Indexed):
        table = _real(name, values.values, "corner")
        index = np.array(values.index, dtype=np.int64, copy=True).reshape(-1)
        if index.size != n_corners:
            raise MeshError(f"corner attribute '{name}' has {index.size} indices for {n_corners} corners")
        bad = np.flatnonzero((index < -1) | (index >= table.shape[0]))
        if bad.size:
            c = int(bad[0])
            raise MeshError(f"corner attribute '{name}': corner {c} refers to value {int(index[c])}, "
                            f"out of range [0, {table.shape[0]})")
        index.flags.writeable = False
        return Indexed(table, index)
    a = _real(name, values, "corner")
    if a.shape[0] != n_corners:
        raise MeshError(f"corner attribute '{name}' must have one value per corner ({n_corners}), got shape {a.shape}")
    return a


def as_face_attribute(name: str, values, n_faces: int):
    """A validated, read-only face attribute (an (m, ...) array or :class:`Labels`)."""
    if isinstance(values, Labels):
        codes = np.array(values.codes, dtype=np.int32, copy=True).reshape(-1)
        names = tuple(str(s) for s in values.names)
        if codes.size != n_faces:
            raise MeshError(f"face attribute '{name}' has {codes.size} labels for {n_faces} faces")
        if ((codes < -1) | (codes >= len(names))).any():
            raise MeshError(f"face attribute '{name}' has a code outside its {len(names)} names")
        codes.flags.writeable = False
        return Labels(codes, names)
    arr = np.asarray(values)
    if arr.dtype.kind in "USO":
        return as_face_attribute(name, Labels.from_values(arr.reshape(-1)), n_faces)
    a = _real(name, arr, "face")
    if a.shape[0] != n_faces:
        raise MeshError(f"face attribute '{name}' must have one value per face ({n_faces}), got shape {a.shape}")
    return a
