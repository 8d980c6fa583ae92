"""The sculpt layer: real-time local brushes.

* :class:`Brush` — the shape-enhancement brush of section 4.3 (one implicit
  flow step restricted to the vertices in a sphere), built from
  :mod:`~shapeflow.sculpt.base` (state, queries, undo, strokes),
  :mod:`~shapeflow.sculpt.cotan_cache` (the incremental cotangent cache) and
  :mod:`~shapeflow.sculpt.dab` (a dab's region and system, solved by
  :class:`shapeflow.linalg.LocalSolver`);
* :class:`InflateBrush` — the inflate baseline of figure 9;
* :mod:`~shapeflow.sculpt.grid` (spatial index), :mod:`~shapeflow.sculpt.numbering`
  (internal vertex order), :mod:`~shapeflow.sculpt.stroke` (falloff, strokes).
"""

from ..linalg.blas import FALLBACKS
from .base import Dab
from .brush import BRUSH_SOLVERS, Brush
from .inflate import InflateBrush
from .stroke import FALLOFFS, resample_polyline

__all__ = ["Brush", "InflateBrush", "Dab", "FALLOFFS", "BRUSH_SOLVERS", "FALLBACKS", "resample_polyline"]
