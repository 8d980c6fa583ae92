"""Per-vertex areas and mean curvature from the operator (H·n = (D − W) V / (4A))."""

from __future__ import annotations

import numpy as np

from ..errors import ParameterError
from ..geometry.cotangent import triangle_cotangents
from ..geometry.measures import pow2_exponent
from ..geometry.normals import vertex_normals
from ..mesh import Mesh
from ..mesh.convert import as_mesh
from .cotan import assemble
from .pattern import OperatorPattern

__all__ = ["vertex_areas", "areas_from", "mean_curvature_normal", "mean_curvature"]


def vertex_areas(mesh: Mesh, kind: str = "ring", scheme: str = "tqlbo") -> np.ndarray:
    """Per-vertex area.

    ``"ring"``
        The paper's ring area (eq. 5): the whole area of the weighted
        triangles around the vertex, about 3× the area the vertex owns.
    ``"barycentric"``
        ``ring / 3``: on triangle meshes exactly the barycentric area (a third
        of each incident triangle); on quads and n-gons it splits each face's
        area among its corners in proportion to the operator's triangles, and
        the areas of a planar face's corners sum to the face area.  Because it
        comes from the same triangles as W it stays consistent on mixed
        meshes (curvature converges on randomly half-triangulated spheres,
        where a plain "face area / corners" split does not).
    ``"mixed"``
        Meyer et al.'s mixed Voronoi area, averaged over the operator's
        triangles with their weights (exactly Meyer's on triangle meshes).
    """
    mesh = as_mesh(mesh)
    pattern, _, _, ring, _, _ = assemble(mesh, scheme, "relative")
    return areas_from(mesh, pattern, ring, kind)


def areas_from(mesh, pattern: OperatorPattern, ring: np.ndarray, kind: str) -> np.ndarray:
    """Per-vertex areas of :func:`vertex_areas` from an assembled operator."""
    if kind == "ring":
        return ring
    if kind == "barycentric":
        return ring / 3.0
    if kind == "mixed":
        tris, _, area_w, _ = pattern.triangles()
        cot, dbl, sq = triangle_cotangents(mesh.vertices, tris)
        area = 0.5 * dbl
        vor = np.empty_like(cot)
        for k in range(3):
            a, b = (k + 1) % 3, (k + 2) % 3
            vor[:, k] = (sq[:, b] * cot[:, b] + sq[:, a] * cot[:, a]) / 8.0
        obtuse = cot < 0  # angle > 90° at that corner
        any_obtuse = obtuse.any(axis=1)
        vor[any_obtuse] = (area[any_obtuse, None] / 4.0) * np.where(obtuse[any_obtuse], 2.0, 1.0)
        vals = (vor * area_w[:, None]).reshape(-1)
        return np.bincount(tris.reshape(-1), vals, minlength=mesh.n_vertices)
    raise ParameterError(f"unknown area kind {kind!r}; choose 'ring', 'barycentric' or 'mixed'")


def mean_curvature_normal(mesh: Mesh, *, area: str = "ring", scheme: str = "tqlbo") -> np.ndarray:
    """Mean curvature normal H·n per vertex (eq. 3/4/7), shape (n, 3).

    Computed as ``−Δx / 2 = (D − W) V / (4 A)``, with H the mean of the
    principal curvatures (1/r on a sphere of radius r) and n the outward
    normal of a consistently oriented closed surface.

    ``area="ring"`` uses the paper's ring area (eq. 5); since that area is
    about 3× the area a vertex owns, the paper's curvature is about 1/3 of
    the true value.  ``area="barycentric"`` or ``"mixed"`` (standard choices,
    see :func:`vertex_areas`) converge to H.
    Vertices with zero area get 0; values at boundary vertices are not
    curvature (no closed ring).
    """
    mesh = as_mesh(mesh)
    k = pow2_exponent(mesh.vertices)
    if k:   # H·n scales as 1/size: computed on an exact power-of-two copy (its areas stay in range)
        return np.ldexp(mean_curvature_normal(mesh.with_vertices(np.ldexp(mesh.vertices, -k)), area=area,
                                              scheme=scheme), -k)
    pattern, pw, deg, ring, _, _ = assemble(mesh, scheme, "relative")
    A = areas_from(mesh, pattern, ring, area)
    KV = pattern.matrix(deg, -pw) @ mesh.vertices
    with np.errstate(divide="ignore", invalid="ignore"):
        out = KV / (4.0 * A[:, None])
    out[~(A > 0)] = 0.0
    return out


def mean_curvature(mesh: Mesh, *, area: str = "ring", scheme: str = "tqlbo") -> np.ndarray:
    """Signed mean curvature per vertex: H = (H·n) · n_vertex.

    Positive where the surface bends away from its normal (convex parts of a
    closed outward-oriented surface: +1/r on a sphere).  See
    :func:`mean_curvature_normal` for the area choices.
    """
    mesh = as_mesh(mesh)
    hn = mean_curvature_normal(mesh, area=area, scheme=scheme)
    return np.einsum("ij,ij->i", hn, vertex_normals(mesh))
