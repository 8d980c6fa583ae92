"""shapeflow: smoothing and shape enhancement of hybrid polygon meshes.

The Laplace–Beltrami operator for hybrid quad/triangle meshes (TQLBO) and the
implicit curvature flow of "Shape Enhanced With an Adapted Laplacian Operator
For Hybrid Quad/Triangle Meshes", extended to n-gons, with a Blender-compatible
mode.  Sign convention throughout: Laplacians are positive semi-definite
(L = D − W, normalised L = I − D⁻¹W).
"""

from .errors import MeshError, OptionalDependencyError, ParameterError, ShapeflowError
from .mesh import WEIGHT, Diagnostics, Mesh, Topology, concatenate, normalize_faces

__version__ = "0.1.0"

__all__ = [
    "Mesh", "Topology", "Diagnostics", "normalize_faces", "concatenate", "WEIGHT",
    "MeshError", "ParameterError", "ShapeflowError", "OptionalDependencyError",
]
