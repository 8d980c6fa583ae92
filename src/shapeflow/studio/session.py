"""What one studio page edits: a mesh, its painted weights, a family of shapes and the history.

:class:`StudioSession` is the studio's model, independent of how a page talks to it: the
λ slider reads shapes from a family solved in the background (one multi-shift solve,
:func:`shapeflow.family`), the weight brush paints per-vertex weights with a smooth
falloff, the sculpt brushes (:class:`~shapeflow.sculpt.Brush`, :class:`~shapeflow.sculpt.InflateBrush`)
move the surface, and every edit is one step of a shared undo history that stores only
the vertices it changed.

Thread model: every public method takes the session's lock, so a page's event handlers may
call it from several threads; the family solve runs on a thread of its own and publishes its
shapes when complete (:meth:`StudioSession.family_status` reports its progress meanwhile).
A new solve supersedes a running one, whose result is then dropped.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from .. import params
from ..errors import ParameterError
from ..mesh import Mesh

__all__ = ["StudioSession", "FamilyStatus", "smooth_falloff"]


def smooth_falloff(t: np.ndarray) -> np.ndarray:
    """(1 − t²)² for t = distance / radius in [0, 1], 0 beyond: 1 at the centre, flat at both ends."""
    t = np.clip(np.asarray(t, np.float64), 0.0, 1.0)
    return (1.0 - t * t) ** 2


class _Superseded(Exception):
    """Raised inside a family solve whose result nobody wants any more."""


@dataclass
class FamilyStatus:
    """Where the background family solve stands."""

    state: str = "none"            #: "none", "running", "done" or "failed"
    done: int = 0
    total: int = 0
    lams: list = field(default_factory=list)
    error: str | None = None


@dataclass
class _Step:
    """One undo step: the vertices it touched, before and after (positions and weights)."""

    what: str
    idx: np.ndarray
    v_before: np.ndarray
    v_after: np.ndarray
    w_before: np.ndarray
    w_after: np.ndarray


class StudioSession:
    """The editable state of one studio page (see the module docstring for the thread model).

    Parameters
    ----------
    mesh : Mesh
        What is edited; its ``"weight"`` attribute, when present, is the start of the weights.
    undo_steps : int
        History length (older steps are forgotten).
    """

    def __init__(self, mesh: Mesh, *, undo_steps: int = 64):
        from ..geometry.weld import weld_if_split
        from ..mesh.convert import as_mesh

        mesh = as_mesh(mesh, "the studio's mesh")
        self._lock = threading.RLock()
        self._input = mesh
        mesh = weld_if_split(mesh)      # seams and soups: one vertex per point, as the command line does
        self._base = mesh
        self._V = np.array(mesh.vertices, dtype=np.float64)
        w = mesh.weights
        self._w = np.ones(mesh.n_vertices) if w is None else np.array(w, dtype=np.float64)
        self._undo: list[_Step] = []
        self._redo: list[_Step] = []
        self._max = params.integer("undo_steps", undo_steps, lo=1, hi=10_000)
        self._family: np.ndarray | None = None
        self._status = FamilyStatus()
        self._job = 0
        self._thread: threading.Thread | None = None
        self._brush = None
        self._brush_key = None
        self.version = 0      #: increases with every change of positions or weights
        self._shape_version = 0

    # --- state ---------------------------------------------------------
    @property
    def base(self) -> Mesh:
        """The mesh the session edits, at the positions it was opened with (welded where the input's
        vertices were split: see :attr:`welded`)."""
        return self._base

    @property
    def welded(self) -> bool:
        """Whether the input's vertices were split at seams (or formed a soup) and the session edits
        them welded (:func:`shapeflow.weld`): :attr:`vertices` has one row per welded vertex,
        :attr:`mesh` the input's own layout."""
        return self._base is not self._input

    @property
    def n_input_vertices(self) -> int:
        """The vertex count of the mesh as opened (before welding)."""
        return self._input.n_vertices

    @property
    def mesh(self) -> Mesh:
        """The current mesh on the input's own layout (a welded session's copies of a vertex all get
        its position and weight), weights as its ``"weight"`` attribute, the input's attributes kept."""
        with self._lock:
            V, w = self._V.copy(), self._w.copy()
        if not self.welded:
            return self._base.with_vertices(V).with_weights(w)
        from ..geometry.weld import unweld

        wmap = self._base.weld_map
        return unweld(self._base.with_vertices(V), self._input, self._base).with_weights(w[wmap])

    @property
    def vertices(self) -> np.ndarray:
        with self._lock:
            return self._V.copy()

    def vertices_at(self, idx) -> np.ndarray:
        """The current positions of the vertices ``idx`` (a copy)."""
        with self._lock:
            return self._V[np.asarray(idx, np.int64)]

    @property
    def weights(self) -> np.ndarray:
        with self._lock:
            return self._w.copy()

    # --- history -------------------------------------------------------
    def _record(self, what: str, idx: np.ndarray, V_new: np.ndarray | None, w_new: np.ndarray | None) -> None:
        idx = np.asarray(idx, np.int64)
        step = _Step(what, idx, self._V[idx].copy(), self._V[idx].copy() if V_new is None else V_new,
                     self._w[idx].copy(), self._w[idx].copy() if w_new is None else w_new)
        self._apply(step.idx, step.v_after, step.w_after)
        self._undo.append(step)
        del self._undo[:-self._max]
        self._redo.clear()

    def _apply(self, idx, V, w) -> None:
        if not np.array_equal(self._V[idx], V):
            self._shape_version += 1          # the brush holds positions: it is rebuilt when they change
        self._V[idx] = V
        self._w[idx] = w
        self.version += 1

    def undo(self) -> bool:
        """Take back the last step; False when there is none."""
        with self._lock:
            if not self._undo:
                return False
            step = self._undo.pop()
            self._apply(step.idx, step.v_before, step.w_before)
            self._redo.append(step)
            return True

    def redo(self) -> bool:
        """Do the last undone step again; False when there is none."""
        with self._lock:
            if not self._redo:
                return False
            step = self._redo.pop()
            self._apply(step.idx, step.v_after, step.w_after)
            self._undo.append(step)
            return True

    @property
    def can_undo(self) -> bool:
        return bool(self._undo)

    @property
    def can_redo(self) -> bool:
        return bool(self._redo)

    # --- weights -------------------------------------------------------
    def set_weights(self, weights) -> None:
        """Replace every weight (one undo step), e.g. by weights read from a file: one number per
        vertex in [0, 1]."""
        from ..flow.options import resolve_weights

        if weights is None:
            raise ParameterError("weights must be one number per vertex in [0, 1], got None")
        with self._lock:
            if self.welded and np.ndim(weights) == 1 and len(weights) == self._input.n_vertices:
                # one weight per vertex of the file as opened: each welded vertex takes its first copy's
                first = np.unique(self._base.weld_map, return_index=True)[1]
                weights = np.asarray(weights)[first]
            w = resolve_weights(self._base, weights)
            self._record("weights", np.arange(self._V.shape[0]), None, w)

    def paint(self, center, radius: float, *, value: float = 1.0, strength: float = 1.0) -> np.ndarray:
        """Move the weights inside the sphere towards ``value`` by ``strength × (1 − (d/r)²)²``;
        returns the vertices touched (one undo step)."""
        c = params.real_array("center", center)
        if c.shape != (3,):
            raise ParameterError(f"center must be 3 numbers, got shape {c.shape}")
        r = params.number("radius", radius)
        if not r > 0:
            raise ParameterError(f"radius must be > 0, got {radius!r}")
        v = params.number("value", value)
        s = params.number("strength", strength)
        if not (0.0 <= v <= 1.0 and 0.0 <= s <= 1.0):
            raise ParameterError(f"value and strength must lie in [0, 1], got {value!r} and {strength!r}")
        with self._lock:
            d = np.linalg.norm(self._V - c, axis=1)
            idx = np.flatnonzero(d < r)
            if idx.size:
                w = self._w[idx] + (v - self._w[idx]) * (s * smooth_falloff(d[idx] / r))
                self._record("paint", idx, None, w)
            return idx

    # --- sculpt --------------------------------------------------------
    def dab(self, center, *, radius: float, lam: float = -50.0, inflate: bool = False,
            strength: float = 0.05) -> np.ndarray:
        """One dab of the enhancement brush (or, with ``inflate``, the inflate brush) at ``center``,
        the painted weights scaling it; returns the vertices moved (one undo step)."""
        from ..sculpt import Brush, InflateBrush

        with self._lock:
            key = (self._shape_version, bool(inflate))
            if self._brush is None or self._brush_key != key:
                mesh = self._base.with_vertices(self._V.copy())
                self._brush = (InflateBrush(mesh, radius=radius, strength=strength, weights=self._w.copy())
                               if inflate else Brush(mesh, radius=radius, lam=lam, weights=self._w.copy()))
            b = self._brush
            b.set_weights(self._w.copy())     # painted since the brush was built: no rebuild for that
            b.radius = radius
            if inflate:
                b.strength = strength
            else:
                b.lam = lam
            moved = np.asarray(b.dab(center), np.int64)
            if moved.size:
                self._record("dab", moved, np.array(b.vertices[moved]), None)
            self._brush_key = (self._shape_version, bool(inflate))     # the brush holds exactly these positions
            return moved

    # --- the family of shapes ------------------------------------------
    def solve_family(self, lams: Sequence[float], *, wait: bool = False, **flow_options) -> None:
        """Solve the flow for every λ of ``lams`` from the current shape and weights, in the background
        (``wait=True``: here).  Options as for :func:`shapeflow.family`."""
        from ..flow.family import family

        lam_arr = np.sort(np.unique(params.real_array("lams", lams)))
        if lam_arr.size == 0:
            raise ParameterError("lams must hold at least one λ")
        with self._lock:
            self._job += 1
            job = self._job
            mesh = self._base.with_vertices(self._V.copy())
            w = self._w.copy()
            self._status = FamilyStatus("running", 0, int(lam_arr.size), lam_arr.tolist())
            self._family = None

        def progress(done, total):
            with self._lock:
                if job != self._job:
                    raise _Superseded      # a newer solve was asked for: this one stops here
                self._status.done, self._status.total = int(done), int(total)

        def work(previous):
            if previous is not None:
                previous.join()            # one solve at a time: the superseded one ends first
            try:
                with self._lock:
                    if job != self._job:
                        return
                shapes = family(mesh, lam_arr, weights=w, progress=progress, **flow_options)
                with self._lock:
                    if job == self._job:
                        self._family = np.asarray(shapes)
                        self._status.state, self._status.done = "done", self._status.total
            except _Superseded:
                pass
            except Exception as exc:   # reported through family_status, never lost in a thread
                with self._lock:
                    if job == self._job:
                        self._status.state, self._status.error = "failed", f"{type(exc).__name__}: {exc}"

        with self._lock:
            previous, self._thread = self._thread, None
        if wait:
            work(previous)
        else:
            t = threading.Thread(target=work, args=(previous,), name="shapeflow-studio-family", daemon=True)
            with self._lock:
                self._thread = t
            t.start()

    def wait_family(self, timeout: float | None = None) -> FamilyStatus:
        """Wait until the current family solve ends (or ``timeout`` seconds pass); its status."""
        with self._lock:
            t = self._thread
        if t is not None:
            t.join(timeout)
        return self.family_status()

    def family_status(self) -> FamilyStatus:
        with self._lock:
            s = self._status
            return FamilyStatus(s.state, s.done, s.total, list(s.lams), s.error)

    def shape_at(self, lam: float) -> np.ndarray:
        """Positions for ``lam`` from the solved family: a member itself, or the linear blend of the two
        members around it (clamped to the range solved)."""
        lam = params.number("lam", lam)
        with self._lock:
            if self._family is None:
                raise ParameterError("no family solved yet (solve_family, then wait for family_status 'done')")
            lams = np.asarray(self._status.lams)
            if lam <= lams[0]:
                return self._family[0].copy()
            if lam >= lams[-1]:
                return self._family[-1].copy()
            k = int(np.searchsorted(lams, lam))
            if lams[k] == lam:
                return self._family[k].copy()
            t = (lam - lams[k - 1]) / (lams[k] - lams[k - 1])
            return (1.0 - t) * self._family[k - 1] + t * self._family[k]

    def apply_shape(self, lam: float) -> None:
        """Make :meth:`shape_at` the current shape (one undo step)."""
        with self._lock:
            V = self.shape_at(lam)
            self._record("family", np.arange(self._V.shape[0]), V, None)

    # --- colour fields ---------------------------------------------------
    FIELDS = ("weights", "curvature", "displacement")

    def field(self, name: str, *, lam: float | None = None) -> np.ndarray:
        """Per-vertex values to colour the surface by: the weights, the signed mean curvature
        (barycentric areas: it converges to H), or the displacement from the input along the
        input's vertex normals (> 0 outwards).  With ``lam``, of the family's shape at ``lam``
        (:meth:`shape_at`: what the slider previews) instead of the current shape."""
        if name not in self.FIELDS:
            raise ParameterError(f"unknown field {name!r}; choose one of {', '.join(self.FIELDS)}")
        with self._lock:
            if name == "weights":
                return self._w.copy()
            V = self._V.copy() if lam is None else self.shape_at(lam)
            if name == "curvature":
                from ..operators.curvature import mean_curvature

                return mean_curvature(self._base.with_vertices(V), area="barycentric")
            from ..geometry.normals import vertex_normals

            return np.einsum("ij,ij->i", V - self._base.vertices, vertex_normals(self._base))

    @property
    def input_vertices(self) -> np.ndarray:
        """The positions the session started from (what the split view shows as "before")."""
        return np.array(self._base.vertices, dtype=np.float64)

    # --- files -----------------------------------------------------------
    @classmethod
    def open(cls, path, **kw) -> "StudioSession":
        from ..io import load

        return cls(load(path), **kw)

    def save(self, path, **kw) -> None:
        """Write the current mesh (weights as the ``"weight"`` attribute where the format keeps it)."""
        from ..io import save

        save(path, self.mesh, **kw)
