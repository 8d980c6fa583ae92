"""Options shared by the flow, the solver object and families: modes, limits and their validation."""

from __future__ import annotations

import numpy as np

from .. import params
from ..errors import ParameterError
from ..linalg.spd import METHODS

__all__ = ["COMPAT_MODES", "UPDATES", "FLOW_SOLVERS", "MEAN_RESTORE_FROM", "ITERATIONS_MAX", "check_run_options"]


COMPAT_MODES = (None, "paper", "blender")


UPDATES = ("fixed", "recompute")


FLOW_SOLVERS = (*METHODS, "chebyshev")


#: From this |λ| on, the solution's conserved means are restored after each solve
#: (:meth:`LinearSystem.restore_means`); below it the solvers' own accuracy is far below ``rtol``.
MEAN_RESTORE_FROM = 1e6


#: The most implicit steps one call takes (k steps of λ move about as far as one step of kλ).
ITERATIONS_MAX = 100_000


def check_run_options(iterations, update, axes, blender: bool) -> np.ndarray:
    """Validate the per-run options of the flow; returns the axes mask."""
    params.integer("iterations", iterations, lo=0, hi=ITERATIONS_MAX)
    if not isinstance(update, str) or update not in UPDATES:
        raise ParameterError(f"update must be 'fixed' or 'recompute', got {update!r}")
    if blender and update != "fixed":
        raise ParameterError("compat='blender' keeps the operator of the first iteration (update='fixed')")
    return params.axes(axes)
