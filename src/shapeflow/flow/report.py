"""What a run did: :class:`FlowReport` (``result.report`` of a flow) and :class:`FamilyReport` (of a family)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["FlowReport", "FamilyReport"]


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
    preconditioner: str = ""  # of the interior CG: "sgs" (symmetric Gauss–Seidel) or "jacobi"; "" without CG
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
    sharp_edges: int = 0      # feature-aware flow: sharp edges,
    curve_vertices: int = 0   # vertices that follow their feature curves,
    feature_fixed: int = 0    # and curve ends and corners, which stay

    def summary(self) -> str:
        """One line: time, max displacement, locked vertices, solver."""
        pre = f" ({self.preconditioner})" if self.preconditioner else ""
        its = f", CG iterations {self.cg_iterations}{pre}" if self.cg_iterations else ""
        notes = f"; {'; '.join(self.notes)}" if self.notes else ""
        return (f"{self.seconds:.3f} s, max displacement {self.max_displacement:.6g}, "
                f"{self.locked} locked vertices, solver {self.solver}{its}{notes}")


@dataclass
class FamilyReport:
    """What :func:`family` did.

    ``path`` is ``"multishift"``, ``"separate"`` or ``"unchanged"`` and
    ``reason`` says why.  ``member_iterations[m]`` is the CG iteration after
    which member ``m`` met the tolerance (multishift: of the shared solve, max
    over the coordinates; separate: flow()'s CG iterations, -1 for a direct
    solver; 0 for members with nothing to solve).  ``krylov_iterations`` is
    the number of shared iterations, each ``krylov_degree + 1`` matrix-vector products per coordinate
    (``krylov_degree``: the shared CG's polynomial preconditioner, 0 for none and for BiCG).
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
    krylov_degree: int = 0
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
            kind = "BiCG" if self.solver.startswith("multishift-bicg") else "CG"   # BiCG: with sharp edges
            per = f" of {self.krylov_degree + 1} products" if self.krylov_degree else ""
            how = (f"one multi-shift {kind} solve for {self.shifts} distinct |λ| "
                   f"({self.krylov_iterations} shared iterations{per})")
        elif self.path == "separate":
            how = f"{k} separate solves on one shared operator ({self.solver})"
        else:
            how = "input returned unchanged"
        fb = f", {len(self.fallback_members)} member(s) redone separately" if self.fallback_members else ""
        notes = f"; {'; '.join(self.notes)}" if self.notes else ""
        return f"{k} members: {how}{fb} ({self.reason}); {self.seconds:.3f} s{notes}"
