"""The flow's linear systems: the operator at given positions, one system per block, and their builder.

One implicit step (docs/method.md) solves, on the free interior vertices,
``(C + D − W) X = C V + Σ_fixed w_ij V_j`` with ``C = diag(m_i/(|λ| w_i))``
(``D − W`` positive semi-definite), after the boundary vertices of open
meshes, which follow their own umbrella system with factor λ_b.
:class:`SystemBuilder` makes both; :class:`LinearSystem` is one of them
with its solver and its couplings to the fixed vertices.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .. import accel
from ..geometry.measures import signed_volume
from ..linalg import spd
from ..linalg.pairs import PairMatrix
from ..linalg.spd import SPDSolver, choose_method
from ..mesh import Mesh
from ..operators.cotan import assemble
from .options import MEAN_RESTORE_FROM
from .report import FlowReport

__all__ = ["Operator", "build_operator", "LinearSystem", "compact_system", "solve_compact", "row_scale",
           "SystemBuilder", "LEAN_FROM"]

#: From this many vertices a single-step flow solves with CG on a :class:`~shapeflow.linalg.pairs.PairMatrix`
#: (the diagonal and the operator's own pairs) instead of a CSR matrix: ~116 bytes per vertex less,
#: the product ~1.8x slower (measured 2026-11-24); what lets a 50M-vertex scan fit in 24 GB.
LEAN_FROM = 8_000_000


@dataclass
class Operator:
    """The operator of the flow at some positions: pair weights, degrees, row masses, locks, boundary umbrella."""

    pattern: object         # the OperatorPattern (topology only)
    pw: np.ndarray          # pair weights w_ij
    deg: np.ndarray         # D_i
    mass: np.ndarray        # m_i: the row scale (D, 2A or Blender's 4aD)
    locked: np.ndarray
    boundary: np.ndarray    # boundary-vertex mask
    umbrella_pairs: np.ndarray     # (Q, 2) boundary-umbrella pairs
    umbrella_weights: np.ndarray   # (Q,) their weights e_ij
    umbrella_degree: np.ndarray    # Σ e_ij per vertex
    n_bad: int
    curve: object = None    # the feature curves' CurveOperator (flow.features), None without sharp edges


def build_operator(mesh: Mesh, V: np.ndarray, scheme: str, blender: bool, normalized: bool) -> Operator:
    """The :class:`Operator` of ``mesh`` at positions ``V`` (paper or Blender rules)."""
    t = mesh.topology
    pattern, pw, deg, ring, locked, n_bad = assemble(mesh, scheme, "blender" if blender else "relative", V)
    edges = t.edges

    def lengths(e):  # only the umbrella edges need a length (few: they lie on the boundary)
        return np.linalg.norm(V[e[:, 0]] - V[e[:, 1]], axis=1)

    if blender:
        boundary = t.vertex_edge_count != t.vertex_corner_count
        if boundary.any():
            ub = edges[boundary[edges[:, 0]] & boundary[edges[:, 1]]]
        else:                  # a closed mesh: no per-edge test
            ub = np.zeros((0, 2), edges.dtype)
        el = lengths(ub)
        # Blender keeps the raw length as the weight of a too-short edge (its ends are locked)
        ue = np.where(el < 1e-5, el, 1.0 / np.where(el < 1e-5, 1.0, el))
        mass = deg if normalized else 4.0 * ring * deg
    else:
        boundary = t.boundary_vertex_mask.copy()
        ub = edges[t.boundary_edge_mask]     # few: only these are tested for locks
        ub = ub[~locked[ub[:, 0]] & ~locked[ub[:, 1]]]
        el = lengths(ub)
        ue = 1.0 / el  # short edges were locked above, so el > 0 here
        mass = deg if normalized else 2.0 * ring
    n = mesh.n_vertices
    E = np.bincount(ub[:, 0], ue, minlength=n) + np.bincount(ub[:, 1], ue, minlength=n) if ub.size else np.zeros(n)
    return Operator(pattern, pw, deg, mass, locked, boundary, ub, ue, E, n_bad)


class LinearSystem:
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


def compact_system(free: np.ndarray, c_all: np.ndarray, pairs: np.ndarray, weights: np.ndarray,
                   degree: np.ndarray, rtol: float, *, drop: np.ndarray | None = None,
                   method: str | None = None) -> LinearSystem:
    """The system ``(C + D − W) X = C V + Σ_fixed e_ij X_j`` of an umbrella-type block (the boundary
    umbrella, the feature curves) on the vertices ``free``, over the pairs ``pairs`` with weights
    ``weights`` and their sums ``degree``: compact (its own rows), with ``C = c_all`` on them.
    Terms of fixed neighbours move to the right-hand side, except those in ``drop``.  ``method``:
    the solver (default LU below 20,000 rows, CG above)."""
    idx = np.flatnonzero(free)
    local = np.full(free.size, -1)
    local[idx] = np.arange(idx.size)
    c = c_all[idx]
    q0, q1 = pairs[:, 0], pairs[:, 1]
    both = free[q0] & free[q1]
    rows = np.concatenate([local[q0[both]], local[q1[both]], np.arange(idx.size)])
    cols = np.concatenate([local[q1[both]], local[q0[both]], np.arange(idx.size)])
    vals = np.concatenate([-weights[both], -weights[both], c + degree[idx]])
    A = sp.csr_matrix((vals, (rows, cols)), shape=(idx.size, idx.size))
    # neighbours that are not free: their position enters the right-hand side
    a = free[q0] & ~free[q1]
    b = free[q1] & ~free[q0]
    r = np.concatenate([q0[a], q1[b]])
    s = np.concatenate([q1[a], q0[b]])
    e = np.concatenate([weights[a], weights[b]])
    if drop is not None:
        keep = ~drop[s]
        r, s, e = r[keep], s[keep], e[keep]
    if method is None:
        method = "lu" if idx.size < 20000 else "cg"
    return LinearSystem(A, free, SPDSolver(A, method, rtol=rtol), (r, s, e), c, idx, local)


def solve_compact(V: np.ndarray, X_fixed: np.ndarray, X: np.ndarray, block: LinearSystem, lam: float) -> None:
    """Solve a compact block (:func:`compact_system`) at positions ``V``, its fixed neighbours at
    ``X_fixed``; writes the block's rows of ``X``."""
    r, s, e = block.coupling
    rhs = block.c[:, None] * V[block.idx]
    if r.size:
        lr = block.local[r]
        for k in range(3):
            rhs[:, k] += np.bincount(lr, e * X_fixed[s, k], minlength=block.idx.size)
    Xb = block.solver.solve(rhs, V[block.idx], overwrite_b=True)
    if abs(lam) >= MEAN_RESTORE_FROM:
        block.restore_means(Xb, V[block.idx])
    X[block.idx] = Xb


def row_scale(mass: np.ndarray, lam_abs: float, w: np.ndarray, rows: np.ndarray,
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


class SystemBuilder:
    """The linear systems of one implicit step on one mesh: the flow's internal interface.

    :class:`~shapeflow.flow.solver.FlowSolver` builds one per solver object
    (``solver.systems``) and steps with it one λ at a time;
    :func:`~shapeflow.flow.family.family` uses the same systems for many λ
    at once.  Each method is the one place its system is defined:

    * :meth:`operator` — the operator (weights, masses, locks, boundary
      umbrella) at the input positions (cached, built once under a lock) or
      at given ones;
    * :meth:`interior` — the interior system for λ (``None``: nothing free);
    * :meth:`boundary` — the boundary-umbrella system for λ_b;
    * :meth:`solve_boundary` — positions after the boundary block's solve;
    * :meth:`rescale_volume` — the volume-preserving rescale after a step.

    Thread model: every method may run from several threads; the cached
    operator is built under a lock, everything else is per call.
    """

    def __init__(self, mesh: Mesh, *, w: np.ndarray, scheme: str, blender: bool, normalized: bool,
                 method: str, rtol: float, lam_border: float, sharp: np.ndarray | None = None):
        self.mesh = mesh
        self.sharp = sharp          # (E,) sharp edges (flow.features), None: the plain flow
        self.curves = None          # their classification, made with the first operator
        self.w = w
        self.scheme = scheme
        self.blender = blender
        self.normalized = normalized
        self.solver_method = method
        self.rtol = rtol
        self.lam_border = lam_border
        self._op0: Operator | None = None
        self._op0_lock = threading.Lock()
        self._coord_scale = float(np.abs(mesh.vertices).max()) if mesh.n_vertices else 1.0

    def operator(self, V: np.ndarray | None = None) -> Operator:
        """The operator at the input positions (cached) or at ``V``."""
        if V is None:
            with self._op0_lock:
                if self._op0 is None:
                    op = build_operator(self.mesh, self.mesh.vertices, self.scheme, self.blender, self.normalized)
                    if self.sharp is not None:
                        from .features import classify, curve_operator

                        self.curves = classify(self.mesh, self.sharp, op.boundary)
                        op.curve = curve_operator(self.mesh.vertices, self.curves, self.normalized)
                    self._op0 = op
            return self._op0
        op = build_operator(self.mesh, V, self.scheme, self.blender, self.normalized)
        if self.sharp is not None:
            from .features import curve_operator

            op.curve = curve_operator(V, self.operator().curve.curves, self.normalized)
        return op

    def curve_system(self, operator: Operator, lam: float) -> LinearSystem | None:
        """The feature curves' system for λ (None without sharp edges or nothing to solve)."""
        if operator.curve is None:
            return None
        from .features import curve_system

        return curve_system(operator.curve, lam, self.w, operator.locked, self._coord_scale, self.rtol)

    def method(self, n_free: int, kappa: float, n_solves: int, *, n_rows: int | None = None,
               lean: bool = False) -> str:
        """The back end for a system of ``n_free`` unknowns (``n_rows`` rows, the lean layout or
        not: what decides the CG's preconditioner, as :class:`SPDSolver` will)."""
        if self.solver_method == "chebyshev":
            return "cg"   # single steps; several fixed steps go through _fixed_steps
        if self.solver_method != "auto":
            return self.solver_method
        # CG on the CSR system preconditions as the linalg kernels do for "auto" (Gauss–Seidel compiled)
        auto = accel.kernels("linalg", n_free if n_rows is None else n_rows).auto_preconditioner
        sgs = not lean and auto == "sgs" and spd.DEFAULT_PRECONDITIONER != "jacobi"
        return choose_method(n_free, kappa, n_solves, self.rtol, "sgs" if sgs else "jacobi")

    def interior(self, operator: Operator, lam: float, n_solves: int, notes: list, *,
                 lean: bool = False) -> LinearSystem | None:
        """The interior system for λ; ``lean`` (compiled kernels only): a :class:`PairMatrix` when CG
        solves it, no CSR arrays (:data:`LEAN_FROM`)."""
        if lam == 0.0:
            return None
        w = self.w
        free = ~operator.boundary & ~operator.locked & (w > 0) & (operator.mass > 0) & (operator.deg > 0)
        indefinite = ~operator.boundary & ~operator.locked & (w > 0) & ((operator.mass < 0) | (operator.deg < 0))
        if operator.curve is not None:     # feature vertices: boundary values of the surface solve
            free &= ~operator.curve.feature
            indefinite &= ~operator.curve.feature
        if indefinite.any():
            if self.blender:
                free |= indefinite  # Blender solves these rows too; use LU below
            else:
                notes.append(f"{int(indefinite.sum())} vertices with negative cotangent degree kept fixed")
        c = row_scale(operator.mass, abs(lam), w, free, self._coord_scale)
        tiny = free & ~np.isfinite(c)
        if tiny.any():
            notes.append(f"{int(tiny.sum())} vertices kept fixed: |λ|·weight is so small that their step "
                         "moves nothing representable")
        free &= ~tiny
        if not free.any():
            return None
        c[~free] = 0.0
        pattern = operator.pattern
        kern = accel.kernels("flow", pattern.n)
        lean = lean and kern.lean_layout
        A, diag, mixed, ratio = self._matrix(operator, free, c, kern, lean)
        # terms of free rows on non-free columns move to the right-hand side
        coupling = kern.interior_coupling(pattern.pairs, free, operator.pw, mixed)
        kappa = 1.0 + 2.0 * ratio
        method = "lu" if (self.blender and indefinite.any()) else \
            self.method(int(free.sum()), kappa, n_solves, n_rows=pattern.n, lean=lean)
        if A is None:   # the lean layout serves CG; a direct solver needs the entries
            A = PairMatrix(pattern.pairs, operator.pw, free, diag) if method == "cg" else \
                self._matrix(operator, free, c, kern, False)[0]
        # A has the pattern's layout (sorted columns, one diagonal entry a row) unless it is a PairMatrix
        pos = pattern.pos_diag if isinstance(A, sp.csr_matrix) and pattern.csr_built else None
        return LinearSystem(A, free, SPDSolver(A, method, rtol=self.rtol, diagonal=diag, diagonal_positions=pos),
                            coupling, c)

    @staticmethod
    def _matrix(operator: Operator, free: np.ndarray, c: np.ndarray, kern, lean: bool):
        """(A, diagonal, counts of pairs with one free end (None when not counted), max D/c) by the flow
        kernels ``kern``; A is None with ``lean`` (the caller makes a :class:`PairMatrix` for CG, no CSR arrays)."""
        if lean:
            diag, mixed, ratio = kern.interior_diag(operator.pattern.pairs, free, c, operator.deg, operator.pw)
            return None, diag, mixed, ratio
        return kern.interior_matrix(operator.pattern, free, c, operator.deg, operator.pw)

    def boundary(self, operator: Operator, lam_b: float) -> LinearSystem | None:
        if lam_b == 0.0 or operator.umbrella_pairs.size == 0:
            return None
        w = self.w
        free = operator.boundary & ~operator.locked & (w > 0) & (operator.umbrella_degree > 0)
        k_b = 2.0 if self.blender else 1.0
        c_all = row_scale(operator.umbrella_degree, k_b * abs(lam_b), w, free, self._coord_scale)
        free &= np.isfinite(c_all)
        if not free.any():
            return None
        # Blender leaves a locked neighbour's term out of the row
        return compact_system(free, c_all, operator.umbrella_pairs, operator.umbrella_weights,
                              operator.umbrella_degree, self.rtol,
                              drop=operator.locked if self.blender else None)

    def solve_boundary(self, V: np.ndarray, boundary_sys: LinearSystem | None, *, copy: bool = True) -> np.ndarray:
        """Positions after the boundary block's solve (a copy of V elsewhere).

        With ``copy=False`` and no boundary block, V itself (not to be written).
        """
        if boundary_sys is None and not copy:
            return V
        X = V.copy()
        if boundary_sys is not None:
            solve_compact(V, V, X, boundary_sys, self.lam_border)
        return X

    def rescale_volume(self, V_before: np.ndarray, V_after: np.ndarray, axes: np.ndarray,
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
