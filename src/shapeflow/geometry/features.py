"""Sharp (feature) edges: by dihedral angle, from a list of vertex pairs, or as a file marks them.

* :func:`dihedral_angles` / :func:`angle_sharp_edges`: an edge with exactly two faces is
  sharp when the angle between the two faces' normals exceeds the feature angle.  A face's
  normal is the direction of its vector area (:func:`~shapeflow.geometry.measures.face_vector_areas`,
  the normal of any polygon, planar or not); when the two faces run through the edge in the same
  direction (inconsistent orientation) one normal is reversed first, so the angle is the bend
  of the surface, not of its orientation.  Boundary edges (one face) are never sharp by angle —
  the flow's boundary factor governs them; edges with three or more faces (non-manifold) always
  are; an edge next to a zero-area face (no normal) is not.
* :func:`edge_ids`: a ``(k, 2)`` array of vertex pairs as edge ids, refusing a pair that is not
  an edge of the mesh (:class:`~shapeflow.errors.ParameterError` naming the row).
* :func:`file_sharp_edges` and :func:`file_creases`: what an OBJ file marks: the borders of
  smoothing groups (``s``: an edge between faces of different groups, or next to a face with
  ``s off`` / ``s 0``, is sharp) and OpenSubdiv ``t crease`` tags (kept by the OBJ reader as
  ``mesh.metadata["obj"]["elements"]``, read here while the vertex numbering they refer to
  holds), and where the corner normals of a file split (:func:`split_normal_edges`: glTF, PLY,
  USD and OBJ ``vn`` keep a hard edge that way).

Everything is vectorised over edges and faces.
"""

from __future__ import annotations

import re

import numpy as np

from .. import accel, params
from ..errors import ParameterError
from .measures import face_vector_areas, pow2_exponent

__all__ = ["dihedral_angles", "angle_sharp_edges", "two_face_edges", "edge_ids", "find_edges", "check_feature_angle",
           "smoothing_group_edges", "file_creases", "file_sharp_edges", "split_normal_edges", "SPLIT_NORMAL_DEGREES",
           "OFF_GROUPS"]

#: smoothing-group names that mean "not smoothed" (``s off``, ``s 0``) and faces before any ``s`` line
OFF_GROUPS = ("", "off", "0")


def check_feature_angle(angle) -> float:
    """A feature angle in degrees, in [0, 180]."""
    return params.number("feature_angle", angle, lo=0.0, hi=180.0)


def two_face_edges(t):
    """Edge ids with exactly two faces, their two faces, and whether both faces run the edge the same way."""
    two = np.flatnonzero(t.edge_face_count == 2)
    o = t.edge_corner_offsets[two]
    c0 = t.edge_corners[o]
    c1 = t.edge_corners[o + 1]
    fi = t.face_indices
    return two, t.corner_face[c0], t.corner_face[c1], fi[c0] == fi[c1]


def dihedral_angles(mesh, vertices: np.ndarray | None = None) -> np.ndarray:
    """(E,) angle in degrees between the normals of each edge's two faces (edges of ``mesh.topology.edges``).

    NaN for edges without exactly two faces, and next to a face of zero area.
    """
    t = mesh.topology
    out = np.full(t.n_edges, np.nan)
    two, f0, f1, same = two_face_edges(t)
    if two.size == 0:
        return out
    fa = face_vector_areas(mesh, mesh.vertices if vertices is None else vertices)
    a, b = fa[f0], fa[f1]
    b[same] *= -1.0                       # inconsistent orientation: the bend, not the flip
    cross = np.cross(a, b)
    sin = np.sqrt(np.einsum("ij,ij->i", cross, cross))
    cos = np.einsum("ij,ij->i", a, b)
    ok = (np.einsum("ij,ij->i", a, a) > 0) & (np.einsum("ij,ij->i", b, b) > 0)
    out[two[ok]] = np.degrees(np.arctan2(sin[ok], cos[ok]))
    return out


def angle_sharp_edges(mesh, angle: float, vertices: np.ndarray | None = None) -> np.ndarray:
    """(E,) mask: edges whose dihedral angle exceeds ``angle`` degrees, and non-manifold edges.

    The cosine of the angle decides (one dot product of unit normals per edge); edges within 1e-6
    of the threshold's cosine are decided by the angle itself, from ``atan2(|a × b|, a · b)``.
    The pass over the edges is the geometry kernel family's (:class:`~shapeflow.geometry.kernels.GeometryKernels`).
    """
    angle = check_feature_angle(angle)
    t = mesh.topology
    V = mesh.vertices if vertices is None else vertices
    k = pow2_exponent(V)
    if k:      # normals are scale-free: an exact power-of-two copy keeps the areas in range
        V = np.ldexp(V, -k)
    return accel.kernels("geometry", t.n_vertices).angle_sharp_edges(mesh, V, angle)


def _edge_keys(t) -> tuple[np.ndarray, np.ndarray]:
    """Sorted keys lo·n + hi of the mesh's edges and the edge id of each."""
    e = t.edges
    key = e[:, 0].astype(np.int64) * np.int64(max(t.n_vertices, 1)) + e[:, 1]
    if key.size > 1 and not (key[1:] > key[:-1]).all():
        order = np.argsort(key, kind="stable")
        return key[order], order
    return key, np.arange(key.size)


def edge_ids(mesh, pairs, name: str = "sharp_edges") -> np.ndarray:
    """Edge ids (into ``mesh.topology.edges``) of the vertex pairs ``pairs`` (k, 2).

    Raises ParameterError naming ``name`` and the first row that is not an edge of the mesh.
    ``mesh`` may be a Mesh or its Topology.
    """
    t = getattr(mesh, "topology", mesh)
    n = t.n_vertices
    a = params.real_array(name, pairs)
    if a.size == 0:
        return np.zeros(0, np.int64)
    if a.ndim != 2 or a.shape[1] != 2:
        raise ParameterError(f"{name} must be a (k, 2) array of vertex pairs, got shape {a.shape}")
    bad = np.flatnonzero(~(np.isfinite(a) & (a == np.round(a))).all(axis=1))
    if bad.size:
        i = int(bad[0])
        raise ParameterError(f"{name}: row {i} {a[i].tolist()} is not a pair of vertex indices")
    bad = np.flatnonzero(((a < 0) | (a >= n)).any(axis=1))
    if bad.size:
        i = int(bad[0])
        raise ParameterError(f"{name}: row {i} {a[i].astype(np.int64).tolist()} names a vertex outside "
                             f"[0, {n})")
    p = a.astype(np.int64)
    ids, found = find_edges(t, p)
    bad = np.flatnonzero(~found)
    if bad.size:
        i = int(bad[0])
        raise ParameterError(f"{name}: row {i} ({int(p[i, 0])}, {int(p[i, 1])}) is not an edge of the mesh"
                             + (f" ({bad.size} such rows)" if bad.size > 1 else ""))
    return ids


def find_edges(mesh, pairs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Edge ids (into ``mesh.topology.edges``) of the integer vertex pairs ``pairs`` (k, 2), in range,
    and whether each is an edge (where not, its id is meaningless); ``mesh`` may be a Topology."""
    t = getattr(mesh, "topology", mesh)
    p = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    lo, hi = np.minimum(p[:, 0], p[:, 1]), np.maximum(p[:, 0], p[:, 1])
    key = lo * np.int64(max(t.n_vertices, 1)) + hi
    keys, ids = _edge_keys(t)
    pos = np.minimum(np.searchsorted(keys, key), max(keys.size - 1, 0))
    found = keys[pos] == key if keys.size else np.zeros(key.size, bool)
    return (ids[pos] if ids.size else np.zeros(key.size, np.int64)), found


def smoothing_group_edges(mesh) -> np.ndarray:
    """(E,) mask: borders of OBJ smoothing groups (face attribute ``"smooth"``); all False without it.

    An edge with two faces is sharp when their groups differ or either face is not smoothed
    (``s off``, ``s 0``, or no ``s`` line before it); an edge with three or more faces when
    any two of them differ so.  Boundary edges are not sharp.
    """
    t = mesh.topology
    out = np.zeros(t.n_edges, bool)
    lab = mesh.face_attributes.get("smooth")
    if lab is None or not hasattr(lab, "codes") or t.n_edges == 0:
        return out
    names = np.array(list(lab.names) + [""], dtype=object)
    off = np.isin(names, OFF_GROUPS)
    codes = np.where(lab.codes >= 0, lab.codes, len(lab.names))
    group = np.where(off[codes], -1, codes)                    # -1: not smoothed
    g = group[t.corner_face[t.edge_corners]]                    # per edge-corner, grouped edge by edge
    o = t.edge_corner_offsets
    cnt = np.diff(o)
    first = np.repeat(g[o[:-1]], cnt)
    differs = (g != first) | (g < 0)
    hit = np.add.reduceat(differs.astype(np.int64), o[:-1]) > 0 if g.size else out
    out[:] = hit & (cnt >= 2)
    return out


_CREASE = re.compile(r"^t[ \t]+crease[ \t]+(\d+)/(\d+)(?:/\d+)?[ \t]+([^\n]*)$", re.MULTILINE)


def file_creases(mesh) -> tuple[np.ndarray, np.ndarray]:
    """The OpenSubdiv ``t crease`` tags an OBJ reader kept: (pairs (k, 2), sharpness (k,)).

    A tag ``t crease N/F v1 .. vN s1 .. sF`` creases the N − 1 edges of the chain v1 … vN
    (0-based vertex numbers, OpenSubdiv's convention; RenderMan's chain reading of N > 2) with
    one sharpness for all (F = 1) or one each (F = N − 1); negative sharpness counts as 0, as
    OpenSubdiv clamps it.  Empty when the mesh has no such tags or its vertex numbering changed
    since it was read.  Raises ParameterError for a malformed tag.
    """
    meta = mesh.metadata.get("obj") or {}
    elements = meta.get("elements") or ()
    empty = (np.zeros((0, 2), np.int64), np.zeros(0))
    of = meta.get("elements_of")
    if not elements or of is None or of[0] != mesh.n_vertices or not np.array_equal(of[1], mesh.face_indices):
        return empty
    tags = _CREASE.findall("\n".join(map(" ".join, elements)))     # the kept 'l', 'p' and 't' lines
    if not tags:
        return empty
    cols = np.array(tags, dtype=str)
    nv, nf = cols[:, 0].astype(np.int64), cols[:, 1].astype(np.int64)
    try:
        vals = np.array(" ".join(cols[:, 2]).split(), dtype=np.float64)
    except ValueError:
        raise ParameterError("sharp_edges='mesh': a 't crease' tag holds a value that is not a number") from None
    ne = np.maximum(nv - 1, 0)
    bad = np.flatnonzero((nv < 2) | ((nf != 1) & (nf != ne)))
    if bad.size or vals.size != int((nv + nf).sum()):
        i = int(bad[0]) if bad.size else 0
        raise ParameterError(f"sharp_edges='mesh': 't crease {nv[i]}/{nf[i]}' tag {i} does not list a chain of "
                             "at least 2 vertices and one sharpness or one per edge")
    start = np.cumsum(nv + nf) - (nv + nf)                    # where each tag's values begin
    tag = np.repeat(np.arange(nv.size), ne)
    k = np.arange(tag.size) - np.repeat(np.cumsum(ne) - ne, ne)   # edge number within its tag
    v = vals[start[tag] + k]
    w = vals[start[tag] + k + 1]
    s = vals[start[tag] + nv[tag] + np.where(nf[tag] == 1, 0, k)]
    if np.isnan(s).any():
        raise ParameterError("sharp_edges='mesh': a 't crease' tag has a sharpness that is not a number")
    s = np.maximum(s, 0.0)
    pairs = np.stack([v, w], axis=1)
    edge_ids(mesh, pairs, "the file's 't crease' tags")       # every pair must be an edge
    return pairs.astype(np.int64), s


#: two corner normals of one vertex closer than this (degrees) are the same normal (float32 files, rounding)
SPLIT_NORMAL_DEGREES = 0.5


def split_normal_edges(mesh) -> np.ndarray:
    """(E,) mask: edges where the mesh's split normals (corner attribute ``"normal"``) break.

    A format without sharp-edge marks (glTF, PLY, USD, OBJ's ``vn``) keeps a hard edge as corner
    normals that differ on its two sides: Blender writes a sharp edge so.  An edge with two or more
    faces is sharp when, at either end vertex, the corner normals of its faces differ by more
    than :data:`SPLIT_NORMAL_DEGREES`.  Corners without a normal (an ``Indexed`` -1, or not finite)
    and zero normals compare equal to anything; boundary edges are never sharp.  All False
    without the attribute.  (A flat-shaded file splits every edge: all are marked.)
    """
    t = mesh.topology
    out = np.zeros(t.n_edges, bool)
    nrm = mesh.corner_attributes.get("normal")
    if nrm is None or t.n_edges == 0:
        return out
    N = nrm.expand() if hasattr(nrm, "expand") else np.asarray(nrm, dtype=np.float64)
    if N.ndim != 2 or N.shape[1] != 3 or N.shape[0] != t.n_corners:
        return out
    N = np.asarray(N, dtype=np.float64)
    length = np.sqrt(np.einsum("ij,ij->i", N, N))
    valid = np.isfinite(length) & (length > 0)
    U = np.where(valid[:, None], N / np.where(valid, length, 1.0)[:, None], 0.0)
    ec = t.edge_corners
    cn = t.corner_next[ec]
    fi = t.face_indices
    forward = fi[ec] < fi[cn]
    lo = np.where(forward, ec, cn)             # the corner at the edge's lower vertex, in this face
    hi = np.where(forward, cn, ec)
    o = t.edge_corner_offsets
    cnt = np.diff(o)
    first = np.repeat(o[:-1], cnt)             # the edge's first face, compared with each other face
    c = float(np.cos(np.radians(SPLIT_NORMAL_DEGREES)))
    differs = np.zeros(ec.size, bool)
    for a in (lo, hi):
        b = a[first]
        dot = np.einsum("ij,ij->i", U[a], U[b])
        differs |= (dot < c) & valid[a] & valid[b]
    hit = np.add.reduceat(differs.astype(np.int64), o[:-1]) > 0 if ec.size else out
    out[:] = hit & (cnt >= 2)
    return out


def file_sharp_edges(mesh) -> np.ndarray:
    """(E,) mask of the edges the file marks sharp: smoothing-group borders, creased edges (sharpness
    > 0) and where split normals break (:func:`split_normal_edges`)."""
    out = smoothing_group_edges(mesh) | split_normal_edges(mesh)
    pairs, s = file_creases(mesh)
    if s.size:
        out[edge_ids(mesh, pairs[s > 0], "the file's 't crease' tags")] = True
    return out
