"""The geometry layer's kernel family: sharp edges by the dihedral angle (NumPy reference).

The numba implementation is :class:`shapeflow.geometry.compiled.GeometryNumba` (one pass over
the corners); :func:`shapeflow.accel.kernels` chooses (``accel.kernels("geometry", n_vertices)``).
"""

from __future__ import annotations

import numpy as np

from ..accel import Family
from .features import two_face_edges
from .measures import face_vector_areas

__all__ = ["GeometryKernels"]


class GeometryKernels(Family):
    """Kernels over a mesh's edges and faces at given positions."""

    family = "geometry"

    def angle_sharp_edges(self, mesh, V: np.ndarray, angle: float) -> np.ndarray:
        """(E,) mask of the edges of ``mesh`` bent by more than ``angle`` degrees at positions ``V``
        (scaled into range), and of those with three or more faces
        (:func:`shapeflow.geometry.features.angle_sharp_edges` says how the angle is decided)."""
        t = mesh.topology
        sharp = t.edge_face_count > 2
        two, f0, f1, same = two_face_edges(t)
        if two.size == 0:
            return sharp
        fa = face_vector_areas(mesh, V)
        ln = np.sqrt(fa[:, 0] * fa[:, 0] + fa[:, 1] * fa[:, 1] + fa[:, 2] * fa[:, 2])
        ok = ln > 0
        inv = np.divide(1.0, ln, out=np.zeros_like(ln), where=ok)
        nx, ny, nz = (fa[:, k] * inv for k in range(3))
        cos = nx[f0] * nx[f1] + ny[f0] * ny[f1] + nz[f0] * nz[f1]
        if same.any():                        # inconsistent orientation: the bend, not the flip
            cos[same] *= -1.0
        c = float(np.cos(np.radians(angle)))
        hit = (cos < c) & ok[f0] & ok[f1]
        near = np.flatnonzero(np.abs(cos - c) < 1e-6)
        if near.size:
            a = np.stack([nx[f0[near]], ny[f0[near]], nz[f0[near]]], axis=1)
            b = np.stack([nx[f1[near]], ny[f1[near]], nz[f1[near]]], axis=1)
            cr = np.cross(a, b)
            sin = np.sqrt(cr[:, 0] * cr[:, 0] + cr[:, 1] * cr[:, 1] + cr[:, 2] * cr[:, 2])
            exact = np.degrees(np.arctan2(sin, cos[near]))
            hit[near] = (exact > angle) & ok[f0[near]] & ok[f1[near]]
        sharp[two[hit]] = True
        return sharp
