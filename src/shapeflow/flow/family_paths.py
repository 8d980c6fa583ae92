"""The two ways a family is solved: one shared multi-shift solve, or a flow per member.

:func:`plan_shared_solve` decides whether the shared solve applies (and for
which members); :func:`shared_solve` runs it on the
:class:`~shapeflow.flow.system.SystemBuilder` of the family's
:class:`~shapeflow.flow.solver.FlowSolver`; :func:`separate_solves` runs
``FlowSolver.run`` for the members left over.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .. import accel
from ..errors import SolverWarning
from ..linalg.multishift import BLOCK_BYTES, TRUE_RESIDUAL_FACTOR, multishift_cg
from ..linalg.spd import estimate_cg_iterations
from .family_features import coupled_seed_system, multishift_bicg
from .report import FamilyReport, FlowReport
from .solver import FlowSolver

__all__ = ["SHARED_CG_MAX_RATIO", "SharedPlan", "plan_shared_solve", "boundary_solve", "shared_solve",
           "check_members", "separate_solves"]


#: members whose estimated CG iterations exceed this many times the iteration cap are
#: not even tried in the shared solve (the estimate is a bound: small meshes converge
#: much sooner, and members that do not converge are redone separately anyway)
SHARED_CG_MAX_RATIO = 3.0

#: degree of the shared CG's polynomial preconditioner (:func:`~shapeflow.linalg.multishift.multishift_cg`):
#: on the figure-1 family on Suzanne ×3, 69 iterations of 3 products instead of 209 of one, a third of the
#: stored residuals (docs/performance.md, "The family's shared solve")
SHARED_DEGREE = 2


@dataclass
class SharedPlan:
    interior_sys: object            # flow's interior system for the seed λ (None: no free interior vertex)
    lam_seed: float
    scale: np.ndarray       # C_1^{-1/2} on free vertices, 1 elsewhere
    sigmas: np.ndarray      # distinct σ = 1/|λ| of the members solved together, ascending
    member_shift: np.ndarray  # (k,) index into sigmas; -1: λ = 0 (nothing to solve) or solved separately
    hard: np.ndarray        # (k,) members left to separate solves (|λ| too large for the shared CG)
    maxiter: int
    note: str = ""
    curve_sys: object = None        # the feature curves' system for the seed λ (flow.features; None: none)


def plan_shared_solve(flow_solver: FlowSolver, operator, lams: np.ndarray, notes: list):
    """The shared interior system, or a string saying why there is none.

    Members whose |λ| would need far more CG iterations than flow()'s CG
    allows (condition number 1 + 2|λ| max(D w / m), the estimate flow()
    itself uses; :data:`SHARED_CG_MAX_RATIO`) are left to separate solves, where flow()
    picks a direct solver; the shared solve takes the others.
    """
    n = flow_solver.mesh.n_vertices
    maxiter = max(200, 10 * int(np.sqrt(n)) + 100)
    absl = np.abs(lams)
    with np.errstate(over="ignore", divide="ignore"):
        tiny = np.isinf(1.0 / absl) & (absl > 0)     # σ = 1/|λ| beyond double precision (|λ| < 5.6e-309)
    if tiny.any() and (tiny | (absl == 0)).all():
        return "every nonzero |λ| is below 1/1.8e308, where the shift σ = 1/|λ| overflows: flow() per λ"
    nz = (absl > 0) & ~tiny
    hard = np.zeros(lams.size, bool)
    interior_sys = None
    if nz.any():
        interior_sys = flow_solver.systems.interior(operator, float(absl.max()), 1, notes)
    if interior_sys is not None:
        free = interior_sys.free
        c1 = interior_sys.c[free] * float(absl.max())        # m_i / w_i
        if not (np.all(c1 > 0) and np.all(np.isfinite(c1)) and np.all(operator.deg[free] >= 0)):
            return "the interior system is indefinite (Blender's rows with negative cotangent degree; LU per λ)"
        rho = float(np.max(operator.deg[free] / c1))
        est = np.array([estimate_cg_iterations(1.0 + 2.0 * a * rho, flow_solver.rtol) for a in absl])
        hard = nz & (est > SHARED_CG_MAX_RATIO * maxiter)
        if hard.all() or (hard | ~nz).all():
            a = float(absl.max())
            its = estimate_cg_iterations(1.0 + 2.0 * a * rho, flow_solver.rtol)
            return (f"the largest |λ| = {a:g} needs about {its:.0f} "
                    f"CG iterations (cap {maxiter}) and so do all the others: a direct solver per λ is cheaper")
    easy = nz & ~hard
    uniq = np.unique(absl[easy])                     # ascending |λ|
    sigmas = 1.0 / uniq[::-1]                        # ascending σ: hardest first
    member_shift = np.full(lams.size, -1)
    if easy.any():
        member_shift[easy] = sigmas.size - 1 - np.searchsorted(uniq, absl[easy])
    lam_seed = float(uniq[-1]) if uniq.size else 0.0
    if interior_sys is not None and lam_seed != float(absl.max()):
        interior_sys = flow_solver.systems.interior(operator, lam_seed, 1, notes)
    scale = np.ones(n)
    note = ""
    if interior_sys is not None:
        scale[interior_sys.free] = 1.0 / np.sqrt(interior_sys.c[interior_sys.free] * lam_seed)
    curve_sys = flow_solver.systems.curve_system(operator, lam_seed) if lam_seed else None
    if curve_sys is not None:
        scale[curve_sys.idx] = 1.0 / np.sqrt(curve_sys.c * lam_seed)
    if hard.any():
        note = (f"{int(hard.sum())} member(s) with |λ| > {lam_seed:g} solved separately: the shared CG "
                f"would need far more than {maxiter} iterations for them")
    if tiny.any():
        hard = hard | tiny
        note = (note + "; " if note else "") + (f"{int(tiny.sum())} member(s) with |λ| below 1/1.8e308 (σ = 1/|λ| "
                                                "overflows) solved separately")
    return SharedPlan(interior_sys, lam_seed, scale, sigmas, member_shift, hard, maxiter, note, curve_sys)


def boundary_solve(flow_solver: FlowSolver, operator, V: np.ndarray):
    """Solve the boundary block (independent of λ): positions X and the system."""
    boundary_sys = flow_solver.systems.boundary(operator, flow_solver.lam_border)
    return flow_solver.systems.solve_boundary(V, boundary_sys), boundary_sys


def shared_solve(flow_solver: FlowSolver, operator, plan: SharedPlan, lams: np.ndarray, ax: np.ndarray,
                 preserve_volume: bool, report: FamilyReport, tick) -> np.ndarray:
    """Every member that shares the seed's Krylov space, from one multi-shift CG (see ``family``)."""
    mesh = flow_solver.mesh
    V = mesh.vertices
    n, k = V.shape[0], lams.size
    X, boundary_sys = boundary_solve(flow_solver, operator, V)
    interior_sys, curve_sys = plan.interior_sys, plan.curve_sys
    report.free_vertices = int((interior_sys.free.sum() if interior_sys is not None else 0)
                               + (boundary_sys.free.sum() if boundary_sys is not None else 0)
                               + (curve_sys.free.sum() if curve_sys is not None else 0))
    report.shifts = int(plan.sigmas.size)
    report.solver = ("multishift-bicg" if curve_sys is not None else
                     "multishift-cg" if interior_sys is not None else "none")
    # every member starts as V with the boundary moved (flow(): sign of λ_b, enabled axes only)
    base = V.copy()
    if boundary_sys is not None:
        sb = 1.0 if flow_solver.lam_border >= 0 else -1.0
        base[np.ix_(boundary_sys.idx, ax)] += sb * (X[boundary_sys.idx] - V[boundary_sys.idx])[:, ax]
    if not np.all(np.isfinite(X)):
        bad = ~np.isfinite(X).all(axis=1)
        X[bad] = V[bad]
        base[bad] = V[bad]
        report.notes.append(f"{int(bad.sum())} vertices with a non-finite solution kept in place")
    out = np.empty((k, n, 3))
    solved = plan.member_shift >= 0
    zero = (plan.member_shift < 0) & ~plan.hard     # λ = 0: V with the boundary moved
    tick(int(zero.sum()))
    if plan.hard.any():
        report.fallback_members = [int(m) for m in np.flatnonzero(plan.hard)]
        report.notes.append(plan.note)
    if (interior_sys is not None or curve_sys is not None) and solved.any():
        member_of_shift = [np.flatnonzero(plan.member_shift == i) for i in range(plan.sigmas.size)]
        counted = np.zeros(plan.sigmas.size, bool)

        def on_progress(conv):
            new = conv & ~counted
            counted[new] = True
            tick(int(sum(member_of_shift[i].size for i in np.flatnonzero(new))))

        finite = np.ones(plan.sigmas.size, bool)
        sink = MemberSink(out, base, lams, ax, member_of_shift, finite)
        res, system = run_shared(flow_solver, operator, plan, X, ax, sink, on_progress)
        out[~solved | ~sink.filled] = base          # (``out`` was the solve's scratch until the sink wrote)
        report.krylov_iterations = res.krylov_iterations
        report.krylov_degree = getattr(res, "degree", 0)
        ok = res.converged.all(axis=1) & finite
        its = np.where(res.converged, res.iterations, res.krylov_iterations).max(axis=1)
        report.member_iterations[solved] = its[plan.member_shift[solved]]
        bad = np.flatnonzero(solved & ~ok[np.maximum(plan.member_shift, 0)])
        if bad.size:
            report.fallback_members = sorted(set(report.fallback_members) | {int(m) for m in bad})
            report.notes.append(f"{bad.size} member(s) did not converge in {plan.maxiter} shared iterations "
                                "and were solved separately")
        checked = np.flatnonzero(solved & ok[np.maximum(plan.member_shift, 0)])
        wrong = check_members(out, base, lams, ax, plan, system, checked, flow_solver.rtol, sink.buffers)
        sink.buffers = []
        if wrong.size:
            report.fallback_members = sorted(set(report.fallback_members) | {int(m) for m in wrong})
            msg = (f"{wrong.size} member(s) of the shared solve missed rtol={flow_solver.rtol:g} in their true "
                   f"residual (λ = {', '.join(f'{lams[m]:g}' for m in wrong)}): solved separately, as flow()")
            report.notes.append(msg)
            warnings.warn(SolverWarning(msg), stacklevel=4)
    else:
        out[:] = base
        tick(int(solved.sum()))                             # no free interior vertex: boundary moves only
    if preserve_volume:
        has_interior, has_boundary = interior_sys is not None or curve_sys is not None, boundary_sys is not None
        rescale_members(flow_solver, out, lams, ax, report,
                        moved=lambda m: (lams[m] != 0.0 and has_interior) or has_boundary)
    return out


class MemberSink:
    """The ``emit`` of the shared solve: each member becomes ``base`` ± its displacement Δ = C_1^{-1/2} Y
    (``rows[t, q]`` column t of shift ``shifts[q]``, scaled already); ``finite[i]`` says whether shift
    i's were, ``filled[m]`` whether member m was written.  :meth:`factors` takes the solve's low-rank
    factors instead of the rows (the flow kernel family's ``add_members``: the members formed and
    written in one pass)."""

    def __init__(self, out: np.ndarray, base: np.ndarray, lams: np.ndarray, ax: np.ndarray,
                 member_of_shift: list, finite: np.ndarray):
        self.out, self.base, self.finite, self.member_of_shift = out, base, finite, member_of_shift
        self.cols = np.flatnonzero(ax)
        self.plus = lams >= 0
        self.filled = np.zeros(lams.size, bool)
        self.buffers = []

    def __call__(self, shifts, rows):
        out, cols, plus = self.out, self.cols, self.plus
        for q, i in enumerate(shifts):
            self.finite[i] = bool(np.isfinite(rows[:, q]).all())
            for m in self.member_of_shift[i]:
                if not self.filled[m]:
                    out[m] = self.base
                    self.filled[m] = True
                for t, j in enumerate(cols):
                    if plus[m]:
                        out[m, :, j] += rows[t, q]
                    else:
                        out[m, :, j] -= rows[t, q]

    def scratch(self, size: int):
        """``out`` as a flat buffer of ``size`` values (the solve's factor and its powers' scratch), None
        if it is smaller or a member is written already: free until :meth:`factors` or ``__call__``
        writes the members (``shared_solve`` writes every other member afterwards)."""
        flat = self.out.reshape(-1)
        return flat[:size] if size <= flat.size and not self.filled.any() else None

    def spare(self, buffers: list) -> None:
        """Keep the solve's buffers it no longer needs (their pages touched) for the true-residual check."""
        self.buffers = buffers

    def factors(self, lefts: list, Ws: list) -> None:
        """Every shift's solution from its low-rank factors: column t is ``lefts[t] @ Ws[t]ᵀ`` (Ws[t] a
        tuple of (n, ·) pieces side by side; see ``multishift_cg``'s ``emit``)."""
        k = len(self.member_of_shift)
        members = np.concatenate(self.member_of_shift).astype(np.int64)
        shift_of = np.repeat(np.arange(k), [ms.size for ms in self.member_of_shift])
        signs = np.where(self.plus[members], 1.0, -1.0)
        kern = accel.kernels("flow", self.out.shape[1])
        self.finite[:] = kern.add_members(self.out, self.base, self.cols, members, shift_of, signs, lefts, Ws, k)
        self.filled[members] = True


def run_shared(flow_solver: FlowSolver, operator, plan: SharedPlan, X: np.ndarray, ax: np.ndarray, add, progress):
    """The multi-shift solve of the plan's shifts, its members handed to ``add`` (:class:`MemberSink`):
    BiCG with feature curves (:mod:`~shapeflow.flow.family_features`), else CG on the system in the
    operator's locality order.  Returns the result and the scaled system solved in the mesh's order,
    ``(A, R0)``."""
    interior_sys, curve_sys, S, V = plan.interior_sys, plan.curve_sys, plan.scale, flow_solver.mesh.vertices
    deltas = plan.sigmas - plan.sigmas[0]
    if curve_sys is not None:     # curves and surface: one non-symmetric shifted system
        R0, As, AsT, _ = coupled_seed_system(interior_sys, curve_sys, S, V, X, ax)
        res = multishift_bicg(As, AsT, R0, deltas, rtol=flow_solver.rtol, maxiter=plan.maxiter, progress=progress)
        add(np.arange(plan.sigmas.size), res.X * S)
        return res, (As, R0)
    R0, As, _ = seed_system(interior_sys, S, V, X, ax)
    Ap, R0p, Sp, inv = in_locality_order(operator, As, R0, S)
    res = multishift_cg(Ap, R0p, deltas, rtol=flow_solver.rtol, maxiter=plan.maxiter,
                        block_bytes=block_bytes(plan.sigmas.size, S.size), progress=progress, emit=add,
                        post=(Sp, inv), degree=SHARED_DEGREE)      # 0 off the free rows; back from the locality order
    return res, (As, R0)


def check_members(out: np.ndarray, base: np.ndarray, lams: np.ndarray, ax: np.ndarray, plan: SharedPlan,
                  system, members: np.ndarray, rtol: float, spare: list = ()) -> np.ndarray:
    """The listed members whose true residual misses the tolerance.

    For each, the scaled system ``(σ I + M) Y = b`` of the shared solve (``system`` = ``(As, R0)``
    from :func:`run_shared`: As = σ_seed I + M and R0 = b in the mesh's order, columns of the enabled
    axes) is evaluated at ``Y = C_1^{1/2} Δ`` with Δ = ±(member − base) read back from ``out``
    (the flow kernel family's ``member_residuals``).
    ``spare``: flat float64 buffers free for the kernel's scratch.
    A column passes when its residual is at most
    :data:`~shapeflow.linalg.multishift.TRUE_RESIDUAL_FACTOR` × (``rtol ‖b‖`` + what rounding the
    positions alone leaves, ε (‖|As|‖∞ + δ)(‖base/S‖ + ‖Y‖)); a non-finite one fails, and so does one
    whose allowance is not finite (‖Y‖ beyond ~1e154, where its squares overflow and the allowance
    would pass any residual: such a member is solved again as ``flow()`` does).
    """
    cols = np.flatnonzero(ax)
    if members.size == 0 or cols.size == 0:
        return members[:0]
    As, R0 = system
    inv_scale = 1.0 / plan.scale
    deltas = (plan.sigmas - plan.sigmas[0])[plan.member_shift[members]]
    signs = np.where(lams[members] >= 0, 1.0, -1.0)
    kern = accel.kernels("flow", base.shape[0])
    n = base.shape[0]
    norm_a = kern.scaled_abs_row_max(As, np.ones(n), np.ones(n, bool))       # ‖|As|‖∞
    eps = np.finfo(np.float64).eps
    tol = TRUE_RESIDUAL_FACTOR * rtol * np.sqrt(np.einsum("ji,ji->j", R0, R0))          # (c,)
    scaled_base = base[:, cols] * inv_scale[:, None]
    base_size = np.sqrt(np.einsum("ij,ij->j", scaled_base, scaled_base))
    res, ynorm = kern.member_residuals(As, R0, out, base, inv_scale, cols, members, signs, deltas, spare)
    floor = TRUE_RESIDUAL_FACTOR * eps * (norm_a + deltas)[:, None] * (base_size + ynorm)
    return members[~((res <= tol + floor) & np.isfinite(floor)).all(axis=1)]


def block_bytes(k: int, n: int) -> int:
    """Memory for the stored seed residuals of a family of ``k`` shifts: four member-sized blocks
    (:func:`~shapeflow.flow.family.family_bytes`), at least :data:`~shapeflow.linalg.multishift.BLOCK_BYTES`."""
    return max(BLOCK_BYTES, 4 * min(k, 64) * 24 * n)


def in_locality_order(operator, As, R0: np.ndarray, S: np.ndarray):
    """The shared system in the operator pattern's bandwidth-reducing order where the compiled kernels
    have one (its products gather from nearby rows: ~17 % faster at 126K vertices): (As, R0, S, inv)
    permuted, with ``inv`` taking rows back; unchanged with ``inv = None`` elsewhere."""
    pattern = operator.pattern
    if not (sp.isspmatrix_csr(As) and getattr(pattern, "csr_built", False) and As.nnz == pattern.indices.size):
        return As, R0, S, None
    loc = pattern.locality()
    if loc is None:
        return As, R0, S, None
    perm, inv, ptr, idx, src = loc
    Ap = sp.csr_matrix((As.data[src], idx, ptr), shape=As.shape, copy=False)
    return Ap, np.ascontiguousarray(R0[:, perm]), S[perm], inv


def seed_system(interior_sys, S: np.ndarray, V: np.ndarray, X: np.ndarray, ax: np.ndarray):
    """The shared solve's right-hand sides and matrix: the seed's initial residuals r0 = b − A X
    (λ-independent: g − K V on free rows, 0 elsewhere) and S A S = σ_seed I + M (I off the free
    rows), both scaled by ``S`` = C_1^{-1/2}; and the columns (axes) solved."""
    n = V.shape[0]
    r_, s_, e_ = interior_sys.coupling
    free = interior_sys.free
    rhs = np.where(free[:, None], interior_sys.c[:, None] * V, X)
    if r_.size:
        for j in range(3):
            rhs[:, j] += np.bincount(r_, e_ * X[s_, j], minlength=n)
    A = interior_sys.A
    cols = np.flatnonzero(ax)
    R0 = np.empty((cols.size, n))
    for t, j in enumerate(cols):
        R0[t] = (rhs[:, j] - A @ X[:, j]) * S
    As = A.copy()
    As.data *= np.repeat(S, np.diff(As.indptr)) * S[As.indices]
    return R0, As, cols


def rescale_members(flow_solver: FlowSolver, out: np.ndarray, lams: np.ndarray, ax: np.ndarray,
                    report: FamilyReport, moved) -> None:
    """Volume preservation of each member solved in the shared solve, as ``FlowSolver.run`` does it."""
    V = flow_solver.mesh.vertices
    center0 = V.mean(axis=0)
    skip = set(report.fallback_members)
    for m in range(lams.size):
        if m in skip or not moved(m):
            continue   # flow() returns the input unchanged there ("no free vertex"): no rescale
        r = FlowReport(lam=float(lams[m]), lam_border=flow_solver.lam_border, iterations=1, mode=report.mode,
                       scheme=report.scheme, update=report.update)
        out[m] = flow_solver.systems.rescale_volume(V, out[m], ax, center0, r)
        report.notes.extend(r.notes)


def separate_solves(flow_solver: FlowSolver, lams: np.ndarray, members, out: np.ndarray, report: FamilyReport, *,
              iterations: int, preserve_volume: bool, axes: np.ndarray, update: str, tick) -> None:
    """flow() for each listed member on the shared FlowSolver (operator built once)."""
    members = list(members)
    solvers_used = []
    reports = report.member_reports or [None] * lams.size
    cache: dict = {}
    for m in members:
        lam = float(lams[m])
        if lam not in cache:
            res = flow_solver.run(lam, iterations=iterations, preserve_volume=preserve_volume, axes=axes, update=update)
            cache[lam] = res
        res = cache[lam]
        out[m] = res.vertices
        r = res.report
        reports[m] = r
        report.member_iterations[m] = max(r.cg_iterations) if r.cg_iterations else (-1 if r.solver != "none" else 0)
        if r.solver != "none":
            solvers_used.append(r.solver)
        report.notes.extend(r.notes)
        tick()
    report.member_reports = reports
    used = "/".join(dict.fromkeys(solvers_used))
    if report.path == "separate":
        report.solver = used or "none"
        report.free_vertices = max((r.free_vertices for r in reports if r is not None), default=0)
    elif used:
        report.solver = f"{report.solver} + {used}"
