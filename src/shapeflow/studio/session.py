"""What one studio page edits: a mesh, its painted weights, a family of shapes and the history.

:class:`StudioSession` is the studio's model, independent of how a page talks to it: the
λ slider reads shapes from a family solved in the background (one multi-shift solve,
:func:`shapeflow.family`), the weight brush paints per-vertex weights with a smooth
falloff, the sculpt brushes (:class:`~shapeflow.sculpt.Brush`, :class:`~shapeflow.sculpt.InflateBrush`)
move the surface, and every edit is one step of a shared undo history that stores only
the vertices it changed (:mod:`~shapeflow.studio.history`): a stroke (:meth:`StudioSession.begin_stroke`
… :meth:`StudioSession.end_stroke`) is one step, and the history is bounded in bytes.  With
``mirror=True`` a brush or paint dab is repeated across the model's plane of symmetry
(:meth:`StudioSession.mirrored`), both in one step.

Thread model: every public method takes the session's lock, so a page's event handlers may
call it from several threads; the family solve runs on a thread of its own and publishes its
shapes when complete (:meth:`StudioSession.family_status` reports its progress meanwhile).
A new solve supersedes a running one, whose result is then dropped; until a solve completes, the
shapes of the previous one stay available for previews while the positions they were solved from
are still the current ones (:attr:`StudioSession.can_preview`: a weight change keeps them).
"""

from __future__ import annotations

import contextlib
import threading
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from .. import params
from ..errors import ParameterError
from ..mesh import Mesh
from .blend import Sculptor
from .history import History
from .sharp import SharpFeatures

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


class StudioSession(SharpFeatures):
    """The editable state of one studio page (see the module docstring for the thread model).

    Parameters
    ----------
    mesh : Mesh
        What is edited; its ``"weight"`` attribute, when present, is the start of the weights.
    history_bytes : int, optional
        The most memory the undo history may hold (older steps are forgotten first; default
        :func:`~shapeflow.studio.history.default_limit`: 256 MiB, less on a machine with less
        than 1 GiB available).
    """

    def __init__(self, mesh: Mesh, *, history_bytes: int | None = None):
        from ..geometry.weld import weld_if_split
        from ..mesh.convert import as_mesh

        mesh = as_mesh(mesh, "the studio's mesh")
        if mesh.n_faces == 0:
            raise ParameterError(f"{mesh.metadata.get('name') or 'the mesh'} has no faces "
                                 f"({mesh.n_vertices:,} points): the studio edits surfaces")
        self._lock = threading.RLock()
        self._input = mesh
        mesh = weld_if_split(mesh)      # seams and soups: one vertex per point, as the command line does
        self._base = mesh
        self._V = np.array(mesh.vertices, dtype=np.float64)
        w = mesh.weights
        self._w = np.ones(mesh.n_vertices) if w is None else np.array(w, dtype=np.float64)
        self._history = History(history_bytes)
        self._family: np.ndarray | None = None
        self._family_lams: np.ndarray | None = None
        self._family_shape = -1           # the shape version the held family was solved from
        self._status = FamilyStatus()
        self._job = 0
        self._thread: threading.Thread | None = None
        self._sculpt = Sculptor()         # the brushes, and the open stroke's blend
        self.version = 0      #: increases with every change of positions or weights
        self._shape_version = 0
        self._axes = None
        self._front = None

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
        its position and weight), the weights as its ``"weight"`` attribute when the input had one or
        any weight is not 1 (the default: a mesh nobody painted carries none, so no format is said to
        drop them), the input's attributes kept, and :attr:`front` as ``metadata["front"]``."""
        with self._lock:
            V, w = self._V.copy(), self._w.copy()
        if self._input.weights is None and np.all(w == 1.0):
            w = None
        if not self.welded:
            out = self._base.with_vertices(V).with_weights(w)
        else:
            from ..geometry.weld import unweld

            out = unweld(self._base.with_vertices(V), self._input, self._base)
            out = out.with_weights(None if w is None else w[self._base.weld_map])
        return out if self.front is None else out.with_metadata(front=self.front)

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
    def _record(self, what: str, idx, V_new: np.ndarray | None, w_new: np.ndarray | None, *,
                alone: bool = False) -> None:
        idx = np.asarray(idx, np.int64)
        self._history.record(what, idx, self._V, self._w, lambda: self._apply(idx, V_new, w_new), alone=alone)

    def _apply(self, idx, V, w) -> None:
        if V is not None and not np.array_equal(self._V[idx], V):
            self._shape_version += 1          # the brush holds positions: it is rebuilt when they change
            self._V[idx] = V
        if w is not None:
            self._w[idx] = w
        self.version += 1

    def begin_stroke(self, what: str = "stroke") -> None:
        """From now until :meth:`end_stroke`, every edit is part of one undo step (a stroke already
        open is closed first)."""
        with self._lock:
            self._history.close(self._V, self._w)
            self._history.open(what, self._V.shape[0])
            self._sculpt.end()

    def end_stroke(self) -> bool:
        """Close the open stroke (its edits become one undo step); False when none was open."""
        with self._lock:
            self._sculpt.end()
            return self._history.close(self._V, self._w)

    @property
    def in_stroke(self) -> bool:
        with self._lock:
            return self._history.grouping

    def undo(self) -> bool:
        """Take back the last step (an open stroke is closed first); False when there is none."""
        with self._lock:
            step = self._history.back(self._V, self._w)
            if step is None:
                return False
            self._apply(step.idx, step.v_before, step.w_before)
            return True

    def redo(self) -> bool:
        """Do the last undone step again; False when there is none."""
        with self._lock:
            step = self._history.forward(self._V, self._w)
            if step is None:
                return False
            self._apply(step.idx, step.v_after, step.w_after)
            return True

    @property
    def can_undo(self) -> bool:
        with self._lock:
            return bool(self._history.undo) or self._history.pending

    @property
    def can_redo(self) -> bool:
        with self._lock:
            return bool(self._history.redo)

    @property
    def history_bytes(self) -> tuple[int, int]:
        """(bytes the undo history holds, its limit)."""
        with self._lock:
            return self._history.bytes, self._history.limit

    @property
    def modified(self) -> bool:
        """Whether the mesh or its weights differ from the state as opened or last saved
        (:meth:`save`, :meth:`mark_saved`); undoing back to that state makes it False again."""
        with self._lock:
            return self._history.modified

    def saved_mesh(self) -> tuple[Mesh, object]:
        """The current :attr:`mesh` and a mark of its state, for :meth:`mark_saved` once it is written
        (an open stroke is closed first)."""
        with self._lock:
            self._history.close(self._V, self._w)
            return self.mesh, self._history.mark()

    def mark_saved(self, mark) -> None:
        """The state ``mark`` (from :meth:`saved_mesh`) was written out: :attr:`modified` counts from it."""
        with self._lock:
            self._history.mark_saved(mark)

    # --- weights -------------------------------------------------------
    def set_weights(self, weights) -> None:
        """Replace every weight (one undo step), e.g. by weights read from a file: one number per
        vertex in [0, 1]."""
        from ..mesh.weights import resolve_weights

        if weights is None:
            raise ParameterError("weights must be one number per vertex in [0, 1], got None")
        with self._lock:
            if self.welded and np.ndim(weights) == 1 and len(weights) == self._input.n_vertices:
                # one weight per vertex of the file as opened: each welded vertex takes its first copy's
                first = np.unique(self._base.weld_map, return_index=True)[1]
                weights = np.asarray(weights)[first]
            w = resolve_weights(self._base, weights)
            self._history.close(self._V, self._w)       # not part of a stroke: one that is open ends here
            self._record("weights", np.arange(self._V.shape[0]), None, w)

    def paint(self, center, radius: float, *, value: float = 1.0, strength: float = 1.0, on=None,
              mirror: bool = False) -> np.ndarray:
        """Move the weights inside the sphere towards ``value`` by ``strength × (1 − (d/r)²)²``;
        returns the vertices touched (one undo step, or part of the open stroke).  ``on``: the
        positions the distances are measured on (default the current ones; the studio passes the
        shape its slider previews, which is what the pointer touched).  ``mirror``: the same dab
        across the plane of symmetry as well (:meth:`mirrored`)."""
        c, r = self._point("center", center), self._radius(radius)
        v = params.number("value", value)
        s = params.number("strength", strength)
        if not (0.0 <= v <= 1.0 and 0.0 <= s <= 1.0):
            raise ParameterError(f"value and strength must lie in [0, 1], got {value!r} and {strength!r}")
        with self._lock:
            P = self._V if on is None else np.asarray(on, np.float64)
            if P.shape != self._V.shape:
                raise ParameterError(f"on must hold {self._V.shape[0]} positions, got shape {P.shape}")
            touched = []
            centres = self._centres(c, r, mirror)
            with self._grouped("paint", len(centres)):
                for cc in centres:
                    d = np.linalg.norm(P - cc, axis=1)
                    idx = np.flatnonzero(d < r)
                    if idx.size:
                        w = self._w[idx] + (v - self._w[idx]) * (s * smooth_falloff(d[idx] / r))
                        self._record("paint", idx, None, w)
                        touched.append(idx)
            return np.unique(np.concatenate(touched)) if touched else np.zeros(0, np.int64)

    # --- sculpt --------------------------------------------------------
    def dab(self, center, *, radius: float, lam: float = -50.0, inflate: bool = False,
            strength: float = 0.05, mirror: bool = False) -> np.ndarray:
        """One dab of the enhancement brush (or, with ``inflate``, the inflate brush) at ``center``,
        the painted weights scaling it; returns the vertices moved (one undo step, or part of the open
        stroke).  ``mirror``: the same dab across the plane of symmetry as well.  The enhancement
        brush has the smooth falloff, and the dabs of one stroke (a mirrored dab's two included) do not
        compound: each is solved on the shape the stroke began on and the stroke blends them
        (:mod:`~shapeflow.studio.blend`)."""
        c, r = self._point("center", center), self._radius(radius)
        with self._lock:
            sc = self._sculpt
            centres = self._centres(c, r, mirror)
            sc.brush_for(self._shaped, self._shape_version, self._V.shape[0],
                         lambda: self._dab_weights(self._w.copy()), self._brush_features, inflate=bool(inflate),
                         blend=self._history.grouping or len(centres) > 1, radius=r, lam=lam, strength=strength)
            moved = []
            with self._grouped("dab", len(centres)):
                for cc in centres:
                    m, new = sc.dab(cc)
                    if m.size:
                        self._record("dab", m, new, None)
                        moved.append(m)
            sc.settled(self._shape_version)
            if not self._history.grouping:
                sc.end()                     # a lone (mirrored) dab's blend ends with it
            return np.unique(np.concatenate(moved)) if moved else np.zeros(0, np.int64)

    def ready_brush(self) -> None:
        """Build the enhancement brush on the current shape now if the last stroke left it behind (the
        studio does it when a stroke ends, so that the next one starts at once).  The build holds no
        lock: the session answers meanwhile, and a brush the shape has outrun is not kept."""
        with self._lock:
            key, version = self._sculpt.key, self._shape_version
            if key is None or key[1] or key[0] == version or self._history.grouping:
                return
            mesh, w, sharp = self._shaped(), self._w.copy(), self._brush_features(False)
        brush = self._sculpt.build(mesh, w, sharp)
        with self._lock:
            if self._sculpt.key == key and self._shape_version == version and not self._history.grouping:
                self._sculpt.brush, self._sculpt.key = brush, (version, False)

    def _shaped(self) -> Mesh:
        """The welded mesh at the current positions (what a brush is built on)."""
        return self._base.with_vertices(self._V.copy())

    # --- symmetry ----------------------------------------------------------
    @property
    def up_axis(self) -> str:
        """The model's up axis by the project's view rule: ``z`` for STL files (as the command line's
        pictures, :func:`shapeflow.cli.images.up_axis`), else ``y``."""
        return "z" if "stl" in self._input.metadata else "y"

    @property
    def front(self) -> str | None:
        """The axis the model faces: the one set here, else the one its ``metadata["front"]`` names (the
        bundled Spot: ``-z``); None when neither names one (or names one along the up axis): the view
        rule's default then.  Setting it (None: back to the file's) turns the views and the mirror
        plane, and :attr:`mesh` carries it in its metadata."""
        from ..rendering.style import frame

        f = self._front if self._front is not None else self._input.metadata.get("front")
        try:
            frame(self.up_axis, f)
        except ParameterError:
            return None
        return f

    @front.setter
    def front(self, axis) -> None:
        from ..rendering.style import frame

        if axis is not None:
            frame(self.up_axis, axis)        # ParameterError: not an axis, or one along the up axis
            axis = str(axis).strip().lower()
        with self._lock:
            self._front, self._axes = axis, None

    @property
    def axes(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(right, up, front) unit axes of the model (:func:`shapeflow.rendering.style.frame` of
        :attr:`up_axis` and :attr:`front`)."""
        if self._axes is None:
            from ..rendering.style import frame

            self._axes = frame(self.up_axis, self.front)
        return self._axes

    @property
    def mirror_origin(self) -> np.ndarray:
        """A point of the plane of symmetry: the centre of the input's bounding box."""
        V = self._base.vertices
        return 0.5 * (V.min(axis=0) + V.max(axis=0)) if len(V) else np.zeros(3)

    def mirrored(self, point) -> np.ndarray:
        """``point`` reflected across the model's plane of symmetry: the plane through the centre of
        the input's bounding box normal to the model's side axis (its right, :attr:`axes`), x = 0 in
        the model's frame."""
        p = self._point("point", point)
        right = self.axes[0]
        return p - 2.0 * float((p - self.mirror_origin) @ right) * right

    def _centres(self, c: np.ndarray, r: float, mirror: bool) -> list:
        """The dab's centres: ``c``, and with ``mirror`` its reflection unless that lies within a
        quarter radius of ``c`` (a dab on the plane itself is not doubled)."""
        if not mirror:
            return [c]
        m = self.mirrored(c)
        with np.errstate(over="ignore"):          # a point far out: inf, two dabs (the far one moves nothing)
            near = np.linalg.norm(m - c) < 0.25 * r
        return [c] if near else [c, m]

    @staticmethod
    def _radius(radius) -> float:
        r = params.number("radius", radius)
        if not r > 0:
            raise ParameterError(f"radius must be > 0, got {radius!r}")
        return r

    @staticmethod
    def _point(name: str, x) -> np.ndarray:
        c = params.real_array(name, x)
        if c.shape != (3,):
            raise ParameterError(f"{name} must be 3 numbers, got shape {c.shape}")
        if not np.isfinite(c).all():
            raise ParameterError(f"{name} must be 3 finite numbers, got {c.tolist()!r}")
        return c

    @contextlib.contextmanager
    def _grouped(self, what: str, edits: int):
        """One step for the ``edits`` edits the block records (inside an open stroke: part of it)."""
        if self._history.grouping or edits < 2:
            yield
            return
        self._history.open(what, self._V.shape[0])
        try:
            yield
        finally:
            self._history.close(self._V, self._w)

    # --- the family of shapes ------------------------------------------
    def solve_family(self, lams: Sequence[float], *, wait: bool = False, **flow_options) -> None:
        """Solve the flow for every λ of ``lams`` from the current shape and weights, in the background
        (``wait=True``: here).  Options as for :func:`shapeflow.family`.  The shapes of the previous
        solve stay available to :meth:`shape_at` until this one completes."""
        from ..flow.family import family

        lam_arr = np.sort(np.unique(params.real_array("lams", lams)))
        if lam_arr.size == 0:
            raise ParameterError("lams must hold at least one λ")
        with self._lock:
            self._job += 1
            job = self._job
            mesh = self._base.with_vertices(self._V.copy())
            w = self._w.copy()
            shape = self._shape_version
            flow_options = {**self.feature_options(), **flow_options}     # sharp edges kept (studio.sharp)
            self._status = FamilyStatus("running", 0, int(lam_arr.size), lam_arr.tolist())

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
                        self._family, self._family_lams, self._family_shape = np.asarray(shapes), lam_arr, shape
                        self._status.state, self._status.done = "done", self._status.total
            except _Superseded:
                pass
            except Exception as exc:   # reported through family_status, never lost in a thread
                from ..errors import ShapeflowError

                with self._lock:
                    if job == self._job:
                        why = str(exc) if isinstance(exc, ShapeflowError) else f"{type(exc).__name__}: {exc}"
                        self._status.state, self._status.error = "failed", why

        with self._lock:                   # the swap and the start at once: a thread joined is a started one
            previous, self._thread = self._thread, None
            if not wait:
                self._thread = threading.Thread(target=work, args=(previous,), name="shapeflow-studio-family",
                                                daemon=True)
                self._thread.start()
        if wait:
            work(previous)

    def stop_family(self) -> None:
        """Stop a running solve at its next progress step (its result is dropped)."""
        with self._lock:
            if self._status.state == "running":
                self._job += 1
                self._status.state = "stopped"

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

    @property
    def can_preview(self) -> bool:
        """Whether :meth:`shape_at` has shapes solved from the current positions (the weights may have
        changed since: a solve with the new ones may be running)."""
        with self._lock:
            return self._family is not None and self._family_shape == self._shape_version

    def shape_at(self, lam: float) -> np.ndarray:
        """Positions for ``lam`` from the last completed family: a member itself, or the linear blend
        of the two members around it (clamped to the range solved)."""
        lam = params.number("lam", lam)
        with self._lock:
            if self._family is None:
                raise ParameterError("no family solved yet (solve_family, then wait for family_status 'done')")
            lams = self._family_lams
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
        """Make :meth:`shape_at` the current shape: one undo step of its own, also inside an open stroke
        (the studio applies the previewed shape when a stroke begins on it; the stroke goes on)."""
        with self._lock:
            V = self.shape_at(lam)
            self._record("family", np.arange(self._V.shape[0]), V, None, alone=True)

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
        """Write the current mesh (weights as the ``"weight"`` attribute where the format keeps it);
        :attr:`modified` is False afterwards."""
        from ..io import save

        mesh, mark = self.saved_mesh()
        save(path, mesh, **kw)
        self.mark_saved(mark)
