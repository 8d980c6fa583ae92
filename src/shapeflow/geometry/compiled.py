"""The compiled twin of the one corner-triangle cotangent formula, and sharp edges by angle.

The NumPy/SciPy references are :func:`shapeflow.geometry.cotangent.corner_terms` and
:class:`shapeflow.geometry.kernels.GeometryKernels` (:class:`GeometryNumba` is the family's numba
implementation); the tests compare the two.
Conventions of all compiled kernels: :mod:`shapeflow.accel`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .kernels import GeometryKernels


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


@njit(inline="always")
def cross_of_differences(V, a, b, c, d):
    """(V[b] − V[a]) × (V[d] − V[c]), as :func:`shapeflow.geometry.measures.face_vector_areas` writes it."""
    px = V[b, 0] - V[a, 0]
    py = V[b, 1] - V[a, 1]
    pz = V[b, 2] - V[a, 2]
    qx = V[d, 0] - V[c, 0]
    qy = V[d, 1] - V[c, 1]
    qz = V[d, 2] - V[c, 2]
    return py * qz - pz * qy, pz * qx - px * qz, px * qy - py * qx


def angle_sharp_edges(face_offsets, face_indices, corner_edge, n_edges, V, angle):
    """``GeometryKernels.angle_sharp_edges`` in one pass over the faces' corners:
    (E,) mask of the edges whose two faces' normals make more than ``angle`` degrees, and of the
    edges with three or more faces."""
    sharp = np.zeros(n_edges, dtype=np.bool_)
    sizes = np.diff(face_offsets)
    quads = bool(sizes.size) and bool((sizes == 4).all())
    _angle_sharp(face_offsets, face_indices, corner_edge, V, quads, float(angle), float(np.cos(np.radians(angle))),
                 np.zeros(n_edges, np.int8), np.empty((n_edges, 3)), sharp)
    return sharp


@njit(cache=True)
def _angle_sharp(offsets, fi, corner_edge, V, quads, angle, c_lim, seen, first, sharp):
    """``first[e]``: the unit normal of the first face met at edge e, times +1 when that face runs the
    edge from its lower to its higher vertex, −1 otherwise; at the second face the bend's cosine is
    −(first)·(this face's normal times its own sign), whatever the two faces' orientations.
    ``seen``: faces met so far (capped at 3); -1: a face without a normal (never sharp by angle)."""
    for f in range(offsets.size - 1):
        o0 = offsets[f]
        o1 = offsets[f + 1]
        a = np.uint64(fi[o0])
        nx = 0.0
        ny = 0.0
        nz = 0.0
        if quads:                                    # face_vector_areas: a quad's diagonals
            nx, ny, nz = cross_of_differences(V, a, np.uint64(fi[o0 + 2]), np.uint64(fi[o0 + 1]),
                                              np.uint64(fi[o0 + 3]))
        for c in range(o0 + 1, o1 - 1 if not quads else o0 + 1):   # else the fan from the first corner
            px, py, pz = cross_of_differences(V, a, np.uint64(fi[c]), a, np.uint64(fi[c + 1]))
            nx += px
            ny += py
            nz += pz
        nx *= 0.5
        ny *= 0.5
        nz *= 0.5
        ln = np.sqrt(nx * nx + ny * ny + nz * nz)
        ok = ln > 0.0
        if ok:
            inv = 1.0 / ln
            nx *= inv
            ny *= inv
            nz *= inv
        for c in range(o0, o1):
            e = np.uint64(corner_edge[c])
            nxt = c + 1 if c + 1 < o1 else o0
            s = 1.0 if fi[c] < fi[nxt] else -1.0
            k = seen[e]
            if k == 0:
                seen[e] = 1 if ok else -1
                first[e, 0] = s * nx
                first[e, 1] = s * ny
                first[e, 2] = s * nz
            elif k == 1 or k == -1:
                seen[e] = 2
                if k == 1 and ok:
                    bx = s * nx
                    by = s * ny
                    bz = s * nz
                    cs = -(first[e, 0] * bx + first[e, 1] * by + first[e, 2] * bz)
                    if abs(cs - c_lim) < 1e-6:          # near the threshold: the angle itself decides
                        cx = first[e, 1] * bz - first[e, 2] * by
                        cy = first[e, 2] * bx - first[e, 0] * bz
                        cz = first[e, 0] * by - first[e, 1] * bx
                        sharp[e] = np.degrees(np.arctan2(np.sqrt(cx * cx + cy * cy + cz * cz), cs)) > angle
                    else:
                        sharp[e] = cs < c_lim
            else:                                          # a third face: non-manifold, sharp
                seen[e] = 3
                sharp[e] = True


class GeometryNumba(GeometryKernels):
    """The geometry family compiled."""

    backend = "numba"

    def angle_sharp_edges(self, mesh, V, angle):
        t = mesh.topology
        if not t.n_edges:
            return super().angle_sharp_edges(mesh, V, angle)
        return angle_sharp_edges(t.face_offsets, t.face_indices, t.corner_edge, t.n_edges,
                                 np.ascontiguousarray(V, dtype=np.float64), angle)
