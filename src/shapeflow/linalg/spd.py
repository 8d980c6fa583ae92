"""Solvers for the symmetric positive definite flow systems ``A X = B``.

``A`` is always symmetric (the scaled form of eq. 11, see
:mod:`shapeflow.flow`), with a few columns of right-hand sides.  Back ends:

``"cg"``
    Preconditioned conjugate gradients on all columns at once, warm
    started (from the current positions), stopping when every column's
    preconditioned residual fell by ``rtol`` relative to its starting value —
    i.e. the error is relative to the *displacement*, not to the coordinates.  No
    set-up cost; iterations grow like sqrt(1 + 2|λ|).  Preconditioners
    (:data:`PRECONDITIONERS`): ``"sgs"``, symmetric Gauss–Seidel in Eisenstat's
    form (``shapeflow.linalg.compiled.sgs_pcg3``), which needs about half the
    iterations of ``"jacobi"`` at the cost of one product by A each (on the
    flow's systems 7 instead of 14 at λ = 1, 21 instead of 45 at λ = 10, 64
    instead of 150 at λ = 100: the CG of a fresh step on Suzanne 126K
    triangulated 38 → 24 ms on one thread, 2026-11-24); its sweeps are
    sequential and run in the order of the unknowns, so numbering the vertices
    differently changes a result within the tolerance, not to the last bit.
    ``"auto"`` (default) takes ``"sgs"`` where the compiled
    kernels run on a CSR matrix with a positive diagonal, ``"jacobi"``
    elsewhere: with SciPy alone a triangular solve costs ~7 products
    (``spsolve_triangular``), so the NumPy path keeps Jacobi, and the lean
    :class:`~shapeflow.linalg.pairs.PairMatrix` layout has no rows to sweep.
``"cholesky"``
    Sparse Cholesky from the optional ``cholespy`` package
    (``pip install 'shapeflow[cholesky]'``): a factorisation reused for
    every later solve with the same matrix.
``"lu"``
    SciPy's SuperLU, always available; also the fallback for an indefinite
    system (never for the normal SPD case).

``"auto"`` picks by a cost model calibrated with ``benchmarks/bench_flow.py``
(see :func:`choose_method`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .. import accel
from ..errors import OptionalDependencyError, ParameterError
from .pairs import PairMatrix

__all__ = ["METHODS", "PRECONDITIONERS", "DEFAULT_PRECONDITIONER", "DEFAULT_RTOL", "cholesky_available",
           "estimate_cg_iterations", "cg_maxiter",
           "choose_method", "SolveStats", "SPDSolver"]


METHODS = ("auto", "cg", "cholesky", "lu")

#: CG preconditioners (see the module docstring)
PRECONDITIONERS = ("auto", "jacobi", "sgs")

#: the preconditioner of an :class:`SPDSolver` made without one (the flow's): a module setting that
#: tests comparing with the Jacobi-only paths (the lean layout) set to "jacobi"
DEFAULT_PRECONDITIONER = "auto"


#: CG stops when each column's (preconditioned) residual norm fell by this factor:
#: the error is ~1e-8 of the displacement, far below anything visible.
DEFAULT_RTOL = 1e-8


def cholesky_available() -> bool:
    try:
        import cholespy  # noqa: F401
    except Exception:   # noqa: BLE001 - not installed, or installed and broken
        return False
    return True


def estimate_cg_iterations(kappa: float, rtol: float = DEFAULT_RTOL) -> float:
    """Textbook CG iteration bound for condition number ``kappa``."""
    return 0.5 * np.sqrt(max(kappa, 1.0)) * np.log(2.0 / rtol) + 1.0


def cg_maxiter(n: int) -> int:
    """The default cap on CG iterations for n unknowns."""
    return max(200, 10 * int(np.sqrt(n)) + 100)


def choose_method(n: int, kappa: float, n_solves: int, rtol: float = DEFAULT_RTOL,
                  preconditioner: str = "jacobi") -> str:
    """Pick the back end expected to be fastest; ``preconditioner``: the one CG would run ("sgs" on
    the compiled path, see :class:`SPDSolver`).

    Jacobi, calibrated with ``benchmarks/bench_flow.py`` on this project's 2-core
    reference machine: on the 126K-vertex Suzanne, a cholespy factorisation
    costs as much as ~185 Jacobi-PCG iterations on three columns and a pair
    of triangular solves ~3 iterations; for surface meshes the factorisation
    grows like n^1.5 and an iteration like n, so the break-even grows like
    sqrt(n).  CG iterations are estimated from the condition number bound.
    Symmetric Gauss–Seidel (2026-11-24, Suzanne 126K triangulated, one flow step, λ = 3 … 300):
    its iterations are 0.43–0.5 of Jacobi's (half the bound is used), and a factorisation
    (1.1–1.5 s) costs ~450 of its iterations (2.5 ms each): at λ = 300, CG 0.39 s (110
    iterations) against Cholesky 1.1 s, where the Jacobi model had chosen Cholesky; at λ = 1000
    1.06 s (197) against 1.5 s; at λ = 3000, the model's break-even, 1.58 against 1.53 s.
    """
    if n < 2000:
        return "lu" if n_solves > 1 or kappa > 1e4 else "cg"
    its = estimate_cg_iterations(kappa, rtol) * (0.5 if preconditioner == "sgs" else 1.0)
    cg_cost = its * n_solves
    factor_cost = (450.0 if preconditioner == "sgs" else 185.0) * np.sqrt(n / 126_000.0)
    if cholesky_available():
        if cg_cost > factor_cost + 3.0 * n_solves:
            return "cholesky"
        return "cg"
    # SuperLU (no cholespy) where CG is expected to run past its iteration cap (it would fall back anyway)
    if its > cg_maxiter(n):
        return "lu"
    return "cg"


@dataclass
class SolveStats:
    method: str
    iterations: int = 0   # CG iterations of the last solve
    preconditioner: str = ""   # of the last CG solve: "jacobi" or "sgs"
    solves: int = 0
    factorizations: int = 0
    fallback: str = ""    # why CG gave way to LU ("" while it has not)


class SPDSolver:
    """Solve ``A X = B`` repeatedly for one symmetric matrix ``A``.

    The factorisation (direct methods) is computed on the first solve and
    reused; CG keeps its preconditioner.  A CG solve that does not reach
    ``rtol`` within its iteration cap is redone by SciPy's SuperLU, and the
    solver stays on LU from then on; ``stats.fallback`` says why (the flow
    copies it into its report), so no solve returns short of its tolerance
    in silence.  ``diagonal``, when the caller
    already has it, saves extracting A's diagonal for the
    preconditioner (it must equal ``A.diagonal()``).  ``preconditioner``: one of
    :data:`PRECONDITIONERS` (CG only; None: :data:`DEFAULT_PRECONDITIONER`).
    ``diagonal_positions``: where each row's diagonal entry is stored in ``A.indices``, for a CSR
    matrix whose columns are sorted in every row with exactly one diagonal entry (the operator
    pattern's ``pos_diag``); it saves the Gauss–Seidel sweeps a pass over A to find them.
    """

    def __init__(self, A: sp.csr_matrix | PairMatrix, method: str = "cg", *, rtol: float = DEFAULT_RTOL,
                 maxiter: int | None = None, diagonal: np.ndarray | None = None,
                 preconditioner: str | None = None, diagonal_positions: np.ndarray | None = None):
        if method not in METHODS or method == "auto":
            raise ParameterError(f"unknown solver {method!r}; choose one of {', '.join(METHODS)}")
        if preconditioner is None:
            preconditioner = DEFAULT_PRECONDITIONER
        if preconditioner not in PRECONDITIONERS:
            raise ParameterError(f"unknown preconditioner {preconditioner!r}; choose one of "
                                 f"{', '.join(PRECONDITIONERS)}")
        if method == "cholesky" and not cholesky_available():
            raise OptionalDependencyError("cholespy", "cholesky", "the Cholesky solver")
        self.A = A
        self.method = method
        self.rtol = float(rtol)
        self.maxiter = maxiter
        self.preconditioner = preconditioner
        self.stats = SolveStats(method)
        self._factor = None
        #: where each row's strictly lower part ends and strictly upper part starts (the Gauss–Seidel
        #: sweeps'), when known
        self.splits = None
        if diagonal_positions is not None:
            pos = np.asarray(diagonal_positions, dtype=np.int64)
            self.splits = (pos, pos + 1)
        d = A.diagonal() if diagonal is None else np.asarray(diagonal, dtype=np.float64)
        self.positive = bool(d.size and d.min() > 0)     #: whether A's diagonal is positive
        self.diagonal = d                                  #: A's diagonal
        if self.positive:      # the usual case: no temporaries
            self.minv = np.divide(1.0, d)                  #: the Jacobi preconditioner (1 where d <= 0)
        else:
            self.minv = np.where(d > 0, 1.0 / np.where(d > 0, d, 1.0), 1.0)

    def solve(self, B: np.ndarray, X0: np.ndarray | None = None, *, overwrite_b: bool = False) -> np.ndarray:
        """X with A X = B; ``X0`` a starting guess (CG).  ``overwrite_b``: B may serve as
        scratch space (its values are then undefined), which saves an allocation."""
        B = np.ascontiguousarray(B, dtype=np.float64)
        self.stats.solves += 1
        if self.method == "cg":
            X, converged, B_left = self._cg(B, X0, overwrite_b)
            if converged:
                return X
            self.stats.fallback = (f"CG did not reach rtol={self.rtol:g} in {self.stats.iterations} iterations "
                                   f"(n={self.A.shape[0]}): solved by LU instead")
            self.method = self.stats.method = "lu"
            B = B_left
        if self._factor is None:
            self._factorize()
        if self.method == "cholesky":
            X = np.zeros_like(B)
            self._factor.solve(B, X)
            return X
        return self._factor.solve(B)

    def csr(self) -> sp.csr_matrix:
        """A as CSR (a :class:`PairMatrix` converts once, for the paths that need the entries)."""
        if isinstance(self.A, PairMatrix):
            self.A = self.A.tocsr()
        return self.A

    def _factorize(self) -> None:
        self.stats.factorizations += 1
        A = self.csr().copy()
        A.sum_duplicates()  # direct solvers need one entry per position
        if self.method == "cholesky":
            import cholespy

            self._factor = cholespy.CholeskySolverD(
                A.shape[0], A.indptr.astype(np.int32), A.indices.astype(np.int32),
                np.ascontiguousarray(A.data, dtype=np.float64), cholespy.MatrixType.CSR)
        else:
            from scipy.sparse.linalg import splu

            self._factor = splu(A.tocsc(), permc_spec="MMD_AT_PLUS_A")

    def _cg(self, B: np.ndarray, X0: np.ndarray | None, overwrite_b: bool = False):
        """PCG on all columns at once (the linalg kernel family's ``cg``); returns (X, converged, B)."""
        n = self.A.shape[0]
        lean = isinstance(self.A, PairMatrix)
        if self.preconditioner == "sgs" and (lean or not self.positive):
            raise ParameterError("the 'sgs' preconditioner needs a CSR matrix with a positive diagonal"
                                 + (" (this one is a PairMatrix)" if lean else ""))
        return accel.kernels("linalg", n).cg(self, B, X0, overwrite_b)

    def iteration_cap(self, n: int) -> int:
        """The most CG iterations of a solve with n unknowns (``maxiter``, else :func:`cg_maxiter`)."""
        return self.maxiter or cg_maxiter(n)
