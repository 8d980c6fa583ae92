"""LAPACK banded Cholesky for small SPD systems given by their upper entries."""

from __future__ import annotations

import numpy as np

from .blas import SingleThreadBLAS

__all__ = ["BANDED_MAX_WORK", "BLOCKED_BAND", "lapack_band", "banded_cholesky"]


#: banded Cholesky is used while (unknowns × bandwidth²) stays below this
#: (about 10 ms of LAPACK dpbtrf on the reference machine); beyond, a sparse
#: factorisation wins.
BANDED_MAX_WORK = 6e7


#: bands from ``BLOCKED_BAND[0]`` to ``BLOCKED_BAND[1] - 1`` are padded (with zeros) to
#: ``BLOCKED_BAND[1]``: LAPACK's dpbtrf runs its unblocked (level-2) code for bands up to its
#: block size, 64 in the OpenBLAS LAPACK SciPy ships, and the blocked code from 65.  Measured
#: (2,400 unknowns): band 63 ~1.9-2.9 ms, the same system padded to 65 ~1.5-2.0 ms, despite the
#: 6% more flops; below ~56 the unblocked code's lower flop count wins.
BLOCKED_BAND = (56, 65)


def lapack_band(bw: int, k: int) -> int:
    """The band to give LAPACK for a band-``bw`` system of ``k`` unknowns (see BLOCKED_BAND)."""
    return BLOCKED_BAND[1] if BLOCKED_BAND[0] <= bw < BLOCKED_BAND[1] and k > BLOCKED_BAND[1] else bw


def banded_cholesky(work, k: int, ru, cu, vu, diag, rhs, bw: int):
    """Solve a k×k SPD system with LAPACK's banded Cholesky (dpbsv), or None if it is not
    numerically positive definite.

    The system is given by its upper entries (``ru < cu``, values ``vu``),
    its diagonal and right-hand sides ``rhs`` (k, c); ``bw`` is the band to
    store (:func:`lapack_band`).  It is stored as the lower triangle (a
    little faster than the upper storage in dpbtrf, ~10%) in ``work(size)``,
    a caller's reusable buffer (fresh memory costs page faults: ~0.35 ms of a
    2,600-unknown dab's ~2.4 ms solve).  LAPACK runs on one BLAS thread.
    """
    from scipy.linalg.lapack import dpbsv

    abf = work((bw + 1) * k)
    abf.fill(0.0)
    ab = abf.reshape((bw + 1, k), order="F")  # entry (i, j) at i + (bw + 1) j
    abf[(cu - ru) + (bw + 1) * ru] = vu       # lower band storage: ab[i - j, j] = a_ij (i >= j)
    ab[0] = diag
    B = np.asfortranarray(rhs)
    with SingleThreadBLAS():
        _, X, info = dpbsv(ab, B, lower=1, overwrite_ab=1, overwrite_b=1)
    if info != 0:
        return None
    return np.ascontiguousarray(X)
