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

The members are then checked by their true residuals, which the recurrences
never compute: every member solved in the shared solve is read back from
the result, ``Y = ±C_1^{1/2}(member − base)``, and ``‖b − (σ I + M) Y‖``
compared per coordinate with ``10 × rtol ‖b‖`` (the factor covers the gap
between the recurrence and the true residual: rounding, ~ε κ, and the
low-rank fold; measured below 1 × rtol on the figure-1 families) plus what
rounding the positions alone leaves (ε (‖|M|‖∞ + σ)(‖C_1^{1/2} base‖ + ‖Y‖)),
by the flow kernel family's ``member_residuals`` (compiled: 16 members per pass over the matrix;
:func:`~shapeflow.flow.family_paths.check_members`).  A member that fails
(a wrong matrix or order, a fold that went astray) is solved again on its own
exactly as ``flow()`` does (with that path's own checks and fallback), and a
:class:`~shapeflow.errors.SolverWarning` names how many members and their λ.

Cost: the shifted solutions are linear combinations of the seed residuals.
Rather than two axpy passes per member per iteration (48 members × 3 columns
× n — more than the matrix-vector product), the residuals are kept in a block
(:data:`BLOCK_BYTES`) and the members' iterates are formed with one GEMM per
block — usually one in all (:func:`multishift_cg`); the per-member
recurrences only touch coefficients.  Measured on the 46,850-vertex figure-1
family (``benchmarks/bench_family.py``, 2-core machine, load ~1, 2026-11-26): the
48 members in 0.53–0.58 s (against the hardest member's flow() alone: docs/performance.md,
"The family's shared solve"), against 14.2 s for 48 flow() calls and ~123 s for 48 Blender
evaluations.  The compiled seed, the factor's powers and the check run on the call's threads
(``accel.use(threads=…)``); the result has the same bits on any number of threads.

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
from typing import Callable, Sequence

import numpy as np

from .. import accel, params
from ..errors import ParameterError
from ..geometry.normals import refresh_normals
from ..linalg.spd import DEFAULT_RTOL
from ..mesh import Mesh
from ..types import Axes, Weights
from .family_paths import plan_shared_solve, separate_solves, shared_solve
from .features import SharpEdges
from .options import check_run_options
from .report import FamilyReport
from .solver import FlowSolver

__all__ = ["family", "family_meshes", "family_bytes", "FamilyReport", "STRATEGIES"]


#: ``strategy=`` values: choose, insist on the shared solve, or force per-λ solves
STRATEGIES = ("auto", "multishift", "separate")


def check_lams(lams) -> np.ndarray:
    if isinstance(lams, (str, bytes)) or np.ndim(lams) != 1:
        raise ParameterError(f"lams must be a 1-D sequence of numbers (one λ per member), got {lams!r}")
    vals = [params.lam(f"lams[{i}]", x) for i, x in enumerate(lams)]
    if not vals:
        raise ParameterError("lams is empty: give at least one λ")
    return np.array(vals, dtype=np.float64)


def family_bytes(k: int, n: int) -> float:
    """Memory (bytes) a family of ``k`` members of ``n`` vertices needs: the (k, n, 3) result plus the
    shared solve's work (~4 such blocks of one batch of members)."""
    return 24.0 * n * (k + 4 * min(k, 64))


@accel.heavy
def family(mesh: Mesh, lams: Sequence[float], *, lam_border: float = 0.0, iterations: int = 1,
           normalized: bool = True, weights: Weights = None, invert_weights: bool = False,
           preserve_volume: bool = False, axes: Axes = (True, True, True),
           scheme: str | None = None, update: str = "fixed", compat: str | None = None,
           solver: str = "auto", rtol: float = DEFAULT_RTOL, strategy: str = "auto",
           progress: Callable[[int, int], None] | None = None, return_report: bool = False,
           feature_angle: float | None = None, sharp_edges: SharpEdges = None
           ) -> np.ndarray | tuple[np.ndarray, FamilyReport]:
    """The flow for every λ of ``lams`` at once: an array ``(k, n, 3)``.

    ``result[m]`` equals ``flow(mesh, lams[m], **options).vertices`` (to the
    CG tolerance), but one iteration of all members costs about as much as the
    hardest member alone (multi-shift CG; see the module docstring).  Every
    member of the shared solve is checked by its true residual (10 × ``rtol``);
    one that misses it is solved again as ``flow()`` and named in a
    :class:`~shapeflow.errors.SolverWarning` (and in ``report.notes`` and
    ``report.fallback_members``).

    Parameters
    ----------
    mesh : Mesh
    lams : sequence of float
        One λ per member, any signs, zeros and repeats allowed (+λ and −λ
        share one solve).  Figure 1 of the paper: ``np.arange(0, -240, -5)``.
    lam_border, iterations, normalized, weights, invert_weights, preserve_volume,
    axes, scheme, update, compat, solver, rtol, feature_angle, sharp_edges
        As in :func:`shapeflow.flow` (validated the same way).  With sharp edges the
        shared solve is a multi-shift BiCG (:mod:`shapeflow.flow.family_features`).  ``rtol`` is the
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

    With the compiled kernels the shared solve runs on the threads of ``accel.use(threads=…)``
    (default ``"auto"``: the cores free when the call starts); the members have the same bits on any
    number of threads.

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
    lam_arr = check_lams(lams)
    preserve_volume = params.flag("preserve_volume", preserve_volume)
    return_report = params.flag("return_report", return_report)
    params.progress(progress)
    flow_solver = FlowSolver(mesh, lam_border=lam_border, normalized=normalized, weights=weights,
                             invert_weights=invert_weights, scheme=scheme, compat=compat, solver=solver, rtol=rtol,
                             feature_angle=feature_angle, sharp_edges=sharp_edges)
    if flow_solver.pow2:   # extreme coordinates: the family of the exact power-of-two copy, scaled back
        e = flow_solver.pow2
        shapes, rep = family(flow_solver.mesh, lam_arr if normalized else np.ldexp(lam_arr, -2 * e),
                             lam_border=lam_border, iterations=iterations, normalized=normalized,
                             weights=flow_solver.w, preserve_volume=preserve_volume, axes=axes, scheme=scheme,
                             update=update, compat=compat, solver=solver, rtol=rtol, strategy=strategy,
                             progress=progress, return_report=True,
                             sharp_edges=None if flow_solver.sharp is None else
                             flow_solver.mesh.topology.edges[flow_solver.sharp])
        shapes = scaled_back(shapes, rep, lam_arr, e)
        return (shapes, rep) if return_report else shapes
    ax = check_run_options(iterations, update, axes, flow_solver.blender)
    k, n = lam_arr.size, mesh.n_vertices
    from ..budget import check_memory

    check_memory(f"a family of {k:,} members of {n:,} vertices", family_bytes(k, n), parameter="lams")
    report = FamilyReport(lams=lam_arr, path="unchanged", reason="", lam_border=flow_solver.lam_border,
                          iterations=int(iterations), mode="blender" if flow_solver.blender else "paper",
                          scheme=flow_solver.scheme, update=update, member_iterations=np.zeros(k, np.int64))
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
    nothing = nothing_to_do(flow_solver, lam_arr, iterations, ax)
    if nothing is not None:
        report.reason = nothing
        out = np.broadcast_to(V0, (k, n, 3)).copy()
        tick(k)
        return finish(out)

    operator = flow_solver.operator()
    report.locked = int(operator.locked.sum())
    report.degenerate_triangles = operator.n_bad
    report.boundary_vertices = int(operator.boundary.sum())

    why_not, plan = choose_path(flow_solver, operator, lam_arr, iterations, strategy, report.notes)
    if strategy == "multishift" and why_not is not None:
        raise ParameterError(f"the multi-shift solve does not apply here: {why_not}")

    if why_not is not None:
        report.path, report.reason = "separate", why_not
        out = np.empty((k, n, 3))
        separate_solves(flow_solver, lam_arr, range(k), out, report, iterations=iterations,
                        preserve_volume=preserve_volume, axes=ax, update=update, tick=tick)
        return finish(out)

    report.path = "multishift"
    report.reason = ("one iteration: every member solves (σI + M) Y = b with σ = 1/|λ| "
                     "for one matrix M and one right-hand side b")
    out = shared_solve(flow_solver, operator, plan, lam_arr, ax, preserve_volume, report, tick)
    if report.fallback_members:
        separate_solves(flow_solver, lam_arr, report.fallback_members, out, report, iterations=iterations,
                        preserve_volume=preserve_volume, axes=ax, update=update, tick=tick)
    return finish(out)


def scaled_back(shapes: np.ndarray, report: FamilyReport, lams: np.ndarray, e: int) -> np.ndarray:
    """Shapes computed on the input scaled by 2^-e, back at the input's scale (exact)."""
    report.lams = lams
    with np.errstate(over="ignore"):
        shapes = np.ldexp(shapes, e)
    if not np.isfinite(shapes).all():
        raise ParameterError("lams: the result leaves the range of double precision (|x| > 1.8e308)")
    report.notes.append(f"computed on the coordinates scaled by 2^{-e} (exact), then scaled back")
    return shapes


def nothing_to_do(flow_solver: FlowSolver, lams: np.ndarray, iterations: int, ax: np.ndarray) -> str | None:
    """Why no member moves (the conditions of ``FlowSolver.run``, for every member), or None."""
    if iterations == 0:
        return "iterations=0"
    if not ax.any():
        return "no axis may change"
    if not (flow_solver.w > 0).any():
        return "every weight is 0"
    if flow_solver.mesh.n_faces == 0:
        return "the mesh has no faces"
    if not lams.any() and flow_solver.lam_border == 0.0:
        return "every λ and λ_b are 0"
    return None


def choose_path(flow_solver: FlowSolver, operator, lams: np.ndarray, iterations: int, strategy: str, notes: list):
    """(why the shared solve does not apply or None, its plan or None)."""
    why_not = None
    if iterations > 1:
        why_not = (f"{iterations} iterations: from the second step on the right-hand sides differ "
                   "per member, so the systems are no longer shifts of one")
    elif flow_solver.solver_method in ("cholesky", "lu"):
        why_not = f"solver={flow_solver.solver_method!r} was asked for"
    plan = None
    if strategy == "separate":
        why_not = "strategy='separate' was asked for"
    elif why_not is None:
        plan = plan_shared_solve(flow_solver, operator, lams, notes)
        if isinstance(plan, str):
            why_not, plan = plan, None
    return why_not, plan


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
