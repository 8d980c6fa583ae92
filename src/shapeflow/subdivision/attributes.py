"""Corner and face attributes through one subdivision step.

Corner values (texture coordinates, split normals) are interpolated face-varying and linearly (as
OpenSubdiv's ``FVAR_LINEAR_ALL``): a child corner at an old vertex keeps that corner's value, at an
edge point it gets the mean of the edge's two corner values in that face, at the face point the
mean over the face's corners.  Seams stay where they were, because a value is only ever mixed
with values of the same face.  An :class:`~shapeflow.mesh.attributes.Indexed` table stays a table:
old entries first, then one entry per distinct pair of entries along an edge, then one per face.
Every child face takes its parent's face attributes.
"""

from __future__ import annotations

import numpy as np

from ..mesh import Topology
from ..mesh.attributes import Indexed, Labels
from .level import child_corners

__all__ = ["child_corner_attribute", "child_face_attribute"]


def child_corner_attribute(attr, t: Topology):
    """A corner attribute of the parent topology ``t`` for its subdivided child."""
    nxt, prv = t.corner_next, t.corner_prev
    if not isinstance(attr, Indexed):
        U = np.asarray(attr, dtype=np.float64)
        flat = U.reshape(U.shape[0], -1)
        centre = np.stack([np.bincount(t.corner_face, flat[:, q], minlength=t.n_faces) for q in range(flat.shape[1])],
                          axis=1) / t.face_sizes[:, None]
        edge = 0.5 * (flat + flat[nxt])
        cols = (flat, edge, centre[t.corner_face], edge[prv])
        out = child_corners(t, cols).reshape(4 * t.n_corners, *U.shape[1:])
        return out.astype(np.asarray(attr).dtype) if np.asarray(attr).dtype.kind == "f" else out
    idx, table = attr.index, np.asarray(attr.values, dtype=np.float64)
    T = table.shape[0]
    a, b = idx, idx[nxt]
    both = (a >= 0) & (b >= 0)
    key = np.where(both, np.minimum(a, b) * T + np.maximum(a, b), -1)
    uniq, inv = np.unique(key[both], return_inverse=True)
    edge_idx = np.full(idx.size, -1, np.int64)
    edge_idx[both] = T + inv
    mid = 0.5 * (table[uniq // T] + table[uniq % T])
    # face point: the mean of the face's corner values, for faces whose corners all have one
    full = np.logical_and.reduceat(idx >= 0, t.face_offsets[:-1]) if idx.size else np.zeros(0, bool)
    safe = np.where(idx >= 0, idx, 0)
    sums = np.stack([np.bincount(t.corner_face, table[safe, q], minlength=t.n_faces)
                     for q in range(table.shape[1])], axis=1)
    centre = sums / t.face_sizes[:, None]
    face_idx = np.where(full, T + uniq.size + np.arange(t.n_faces), -1)
    cols = (idx, edge_idx, face_idx[t.corner_face], edge_idx[prv])
    new_index = child_corners(t, cols).reshape(-1)
    values = np.concatenate([table, mid, centre]).astype(attr.values.dtype)
    return Indexed(values, new_index)


def child_face_attribute(attr, t: Topology):
    """A face attribute for the children: each child quad (one per parent corner) takes its face's."""
    if isinstance(attr, Labels):
        return Labels(attr.codes[t.corner_face], attr.names)
    return np.asarray(attr)[t.corner_face]
