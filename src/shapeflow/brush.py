"""Real-time sculpt brushes: the shape-enhancement brush of section 4.3 and an inflate baseline.

A :class:`Brush` applies one implicit flow step (eq. 11, see :mod:`shapeflow.flow`)
restricted to the vertices inside a sphere (centre u, radius r):

* *inside*: vertices with ``|v − u| ≤ r`` (current positions);
* *rim*: inside vertices with a face neighbour (any vertex sharing a face,
  quad diagonals included) outside the sphere.  They are not solved for: they
  stay where they are and anchor the solve as Dirichlet values;
* *unknowns*: the other inside vertices, minus those :func:`shapeflow.flow`
  keeps fixed (weight 0, locked by a degenerate element, zero or negative
  degree/mass).  Their rows are exactly flow's rows, paper mode:
  ``(C + D − W) X = C V + Σ_fixed w_ij V_j`` with ``C = diag(m_i/(|λ| w_i))``,
  ``m = D`` (normalised, eq. 10) or ``2A`` (eq. 9), then
  ``V ← V + sign(λ)(X − V)``.  Boundary vertices of open meshes use the
  umbrella operator with their own ``λ_b`` (``lam_border``, 0 = fixed), solved
  first, as in :func:`shapeflow.flow`.

Everything outside the unknowns is never written: outside vertices and the rim
are bit-identical after any number of dabs.  A dab that covers a whole closed
mesh (empty rim) is ``flow(mesh, lam)``.

``falloff`` (beyond the paper, which has none) multiplies the vertex weights
W_p by a function of ``t = d/r``: ``"smooth"`` is ``(1 − t²)²``, or pass a
callable mapping an array of ``t`` in [0, 1] to factors in [0, 1].

Work reused between dabs (nothing proportional to the whole mesh is done or
allocated per dab):

* a :class:`scipy.spatial.cKDTree` over the positions of its last build,
  queried with ``r + tau`` (``tau = rebuild_fraction · r``); vertices that
  have since moved farther than ``tau`` are kept in a short list checked
  directly, and the tree is rebuilt (lazily, at the next dab) once that list
  exceeds ``max(4096, n/16)`` vertices or the radius shrank below ``tau/2``;
* per-triangle cotangent contributions, areas and degeneracy flags of every
  weighted triangle of the operator (a triangle face once, the corner
  triangles of a quad or n-gon, and for "tqlbo" n-gons their interior fan
  triangles), the pair weights ``w_ij`` and per-vertex lock counts: after a
  committed dab only the triangles of the faces touching moved vertices are
  recomputed, and the pair weights updated by their change (round-off drift
  over very many dabs is removed by :meth:`Brush.refresh`);
* an internal vertex numbering (reverse Cuthill–McKee of the whole mesh,
  faces sorted to match): a dab touches a few contiguous stretches of every
  array (scanned meshes in file order got ~1.7× faster per dab), and a dab's
  unknowns, sorted, already form a narrow-band matrix.  Indices and positions
  seen by the caller are always in the mesh's own numbering.

The small SPD system of a dab is solved, from :data:`SPLIT_MIN` unknowns and
with the compiled kernels on two threads, by :meth:`Brush._split`: the
unknowns in Cuthill–McKee level order, cut at the middle level into two
banded halves that LAPACK factors at the same time (one per thread) and a
separator solved through its dense Schur complement (1.1–2.3 ms against
1.6–3.8 ms for one band on captured 2,400-unknown dab systems).  Otherwise,
and where the split does not apply (no balanced cut), with LAPACK's banded Cholesky
(``dpbsv``, lower band storage, one BLAS thread), after a local reordering
(breadth-first Cuthill–McKee from a pseudo-peripheral unknown) when the band
of the global order is much wider than that usually gives (about 1.2·sqrt(k)
for k unknowns); a sparse factorisation (cholespy when installed, SuperLU
otherwise) takes over for regions too large for a band.  Measured on
the project's 2-core machine (shared with other jobs) for systems of real
dabs (``benchmarks/bench_brush.py --solvers``), median solve times at ~700 /
~1,600 / ~2,400 unknowns: banded 0.4–0.8 / 1.3–1.9 / 2.3–4.4 ms, SuperLU
1.8–2.5 / 3.8–4.3 / 6.5–8.4 ms, cholespy 1.9–3.4 / 5.2–5.8 / 9–12 ms (the
symbolic analysis dominates at these sizes), dense Cholesky 5–90 / 40–95 /
135–160 ms.

The degeneracy thresholds are those of flow's paper mode ("relative"), with the
mean edge length ``h`` taken from the mesh the brush was built on (it is a
global quantity; recomputing it per dab would be full-mesh work).

Gathers on the per-dab paths use ``ndarray.take(..., mode="clip")`` (indices
are always valid, so the result is the same): with numpy 1.26 it is ~25%
faster than fancy indexing for 1-D arrays and ~4× for rows of an (n, 3) array.
"""

from __future__ import annotations

import functools
import logging
import math
import threading
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import scipy.sparse as sp

from . import kernels, params
from .errors import ParameterError
from .flow import resolve_weights
from .geometry import refresh_normals
from .mesh import Mesh
from .operators import REL_EDGE_TOL, REL_SHAPE_TOL, _check_scheme, _structure

__all__ = ["Brush", "InflateBrush", "Dab", "FALLOFFS", "BRUSH_SOLVERS"]

FALLOFFS = (None, "none", "constant", "smooth")
BRUSH_SOLVERS = ("auto", "banded", "lu", "cholesky")

#: banded Cholesky is used while (unknowns × bandwidth²) stays below this
#: (about 10 ms of LAPACK dpbtrf on the reference machine); beyond, a sparse
#: factorisation wins.
BANDED_MAX_WORK = 6e7
#: try a local narrow-band reordering (see ``Brush._local_rcm``) when the band
#: of the global order is expected to cost this much more (k·(bw² − 1.44 k)
#: flops, 1.44 k ≈ the square of the band the local order usually reaches) than
#: the reordering (~0.25 ms for 2,600 unknowns).  dpbtrf's time grows slowly
#: with the band at these sizes (per-column overhead): measured, reordering
#: pays from a global band of ~90–100 for ~2,400 unknowns.
LOCAL_RCM_WORK = 1e7
#: bands from ``BLOCKED_BAND[0]`` to ``BLOCKED_BAND[1] - 1`` are padded (with zeros) to
#: ``BLOCKED_BAND[1]``: LAPACK's dpbtrf runs its unblocked (level-2) code for bands up to its
#: block size, 64 in the OpenBLAS LAPACK SciPy ships, and the blocked code from 65.  Measured
#: (2,400 unknowns): band 63 ~1.9-2.9 ms, the same system padded to 65 ~1.5-2.0 ms, despite the
#: 6% more flops; below ~56 the unblocked code's lower flop count wins.
BLOCKED_BAND = (56, 65)


def _lapack_band(bw: int, k: int) -> int:
    """The band to give LAPACK for a band-``bw`` system of ``k`` unknowns (see BLOCKED_BAND)."""
    return BLOCKED_BAND[1] if BLOCKED_BAND[0] <= bw < BLOCKED_BAND[1] and k > BLOCKED_BAND[1] else bw


#: the most dabs one stroke is resampled to (a dab takes ~1-5 ms: about an hour of sculpting)
MAX_DABS = 1_000_000

#: from this many unknowns, "auto" solves a dab with the split solver
#: (:meth:`Brush._split`: two banded halves factored on two threads); below, one band.
SPLIT_MIN = 1000


# --------------------------------------------------------------------------
# parameters
# --------------------------------------------------------------------------

def _serialised(fn):
    """Method decorator: one call at a time per brush (the brush's re-entrant lock)."""
    @functools.wraps(fn)
    def wrapper(self, *args, **kwargs):
        with self._lock:
            return fn(self, *args, **kwargs)
    return wrapper


def _positive(name: str, x) -> float:
    return params.number(name, x, lo=0.0, lo_open=True)


def _smooth_falloff(t: np.ndarray) -> np.ndarray:
    s = 1.0 - t * t
    return s * s


def _check_falloff(falloff):
    if falloff is None or (isinstance(falloff, str) and falloff in ("none", "constant")):
        return None
    if isinstance(falloff, str):
        if falloff == "smooth":
            return _smooth_falloff
        raise ParameterError(f"unknown falloff {falloff!r}; choose None, 'smooth' or a callable f(d/r)")
    if callable(falloff):
        return falloff
    raise ParameterError(f"falloff must be None, 'smooth' or a callable f(d/r), got {type(falloff).__name__}")


def _apply_falloff(fn, t: np.ndarray) -> np.ndarray:
    f = np.asarray(fn(t), dtype=np.float64)
    if f.shape != t.shape:
        try:
            f = np.broadcast_to(f, t.shape).astype(np.float64)
        except ValueError:
            raise ParameterError(f"falloff returned shape {f.shape} for {t.shape[0]} distances") from None
    if not np.all(np.isfinite(f)) or (f.size and (f.min() < 0.0 or f.max() > 1.0)):
        raise ParameterError("falloff must return finite values in [0, 1]")
    return f


def _as_point(center) -> np.ndarray:
    c = params.real_array("center", center).reshape(-1)
    if c.shape != (3,) or not np.all(np.isfinite(c)):
        raise ParameterError(f"a brush centre must be 3 finite numbers, got {np.asarray(center).tolist()!r}")
    return c


def _as_points(points) -> np.ndarray:
    P = params.real_array("points", points)
    if P.ndim == 1 and P.size == 3:
        P = P.reshape(1, 3)
    if P.ndim != 2 or P.shape[1] != 3 or P.shape[0] == 0:
        raise ParameterError(f"stroke points must have shape (m, 3) with m >= 1, got {P.shape}")
    if not np.all(np.isfinite(P)):
        raise ParameterError("stroke points must be finite")
    return P.copy()


def resample_polyline(points, step: float) -> np.ndarray:
    """Points every ``step`` of arc length along a polyline, starting at its first point.

    The last point of the polyline is not added unless it falls on the grid;
    a single point gives itself.  ``step`` must be > 0.
    """
    P = _as_points(points)
    step = _positive("spacing", step)
    with np.errstate(over="ignore", invalid="ignore"):
        seg = np.linalg.norm(np.diff(P, axis=0), axis=1)
        cum = np.concatenate([[0.0], np.cumsum(seg)])
    total = float(cum[-1])
    if not math.isfinite(total):
        raise ParameterError("points: the stroke is too long to measure in double precision")
    if total == 0.0:
        return P[:1].copy()
    count = total / step + 1.0
    if count > MAX_DABS:
        raise ParameterError(f"spacing: a step of {step:.3g} along a stroke of length {total:.3g} gives "
                             f"{count:.3g} dabs; at most {MAX_DABS:,} (use a larger spacing)")
    s = np.arange(int(math.floor(total / step + 1e-9)) + 1) * step
    s = np.minimum(s, total)
    j = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(seg) - 1)
    # skip zero-length segments: searchsorted(side="right") already lands past them
    with np.errstate(invalid="ignore", divide="ignore"):
        a = np.where(seg[j] > 0, (s - cum[j]) / np.where(seg[j] > 0, seg[j], 1.0), 0.0)
    return P[j] + a[:, None] * (P[j + 1] - P[j])


# --------------------------------------------------------------------------
# small helpers
# --------------------------------------------------------------------------

class _SingleThreadBLAS:
    """Run LAPACK's banded Cholesky on one thread.

    OpenBLAS threads the small blocked updates inside ``dpbtrf``; on the 2-core
    reference machine that made a 2,600-unknown solve 2–5× slower (median)
    than one thread, much worse when other jobs share the machine.  Uses the
    thread-local setter of the OpenBLAS bundled with SciPy wheels when it is
    there (cheap, affects this thread only), else ``threadpoolctl`` when it
    is installed, else nothing.
    """

    _how = None         # "local" | "threadpoolctl" | "" (not available)
    _setter = None
    _controller = None

    @classmethod
    def _find(cls) -> str:
        if cls._how is not None:
            return cls._how
        cls._how = ""
        try:
            import ctypes
            import glob
            import os

            import scipy

            libdir = os.path.join(os.path.dirname(os.path.dirname(scipy.__file__)), "scipy.libs")
            for path in sorted(glob.glob(os.path.join(libdir, "libscipy_openblas*.so"))):
                lib = ctypes.CDLL(path)
                if hasattr(lib, "openblas_set_num_threads_local"):
                    f = lib.openblas_set_num_threads_local
                    f.argtypes = [ctypes.c_int]
                    f.restype = ctypes.c_int
                    cls._setter = f
                    cls._how = "local"
                    return cls._how
        except Exception as exc:  # pragma: no cover - platform dependent
            _fallback("blas-local", f"OpenBLAS's thread-local setter could not be loaded ({type(exc).__name__}: {exc})")
        try:  # pragma: no cover - depends on what is installed
            from threadpoolctl import ThreadpoolController

            cls._controller = ThreadpoolController()
            cls._how = "threadpoolctl"
        except Exception as exc:
            _fallback("blas", "LAPACK's banded Cholesky may use several OpenBLAS threads: no thread-local setter "
                              f"and no threadpoolctl ({type(exc).__name__})")
        return cls._how

    def __enter__(self):
        how = self._find()
        self._old = None
        self._limiter = None
        if how == "local":
            self._old = self._setter(1)
        elif how == "threadpoolctl":  # pragma: no cover
            self._limiter = self._controller.limit(limits=1, user_api="blas")
        return self

    def __exit__(self, *exc):
        if self._old is not None:
            self._setter(self._old)
        elif self._limiter is not None:  # pragma: no cover
            self._limiter.restore_original_limits()
        return False


@functools.cache
def _split_routines():
    """ctypes pointers to the LAPACK/BLAS routines of the split solver (SciPy's
    ``cython_lapack``/``cython_blas``) and OpenBLAS's thread-local thread count
    setter, or None where any is missing (the one-band solver is used then)."""
    if _SingleThreadBLAS._find() != "local":
        _fallback("split", "the two-thread split solver needs the thread-local setter of the OpenBLAS in SciPy's "
                           "wheels; dabs use one band")
        return None
    try:
        import ctypes

        from numba.extending import get_cython_function_address

        vp = ctypes.c_void_p
        fns = []
        for mod, name, nargs in (("lapack", "dpbtrf", 6), ("lapack", "dtbtrs", 11), ("lapack", "dpotrf", 5),
                                 ("lapack", "dpotrs", 8), ("blas", "dtrsm", 11), ("blas", "dsyrk", 10),
                                 ("blas", "dgemm", 13)):
            addr = get_cython_function_address("scipy.linalg.cython_" + mod, name)
            fns.append(ctypes.CFUNCTYPE(None, *([vp] * nargs))(addr))
        addr = ctypes.cast(_SingleThreadBLAS._setter, vp).value
        fns.append(ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_int)(addr))
    except Exception as exc:  # pragma: no cover - depends on the SciPy build
        _fallback("split", f"SciPy's LAPACK/BLAS pointers are not available ({type(exc).__name__}: {exc}); "
                           "dabs use one band")
        return None
    return tuple(fns)


#: why an optional fast path is not used in this process (key -> reason); each is logged once
FALLBACKS: dict[str, str] = {}
_log = logging.getLogger("shapeflow")


def _fallback(key: str, reason: str) -> None:
    """Record (and log once, at INFO on the "shapeflow" logger) that a fast path falls back."""
    if key not in FALLBACKS:
        FALLBACKS[key] = reason
        _log.info("shapeflow brush: %s", reason)


def _sq_norms(D: np.ndarray) -> np.ndarray:
    """Row norms² summed (x² + y²) + z², the order of the compiled grid query."""
    x, y, z = D[:, 0], D[:, 1], D[:, 2]
    return x * x + y * y + z * z


class _CellGrid:
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
        K = kernels.get(V.shape[0], min_size=0)
        m = K.grid_query(self.keys, self.starts, self.order, self.dims, self.lo, self.h, V, far,
                         float(c[0]), float(c[1]), float(c[2]), float(R), float(r), self._out, self._dist)
        return self._out[:m].copy(), self._dist[:m].copy()


def _csr_ranges(ptr: np.ndarray, rows: np.ndarray):
    """Positions of the entries of ``rows`` in a CSR layout, and the row lengths."""
    starts = ptr.take(rows, mode="clip")
    lens = ptr.take(rows + 1, mode="clip") - starts
    total = int(lens.sum())
    offs = np.cumsum(lens) - lens
    ent = np.arange(total, dtype=np.int64) + np.repeat(starts - offs, lens)
    return ent, lens


def _unique_stamp(ids: np.ndarray, stamp: np.ndarray) -> np.ndarray:
    """Unique values of ``ids`` in O(len) with a scratch array over the id range."""
    k = np.arange(ids.size, dtype=np.int64)
    stamp[ids] = k
    return ids[stamp.take(ids, mode="clip") == k]


def _locality_order(mesh: Mesh) -> np.ndarray:
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


def _renumbered(mesh: Mesh, perm: np.ndarray, inv: np.ndarray) -> Mesh:
    """``mesh`` with vertex i' = inv[i], faces sorted by their lowest new vertex."""
    t = mesh.topology
    if t.n_faces == 0:
        return Mesh(mesh.vertices[perm], [])
    fi = inv[t.face_indices]
    key = np.minimum.reduceat(fi, t.face_offsets[:-1])
    forder = np.argsort(key, kind="stable")
    ent, _ = _csr_ranges(t.face_offsets, forder)
    return Mesh.from_csr(mesh.vertices[perm], t.face_sizes[forder], fi[ent])


def _row_ptr(rows: np.ndarray, n: int, dtype=np.int64) -> np.ndarray:
    """CSR row pointer (n+1) of entries with row numbers ``rows`` (grouped by row)."""
    ptr = np.zeros(n + 1, dtype=dtype)
    np.cumsum(np.bincount(rows, minlength=n), out=ptr[1:])
    return ptr


def _csr_by(keys: np.ndarray, n: int):
    """Stable grouping of positions by key: (ptr (n+1), order)."""
    return _row_ptr(keys, n), np.argsort(keys, kind="stable")


def _tri_geometry(VT: np.ndarray, tv: np.ndarray):
    """Cotangents at the corners (a, b, d) of triangles ``tv`` (rows a, b, d), from
    component-major positions ``VT`` (3, n).

    Returns ``cot`` (3, m) (angle at a, b, d; 0 for zero-area rows), twice the
    area, and ``sq`` (3, m): the squared length of the side opposite each
    corner, each computed directly from its two end points (so an edge gets the
    same bits from every triangle).  The cotangents follow
    :func:`shapeflow.operators.corner_cotangents` with a = prev, b = curr, d = next.
    """
    a, b, d = tv
    X, Y, Z = VT
    # take(mode="clip") gathers faster than fancy indexing (indices are valid)
    ax, ay, az = X.take(a, mode="clip"), Y.take(a, mode="clip"), Z.take(a, mode="clip")
    bx, by, bz = X.take(b, mode="clip"), Y.take(b, mode="clip"), Z.take(b, mode="clip")
    dx, dy, dz = X.take(d, mode="clip"), Y.take(d, mode="clip"), Z.take(d, mode="clip")
    ex, ey, ez = dx - bx, dy - by, dz - bz        # curr -> next
    px, py, pz = bx - ax, by - ay, bz - az        # prev -> curr
    sx, sy, sz = dx - ax, dy - ay, dz - az        # prev -> next
    sq = np.empty((3, a.size))
    l_next = np.add(np.add(ex * ex, ey * ey, out=sq[0]), ez * ez, out=sq[0])
    np.add(np.add(sx * sx, sy * sy, out=sq[1]), sz * sz, out=sq[1])
    l_prev = np.add(np.add(px * px, py * py, out=sq[2]), pz * pz, out=sq[2])
    dot = -(px * ex + py * ey + pz * ez)
    cx = py * ez - pz * ey
    cy = pz * ex - px * ez
    cz = px * ey - py * ex
    dbl = np.sqrt(cx * cx + cy * cy + cz * cz)
    inv = np.divide(1.0, dbl, out=np.zeros_like(dbl), where=dbl > 0)
    cot = np.empty((3, a.size))
    np.multiply(l_prev - dot, inv, out=cot[0])
    np.multiply(dot, inv, out=cot[1])
    np.multiply(l_next - dot, inv, out=cot[2])
    return cot, dbl, sq


# --------------------------------------------------------------------------
# dab record
# --------------------------------------------------------------------------

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


# --------------------------------------------------------------------------
# common machinery: state, spatial index, preview/commit, undo, strokes
# --------------------------------------------------------------------------

class _BrushBase:
    """State shared by the brushes: working positions, spatial index, preview, undo."""

    def __init__(self, mesh: Mesh, *, radius: float, falloff=None, weights=None,
                 undo_limit: int = 64, rebuild_fraction: float = 0.15):
        if not isinstance(mesh, Mesh):
            raise ParameterError(f"expected a shapeflow.Mesh, got {type(mesh).__name__}")
        self._lock = threading.RLock()   # thread model: every public call holds it (see the class docstring)
        self._mesh0 = mesh
        n = mesh.n_vertices
        self._n = n
        self.radius = radius
        self.falloff = falloff
        w = resolve_weights(mesh, weights)
        # internal numbering for locality (see _locality_order); user-facing indices
        # and positions are always in the mesh's own numbering
        self._perm = _locality_order(mesh)              # internal -> mesh index
        self._inv = np.empty(n, dtype=np.int64)         # mesh -> internal index
        self._inv[self._perm] = np.arange(n)
        self._imesh = _renumbered(mesh, self._perm, self._inv)
        self._V = np.array(self._imesh.vertices, dtype=np.float64, order="C")   # working copy (internal)
        self._Vx = np.array(mesh.vertices, dtype=np.float64, order="C")         # the same, mesh order
        self._w = w[self._perm]
        if isinstance(undo_limit, bool) or not isinstance(undo_limit, (int, np.integer)) or undo_limit < 0:
            raise ParameterError(f"undo_limit must be a non-negative integer, got {undo_limit!r}")
        self.undo_limit = int(undo_limit)
        self.rebuild_fraction = _positive("rebuild_fraction", rebuild_fraction)
        self._slot = np.full(n, -1, dtype=np.int64)     # scratch: row of a vertex in the current region
        self._tree = None
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
    @_serialised
    def radius(self) -> float:
        """Brush radius (model units); may change between dabs."""
        return self._radius

    @radius.setter
    @_serialised
    def radius(self, r) -> None:
        self._radius = _positive("radius", r)

    @property
    @_serialised
    def falloff(self):
        """None (constant), "smooth" ((1 − t²)², t = d/r) or a callable f(t)."""
        return self._falloff_spec

    @falloff.setter
    @_serialised
    def falloff(self, f) -> None:
        self._falloff_fn = _check_falloff(f)
        self._falloff_spec = f

    @property
    @_serialised
    def weights(self) -> np.ndarray:
        """Per-vertex weights W_p in [0, 1] (a copy)."""
        return self._w[self._inv]

    # --- state -------------------------------------------------------------------
    @property
    @_serialised
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
    @_serialised
    def vertices(self) -> np.ndarray:
        """Current positions, a read-only view (it changes with later dabs; copy to keep)."""
        v = self._Vx.view()
        v.flags.writeable = False
        return v

    @property
    @_serialised
    def pending(self) -> Dab | None:
        """The previewed dab waiting for :meth:`commit` or :meth:`discard`."""
        return self._pending

    @property
    @_serialised
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
        grid = kernels.get(n, min_size=0) is not None     # the compiled grid, else SciPy's k-d tree
        if (self._tree is not None and self._far_count <= max(4096, n // 16)
                and self._tau <= 2.0 * self._radius
                and isinstance(self._tree, _CellGrid) == grid
                and (not grid or self._radius + self._tau <= 4.0 * self._tree.h)):
            return
        self._tree_V = self._V.copy()
        self._tau = self.rebuild_fraction * self._radius
        if not n:
            self._tree = None
        elif grid:
            self._tree = _CellGrid(self._tree_V, self._radius + self._tau)
        else:
            from scipy.spatial import cKDTree

            self._tree = cKDTree(self._tree_V)
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
        if isinstance(self._tree, _CellGrid):
            S, d = self._tree.query(self._V, self._far, c, r + self._tau, r)   # skips the far vertices
            if self._far_count:
                Sf, df = self._within(self._far_list[:self._far_count], c, r)
                S, d = np.concatenate([S, Sf]), np.concatenate([d, df])
            return S, d
        found = self._tree.query_ball_point(c, r + self._tau, return_sorted=False)
        cand = np.fromiter(found, dtype=np.int64, count=len(found))
        if self._far_count:
            cand = np.concatenate([cand[~self._far[cand]], self._far_list[:self._far_count]])
        return self._within(cand, c, r)

    def _within(self, cand: np.ndarray, c: np.ndarray, r: float):
        """The candidates within ``r`` of ``c`` at the current positions, and their distances."""
        if cand.size == 0:
            return cand, np.zeros(0)
        diff = self._V.take(cand, axis=0, mode="clip") - c     # (row take: ~4x faster than V[cand])
        d2 = _sq_norms(diff)
        keep = d2 <= r * r
        return cand[keep], np.sqrt(d2[keep])

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

    @_serialised
    def inside(self, center) -> np.ndarray:
        """Indices of the vertices inside the sphere at ``center`` (current positions)."""
        c = _as_point(center)
        return np.sort(self._perm[self._query(c, self._radius)[0]])

    # --- dabs ---------------------------------------------------------------------------
    def _compute(self, c: np.ndarray) -> Dab:  # pragma: no cover - abstract
        raise NotImplementedError

    @_serialised
    def preview(self, center) -> Dab:
        """Compute a dab at ``center`` without applying it ("Drag Dot").

        Replaces any pending preview.  Apply it with :meth:`commit`, drop it
        with :meth:`discard`; :attr:`preview_mesh` shows it.
        """
        c = _as_point(center)
        self._pending = None
        t0 = time.perf_counter()
        dab = self._compute(c)
        dab.seconds = time.perf_counter() - t0
        self._pending = dab
        return dab

    @_serialised
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

    @_serialised
    def discard(self) -> None:
        """Drop the pending preview (the mesh is unchanged)."""
        self._pending = None

    @_serialised
    def dab(self, center) -> np.ndarray:
        """Apply one dab at ``center``; returns the indices of the vertices it moved.

        Any pending preview is discarded first.
        """
        self.preview(center)
        return self.commit()

    @_serialised
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

    @_serialised
    def dab_centers(self, points, spacing: float | None = 0.25) -> np.ndarray:
        """The dab centres :meth:`stroke` would use for ``points``."""
        if spacing is None:
            return _as_points(points)
        return resample_polyline(points, _positive("spacing", spacing) * self._radius)

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

    @_serialised
    def undo(self) -> np.ndarray:
        """Undo the last dab or stroke (exactly); returns the indices restored."""
        self._pending = None
        if not self._undo:
            return np.zeros(0, np.int64)
        group = self._undo.pop()
        self._redo.append(group)
        return self._perm[self._restore(group, use_old=True)]

    @_serialised
    def redo(self) -> np.ndarray:
        """Redo the last undone dab or stroke; returns the indices changed."""
        self._pending = None
        if not self._redo:
            return np.zeros(0, np.int64)
        group = self._redo.pop()
        self._undo.append(group)
        return self._perm[self._restore(group, use_old=False)]

    @property
    @_serialised
    def can_undo(self) -> bool:
        return bool(self._undo)

    @property
    @_serialised
    def can_redo(self) -> bool:
        return bool(self._redo)


# --------------------------------------------------------------------------
# the enhancement / smoothing brush (section 4.3)
# --------------------------------------------------------------------------

class Brush(_BrushBase):
    """The shape-enhancement sculpt brush (section 4.3 of the paper).

    Each dab runs one implicit TQLBO flow step on the vertices inside a
    sphere, with the rim of the selection fixed (see the module docstring).

    Parameters
    ----------
    mesh : Mesh
    lam : float
        λ of each dab: < 0 enhances, > 0 smooths (as :func:`shapeflow.flow`).
    radius : float
        Sphere radius in model units.
    falloff : None, "smooth" or callable
        Multiplies W_p by f(d/r); None = the paper (no falloff).
    lam_border : float
        λ_b for boundary vertices of open meshes (umbrella operator, own
        sign); 0 keeps them fixed.
    weights : None, str or array (n,)
        Per-vertex W_p in [0, 1]; a string names a mesh attribute.
    scheme : {"tqlbo", "blender"}
        Cotangent weights (paper mode thresholds either way).
    normalized : bool
        True: eq. 10 (scale-invariant); False: eq. 9 (mass 2A).
    solver : {"auto", "banded", "lu", "cholesky"}
        Linear solver for a dab (module docstring); "auto" picks by cost
        (the two-thread split solver when it applies); "banded" is one band.
    undo_limit : int
        Number of dabs/strokes kept for :meth:`undo`.
    rebuild_fraction : float
        Rebuild the spatial index when a vertex moved more than this × radius
        since it was built.

    Thread model
    ------------
    A brush holds working positions, caches and solver work space, so its
    calls are serialised: every public method and property takes the
    brush's (re-entrant) lock, and a call from a second thread waits until
    the first one returns.  Several threads may share one brush safely,
    without any speed-up; use one brush per thread for parallel work.

    Examples
    --------
    >>> import shapeflow as sf
    >>> mesh = sf.load_example("spot")
    >>> brush = sf.Brush(mesh, lam=-50.0, radius=0.2)
    >>> moved = brush.dab(mesh.vertices[0])
    >>> moved = brush.stroke([mesh.vertices[0], mesh.vertices[10]])
    >>> sculpted = brush.mesh
    """

    @kernels.with_small_pages
    def __init__(self, mesh: Mesh, *, lam: float = -50.0, radius: float, falloff=None,
                 lam_border: float = 0.0, weights=None, scheme: str = "tqlbo", normalized: bool = True,
                 solver: str = "auto", undo_limit: int = 64, rebuild_fraction: float = 0.15):
        super().__init__(mesh, radius=radius, falloff=falloff, weights=weights,
                         undo_limit=undo_limit, rebuild_fraction=rebuild_fraction)
        self.lam = lam
        self.lam_border = lam_border
        self.scheme = _check_scheme(scheme)
        self.normalized = bool(normalized)
        if solver not in BRUSH_SOLVERS:
            raise ParameterError(f"unknown solver {solver!r}; choose one of {', '.join(BRUSH_SOLVERS)}")
        if solver == "cholesky":
            from .solvers import cholesky_available

            if not cholesky_available():
                from .errors import OptionalDependencyError

                raise OptionalDependencyError("cholespy", "cholesky", "the Cholesky solver")
        self.solver = solver
        self._work_buf = None  # work space reused by the banded and split solves (see _work)
        self._build()

    # --- parameters ------------------------------------------------------------
    @property
    @_serialised
    def lam(self) -> float:
        """λ of each dab (< 0 enhances, > 0 smooths); may change between dabs."""
        return self._lam

    @lam.setter
    @_serialised
    def lam(self, v) -> None:
        self._lam = params.lam("lam", v)

    @property
    @_serialised
    def lam_border(self) -> float:
        """λ_b for boundary vertices of open meshes (0: fixed)."""
        return self._lam_b

    @lam_border.setter
    @_serialised
    def lam_border(self, v) -> None:
        self._lam_b = params.lam("lam_border", v)

    # --- one-time set-up ----------------------------------------------------------
    def _build(self) -> None:
        mesh = self._imesh          # internal numbering (RCM order: sorted unknowns have a narrow band)
        t = mesh.topology
        n = self._n
        st = _structure(mesh, self.scheme)
        E = t.n_edges
        # unique vertex pairs: the operator's pair list may repeat a chord (once per
        # contribution); here every pair of vertices has one id
        keys = st.pairs[:, 0].astype(np.int64) * n + st.pairs[:, 1]   # pairs may be int32
        ukeys, uinv = np.unique(keys, return_inverse=True)
        P = ukeys.size
        upairs = np.stack([ukeys // n, ukeys % n], axis=1)
        self._upairs = upairs
        self._uedge = np.zeros(P + 1, dtype=bool)      # pairs that are mesh edges
        self._uedge[uinv[:E]] = True
        self._edge_uid = uinv[:E]
        T, self._tv, self._tp, self._tw, self._taw, tface = self._triangles(mesh, st, ukeys, uinv)
        self._P, self._E = P, E
        self._ttri = np.zeros(T, dtype=bool)            # triangles that are whole triangle faces
        self._ttri[np.flatnonzero(t.face_sizes[tface] == 3)] = True
        # face -> its triangles (triangles are numbered face by face)
        self._ft_ptr = _row_ptr(tface, t.n_faces)
        # vertex -> faces
        self._vf_ptr, order = _csr_by(t.face_indices, n)
        self._vf_face = t.corner_face[order]
        self._vt_ptr = None   # vertex -> triangles, built when first needed (eq. 9 areas)
        # vertex -> face neighbours with the pair id (P = "no weight": face neighbours
        # that are not pairs, i.e. long chords of 6+-gons in scheme "blender")
        a = np.concatenate([upairs[:, 0], upairs[:, 1]])
        b = np.concatenate([upairs[:, 1], upairs[:, 0]])
        pid = np.concatenate([np.arange(P), np.arange(P)])
        extra = self._missing_face_pairs(mesh, upairs, n)
        if extra.size:
            a = np.concatenate([a, extra[:, 0], extra[:, 1]])
            b = np.concatenate([b, extra[:, 1], extra[:, 0]])
            pid = np.concatenate([pid, np.full(2 * extra.shape[0], P)])
        self._vn_ptr, order = _csr_by(a, n)
        self._vn_nb = b[order]
        self._vn_pair = pid[order]
        # boundary (paper mode): vertices on a boundary edge; vertex -> boundary edges
        self._bmask = t.boundary_vertex_mask
        be = t.boundary_edges
        ba = np.concatenate([be[:, 0], be[:, 1]])
        self._vb_ptr, order = _csr_by(ba, n)
        self._vb_nb = np.concatenate([be[:, 1], be[:, 0]])[order]
        # caches
        self._VT = np.ascontiguousarray(self._V.T)   # component-major copy of the positions
        self._tval = np.zeros((3, T))      # w_t · cot_k (0 if degenerate), added to pair tp[k, t]
        self._tarea = np.zeros(T)          # area weight · area (kept for eq. 9 only)
        self._tbad = np.zeros(T, dtype=bool)
        self._pshort = np.zeros(P + 1, dtype=bool)   # edges shorter than flow's relative threshold
        self._vlock = np.zeros(n, dtype=np.int64)    # degenerate triangles + short edges at each vertex
        self._fstamp = np.zeros(t.n_faces, dtype=np.int64)
        self._tri_buf = None               # compiled cache update: the moved triangles
        # mean edge length h (flow's "relative" thresholds), from the initial positions
        E_ = t.edges
        el2 = ((self._V[E_[:, 0]] - self._V[E_[:, 1]]) ** 2).sum(axis=1) if E else np.zeros(0)
        h = float(np.sqrt(el2).mean()) if E else 0.0
        self._h = h
        self._short2 = (REL_EDGE_TOL * h) ** 2
        self._update_triangles(np.arange(T), initial=True)
        self._pw = np.zeros(P + 1)         # pair weights w_ij, plus a zero for "no pair"
        self._pw[:P] = np.bincount(self._tp.reshape(-1), self._tval.reshape(-1), minlength=P)[:P]
        short = el2 <= self._short2
        self._pshort[self._edge_uid] = short
        if short.any():
            self._vlock += np.bincount(E_[short].reshape(-1), minlength=n)

    @staticmethod
    def _triangles(mesh: Mesh, st, ukeys: np.ndarray, uinv: np.ndarray):
        """Every weighted triangle of the operator, numbered face by face.

        A triangle face is one triangle with 3× its corner-triangle weight (its
        three corner triangles are the same triangle); a face with 4+ corners
        has its corner triangles (prev, curr, next), and for "tqlbo" n-gons
        the interior fan triangles of the operator structure.  Returns T,
        vertices (3, T), pair opposite each corner (3, T), cotangent weight,
        area weight and face of each triangle.  Pair ids index the sorted
        unique pair keys ``ukeys``; ``uinv`` maps the operator's pair ids to them.
        """
        t = mesh.topology
        sizes, offs = t.face_sizes, t.face_offsets
        fi, nxt, prv, ce = st.fi, st.nxt, st.prv, st.corner_edge
        c = fi.size
        cs = np.repeat(sizes, sizes)
        first = np.repeat(offs[:-1], sizes)
        mc = np.flatnonzero((cs > 3) | (np.arange(c) == first))
        mult = np.where(cs[mc] == 3, 3.0, 1.0)
        tv = [np.stack([fi[prv[mc]], fi[mc], fi[nxt[mc]]])]
        tp = [uinv[np.stack([ce[mc], st.skip_pair[mc], ce[prv[mc]]])]]
        tw = [st.corner_w[mc] * mult]
        taw = [st.corner_aw[mc] * mult]
        tf = [t.corner_face[mc]]
        if st.extra_tris.size:
            tv.append(st.extra_tris.T)
            tp.append(uinv[st.extra_pair].T)
            tw.append(st.extra_w)
            taw.append(st.extra_w)
            tf.append(st.extra_face)
        face = np.concatenate(tf)
        order = np.argsort(face, kind="stable")
        tv = np.ascontiguousarray(np.concatenate(tv, axis=1)[:, order].astype(np.int64))
        tp = np.ascontiguousarray(np.concatenate(tp, axis=1)[:, order].astype(np.int64))
        return (order.size, tv, tp, np.concatenate(tw)[order], np.concatenate(taw)[order], face[order])

    @staticmethod
    def _missing_face_pairs(mesh: Mesh, pairs: np.ndarray, n: int) -> np.ndarray:
        sizes = mesh.face_sizes
        big = np.flatnonzero(sizes >= 6)
        if big.size == 0:
            return np.zeros((0, 2), np.int64)
        out = []
        fi, off = mesh.face_indices, mesh.face_offsets
        for s in np.unique(sizes[big]):
            s = int(s)
            faces = big[sizes[big] == s]
            block = fi[off[faces][:, None] + np.arange(s)]
            iu, ju = np.triu_indices(s, 1)
            x, y = block[:, iu].reshape(-1), block[:, ju].reshape(-1)
            out.append(np.stack([np.minimum(x, y), np.maximum(x, y)], axis=1))
        allp = np.unique(np.concatenate(out), axis=0)
        have = pairs[:, 0] * n + pairs[:, 1]
        keys = allp[:, 0] * n + allp[:, 1]
        return allp[~np.isin(keys, have)]

    def _update_triangles(self, tris: np.ndarray, initial: bool = False) -> None:
        """Recompute the cache of triangles ``tris`` from the current positions.

        After the first call, the pair weights follow by adding each slot's
        change (new − old), and the locks (degenerate triangles, short edges)
        by counting flips.
        """
        tv, tp, tval = self._tv, self._tp, self._tval
        K = None if initial else kernels.get(self._n, min_size=0)
        if K is not None:   # the branch below in one compiled pass
            flips = np.empty(3 * tris.size, self._tp.dtype)
            nf = K.brush_update_triangles(tris, tv, tp, self._tw, self._taw, self._VT, tval, self._tarea,
                                          not self.normalized, self._tbad, self._vlock, self._pw, self._ttri,
                                          self._pshort, self._short2, REL_SHAPE_TOL, flips)
            if nf:
                self._flip_short(np.unique(flips[:nf]))
            return
        tvs = (tv[0].take(tris, mode="clip"), tv[1].take(tris, mode="clip"), tv[2].take(tris, mode="clip"))
        cot, dbl, sq = _tri_geometry(self._VT, tvs)
        bad = dbl <= REL_SHAPE_TOL * np.maximum(np.maximum(sq[0], sq[1]), sq[2])
        w = self._tw.take(tris, mode="clip")
        anybad = bad.any()
        if anybad:
            w = np.where(bad, 0.0, w)
        if not self.normalized or initial:
            self._tarea[tris] = 0.5 * dbl * self._taw[tris]
        if initial:
            for k in range(3):
                tval[k][tris] = cot[k] * w
            self._tbad[tris] = bad
            if anybad:
                self._vlock += np.bincount(np.concatenate([v[bad] for v in tvs]), minlength=self._n)
            return
        pw = self._pw
        tps = []
        for k in range(3):
            new = cot[k] * w
            row = tval[k]
            old = row.take(tris, mode="clip")
            row[tris] = new
            tpk = tp[k].take(tris, mode="clip")
            tps.append(tpk)
            np.add.at(pw, tpk, new - old)
        chg = self._tbad.take(tris, mode="clip") != bad
        if chg.any():
            delta = np.where(bad[chg], 1, -1)
            np.add.at(self._vlock, np.concatenate([v[chg] for v in tvs]), np.tile(delta, 3))
            self._tbad[tris[chg]] = bad[chg]
        # short edges: side 0 of every triangle is an edge or a chord, the sides of
        # triangle faces are edges; flips are rare
        short2, pshort = self._short2, self._pshort
        flips = [tps[0][(sq[0] <= short2) != pshort.take(tps[0], mode="clip")]]
        tri3 = self._ttri.take(tris, mode="clip")
        if tri3.any():
            for k in (1, 2):
                e = tps[k][tri3]
                flips.append(e[(sq[k][tri3] <= short2) != pshort[e]])
        flips = np.concatenate(flips) if len(flips) > 1 else flips[0]
        if flips.size:
            self._flip_short(np.unique(flips))

    def _flip_short(self, pairs: np.ndarray) -> None:
        e = pairs[self._uedge[pairs]]
        if e.size == 0:
            return
        ends = self._upairs[e]
        d = self._V[ends[:, 0]] - self._V[ends[:, 1]]
        short = np.einsum("ij,ij->i", d, d) <= self._short2
        chg = short != self._pshort[e]
        if chg.any():
            self._pshort[e[chg]] = short[chg]
            np.add.at(self._vlock, ends[chg].reshape(-1), np.repeat(np.where(short[chg], 1, -1), 2))

    def _moved(self, idx: np.ndarray) -> None:
        """Recompute the triangles of the faces touching ``idx``."""
        new = self._V.take(idx, axis=0, mode="clip")
        VT = self._VT
        for q in range(3):
            VT[q][idx] = new[:, q]
        K = kernels.get(self._n, min_size=0)
        if K is not None:   # the same triangles, in first-seen order, in one compiled pass
            if self._tri_buf is None:
                self._tri_buf = np.empty(self._tv.shape[1], dtype=np.int64)
            nt = K.brush_moved_triangles(idx, self._vf_ptr, self._vf_face, self._ft_ptr, self._fstamp,
                                         self._tri_buf)
            self._update_triangles(self._tri_buf[:nt])
            return
        ent, _ = _csr_ranges(self._vf_ptr, idx)
        faces = _unique_stamp(self._vf_face.take(ent, mode="clip"), self._fstamp)
        tris, _ = _csr_ranges(self._ft_ptr, faces)
        self._update_triangles(tris)

    @_serialised
    def refresh(self) -> None:
        """Recompute every cached weight from the current positions (O(n)).

        Pair weights are updated incrementally after each dab; this removes the
        (round-off sized) drift that many thousands of dabs may accumulate.
        """
        T = self._tv.shape[1]
        self._tval[:] = 0.0
        self._tbad[:] = False
        self._vlock[:] = 0
        self._update_triangles(np.arange(T), initial=True)
        P = self._P
        self._pw[:] = 0.0
        self._pw[:P] = np.bincount(self._tp.reshape(-1), self._tval.reshape(-1), minlength=P)[:P]
        E_ = self._imesh.topology.edges
        d = self._V[E_[:, 0]] - self._V[E_[:, 1]]
        short = np.einsum("ij,ij->i", d, d) <= self._short2
        self._pshort[:] = False
        self._pshort[self._edge_uid] = short
        if short.any():
            self._vlock += np.bincount(E_[short].reshape(-1), minlength=self._n)

    @_serialised
    def pair_weights(self):
        """Current cotangent weights as ``(pairs, w)``: pairs (P, 2) of mesh vertex
        indices (each row sorted, rows sorted) and w_ij, from the cache."""
        pr = np.sort(self._perm[self._upairs], axis=1)
        order = np.lexsort((pr[:, 1], pr[:, 0]))
        return pr[order], self._pw[:self._P][order]

    @property
    @_serialised
    def locked(self) -> np.ndarray:
        """(n,) bool: vertices touching a degenerate triangle or a too-short edge
        (kept fixed, as :func:`shapeflow.flow` does), at the current positions."""
        return self._vlock[self._inv] > 0

    def _ring_areas(self, S: np.ndarray) -> np.ndarray:
        """Ring area (eq. 5) of vertices ``S`` from the cached triangle areas."""
        if self._vt_ptr is None:
            T = self._tv.shape[1]
            self._vt_ptr, order = _csr_by(self._tv.reshape(-1), self._n)
            self._vt_tri = order % T
        te, tl = _csr_ranges(self._vt_ptr, S)
        return np.bincount(np.repeat(np.arange(S.size), tl), self._tarea[self._vt_tri[te]], minlength=S.size)

    # --- the dab ------------------------------------------------------------------------
    @_serialised
    def region(self, center) -> dict:
        """Inside, rim and free vertices of a dab at ``center`` (nothing is solved).

        Returns sorted index arrays ``inside``, ``rim``, ``free`` (the vertices
        a dab would solve for) and ``fixed`` (inside, not rim, yet kept in
        place: weight 0, locked, or a boundary vertex with λ_b = 0).
        """
        c = _as_point(center)
        S, d = self._query(c, self._radius)
        try:
            info = self._classify(S, d)
            free = info["free_i"] | info["free_b"]
            P = self._perm
            return {"inside": np.sort(P[S]), "rim": np.sort(P[S[info["rim"]]]), "free": np.sort(P[S[free]]),
                    "fixed": np.sort(P[S[~info["rim"] & ~free]])}
        finally:
            self._slot[S] = -1

    def _classify(self, S: np.ndarray, d: np.ndarray) -> dict:
        """Rim, locks, weights and degrees of the region ``S`` (fills ``self._slot``)."""
        ns = S.size
        slot = self._slot
        slot[S] = np.arange(ns)
        K = kernels.get(self._n, min_size=0)
        if K is not None:   # the same rim and degrees in one compiled pass; _solve_region walks again
            rim = np.empty(ns, dtype=bool)
            deg = np.empty(ns)
            K.brush_classify(S, slot, self._vn_ptr, self._vn_nb, self._vn_pair, self._pw, rim, deg)
            rowid = snb = pwe = None
        else:
            ent, lens = _csr_ranges(self._vn_ptr, S)
            rowid = np.repeat(np.arange(ns), lens)
            nb = self._vn_nb.take(ent, mode="clip")
            pwe = self._pw.take(self._vn_pair.take(ent, mode="clip"), mode="clip")
            snb = slot.take(nb, mode="clip")
            rim = np.bincount(rowid[snb < 0], minlength=ns) > 0
            rim |= lens == 0
            deg = np.bincount(rowid, pwe, minlength=ns)
        w = self._w[S]
        if self._falloff_fn is not None:
            w = w * _apply_falloff(self._falloff_fn, d / self._radius)
        mass = deg if self.normalized else 2.0 * self._ring_areas(S)
        bnd = self._bmask[S]
        cand = ~rim & (self._vlock[S] == 0) & (w > 0)
        if self._lam != 0.0:
            free_i = cand & ~bnd & (mass > 0) & (deg > 0)
        else:
            free_i = np.zeros(ns, dtype=bool)
        free_b = cand & bnd if self._lam_b != 0.0 else np.zeros(ns, dtype=bool)
        return dict(rowid=rowid, snb=snb, pwe=pwe, rim=rim, deg=deg, w=w, mass=mass,
                    free_i=free_i, free_b=free_b)

    def _compute(self, c: np.ndarray) -> Dab:
        self._notes = []   # fallbacks taken by this dab (calls are serialised: one dab at a time)
        S, d = self._query(c, self._radius)
        if S.size == 0:
            return Dab(c, self._radius, np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros((0, 3)))
        order = np.argsort(S)
        S, d = S[order], d[order]
        try:
            info = self._classify(S, d)
            return self._solve_region(c, S, info)
        finally:
            self._slot[S] = -1

    def _solve_region(self, c: np.ndarray, S: np.ndarray, info: dict) -> Dab:
        V = self._V
        ns = S.size
        rim = S[info["rim"]]
        lam, lam_b = self._lam, self._lam_b
        # --- boundary vertices first (umbrella operator, as flow's paper mode) -------
        Rb = np.zeros(0, np.int64)
        Xb = np.zeros((0, 3))
        if info["free_b"].any():
            Rb, Xb = self._solve_boundary(S, info)
        # --- interior ----------------------------------------------------------------
        R = np.flatnonzero(info["free_i"])
        k = R.size
        solver_used, bw = "none", 0
        if k:
            loc = np.full(ns, -1, dtype=np.int64)
            loc[R] = np.arange(k)
            cdiag = info["mass"][R] / (abs(lam) * info["w"][R])
            U = S[R]
            if info["rowid"] is None:   # compiled assembly (see _classify)
                ri, ci, vi, rhs, VU = self._assemble_compiled(S, R, loc, cdiag, Rb, Xb)
            else:
                ri, ci, vi, rhs, VU = self._assemble_numpy(S, R, loc, cdiag, Rb, Xb, info)
            Xi, solver_used, bw = self._solve_spd(k, ri, ci, vi, cdiag + info["deg"][R], rhs)
            bad = ~np.isfinite(Xi).all(axis=1)
            if bad.any():
                Xi[bad] = VU[bad]
        # --- result: V + sign(λ)(X − V) --------------------------------------------------
        idx_parts, new_parts, old_parts = [], [], []
        if Rb.size:
            Ub = S[Rb]
            Vb = V.take(Ub, axis=0, mode="clip")
            idx_parts.append(Ub)
            old_parts.append(Vb)
            new_parts.append(Xb if lam_b >= 0 else Vb - (Xb - Vb))
        if k:
            idx_parts.append(U)
            old_parts.append(VU)
            new_parts.append(Xi if lam >= 0 else VU - (Xi - VU))
        if not idx_parts:
            z = np.zeros((0, 3))
            return Dab(c, self._radius, np.zeros(0, np.int64), z, z, rim=self._perm[rim], n_inside=ns,
                       _internal=np.zeros(0, np.int64))
        if len(idx_parts) == 1:
            idx, new, old = idx_parts[0], new_parts[0], old_parts[0]
        else:
            idx, new, old = (np.concatenate(p) for p in (idx_parts, new_parts, old_parts))
        return Dab(c, self._radius, self._perm[idx], new, old, rim=self._perm[rim], n_inside=ns,
                   solver=solver_used, bandwidth=bw, notes=self._notes, _internal=idx)

    def _assemble_compiled(self, S, R, loc, cdiag, Rb, Xb):
        """The interior system of a dab in one compiled pass (``brush_assemble``):
        off-diagonal entries (ri, ci, vi), grouped by row, the right-hand side and the positions."""
        ns, k = S.size, R.size
        U = S[R]
        bl = np.full(ns, -1, dtype=np.int64)
        if Rb.size:
            bl[Rb] = np.arange(Rb.size)
        nent = int(self._vn_ptr.take(U + 1, mode="clip").sum() - self._vn_ptr.take(U, mode="clip").sum())
        ri = np.empty(nent, np.int64)
        ci = np.empty(nent, np.int64)
        vi = np.empty(nent)
        rhs = np.empty((k, 3))
        VU = np.empty((k, 3))
        m = kernels.get(self._n, min_size=0).brush_assemble(
            S, R, loc, self._slot, self._vn_ptr, self._vn_nb, self._vn_pair, self._pw, self._V, cdiag, bl,
            np.ascontiguousarray(Xb, dtype=np.float64), ri, ci, vi, rhs, VU)
        return ri[:m], ci[:m], vi[:m], rhs, VU

    def _assemble_numpy(self, S, R, loc, cdiag, Rb, Xb, info):
        """The same system as :meth:`_assemble_compiled`, from the neighbour lists of ``_classify``."""
        V = self._V
        ns, k = S.size, R.size
        rowid, snb, pwe = info["rowid"], info["snb"], info["pwe"]
        lr = loc.take(rowid, mode="clip")
        sel = np.flatnonzero(lr >= 0)
        r_loc = lr.take(sel, mode="clip")
        nbr = snb.take(sel, mode="clip")      # neighbours of free rows are all inside
        c_loc = loc.take(nbr, mode="clip")
        w_e = pwe.take(sel, mode="clip")
        inm = c_loc >= 0
        VU = V.take(S[R], axis=0, mode="clip")
        rhs = cdiag[:, None] * VU
        cp = np.flatnonzero(~inm)
        if cp.size:
            rows_c = r_loc[cp]
            Xn = V.take(S[nbr[cp]], axis=0, mode="clip")
            if Rb.size:
                # neighbours solved on the boundary enter with their new (pre-sign) value
                bl = np.full(ns, -1, dtype=np.int64)
                bl[Rb] = np.arange(Rb.size)
                j = bl[nbr[cp]]
                hit = j >= 0
                if hit.any():
                    Xn[hit] = Xb[j[hit]]
            wc = w_e[cp]
            for q in range(3):
                rhs[:, q] += np.bincount(rows_c, wc * Xn[:, q], minlength=k)
        m = np.flatnonzero(inm)
        return r_loc.take(m, mode="clip"), c_loc.take(m, mode="clip"), -w_e.take(m, mode="clip"), rhs, VU

    def _solve_boundary(self, S: np.ndarray, info: dict):
        """flow's boundary step on the free boundary vertices of the region."""
        V = self._V
        ns = S.size
        Rb = np.flatnonzero(info["free_b"])
        Ub = S[Rb]
        ent, lens = _csr_ranges(self._vb_ptr, Ub)
        row = np.repeat(np.arange(Rb.size), lens)
        nb = self._vb_nb[ent]
        keep = self._vlock[nb] == 0             # flow drops umbrella edges with a locked end
        row, nb = row[keep], nb[keep]
        snb = self._slot[nb]                    # face neighbours of non-rim vertices: inside
        diff = V.take(Ub[row], axis=0, mode="clip") - V.take(nb, axis=0, mode="clip")
        e = 1.0 / np.sqrt(np.einsum("ij,ij->i", diff, diff))
        Esum = np.bincount(row, e, minlength=Rb.size)
        ok = Esum > 0
        if not ok.all():                        # no usable umbrella edge: the vertex stays
            sub = np.flatnonzero(ok)
            remap = np.full(ok.size, -1, dtype=np.int64)
            remap[sub] = np.arange(sub.size)
            row = remap[row]
            m = row >= 0
            row, nb, snb, e = row[m], nb[m], snb[m], e[m]
            Rb, Ub, Esum = Rb[sub], Ub[sub], Esum[sub]
            if Rb.size == 0:
                return Rb, np.zeros((0, 3))
        kb = Rb.size
        bloc = np.full(ns, -1, dtype=np.int64)
        bloc[Rb] = np.arange(kb)
        col = bloc[snb]
        cb = Esum / (abs(self._lam_b) * info["w"][Rb])
        rhs = cb[:, None] * V.take(Ub, axis=0, mode="clip")
        cp = col < 0
        if cp.any():
            for q in range(3):
                rhs[:, q] += np.bincount(row[cp], e[cp] * V[nb[cp], q], minlength=kb)
        m = ~cp
        # rows come grouped by vertex, but in the order of Rb, so sort the entries by row
        X, _, _ = self._solve_spd(kb, row[m], col[m], -e[m], cb + Esum, rhs, grouped=False)
        bad = ~np.isfinite(X).all(axis=1)
        if bad.any():
            X[bad] = V[Ub[bad]]
        return Rb, X

    # --- linear algebra ---------------------------------------------------------------
    def _solve_spd(self, k: int, ri, ci, vi, diag, rhs, grouped: bool = True):
        """Solve the SPD system with off-diagonal entries (ri, ci, vi) — both triangles,
        rows grouped in increasing order when ``grouped`` — and diagonal ``diag``."""
        method = self.solver
        if method == "auto" and grouped and k >= SPLIT_MIN:
            res = self._split(k, ri, ci, vi, diag, rhs)
            if res is not None:
                return res
        up = ri < ci
        ru, cu = ri[up], ci[up]
        bw = int((cu - ru).max()) if ru.size else 0
        if method in ("auto", "banded"):
            perm = None
            vu = vi[up]
            # a local reordering pays when the global order's band is much wider
            # than the ~1.2 sqrt(k) it usually reaches (see LOCAL_RCM_WORK)
            if k * (bw * bw - 1.44 * k) > LOCAL_RCM_WORK and k > 2:
                p, inv = self._local_rcm(k, ri, ci, grouped)
                x, y = inv[ru], inv[cu]
                lo, hi = np.minimum(x, y), np.maximum(x, y)
                bw2 = int((hi - lo).max())
                if bw2 < bw:
                    perm, bw, ru, cu = p, bw2, lo, hi
            if method == "banded" or k * bw * bw <= BANDED_MAX_WORK:
                stored = _lapack_band(bw, k)   # the report keeps the true band
                if perm is None:
                    X = self._banded(k, ru, cu, vu, diag, rhs, stored)
                else:
                    X = self._banded(k, ru, cu, vu, diag.take(perm, mode="clip"),
                                     rhs.take(perm, axis=0, mode="clip"), stored)
                    if X is not None:
                        out = np.empty_like(X)
                        out[perm] = X
                        X = out
                if X is not None:
                    return X, "banded", bw
                method = "auto"
        if method == "cholesky" or (method == "auto" and k > 2000):
            from .solvers import cholesky_available

            if cholesky_available():
                import cholespy

                A = self._csr(k, ri, ci, vi, diag)
                f = cholespy.CholeskySolverD(k, A.indptr.astype(np.int32), A.indices.astype(np.int32),
                                             A.data, cholespy.MatrixType.CSR)
                X = np.zeros_like(rhs)
                f.solve(np.ascontiguousarray(rhs), X)
                return X, "cholesky", bw
        from scipy.sparse.linalg import splu

        A = self._csr(k, ri, ci, vi, diag)
        X = splu(A.tocsc(), permc_spec="MMD_AT_PLUS_A", options=dict(SymmetricMode=True)).solve(rhs)
        return X, "lu", bw

    @staticmethod
    def _csr(k, ri, ci, vi, diag) -> sp.csr_matrix:
        d = np.arange(k)
        return sp.csr_matrix((np.concatenate([vi, diag]), (np.concatenate([ri, d]), np.concatenate([ci, d]))),
                             shape=(k, k))

    @staticmethod
    def _local_rcm(k, ri, ci, grouped: bool = True):
        """A narrow-band order of the k unknowns: (perm, inverse).

        Cuthill–McKee (breadth-first) order from a pseudo-peripheral vertex:
        u, the last vertex reached from vertex 0, and w, the last reached from
        u (a second sweep of the search); of the two orders, the one with the
        narrower band (u's on a tie).  C-level searches (~0.05 ms each for
        2,600 unknowns) cost less than scipy's reverse Cuthill–McKee (~0.2–0.4
        ms, started from a minimum-degree vertex) and give a narrower band on
        dab regions (Spot subdivided twice, ~2,350 unknowns: 49–84, where
        scipy's RCM gave 58–130).  The second sweep narrows some bands a lot
        (31 dab systems: 106 → 90, 141 → 100, 93 → 87; none wider), ~17% less
        LAPACK time in total.  Disconnected systems use scipy's RCM.  The
        order depends on the connectivity only.
        """
        from scipy.sparse.csgraph import breadth_first_order, reverse_cuthill_mckee

        K = kernels.get(k, min_size=0)
        if grouped and K is not None:   # the same searches, compiled, without a CSR matrix
            perm, inv = np.empty(k, np.int64), np.empty(k, np.int64)
            o2, lev1, lev2 = np.empty((3, k), np.int64)
            if K.cm_order(_row_ptr(ri, k), ri, ci, perm, inv, o2, lev1, lev2):
                return perm, inv
        # float64 data: the graph routines would otherwise convert (copy) it
        if grouped:
            ptr = _row_ptr(ri, k, np.int32)
            G = sp.csr_matrix((np.ones(ri.size), ci.astype(np.int32), ptr), shape=(k, k))
        else:
            G = sp.csr_matrix((np.ones(ri.size), (ri, ci)), shape=(k, k))
        o = breadth_first_order(G, 0, directed=True, return_predecessors=False)
        if o.size == k:
            perm = breadth_first_order(G, int(o[-1]), directed=True,
                                       return_predecessors=False).astype(np.int64)
            perm2 = breadth_first_order(G, int(perm[-1]), directed=True,
                                        return_predecessors=False).astype(np.int64)
            return Brush._narrower(k, ri, ci, perm, perm2)
        perm = reverse_cuthill_mckee(G, symmetric_mode=True).astype(np.int64)
        inv = np.empty(k, np.int64)
        inv[perm] = np.arange(k)
        return perm, inv

    @staticmethod
    def _narrower(k, ri, ci, perm, perm2):
        """(perm, inverse) of the order with the narrower band over the entries (ri, ci); the first on a tie."""
        best = None
        for p in (perm, perm2):
            inv = np.empty(k, np.int64)
            inv[p] = np.arange(k)
            band = int(np.abs(inv[ri] - inv[ci]).max()) if ri.size else 0
            if best is None or band < best[0]:
                best = (band, p, inv)
        return best[1], best[2]

    def _split(self, k, ri, ci, vi, diag, rhs):
        """The system solved as two banded halves and their separator, the halves on
        two threads (``split_solve`` in the compiled kernels): (X, "split", band),
        or None where it does not apply (no kernels, one thread, no LAPACK pointers,
        no balanced cut, not numerically positive definite).

        Order: Cuthill–McKee levels of the largest connected component as
        :meth:`_local_rcm`, cut at the level of its median unknown (the
        separator S, a dense Schur complement); the levels before it (CM
        order) and after it (reversed) are the halves, so only their trailing
        rows couple to S; other components join the smaller half.  Same flops as one band of
        the same width, but each thread factors half the rows: on 36
        captured 2,400-unknown dab systems, 1.1–2.3 ms against 1.6–3.8 ms for
        the one-band solve (reordering included).  The band reported is the
        wider half's.
        """
        K = kernels.get(k, min_size=0)
        fns = None if K is None else _split_routines()
        if fns is None or K.get_num_threads() < 2:
            if K is not None and fns is None:
                self._notes.append(FALLBACKS.get("split", "split solver unavailable"))
            return None
        perm, inv, o1, o2, lev1, lev2 = np.empty((6, k), np.int64)
        dims = np.empty(7, np.int64)
        if K.split_order(_row_ptr(ri, k), ri, ci, max(64, k // 5), perm, inv, o1, o2, lev1, lev2, dims) != 0:
            return None
        band = int(max(dims[3], dims[4]))
        for h in range(2):
            dims[3 + h] = _lapack_band(int(dims[3 + h]), int(dims[h]))
        buf = self._work(K.split_work_size(dims))
        X = np.empty((k, 3))
        with _SingleThreadBLAS():
            st = K.split_solve(*fns, ri, ci, np.ascontiguousarray(vi, dtype=np.float64),
                               np.ascontiguousarray(diag, dtype=np.float64),
                               np.ascontiguousarray(rhs, dtype=np.float64), perm, inv, dims, buf, X)
        if st != 0:
            return None
        return X, "split", band

    #: largest work space (doubles) a brush keeps between dabs (16 MB)
    _WORK_KEEP = 2_000_000

    def _work(self, size: int) -> np.ndarray:
        """``size`` doubles of work space, reused dab after dab when not too large
        (fresh memory costs page faults: ~0.35 ms of a 2,600-vertex dab's ~2.4 ms solve)."""
        buf = self._work_buf
        if buf is None or buf.size < size:
            buf = np.empty(size)
            if size <= self._WORK_KEEP:
                self._work_buf = buf
        return buf[:size]

    def _banded(self, k, ru, cu, vu, diag, rhs, bw):
        """LAPACK banded Cholesky (dpbsv) from the upper entries (ru < cu), stored as
        the lower triangle;
        None if not numerically positive definite.

        The band storage is one buffer kept by the brush and reused dab after dab
        (fresh memory costs page faults: ~0.35 ms of a 2,600-vertex dab's ~2.4 ms solve).
        """
        from scipy.linalg.lapack import dpbsv

        abf = self._work((bw + 1) * k)
        abf.fill(0.0)
        ab = abf.reshape((bw + 1, k), order="F")  # entry (i, j) at i + (bw + 1) j
        # lower band storage, ab[i - j, j] = a_ij (i >= j): a little faster than
        # the upper storage in LAPACK's dpbtrf (~10%)
        abf[(cu - ru) + (bw + 1) * ru] = vu
        ab[0] = diag
        B = np.asfortranarray(rhs)
        with _SingleThreadBLAS():
            _, X, info = dpbsv(ab, B, lower=1, overwrite_ab=1, overwrite_b=1)
        if info != 0:
            return None  # a sparse LU takes over
        return np.ascontiguousarray(X)


# --------------------------------------------------------------------------
# the inflate baseline (figure 9)
# --------------------------------------------------------------------------

class InflateBrush(_BrushBase):
    """Move the vertices inside the sphere along their normals (the baseline of figure 9).

    Each dab moves vertex i by ``strength · radius · f(d_i/r) · w_i · n_i``
    (``n_i``: unit area-weighted vertex normal at the current positions, as
    :func:`shapeflow.geometry.vertex_normals`); negative strength deflates.
    Same API and thread model (calls serialised by a lock) as :class:`Brush`.
    """

    def __init__(self, mesh: Mesh, *, strength: float = 0.05, radius: float, falloff=None, weights=None,
                 undo_limit: int = 64, rebuild_fraction: float = 0.15):
        super().__init__(mesh, radius=radius, falloff=falloff, weights=weights,
                         undo_limit=undo_limit, rebuild_fraction=rebuild_fraction)
        self.strength = strength
        t = self._imesh.topology
        self._vf_ptr, order = _csr_by(t.face_indices, self._n)
        self._vf_face = t.corner_face[order]
        self._fstamp = np.zeros(t.n_faces, dtype=np.int64)
        self._tri_buf = None               # compiled cache update: the moved triangles

    @property
    @_serialised
    def strength(self) -> float:
        """Displacement per dab as a fraction of the radius (< 0 deflates)."""
        return self._strength

    @strength.setter
    @_serialised
    def strength(self, v) -> None:
        self._strength = params.number("strength", v)

    def _normals(self, S: np.ndarray) -> np.ndarray:
        """Unit area-weighted normals of vertices ``S`` (zero where undefined)."""
        t = self._imesh.topology
        ent, lens = _csr_ranges(self._vf_ptr, S)
        fv = self._vf_face[ent]
        faces = _unique_stamp(fv, self._fstamp)
        # vector area of each face: ½ Σ (v_k − v_0) × (v_{k+1} − v_0), as geometry.face_vector_areas
        off = t.face_offsets
        fsz = off[faces + 1] - off[faces]
        cent, clen = _csr_ranges(off, faces)
        corners = cent
        first = np.repeat(off[faces], fsz)
        V = self._V
        fi = t.face_indices
        base = V[fi[first]]
        a = V[fi[corners]] - base
        b = V[fi[t.corner_next[corners]]] - base
        cr = np.cross(a, b)
        starts = np.cumsum(fsz) - fsz
        fa = 0.5 * np.add.reduceat(cr, starts, axis=0)
        floc = self._fstamp  # reuse as face -> local index
        floc[faces] = np.arange(faces.size)
        nrm = np.zeros((S.size, 3))
        rows = np.repeat(np.arange(S.size), lens)
        loc = floc[fv]
        for q in range(3):
            nrm[:, q] = np.bincount(rows, fa[loc, q], minlength=S.size)
        ln = np.sqrt(np.einsum("ij,ij->i", nrm, nrm))
        ok = ln > 0
        nrm[ok] /= ln[ok, None]
        return nrm

    def _compute(self, c: np.ndarray) -> Dab:
        S, d = self._query(c, self._radius)
        if S.size == 0:
            return Dab(c, self._radius, np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros((0, 3)))
        S_order = np.argsort(S)
        S, d = S[S_order], d[S_order]
        f = self._w[S].copy()
        if self._falloff_fn is not None:
            f *= _apply_falloff(self._falloff_fn, d / self._radius)
        nrm = self._normals(S)
        move = (f != 0) & (np.abs(nrm).sum(axis=1) > 0)
        if self._strength == 0.0:
            move[:] = False
        idx = S[move]
        old = self._V[idx]
        new = old + (self._strength * self._radius * f[move])[:, None] * nrm[move]
        return Dab(c, self._radius, self._perm[idx], new, old, n_inside=S.size, solver="inflate", _internal=idx)
