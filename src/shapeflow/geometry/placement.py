"""Affine placements (a 4×4 matrix M, column vectors): points and normals into the placed frame and back.

Scene formats (glTF nodes, USD transforms) keep each mesh in its own coordinates and place it with
M; the readers bring positions and normals into the scene and the writers take them back.
"""

from __future__ import annotations

import numpy as np

__all__ = ["place", "unplace", "place_normals", "unplace_normals", "orientation"]


def place(points: np.ndarray, M: np.ndarray) -> np.ndarray:
    """M applied to (n, 3) points: A p + t."""
    return points @ M[:3, :3].T + M[:3, 3]


def unplace(points: np.ndarray, M: np.ndarray) -> np.ndarray:
    """The inverse of :func:`place`: A⁻¹ (p − t)."""
    return (points - M[:3, 3]) @ np.linalg.inv(M[:3, :3]).T


def orientation(M: np.ndarray) -> int:
    """The sign of the determinant of M's linear part (-1 mirrors, +1 keeps, 0: singular or not
    finite), taken on a copy scaled by a power of two to a largest entry in [0.5, 1): a scale of
    1e300 or 1e-110 per axis neither overflows nor underflows to a wrong answer."""
    A = np.asarray(M, dtype=np.float64)[:3, :3]
    s = float(np.abs(A).max())
    if not np.isfinite(A).all() or s == 0.0:
        return 0
    d = float(np.linalg.det(np.ldexp(A, -int(np.frexp(s)[1]))))
    return 0 if abs(d) < 1e-300 else (1 if d > 0 else -1)


def _unit(v: np.ndarray) -> np.ndarray:
    ln = np.linalg.norm(v, axis=1, keepdims=True)
    return np.divide(v, ln, out=np.zeros_like(v), where=ln > 0)


def place_normals(normals: np.ndarray, M: np.ndarray) -> np.ndarray:
    """Normals through the inverse transpose of M's linear part, unit length again (zero stays zero)."""
    return _unit(np.asarray(normals, np.float64) @ np.linalg.inv(M[:3, :3]))


def unplace_normals(normals: np.ndarray, M: np.ndarray) -> np.ndarray:
    """The inverse of :func:`place_normals`: through M's linear part transposed, unit length again."""
    return _unit(np.asarray(normals, np.float64) @ M[:3, :3])
