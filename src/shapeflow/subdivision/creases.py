"""Semi-sharp creases for Catmull–Clark subdivision: what ``subdivide(..., creases=...)`` accepts.

Creases are given in Blender's convention, a value c in [0, 1] per edge (the ``crease_edge``
attribute); Blender hands OpenSubdiv the sharpness 10·c² (``crease_to_sharpness``), and a
sharpness of 10 or more (c = 1) is infinitely sharp.  ``creases="mesh"`` takes the creases a mesh
carries: ``mesh.creases`` of a subdivision result (the halves of each creased edge, one level
down), else the OpenSubdiv ``t crease`` tags of an OBJ file, whose values are sharpness already.
"""

from __future__ import annotations

from typing import Sequence, Union

import numpy as np
from numpy.typing import ArrayLike

from .. import params
from ..errors import ParameterError
from ..geometry.features import edge_ids, file_creases
from .rules import INF, SHARPNESS_INFINITE, crease_sharpness

__all__ = ["Creases", "resolve_creases"]

#: creases: None, "mesh", or (edges (k, 2) vertex pairs, values: one in [0, 1] or (k,))
Creases = Union[None, str, Sequence[ArrayLike]]


def resolve_creases(mesh, creases) -> np.ndarray | None:
    """(E,) sharpness (OpenSubdiv units, inf for infinitely sharp) of the edges of ``mesh.topology``,
    or None for no creases.  An edge listed twice takes its largest value."""
    if creases is None:
        return None
    if isinstance(creases, str):
        if creases != "mesh":
            raise ParameterError(f"creases must be (edges, values) or 'mesh', got {creases!r}")
        carried = getattr(mesh, "creases", None)
        if carried is not None:
            pairs, values = carried
            sharp = crease_sharpness(values)
        else:
            pairs, sharp = file_creases(mesh)
            sharp = np.where(sharp >= SHARPNESS_INFINITE, INF, sharp)
        name = "creases='mesh'"
    else:
        if not isinstance(creases, (tuple, list)) or len(creases) != 2:
            raise ParameterError("creases must be a pair (edges (k, 2), values (k,)) or 'mesh'")
        pairs, values = creases
        name = "creases"
        values = params.real_array("creases values", values).reshape(-1) if np.ndim(values) else \
            params.real_array("creases values", [values])
        k = np.shape(pairs)[0] if np.ndim(pairs) == 2 else -1
        if k >= 0 and values.size == 1 and k != 1:
            values = np.full(k, values[0])            # one value for every edge
        if k >= 0 and values.size != k:
            raise ParameterError(f"creases: {k} edges but {values.size} values")
        bad = np.flatnonzero(~np.isfinite(values) | (values < 0) | (values > 1))
        if bad.size:
            i = int(bad[0])
            raise ParameterError(f"creases: value {i} is {float(values[i])!r}; Blender's creases lie in [0, 1]")
        sharp = crease_sharpness(values)
    t = getattr(mesh, "topology", mesh)
    ids = edge_ids(mesh, pairs, name)
    out = np.zeros(t.n_edges)
    np.maximum.at(out, ids, np.asarray(sharp, dtype=np.float64))
    return out
