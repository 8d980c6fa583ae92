"""Several implicit steps of a fixed operator at once, by one Chebyshev expansion."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .. import accel
from ..linalg.chebyshev import chebyshev_coefficients, chebyshev_steps
from ..linalg.spd import estimate_cg_iterations
from .report import FlowReport
from .system import LinearSystem

__all__ = ["fixed_steps"]


def fixed_steps(V: np.ndarray, lam: float, k: int, interior_sys: LinearSystem, axes: np.ndarray,
                report: FlowReport, pattern, rtol: float) -> np.ndarray | None:
    """All ``k`` steps of a fixed operator at once, by a Chebyshev expansion.

    With the operator fixed, no boundary step and no volume rescaling, the
    k steps are one affine map.  In u = C^½ x on the free rows, with
    S = C^-½ A C^-½ (spectrum in [1, b], b from Gershgorin) and
    h = C^-½ g (the fixed neighbours' terms), a step is
    u ← a(S) u + b(S) h with a(t) = 1/t, b(t) = 1/t for λ > 0 and
    a(t) = 2 − 1/t, b(t) = −1/t for λ < 0; so
    u_k = a(S)^k u_0 + b(S) Σ_{j<k} a(S)^j h.  Both Chebyshev series are
    summed by one Clenshaw recurrence on three columns (a sparse product
    per degree; :func:`~shapeflow.linalg.chebyshev.chebyshev_steps`), to a degree at
    which the bound on what is left is below ``rtol`` × the displacement —
    the accuracy of k CG solves, for the price of about three.  Returns None
    (iterate instead) when the expansion would cost more than iterating.
    """
    free = interior_sys.free
    A = interior_sys.A
    isq = np.zeros(V.shape[0])
    isq[free] = 1.0 / np.sqrt(interior_sys.c[free])
    # Gershgorin bound of S on the free rows (non-free rows are identity rows of A);
    # duplicate entries (a chord shared by two faces) add their |a_ij|: still a bound
    kern = accel.kernels("flow", A.shape[0])
    upper = kern.scaled_abs_row_max(A, isq, free)
    lo, hi = 1.0, max(upper, 1.0 + 1e-12)
    if lam > 0:
        fa = lambda t: 1.0 / t                     # noqa: E731
        fb = lambda t: 1.0 / t                     # noqa: E731
    else:
        fa = lambda t: 2.0 - 1.0 / t               # noqa: E731
        fb = lambda t: -1.0 / t                    # noqa: E731

    def fu(t):
        return fa(t) ** k

    def fh(t):
        at = fa(t)
        acc = np.ones_like(t)
        for _ in range(k - 1):
            acc = 1.0 + at * acc
        return fb(t) * acc

    cu, tu = chebyshev_coefficients(fu, lo, hi)
    ch, th = chebyshev_coefficients(fh, lo, hi)
    n_c = min(cu.size, ch.size)
    ok = (tu[:n_c] <= 1e-12 * np.abs(cu).sum()) & (th[:n_c] <= 1e-12 * np.abs(ch).sum())
    need = int(np.argmax(ok)) if ok.any() else 0
    if need == 0 or need > 0.5 * k * estimate_cg_iterations(hi, rtol):
        return None
    r, s_, e = interior_sys.coupling
    n = V.shape[0]
    G = np.zeros((n, 3))
    if r.size:
        for q in np.flatnonzero(axes):
            G[:, q] = np.bincount(r, e * V[s_, q], minlength=n)
    c = interior_sys.c                                      # 0 on the held rows (see _interior_system)
    # with the kernels, the expansion's sparse products in a bandwidth-reducing order:
    # same sums, in cache-friendlier order (A's data lies on the operator's pattern, as built there)
    loc = pattern.locality() if axes.all() else None
    if loc is not None:
        perm, inv, ptr, idx, src = loc
        Ap = sp.csr_matrix((kern.take(A.data, src), idx, ptr), shape=A.shape, copy=False)
        X0p = np.empty((n, 3))
        kern.take_free(V, perm, free, X0p)             # V on the free rows, 0 elsewhere, permuted
        Yp, degree = chebyshev_steps(Ap, kern.take(c, perm), X0p, kern.take(G, perm), lo, hi,
                                     (cu, tu), (ch, th), rtol, need, steps=k, overwrite_g=True)
        if Yp is None or not np.all(np.isfinite(Yp)):
            return None
        out = X0p                                   # free again: the result, fixed rows exactly V
        kern.untake_free(Yp, inv, free, V, out)
    else:
        # entries the steps may change: (n, 1) when every axis moves, else (n, 3)
        moving = free[:, None] if axes.all() else free[:, None] & axes[None, :]
        X0 = np.multiply(V, moving)                 # V on the moving entries, 0 elsewhere
        Y, degree = chebyshev_steps(A, c, X0, G, lo, hi, (cu, tu), (ch, th), rtol, need, steps=k,
                                    overwrite_g=True)
        if Y is None or not np.all(np.isfinite(Y)):
            return None
        np.copyto(Y, V, where=~moving)              # Y is ours: the fixed entries, exactly
        out = Y
    report.solver = "chebyshev"
    report.notes.append(f"{k} fixed-operator steps as one Chebyshev expansion of degree {degree} "
                        f"(spectrum bound [1, {hi:.3g}])")
    return out
