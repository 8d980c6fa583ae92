"""The numba accelerator (the ``fast`` extra): every kernel family compiled.

Each family's numba implementation is a subclass of its NumPy/SciPy reference at the end of
the package's ``compiled`` module (the kernels themselves are the ``@njit`` functions above
it).  Importing this module imports neither numba nor those modules: the registry loads an
implementation when it first runs.
"""

from __future__ import annotations

from . import apply_call_threads, numba_usable
from .registry import Accelerator

__all__ = ["NUMBA"]

NUMBA = Accelerator(
    name="numba",
    available=numba_usable,
    families={
        "mesh": "shapeflow.mesh.compiled:MeshNumba",
        "geometry": "shapeflow.geometry.compiled:GeometryNumba",
        "operators": "shapeflow.operators.compiled:OperatorNumba",
        "linalg": "shapeflow.linalg.compiled:LinalgNumba",
        "local": "shapeflow.linalg.compiled_split:LocalNumba",
        "flow": "shapeflow.flow.compiled:FlowNumba",
        "sculpt": "shapeflow.sculpt.compiled:SculptNumba",
    },
    activate=apply_call_threads,   # numba may have been imported just now, inside a heavy call
)
