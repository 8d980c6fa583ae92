"""The brushes' spatial index: a uniform grid over vertex positions (compiled query)."""

from __future__ import annotations

import numpy as np

from .. import accel

__all__ = ["sq_norms", "CellGrid"]


def sq_norms(D: np.ndarray) -> np.ndarray:
    """Row norms² summed (x² + y²) + z², the order of the compiled grid query."""
    x, y, z = D[:, 0], D[:, 1], D[:, 2]
    return x * x + y * y + z * z


class CellGrid:
    """Uniform grid of cell size ``h`` over fixed positions (the compiled spatial index).

    Vertices are grouped by cell (sorted cell keys, CSR); a query visits the
    cells that overlap the query sphere's bounding box.  Answers the same
    question as SciPy's k-d tree, the index used without the kernels
    (``cKDTree.query_ball_point`` plus the distance test), in ~0.07 ms
    instead of ~0.55 ms for a dab of 2,600 vertices, with preallocated
    output buffers (nothing mesh-sized per dab).
    A query sphere much larger than the cells scans the occupied cells
    instead, so any radius is answered (the brush rebuilds the grid when its
    radius grows past 4 cells).
    """

    def __init__(self, P: np.ndarray, h: float):
        n = P.shape[0]
        self.lo = P.min(axis=0)
        extent = float(np.ptp(P, axis=0).max())
        # at most ~2**20 cells per axis: the keys fit in int64 whatever the radius
        self.h = h = max(float(h), extent * 2.0 ** -20, np.finfo(np.float64).tiny)
        ijk = np.floor((P - self.lo) / h).astype(np.int64)
        self.dims = ijk.max(axis=0) + 1
        key = (ijk[:, 0] * self.dims[1] + ijk[:, 1]) * self.dims[2] + ijk[:, 2]
        self.order = np.argsort(key, kind="stable")
        self.keys, first = np.unique(key[self.order], return_index=True)
        self.starts = np.append(first, n).astype(np.int64)
        self._out = np.empty(n, np.int64)
        self._dist = np.empty(n)

    def query(self, V: np.ndarray, far: np.ndarray, c: np.ndarray, R: float, r: float):
        fast = accel.compiled("sculpt", V.shape[0], min_size=0)
        m = fast.grid_query(self.keys, self.starts, self.order, self.dims, self.lo, self.h, V, far,
                         float(c[0]), float(c[1]), float(c[2]), float(R), float(r), self._out, self._dist)
        return self._out[:m].copy(), self._dist[:m].copy()
