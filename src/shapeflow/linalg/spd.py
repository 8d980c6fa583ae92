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
        self._splits = None
        if diagonal_positions is not None:
            pos = np.asarray(diagonal_positions, dtype=np.int64)
            self._splits = (pos, pos + 1)
        d = A.diagonal() if diagonal is None else np.asarray(diagonal, dtype=np.float64)
        self._positive = bool(d.size and d.min() > 0)
        self._d = d
        if self._positive:      # the usual case: no temporaries
            self._minv = np.divide(1.0, d)
        else:
            self._minv = np.where(d > 0, 1.0 / np.where(d > 0, d, 1.0), 1.0)

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

    def _csr(self) -> sp.csr_matrix:
        """A as CSR (a :class:`PairMatrix` converts once, for the paths that need the entries)."""
        if isinstance(self.A, PairMatrix):
            self.A = self.A.tocsr()
        return self.A

    def _factorize(self) -> None:
        self.stats.factorizations += 1
        A = self._csr().copy()
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
        """PCG on all columns at once; returns (X, converged, B).  Jacobi here; the compiled path
        (:meth:`_cg_kernel`) and ``preconditioner="sgs"`` (:meth:`_cg_sgs`) as the class says.

        ``B`` comes back as given (rebuilt as R + A·X where the compiled path
        used it as the residual's storage) for a direct solve to take over.

        Stops when every column's preconditioned residual norm sqrt(rᵀM⁻¹r)
        fell below ``rtol`` × its initial value.  Vectors are stored
        component-major, (k, n), so every update runs over contiguous length-n
        rows (an (n, 3) layout makes NumPy loop over the length-3 axis).
        """
        n = self.A.shape[0]
        squeeze = B.ndim == 1
        fast = accel.compiled("linalg", n)
        lean = isinstance(self.A, PairMatrix)
        if self.preconditioner == "sgs" and (lean or not self._positive):
            raise ParameterError("the 'sgs' preconditioner needs a CSR matrix with a positive diagonal"
                                 + (" (this one is a PairMatrix)" if lean else ""))
        if fast is not None and (1 if squeeze else B.shape[1]) <= 3 and (lean or (
                self.A.indices.dtype == np.int32 and self.A.indptr.dtype == np.int32)):
            return self._cg_kernel(fast, B, X0, squeeze, overwrite_b)
        if self.preconditioner == "sgs":
            return self._cg_sgs(B, X0, squeeze)
        self.stats.preconditioner = "jacobi"
        A = self._csr()
        Bt = np.ascontiguousarray((B[:, None] if squeeze else B).T)
        k = Bt.shape[0]
        if X0 is None:
            X = np.zeros_like(Bt)
        else:
            X = np.ascontiguousarray(np.asarray(X0, dtype=np.float64).reshape(n, k).T)
        minv = self._minv

        def matvec(Y, out):
            for j in range(k):
                out[j] = A @ Y[j]
            return out

        R = np.empty_like(Bt)
        matvec(X, R)
        np.subtract(Bt, R, out=R)
        Z = R * minv
        rz = np.einsum("ij,ij->i", R, Z)
        tol2 = (self.rtol ** 2) * rz
        P = Z.copy()
        AP = np.empty_like(P)
        T = np.empty_like(P)
        maxiter = self._maxiter(n)
        it = 0
        while it < maxiter and (rz > tol2).any():
            it += 1
            matvec(P, AP)
            pap = np.einsum("ij,ij->i", P, AP)
            alpha = np.divide(rz, pap, out=np.zeros_like(rz), where=(pap > 0) & (rz > tol2))
            np.multiply(P, alpha[:, None], out=T)
            X += T
            np.multiply(AP, alpha[:, None], out=T)
            R -= T
            np.multiply(R, minv, out=Z)
            rz_new = np.einsum("ij,ij->i", R, Z)
            beta = np.divide(rz_new, rz, out=np.zeros_like(rz), where=rz > 0)
            rz = rz_new
            P *= beta[:, None]
            P += Z
        self.stats.iterations = it
        converged = not (rz > tol2).any() and bool(np.all(np.isfinite(X)))
        return (X[0] if squeeze else np.ascontiguousarray(X.T)), converged, B

    def _maxiter(self, n: int) -> int:
        return self.maxiter or cg_maxiter(n)

    def _cg_sgs(self, B: np.ndarray, X0: np.ndarray | None, squeeze: bool):
        """The symmetric Gauss–Seidel PCG of ``compiled.sgs_pcg3`` with SciPy's triangular solves
        (the NumPy twin of that kernel: the same formulas, (n, k) layout); returns (X, converged, B)."""
        from scipy.sparse.linalg import spsolve_triangular

        self.stats.preconditioner = "sgs"
        A = self._csr()
        n = A.shape[0]
        Bn = B[:, None] if squeeze else B
        X = np.zeros(Bn.shape) if X0 is None else np.array(np.asarray(X0, dtype=np.float64).reshape(Bn.shape))
        d = self._d[:, None]
        E = sp.tril(A, 0, format="csr")
        F = sp.triu(A, 0, format="csr")
        U = sp.triu(A, 1, format="csr")
        R = spsolve_triangular(E, Bn - U @ X, lower=True) - X     # r̂0 = E⁻¹(b − U x0) − x0
        P = d * R
        rz = np.einsum("ij,ij->j", R, R * d)
        tol2 = (self.rtol ** 2) * rz
        maxiter = self._maxiter(n)
        it = 0
        while it < maxiter and (rz > tol2).any():
            it += 1
            T = spsolve_triangular(F, P, lower=False)            # t = F⁻¹ p
            Q = T + spsolve_triangular(E, P - d * T, lower=True)  # E⁻¹ A F⁻¹ p = t + E⁻¹(p − D t)
            pq = np.einsum("ij,ij->j", P, Q)
            alpha = np.divide(rz, pq, out=np.zeros_like(rz), where=(pq > 0) & (rz > tol2))
            X += alpha * T                                        # x = F⁻¹ y
            R -= alpha * Q
            rz_new = np.einsum("ij,ij->j", R, R * d)
            beta = np.divide(rz_new, rz, out=np.zeros_like(rz), where=rz > 0)
            rz = rz_new
            P = d * R + beta * P
        self.stats.iterations = it
        converged = not (rz > tol2).any() and bool(np.all(np.isfinite(X)))
        return (X[:, 0] if squeeze else X), converged, B

    def _cg_kernel(self, fast, B: np.ndarray, X0: np.ndarray | None, squeeze: bool,
                   overwrite_b: bool = False):
        """:meth:`_cg` compiled, (n, 3) layout: Jacobi (all cores) or symmetric Gauss–Seidel (one core;
        ``preconditioner`` "auto" on a CSR matrix with sorted columns and a positive diagonal, or "sgs")."""
        A = self.A
        n = A.shape[0]
        k = 1 if squeeze else B.shape[1]
        if k == 3:   # B is C-contiguous float64 (solve() made it so); the kernel only reads it
            B3 = B
            X = np.array(X0, dtype=np.float64, order="C") if X0 is not None else np.zeros((n, 3))
        else:
            B3 = np.zeros((n, 3))
            B3[:, :k] = B.reshape(n, k)
            X = np.zeros((n, 3))
            if X0 is not None:
                X[:, :k] = np.asarray(X0, dtype=np.float64).reshape(n, k)
        maxiter = self._maxiter(n)
        reused = overwrite_b or B3 is not B
        sgs = False
        if isinstance(A, PairMatrix):
            its = fast.pcg3_pairs(A.pairs, A.weights, A.free, A.d, self._minv, B3, X, self.rtol, maxiter,
                                  overwrite_b=reused)
        else:
            if self.preconditioner != "jacobi" and self._positive and self._splits is None:
                self._splits = fast.row_splits(A.indptr, A.indices)
                if self._splits is None and self.preconditioner == "sgs":   # unsorted columns: a sorted copy
                    self.A = A = A.sorted_indices()
                    self._splits = fast.row_splits(A.indptr, A.indices)
            sgs = self.preconditioner != "jacobi" and self._positive and self._splits is not None
            data = np.ascontiguousarray(A.data, dtype=np.float64)
            if sgs:
                its = fast.sgs_pcg3(A.indptr, A.indices, data, self._splits, self._d, B3, X, self.rtol, maxiter,
                                    overwrite_b=reused)
            else:
                its = fast.pcg3(A.indptr, A.indices, data, self._minv, B3, X, self.rtol, maxiter,
                                overwrite_b=reused)
        self.stats.preconditioner = "sgs" if sgs else "jacobi"
        self.stats.iterations = int(its)
        # the kernel stops at convergence or at the cap: reaching the cap counts as not converged
        converged = self.stats.iterations < maxiter and bool(np.all(np.isfinite(X)))
        if not converged and reused and B3 is B:   # B holds the residual: rebuild B
            # Jacobi: r = B − A X; SGS: r̂ = E⁻¹ r with E = D + L, the lower triangle of A
            B = (sp.tril(A, 0, format="csr") @ B3 if sgs else B3) + A @ X
        Xk = X[:, 0].copy() if squeeze else (X if k == 3 else X[:, :k].copy())
        return Xk, converged, B
