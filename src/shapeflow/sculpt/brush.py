"""The shape-enhancement sculpt brush of section 4.3 of the paper.
A :class:`Brush` applies one implicit flow step (eq. 11, see :mod:`shapeflow.flow`)
restricted to the vertices inside a sphere (centre u, radius r):

* *inside*: vertices with ``|v − u| ≤ r`` (current positions);
* *rim*: inside vertices with a face neighbour (any vertex sharing a face,
  quad diagonals included) outside the sphere.  They are not solved for: they
  stay where they are and anchor the solve as Dirichlet values;
* *unknowns*: the other inside vertices, minus those :func:`shapeflow.flow`
  keeps fixed (weight 0, locked by a degenerate element, zero or negative
  degree/mass).  Their rows are exactly flow's rows, paper mode:
  ``(C + D − W) X = C V + Σ_fixed w_ij V_j`` with ``C = diag(m_i/(|λ| w_i))``,
  ``m = D`` (normalised, eq. 10) or ``2A`` (eq. 9), then
  ``V ← V + sign(λ)(X − V)``.  Boundary vertices of open meshes use the
  umbrella operator with their own ``λ_b`` (``lam_border``, 0 = fixed), solved
  first, as in :func:`shapeflow.flow`.

Everything outside the unknowns is never written: outside vertices and the rim
are bit-identical after any number of dabs.  A dab that covers a whole closed
mesh (empty rim) is ``flow(mesh, lam)``.

``falloff`` (beyond the paper, which has none) multiplies the vertex weights
W_p by a function of ``t = d/r``: ``"smooth"`` is ``(1 − t²)²``, or pass a
callable mapping an array of ``t`` in [0, 1] to factors in [0, 1].

Work reused between dabs (nothing proportional to the whole mesh is done or
allocated per dab):

* a spatial index over the positions of its last build
  (:class:`~shapeflow.sculpt.grid.CellGrid` with the compiled kernels, else
  SciPy's ``cKDTree``), queried with ``r + tau`` (``tau = rebuild_fraction
  · r``); vertices that have since moved farther than ``tau`` are kept in a
  short list checked directly (a vertex leaves it when it comes back within
  ``tau``, as after an undo), and the index is rebuilt (lazily, at the next
  dab) once that list exceeds ``max(4096, n/16)`` vertices or the radius
  shrank below ``tau/2``;
* the incremental cotangent cache of
  :class:`~shapeflow.sculpt.cotan_cache.CotanCache`: after a committed dab
  only the triangles of the faces touching moved vertices are recomputed
  (round-off drift over very many dabs is removed by :meth:`Brush.refresh`);
* the index arrays a dab reads (neighbours, pairs, faces, triangles) in
  32 bits where the mesh's counts fit;
* an internal vertex numbering (reverse Cuthill–McKee of the whole mesh,
  faces sorted to match; :mod:`~shapeflow.sculpt.numbering`): a dab touches a
  few contiguous stretches of every array (scanned meshes in file order got
  ~1.7× faster per dab), and a dab's unknowns, sorted, already form a
  narrow-band matrix.  Indices and positions seen by the caller are always
  in the mesh's own numbering.

The small SPD system of a dab is solved by a
:class:`~shapeflow.linalg.local.LocalSolver` (the two-thread split solver,
LAPACK's banded Cholesky, or a sparse factorisation; its docstring gives
the measured times).

The degeneracy thresholds are those of flow's paper mode ("relative"), with the
mean edge length ``h`` taken from the mesh the brush was built on (it is a
global quantity; recomputing it per dab would be full-mesh work).

Gathers on the per-dab paths use ``ndarray.take(..., mode="clip")`` (indices
are always valid, so the result is the same): with numpy 1.26 it is ~25%
faster than fancy indexing for 1-D arrays and ~4× for rows of an (n, 3) array.
"""

from __future__ import annotations

from .. import accel, params
from ..errors import ParameterError
from ..flow.features import SharpEdges
from ..linalg.local import LOCAL_METHODS, LocalSolver
from ..mesh import Mesh
from ..operators.pattern import check_scheme
from ..types import Falloff, Weights
from .base import BrushBase, serialised
from .cotan_cache import CotanCache
from .dab import DabSystem

__all__ = ["Brush", "BRUSH_SOLVERS"]

BRUSH_SOLVERS = LOCAL_METHODS


class Brush(CotanCache, DabSystem, BrushBase):
    """The shape-enhancement sculpt brush (section 4.3 of the paper).

    Each dab runs one implicit TQLBO flow step on the vertices inside a
    sphere, with the rim of the selection fixed (see the module docstring).

    Parameters
    ----------
    mesh : Mesh
    lam : float
        λ of each dab: < 0 enhances, > 0 smooths (as :func:`shapeflow.flow`).
    radius : float
        Sphere radius in model units.
    falloff : None, "smooth" or callable
        Multiplies W_p by f(d/r); None = the paper (no falloff).
    lam_border : float
        λ_b for boundary vertices of open meshes (umbrella operator, own
        sign); 0 keeps them fixed.
    weights : None, str or array (n,)
        Per-vertex W_p in [0, 1]; a string names a mesh attribute.
    scheme : {"tqlbo", "blender"}
        Cotangent weights (paper mode thresholds either way).
    normalized : bool
        True: eq. 10 (scale-invariant); False: eq. 9 (mass 2A).
    solver : {"auto", "banded", "lu", "cholesky"}
        Linear solver for a dab (module docstring); "auto" picks by cost
        (the two-thread split solver when it applies); "banded" is one band.
    undo_limit : int
        Number of dabs/strokes kept for :meth:`undo`.
    rebuild_fraction : float
        Rebuild the spatial index when a vertex moved more than this × radius
        since it was built.
    feature_angle, sharp_edges
        Sharp edges, as in :func:`shapeflow.flow` (found once, on the mesh the
        brush is made with).  A dab never drags a vertex across them: inside a
        dab a vertex on two sharp edges moves along its feature curve (the
        curve's own step, with the curve's fixed vertices, the dab's rim and
        the solved boundary as boundary values), curve ends and corners stay,
        and the other vertices take the feature vertices' new positions as
        boundary values.

    Thread model
    ------------
    A brush holds working positions, caches and solver work space, so its
    calls are serialised: every public method and property takes the
    brush's (re-entrant) lock, and a call from a second thread waits until
    the first one returns.  Several threads may share one brush safely,
    without any speed-up; use one brush per thread for parallel work.

    Examples
    --------
    >>> import shapeflow as sf
    >>> mesh = sf.load_example("spot")
    >>> brush = sf.Brush(mesh, lam=-50.0, radius=0.2)
    >>> moved = brush.dab(mesh.vertices[0])
    >>> moved = brush.stroke([mesh.vertices[0], mesh.vertices[10]])
    >>> sculpted = brush.mesh
    """

    @accel.heavy
    def __init__(self, mesh: Mesh, *, lam: float = -50.0, radius: float, falloff: Falloff = None,
                 lam_border: float = 0.0, weights: Weights = None, scheme: str = "tqlbo", normalized: bool = True,
                 solver: str = "auto", undo_limit: int = 64, rebuild_fraction: float = 0.15,
                 feature_angle: float | None = None, sharp_edges: SharpEdges = None):
        super().__init__(mesh, radius=radius, falloff=falloff, weights=weights,
                         undo_limit=undo_limit, rebuild_fraction=rebuild_fraction)
        self.lam = lam
        self.lam_border = lam_border
        self.scheme = check_scheme(scheme)
        self.normalized = bool(normalized)
        if solver not in BRUSH_SOLVERS:
            raise ParameterError(f"unknown solver {solver!r}; choose one of {', '.join(BRUSH_SOLVERS)}")
        if solver == "cholesky":
            from ..linalg.spd import cholesky_available

            if not cholesky_available():
                from ..errors import OptionalDependencyError

                raise OptionalDependencyError("cholespy", "cholesky", "the Cholesky solver")
        self.solver = solver
        self._local_solver = LocalSolver(solver)   # reuses its work space dab after dab
        self._build()
        self._build_features(self._mesh0, feature_angle, sharp_edges)

    @property
    @serialised
    def lam(self) -> float:
        """λ of each dab (< 0 enhances, > 0 smooths); may change between dabs."""
        return self._lam

    @lam.setter
    @serialised
    def lam(self, v) -> None:
        self._lam = params.lam("lam", v)

    @property
    @serialised
    def lam_border(self) -> float:
        """λ_b for boundary vertices of open meshes (0: fixed)."""
        return self._lam_b

    @lam_border.setter
    @serialised
    def lam_border(self, v) -> None:
        self._lam_b = params.lam("lam_border", v)

