"""What every brush shares: state, spatial queries, preview/commit, undo/redo and strokes."""

from __future__ import annotations

import functools
import threading
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from .. import accel, params
from ..errors import ParameterError
from ..geometry.normals import refresh_normals
from ..mesh import Mesh
from ..mesh.convert import as_mesh
from ..mesh.weights import resolve_weights
from ..types import Falloff, Weights
from .grid import within
from .numbering import locality_order, renumbered
from .stroke import as_point, as_points, check_falloff, positive, resample_polyline

__all__ = ["serialised", "Dab", "BrushBase"]


def serialised(fn):
    """Method decorator: one call at a time per brush (the brush's re-entrant lock)."""
    @functools.wraps(fn)
    def wrapper(self, *args, **kwargs):
        with self._lock:
            return fn(self, *args, **kwargs)
    return wrapper


@dataclass
class Dab:
    """One computed dab (committed or pending).

    Attributes
    ----------
    center, radius : the sphere.
    indices : (k,) vertices the dab solves for (every other vertex is untouched).
    positions : (k, 3) their new positions.
    previous : (k, 3) their positions before the dab.
    rim : (r,) the fixed rim (inside vertices with a face neighbour outside).
    n_inside : number of vertices inside the sphere.
    solver : how the system was solved ("split", "banded", "lu", "cholesky", "inflate" or "none").
    bandwidth : band of the interior system (banded solver; the wider half's for "split").
    seconds : time spent computing the dab (commit excluded).
    notes : fast paths this dab could not take, and why (``Brush.FALLBACKS`` has them all).
    """

    center: np.ndarray
    radius: float
    indices: np.ndarray
    positions: np.ndarray
    previous: np.ndarray
    rim: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    n_inside: int = 0
    solver: str = "none"
    bandwidth: int = 0
    seconds: float = 0.0
    notes: list = field(default_factory=list)
    _internal: np.ndarray | None = field(default=None, repr=False, compare=False)

    @property
    def displacement(self) -> np.ndarray:
        """(k, 3) new minus old positions."""
        return self.positions - self.previous


class BrushBase:
    """State shared by the brushes: working positions, spatial index, preview, undo."""

    def __init__(self, mesh: Mesh, *, radius: float, falloff: Falloff = None, weights: Weights = None,
                 undo_limit: int = 64, rebuild_fraction: float = 0.15):
        mesh = as_mesh(mesh)
        self._lock = threading.RLock()   # thread model: every public call holds it (see the class docstring)
        self._mesh0 = mesh
        n = mesh.n_vertices
        self._n = n
        self.radius = radius
        self.falloff = falloff
        w = resolve_weights(mesh, weights)
        # internal numbering for locality (see locality_order); user-facing indices
        # and positions are always in the mesh's own numbering
        self._perm = locality_order(mesh)              # internal -> mesh index
        self._inv = np.empty(n, dtype=np.int64)         # mesh -> internal index
        self._inv[self._perm] = np.arange(n)
        self._imesh = renumbered(mesh, self._perm, self._inv)
        self._V = np.array(self._imesh.vertices, dtype=np.float64, order="C")   # working copy (internal)
        self._Vx = np.array(mesh.vertices, dtype=np.float64, order="C")         # the same, mesh order
        self._w = w[self._perm]
        if isinstance(undo_limit, bool) or not isinstance(undo_limit, (int, np.integer)) or undo_limit < 0:
            raise ParameterError(f"undo_limit must be a non-negative integer, got {undo_limit!r}")
        self.undo_limit = int(undo_limit)
        self.rebuild_fraction = positive("rebuild_fraction", rebuild_fraction)
        self._slot = np.full(n, -1, dtype=np.int64)     # scratch: row of a vertex in the current region
        self._tree = None
        self._tree_kernels = None     # the sculpt kernels that built the tree
        self._tree_V = None
        self._tau = 0.0
        self._far = None
        self._far_list = np.zeros(0, np.int64)
        self._far_count = 0
        self._pending: Dab | None = None
        self._undo: list[list[tuple]] = []
        self._redo: list[list[tuple]] = []
        self._group: list | None = None
        self._mesh_cache: Mesh | None = None
        self.last: Dab | None = None
        self.tree_rebuilds = 0

    # --- parameters ------------------------------------------------------------
    @property
    @serialised
    def radius(self) -> float:
        """Brush radius (model units); may change between dabs."""
        return self._radius

    @radius.setter
    @serialised
    def radius(self, r) -> None:
        self._radius = positive("radius", r)

    @property
    @serialised
    def falloff(self):
        """None (constant), "smooth" ((1 − t²)², t = d/r) or a callable f(t)."""
        return self._falloff_spec

    @falloff.setter
    @serialised
    def falloff(self, f) -> None:
        self._falloff_fn = check_falloff(f)
        self._falloff_spec = f

    @property
    @serialised
    def weights(self) -> np.ndarray:
        """Per-vertex weights W_p in [0, 1] (a copy)."""
        return self._w[self._inv]

    @serialised
    def set_weights(self, weights: Weights) -> None:
        """Replace the per-vertex weights (None: all 1; an array, or an attribute name of the input);
        later dabs use them, nothing already done changes.  Checked as in the constructor."""
        self._w = resolve_weights(self._mesh0, weights)[self._perm]

    # --- state -------------------------------------------------------------------
    @property
    @serialised
    def mesh(self) -> Mesh:
        """The current sculpted mesh (built on demand, cached until the next change)."""
        if self._mesh_cache is None:
            self._mesh_cache = refresh_normals(self._mesh0.with_vertices(self._Vx))
        return self._mesh_cache

    @property
    def original(self) -> Mesh:
        """The mesh the brush was created with."""
        return self._mesh0

    @property
    @serialised
    def vertices(self) -> np.ndarray:
        """Current positions, a read-only view (it changes with later dabs; copy to keep)."""
        v = self._Vx.view()
        v.flags.writeable = False
        return v

    @property
    @serialised
    def pending(self) -> Dab | None:
        """The previewed dab waiting for :meth:`commit` or :meth:`discard`."""
        return self._pending

    @property
    @serialised
    def preview_mesh(self) -> Mesh:
        """The current mesh with the pending preview applied (the mesh itself if none)."""
        if self._pending is None:
            return self.mesh
        V = self._Vx.copy()
        V[self._pending.indices] = self._pending.positions
        return refresh_normals(self._mesh0.with_vertices(V))

    # --- spatial queries ---------------------------------------------------------------
    def _ensure_tree(self) -> None:
        n = self._n
        kern = accel.kernels("sculpt", n)       # the compiled grid, else SciPy's k-d tree
        if (self._tree is not None and self._far_count <= max(4096, n // 16)
                and self._tau <= 2.0 * self._radius
                and self._tree_kernels is kern
                and self._tree.fits(self._radius + self._tau)):
            return
        self._tree_V = self._V.copy()
        self._tau = self.rebuild_fraction * self._radius
        self._tree = kern.spatial_index(self._tree_V, self._radius + self._tau) if n else None
        self._tree_kernels = kern
        self._far = np.zeros(n, dtype=bool)
        self._far_list = np.zeros(0, np.int64)
        self._far_count = 0
        self.tree_rebuilds += 1

    def _query(self, c: np.ndarray, r: float):
        """Vertices with |v − c| <= r at the current positions, and their distances.

        The tree holds the positions of its last build; a vertex that moved
        less than ``tau`` since is found by a query of radius ``r + tau``, the
        others ("far" vertices, listed as they move) are checked one by one.
        The tree is rebuilt when the far list gets long.
        """
        self._ensure_tree()
        if self._tree is None:
            return np.zeros(0, np.int64), np.zeros(0)
        S, d = self._tree.query(self._V, self._far, c, r + self._tau, r)   # skips the far vertices
        if self._far_count:
            Sf, df = within(self._V, self._far_list[:self._far_count], c, r)
            S, d = np.concatenate([S, Sf]), np.concatenate([d, df])
        return S, d

    def _track(self, idx: np.ndarray) -> None:
        """After ``idx`` moved: mark those now farther than ``tau`` from their indexed position."""
        if self._tree_V is None or idx.size == 0:
            return
        d = self._V.take(idx, axis=0, mode="clip") - self._tree_V.take(idx, axis=0, mode="clip")
        far = (np.einsum("ij,ij->i", d, d) > self._tau * self._tau) & ~self._far[idx]
        if far.any():
            new = idx[far]
            self._far[new] = True
            need = self._far_count + new.size
            if need > self._far_list.size:
                grown = np.empty(max(need, 2 * self._far_list.size, 256), np.int64)
                grown[:self._far_count] = self._far_list[:self._far_count]
                self._far_list = grown
            self._far_list[self._far_count:need] = new
            self._far_count = need

    @serialised
    def inside(self, center) -> np.ndarray:
        """Indices of the vertices inside the sphere at ``center`` (current positions)."""
        c = as_point(center)
        return np.sort(self._perm[self._query(c, self._radius)[0]])

    # --- dabs ---------------------------------------------------------------------------
    def _compute(self, c: np.ndarray) -> Dab:  # pragma: no cover - abstract
        raise NotImplementedError

    @serialised
    @accel.heavy
    def preview(self, center) -> Dab:
        """Compute a dab at ``center`` without applying it ("Drag Dot").

        Replaces any pending preview.  Apply it with :meth:`commit`, drop it
        with :meth:`discard`; :attr:`preview_mesh` shows it.
        """
        c = as_point(center)
        self._pending = None
        t0 = time.perf_counter()
        dab = self._compute(c)
        dab.seconds = time.perf_counter() - t0
        self._pending = dab
        return dab

    @serialised
    def commit(self) -> np.ndarray:
        """Apply the pending preview; returns the indices it moved (empty if none)."""
        dab = self._pending
        if dab is None:
            return np.zeros(0, np.int64)
        self._pending = None
        idx = dab._internal if dab._internal is not None else self._inv[dab.indices]
        self._apply(idx, dab.previous, dab.positions)
        rec = (idx, dab.previous, dab.positions)
        if self._group is not None:
            self._group.append(rec)
        else:
            self._push_undo([rec])
        self.last = dab
        return dab.indices

    @serialised
    def discard(self) -> None:
        """Drop the pending preview (the mesh is unchanged)."""
        self._pending = None

    @serialised
    @accel.heavy
    def dab(self, center) -> np.ndarray:
        """Apply one dab at ``center``; returns the indices of the vertices it moved.

        Any pending preview is discarded first.
        """
        self.preview(center)
        return self.commit()

    @serialised
    @accel.heavy
    def stroke(self, points, spacing: float | None = 0.25, *,
               progress: Callable[[int, int], None] | None = None) -> np.ndarray:
        """Dabs along a polyline, one every ``spacing × radius`` of arc length.

        ``spacing=None`` dabs at the given points as they are.  The stroke is
        one undo step (an interrupted stroke too: one :meth:`undo` takes back
        what it did).  ``progress(done, total)`` is called after each dab.  Returns
        the sorted indices of every vertex moved.
        """
        params.progress(progress)
        P = self.dab_centers(points, spacing)
        self._pending = None
        self._group = []
        moved = []
        try:
            for i, c in enumerate(P):
                moved.append(self.dab(c))
                if progress is not None:
                    progress(i + 1, len(P))
        finally:
            group, self._group = self._group, None
            if group:
                self._push_undo(group)
        if not moved:
            return np.zeros(0, np.int64)
        return np.unique(np.concatenate(moved))

    @serialised
    def dab_centers(self, points, spacing: float | None = 0.25) -> np.ndarray:
        """The dab centres :meth:`stroke` would use for ``points``."""
        if spacing is None:
            return as_points(points)
        return resample_polyline(points, positive("spacing", spacing) * self._radius)

    # --- applying and undoing ---------------------------------------------------------
    def _apply(self, idx: np.ndarray, old: np.ndarray, new: np.ndarray) -> None:
        if idx.size == 0:
            return
        self._V[idx] = new
        self._Vx[self._perm[idx]] = new
        self._mesh_cache = None
        self._track(idx)
        self._moved(idx)

    def _moved(self, idx: np.ndarray) -> None:
        """Hook: update caches after the vertices ``idx`` moved."""

    def _push_undo(self, group: list) -> None:
        self._redo.clear()
        if self.undo_limit == 0:
            return
        self._undo.append(group)
        if len(self._undo) > self.undo_limit:
            del self._undo[0]

    def _restore(self, group: list, use_old: bool) -> np.ndarray:
        recs = reversed(group) if use_old else group
        touched = []
        for idx, old, new in recs:
            val = old if use_old else new
            self._V[idx] = val
            self._Vx[self._perm[idx]] = val
            touched.append(idx)
        if not touched:
            return np.zeros(0, np.int64)
        idx = np.unique(np.concatenate(touched))
        self._mesh_cache = None
        self._track(idx)
        self._moved(idx)
        return idx

    @serialised
    def undo(self) -> np.ndarray:
        """Undo the last dab or stroke (exactly); returns the indices restored."""
        self._pending = None
        if not self._undo:
            return np.zeros(0, np.int64)
        group = self._undo.pop()
        self._redo.append(group)
        return self._perm[self._restore(group, use_old=True)]

    @serialised
    def redo(self) -> np.ndarray:
        """Redo the last undone dab or stroke; returns the indices changed."""
        self._pending = None
        if not self._redo:
            return np.zeros(0, np.int64)
        group = self._redo.pop()
        self._undo.append(group)
        return self._perm[self._restore(group, use_old=False)]

    @property
    @serialised
    def can_undo(self) -> bool:
        return bool(self._undo)

    @property
    @serialised
    def can_redo(self) -> bool:
        return bool(self._redo)
