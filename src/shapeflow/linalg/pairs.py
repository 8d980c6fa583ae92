"""A symmetric matrix held as its diagonal and its vertex pairs: the lean layout for very large systems.

``A = diag(d) − Σ_p m_p w_p (e_a e_bᵀ + e_b e_aᵀ)`` over the pairs ``p = (a, b)``,
where ``m_p`` is 1 when both ends are free and 0 otherwise: the flow's
interior system ``C + D − W`` (D − W positive semi-definite; held rows are
identity rows) without a CSR copy.  The pairs and weights are the operator's
own arrays, so the matrix costs one diagonal (8 bytes per vertex) where a CSR
matrix with its pattern costs ~116 (the values, column indices, row pointers
and the pattern's scatter positions) — what lets a 50-million-vertex scan fit
in 24 GB.  Compiled CG runs on it directly (:func:`shapeflow.linalg.compiled.pcg3_pairs`,
a sequential scatter, ~1.8× the time of a CSR product); anything else
(direct solvers, the NumPy CG) takes :meth:`PairMatrix.tocsr`.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

__all__ = ["PairMatrix"]


class PairMatrix:
    """``diag(d) − W_free``: see the module docstring.  Read-only; shares ``pairs`` and ``weights``."""

    def __init__(self, pairs: np.ndarray, weights: np.ndarray, free: np.ndarray, diagonal: np.ndarray):
        self.pairs = pairs
        self.weights = weights
        self.free = np.ascontiguousarray(free, dtype=np.bool_)
        self.d = np.ascontiguousarray(diagonal, dtype=np.float64)
        n = self.d.size
        self.shape = (n, n)
        self.dtype = np.dtype(np.float64)
        self._csr: sp.csr_matrix | None = None

    def diagonal(self) -> np.ndarray:
        return self.d

    def _both_free(self) -> np.ndarray:
        return self.free[self.pairs[:, 0]] & self.free[self.pairs[:, 1]]

    def __matmul__(self, X: np.ndarray) -> np.ndarray:
        """A·X for a vector or an (n, k) array (NumPy: bincounts over the free pairs)."""
        X = np.asarray(X, dtype=np.float64)
        cols = X.reshape(X.shape[0], -1)
        both = self._both_free()
        a, b = self.pairs[both, 0], self.pairs[both, 1]
        w = self.weights[both]
        n = self.d.size
        out = self.d[:, None] * cols
        for k in range(cols.shape[1]):
            out[:, k] -= np.bincount(a, w * cols[b, k], minlength=n) + np.bincount(b, w * cols[a, k], minlength=n)
        return out.reshape(X.shape)

    def tocsr(self) -> sp.csr_matrix:
        """The same matrix in CSR (built once; for direct solvers and the NumPy paths)."""
        if self._csr is None:
            both = self._both_free()
            a, b = self.pairs[both, 0], self.pairs[both, 1]
            w = self.weights[both]
            n = self.d.size
            rows = np.concatenate([a, b, np.arange(n)])
            cols = np.concatenate([b, a, np.arange(n)])
            self._csr = sp.csr_matrix((np.concatenate([-w, -w, self.d]), (rows, cols)), shape=self.shape)
        return self._csr

    def tocsc(self) -> sp.csc_matrix:
        return self.tocsr().tocsc()
