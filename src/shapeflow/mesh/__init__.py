"""The mesh layer: the immutable hybrid polygon :class:`Mesh`, its :class:`Topology`, and input validation.

Faces are CSR inside (``face_indices`` + ``face_offsets``, the layout of
Blender loops, VTK cells and libigl's polygon arrays); lists and (m, k) arrays
are accepted only at this boundary (:func:`normalize_faces`).
"""

from .core import Mesh, concatenate
from .topology import Diagnostics, Topology
from .validate import normalize_faces
from .weights import WEIGHT

__all__ = ["Mesh", "Topology", "Diagnostics", "normalize_faces", "concatenate", "WEIGHT"]
