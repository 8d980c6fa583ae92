"""Per-vertex weights W_p: the one check (one finite value in [0, 1] per vertex) and where they come from.

Every entry point that takes weights checks them here: the ``"weight"``
attribute of a :class:`~shapeflow.mesh.Mesh` (:func:`~shapeflow.mesh.validate.as_attribute`),
the ``weights`` of the flow, the brushes and the studio (:func:`resolve_weights`: None, an
attribute's name or an array), and weight files (:func:`shapeflow.io.load_weights`, which reads
``.npy`` and ``.txt`` and hands the values here).  A message names the parameter, attribute or
file, and the first offending vertex (with the file's line when there is one).

>>> check_weights("weights", np.array([0.0, 0.5, 1.5]), 3)
Traceback (most recent call last):
...
shapeflow.errors.MeshError: weights must lie in [0, 1]; vertex 2 has 1.5 (1 such vertices)
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Callable

import numpy as np

from .. import params
from ..errors import MeshError, ParameterError

if TYPE_CHECKING:
    from .core import Mesh

__all__ = ["WEIGHT", "check_weights", "resolve_weights"]


#: Name of the per-vertex weight attribute (values in [0, 1]).
WEIGHT = "weight"


def check_weights(name: str, w: np.ndarray, n: int, where: Callable[[int], str] | None = None, *,
                  error: type[ValueError] = MeshError) -> np.ndarray:
    """``w`` (float64) checked as the weights of ``n`` vertices: shape (n,), finite, in [0, 1]; returns it.

    ``name`` is the parameter, or the file the values were read from; ``where(i)`` then says
    where vertex i's value is in it (``"line 7"``, ``"value 7"``) and the messages take the
    file's form.  Raises ``error`` (:class:`MeshError` for files and mesh attributes,
    :class:`ParameterError` for parameters), naming the first offending vertex.
    """
    if w.ndim != 1 or w.shape[0] != n:
        if where is not None and w.ndim == 1:
            raise error(f"{name}: has {w.shape[0]} weights but the mesh has {n} vertices")
        raise error(f"{name} must have shape ({n},) (one per vertex), got {w.shape}")
    if where is None:
        bad = np.flatnonzero(~np.isfinite(w) | (w < 0) | (w > 1))
        if bad.size:
            i = int(bad[0])
            raise error(f"{name} must lie in [0, 1]; vertex {i} has {float(w[i])!r} ({bad.size} such vertices)")
        return w
    bad = np.flatnonzero(~np.isfinite(w))
    if bad.size:
        i = int(bad[0])
        raise error(f"{name}: {where(i)}: weight of vertex {i} is not finite ({float(w[i])!r})")
    bad = np.flatnonzero((w < 0) | (w > 1))
    if bad.size:
        i = int(bad[0])
        raise error(f"{name}: {where(i)}: weight of vertex {i} is {float(w[i])!r}, outside [0, 1] "
                    f"({bad.size} such values)")
    return w


def resolve_weights(mesh: Mesh, weights, invert: bool = False) -> np.ndarray:
    """Per-vertex weights (a new float64 array) from None (all 1), an attribute's name or an array;
    ``invert``: 1 − w.  Raises :class:`ParameterError` naming the parameter or the attribute."""
    n = mesh.n_vertices
    if weights is None:
        w = np.ones(n)
    elif isinstance(weights, str):
        if weights not in mesh.attributes:
            have = ", ".join(mesh.attributes) or "none"
            raise ParameterError(f"the mesh has no attribute '{weights}' (attributes: {have})")
        w = check_weights(f"weights (attribute '{weights}')", np.asarray(mesh.attributes[weights], dtype=np.float64),
                          n, error=ParameterError)
    else:
        w = check_weights("weights", params.real_array("weights", weights), n, error=ParameterError)
    return 1.0 - w if invert else w.copy()
