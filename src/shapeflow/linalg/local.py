"""Solver of small sparse SPD systems solved one after another (the sculpt brush's dabs).

:class:`LocalSolver` picks, per system, from:

* ``"split"`` (``"auto"`` from :data:`SPLIT_MIN` unknowns, with the compiled
  kernels on two threads): the unknowns in Cuthill–McKee level order, cut at
  the middle level into two banded halves that LAPACK factors at the same
  time (one per thread) and a separator solved through its dense Schur
  complement (1.1–2.3 ms against 1.6–3.8 ms for one band on captured
  2,400-unknown dab systems);
* ``"banded"``: LAPACK's banded Cholesky on one BLAS thread, after a local
  reordering (:func:`~shapeflow.linalg.ordering.local_order`) when the band
  of the given order is much wider than that usually gives (about
  1.2·sqrt(k) for k unknowns);
* ``"cholesky"`` (cholespy) or ``"lu"`` (SuperLU) for systems too large for
  a band.

Measured on a 2-core machine shared with other jobs, for systems of real
dabs (``benchmarks/bench_brush.py --solvers``), median solve times at ~700 /
~1,600 / ~2,400 unknowns: banded 0.4–0.8 / 1.3–1.9 / 2.3–4.4 ms, SuperLU
1.8–2.5 / 3.8–4.3 / 6.5–8.4 ms, cholespy 1.9–3.4 / 5.2–5.8 / 9–12 ms (the
symbolic analysis dominates at these sizes), dense Cholesky 5–90 / 40–95 /
135–160 ms.

Thread model: one solve at a time per object (it reuses one work buffer);
its owner serialises the calls.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .. import accel
from .banded import BANDED_MAX_WORK, banded_cholesky, lapack_band
from .ordering import LOCAL_RCM_WORK, local_order

__all__ = ["LOCAL_METHODS", "SPLIT_MIN", "LocalSolver", "csr"]

LOCAL_METHODS = ("auto", "banded", "lu", "cholesky")

#: from this many unknowns, "auto" solves with the split solver (two banded halves on two threads)
SPLIT_MIN = 1000

#: largest work space (doubles) kept between solves (16 MB)
WORK_KEEP = 2_000_000


class LocalSolver:
    """Solves a stream of small SPD systems, reusing its work space.

    Parameters
    ----------
    method : {"auto", "banded", "lu", "cholesky"}
    """

    def __init__(self, method: str = "auto"):
        self.method = method
        self._work_buf = None

    def work(self, size: int) -> np.ndarray:
        """``size`` doubles of work space, reused solve after solve when not too large
        (fresh memory costs page faults: ~0.35 ms of a 2,600-vertex dab's ~2.4 ms solve)."""
        buf = self._work_buf
        if buf is None or buf.size < size:
            buf = np.empty(size)
            if size <= WORK_KEEP:
                self._work_buf = buf
        return buf[:size]

    def solve(self, k: int, ri, ci, vi, diag, rhs, *, grouped: bool = True, notes: list | None = None):
        """Solve the system with off-diagonal entries (ri, ci, vi) — both triangles,
        rows grouped in increasing order when ``grouped`` — and diagonal ``diag``.

        Returns ``(X, how, band)``: the solution (k, c), the solver that ran
        and the band of the system (the wider half's for "split").  Fast paths
        that could not be taken are appended to ``notes``.
        """
        method = self.method
        if method == "auto" and grouped and k >= SPLIT_MIN:
            res = self.split(k, ri, ci, vi, diag, rhs, notes)
            if res is not None:
                return res
        up = ri < ci
        ru, cu = ri[up], ci[up]
        bw = int((cu - ru).max()) if ru.size else 0
        if method in ("auto", "banded"):
            res = self._banded(k, ri, ci, vi, up, ru, cu, bw, diag, rhs, grouped)
            if res is not None:
                return res
            method = "auto"
        if method == "cholesky" or (method == "auto" and k > 2000):
            from .spd import cholesky_available

            if cholesky_available():
                import cholespy

                A = csr(k, ri, ci, vi, diag)
                f = cholespy.CholeskySolverD(k, A.indptr.astype(np.int32), A.indices.astype(np.int32),
                                             A.data, cholespy.MatrixType.CSR)
                X = np.zeros_like(rhs)
                f.solve(np.ascontiguousarray(rhs), X)
                return X, "cholesky", bw
        from scipy.sparse.linalg import splu

        A = csr(k, ri, ci, vi, diag)
        X = splu(A.tocsc(), permc_spec="MMD_AT_PLUS_A", options=dict(SymmetricMode=True)).solve(rhs)
        return X, "lu", bw

    def _banded(self, k, ri, ci, vi, up, ru, cu, bw, diag, rhs, grouped):
        """The banded solve, reordered when that pays; None when the band is too wide
        (and "auto") or the system is not numerically positive definite."""
        perm = None
        vu = vi[up]
        # a local reordering pays when the given order's band is much wider
        # than the ~1.2 sqrt(k) it usually reaches (see LOCAL_RCM_WORK)
        if k * (bw * bw - 1.44 * k) > LOCAL_RCM_WORK and k > 2:
            p, inv = local_order(k, ri, ci, grouped)
            x, y = inv[ru], inv[cu]
            lo, hi = np.minimum(x, y), np.maximum(x, y)
            bw2 = int((hi - lo).max())
            if bw2 < bw:
                perm, bw, ru, cu = p, bw2, lo, hi
        if not (self.method == "banded" or k * bw * bw <= BANDED_MAX_WORK):
            return None
        stored = lapack_band(bw, k)   # the report keeps the true band
        if perm is None:
            X = banded_cholesky(self.work, k, ru, cu, vu, diag, rhs, stored)
        else:
            X = banded_cholesky(self.work, k, ru, cu, vu, diag.take(perm, mode="clip"),
                                rhs.take(perm, axis=0, mode="clip"), stored)
            if X is not None:
                out = np.empty_like(X)
                out[perm] = X
                X = out
        return None if X is None else (X, "banded", bw)

    def split(self, k, ri, ci, vi, diag, rhs, notes: list | None = None):
        """The system solved as two banded halves and their separator, the halves on
        two threads when there are two (compiled ``split_solve``): (X, "split", band),
        or None where it does not apply (no kernels, no LAPACK pointers, no balanced
        cut, not numerically positive definite).  The result is the same on one thread.

        Order: Cuthill–McKee levels of the largest connected component as
        :func:`~shapeflow.linalg.ordering.local_order`, cut at the level of
        its median unknown (the separator S, a dense Schur complement); the
        levels before it (CM order) and after it (reversed) are the halves,
        so only their trailing rows couple to S; other components join the
        smaller half.  Same flops as one band of the same width, but each
        thread factors half the rows.  The band reported is the wider half's.
        """
        return accel.kernels("local", k).split_solve(self, k, ri, ci, vi, diag, rhs, notes)


def csr(k: int, ri, ci, vi, diag) -> sp.csr_matrix:
    """The k×k matrix with off-diagonal entries (ri, ci, vi) and diagonal ``diag``."""
    d = np.arange(k)
    return sp.csr_matrix((np.concatenate([vi, diag]), (np.concatenate([ri, d]), np.concatenate([ci, d]))),
                         shape=(k, k))
