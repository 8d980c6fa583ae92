"""The operators layer: cotangent weights W, degrees D, ring areas, Laplacians, curvature.

Sign convention (everywhere in shapeflow): Laplacians are **positive
semi-definite**.  With W the symmetric cotangent weights (w_ij >= 0 on
well-shaped meshes) and D = diag(Σ_j w_ij):

* ``K = D − W``            the cotangent "stiffness" matrix (PSD, zero row sums);
* ``L = I − D⁻¹W``         the normalised operator, eq. 10 of the paper;
* ``L = (D − W) / (2A)``   the area-normalised operator, eq. 9 (A = ring area).

So ``L @ V`` points *away* from the neighbour average, and the discrete
Laplace–Beltrami of the positions is ``Δx = −L_area @ V``.

Schemes (how a face contributes to W)
--------------------------------------
``"tqlbo"`` (default; the paper, section 4.1, with the ½ of case (c) of eq. 8 restored: docs/method.md)
    A triangle adds cot(opposite angle) to each of its edges.  A quad is the
    mean over its two triangulations: each of its 4 corner triangles adds
    ½·cot to every pair of that corner triangle (diagonals included).
    **N-gons** (beyond the paper): the mean over the n fan triangulations
    (one rooted at each corner), so each fan triangle adds cot/n.  This is
    exactly the paper on triangles (1 fan) and quads (the 4 fans are the two
    triangulations twice), and keeps linear precision on planar polygons
    because every triangulation of a planar polygon has it.  Ring areas
    (eq. 5) use the same weights: on a quad A(i) gets ½[A(t1)+A(t2)+A(t3)].
``"blender"`` (what Blender's Laplacian Smooth modifier computes)
    Every polygon corner triangle (prev, curr, next) adds ½·cot to its three
    pairs, for triangles, quads and n-gons alike (so a triangle counts 1.5×
    relative to a quad); its ring area adds the whole corner-triangle area to
    each of its three vertices.

Degenerate elements: see :mod:`shapeflow.operators.cotan`.

Layout: :mod:`~shapeflow.operators.pattern` (topology only) → :mod:`~shapeflow.operators.cotan`
(cotangents at given positions) → :mod:`~shapeflow.operators.laplacian` and
:mod:`~shapeflow.operators.curvature`.
"""

from .cotan import REL_EDGE_TOL, REL_SHAPE_TOL, THRESHOLDS, CotanWeights, cotan_weights
from .curvature import mean_curvature, mean_curvature_normal, vertex_areas
from .laplacian import laplacian
from .pattern import SCHEMES, check_scheme, operator_pattern

__all__ = [
    "SCHEMES", "THRESHOLDS", "REL_EDGE_TOL", "REL_SHAPE_TOL", "CotanWeights", "cotan_weights", "laplacian",
    "mean_curvature_normal", "mean_curvature", "vertex_areas", "check_scheme", "operator_pattern",
]
