"""The linear-algebra layer: every solver shapeflow uses, for the systems the flow and the brush build.

* :mod:`~shapeflow.linalg.spd` — :class:`SPDSolver` (CG preconditioned by
  symmetric Gauss–Seidel or Jacobi, sparse Cholesky, SuperLU) with the cost
  model that picks one;
* :mod:`~shapeflow.linalg.chebyshev` — several fixed-operator steps as one
  Chebyshev expansion;
* :mod:`~shapeflow.linalg.pairs` — :class:`PairMatrix`, a symmetric matrix as its diagonal and
  vertex pairs (the lean layout of very large systems);
* :mod:`~shapeflow.linalg.multishift` — multi-shift CG (a family of shifted
  systems from one Krylov space), with the polynomial preconditioner of
  :mod:`~shapeflow.linalg.shift_polynomial` that keeps them shifts of one operator;
* :mod:`~shapeflow.linalg.local` — :class:`LocalSolver` for streams of small
  SPD systems (banded, split, sparse), with :mod:`~shapeflow.linalg.banded`,
  :mod:`~shapeflow.linalg.ordering` and the BLAS thread control of
  :mod:`~shapeflow.linalg.blas`.

Kernel families (:mod:`~shapeflow.linalg.kernels`): ``"linalg"`` (CG, Clenshaw step) and ``"local"``
(the small systems' orders and split solve); numba implementations in :mod:`~shapeflow.linalg.compiled`
and :mod:`~shapeflow.linalg.compiled_split`.
"""

from .chebyshev import chebyshev_coefficients, chebyshev_steps
from .local import LocalSolver
from .multishift import MultiShiftResult, multishift_cg
from .pairs import PairMatrix
from .spd import DEFAULT_RTOL, METHODS, PRECONDITIONERS, SolveStats, SPDSolver, cholesky_available, choose_method

__all__ = ["SPDSolver", "SolveStats", "METHODS", "PRECONDITIONERS", "DEFAULT_RTOL", "choose_method",
           "cholesky_available", "chebyshev_coefficients", "chebyshev_steps", "multishift_cg", "MultiShiftResult",
           "LocalSolver", "PairMatrix"]
