"""Families of shapes from one solve: the flow for many λ at once (figure 1).

``family(mesh, lams, **flow_options)`` returns the same shapes as calling
``flow(mesh, lam, **flow_options)`` for every λ, as one array ``(k, n, 3)``,
but shares the work between the members.

Why one solve is enough (one iteration)
---------------------------------------
For one step of eq. 11 (docs/method.md, "The step"; :mod:`shapeflow.flow`)
the free interior vertices solve

    (C_λ + K) X = C_λ V + g,      C_λ = diag(m_i / (|λ| w_i)) = C_1 / |λ|,

with ``K = D − W`` restricted to the free vertices (positive semi-definite)
and ``g`` the couplings to the fixed vertices and to the boundary vertices,
which are solved first with their own factor λ_b — independently of λ.
Written for the displacement ``Δ = X − V`` the right-hand side no longer
depends on λ either,

    (C_λ + K) Δ = g − K V =: r0        (the initial residual of flow()'s
                                          CG, which starts from V),

and the symmetric scaling ``Y = C_1^{1/2} Δ`` turns every member into a
*shifted* system of one matrix,

    (σ I + M) Y = C_1^{-1/2} r0,      σ = 1/|λ|,   M = C_1^{-1/2} K C_1^{-1/2}.

(Only a scaling by C_1 makes the λ-dependent part a multiple of the identity:
with D-based scaling, ``diag(1/(|λ| w_i)) + D^{-1/2} K D^{-1/2}``, the shift is
not uniform as soon as the weights vary.)  Krylov spaces are invariant under
shifts, so multi-shift CG (CG-M: Jegerlehner 1996, hep-lat/9612014; Frommer
2003) solves every σ with the matrix-vector products of the hardest member
alone (smallest σ = largest |λ|, the "seed").  Each member is then
``V + sign(λ) Δ`` — so +λ and −λ share one shift, and λ = 0 is the identity
(its boundary still moves when λ_b ≠ 0, exactly as in flow()).

Each member stops on its own residual, ``‖r_σ‖ ≤ rtol · ‖r0‖`` in the scaled
norm (``r_σ = ζ_σ r_seed`` is known for free), and converged members stop
being updated.  Without weights the scaled norm *is* the Jacobi-preconditioned
norm flow()'s CG stops on, so the seed member reproduces flow()'s CG
iterations exactly (in exact arithmetic); with weights both are valid
preconditioners and the results agree to the CG tolerance.

Cost: the shifted solutions are linear combinations of the seed residuals.
Rather than two axpy passes per member per iteration (48 members × 3 columns
× n — more than the matrix-vector product), the residuals are kept in a block
(:data:`BLOCK_BYTES`) and the members' iterates are formed with one GEMM per
block — usually one in all (:func:`multishift_cg`); the per-member
recurrences only touch coefficients.  Measured on the 46,850-vertex figure-1
family (``benchmarks/bench_family.py``, 2-core machine under load ~2): the
48 members in 0.65–0.9 s, about 1.2× the hardest member's flow() alone,
against ~21 s for 48 flow() calls and ~200 s for 48 Blender evaluations.

Paths
-----
``"multishift"``
    One iteration (``update`` is irrelevant then: flow() rebuilds the
    operator only from the second iteration on), paper or Blender mode as
    long as the interior system is positive definite, ``solver`` "auto" or
    "cg".  ``preserve_volume`` is a per-member rescale after the step (exactly
    flow()'s), so it keeps this path.
``"separate"``
    Per-λ solves with one :class:`~shapeflow.flow.FlowSolver` (the cotangent
    structure and the operator at the input positions are built once; each
    run builds its own λ-dependent matrices): several iterations (the
    right-hand sides of the second step differ per member), Blender mode with
    indefinite rows (LU), an explicit ``solver="cholesky"`` or ``"lu"``, or
    ``strategy="separate"``; also when every nonzero |λ| is far beyond the CG
    budget (:data:`HOPELESS`; e.g. the area-normalised eq. 9 on a model of
    size ~1), where flow() itself factorises.  Within the multishift path,
    members beyond that budget, or that the shared CG did not converge within
    its iteration cap, are redone this way (``report.fallback_members``).
``"unchanged"``
    Nothing to do (``iterations=0``, no axes, all weights 0, no faces, or
    every λ and λ_b zero): every member is the input.

The report (``family(..., return_report=True)`` or ``.report`` on every mesh
of :func:`family_meshes`) is a :class:`FamilyReport` saying which path ran and
why.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

from . import kernels, params
from .errors import ParameterError
from .flow import FlowReport, FlowSolver, check_run_options
from .geometry import refresh_normals
from .mesh import Mesh
from .solvers import DEFAULT_RTOL, estimate_cg_iterations

__all__ = ["family", "family_meshes", "FamilyReport", "multishift_cg", "MultiShiftResult", "STRATEGIES"]

#: ``strategy=`` values: choose, insist on the shared solve, or force per-λ solves
STRATEGIES = ("auto", "multishift", "separate")

#: memory for the block of stored seed residuals (the rest is O(k·n))
BLOCK_BYTES = 128 * 2 ** 20

#: members whose estimated CG iterations exceed this many times the iteration cap are
#: not even tried in the shared solve (the estimate is a bound: small meshes converge
#: much sooner, and members that do not converge are redone separately anyway)
HOPELESS = 3.0


# --------------------------------------------------------------------------
# multi-shift CG
# --------------------------------------------------------------------------

@dataclass
class MultiShiftResult:
    """Solutions of :func:`multishift_cg`.

    ``X[j, i]`` is column ``j`` of the solution for shift ``i`` (component-major,
    shifts in the order given); ``iterations[i, j]`` the iteration after which it
    met the tolerance (``-1``: never), ``converged[i, j]`` whether it did.
    ``flushes`` counts the GEMMs folding a block of residuals into the iterates.
    """

    X: np.ndarray
    iterations: np.ndarray
    converged: np.ndarray
    krylov_iterations: int
    flushes: int


def multishift_cg(A, B: np.ndarray, shifts, *, rtol: float = DEFAULT_RTOL, maxiter: int | None = None,
                  block_bytes: int = BLOCK_BYTES,
                  progress: Callable[[np.ndarray], None] | None = None) -> MultiShiftResult:
    """Solve ``(A + s_i I) X_i = B`` for every shift ``s_i`` with one Krylov space.

    Parameters
    ----------
    A : sparse matrix (n, n) or anything with ``A @ vector``, symmetric, such
        that ``A + min(shifts) I`` is positive definite.
    B : (c, n) right-hand-side columns, component-major (one row per column).
    shifts : (k,) real.
    rtol : every (shift, column) stops when its residual ``‖b − (A + s)x‖``
        (the recursively updated one, ``|ζ_s| ‖r‖``, as CG's) fell below
        ``rtol × ‖b‖`` (the initial residual; the start is x = 0), and is no
        longer updated after that.
    maxiter : cap on the shared iterations (default ``max(200, 10·√n + 100)``,
        as :class:`~shapeflow.solvers.SPDSolver`).
    block_bytes : memory for the stored seed residuals; the shifted iterates
        are built from them with one GEMM per block.
    progress : called with the (k,) bool array "shift converged in every
        column" whenever it changes.

    Notes
    -----
    CG-M (Jegerlehner 1996; Frommer 2003): CG runs on the smallest shift (the
    seed); the residual of shift ``s`` is ``ζ_s r`` with ζ from a three-term
    scalar recurrence, its search direction is ``p_s ← ζ_s r + β_s p_s`` and
    its iterate ``x_s ← x_s + α_s p_s``.  Here ``p_s`` and ``x_s`` are carried
    as coefficients over the stored residuals of the current block (plus the
    block-start direction ``P_s`` after the first block), so an iteration
    costs the seed's matrix-vector product and vector updates plus
    O(k × block) scalars; the k shifted vectors are formed by a GEMM when the
    block is full or the run ends (one GEMM in all when the residuals fit in
    ``block_bytes``).  Columns are independent CG runs (their own α, β), as
    in the repository's CG.
    """
    B = np.ascontiguousarray(np.atleast_2d(np.asarray(B, dtype=np.float64)))
    c, n = B.shape
    shifts = np.asarray(shifts, dtype=np.float64).ravel()
    k = shifts.size
    if k == 0:
        return MultiShiftResult(np.zeros((c, 0, n)), np.zeros((0, c), np.int64), np.zeros((0, c), bool), 0, 0)
    if not np.all(np.isfinite(shifts)):
        raise ParameterError("shifts must be finite")
    order = np.argsort(shifts, kind="stable")           # hardest (smallest shift) first
    inv = np.argsort(order)
    s_sorted = shifts[order]
    seed = float(s_sorted[0])
    delta = (s_sorted - seed)[:, None]                  # (k, 1) >= 0
    if maxiter is None:
        maxiter = max(200, 10 * int(np.sqrt(n)) + 100)
    cap = int(max(8, min(maxiter + 1, block_bytes // max(1, 8 * c * n))))

    rho = np.einsum("ij,ij->i", B, B)                   # (c,)
    tol2 = rtol * rtol * rho
    active = np.broadcast_to(rho > tol2, (k, c)).copy()  # (shift, column) still iterating
    iterations = np.where(active, -1, 0)
    if not active.any():
        return MultiShiftResult(np.zeros((c, k, n)), iterations[inv], ~active[inv], 0, 0)
    X = np.empty((c, k, n))                             # written by the first flush
    Rb = np.empty((c, cap, n))                          # the block's seed residuals; r is always Rb[:, used-1]
    Rb[:, 0] = B
    used = 1
    r_spare = np.empty_like(B)                          # the new residual when the block is full
    p = B.copy()
    Ap = np.zeros_like(B)                               # stays 0 in columns that never run
    P = None                                            # block-start directions P_s (c, kp, n), after a first block
    Cf = np.zeros((c, k, cap))                          # p_s = a_s P_s + Σ_t Cf[t] Rb[t]
    Xf = np.zeros((c, k, cap))                          # x_s = X_s + xa_s P_s + Σ_t Xf[t] Rb[t]
    a = np.zeros((c, k))
    xa = np.zeros((c, k))
    Cf[:, :, 0] = 1.0                                   # p_s(0) = r(0) for every shift
    zeta = np.ones((k, c))
    zeta_prev = np.ones((k, c))
    alpha_prev = np.ones(c)
    beta_prev = np.zeros(c)
    flushes = 0
    done_prev = ~active.any(axis=1)
    if progress is not None and done_prev.any():
        progress(done_prev[inv])

    def flush(kx: int, ka: int) -> None:
        """Fold the block into X (shifts [:kx], all that were active in it) and P ([:ka], still active)."""
        nonlocal P, flushes
        flushes += 1
        Rv = Rb[:, :used]
        for j in range(c):
            if flushes == 1:                             # X is still empty: write, don't accumulate
                np.matmul(Xf[j, :kx, :used], Rv[j], out=X[j, :kx])
                X[j, kx:] = 0.0
                continue
            if P is not None:
                for s_ in np.flatnonzero(xa[j, :kx]):
                    X[j, s_] += xa[j, s_] * P[j, s_]
            X[j, :kx] += Xf[j, :kx, :used] @ Rv[j]
        if ka:
            if P is None:
                P = np.empty((c, ka, n))
                for j in range(c):
                    np.matmul(Cf[j, :ka, :used], Rv[j], out=P[j])
            else:
                for j in range(c):
                    P[j, :ka] *= a[j, :ka, None]
                    P[j, :ka] += Cf[j, :ka, :used] @ Rv[j]

    it = 0
    k_blk = k                                           # shifts active at the start of the block
    with np.errstate(divide="ignore", invalid="ignore", over="ignore", under="ignore"):
        while it < maxiter:
            cols = active.any(axis=0)                    # columns still running
            ka = int(np.flatnonzero(active.any(axis=1)).max()) + 1   # active shifts: (about) a prefix
            it += 1
            r = Rb[:, used - 1]
            for j in np.flatnonzero(cols):               # (per column: faster than SciPy's multi-vector product)
                Ap[j] = A @ p[j]
            if seed != 0.0:
                Ap += seed * p
            pAp = np.einsum("ij,ij->i", p, Ap)
            ok = cols & (pAp > 0)
            alpha = np.where(ok, rho / np.where(ok, pAp, 1.0), 0.0)
            r_new = Rb[:, used] if used < cap else r_spare
            np.multiply(Ap, alpha[:, None], out=r_new)
            np.subtract(r, r_new, out=r_new)
            rho_new = np.einsum("ij,ij->i", r_new, r_new)
            beta = np.where(ok & (rho > 0), rho_new / np.where(rho > 0, rho, 1.0), 0.0)
            # shifted recurrences (k, c): ζ_{i+1}, α_s, β_s
            den = alpha_prev * zeta_prev * (1.0 + alpha * delta) + alpha * beta_prev * (zeta_prev - zeta)
            zeta_new = zeta * zeta_prev * alpha_prev / den
            ratio = zeta_new / zeta
            upd = active & ok & np.isfinite(ratio)
            alpha_s = np.where(upd, alpha * ratio, 0.0)
            beta_s = np.where(upd, beta * ratio * ratio, 0.0)
            # x_s += α_s p_s ;  p_s ← β_s p_s (+ ζ_s r_new below): coefficients only
            aT = alpha_s[:ka].T                          # (c, ka)
            Xf[:, :ka, :used] += aT[:, :, None] * Cf[:, :ka, :used]
            xa[:, :ka] += aT * a[:, :ka]
            bT = beta_s[:ka].T
            Cf[:, :ka, :used] *= bT[:, :, None]
            a[:, :ka] *= bT
            # convergence of each (shift, column) after this iteration
            zeta_prev = np.where(upd, zeta, zeta_prev)
            zeta = np.where(upd, zeta_new, zeta)
            newly = upd & (zeta * zeta * rho_new <= tol2)
            iterations[newly] = it
            active &= ~newly
            active &= ok | ~cols                         # a column whose seed broke down is finished
            if progress is not None:
                done = ~active.any(axis=1)
                if (done != done_prev).any():
                    progress(done[inv])
                    done_prev = done
            if not active.any():
                break
            ka = int(np.flatnonzero(active.any(axis=1)).max()) + 1
            if used == cap:                              # block full: fold it into X and P, start a new one
                flush(k_blk, ka)
                k_blk = ka
                Cf[:] = 0.0
                Xf[:] = 0.0
                a[:] = 1.0
                xa[:] = 0.0
                used = 0
                Rb[:, 0] = r_spare
            Cf[:, :ka, used] = zeta[:ka].T
            used += 1
            p *= beta[:, None]
            p += Rb[:, used - 1]
            rho = np.where(ok, rho_new, rho)
            alpha_prev = np.where(ok, alpha, alpha_prev)
            beta_prev = np.where(ok, beta, beta_prev)
    flush(k_blk, 0)
    return MultiShiftResult(X[:, inv], iterations[inv], ~active[inv], it, flushes)


# --------------------------------------------------------------------------
# report
# --------------------------------------------------------------------------

@dataclass
class FamilyReport:
    """What :func:`family` did.

    ``path`` is ``"multishift"``, ``"separate"`` or ``"unchanged"`` and
    ``reason`` says why.  ``member_iterations[m]`` is the CG iteration after
    which member ``m`` met the tolerance (multishift: of the shared solve, max
    over the coordinates; separate: flow()'s CG iterations, -1 for a direct
    solver; 0 for members with nothing to solve).  ``krylov_iterations`` is
    the number of shared iterations (matrix-vector products per coordinate).
    ``member_reports`` holds flow()'s own :class:`~shapeflow.flow.FlowReport`
    of every separately solved member (``None`` elsewhere).
    """

    lams: np.ndarray
    path: str
    reason: str
    lam_border: float
    iterations: int
    mode: str
    scheme: str
    update: str
    solver: str = "none"
    krylov_iterations: int = 0
    member_iterations: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    shifts: int = 0
    fallback_members: list = field(default_factory=list)
    member_reports: list = field(default_factory=list)
    locked: int = 0
    degenerate_triangles: int = 0
    boundary_vertices: int = 0
    free_vertices: int = 0
    notes: list = field(default_factory=list)
    seconds: float = 0.0

    def summary(self) -> str:
        """One line: path, members, time, iterations."""
        k = len(self.lams)
        if self.path == "multishift":
            how = (f"one multi-shift CG solve for {self.shifts} distinct |λ| "
                   f"({self.krylov_iterations} shared iterations)")
        elif self.path == "separate":
            how = f"{k} separate solves on one shared operator ({self.solver})"
        else:
            how = "input returned unchanged"
        fb = f", {len(self.fallback_members)} member(s) redone separately" if self.fallback_members else ""
        notes = f"; {'; '.join(self.notes)}" if self.notes else ""
        return f"{k} members: {how}{fb} ({self.reason}); {self.seconds:.3f} s{notes}"


# --------------------------------------------------------------------------
# the family
# --------------------------------------------------------------------------

def _check_lams(lams) -> np.ndarray:
    if isinstance(lams, (str, bytes)) or np.ndim(lams) != 1:
        raise ParameterError(f"lams must be a 1-D sequence of numbers (one λ per member), got {lams!r}")
    vals = [params.lam(f"lams[{i}]", x) for i, x in enumerate(lams)]
    if not vals:
        raise ParameterError("lams is empty: give at least one λ")
    return np.array(vals, dtype=np.float64)


@kernels.with_small_pages
def family(mesh: Mesh, lams: Sequence[float], *, lam_border: float = 0.0, iterations: int = 1,
           normalized: bool = True, weights=None, invert_weights: bool = False,
           preserve_volume: bool = False, axes: Sequence[bool] | str = (True, True, True),
           scheme: str | None = None, update: str = "fixed", compat: str | None = None,
           solver: str = "auto", rtol: float = DEFAULT_RTOL, strategy: str = "auto",
           progress: Callable[[int, int], None] | None = None, return_report: bool = False):
    """The flow for every λ of ``lams`` at once: an array ``(k, n, 3)``.

    ``result[m]`` equals ``flow(mesh, lams[m], **options).vertices`` (to the
    CG tolerance), but one iteration of all members costs about as much as the
    hardest member alone (multi-shift CG; see the module docstring).

    Parameters
    ----------
    mesh : Mesh
    lams : sequence of float
        One λ per member, any signs, zeros and repeats allowed (+λ and −λ
        share one solve).  Figure 1 of the paper: ``np.arange(0, -240, -5)``.
    lam_border, iterations, normalized, weights, invert_weights, preserve_volume,
    axes, scheme, update, compat, solver, rtol
        As in :func:`shapeflow.flow` (validated the same way).  ``rtol`` is the
        tolerance of the shared solve too: each member stops when its own
        residual fell by ``rtol``.
    strategy : {"auto", "multishift", "separate"}
        ``"auto"`` takes the shared solve wherever the shift structure holds,
        ``"multishift"`` insists (ParameterError where it does not hold),
        ``"separate"`` solves every λ on its own (one shared FlowSolver).
    progress : callable(done, total), optional
        Called as members are finished (total = number of members).
    return_report : bool
        Also return a :class:`FamilyReport` (which path ran and why).

    Returns
    -------
    ndarray (k, n, 3), or ``(positions, FamilyReport)`` with ``return_report``.

    Examples
    --------
    >>> import numpy as np, shapeflow as sf
    >>> mesh = sf.load_example("spot")
    >>> shapes, report = sf.family(mesh, np.arange(0.0, -240.0, -5.0), return_report=True)
    >>> shapes.shape[0], report.path
    (48, 'multishift')
    """
    t0 = time.perf_counter()
    if not isinstance(strategy, str) or strategy not in STRATEGIES:
        raise ParameterError(f"strategy must be one of {', '.join(STRATEGIES)}, got {strategy!r}")
    lam_arr = _check_lams(lams)
    preserve_volume = params.flag("preserve_volume", preserve_volume)
    return_report = params.flag("return_report", return_report)
    params.progress(progress)
    fs = FlowSolver(mesh, lam_border=lam_border, normalized=normalized, weights=weights,
                    invert_weights=invert_weights, scheme=scheme, compat=compat, solver=solver, rtol=rtol)
    if fs._pow2:   # extreme coordinates: the family of the exact power-of-two copy, scaled back
        e = fs._pow2
        lams_in = lam_arr if normalized else np.ldexp(lam_arr, -2 * e)
        res = family(fs.mesh, lams_in, lam_border=lam_border, iterations=iterations, normalized=normalized,
                     weights=fs.w, preserve_volume=preserve_volume, axes=axes, scheme=scheme, update=update,
                     compat=compat, solver=solver, rtol=rtol, strategy=strategy, progress=progress,
                     return_report=True)
        shapes, rep = res
        rep.lams = lam_arr
        with np.errstate(over="ignore"):
            shapes = np.ldexp(shapes, e)
        if not np.isfinite(shapes).all():
            raise ParameterError("lams: the result leaves the range of double precision (|x| > 1.8e308)")
        rep.notes.append(f"computed on the coordinates scaled by 2^{-e} (exact), then scaled back")
        return (shapes, rep) if return_report else shapes
    ax = check_run_options(iterations, update, axes, fs.blender)
    k, n = lam_arr.size, mesh.n_vertices
    from .budget import check_memory

    # the (k, n, 3) result, plus the shared solve's work (~4 such blocks of one batch of members)
    check_memory(f"a family of {k:,} members of {n:,} vertices", 24.0 * n * (k + 4 * min(k, 64)),
                 parameter="lams")
    report = FamilyReport(lams=lam_arr, path="unchanged", reason="", lam_border=fs.lam_border,
                          iterations=int(iterations), mode="blender" if fs.blender else "paper",
                          scheme=fs.scheme, update=update, member_iterations=np.zeros(k, np.int64))
    V0 = mesh.vertices
    done = [0]

    def tick(m: int = 1) -> None:
        done[0] = min(k, done[0] + m)
        if progress is not None:
            progress(done[0], k)

    def finish(out):
        report.notes = list(dict.fromkeys(report.notes))
        report.seconds = time.perf_counter() - t0
        return (out, report) if return_report else out

    # --- nothing to do: the conditions of FlowSolver.run(), for every member
    nothing = None
    if iterations == 0:
        nothing = "iterations=0"
    elif not ax.any():
        nothing = "no axis may change"
    elif not (fs.w > 0).any():
        nothing = "every weight is 0"
    elif mesh.n_faces == 0:
        nothing = "the mesh has no faces"
    elif not lam_arr.any() and fs.lam_border == 0.0:
        nothing = "every λ and λ_b are 0"
    if nothing is not None:
        report.reason = nothing
        out = np.broadcast_to(V0, (k, n, 3)).copy()
        tick(k)
        return finish(out)

    op = fs.operator()
    report.locked = int(op.locked.sum())
    report.degenerate_triangles = op.n_bad
    report.boundary_vertices = int(op.boundary.sum())

    # --- which path
    why_not = None
    if iterations > 1:
        why_not = (f"{iterations} iterations: from the second step on the right-hand sides differ "
                   "per member, so the systems are no longer shifts of one")
    elif fs.solver_method in ("cholesky", "lu"):
        why_not = f"solver={fs.solver_method!r} was asked for"
    plan = None
    if strategy == "separate":
        why_not = "strategy='separate' was asked for"
    elif why_not is None:
        plan = _plan_multishift(fs, op, lam_arr, report.notes)
        if isinstance(plan, str):
            why_not, plan = plan, None
    if strategy == "multishift" and why_not is not None:
        raise ParameterError(f"the multi-shift solve does not apply here: {why_not}")

    if why_not is not None:
        report.path, report.reason = "separate", why_not
        out = np.empty((k, n, 3))
        _separate(fs, lam_arr, range(k), out, report, iterations=iterations, preserve_volume=preserve_volume,
                  axes=ax, update=update, tick=tick)
        return finish(out)

    report.path = "multishift"
    report.reason = ("one iteration: every member solves (σI + M) Y = b with σ = 1/|λ| "
                     "for one matrix M and one right-hand side b")
    out = _multishift(fs, op, plan, lam_arr, ax, preserve_volume, report, tick)
    if report.fallback_members:
        _separate(fs, lam_arr, report.fallback_members, out, report, iterations=iterations,
                  preserve_volume=preserve_volume, axes=ax, update=update, tick=tick)
    return finish(out)


def family_meshes(mesh: Mesh, lams: Sequence[float], **options) -> list[Mesh]:
    """:func:`family` as a list of meshes (same faces and attributes as ``mesh``).

    Every mesh carries ``.lam`` (its λ) and ``.report``, the shared
    :class:`FamilyReport` of the whole family.  Options as :func:`family`
    (``return_report`` is not accepted: the report is on the meshes).
    """
    if "return_report" in options:
        raise ParameterError("family_meshes() puts the report on every mesh (.report); drop return_report")
    shapes, report = family(mesh, lams, return_report=True, **options)
    out = []
    for lam, V in zip(report.lams, shapes):
        m = refresh_normals(mesh.with_vertices(V))
        m.lam = float(lam)
        m.report = report
        out.append(m)
    return out


# --------------------------------------------------------------------------
# paths
# --------------------------------------------------------------------------

@dataclass
class _Plan:
    isys: object            # flow's interior system for the seed λ (None: no free interior vertex)
    lam_seed: float
    scale: np.ndarray       # C_1^{-1/2} on free vertices, 1 elsewhere
    sigmas: np.ndarray      # distinct σ = 1/|λ| of the members solved together, ascending
    member_shift: np.ndarray  # (k,) index into sigmas; -1: λ = 0 (nothing to solve) or solved separately
    hard: np.ndarray        # (k,) members left to separate solves (|λ| too large for the shared CG)
    maxiter: int
    note: str = ""


def _plan_multishift(fs: FlowSolver, op, lams: np.ndarray, notes: list):
    """The shared interior system, or a string saying why there is none.

    Members whose |λ| would need far more CG iterations than flow()'s CG
    allows (condition number 1 + 2|λ| max(D w / m), the estimate flow()
    itself uses; :data:`HOPELESS`) are left to separate solves, where flow()
    picks a direct solver; the shared solve takes the others.
    """
    n = fs.mesh.n_vertices
    maxiter = max(200, 10 * int(np.sqrt(n)) + 100)
    absl = np.abs(lams)
    nz = absl > 0
    hard = np.zeros(lams.size, bool)
    isys = None
    if nz.any():
        isys = fs._interior_system(op, float(absl.max()), 1, notes)
    if isys is not None:
        free = isys.free
        c1 = isys.c[free] * float(absl.max())        # m_i / w_i
        if not (np.all(c1 > 0) and np.all(np.isfinite(c1)) and np.all(op.deg[free] >= 0)):
            return "the interior system is indefinite (Blender's rows with negative cotangent degree; LU per λ)"
        rho = float(np.max(op.deg[free] / c1))
        est = np.array([estimate_cg_iterations(1.0 + 2.0 * a * rho, fs.rtol) for a in absl])
        hard = nz & (est > HOPELESS * maxiter)
        if hard.all() or (hard | ~nz).all():
            a = float(absl.max())
            return (f"the largest |λ| = {a:g} needs about {estimate_cg_iterations(1.0 + 2.0 * a * rho, fs.rtol):.0f} "
                    f"CG iterations (cap {maxiter}) and so do all the others: a direct solver per λ is cheaper")
    easy = nz & ~hard
    uniq = np.unique(absl[easy])                     # ascending |λ|
    sigmas = 1.0 / uniq[::-1]                        # ascending σ: hardest first
    member_shift = np.full(lams.size, -1)
    if easy.any():
        member_shift[easy] = sigmas.size - 1 - np.searchsorted(uniq, absl[easy])
    lam_seed = float(uniq[-1]) if uniq.size else 0.0
    if isys is not None and lam_seed != float(absl.max()):
        isys = fs._interior_system(op, lam_seed, 1, notes)
    scale = np.ones(n)
    note = ""
    if isys is not None:
        scale[isys.free] = 1.0 / np.sqrt(isys.c[isys.free] * lam_seed)
    if hard.any():
        note = (f"{int(hard.sum())} member(s) with |λ| > {lam_seed:g} solved separately: the shared CG "
                f"would need far more than {maxiter} iterations for them")
    return _Plan(isys, lam_seed, scale, sigmas, member_shift, hard, maxiter, note)


def _boundary_solve(fs: FlowSolver, op, V: np.ndarray):
    """Solve the boundary block (independent of λ): positions X and the system."""
    bsys = fs._boundary_system(op, fs.lam_border)
    return fs._solve_boundary(V, bsys), bsys


def _multishift(fs: FlowSolver, op, plan: _Plan, lams: np.ndarray, ax: np.ndarray, preserve_volume: bool,
                report: FamilyReport, tick) -> np.ndarray:
    mesh = fs.mesh
    V = mesh.vertices
    n, k = V.shape[0], lams.size
    X, bsys = _boundary_solve(fs, op, V)
    isys = plan.isys
    report.free_vertices = int((isys.free.sum() if isys is not None else 0)
                               + (bsys.free.sum() if bsys is not None else 0))
    report.shifts = int(plan.sigmas.size)
    report.solver = "multishift-cg" if isys is not None else "none"
    # every member starts as V with the boundary moved (flow(): sign of λ_b, enabled axes only)
    base = V.copy()
    if bsys is not None:
        sb = 1.0 if fs.lam_border >= 0 else -1.0
        base[np.ix_(bsys.idx, ax)] += sb * (X[bsys.idx] - V[bsys.idx])[:, ax]
    if not np.all(np.isfinite(X)):
        bad = ~np.isfinite(X).all(axis=1)
        X[bad] = V[bad]
        base[bad] = V[bad]
        report.notes.append(f"{int(bad.sum())} vertices with a non-finite solution kept in place")
    out = np.empty((k, n, 3))
    out[:] = base
    zero = (plan.member_shift < 0) & ~plan.hard     # λ = 0: V with the boundary moved
    tick(int(zero.sum()))
    if plan.hard.any():
        report.fallback_members = [int(m) for m in np.flatnonzero(plan.hard)]
        report.notes.append(plan.note)
    solved = plan.member_shift >= 0
    if isys is not None and solved.any():
        # r0 = b − A X for the seed (λ-independent: g − K V on free rows, 0 elsewhere)
        r_, s_, e_ = isys.coupling
        free = isys.free
        rhs = np.where(free[:, None], isys.c[:, None] * V, X)
        if r_.size:
            for j in range(3):
                rhs[:, j] += np.bincount(r_, e_ * X[s_, j], minlength=n)
        A = isys.A
        cols = np.flatnonzero(ax)
        R0 = np.empty((cols.size, n))
        for t, j in enumerate(cols):
            R0[t] = (rhs[:, j] - A @ X[:, j]) * plan.scale
        # the seed matrix scaled: S A S = σ_seed I + M on free rows, I elsewhere
        S = plan.scale
        As = A.copy()
        As.data *= np.repeat(S, np.diff(As.indptr)) * S[As.indices]
        deltas = plan.sigmas - plan.sigmas[0]
        member_of_shift = [np.flatnonzero(plan.member_shift == i) for i in range(plan.sigmas.size)]
        counted = np.zeros(plan.sigmas.size, bool)

        def on_progress(conv):
            new = conv & ~counted
            counted[new] = True
            tick(int(sum(member_of_shift[i].size for i in np.flatnonzero(new))))

        res = multishift_cg(As, R0, deltas, rtol=fs.rtol, maxiter=plan.maxiter, progress=on_progress)
        report.krylov_iterations = res.krylov_iterations
        Y = res.X                                           # (c, shifts, n)
        Y *= S                                              # displacement Δ = C_1^{-1/2} Y (0 off the free rows)
        ok = res.converged.all(axis=1) & np.isfinite(Y).all(axis=(0, 2))
        its = np.where(res.converged, res.iterations, res.krylov_iterations).max(axis=1)
        report.member_iterations[solved] = its[plan.member_shift[solved]]
        sign = np.where(lams >= 0, 1.0, -1.0)
        for m in np.flatnonzero(solved):
            i = plan.member_shift[m]
            if not ok[i]:
                continue
            for t, j in enumerate(cols):
                if sign[m] > 0:
                    out[m, :, j] += Y[t, i]
                else:
                    out[m, :, j] -= Y[t, i]
        bad = np.flatnonzero(solved & ~ok[np.maximum(plan.member_shift, 0)])
        if bad.size:
            report.fallback_members = sorted(set(report.fallback_members) | {int(m) for m in bad})
            report.notes.append(f"{bad.size} member(s) did not converge in {plan.maxiter} shared iterations "
                                "and were solved separately")
    elif solved.any():
        tick(int(solved.sum()))                             # no free interior vertex: boundary moves only
    if preserve_volume:
        center0 = V.mean(axis=0)
        skip = set(report.fallback_members)
        for m in range(k):
            moved = (lams[m] != 0.0 and isys is not None) or bsys is not None
            if m in skip or not moved:
                continue   # flow() returns the input unchanged there ("no free vertex"): no rescale
            r = FlowReport(lam=float(lams[m]), lam_border=fs.lam_border, iterations=1, mode=report.mode,
                           scheme=report.scheme, update=report.update)
            out[m] = fs._preserve_volume(V, out[m], ax, center0, r)
            report.notes.extend(r.notes)
    return out


def _separate(fs: FlowSolver, lams: np.ndarray, members, out: np.ndarray, report: FamilyReport, *,
              iterations: int, preserve_volume: bool, axes: np.ndarray, update: str, tick) -> None:
    """flow() for each listed member on the shared FlowSolver (operator built once)."""
    members = list(members)
    solvers_used = []
    reports = report.member_reports or [None] * lams.size
    cache: dict = {}
    for m in members:
        lam = float(lams[m])
        if lam not in cache:
            res = fs.run(lam, iterations=iterations, preserve_volume=preserve_volume, axes=axes, update=update)
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


# --------------------------------------------------------------------------
