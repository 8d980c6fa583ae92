"""The flow's kernel family: the interior system, its couplings, the Chebyshev bound and gathers (NumPy reference).

The numba implementation is :class:`shapeflow.flow.compiled.FlowNumba`; :func:`shapeflow.accel.kernels`
chooses (``accel.kernels("flow", n_vertices)``).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..accel import Family

__all__ = ["FlowKernels"]


def no_coupling():
    """No pair with one free end: ``(free ends, other ends, weights)``, all empty."""
    return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)


class FlowKernels(Family):
    """Kernels of the flow's interior system (:class:`~shapeflow.flow.system.SystemBuilder`) and steps."""

    family = "flow"
    #: whether :meth:`interior_diag` serves the lean layout (CG on a
    #: :class:`~shapeflow.linalg.pairs.PairMatrix`, no CSR arrays; ``flow.system.LEAN_FROM``): its
    #: products and CG are the compiled ones, so not here
    lean_layout = False

    def interior_matrix(self, pattern, free: np.ndarray, c: np.ndarray, deg: np.ndarray, pw: np.ndarray):
        """The interior system's matrix on the operator's ``pattern``: ``(A, diagonal, mixed, ratio)``.

        Free rows: c + D on the diagonal, −w_ij where both ends are free; other rows are identity
        rows.  ``mixed``: the numbers of pairs with only their first / only their second end free
        (None when not counted: :meth:`interior_coupling` finds them); ``ratio``: max |D/c| over
        the free rows (|D| where c = 0), for the condition estimate.
        """
        p0, p1 = pattern.pairs[:, 0], pattern.pairs[:, 1]
        both = free[p0] & free[p1]
        diag = np.where(free, c + deg, 1.0)
        A = pattern.matrix(diag, np.where(both, -pw, 0.0))
        ratio = float(np.max(np.abs(deg[free] / np.where(c[free] != 0, c[free], 1.0))))
        return A, diag, None, ratio

    def interior_diag(self, pairs: np.ndarray, free: np.ndarray, c: np.ndarray, deg: np.ndarray, pw: np.ndarray):
        """:meth:`interior_matrix` without the matrix (the lean layout): ``(diagonal, mixed, ratio)``."""
        diag = np.where(free, c + deg, 1.0)
        fa, fb = free[pairs[:, 0]], free[pairs[:, 1]]
        mixed = (int(np.count_nonzero(fa & ~fb)), int(np.count_nonzero(fb & ~fa)))
        ratio = float(np.max(np.abs(deg[free] / np.where(c[free] != 0, c[free], 1.0)), initial=0.0))
        return diag, mixed, ratio

    def interior_coupling(self, pairs: np.ndarray, free: np.ndarray, pw: np.ndarray, mixed):
        """The pairs with exactly one free end: ``(free end, other end, weight)``, first the pairs whose
        first end is free, then the others, each group in pair order (their terms go to the
        right-hand side).  ``mixed``: the counts from :meth:`interior_matrix` (None: not counted)."""
        if mixed is not None and not sum(mixed):
            return no_coupling()
        p0, p1 = pairs[:, 0], pairs[:, 1]
        a = free[p0] & ~free[p1]
        b = free[p1] & ~free[p0]
        return np.concatenate([p0[a], p1[b]]), np.concatenate([p1[a], p0[b]]), np.concatenate([pw[a], pw[b]])

    def scaled_abs_row_max(self, A, s: np.ndarray, free: np.ndarray) -> float:
        """max over the ``free`` rows (those with s_i > 0) of s_i Σ_j |a_ij| s_j: a Gershgorin bound of S A S."""
        absA = sp.csr_matrix((np.abs(A.data), A.indices, A.indptr), shape=A.shape)
        return float((s * (absA @ s))[free].max())

    def take(self, a: np.ndarray, idx: np.ndarray) -> np.ndarray:
        """``a[idx]`` (rows of a 1-D or (n, 3) array; indices >= 0)."""
        return a.take(idx, axis=0)

    def take_free(self, V: np.ndarray, perm: np.ndarray, free: np.ndarray, out: np.ndarray) -> None:
        """out[i] = V[perm[i]] where free[perm[i]], else 0 (rows of (n, 3) arrays)."""
        np.copyto(out, np.where(free.take(perm)[:, None], V.take(perm, axis=0), 0.0))

    def untake_free(self, Y: np.ndarray, inv: np.ndarray, free: np.ndarray, V: np.ndarray, out: np.ndarray) -> None:
        """out[v] = Y[inv[v]] where free[v], else V[v] (rows of (n, 3) arrays)."""
        np.copyto(out, np.where(free[:, None], Y.take(inv, axis=0), V))

    def max_row_distance(self, A: np.ndarray, B: np.ndarray, chunk: int = 4096) -> float:
        """max_i |A_i − B_i| over the rows of two (n, 3) arrays, in chunks small enough for malloc to
        reuse (no fresh pages)."""
        best = 0.0
        for s in range(0, A.shape[0], chunk):
            d = A[s:s + chunk] - B[s:s + chunk]
            best = max(best, float(np.einsum("ij,ij->i", d, d).max()))
        return float(np.sqrt(best))
