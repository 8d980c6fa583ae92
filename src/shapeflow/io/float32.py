"""Coordinates for the formats that store float32 (STL, glTF/GLB, USD points): checked, then cast.

A float64 mesh may hold coordinates float32 cannot: beyond ±3.4e38 they would become infinities,
and a mesh whose every coordinate is below float32's smallest normal number (1.2e-38) would
collapse to zeros and subnormals.  Such a mesh is refused by name; PLY, OBJ and OFF keep doubles.
"""

from __future__ import annotations

import numpy as np

from ..errors import MeshError

__all__ = ["F32_MAX", "F32_TINY", "as_float32"]

F32_MAX = float(np.finfo(np.float32).max)
F32_TINY = float(np.finfo(np.float32).tiny)


def as_float32(values: np.ndarray, fmt: str, what: str = "coordinates") -> np.ndarray:
    """``values`` as a contiguous little-endian float32 array, or a MeshError saying why ``fmt``
    cannot hold them (the writers' caller prefixes the output's name)."""
    a = np.asarray(values, dtype=np.float64)
    m = float(np.abs(a).max()) if a.size else 0.0
    if not np.isfinite(m):
        raise MeshError(f"{what} that are not finite cannot be written to {fmt}")
    if m > F32_MAX:
        raise MeshError(f"{what} up to {m:.3g} are beyond float32 (±{F32_MAX:.3g}), the widest type {fmt} "
                        "stores; write PLY, OBJ or OFF, which keep double precision")
    if 0.0 < m < F32_TINY:
        raise MeshError(f"{what} all below {F32_TINY:.3g} in magnitude (up to {m:.3g}) vanish in float32, "
                        f"the type {fmt} stores; write PLY, OBJ or OFF, which keep double precision")
    return np.ascontiguousarray(a, "<f4")
