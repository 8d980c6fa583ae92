"""The brushes' internal vertex numbering and the CSR helpers of their per-dab gathers."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..linalg.ordering import row_ptr
from ..mesh import Mesh

__all__ = ["csr_ranges", "unique_stamp", "locality_order", "renumbered", "csr_by", "index_dtype"]


def csr_ranges(ptr: np.ndarray, rows: np.ndarray):
    """Positions of the entries of ``rows`` in a CSR layout, and the row lengths."""
    starts = ptr.take(rows, mode="clip")
    lens = ptr.take(rows + 1, mode="clip") - starts
    total = int(lens.sum())
    offs = np.cumsum(lens) - lens
    ent = np.arange(total, dtype=np.int64) + np.repeat(starts - offs, lens)
    return ent, lens


def unique_stamp(ids: np.ndarray, stamp: np.ndarray) -> np.ndarray:
    """Unique values of ``ids`` in O(len) with a scratch array over the id range."""
    k = np.arange(ids.size, dtype=np.int64)
    stamp[ids] = k
    return ids[stamp.take(ids, mode="clip") == k]


def locality_order(mesh: Mesh) -> np.ndarray:
    """Reverse Cuthill–McKee order of the vertices over edges and face skip pairs.

    Used as the brushes' internal numbering: neighbouring vertices get nearby
    numbers, so a dab touches a few contiguous stretches of every per-vertex
    array (cache-friendly), and the unknowns of any dab, sorted, form a
    narrow-band matrix.
    """
    from scipy.sparse.csgraph import reverse_cuthill_mckee

    t = mesh.topology
    n = mesh.n_vertices
    if n == 0 or t.n_corners == 0:
        return np.arange(n, dtype=np.int64)
    fi, nxt, prv = t.face_indices, t.corner_next, t.corner_prev
    a = np.concatenate([fi, fi[prv]])
    b = np.concatenate([fi[nxt], fi[nxt]])
    G = sp.csr_matrix((np.ones(2 * a.size, np.int8), (np.concatenate([a, b]), np.concatenate([b, a]))),
                      shape=(n, n))
    return reverse_cuthill_mckee(G, symmetric_mode=True).astype(np.int64)


def renumbered(mesh: Mesh, perm: np.ndarray, inv: np.ndarray) -> Mesh:
    """``mesh`` with vertex i' = inv[i], faces sorted by their lowest new vertex."""
    t = mesh.topology
    if t.n_faces == 0:
        return Mesh(mesh.vertices[perm], [])
    fi = inv[t.face_indices]
    key = np.minimum.reduceat(fi, t.face_offsets[:-1])
    forder = np.argsort(key, kind="stable")
    ent, _ = csr_ranges(t.face_offsets, forder)
    return Mesh.from_csr(mesh.vertices[perm], t.face_sizes[forder], fi[ent])


def csr_by(keys: np.ndarray, n: int):
    """Stable grouping of positions by key: (ptr (n+1), order)."""
    return row_ptr(keys, n), np.argsort(keys, kind="stable")


def index_dtype(count: int):
    """int32 when indices and offsets below ``count`` fit in it, else int64 (a brush's cached index
    arrays: a dab reads a few thousand entries of each, and half the bytes is half the cache lines)."""
    return np.int32 if count < np.iinfo(np.int32).max else np.int64
