"""Solvers for the symmetric positive definite flow systems ``A X = B``.

``A`` is always symmetric (the scaled form of eq. 11, see
:mod:`shapeflow.flow`), with a few columns of right-hand sides.  Back ends:

``"cg"``
    Jacobi-preconditioned conjugate gradients on all columns at once, warm
    started (from the current positions), stopping when every column's
    residual fell by ``rtol`` relative to its starting residual — i.e. the
    error is relative to the *displacement*, not to the coordinates.  No
    set-up cost; iterations grow like sqrt(1 + 2|λ|).
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

from .errors import OptionalDependencyError, ParameterError

METHODS = ("auto", "cg", "cholesky", "lu")

#: CG stops when each column's residual is below ``rtol`` × its initial residual.
DEFAULT_RTOL = 1e-10


def cholesky_available() -> bool:
    try:
        import cholespy  # noqa: F401
    except ImportError:
        return False
    return True


def estimate_cg_iterations(kappa: float, rtol: float = DEFAULT_RTOL) -> float:
    """Textbook CG iteration bound for condition number ``kappa``."""
    return 0.5 * np.sqrt(max(kappa, 1.0)) * np.log(2.0 / rtol) + 1.0


def choose_method(n: int, kappa: float, n_solves: int, rtol: float = DEFAULT_RTOL) -> str:
    """Pick the back end expected to be fastest.

    Measured on this project's 2-core reference machine (126K-vertex quad
    mesh, ``benchmarks/bench_flow.py``): one Jacobi-PCG iteration on three
    columns costs about as much as 1/250 of a cholespy factorisation, and a
    triangular solve pair about 3 CG iterations.  So CG wins unless the
    expected total CG iterations exceed ~250 + 3 per solve.
    """
    if n < 2000:
        return "lu" if n_solves > 1 or kappa > 1e4 else "cg"
    cg_cost = estimate_cg_iterations(kappa, rtol) * n_solves
    if cholesky_available() and cg_cost > 250.0 + 3.0 * n_solves:
        return "cholesky"
    return "cg"


@dataclass
class SolveStats:
    method: str
    iterations: int = 0   # CG iterations of the last solve
    solves: int = 0
    factorizations: int = 0


class SPDSolver:
    """Solve ``A X = B`` repeatedly for one symmetric matrix ``A``.

    The factorisation (direct methods) is computed on the first solve and
    reused; CG keeps its preconditioner.
    """

    def __init__(self, A: sp.csr_matrix, method: str = "cg", *, rtol: float = DEFAULT_RTOL,
                 maxiter: int | None = None):
        if method not in METHODS or method == "auto":
            raise ParameterError(f"unknown solver {method!r}; choose one of {', '.join(METHODS)}")
        if method == "cholesky" and not cholesky_available():
            raise OptionalDependencyError("cholespy", "cholesky", "the Cholesky solver")
        self.A = A
        self.method = method
        self.rtol = float(rtol)
        self.maxiter = maxiter
        self.stats = SolveStats(method)
        self._factor = None
        d = A.diagonal()
        self._minv = np.where(d > 0, 1.0 / np.where(d > 0, d, 1.0), 1.0)

    def solve(self, B: np.ndarray, X0: np.ndarray | None = None) -> np.ndarray:
        B = np.ascontiguousarray(B, dtype=np.float64)
        self.stats.solves += 1
        if self.method == "cg":
            return self._cg(B, X0)
        if self._factor is None:
            self._factorize()
        if self.method == "cholesky":
            X = np.zeros_like(B)
            self._factor.solve(B, X)
            return X
        return self._factor.solve(B)

    def _factorize(self) -> None:
        self.stats.factorizations += 1
        A = self.A
        if self.method == "cholesky":
            import cholespy

            self._factor = cholespy.CholeskySolverD(
                A.shape[0], A.indptr.astype(np.int32), A.indices.astype(np.int32),
                np.ascontiguousarray(A.data, dtype=np.float64), cholespy.MatrixType.CSR)
        else:
            from scipy.sparse.linalg import splu

            self._factor = splu(A.tocsc(), permc_spec="MMD_AT_PLUS_A")

    def _cg(self, B: np.ndarray, X0: np.ndarray | None) -> np.ndarray:
        A = self.A
        n = A.shape[0]
        squeeze = B.ndim == 1
        if squeeze:
            B = B[:, None]
        X = np.zeros_like(B) if X0 is None else np.array(X0, dtype=np.float64, order="C").reshape(B.shape)
        R = B - A @ X
        r0 = np.sqrt(np.einsum("ij,ij->j", R, R))
        bn = np.sqrt(np.einsum("ij,ij->j", B, B))
        tol = self.rtol * np.maximum(r0, 1e-300) + 1e-300 * bn
        minv = self._minv[:, None]
        Z = minv * R
        P = Z.copy()
        rz = np.einsum("ij,ij->j", R, Z)
        maxiter = self.maxiter or max(200, 10 * int(np.sqrt(n)) + 100)
        it = 0
        AP = np.empty_like(P)
        active = r0 > tol
        while active.any() and it < maxiter:
            it += 1
            AP = A @ P
            pap = np.einsum("ij,ij->j", P, AP)
            alpha = np.where(pap > 0, rz / np.where(pap > 0, pap, 1.0), 0.0) * active
            X += alpha * P
            R -= alpha * AP
            rn = np.sqrt(np.einsum("ij,ij->j", R, R))
            active = rn > tol
            if not active.any():
                break
            np.multiply(minv, R, out=Z)
            rz_new = np.einsum("ij,ij->j", R, Z)
            beta = np.where(rz > 0, rz_new / np.where(rz > 0, rz, 1.0), 0.0)
            rz = rz_new
            P *= beta
            P += Z
        self.stats.iterations = it
        if active.any() and not np.all(np.isfinite(X)):
            raise FloatingPointError("CG diverged")
        return X[:, 0] if squeeze else X
