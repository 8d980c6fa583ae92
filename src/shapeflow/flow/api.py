"""The functional flow API: :func:`flow`, :func:`smooth` and :func:`enhance`."""

from __future__ import annotations

from typing import Callable

from .. import accel, params
from ..errors import ParameterError
from ..linalg.spd import DEFAULT_RTOL
from ..mesh import Mesh
from ..types import Axes, Weights
from .features import SharpEdges
from .solver import FlowSolver

__all__ = ["flow", "smooth", "enhance"]


@accel.heavy
def flow(mesh: Mesh, lam: float, *, lam_border: float = 0.0, iterations: int = 1,
         normalized: bool = True, weights: Weights = None, invert_weights: bool = False,
         preserve_volume: bool = False, axes: Axes = (True, True, True),
         scheme: str | None = None, update: str = "fixed", compat: str | None = None,
         solver: str = "auto", rtol: float = DEFAULT_RTOL,
         progress: Callable[[int, int], None] | None = None, feature_angle: float | None = None,
         sharp_edges: SharpEdges = None) -> Mesh:
    """Smooth (λ > 0) or enhance (λ < 0) a mesh with the implicit TQLBO flow.

    Parameters
    ----------
    mesh : Mesh
    lam : float
        λ of eq. 11 (λ·dt folded into one number): > 0 smooths, < 0 enhances;
        the paper's figures use +90 … −400.
    lam_border : float
        λ_b for boundary vertices of open meshes (own sign); 0 keeps them fixed.
    iterations : int
        Number of implicit steps (0 returns the input).
    normalized : bool
        True: eq. 10, L = I − D⁻¹W (scale-invariant, recommended).
        False: eq. 9, area-normalised (depends on the model's scale).
    weights : None, str or array (n,)
        Per-vertex factor in [0, 1] (W_p); 0 leaves a vertex untouched.  A
        string names a mesh attribute (e.g. ``"weight"``); None = all 1.
    invert_weights : bool
        Use 1 − weights.
    preserve_volume : bool
        Rescale about the centroid after each step to keep the enclosed volume.
        It is a global similarity: every vertex, fixed ones too, is rescaled.
    axes : three bools or a string such as ``"xy"``
        Which coordinates may change.
    scheme : {"tqlbo", "blender"}, optional
        Cotangent weights; default "tqlbo" (paper) or "blender" with compat.
    update : {"fixed", "recompute"}
        Keep the operator of the first iteration (Blender's behaviour) or
        rebuild it from the current positions every iteration (a true flow).
    compat : None or "blender"
        ``"blender"`` reproduces Blender's Laplacian Smooth modifier exactly
        (see the module docstring for every difference).
    solver : {"auto", "cg", "cholesky", "lu", "chebyshev"}
        Linear solver (:mod:`shapeflow.linalg.spd`); "auto" picks by cost.
        ``"chebyshev"``: several fixed-operator steps as one Chebyshev
        expansion (CG for a single step); "auto" uses it where it picks CG and
        the expansion is cheaper than one CG solve per step.
    rtol : float
        CG tolerance, relative to the initial residual of each solve.
    progress : callable(done, total), optional
        Called after each iteration.
    feature_angle : float, optional
        Degrees: an edge whose two faces' normals make a larger angle is sharp
        (:mod:`shapeflow.geometry.features`; boundary edges never are).
    sharp_edges : (k, 2) array of vertex pairs, or "mesh"
        Sharp edges given (each pair must be an edge), or those the mesh
        carries ("mesh": OBJ smoothing-group borders and ``t crease`` tags, a
        subdivision's ``creases``); with ``feature_angle``, their union.  With
        either, sharp edges form feature curves: a vertex on two of them moves
        along its curve by the curve's own Laplacian, curve ends and corners
        stay, and the rest of the surface flows with them as boundary values
        (:mod:`shapeflow.flow.features`).  Without either, the plain flow.

    Returns
    -------
    Mesh
        New positions, same faces and attributes; ``result.report`` is a
        :class:`FlowReport` (locked vertices, solver, CG iterations, time...).

    Examples
    --------
    >>> import shapeflow as sf
    >>> mesh = sf.load_example("spot")
    >>> bigger = sf.flow(mesh, -20.0)              # enhance
    >>> smoother = sf.flow(mesh, 5.0, iterations=3)  # smooth
    >>> bigger.report.locked
    0
    """
    return FlowSolver(mesh, lam_border=lam_border, normalized=normalized, weights=weights,
                      invert_weights=invert_weights, scheme=scheme, compat=compat, solver=solver,
                      rtol=rtol, feature_angle=feature_angle, sharp_edges=sharp_edges
                      ).run(lam, iterations=iterations, preserve_volume=preserve_volume, axes=axes, update=update,
                            progress=progress)


def check_strength(s) -> float:
    v = params.number("strength", s)
    if v < 0:
        raise ParameterError(f"strength must be >= 0 (use flow() for a signed λ), got {v}")
    return v


def smooth(mesh: Mesh, strength: float, **kw) -> Mesh:
    """Smooth: ``flow(mesh, +strength, **kw)`` (strength >= 0)."""
    return flow(mesh, check_strength(strength), **kw)


def enhance(mesh: Mesh, strength: float, **kw) -> Mesh:
    """Enhance the shape: ``flow(mesh, −strength, **kw)`` (strength >= 0)."""
    return flow(mesh, -check_strength(strength), **kw)
