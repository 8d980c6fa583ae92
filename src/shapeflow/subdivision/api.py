"""Subdivision of a mesh and of its attributes: :func:`subdivide` and :func:`subdivision_matrix`."""

from __future__ import annotations

from typing import Callable

import numpy as np
import scipy.sparse as sp

from .. import accel, params
from ..geometry.normals import refresh_normals
from ..mesh import WEIGHT, Mesh, Topology
from ..mesh.convert import as_mesh
from .attributes import child_corner_attribute, child_face_attribute
from .creases import Creases, resolve_creases
from .level import build_levels
from .rules import (
    BOUNDARY_RULES,
    EDGE_ORDERS,
    SCHEMES,
    WEIGHT_RULES,
    as_topology,
    check_choice,
    check_levels,
    check_output_size,
    check_threads,
    sharpness_crease,
)

__all__ = ["subdivide", "subdivision_matrix"]


@accel.heavy
def subdivision_matrix(mesh: Mesh, *, levels: int = 1, scheme: str = "catmull-clark",
                       boundary: str = "smooth", edge_order: str = "blender",
                       blender_threads: int = 1, creases: Creases = None) -> tuple[sp.csr_matrix, Topology]:
    """The sparse subdivision matrix of ``levels`` steps, and the new faces.

    Parameters
    ----------
    mesh : Mesh or Topology
        The cage; only its connectivity matters.
    levels : int, default 1
        Number of subdivision steps (0 gives the identity and the same faces).
    scheme : {"catmull-clark", "simple"}
        Catmull–Clark, or simple (linear: midpoints and centroids, old vertices
        unmoved; same connectivity).
    boundary : {"smooth", "keep-corners"}
        Boundary vertices follow the cubic B-spline curve rule; with
        ``"keep-corners"`` vertices with one face and two edges stay put
        (Blender's ``ALL`` and ``PRESERVE_CORNERS``).  No effect on ``"simple"``.
    edge_order : {"blender", "sorted"}
        Numbering of the edge points: Blender's (see the module docstring) or
        the order of ``mesh.topology.edges``.
    blender_threads : int, default 1
        Threads of the Blender whose edge order is reproduced (matters only for
        meshes with 1000 faces or more).
    creases : None, (edges (k, 2), values (k,)) or "mesh"
        Semi-sharp creases, Blender's values in [0, 1] (see :func:`subdivide`).

    Returns
    -------
    S : scipy.sparse.csr_matrix, shape (n_new, n)
        New vertices as combinations of the old ones (rows sum to 1), the
        product of the per-level matrices.
    topology : Topology
        The new faces (``face_indices``, ``face_offsets``, ``face_sizes``), all
        quads when ``levels >= 1``; reuse it for many meshes with
        ``subdivide(...).with_vertices(S @ V)``.

    Examples
    --------
    >>> import numpy as np, shapeflow as sf
    >>> quad = sf.Mesh([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], [[0, 1, 2, 3]])
    >>> S, topo = subdivision_matrix(quad)
    >>> S.shape, topo.n_faces
    ((9, 4), 4)
    """
    levels = check_levels(levels)
    check_output_size(mesh, levels)
    scheme = check_choice("scheme", scheme, SCHEMES)
    boundary = check_choice("boundary", boundary, BOUNDARY_RULES)
    edge_order = check_choice("edge_order", edge_order, EDGE_ORDERS)
    threads = check_threads(blender_threads)
    sharp = resolve_creases(mesh if isinstance(mesh, Topology) else as_mesh(mesh), creases)
    t = as_topology(mesh)
    S = sp.identity(t.n_vertices, format="csr")
    topo = t
    for mats, child in build_levels(t, levels, (scheme,), boundary, edge_order, threads, creases=sharp):
        S = mats[scheme] @ S
        topo = child
    return S.tocsr(), topo


@accel.heavy
def subdivide(mesh: Mesh, levels: int = 1, *, scheme: str = "catmull-clark",
              boundary: str = "smooth", weights_rule: str = "linear",
              edge_order: str = "blender", blender_threads: int = 1,
              progress: Callable[[int, int], None] | None = None, creases: Creases = None) -> Mesh:
    """Subdivide a mesh ``levels`` times, carrying its per-vertex attributes.

    Works on any mix of triangles, quads and n-gons, open or closed; after one
    Catmull–Clark or simple step every face is a quad (a face of size ``s``
    becomes ``s`` quads).  Positions and every attribute other than the
    weights follow ``scheme``; the weights (attribute ``"weight"``) follow
    ``weights_rule``: ``"linear"`` (what Blender does: old vertices keep their
    weight, edge points get the edge mean, face points the face mean) or
    ``"smooth"`` (the Catmull–Clark stencil, for smoother influence zones).
    Weights stay in [0, 1] either way.

    Parameters
    ----------
    mesh : Mesh
    levels : int, default 1
        Number of steps, >= 0 (0 returns an equal mesh).
    scheme : {"catmull-clark", "simple"}
    boundary : {"smooth", "keep-corners"}
        See :func:`subdivision_matrix`.
    weights_rule : {"linear", "smooth"}
    edge_order, blender_threads
        Numbering of the new vertices, see :func:`subdivision_matrix`.
    progress : callable(done, total), optional
        Called after each level.  The output's memory is estimated before
        the first level, and a subdivision that cannot fit is refused.
    creases : None, (edges (k, 2), values (k,)) or "mesh"
        Semi-sharp creases as Blender's Subdivision Surface takes them with
        ``use_creases``: a value c in [0, 1] per edge (a pair of vertices of
        an edge; one value for all, or one each), OpenSubdiv's sharpness 10·c²
        (c = 1: infinitely sharp), fractional sharpness blending the smooth
        and sharp rules and decreasing by 1 per level.  ``"mesh"``: the
        ``creases`` of a subdivision result, or an OBJ's ``t crease`` tags.
        The result carries ``result.creases`` = (edges, values): the halves of
        every creased edge with their values one level down per level, so
        subdividing it again with ``creases="mesh"`` continues the same surface.

    Returns
    -------
    Mesh
        ``n + E + F`` vertices per level (old vertices first, with unchanged
        indices), all-quad faces.

    Raises
    ------
    ParameterError
        A bad ``levels``, ``scheme``, ``boundary`` or ``weights_rule``.

    Examples
    --------
    >>> import shapeflow as sf
    >>> cube = sf.Mesh([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)],
    ...                [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]])
    >>> fine = subdivide(cube, 2)
    >>> fine.n_vertices, fine.n_faces
    (98, 96)
    """
    mesh = as_mesh(mesh)
    levels = check_levels(levels)
    check_output_size(mesh, levels)
    scheme = check_choice("scheme", scheme, SCHEMES)
    boundary = check_choice("boundary", boundary, BOUNDARY_RULES)
    weights_rule = check_choice("weights_rule", weights_rule, WEIGHT_RULES)
    edge_order = check_choice("edge_order", edge_order, EDGE_ORDERS)
    threads = check_threads(blender_threads)
    params.progress(progress)
    sharp = resolve_creases(mesh, creases)
    carry = None if sharp is None else {}

    attrs: dict[str, np.ndarray] = {k: np.asarray(v) for k, v in mesh.attributes.items()}
    types = {k: v.dtype for k, v in attrs.items()}
    weights = attrs.pop(WEIGHT, None)
    w_scheme = "simple" if weights_rule == "linear" else "catmull-clark"
    schemes = (scheme,) if weights is None or w_scheme == scheme else (scheme, w_scheme)

    X = mesh.vertices
    topo = mesh.topology
    corner = dict(mesh.corner_attributes)
    face = dict(mesh.face_attributes)
    # each level's matrix is applied as its two factors (S = P @ Q), which is
    # cheaper than forming S for a single use; subdivision_matrix() forms it
    for done, (mats, child) in enumerate(build_levels(mesh, levels, schemes, boundary, edge_order, threads,
                                                 factored=True, creases=sharp, carry=carry), start=1):
        S = mats[scheme]
        X = S @ X
        attrs = {k: (S @ v.reshape(v.shape[0], -1)).reshape((S.shape[0],) + v.shape[1:])
                 for k, v in attrs.items()}
        if weights is not None:
            weights = mats[w_scheme] @ weights
        corner = {k: child_corner_attribute(v, topo) for k, v in corner.items()}
        face = {k: child_face_attribute(v, topo) for k, v in face.items()}
        topo = child
        if progress is not None:
            progress(done, levels)
    if levels == 0:
        out = mesh.with_vertices(mesh.vertices)
        if sharp is not None:
            e = np.flatnonzero(sharp > 0)
            out.creases = (mesh.topology.edges[e].astype(np.int64), sharpness_crease(sharp[e]))
        return out
    if weights is not None:
        attrs[WEIGHT] = np.clip(weights, 0.0, 1.0)  # convex combinations; clip round-off
    for k, v in attrs.items():   # every attribute in its own type: integers rounded into their range
        dt = types[k]
        if dt.kind in "iu":
            info = np.iinfo(dt)
            attrs[k] = np.clip(np.rint(v), info.min, info.max).astype(dt)
        elif dt != v.dtype:
            attrs[k] = v.astype(dt)
    # normals (nx, ny, nz) were averaged like the rest: recomputed from the new surface, in their type
    out = refresh_normals(Mesh(X, None, attributes=attrs, corner_attributes=corner, face_attributes=face,
                               metadata=mesh.metadata, _topology=topo))
    if carry is not None:
        pairs, values = carry["creases"]
        out.creases = (pairs, sharpness_crease(values))
    return out
