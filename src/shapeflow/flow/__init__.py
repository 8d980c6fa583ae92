"""Implicit curvature flow: smoothing (λ > 0) and shape enhancement (λ < 0), eq. 11.

One step (docs/method.md derives it; the printed minus sign of eq. 11 is a typo):

    (I + |λ| W_p L) V' = V        L = I − D⁻¹W (eq. 10) or (D − W)/(2A) (eq. 9)
    V ← V + sign(λ) (V' − V)

so λ > 0 is a backward-Euler smoothing step and λ < 0 moves every vertex by
the same displacement the other way.  W_p = diag(vertex weights in [0, 1]):
weight 0 leaves a vertex where it is.

The system is never solved in that non-symmetric form.  Rows are scaled by
``W_p⁻¹ M / |λ|`` (M = D for the normalised operator, 2A for eq. 9), giving
the symmetric positive definite

    (C + D − W) V' = C V,      C = diag(m_i / (|λ| w_i)),

restricted to the free vertices (fixed ones — weight 0, locked, or boundary —
move to the right-hand side).  Boundary vertices of open meshes are solved
first, with the scale-dependent umbrella operator (weights 1/|e_ij|) and their
own factor λ_b and sign, then the interior.

Two modes
---------
paper (default, ``compat=None``)
    ``scheme="tqlbo"`` weights (triangles 1×, quads = mean of the two
    triangulations, n-gons = mean of the fan triangulations); degeneracy
    thresholds relative to the mesh size; boundary vertices = vertices on a
    boundary edge, umbrella over boundary edges, step ``(I + |λ_b| L_b)``;
    eq. 9 uses ``2A`` with the ring area of eq. 5; volume preservation uses
    the signed volume and rescales about the current vertex centroid by
    ``(vol_before/vol_after)^(1/k)`` over the k enabled axes (exact); the
    operator may be rebuilt each iteration (``update="recompute"``).
``compat="blender"``
    Exactly what Blender 5.0.1's Laplacian Smooth modifier computes
    (``docs/blender-compat.md`` in the repository lists every rule):
    ``"blender"`` weights (½·cot per corner triangle, triangles count 1.5×),
    absolute 1e-5 locking thresholds, interior = "as many incident edges as
    face corners", boundary umbrella over every edge joining two boundary
    vertices with factor ``2|λ_b|`` (and Blender's pull toward the origin
    next to a locked vertex), eq. 9 replaced by Blender's ``4·a_i``
    normalisation, volume rescaled about the *input* centroid by
    ``(|vol_before|/|vol_after|)^(1/3)``, operator fixed after the first
    iteration.
"""

from ..mesh.weights import resolve_weights
from .api import enhance, flow, smooth
from .family import STRATEGIES, family, family_meshes
from .options import COMPAT_MODES, FLOW_SOLVERS
from .report import FamilyReport, FlowReport
from .solver import FlowSolver
from .system import SystemBuilder

__all__ = ["flow", "smooth", "enhance", "FlowReport", "FlowSolver", "COMPAT_MODES", "FLOW_SOLVERS", "family",
           "family_meshes", "FamilyReport", "STRATEGIES", "resolve_weights", "SystemBuilder"]
