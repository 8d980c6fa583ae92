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

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np
import scipy.sparse as sp

from . import kernels, params
from .errors import ParameterError
from .geometry import NORMAL_ATTRIBUTES, pow2_exponent, refresh_normals, signed_volume
from .mesh import Mesh
from .operators import _assemble, _check_scheme
from .solvers import (DEFAULT_RTOL, METHODS, SPDSolver, chebyshev_coefficients, chebyshev_steps, choose_method,
                      estimate_cg_iterations)

__all__ = ["flow", "smooth", "enhance", "FlowReport", "FlowSolver", "COMPAT_MODES"]

COMPAT_MODES = (None, "paper", "blender")
UPDATES = ("fixed", "recompute")
FLOW_SOLVERS = (*METHODS, "chebyshev")


# --------------------------------------------------------------------------
# parameters
# --------------------------------------------------------------------------

#: From this |λ| on, the solution's conserved means are restored after each solve
#: (:meth:`_System.restore_means`); below it the solvers' own accuracy is far below ``rtol``.
MEAN_RESTORE_FROM = 1e6

#: The most implicit steps one call takes (k steps of λ move about as far as one step of kλ).
ITERATIONS_MAX = 100_000


def check_run_options(iterations, update, axes, blender: bool) -> np.ndarray:
    """Validate the per-run options of the flow; returns the axes mask."""
    params.integer("iterations", iterations, lo=0, hi=ITERATIONS_MAX)
    if not isinstance(update, str) or update not in UPDATES:
        raise ParameterError(f"update must be 'fixed' or 'recompute', got {update!r}")
    if blender and update != "fixed":
        raise ParameterError("compat='blender' keeps the operator of the first iteration (update='fixed')")
    return params.axes(axes)


def resolve_weights(mesh: Mesh, weights, invert: bool = False) -> np.ndarray:
    """Per-vertex weights in [0, 1] from None (all 1), an attribute name or an array."""
    n = mesh.n_vertices
    if weights is None:
        w = np.ones(n)
    elif isinstance(weights, str):
        if weights not in mesh.attributes:
            have = ", ".join(mesh.attributes) or "none"
            raise ParameterError(f"the mesh has no attribute '{weights}' (attributes: {have})")
        w = np.asarray(mesh.attributes[weights], dtype=np.float64)
        if w.ndim != 1:
            raise ParameterError(f"attribute '{weights}' has shape {w.shape}; weights need shape ({n},)")
    else:
        w = params.real_array("weights", weights)
        if w.shape != (n,):
            raise ParameterError(f"weights must have shape ({n},) (one per vertex), got {w.shape}")
    bad = np.flatnonzero(~np.isfinite(w) | (w < 0) | (w > 1))
    if bad.size:
        i = int(bad[0])
        raise ParameterError(f"weights must lie in [0, 1]; vertex {i} has {float(w[i])!r} ({bad.size} such vertices)")
    return 1.0 - w if invert else w.copy()


# --------------------------------------------------------------------------
# report
# --------------------------------------------------------------------------

@dataclass
class FlowReport:
    """What a flow run did (``result.report`` on the returned mesh)."""

    lam: float
    lam_border: float
    iterations: int
    mode: str
    scheme: str
    update: str
    solver: str = "none"
    cg_iterations: list = field(default_factory=list)
    locked: int = 0
    locked_vertices: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    degenerate_triangles: int = 0
    boundary_vertices: int = 0
    free_vertices: int = 0
    volume_scale: list = field(default_factory=list)
    notes: list = field(default_factory=list)
    seconds: float = 0.0
    max_displacement: float = 0.0
    steps: int = 0            # steps taken (fewer than ``iterations`` only when no vertex was left free)

    def summary(self) -> str:
        """One line: time, max displacement, locked vertices, solver."""
        its = f", CG iterations {self.cg_iterations}" if self.cg_iterations else ""
        notes = f"; {'; '.join(self.notes)}" if self.notes else ""
        return (f"{self.seconds:.3f} s, max displacement {self.max_displacement:.6g}, "
                f"{self.locked} locked vertices, solver {self.solver}{its}{notes}")


# --------------------------------------------------------------------------
# the operator at given positions
# --------------------------------------------------------------------------

@dataclass
class _Operator:
    st: object
    pw: np.ndarray          # pair weights w_ij
    deg: np.ndarray         # D_i
    mass: np.ndarray        # m_i: the row scale (D, 2A or Blender's 4aD)
    locked: np.ndarray
    boundary: np.ndarray    # boundary-vertex mask
    ub: np.ndarray          # (Q, 2) umbrella pairs
    ue: np.ndarray          # (Q,) umbrella weights e_ij
    E: np.ndarray           # Σ e_ij per vertex
    n_bad: int


def _build_operator(mesh: Mesh, V: np.ndarray, scheme: str, blender: bool, normalized: bool) -> _Operator:
    t = mesh.topology
    st, pw, deg, ring, locked, n_bad = _assemble(mesh, scheme, "blender" if blender else "relative", V)
    edges = t.edges

    def lengths(e):  # only the umbrella edges need a length (few: they lie on the boundary)
        return np.linalg.norm(V[e[:, 0]] - V[e[:, 1]], axis=1)

    if blender:
        boundary = t.vertex_edge_count != t.vertex_corner_count
        sel = boundary[edges[:, 0]] & boundary[edges[:, 1]] if edges.size else np.zeros(0, bool)
        ub = edges[sel]
        el = lengths(ub)
        # Blender keeps the raw length as the weight of a too-short edge (its ends are locked)
        ue = np.where(el < 1e-5, el, 1.0 / np.where(el < 1e-5, 1.0, el))
        mass = deg if normalized else 4.0 * ring * deg
    else:
        boundary = t.boundary_vertex_mask.copy()
        sel = t.boundary_edge_mask & ~locked[edges[:, 0]] & ~locked[edges[:, 1]]
        ub = edges[sel]
        el = lengths(ub)
        ue = 1.0 / el  # short edges were locked above, so el > 0 here
        mass = deg if normalized else 2.0 * ring
    n = mesh.n_vertices
    E = np.bincount(ub[:, 0], ue, minlength=n) + np.bincount(ub[:, 1], ue, minlength=n) if ub.size else np.zeros(n)
    return _Operator(st, pw, deg, mass, locked, boundary, ub, ue, E, n_bad)


# --------------------------------------------------------------------------
# the solver object
# --------------------------------------------------------------------------

class _System:
    """One linear system on a subset of free vertices, with its couplings.

    ``c`` is the diagonal scale C of the free rows; ``coupling`` the (rows,
    cols, weights) of terms moved to the right-hand side.  A boundary system
    is compact: ``idx`` lists its vertices and ``local`` maps a vertex to its
    row (-1 elsewhere); an interior system spans all n rows (``idx`` None).
    """

    def __init__(self, A, free, solver, coupling, c, idx=None, local=None):
        self.A = A
        self.free = free
        self.solver = solver
        self.coupling = coupling
        self.c = c
        self.idx = idx
        self.local = local
        self.held = np.flatnonzero(~free) if idx is None else None   # interior system: rows kept as they are
        self._modes = None

    def restore_means(self, X: np.ndarray, V: np.ndarray) -> None:
        """Put back, in place, the exact C-weighted mean of every free part that couples to nothing fixed.

        On such a part K the rows of A sum to c (A = C + D − W, and D − W has
        zero row sums), so Σ_K c_i x_i = Σ_K c_i v_i holds exactly for the
        solution.  A direct solver's rounding error, amplified by the
        condition number ~|λ|, lies almost entirely in that constant mode (the
        system is singular but for C there): at |λ| = 1e12 it moved the mean by
        ~1e-6 of the displacement.  Restoring the mean removes it.  ``X``, ``V``
        are the system's rows (all n for the interior, ``idx`` for the boundary).
        """
        if self._modes is None:
            self._modes = self._free_parts()
        labels, k = self._modes
        if k == 0:
            return
        sel = labels >= 0
        lab, c = labels[sel], self.c[sel]
        cw = np.bincount(lab, c, minlength=k)
        for q in range(X.shape[1]):
            shift = (np.bincount(lab, c * V[sel, q], minlength=k) - np.bincount(lab, c * X[sel, q], minlength=k)) / cw
            X[sel, q] += shift[lab]

    def _free_parts(self):
        """Labels (-1: not in such a part) and count of the free parts that couple to nothing fixed."""
        from scipy.sparse.csgraph import connected_components

        A = self.A.tocsr()
        rows = np.flatnonzero(self.free) if self.idx is None else np.arange(A.shape[0])
        sub = A[rows][:, rows]
        k, lab = connected_components(sub, directed=False)
        bad = np.zeros(k, bool)
        r = self.coupling[0]
        if r.size:   # parts with a term moved to the right-hand side: their mean is not conserved
            pos = np.full(self.free.shape[0], -1)
            pos[rows if self.idx is None else self.idx] = np.arange(rows.size)
            bad[lab[pos[r]]] = True
        # rows that do not sum to c (e.g. Blender's indefinite rows): no conservation to restore
        excess = np.abs(np.asarray(sub.sum(axis=1)).ravel() - self.c[rows])
        scale = np.asarray(abs(sub).sum(axis=1)).ravel()
        bad[lab[excess > 1e-9 * scale]] = True
        keep = ~bad
        new = np.cumsum(keep) - 1
        labels = np.full(A.shape[0], -1)
        labels[rows] = np.where(keep[lab], new[lab], -1)
        return labels, int(keep.sum())


def _max_row_distance(A: np.ndarray, B: np.ndarray, chunk: int = 4096) -> float:
    """max_i |A_i − B_i| (rows of (n, 3) arrays), in chunks small enough for malloc to reuse (no fresh pages)."""
    best = 0.0
    for s in range(0, A.shape[0], chunk):
        d = A[s:s + chunk] - B[s:s + chunk]
        best = max(best, float(np.einsum("ij,ij->i", d, d).max()))
    return float(np.sqrt(best))


def _row_scale(mass: np.ndarray, lam_abs: float, w: np.ndarray, rows: np.ndarray,
               coord_scale: float) -> np.ndarray:
    """C = m / (|λ| w) on ``rows`` (0 elsewhere).

    A step so small that C·V would overflow (|λ| near the float limit) moves
    nothing representable: those rows come back as inf and the caller keeps
    them fixed.
    """
    c = np.zeros_like(mass)
    with np.errstate(over="ignore", divide="ignore"):
        c[rows] = mass[rows] / (lam_abs * w[rows])
    limit = np.finfo(np.float64).max / (64.0 * max(coord_scale, 1.0))
    c[c > limit] = np.inf
    return c


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

    @kernels.with_small_pages
    def __init__(self, mesh: Mesh, *, lam_border: float = 0.0, normalized: bool = True,
                 weights=None, invert_weights: bool = False, scheme: str | None = None,
                 compat: str | None = None, solver: str = "auto", rtol: float = DEFAULT_RTOL):
        if not isinstance(mesh, Mesh):
            raise ParameterError(f"expected a shapeflow.Mesh, got {type(mesh).__name__}")
        if not isinstance(compat, (str, type(None))) or compat not in COMPAT_MODES:
            raise ParameterError(f"unknown compat mode {compat!r}; choose 'blender' or None (paper)")
        self.blender = compat == "blender"
        if self.blender and scheme not in (None, "blender"):
            raise ParameterError(f"compat='blender' uses Blender's weights; scheme={scheme!r} is not allowed with it")
        self.scheme = _check_scheme(scheme or ("blender" if self.blender else "tqlbo"))
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
        self._op0: _Operator | None = None
        self._op0_lock = threading.Lock()
        self._coord_scale = float(np.abs(self.mesh.vertices).max()) if mesh.n_vertices else 1.0

    # --- operator and systems ----------------------------------------------
    def operator(self, V: np.ndarray | None = None) -> _Operator:
        """The operator at the input positions (cached) or at ``V``."""
        if V is None:
            with self._op0_lock:
                if self._op0 is None:
                    self._op0 = _build_operator(self.mesh, self.mesh.vertices, self.scheme, self.blender,
                                                self.normalized)
            return self._op0
        return _build_operator(self.mesh, V, self.scheme, self.blender, self.normalized)

    def _method(self, n_free: int, kappa: float, n_solves: int) -> str:
        if self.solver_method == "chebyshev":
            return "cg"   # single steps; several fixed steps go through _fixed_steps
        if self.solver_method != "auto":
            return self.solver_method
        return choose_method(n_free, kappa, n_solves, self.rtol)

    def _interior_system(self, op: _Operator, lam: float, n_solves: int, notes: list) -> _System | None:
        if lam == 0.0:
            return None
        w = self.w
        free = ~op.boundary & ~op.locked & (w > 0) & (op.mass > 0) & (op.deg > 0)
        indefinite = ~op.boundary & ~op.locked & (w > 0) & ((op.mass < 0) | (op.deg < 0))
        if indefinite.any():
            if self.blender:
                free |= indefinite  # Blender solves these rows too; use LU below
            else:
                notes.append(f"{int(indefinite.sum())} vertices with negative cotangent degree kept fixed")
        c = _row_scale(op.mass, abs(lam), w, free, self._coord_scale)
        tiny = free & ~np.isfinite(c)
        if tiny.any():
            notes.append(f"{int(tiny.sum())} vertices kept fixed: |λ|·weight is so small that their step "
                         "moves nothing representable")
        free &= ~tiny
        if not free.any():
            return None
        c[~free] = 0.0
        st = op.st
        p0, p1 = st.pairs[:, 0], st.pairs[:, 1]
        K = kernels.get(st.n)
        if K is not None:   # the same matrix in one compiled pass
            data, diag, mixed, ratio = K.interior_data(st.indices.size, st.pos_diag, st.pos_upper, st.pos_lower,
                                                       st.pairs, free, c, op.deg, op.pw)
            A = st.matrix_from_data(data)
            n_mixed = sum(mixed)
        else:
            both = free[p0] & free[p1]
            diag = np.where(free, c + op.deg, 1.0)
            A = st.matrix(diag, np.where(both, -op.pw, 0.0))
            n_mixed = -1
            ratio = float(np.max(np.abs(op.deg[free] / np.where(c[free] != 0, c[free], 1.0))))
        # terms of free rows on non-free columns move to the right-hand side
        if n_mixed and K is not None:
            coupling = K.interior_coupling(st.pairs, free, op.pw, mixed)
        elif n_mixed:
            a = free[p0] & ~free[p1]
            b = free[p1] & ~free[p0]
            coupling = (np.concatenate([p0[a], p1[b]]), np.concatenate([p1[a], p0[b]]),
                        np.concatenate([op.pw[a], op.pw[b]]))
        else:
            coupling = (np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0))
        kappa = 1.0 + 2.0 * ratio
        method = "lu" if (self.blender and indefinite.any()) else self._method(int(free.sum()), kappa, n_solves)
        return _System(A, free, SPDSolver(A, method, rtol=self.rtol, diagonal=diag), coupling, c)

    def _boundary_system(self, op: _Operator, lam_b: float) -> _System | None:
        if lam_b == 0.0 or op.ub.size == 0:
            return None
        w = self.w
        free = op.boundary & ~op.locked & (w > 0) & (op.E > 0)
        k_b = 2.0 if self.blender else 1.0
        c_all = _row_scale(op.E, k_b * abs(lam_b), w, free, self._coord_scale)
        free &= np.isfinite(c_all)
        if not free.any():
            return None
        idx = np.flatnonzero(free)
        local = np.full(self.mesh.n_vertices, -1)
        local[idx] = np.arange(idx.size)
        c = c_all[idx]
        q0, q1 = op.ub[:, 0], op.ub[:, 1]
        both = free[q0] & free[q1]
        rows = np.concatenate([local[q0[both]], local[q1[both]], np.arange(idx.size)])
        cols = np.concatenate([local[q1[both]], local[q0[both]], np.arange(idx.size)])
        vals = np.concatenate([-op.ue[both], -op.ue[both], c + op.E[idx]])
        A = sp.csr_matrix((vals, (rows, cols)), shape=(idx.size, idx.size))
        # neighbours that are not free: their current position enters the right-hand side,
        # except (Blender) a locked neighbour, whose term Blender leaves out of the row
        a = free[q0] & ~free[q1]
        b = free[q1] & ~free[q0]
        r = np.concatenate([q0[a], q1[b]])
        s = np.concatenate([q1[a], q0[b]])
        e = np.concatenate([op.ue[a], op.ue[b]])
        if self.blender:
            keep = ~op.locked[s]
            r, s, e = r[keep], s[keep], e[keep]
        method = "lu" if idx.size < 20000 else "cg"
        return _System(A, free, SPDSolver(A, method, rtol=self.rtol), (r, s, e), c, idx, local)

    # --- one step -------------------------------------------------------------
    def _solve_boundary(self, V: np.ndarray, bsys: _System | None, *, copy: bool = True) -> np.ndarray:
        """Positions after the boundary block's solve (a copy of V elsewhere).

        With ``copy=False`` and no boundary block, V itself (not to be written).
        """
        if bsys is None and not copy:
            return V
        X = V.copy()
        if bsys is not None:
            r, s, e = bsys.coupling
            rhs = bsys.c[:, None] * V[bsys.idx]
            if r.size:
                lr = bsys.local[r]
                for k in range(3):
                    rhs[:, k] += np.bincount(lr, e * V[s, k], minlength=bsys.idx.size)
            Xb = bsys.solver.solve(rhs, V[bsys.idx], overwrite_b=True)
            if abs(self.lam_border) >= MEAN_RESTORE_FROM:
                bsys.restore_means(Xb, V[bsys.idx])
            X[bsys.idx] = Xb
        return X

    @staticmethod
    def _note_solver(system: _System | None, report: FlowReport) -> None:
        """Carry a solver's fallback (CG short of its tolerance, redone by LU) into the report."""
        if system is not None and system.solver.stats.fallback:
            report.notes.append(system.solver.stats.fallback)
            if system.idx is None:   # the interior system names the run's solver
                report.solver = system.solver.method

    def _step(self, V: np.ndarray, lam: float, lam_b: float, isys: _System | None,
              bsys: _System | None, boundary: np.ndarray, axes: np.ndarray, report: FlowReport) -> np.ndarray:
        X = self._solve_boundary(V, bsys, copy=False)   # V itself when there is no boundary block
        if isys is not None:
            r, s, e = isys.coupling
            held = isys.held
            rhs = isys.c[:, None] * V          # c = 0 on held rows
            rhs[held] = X[held]                # identity rows of A
            if r.size:
                for k in range(3):
                    rhs[:, k] += np.bincount(r, e * X[s, k], minlength=V.shape[0])
            Xi = isys.solver.solve(rhs, X, overwrite_b=True)   # rhs is ours: the CG's residual
            if isys.solver.method == "cg" or isys.solver.stats.fallback:
                report.cg_iterations.append(isys.solver.stats.iterations)
            Xi[held] = X[held]                 # exactly, not to the solver's tolerance
            if abs(lam) >= MEAN_RESTORE_FROM:
                isys.restore_means(Xi, V)
            X = Xi
        self._note_solver(bsys, report)
        self._note_solver(isys, report)
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

    def _fixed_steps(self, V: np.ndarray, lam: float, k: int, isys: _System, axes: np.ndarray,
                     report: FlowReport, st) -> np.ndarray | None:
        """All ``k`` steps of a fixed operator at once, by a Chebyshev expansion.

        With the operator fixed, no boundary step and no volume rescaling, the
        k steps are one affine map.  In u = C^½ x on the free rows, with
        S = C^-½ A C^-½ (spectrum in [1, b], b from Gershgorin) and
        h = C^-½ g (the fixed neighbours' terms), a step is
        u ← a(S) u + b(S) h with a(t) = 1/t, b(t) = 1/t for λ > 0 and
        a(t) = 2 − 1/t, b(t) = −1/t for λ < 0; so
        u_k = a(S)^k u_0 + b(S) Σ_{j<k} a(S)^j h.  Both Chebyshev series are
        summed by one Clenshaw recurrence on three columns (a sparse product
        per degree; :func:`~shapeflow.solvers.chebyshev_steps`), to a degree at
        which the bound on what is left is below ``rtol`` × the displacement —
        the accuracy of k CG solves, for the price of about three.  Returns None
        (iterate instead) when the expansion would cost more than iterating.
        """
        free = isys.free
        A = isys.A
        isq = np.zeros(V.shape[0])
        isq[free] = 1.0 / np.sqrt(isys.c[free])
        # Gershgorin bound of S on the free rows (non-free rows are identity rows of A);
        # duplicate entries (a chord shared by two faces) add their |a_ij|: still a bound
        K = kernels.get(A.shape[0])
        if K is not None:
            upper = K.scaled_abs_row_max(A.indptr, A.indices, A.data, isq)
        else:
            absA = sp.csr_matrix((np.abs(A.data), A.indices, A.indptr), shape=A.shape)
            upper = float((isq * (absA @ isq))[free].max())
        lo, hi = 1.0, max(upper, 1.0 + 1e-12)
        if lam > 0:
            fa = lambda t: 1.0 / t                     # noqa: E731
            fb = lambda t: 1.0 / t                     # noqa: E731
        else:
            fa = lambda t: 2.0 - 1.0 / t               # noqa: E731
            fb = lambda t: -1.0 / t                    # noqa: E731

        def fu(t):
            return fa(t) ** k

        def fh(t):
            at = fa(t)
            acc = np.ones_like(t)
            for _ in range(k - 1):
                acc = 1.0 + at * acc
            return fb(t) * acc

        cu, tu = chebyshev_coefficients(fu, lo, hi)
        ch, th = chebyshev_coefficients(fh, lo, hi)
        n_c = min(cu.size, ch.size)
        ok = (tu[:n_c] <= 1e-12 * np.abs(cu).sum()) & (th[:n_c] <= 1e-12 * np.abs(ch).sum())
        need = int(np.argmax(ok)) if ok.any() else 0
        if need == 0 or need > 0.5 * k * estimate_cg_iterations(hi, self.rtol):
            return None
        r, s_, e = isys.coupling
        n = V.shape[0]
        G = np.zeros((n, 3))
        if r.size:
            for q in np.flatnonzero(axes):
                G[:, q] = np.bincount(r, e * V[s_, q], minlength=n)
        c = isys.c                                      # 0 on the held rows (see _interior_system)
        # with the kernels, the expansion's sparse products in a bandwidth-reducing order:
        # same sums, in cache-friendlier order (A's data lies on st's pattern, as built there)
        loc = st.locality() if axes.all() else None
        if loc is not None:
            perm, inv, ptr, idx, src = loc
            Ap = sp.csr_matrix((K.take(A.data, src), idx, ptr), shape=A.shape, copy=False)
            X0p = np.empty((n, 3))
            K.take_free(V, perm, free, X0p)             # V on the free rows, 0 elsewhere, permuted
            Yp, degree = chebyshev_steps(Ap, K.take(c, perm), X0p, K.take(G, perm), lo, hi,
                                         (cu, tu), (ch, th), self.rtol, need, steps=k, overwrite_g=True)
            if Yp is None or not np.all(np.isfinite(Yp)):
                return None
            out = X0p                                   # free again: the result, fixed rows exactly V
            K.untake_free(Yp, inv, free, V, out)
        else:
            # entries the steps may change: (n, 1) when every axis moves, else (n, 3)
            moving = free[:, None] if axes.all() else free[:, None] & axes[None, :]
            X0 = np.multiply(V, moving)                 # V on the moving entries, 0 elsewhere
            Y, degree = chebyshev_steps(A, c, X0, G, lo, hi, (cu, tu), (ch, th), self.rtol, need, steps=k,
                                        overwrite_g=True)
            if Y is None or not np.all(np.isfinite(Y)):
                return None
            np.copyto(Y, V, where=~moving)              # Y is ours: the fixed entries, exactly
            out = Y
        report.solver = "chebyshev"
        report.notes.append(f"{k} fixed-operator steps as one Chebyshev expansion of degree {degree} "
                            f"(spectrum bound [1, {hi:.3g}])")
        return out

    # --- volume ------------------------------------------------------------------
    def _preserve_volume(self, V_before: np.ndarray, V_after: np.ndarray, axes: np.ndarray,
                         center0: np.ndarray, report: FlowReport) -> np.ndarray:
        mesh = self.mesh
        k = int(axes.sum())
        if self.blender:
            vb = abs(signed_volume(mesh, V_before, center0))
            va = abs(signed_volume(mesh, V_after, center0))
            if va == 0.0:
                return V_after
            beta = (vb / va) ** (1.0 / 3.0)
            c = center0
        else:
            c = V_after.mean(axis=0)
            vb = signed_volume(mesh, V_before, c)
            va = signed_volume(mesh, V_after, c)
            # a volume at rounding level (flat or open surfaces) carries no information
            tiny = 1e-12 * float(np.linalg.norm(np.ptp(V_before, axis=0))) ** 3
            if abs(va) <= tiny or abs(vb) <= tiny or (va > 0) != (vb > 0):
                report.notes.append("volume preservation skipped (volume is zero or changed sign)")
                return V_after
            beta = (vb / va) ** (1.0 / k)
        report.volume_scale.append(float(beta))
        out = V_after.copy()
        out[:, axes] = c[axes] + beta * (V_after[:, axes] - c[axes])
        return out

    # --- public -----------------------------------------------------------------
    @kernels.with_small_pages
    def run(self, lam: float, *, iterations: int = 1, preserve_volume: bool = False,
            axes=(True, True, True), update: str = "fixed",
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
        op = self.operator()
        report.locked_vertices = np.flatnonzero(op.locked)
        report.locked = int(report.locked_vertices.size)
        report.degenerate_triangles = op.n_bad
        report.boundary_vertices = int(op.boundary.sum())
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
                    op = self.operator(V)
                    # the report describes the operator of the last step taken
                    report.locked_vertices = np.flatnonzero(op.locked)
                    report.locked = int(report.locked_vertices.size)
                    report.degenerate_triangles = op.n_bad
                isys = self._interior_system(op, lam, n_solves, report.notes)
                bsys = self._boundary_system(op, lam_b)
                if isys is not None:
                    report.solver = isys.solver.method
                report.free_vertices = int((isys.free.sum() if isys else 0) + (bsys.free.sum() if bsys else 0))
                if isys is None and bsys is None:
                    report.notes.append("no free vertex: input returned unchanged" if it == 0 else
                                        f"no free vertex left after step {it} (the operator rebuilt at the moved "
                                        f"positions locks or fixes them all): stopped after {it} of "
                                        f"{int(iterations)} steps")
                    report.steps = it
                    break
            if it == 0 and update == "fixed" and iterations >= 2 and not preserve_volume and bsys is None \
                    and isys is not None and isys.solver.method == "cg" \
                    and self.solver_method in ("auto", "chebyshev"):
                V_all = self._fixed_steps(V, lam, int(iterations), isys, ax, report, op.st)
                if V_all is not None:
                    V = V_all
                    report.steps = int(iterations)
                    if progress is not None:
                        progress(int(iterations), int(iterations))
                    break
            V_new = self._step(V, lam, lam_b, isys, bsys, op.boundary, ax, report)
            if preserve_volume:
                V_new = self._preserve_volume(V, V_new, ax, center0, report)
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
            report.max_displacement = float(np.ldexp(_max_row_distance(V, self.mesh.vertices), self._pow2))
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
            out = mesh._with_own_vertices(V)
        if moved and any(k in out.attributes for k in NORMAL_ATTRIBUTES):
            out = refresh_normals(out)
            report.notes.append("vertex normals (nx, ny, nz) recomputed from the new surface")
        report.seconds = time.perf_counter() - t0
        out.report = report
        return out


# --------------------------------------------------------------------------
# functional API
# --------------------------------------------------------------------------

@kernels.with_small_pages
def flow(mesh: Mesh, lam: float, *, lam_border: float = 0.0, iterations: int = 1,
         normalized: bool = True, weights=None, invert_weights: bool = False,
         preserve_volume: bool = False, axes: Sequence[bool] | str = (True, True, True),
         scheme: str | None = None, update: str = "fixed", compat: str | None = None,
         solver: str = "auto", rtol: float = DEFAULT_RTOL,
         progress: Callable[[int, int], None] | None = None) -> Mesh:
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
        Linear solver (:mod:`shapeflow.solvers`); "auto" picks by cost.
        ``"chebyshev"``: several fixed-operator steps as one Chebyshev
        expansion (CG for a single step); "auto" uses it where it picks CG and
        the expansion is cheaper than one CG solve per step.
    rtol : float
        CG tolerance, relative to the initial residual of each solve.
    progress : callable(done, total), optional
        Called after each iteration.

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
                      rtol=rtol).run(lam, iterations=iterations, preserve_volume=preserve_volume,
                                     axes=axes, update=update, progress=progress)


def _strength(s) -> float:
    v = params.number("strength", s)
    if v < 0:
        raise ParameterError(f"strength must be >= 0 (use flow() for a signed λ), got {v}")
    return v


def smooth(mesh: Mesh, strength: float, **kw) -> Mesh:
    """Smooth: ``flow(mesh, +strength, **kw)`` (strength >= 0)."""
    return flow(mesh, _strength(strength), **kw)


def enhance(mesh: Mesh, strength: float, **kw) -> Mesh:
    """Enhance the shape: ``flow(mesh, −strength, **kw)`` (strength >= 0)."""
    return flow(mesh, -_strength(strength), **kw)
