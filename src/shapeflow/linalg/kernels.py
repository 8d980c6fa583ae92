"""The linear-algebra kernel families (NumPy/SciPy references).

* ``"linalg"`` (:class:`LinalgKernels`): the CG of :class:`~shapeflow.linalg.spd.SPDSolver`, the
  Clenshaw step of :func:`~shapeflow.linalg.chebyshev.chebyshev_steps` and the seed's CG of
  :func:`~shapeflow.linalg.multishift.multishift_cg`;
* ``"local"`` (:class:`LocalKernels`, any size): the brush's small systems, their narrow-band
  order and the split solve (:class:`~shapeflow.linalg.local.LocalSolver`).

The numba implementations are :class:`shapeflow.linalg.compiled.LinalgNumba` and
:class:`shapeflow.linalg.compiled_split.LocalNumba`; :func:`shapeflow.accel.kernels` chooses.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..accel import Family
from .ordering import narrower, row_ptr

__all__ = ["LinalgKernels", "LocalKernels"]


class LinalgKernels(Family):
    """Kernels of the flow's large SPD systems."""

    family = "linalg"
    #: the preconditioner CG runs for ``preconditioner="auto"`` on a CSR matrix with a positive
    #: diagonal (the flow's cost model asks): Jacobi here, where a Gauss–Seidel sweep would cost
    #: about seven products (SciPy's ``spsolve_triangular``)
    auto_preconditioner = "jacobi"

    def cg(self, solver, B: np.ndarray, X0: np.ndarray | None, overwrite_b: bool = False):
        """PCG of ``solver`` (an :class:`~shapeflow.linalg.spd.SPDSolver`) on every column of ``B`` at
        once: ``(X, converged, B)``, ``B`` as given (or rebuilt as R + A·X where an implementation used
        it as the residual's storage) for a direct solve to take over.  Symmetric Gauss–Seidel when
        the solver's preconditioner is ``"sgs"``, else Jacobi.

        Stops when every column's preconditioned residual norm sqrt(rᵀM⁻¹r) fell below ``rtol`` ×
        its initial value.  Vectors are stored component-major, (k, n), so every update runs over
        contiguous length-n rows (an (n, 3) layout makes NumPy loop over the length-3 axis).
        """
        squeeze = B.ndim == 1
        if solver.preconditioner == "sgs":
            return sgs_cg(solver, B, X0, squeeze)
        solver.stats.preconditioner = "jacobi"
        A = solver.csr()
        n = A.shape[0]
        Bt = np.ascontiguousarray((B[:, None] if squeeze else B).T)
        k = Bt.shape[0]
        if X0 is None:
            X = np.zeros_like(Bt)
        else:
            X = np.ascontiguousarray(np.asarray(X0, dtype=np.float64).reshape(n, k).T)
        minv = solver.minv

        def matvec(Y, out):
            for j in range(k):
                out[j] = A @ Y[j]
            return out

        R = np.empty_like(Bt)
        matvec(X, R)
        np.subtract(Bt, R, out=R)
        Z = R * minv
        rz = np.einsum("ij,ij->i", R, Z)
        tol2 = (solver.rtol ** 2) * rz
        P = Z.copy()
        AP = np.empty_like(P)
        T = np.empty_like(P)
        maxiter = solver.iteration_cap(n)
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
        solver.stats.iterations = it
        converged = not (rz > tol2).any() and bool(np.all(np.isfinite(X)))
        return (X[0] if squeeze else np.ascontiguousarray(X.T)), converged, B

    def multishift_seed(self, A, B: np.ndarray, seed: float, cap: int, coef: np.ndarray | None = None):
        """The seed's CG of :func:`~shapeflow.linalg.multishift.multishift_cg` on ``A₀ = A + seed I`` (or
        ``A₀ p(A₀)``, p's monomial coefficients ``coef``) from the residuals ``B`` (c, n), storing ``cap``
        residuals per block: a :class:`~shapeflow.linalg.multishift.NumpySeed` (its first pass and the
        replays of later blocks)."""
        from .multishift import NumpySeed

        return NumpySeed(A, B, seed, cap, coef)

    def shifted_powers(self, A, seed: float, Y: np.ndarray, degree: int, out: list | None = None,
                       take: np.ndarray | None = None, scale: np.ndarray | None = None) -> list:
        """``[Y, A₀ Y, …, A₀^degree Y]`` for ``Y`` (n, r) and A₀ = A + seed I (the solutions of
        :func:`~shapeflow.linalg.multishift.multishift_cg`'s polynomial preconditioner), each row s times
        ``scale[s]`` and the rows then taken by ``take`` (None: as they are): ``(scale · power)[take]``,
        each (·, r), ``Y`` itself left as it is.  ``out``: memory to use, up to ``degree + 2`` arrays
        (the powers' of their shape, column slices of one wider array allowed; the last one, scratch,
        C-contiguous of Y's shape); a power is returned in its ``out`` array where the shapes agree;
        what the list lacks is allocated."""
        res = [np.ascontiguousarray(Y)]
        for _ in range(degree):
            res.append(np.ascontiguousarray(np.asarray(A @ res[-1]) + seed * res[-1]))
        if scale is not None:
            res = [P * scale[:, None] for P in res]
        if take is not None:
            res = [P[take] for P in res]
        for i in range(min(len(out or []), degree + 1)):
            if out[i].shape == res[i].shape:
                out[i][...] = res[i]
                res[i] = out[i]
        if res[0] is Y:
            res[0] = Y.copy()
        return res

    def weighted_col_norms(self, A, c: np.ndarray, Y: np.ndarray) -> np.ndarray:
        """sqrt(Σ_i c_i Y_ij²) of each column of Y (the Chebyshev expansion's C-norms; ``A`` is its matrix)."""
        return np.sqrt(np.einsum("i,ij,ij->j", c, Y, Y))

    def clenshaw_step(self, A, cinv, B1, B2, X0, H0, f, alpha, beta, cuj, chj) -> None:
        """One step of :func:`~shapeflow.linalg.chebyshev.chebyshev_steps`, in place:
        B2 <- f·(α C⁻¹ A B1 − β B1) − B2 + cuj X0 + chj H0."""
        AB = A @ B1
        B2 *= -1.0
        B2 += f * (alpha * cinv[:, None] * AB - beta * B1) + cuj * X0 + chj * H0


def sgs_cg(solver, B: np.ndarray, X0: np.ndarray | None, squeeze: bool):
    """The symmetric Gauss–Seidel PCG of ``compiled.sgs_pcg3`` with SciPy's triangular solves
    (its NumPy twin: the same formulas, (n, k) layout); returns (X, converged, B)."""
    from scipy.sparse.linalg import spsolve_triangular

    solver.stats.preconditioner = "sgs"
    A = solver.csr()
    n = A.shape[0]
    Bn = B[:, None] if squeeze else B
    X = np.zeros(Bn.shape) if X0 is None else np.array(np.asarray(X0, dtype=np.float64).reshape(Bn.shape))
    d = solver.diagonal[:, None]
    E = sp.tril(A, 0, format="csr")
    F = sp.triu(A, 0, format="csr")
    U = sp.triu(A, 1, format="csr")
    R = spsolve_triangular(E, Bn - U @ X, lower=True) - X     # r̂0 = E⁻¹(b − U x0) − x0
    P = d * R
    rz = np.einsum("ij,ij->j", R, R * d)
    tol2 = (solver.rtol ** 2) * rz
    maxiter = solver.iteration_cap(n)
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
    solver.stats.iterations = it
    converged = not (rz > tol2).any() and bool(np.all(np.isfinite(X)))
    return (X[:, 0] if squeeze else X), converged, B


class LocalKernels(Family):
    """Kernels of the brush's small SPD systems (every size: a dab's system is small whatever the mesh)."""

    family = "local"
    min_size = 0

    def local_order(self, k: int, ri, ci, grouped: bool = True):
        """A narrow-band order of the k unknowns of the entries (ri, ci): ``(perm, inverse)``
        (:func:`shapeflow.linalg.ordering.local_order` says which), by scipy's graph searches."""
        from scipy.sparse.csgraph import breadth_first_order, reverse_cuthill_mckee

        # float64 data: the graph routines would otherwise convert (copy) it
        if grouped:
            ptr = row_ptr(ri, k, np.int32)
            G = sp.csr_matrix((np.ones(ri.size), ci.astype(np.int32), ptr), shape=(k, k))
        else:
            G = sp.csr_matrix((np.ones(ri.size), (ri, ci)), shape=(k, k))
        o = breadth_first_order(G, 0, directed=True, return_predecessors=False)
        if o.size == k:
            perm = breadth_first_order(G, int(o[-1]), directed=True, return_predecessors=False).astype(np.int64)
            perm2 = breadth_first_order(G, int(perm[-1]), directed=True, return_predecessors=False).astype(np.int64)
            return narrower(k, ri, ci, perm, perm2)
        perm = reverse_cuthill_mckee(G, symmetric_mode=True).astype(np.int64)
        inv = np.empty(k, np.int64)
        inv[perm] = np.arange(k)
        return perm, inv

    def split_solve(self, solver, k: int, ri, ci, vi, diag, rhs, notes: list | None = None):
        """The system solved as two banded halves and their separator (``LocalSolver.split``):
        ``(X, "split", band)``, or None where it does not apply — here always (the split solve
        factors the halves on two threads, which NumPy cannot)."""
        return None
