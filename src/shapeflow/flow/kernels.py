"""The flow's kernel family: the interior system, its couplings, the Chebyshev bound and gathers (NumPy reference).

The numba implementation is :class:`shapeflow.flow.compiled.FlowNumba`; :func:`shapeflow.accel.kernels`
chooses (``accel.kernels("flow", n_vertices)``).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..accel import Family

__all__ = ["FlowKernels", "MEMBER_BLOCK", "ADD_ROWS"]

#: members whose true residuals :meth:`FlowKernels.member_residuals` checks at a time (three (n, 8, c)
#: blocks; 8 measured faster than 4, 16 or 48 on Suzanne ×3: the blocks' passes stay in cache)
MEMBER_BLOCK = 8

#: vertices whose member values :meth:`FlowKernels.add_members` forms at a time (three (k, 4096) blocks)
ADD_ROWS = 4096


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

    def step_rhs(self, c: np.ndarray, V: np.ndarray, X: np.ndarray, held: np.ndarray, r: np.ndarray,
                 s: np.ndarray, e: np.ndarray) -> np.ndarray:
        """The interior system's right-hand side, a new (n, 3) array: C·V, the ``held`` rows (identity
        rows of A) X, plus Σ e·X[s] over the couplings into their rows ``r`` (summed row by row in
        coupling order, then added)."""
        rhs = c[:, None] * V          # c = 0 on held rows
        rhs[held] = X[held]
        if r.size:
            for k in range(3):
                rhs[:, k] += np.bincount(r, e * X[s, k], minlength=V.shape[0])
        return rhs

    def step_result(self, X: np.ndarray, V: np.ndarray, factor: np.ndarray | None, flip: bool, axes: np.ndarray,
                    out: np.ndarray) -> int:
        """A step's new positions ``out = V + f·(X − V)`` (``out`` may be X): rows of X with a non-finite
        value count as V; f = ``factor`` per row (±1) when given, else −1 with ``flip``, else 1; 0 on
        the axes not in ``axes``.  Returns the number of non-finite rows."""
        n_bad = 0
        if not np.all(np.isfinite(X)):
            bad = ~np.isfinite(X).all(axis=1)
            n_bad = int(bad.sum())
            if out is not X:
                X = X.copy()
            X[bad] = V[bad]
        d = np.subtract(X, V, out=out)
        if factor is not None:
            d *= factor[:, None]
        elif flip:
            np.negative(d, out=d)
        if not axes.all():
            d[:, ~axes] = 0.0
        np.add(V, d, out=d)
        return n_bad

    def member_residuals(self, As, R0: np.ndarray, out: np.ndarray, base: np.ndarray, inv_scale: np.ndarray,
                         cols: np.ndarray, members: np.ndarray, signs: np.ndarray, deltas: np.ndarray,
                         spare: list = ()):
        """True residuals of a family's members in the shared solve's scaled system: ``(res, ynorm)``,
        both (members, c) with c = ``cols.size``.

        For member ``members[q]`` and column t: y = ``signs[q]`` (out[m][:, cols[t]] − base[:, cols[t]]) ·
        ``inv_scale`` (its displacement Δ read back from the positions, times C_1^{1/2}), ``ynorm`` = ‖y‖ and
        ``res`` = ‖(As + ``deltas[q]`` I) y − R0[t]‖; ``As`` (n, n) CSR and ``R0`` (c, n) in the mesh's order,
        ``base`` (n, 3).  A non-finite position gives a non-finite residual.  Blocks of
        :data:`MEMBER_BLOCK` members: one sparse product per block (``shifted_residuals``).  ``spare``: flat
        float64 buffers the compiled kernel takes its scratch from (:class:`~shapeflow.linalg.spare.Spare`).
        """
        from ..linalg.multishift import shifted_residuals

        n, c = base.shape[0], cols.size
        base_c = np.ascontiguousarray(base[:, cols])
        inv = np.repeat(inv_scale, c).reshape(n, c)
        res = np.empty((members.size, c))
        ynorm = np.empty((members.size, c))
        for s0 in range(0, members.size, MEMBER_BLOCK):
            ms = members[s0:s0 + MEMBER_BLOCK]
            D = np.empty((ms.size, n, c))                        # ±Δ, contiguous rows
            for q, m in enumerate(ms):                           # (members, not vertices)
                np.subtract(out[m][:, cols], base_c, out=D[q])
                if signs[s0 + q] < 0:
                    np.negative(D[q], out=D[q])
            D *= inv
            # (n, q, c) for one sparse product over all members: the (n, c) rows moved as single items
            Y = np.ascontiguousarray(D.view(np.dtype((np.void, 8 * c))).reshape(ms.size, n).T)
            Y = Y.view(np.float64).reshape(n, ms.size, c)
            res[s0:s0 + ms.size], ynorm[s0:s0 + ms.size] = shifted_residuals(As, R0, deltas[s0:s0 + ms.size], Y)
        return res, ynorm

    def add_members(self, out: np.ndarray, base: np.ndarray, cols: np.ndarray, members: np.ndarray,
                    shift_of: np.ndarray, signs: np.ndarray, lefts: list, Ws: list, k: int) -> np.ndarray:
        """Members from the low-rank factors of a multi-shift solve: for each listed member m (shift
        q = ``shift_of`` of it), ``out[m] = base`` and, for column t, ``out[m][:, cols[t]] += signs ·
        (lefts[t][q] @ Ws[t]ᵀ)`` (``lefts[t]`` (k, r_t); ``Ws[t]`` (n, r_t) vertex-major, or a tuple of
        (n, ·) pieces side by side; the solution columns already scaled and in the mesh's order).  Returns (k,)
        bool: whether every value of shift q's solution was finite (True for a shift without a listed
        member).  The values are formed :data:`ADD_ROWS` vertices at a time (the factor's rows of the
        block gathered side by side), one GEMM per column on one thread into a block that stays in
        cache, and written by :meth:`scatter_members`."""
        from ..linalg.multishift import gemm

        n, c = out.shape[1], cols.size
        finite = np.ones(k, bool)
        width = min(n, ADD_ROWS)
        rows = np.empty((c, k, width))
        lefts = [np.ascontiguousarray(L) for L in lefts]
        pieces = [W if isinstance(W, tuple) else (W,) for W in Ws]
        parts = [None if len(P) == 1 else np.empty((width, L.shape[1])) for L, P in zip(lefts, pieces)]
        for i0 in range(0, n, ADD_ROWS):                           # (blocks of vertices)
            w = min(n, i0 + ADD_ROWS) - i0
            for t in range(c):
                if len(pieces[t]) == 1:                             # (its rows i0 … i0 + w − 1: contiguous)
                    gemm(lefts[t], np.ascontiguousarray(pieces[t][0][i0:i0 + w]), rows[t, :, :w], trans_b=True)
                    continue
                o = 0
                for P in pieces[t]:                                 # the block's rows side by side
                    parts[t][:w, o:o + P.shape[1]] = P[i0:i0 + w]
                    o += P.shape[1]
                gemm(lefts[t], parts[t][:w], rows[t, :, :w], trans_b=True)
            finite &= self.scatter_members(out, base, cols, i0, rows[:, :, :w], members, shift_of, signs)
        return finite

    def scatter_members(self, out: np.ndarray, base: np.ndarray, cols: np.ndarray, i0: int, rows: np.ndarray,
                        members: np.ndarray, shift_of: np.ndarray, signs: np.ndarray) -> np.ndarray:
        """For every listed member m = ``members[p]``, rows i0 … i0 + w − 1 of ``out[m]`` become those of
        ``base`` plus ``signs[p] · rows[t, shift_of[p]]`` in column ``cols[t]`` (``rows`` (c, k, w));
        returns (k,) bool: whether every value of each shift's rows was finite (True for a shift without a
        listed member)."""
        w = rows.shape[2]
        for m, q, sg in zip(members, shift_of, signs):             # (members, not vertices)
            block = out[m, i0:i0 + w]
            block[:] = base[i0:i0 + w]
            for t, j in enumerate(cols):
                if sg >= 0:
                    block[:, j] += rows[t, q]
                else:
                    block[:, j] -= rows[t, q]
        finite = np.ones(rows.shape[1], bool)
        finite[shift_of] = np.isfinite(rows[:, shift_of]).all(axis=(0, 2))
        return finite

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
