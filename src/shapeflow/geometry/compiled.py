"""The compiled twin of the one corner-triangle cotangent formula.

The NumPy/SciPy reference is :func:`shapeflow.geometry.cotangent.corner_terms`; the tests compare
the two.
Conventions of all compiled kernels: :mod:`shapeflow.accel`.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(inline="always")
def corner_triangle(ax, ay, az, bx, by, bz, dx, dy, dz):
    """Corner triangle (prev a, curr b, next d), as :func:`shapeflow.geometry.cotangent.corner_terms`:
    |b − a|², |d − b|², (a − b)·(d − b) and twice the area."""
    px = bx - ax
    py = by - ay
    pz = bz - az
    qx = dx - bx
    qy = dy - by
    qz = dz - bz
    lp = px * px + py * py + pz * pz
    ln = qx * qx + qy * qy + qz * qz
    dot = -(px * qx + py * qy + pz * qz)
    cx = py * qz - pz * qy
    cy = pz * qx - px * qz
    cz = px * qy - py * qx
    return lp, ln, dot, np.sqrt(cx * cx + cy * cy + cz * cz)
