"""The stateful flow on one mesh: :class:`FlowSolver` (reuses the operator between runs)."""

from __future__ import annotations

import time
from typing import Callable

import numpy as np

from .. import accel, params
from ..errors import ParameterError
from ..geometry.measures import pow2_exponent
from ..geometry.normals import has_normals, refresh_normals
from ..linalg.pairs import PairMatrix
from ..linalg.spd import DEFAULT_RTOL
from ..mesh import Mesh
from ..mesh.convert import as_mesh
from ..mesh.weights import resolve_weights
from ..operators.pattern import check_scheme
from ..types import Axes, Weights
from . import system
from .features import SharpEdges, resolve_sharp_edges, solve_curves
from .fixed import fixed_steps
from .options import COMPAT_MODES, FLOW_SOLVERS, MEAN_RESTORE_FROM, check_run_options
from .report import FlowReport
from .system import LinearSystem, Operator, SystemBuilder

__all__ = ["FlowSolver", "max_row_distance"]


class FlowSolver:
    """Stateful flow on one mesh: reuses operators and factorisations.

    Use it for repeated runs (several λ, iterations, brush dabs); ``flow()``
    is a thin wrapper.  Options are those of :func:`flow`.

    Thread model: :meth:`run` may be called from several threads at once.
    Its only shared state is the operator at the input positions, built
    once under a lock; everything else a run uses is its own.

    Examples
    --------
    >>> import shapeflow as sf
    >>> mesh = sf.load_example("spot")
    >>> solver = sf.FlowSolver(mesh)
    >>> shapes = [solver.run(lam) for lam in (-5.0, -10.0)]
    """

    @accel.heavy
    def __init__(self, mesh: Mesh, *, lam_border: float = 0.0, normalized: bool = True,
                 weights: Weights = None, invert_weights: bool = False, scheme: str | None = None,
                 compat: str | None = None, solver: str = "auto", rtol: float = DEFAULT_RTOL,
                 feature_angle: float | None = None, sharp_edges: SharpEdges = None):
        mesh = as_mesh(mesh)
        if not isinstance(compat, (str, type(None))) or compat not in COMPAT_MODES:
            raise ParameterError(f"unknown compat mode {compat!r}; choose 'blender' or None (paper)")
        self.blender = compat == "blender"
        if self.blender and scheme not in (None, "blender"):
            raise ParameterError(f"compat='blender' uses Blender's weights; scheme={scheme!r} is not allowed with it")
        self.scheme = check_scheme(scheme or ("blender" if self.blender else "tqlbo"))
        if not isinstance(solver, str) or solver not in FLOW_SOLVERS:
            raise ParameterError(f"unknown solver {solver!r}; choose one of {', '.join(FLOW_SOLVERS)}")
        # extreme coordinates: the flow runs on an exact power-of-two copy (it is scale-equivariant:
        # eq. 10 and the umbrella step are scale-free, eq. 9's λ scales with the area) and the result
        # is scaled back exactly; Blender's absolute thresholds keep Blender's units
        self.input_mesh = mesh
        self._pow2 = pow2_exponent(mesh.vertices)
        if self._pow2 and self.blender:
            if self._pow2 > 0:
                raise ParameterError(f"compat='blender' computes in Blender's absolute units, and coordinates up "
                                     f"to {np.ldexp(1.0, self._pow2):.3g} are beyond its float32 range; use the "
                                     "paper mode (compat=None), which works at any scale")
            self._pow2 = 0    # tiny Blender meshes: Blender's thresholds lock them, as Blender does
        self.mesh = mesh if not self._pow2 else mesh.with_vertices(np.ldexp(mesh.vertices, -self._pow2))
        self.lam_border = params.lam("lam_border", lam_border)
        self.normalized = params.flag("normalized", normalized)
        self.w = resolve_weights(mesh, weights, params.flag("invert_weights", invert_weights))
        self.solver_method = solver
        self.rtol = params.rtol(rtol)
        # sharp edges (flow.features): topology, detected once at the input positions
        self.sharp = resolve_sharp_edges(self.mesh, feature_angle, sharp_edges, carrier=mesh)
        self.systems = SystemBuilder(self.mesh, w=self.w, scheme=self.scheme, blender=self.blender,
                                     normalized=self.normalized, method=solver, rtol=self.rtol,
                                     lam_border=self.lam_border, sharp=self.sharp)

    @property
    def pow2(self) -> int:
        """k when the flow runs on the input scaled by 2^-k (extreme coordinates), else 0."""
        return self._pow2

    def operator(self, V: np.ndarray | None = None) -> Operator:
        """The operator at the input positions (cached) or at ``V`` (:meth:`SystemBuilder.operator`)."""
        return self.systems.operator(V)

    @staticmethod
    def _note_features(operator: Operator, report: FlowReport) -> None:
        """The sharp edges' counts in the report (nothing without sharp edges)."""
        if operator.curve is not None:
            report.sharp_edges, report.curve_vertices, report.feature_fixed = operator.curve.curves.counts
            report.notes.append(f"{report.sharp_edges} sharp edges: {report.curve_vertices} vertices follow their "
                                f"feature curves, {report.feature_fixed} curve ends and corners stay")

    @staticmethod
    def _note_solver(system: LinearSystem | None, report: FlowReport) -> None:
        """Carry a solver's fallback (CG short of its tolerance, redone by LU) into the report."""
        if system is not None and system.solver.stats.fallback:
            report.notes.append(system.solver.stats.fallback)
            if system.idx is None:   # the interior system names the run's solver
                report.solver = system.solver.method

    def _step(self, V: np.ndarray, lam: float, lam_b: float, interior_sys: LinearSystem | None,
              boundary_sys: LinearSystem | None, boundary: np.ndarray, axes: np.ndarray,
              report: FlowReport, curve_sys: LinearSystem | None = None) -> np.ndarray:
        X = self.systems.solve_boundary(V, boundary_sys, copy=False)   # V itself when there is no boundary block
        if curve_sys is not None:      # the feature curves, then the surface with them as boundary values
            X = solve_curves(V, X, curve_sys, lam)
            self._note_solver(curve_sys, report)
        if interior_sys is not None:
            r, s, e = interior_sys.coupling
            held = interior_sys.held
            rhs = interior_sys.c[:, None] * V          # c = 0 on held rows
            rhs[held] = X[held]                # identity rows of A
            if r.size:
                for k in range(3):
                    rhs[:, k] += np.bincount(r, e * X[s, k], minlength=V.shape[0])
            Xi = interior_sys.solver.solve(rhs, X, overwrite_b=True)   # rhs is ours: the CG's residual
            if interior_sys.solver.method == "cg" or interior_sys.solver.stats.fallback:
                report.cg_iterations.append(interior_sys.solver.stats.iterations)
                report.preconditioner = interior_sys.solver.stats.preconditioner
            Xi[held] = X[held]                 # exactly, not to the solver's tolerance
            if abs(lam) >= MEAN_RESTORE_FROM:
                interior_sys.restore_means(Xi, V)
            X = Xi
        self._note_solver(boundary_sys, report)
        self._note_solver(interior_sys, report)
        if not np.all(np.isfinite(X)):
            bad = ~np.isfinite(X).all(axis=1)
            X[bad] = V[bad]
            report.notes.append(f"{int(bad.sum())} vertices with a non-finite solution kept in place")
        # V + sign (X - V), per vertex sign (boundary vertices follow λ_b), on the chosen axes
        s_in, s_b = (1.0 if lam >= 0 else -1.0), (1.0 if lam_b >= 0 else -1.0)
        d = np.subtract(X, V, out=None if X is V else X)
        if s_in != s_b and boundary.any():
            d *= np.where(boundary, s_b, s_in)[:, None]
        elif s_in < 0:
            np.negative(d, out=d)
        if not axes.all():
            d[:, ~axes] = 0.0
        return np.add(V, d, out=d)

    @accel.heavy
    def run(self, lam: float, *, iterations: int = 1, preserve_volume: bool = False,
            axes: Axes = (True, True, True), update: str = "fixed",
            progress: Callable[[int, int], None] | None = None) -> Mesh:
        """Run ``iterations`` implicit steps with factor ``lam``; returns a new Mesh.

        The returned mesh carries a :class:`FlowReport` as ``result.report``.
        """
        t0 = time.perf_counter()
        lam = params.lam("lam", lam)
        lam_user = lam
        if self._pow2 and not self.normalized:   # eq. 9: C = 2A/(|λ|w) and A scales by 4^-k
            lam = float(np.ldexp(lam, -2 * self._pow2))
        preserve_volume = params.flag("preserve_volume", preserve_volume)
        params.progress(progress)
        lam_b = self.lam_border
        ax = check_run_options(iterations, update, axes, self.blender)
        report = FlowReport(lam=lam_user, lam_border=lam_b, iterations=int(iterations),
                            mode="blender" if self.blender else "paper", scheme=self.scheme, update=update)
        mesh = self.mesh
        V0 = mesh.vertices
        if iterations == 0 or not ax.any() or (lam == 0.0 and lam_b == 0.0) or not (self.w > 0).any() \
                or mesh.n_faces == 0:
            report.notes.append("nothing to do: input returned unchanged")
            return self._result(V0, report, t0)
        operator = self.operator()
        report.locked_vertices = np.flatnonzero(operator.locked)
        report.locked = int(report.locked_vertices.size)
        report.degenerate_triangles = operator.n_bad
        report.boundary_vertices = int(operator.boundary.sum())
        self._note_features(operator, report)
        topo = mesh.topology
        nm = int(topo.nonmanifold_edge_mask.sum())
        if nm:
            report.notes.append(f"{nm} non-manifold edges: their faces all contribute, vertices treated as interior")
        if preserve_volume:
            inc = int(topo.inconsistent_edge_mask.sum())
            if inc:
                report.notes.append(f"{inc} edges with inconsistent face orientation: "
                                    "the volume being preserved is ill-defined")
        center0 = V0.mean(axis=0) if preserve_volume else None
        n_solves = iterations if update == "fixed" else 1
        V = V0                     # read only: every step returns new positions
        for it in range(int(iterations)):
            if it == 0 or update == "recompute":
                if it > 0:
                    operator = self.operator(V)
                    # the report describes the operator of the last step taken
                    report.locked_vertices = np.flatnonzero(operator.locked)
                    report.locked = int(report.locked_vertices.size)
                    report.degenerate_triangles = operator.n_bad
                interior_sys = self.systems.interior(operator, lam, n_solves, report.notes,
                                                     lean=mesh.n_vertices >= system.LEAN_FROM)
                boundary_sys = self.systems.boundary(operator, lam_b)
                curve_sys = self.systems.curve_system(operator, lam)
                if interior_sys is not None:
                    report.solver = interior_sys.solver.method
                n_free_i = int(interior_sys.free.sum()) if interior_sys else 0
                n_free_b = int(boundary_sys.free.sum()) if boundary_sys else 0
                report.free_vertices = n_free_i + n_free_b + (int(curve_sys.free.sum()) if curve_sys else 0)
                if interior_sys is None and boundary_sys is None and curve_sys is None:
                    report.notes.append("no free vertex: input returned unchanged" if it == 0 else
                                        f"no free vertex left after step {it} (the operator rebuilt at the moved "
                                        f"positions locks or fixes them all): stopped after {it} of "
                                        f"{int(iterations)} steps")
                    report.steps = it
                    break
            if it == 0 and update == "fixed" and iterations >= 2 and not preserve_volume and boundary_sys is None \
                    and curve_sys is None and interior_sys is not None and interior_sys.solver.method == "cg" \
                    and not isinstance(interior_sys.A, PairMatrix) \
                    and self.solver_method in ("auto", "chebyshev"):
                V_all = fixed_steps(V, lam, int(iterations), interior_sys, ax, report, operator.pattern, self.rtol)
                if V_all is not None:
                    V = V_all
                    report.steps = int(iterations)
                    if progress is not None:
                        progress(int(iterations), int(iterations))
                    break
            V_new = self._step(V, lam, lam_b, interior_sys, boundary_sys, operator.boundary, ax, report, curve_sys)
            if preserve_volume:
                V_new = self.systems.rescale_volume(V, V_new, ax, center0, report)
            V = V_new
            if progress is not None:
                progress(it + 1, int(iterations))
        else:
            report.steps = int(iterations)
        report.notes = list(dict.fromkeys(report.notes))
        return self._result(V, report, t0)

    def _result(self, V: np.ndarray, report: FlowReport, t0: float) -> Mesh:
        moved = V is not self.mesh.vertices
        with np.errstate(over="ignore"):   # measured at the computed scale, scaled back exactly (2^0 = 1)
            report.max_displacement = float(np.ldexp(max_row_distance(V, self.mesh.vertices), self._pow2))
        mesh = self.input_mesh
        if self._pow2:   # back to the caller's scale, exactly
            report.notes.append(f"computed on the coordinates scaled by 2^{-self._pow2} (exact), then scaled back")
            if moved:
                with np.errstate(over="ignore"):
                    V = np.ldexp(V, self._pow2)
                if not np.isfinite(V).all():
                    raise ParameterError("lam: the result leaves the range of double precision (|x| > 1.8e308)")
        if not moved:
            out = mesh.with_vertices(mesh.vertices)
        else:   # V is a new array of this run: handed over without a copy (validated if not finite)
            out = mesh.with_own_vertices(V)
        if moved and has_normals(out):
            out = refresh_normals(out)
            report.notes.append("normals recomputed from the new surface")
        report.seconds = time.perf_counter() - t0
        out.report = report
        return out


def max_row_distance(A: np.ndarray, B: np.ndarray) -> float:
    """max_i |A_i − B_i| over the rows of two (n, 3) arrays (the flow family's kernel)."""
    return accel.kernels("flow", A.shape[0]).max_row_distance(A, B)
