"""Cotangent weights, degrees and ring areas at given positions, with the degeneracy rules.

Degenerate elements
-------------------
``thresholds="relative"`` (default): with h the mean edge length, an edge
shorter than ``1e-8·h`` is zero-length (both ends locked); a triangle with
twice-area ``≤ 1e-8 · (longest edge)²`` (flat or needle-like, |cot| would
exceed ~1e8) is excluded from W and its vertices are locked.  Both tests are
scale-invariant.  ``thresholds="blender"``: Blender's absolute rules (edge
shorter than 1e-5 locks both ends; a corner triangle of area below 1e-5 locks
its corner vertex; a cotangent is 0 when the cross product is below float32
epsilon).  No NaN or inf ever reaches W.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .. import accel
from ..errors import ParameterError
from ..geometry.cotangent import triangle_cotangents
from ..geometry.measures import pow2_exponent
from ..mesh import Mesh
from ..mesh.convert import as_mesh
from .pattern import check_scheme, operator_pattern

__all__ = ["THRESHOLDS", "REL_EDGE_TOL", "REL_SHAPE_TOL", "BLENDER_MIN", "FLT_EPSILON", "CotanWeights",
           "assemble", "cotan_weights"]


THRESHOLDS = ("relative", "blender")


REL_EDGE_TOL = 1e-8   # zero-length edge: |e| <= REL_EDGE_TOL * mean edge length


REL_SHAPE_TOL = 1e-8  # flat triangle: 2*area <= REL_SHAPE_TOL * longest_edge**2


BLENDER_MIN = 1e-5    # Blender's absolute edge-length and corner-area threshold


FLT_EPSILON = float(np.finfo(np.float32).eps)


@dataclass
class CotanWeights:
    """Cotangent weights of a mesh and what was done about degeneracy.

    Unpacks as ``W, ring_area = cotan_weights(mesh)``.

    Attributes
    ----------
    W : scipy.sparse.csr_matrix (n, n)
        Symmetric weights w_ij (zero diagonal).
    degree : (n,) float64
        D_i = Σ_j w_ij.
    ring_area : (n,) float64
        Ring area of each vertex (eq. 5 for ``"tqlbo"``; Blender's sum of
        corner-triangle areas for ``"blender"``).
    locked : (n,) bool
        Vertices touching a degenerate element; the flow keeps them fixed.
    n_degenerate : int
        Number of weighted triangles excluded from W.
    pairs, pair_weights : (P, 2), (P,)
        W as a pair list (a pair may repeat when two faces share a chord;
        repeated weights add up).
    """

    W: sp.csr_matrix
    degree: np.ndarray
    ring_area: np.ndarray
    locked: np.ndarray
    n_degenerate: int
    pairs: np.ndarray
    pair_weights: np.ndarray
    scheme: str

    def __iter__(self):
        yield self.W
        yield self.ring_area


def assemble(mesh, scheme: str, thresholds: str, vertices: np.ndarray | None = None):
    """Pair weights, degrees, ring areas, locked mask, #degenerate (no matrix)."""
    if thresholds not in THRESHOLDS:
        raise ParameterError(f"unknown thresholds {thresholds!r}; choose one of {', '.join(THRESHOLDS)}")
    pattern = operator_pattern(mesh, check_scheme(scheme))
    V = mesh.vertices if vertices is None else vertices
    # extreme scales (relative thresholds only: Blender's are absolute): an exact power-of-two copy
    k = pow2_exponent(V) if thresholds == "relative" else 0
    if k:
        V = np.ldexp(V, -k)
    n = mesh.n_vertices
    xcot, xdbl, xsq = triangle_cotangents(V, pattern.extra_tris)
    P = pattern.pairs.shape[0]
    kern = accel.kernels("operators", n)
    pw, ring, locked, n_bad = kern.assemble_corners(V, pattern, mesh.topology, thresholds)
    # the tqlbo fan triangles of n-gons (few)
    if thresholds == "relative":
        xbad = xdbl <= REL_SHAPE_TOL * xsq.max(axis=1) if xdbl.size else np.zeros(0, bool)
        locked[pattern.extra_tris[xbad].reshape(-1)] = True
    else:
        locked[pattern.extra_tris[0.5 * xdbl < BLENDER_MIN].reshape(-1)] = True
        xbad = ~(xdbl > FLT_EPSILON)
    n_bad = int(n_bad) + int(xbad.sum())
    if pattern.extra_tris.size:
        xv = (xcot * np.where(xbad, 0.0, pattern.extra_w)[:, None]).reshape(-1)
        pw += np.bincount(pattern.extra_pair.reshape(-1), xv, minlength=P)
    deg = kern.pair_degree(pattern.pairs, pw, n)
    if pattern.extra_tris.size:
        xa = 0.5 * xdbl * pattern.extra_w
        ring += np.bincount(pattern.extra_tris.reshape(-1), np.repeat(xa, 3), minlength=n)
    if k:
        with np.errstate(over="ignore"):
            ring = np.ldexp(ring, 2 * k)
        if not np.isfinite(ring).all():
            raise ParameterError(f"the mesh's coordinates (up to {np.ldexp(1.0, k):.3g}) give areas beyond double "
                                 "precision; rescale it (the normalised flow does this itself)")
    return pattern, pw, deg, ring, locked, n_bad


@accel.heavy
def cotan_weights(mesh: Mesh, scheme: str = "tqlbo", *, thresholds: str = "relative") -> CotanWeights:
    """Cotangent weights W and ring areas of a hybrid mesh.

    Parameters
    ----------
    mesh : Mesh
    scheme : {"tqlbo", "blender"}
        ``"tqlbo"``: the paper's hybrid operator (quads = mean of their two
        triangulations, n-gons = mean of their fan triangulations).
        ``"blender"``: ½·cot per polygon corner triangle, as Blender.
    thresholds : {"relative", "blender"}
        Degeneracy rule (module docstring).

    Returns
    -------
    CotanWeights
        ``W`` (symmetric, zero diagonal), ``degree``, ``ring_area``,
        ``locked`` vertices, ``n_degenerate``.  Unpacks as ``W, areas``.

    Examples
    --------
    >>> import shapeflow as sf
    >>> quad = sf.Mesh([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], [[0, 1, 2, 3]])
    >>> W, A = sf.cotan_weights(quad)
    >>> round(W[0, 1], 12), round(W[0, 2], 12), A.tolist()
    (1.0, 0.0, [0.75, 0.75, 0.75, 0.75])
    """
    mesh = as_mesh(mesh)
    pattern, pw, deg, ring, locked, n_bad = assemble(mesh, scheme, thresholds)
    K = pattern.matrix(np.zeros(mesh.n_vertices), pw, copy_pattern=True)
    K.sum_duplicates()   # a chord shared by two faces becomes one entry
    K.eliminate_zeros()  # the explicit zero diagonal (and exact-zero weights)
    return CotanWeights(W=K, degree=deg, ring_area=ring, locked=locked, n_degenerate=n_bad,
                        pairs=pattern.pairs, pair_weights=pw, scheme=scheme)
