"""The cotangent formula: one definition for every corner and triangle of the operator.

A corner triangle (a = prev, b = curr, d = next) is described by its two
half-edge vectors p = b − a and q = d − b.  :func:`corner_terms` gives
|p|², |q|², the dot product (a − b)·(d − b) = −p·q and twice the area |p × q|;
the three cotangents follow as

    cot(angle at b) = dot / 2A,  cot(at a) = (|p|² − dot) / 2A,  cot(at d) = (|q|² − dot) / 2A,

(0 for a zero-area triangle, never inf or NaN).  The operator's corner
triangles (:func:`corner_cotangents`), its n-gon fan triangles and mixed
areas (:func:`triangle_cotangents`), the brush's cached triangles
(:func:`tri_geometry`) and the compiled twin
(:func:`shapeflow.geometry.compiled.corner_triangle`, same operations in the
same order, tested against this one) all use it.
"""

from __future__ import annotations

import numpy as np

__all__ = ["corner_terms", "corner_cotangents", "tri_geometry", "triangle_cotangents"]


def corner_terms(px, py, pz, qx, qy, qz):
    """|p|², |q|², −p·q and |p × q| of half-edge vectors p = b − a, q = d − b (component arrays)."""
    lp = px * px + py * py + pz * pz
    lq = qx * qx + qy * qy + qz * qz
    dot = -(px * qx + py * qy + pz * qz)
    cx = py * qz - pz * qy
    cy = pz * qx - px * qz
    cz = px * qy - py * qx
    return lp, lq, dot, np.sqrt(cx * cx + cy * cy + cz * cz)


def _inverse(dbl: np.ndarray) -> np.ndarray:
    return np.divide(1.0, dbl, out=np.zeros_like(dbl), where=dbl > 0)


def corner_cotangents(V: np.ndarray, fi: np.ndarray, nxt: np.ndarray, prv: np.ndarray):
    """Cotangents of every polygon corner triangle (prev, curr, next), from half-edge vectors.

    Returns ``cot_p, cot_c, cot_n`` (angles at prev, curr, next), twice the
    area ``dbl``, and the squared lengths ``l_prev`` (curr–prev), ``l_next``
    (curr–next), ``l_skip`` (prev–next).  Zero-area rows give 0, never inf.
    Computed component by component on contiguous arrays.
    """
    Vt = V.T
    ex, ey, ez = (Vt[k][fi[nxt]] - Vt[k][fi] for k in range(3))   # curr -> next, per corner
    px, py, pz = ex[prv], ey[prv], ez[prv]                          # prev -> curr
    l_prev, l_next, dot, dbl = corner_terms(px, py, pz, ex, ey, ez)
    inv = _inverse(dbl)
    cot_c = dot * inv
    cot_p = (l_prev - dot) * inv
    cot_n = (l_next - dot) * inv
    l_skip = l_prev + l_next - 2.0 * dot
    return cot_p, cot_c, cot_n, dbl, l_prev, l_next, l_skip


def tri_geometry(VT: np.ndarray, tv: np.ndarray):
    """Cotangents at the corners (a, b, d) of triangles ``tv`` (rows a, b, d), from
    component-major positions ``VT`` (3, n).

    Returns ``cot`` (3, m) (angle at a, b, d; 0 for zero-area rows), twice the
    area, and ``sq`` (3, m): the squared length of the side opposite each
    corner, each computed directly from its two end points (so an edge gets the
    same bits from every triangle).
    """
    a, b, d = tv
    X, Y, Z = VT
    # take(mode="clip") gathers faster than fancy indexing (indices are valid)
    ax, ay, az = X.take(a, mode="clip"), Y.take(a, mode="clip"), Z.take(a, mode="clip")
    bx, by, bz = X.take(b, mode="clip"), Y.take(b, mode="clip"), Z.take(b, mode="clip")
    dx, dy, dz = X.take(d, mode="clip"), Y.take(d, mode="clip"), Z.take(d, mode="clip")
    l_prev, l_next, dot, dbl = corner_terms(bx - ax, by - ay, bz - az, dx - bx, dy - by, dz - bz)
    sx, sy, sz = dx - ax, dy - ay, dz - az        # prev -> next, from its own end points
    sq = np.stack([l_next, sx * sx + sy * sy + sz * sz, l_prev])
    inv = _inverse(dbl)
    cot = np.stack([(l_prev - dot) * inv, dot * inv, (l_next - dot) * inv])
    return cot, dbl, sq


def triangle_cotangents(vertices: np.ndarray, tris: np.ndarray):
    """Cotangents of the three angles of each triangle, and twice its area (:func:`tri_geometry`, row-major).

    Parameters
    ----------
    vertices : (n, 3) float64
    tris : (T, 3) int vertex indices

    Returns
    -------
    cot : (T, 3) float64
        ``cot[t, k]`` is the cotangent of the angle at corner ``k`` of
        triangle ``t`` (opposite the pair of the other two corners).  Rows of
        triangles with zero area are 0 (never inf or NaN).
    dbl_area : (T,) float64
        Twice the triangle area.
    sq_len : (T, 3) float64
        Squared length of the edge opposite each corner.
    """
    tris = np.asarray(tris, dtype=np.int64).reshape(-1, 3)
    cot, dbl, sq = tri_geometry(np.ascontiguousarray(vertices.T), np.ascontiguousarray(tris.T))
    return cot.T, dbl, sq.T
