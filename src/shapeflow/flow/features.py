"""Feature-aware flow: sharp edges form feature curves that move along themselves (docs/method.md).

``flow(mesh, lam, feature_angle=DEG)`` and ``flow(mesh, lam, sharp_edges=E)`` (or both: their
union; ``sharp_edges="mesh"``: the edges the file marks, :func:`shapeflow.geometry.features.file_sharp_edges`)
split the vertices that are not on the mesh's boundary by the number of sharp edges at them:

* none — a *surface* vertex: the flow's own row, with every feature vertex among its neighbours
  a boundary value (Dirichlet) at its solved position;
* exactly two — a *curve* vertex: it moves along its feature curve, by the curve's own
  one-dimensional Laplacian with the same λ, weights and implicit step,
  ``(I + |λ| W_p L_c) X = V``, then ``V ← V + sign(λ)(X − V)``;
* one (a curve's end) or three and more (a corner) — it stays where it is.

The curve Laplacian has the weights ``e_ij = 1/|v_i − v_j|`` along the two sharp edges: the
one-dimensional cotangent (finite-element stiffness) weights, so, like the surface operator, it
has linear precision — vertices of a straight stretch do not slide along it, whatever their
spacing — and they are the boundary umbrella's weights.  Normalised like the surface operator:
``L_c = I − D_c⁻¹W_c`` with ``normalized=True`` (scale-free), ``M_c⁻¹(D_c − W_c)`` with
``M_c`` the vertex's half of its two edges (the arc-length second derivative, units 1/length²
like eq. 9) otherwise.

The curves are solved after the boundary block (a boundary vertex at a curve's end enters at its
solved position) and before the surface, whose system is then one on the free surface vertices
only.  The classification is made once, at the input positions, and kept with the operator; with
``update="recompute"`` the curves' weights follow the moved positions.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Union

import numpy as np
from numpy.typing import ArrayLike

from ..errors import ParameterError
from ..geometry.features import angle_sharp_edges, check_feature_angle, edge_ids, file_sharp_edges
from ..mesh import Mesh
from .system import LinearSystem, compact_system, row_scale, solve_compact

__all__ = ["SharpEdges", "resolve_sharp_edges", "FeatureCurves", "CurveOperator", "classify", "curve_operator",
           "curve_system", "solve_curves", "mesh_sharp_edges"]

#: sharp edges: None (none), a (k, 2) array of vertex pairs, or "mesh" (those the mesh carries)
SharpEdges = Union[None, str, ArrayLike]


def mesh_sharp_edges(mesh: Mesh) -> np.ndarray:
    """(E,) the sharp edges the mesh carries: the file's (:func:`~shapeflow.geometry.features.file_sharp_edges`)
    and the creased edges of a subdivision result (``mesh.creases``, value > 0)."""
    sharp = file_sharp_edges(mesh)
    creases = getattr(mesh, "creases", None)
    if creases is not None:
        pairs, values = creases
        sharp[edge_ids(mesh, np.asarray(pairs)[np.asarray(values) > 0], "mesh.creases")] = True
    return sharp


def resolve_sharp_edges(mesh: Mesh, feature_angle, sharp_edges, carrier: Mesh | None = None) -> np.ndarray | None:
    """(E,) mask of the sharp edges, or None when neither option is given (the plain flow).

    ``carrier``: the mesh whose file data and ``creases`` ``sharp_edges="mesh"`` reads (default
    ``mesh``; the flow's scaled copy of an input with extreme coordinates shares its topology)."""
    if feature_angle is None and sharp_edges is None:
        return None
    sharp = np.zeros(mesh.topology.n_edges, bool)
    if feature_angle is not None:
        sharp |= angle_sharp_edges(mesh, check_feature_angle(feature_angle))
    if isinstance(sharp_edges, str):
        if sharp_edges != "mesh":
            raise ParameterError(f"sharp_edges must be a (k, 2) array of vertex pairs or 'mesh', got {sharp_edges!r}")
        sharp |= mesh_sharp_edges(mesh if carrier is None else carrier)
    elif sharp_edges is not None:
        sharp[edge_ids(mesh, sharp_edges, "sharp_edges")] = True
    return sharp


@dataclass
class FeatureCurves:
    """The classification of the vertices by their sharp edges (topology only)."""

    sharp: np.ndarray       # (E,) sharp edges
    feature: np.ndarray     # (n,) vertices off the mesh boundary with a sharp edge: held out of the surface solve
    curve: np.ndarray       # (n,) those with exactly two: they follow their curve
    pairs: np.ndarray       # (q, 2) sharp edges with a curve vertex at either end

    @property
    def counts(self) -> tuple[int, int, int]:
        """(sharp edges, curve vertices, fixed feature vertices: ends and corners)."""
        return int(self.sharp.sum()), int(self.curve.sum()), int((self.feature & ~self.curve).sum())


def classify(mesh: Mesh, sharp: np.ndarray, boundary: np.ndarray) -> FeatureCurves:
    """Curve, end and corner vertices of the sharp edges ``sharp`` (boundary vertices excluded)."""
    t = mesh.topology
    se = t.edges[sharp]
    count = np.bincount(se.reshape(-1), minlength=t.n_vertices)
    feature = (count > 0) & ~boundary
    curve = (count == 2) & ~boundary
    pairs = se[curve[se[:, 0]] | curve[se[:, 1]]].astype(np.int64)
    return FeatureCurves(sharp, feature, curve, pairs)


@dataclass
class CurveOperator:
    """The curves' operator at some positions: weights 1/length, their sums, the row masses."""

    curves: FeatureCurves
    weights: np.ndarray     # (q,) e_ij
    degree: np.ndarray      # (n,) Σ e_ij
    mass: np.ndarray        # (n,) D_c (normalised) or half the two edges' length
    movable: np.ndarray     # (n,) curve vertices whose two curve edges have a length

    @property
    def feature(self) -> np.ndarray:
        return self.curves.feature


def curve_operator(V: np.ndarray, curves: FeatureCurves, normalized: bool) -> CurveOperator:
    """The :class:`CurveOperator` at positions ``V``."""
    n = V.shape[0]
    p = curves.pairs
    d = V[p[:, 0]] - V[p[:, 1]]
    length = np.sqrt(np.einsum("ij,ij->i", d, d))
    pos = length > 0
    e = np.zeros(length.size)
    np.divide(1.0, length, out=e, where=pos)
    ends = p.reshape(-1)
    degree = np.bincount(ends, np.repeat(e, 2), minlength=n)
    movable = curves.curve & (np.bincount(ends, np.repeat(pos, 2), minlength=n) == 2)
    mass = degree if normalized else 0.5 * np.bincount(ends, np.repeat(length, 2), minlength=n)
    return CurveOperator(curves, e, degree, mass, movable)


def curve_system(op: CurveOperator, lam: float, w: np.ndarray, locked: np.ndarray, coord_scale: float,
                 rtol: float) -> LinearSystem | None:
    """The curves' system for λ (None: nothing to solve); fixed neighbours (curve ends, corners,
    boundary, locked and weight-0 vertices) are boundary values."""
    if lam == 0.0 or op.weights.size == 0:
        return None
    free = op.movable & ~locked & (w > 0) & (op.degree > 0) & (op.mass > 0)
    c_all = row_scale(op.mass, abs(lam), w, free, coord_scale)
    free &= np.isfinite(c_all)
    if not free.any():
        return None
    return compact_system(free, c_all, op.curves.pairs, op.weights, op.degree, rtol, method="lu")


def solve_curves(V: np.ndarray, X: np.ndarray, curve_sys: LinearSystem, lam: float) -> np.ndarray:
    """Positions ``X`` (the boundary block solved, or ``V`` itself) with the curves solved too:
    written into ``X`` when it is not ``V`` (curves and boundary share no vertex), else a copy."""
    out = X.copy() if X is V else X
    solve_compact(V, X, out, curve_sys, lam)
    return out
