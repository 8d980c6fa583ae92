"""The mesh layer's kernel family: unique edges and the checks of a face layout (NumPy reference).

The numba implementation is :class:`shapeflow.mesh.compiled.MeshNumba`; :func:`shapeflow.accel.kernels`
chooses (``accel.kernels("mesh", n_vertices)``).
"""

from __future__ import annotations

import numpy as np

from ..accel import Family
from ..errors import MeshError

__all__ = ["MeshKernels"]


class MeshKernels(Family):
    """Kernels of :class:`~shapeflow.mesh.Topology` and of face validation."""

    family = "mesh"

    def edge_data(self, topology) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(edges, corner_edge, offsets, order)`` of a topology: the unique edges (low, high) in the
        order of a stable sort of lo·n + hi over the half-edges, each corner's edge, and the half-edges
        of each edge (``order[offsets[e]:offsets[e + 1]]``), all of the topology's ``index_dtype``."""
        fi = topology.face_indices
        a = fi
        b = fi[topology.corner_next]
        lo = np.minimum(a, b)
        hi = np.maximum(a, b)
        key = lo * np.int64(topology.n_vertices) + hi
        order = np.argsort(key, kind="stable")
        sk = key[order]
        new = np.empty(sk.size, dtype=bool)
        if sk.size:
            new[0] = True
            np.not_equal(sk[1:], sk[:-1], out=new[1:])
        it = topology.index_dtype
        eid_sorted = np.cumsum(new, dtype=it) - 1
        corner_edge = np.empty(sk.size, dtype=it)
        corner_edge[order] = eid_sorted
        starts = np.flatnonzero(new)
        first = order[starts]
        edges = np.stack([lo[first], hi[first]], axis=1).astype(it)
        offsets = np.append(starts, sk.size).astype(it)
        return edges, corner_edge, offsets, order.astype(it)

    def check_faces(self, indices: np.ndarray, offsets: np.ndarray, n: int) -> None:
        """Raise :class:`MeshError` naming the first face with fewer than 3 corners, else the first
        corner outside [0, n), else the first face that repeats a vertex (``offsets`` already checked)."""
        sizes = np.diff(offsets)
        small = np.flatnonzero(sizes < 3)
        if small.size:
            f = int(small[0])
            raise MeshError(f"face {f} has {int(sizes[f])} corners; a face needs at least 3 ({small.size} such faces)")
        if indices.size and (indices.min() < 0 or indices.max() >= n):
            bad = np.flatnonzero((indices < 0) | (indices >= n))
            c = int(bad[0])
            f = int(np.searchsorted(offsets, c, side="right") - 1)
            raise MeshError(
                f"face {f} refers to vertex {int(indices[c])}, out of range [0, {n}) "
                f"({bad.size} such corners)"
            )
        # a vertex repeated inside one face: sort each face's corners, per face size
        for s in np.unique(sizes):
            faces_s = np.flatnonzero(sizes == s)
            block = indices[offsets[faces_s][:, None] + np.arange(s)]
            block.sort(axis=1)
            rep = (block[:, 1:] == block[:, :-1]).any(axis=1)
            if rep.any():
                f = int(faces_s[np.flatnonzero(rep)[0]])
                corners = indices[offsets[f]:offsets[f + 1]].tolist()
                raise MeshError(f"face {f} repeats a vertex: {corners}")
