"""shapeflow: smoothing and shape enhancement of hybrid polygon meshes.

The Laplace–Beltrami operator for hybrid quad/triangle meshes (TQLBO) and the
implicit curvature flow of "Shape Enhanced With an Adapted Laplacian Operator
For Hybrid Quad/Triangle Meshes", extended to n-gons, with a Blender-compatible
mode.  Sign convention throughout: Laplacians are positive semi-definite
(L = D − W, normalised L = I − D⁻¹W).

Only numpy and scipy are imported eagerly; I/O, subdivision and the optional
extras load on first use.
"""

from .errors import DataLossWarning, MeshError, OptionalDependencyError, ParameterError, ShapeflowError
from .flow import FlowReport, FlowSolver, enhance, flow, smooth
from .mesh import WEIGHT, Diagnostics, Mesh, Topology, concatenate, normalize_faces
from .operators import (
    CotanWeights,
    cotan_weights,
    laplacian,
    mean_curvature,
    mean_curvature_normal,
    vertex_areas,
)

__version__ = "0.1.0"

_LAZY = {
    "load": "io", "save": "io", "load_weights": "io", "save_weights": "io",
    "load_example": "examples", "example_path": "examples",
    "subdivide": "subdivision", "subdivision_matrix": "subdivision",
    "weld": "geometry.weld", "unweld": "geometry.weld", "as_mesh": "mesh.convert",
    "family": "flow", "family_meshes": "flow",
    "render": "rendering", "render_meshes": "rendering",
    "Brush": "sculpt", "InflateBrush": "sculpt",
    "studio": "studio",
}


def __getattr__(name):
    mod = _LAZY.get(name)
    if mod is None:
        raise AttributeError(f"module 'shapeflow' has no attribute {name!r}")
    import importlib

    return getattr(importlib.import_module(f".{mod}", __name__), name)


__all__ = [
    "Mesh", "Topology", "Diagnostics", "normalize_faces", "concatenate", "WEIGHT",
    "MeshError", "ParameterError", "ShapeflowError", "OptionalDependencyError", "DataLossWarning",
    "cotan_weights", "CotanWeights", "laplacian", "mean_curvature", "mean_curvature_normal", "vertex_areas",
    "flow", "smooth", "enhance", "FlowSolver", "FlowReport",
    *_LAZY,
]
