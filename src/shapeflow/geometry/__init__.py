"""The geometry layer: the one cotangent formula, areas, volume and normals.

Pure, vectorised functions of positions and index arrays; no sparse assembly
here (that is :mod:`shapeflow.operators`).
"""

from .cotangent import corner_cotangents, corner_terms, tri_geometry, triangle_cotangents
from .measures import SCALE_HI, SCALE_LO, face_vector_areas, mean_edge_length, pow2_exponent, signed_volume
from .normals import NORMAL_ATTRIBUTES, refresh_normals, vertex_normals

__all__ = [
    "corner_terms", "corner_cotangents", "tri_geometry", "triangle_cotangents",
    "face_vector_areas", "signed_volume", "vertex_normals", "mean_edge_length",
    "pow2_exponent", "SCALE_LO", "SCALE_HI", "NORMAL_ATTRIBUTES", "refresh_normals",
]
