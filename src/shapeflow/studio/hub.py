"""What every tab shares: the session, the slider's λ, the family's options, and the handlers of the
protocol's messages (:data:`HANDLERS`, one per entry of :data:`~shapeflow.studio.protocol.MESSAGES`).

The editing model (docs/studio.md, "Editing at any slider position"):

* the slider previews the family's shape at λ; λ = 0 is the current shape;
* a sculpt dab that arrives while the slider previews λ ≠ 0 first makes the previewed shape the
  current one (one undo step of its own) and returns the slider to 0: the dab acts on what the
  user sees;
* painting weights at λ ≠ 0 measures the brush on the previewed shape, keeps the preview, and
  solves the family again with the new weights when the stroke ends: the preview follows;
* a stroke (``begin`` … ``end``) is one undo step; a stroke left open is closed by the next
  message that is not part of a stroke, and when the tab that began it closes;
* after any other edit the family is solved again, at once when the slider is off 0, else when
  it next moves.
"""

from __future__ import annotations

import asyncio
import contextlib
import functools

import numpy as np

from ..errors import ParameterError
from ..geometry.measures import fan_triangles
from . import protocol
from .session import StudioSession

__all__ = ["Hub", "HANDLERS", "STROKE_OPS", "frame", "field_scale", "FLOAT32_MAX", "NAMED_VIEWS"]

#: largest |coordinate| a page can draw (float32)
FLOAT32_MAX = float(np.finfo(np.float32).max)
#: the messages that belong to a stroke (any other closes a stroke left open)
STROKE_OPS = frozenset({"begin", "end", "dab", "paint", "field"})
#: the views the page offers (Blender's numpad 1, 3, 7 and, with Ctrl, the opposite sides)
NAMED_VIEWS = ("front", "back", "right", "left", "top", "bottom")


def frame(tag: bytes, arr: np.ndarray, dtype) -> bytes:
    """A binary frame: the 4-byte ``tag`` and the array's bytes (refused when not finite in float32)."""
    a = np.ascontiguousarray(arr, dtype=dtype)
    if a.dtype.kind == "f" and not np.isfinite(a).all():
        raise ParameterError("the result holds values a page cannot draw (not finite in float32); nothing was sent")
    return tag + a.tobytes()


def _views(session: StudioSession) -> dict:
    """Where the camera looks from in each named view: the direction from the model towards the camera
    and the camera's up, by the project's view rule (:func:`shapeflow.rendering.scene.camera`)."""
    from ..rendering.scene import camera

    V = session.base.vertices
    out = {}
    for name in NAMED_VIEWS:
        cam = camera(V, name, session.up_axis, 1.0, front=session.front)
        d = np.asarray(cam.position, float) - np.asarray(cam.target, float)
        out[name] = {"dir": (d / np.linalg.norm(d)).tolist(), "up": np.asarray(cam.up, float).tolist()}
    return out


class Hub:
    """The session, the family's options and the sockets of the open tabs."""

    def __init__(self, session: StudioSession, lams, name: str = "", front: str | None = None):
        self.lams = list(lams)
        self.front = front           # the front chosen (--front, the page): for files that name none
        self.options: dict = {}
        self.sockets: dict = {}      # WebSocketResponse -> its Outbox
        self.lock = asyncio.Lock()
        self.watcher: asyncio.Task | None = None
        self.sender = None           # the socket whose message is being handled
        self.stroke_owner = None     # the socket that began the open stroke
        self.use(session, name)

    def use(self, session: StudioSession, name: str = "") -> None:
        """Edit ``session`` (shown as ``name``) from now on: what the page draws is derived here."""
        V = session.vertices
        if V.size and float(np.abs(V).max()) > FLOAT32_MAX / 16:
            raise ParameterError(f"{name or 'the mesh'}: coordinates up to {np.abs(V).max():.3g} cannot be drawn "
                                 "in a browser (float32); scale the model first")
        old = getattr(self, "session", None)
        if old is not None and old is not session:
            old.stop_family()           # one family solve at a time: the replaced session's ends
        if old is not None and old is not session:     # a preference, as the family's options: kept
            session.set_features(old.features["on"], old.features["angle"])
        self.session = session
        if self.front is not None and session.front is None:
            with contextlib.suppress(ParameterError):   # along this model's up axis: its default front
                session.front = self.front
        mesh = session.base             # what the page draws: the welded mesh
        self.tris = fan_triangles(mesh)
        self.edges = mesh.topology.edges
        self.name = str(name or mesh.metadata.get("name", ""))
        self.n_vertices, self.n_faces = mesh.n_vertices, mesh.n_faces
        self.diagonal = float(mesh.diagonal) or 1.0
        self.box = (V.min(axis=0), V.max(axis=0)) if V.size else (np.zeros(3), np.zeros(3))
        self.views = _views(session) if V.size else {}
        self.lam = 0.0
        self.stale = False
        self.stroke_owner = None

    # --- what the tabs see ----------------------------------------------
    def orientation(self) -> dict:
        """The model's frame: the axis it faces (``front``: None for the view rule's default, which is
        ``default_front``), its axes, the named views and the mirror plane."""
        from ..rendering.style import DEFAULT_FRONT

        s = self.session
        right, up, front = (a.tolist() for a in s.axes)
        return {"front": s.front, "default_front": DEFAULT_FRONT[s.up_axis], "up_axis": s.up_axis,
                "axes": {"right": right, "up": up, "front": front}, "views": self.views,
                "mirror": {"origin": s.mirror_origin.tolist(), "normal": right}}

    def mesh_frames(self) -> list:
        """Everything a page needs to draw the session from scratch."""
        s = self.session
        return [{"type": "mesh", "n_vertices": self.n_vertices, "n_faces": self.n_faces, "name": self.name,
                 "formats": _extensions(), **self.orientation()},
                frame(b"TRI0", self.tris, "<u4"), frame(b"EDG0", self.edges, "<u4"),
                frame(b"BAS0", s.input_vertices, "<f4"), frame(b"POS0", self.shown(), "<f4"),
                frame(b"WGT0", s.weights, "<f4"), *self.sharp_frames(), self.state()]

    def snapshot(self) -> list:
        """The current positions, weights and state (a tab that fell behind gets this instead)."""
        return [frame(b"POS0", self.shown(), "<f4"), frame(b"WGT0", self.session.weights, "<f4"),
                {**self.state(), "resync": True}]

    @property
    def previewing(self) -> bool:
        """Whether the tabs show the family's shape at the slider's λ (not the current shape)."""
        return self.lam != 0 and self.session.can_preview

    def shown(self) -> np.ndarray:
        s = self.session
        return s.shape_at(self.lam) if self.previewing else s.vertices

    def state(self) -> dict:
        s = self.session
        st = s.family_status()
        used, limit = s.history_bytes
        return {"type": "state", "lam": self.lam, "version": s.version, "can_undo": s.can_undo,
                "can_redo": s.can_redo, "lams": self.lams, "options": self.options,
                "modified": s.modified, "stroke": s.in_stroke, "previewing": self.previewing,
                "stale": self.stale, "history": {"bytes": used, "limit": limit},
                "family": {"state": st.state, "done": st.done, "total": st.total, "error": st.error}}

    async def broadcast(self, *messages) -> None:
        """Queue ``messages`` for every open tab (each tab's own writer sends them in order)."""
        for box in list(self.sockets.values()):
            box.put(*messages)

    # --- the family and the strokes ---------------------------------------
    def solve(self) -> None:
        self.stale = False
        self.session.solve_family(self.lams, **self.options)
        self.follow_sharp()
        if self.watcher is None or self.watcher.done():     # one watcher follows whichever solve is current
            self.watcher = asyncio.create_task(_watch_family(self))

    def changed(self) -> None:
        """The positions or weights changed: solve the family again now if the slider previews one
        (outside a stroke; a stroke's end does it), else when the slider next moves."""
        self.stale = True
        if self.lam != 0 and not self.session.in_stroke:
            self.solve()

    sharp_sent = None       # the sharp edges last sent to the tabs (:meth:`sharp_frames`)

    def sharp_frames(self) -> list:
        """The "Keep sharp edges" setting and the sharp edges it keeps at the current shape (``SHP0``: vertex
        pairs; none when it is off), which the page draws as lines on the shape shown."""
        s = self.session
        pairs = s.sharp_edges()
        self.sharp_sent = pairs
        return [{"type": "features", **s.features, "marked_count": s.marked_count, "count": len(pairs)},
                frame(b"SHP0", pairs, "<u4")]

    def follow_sharp(self) -> None:
        """Send every tab the sharp edges again when they changed since last sent (the family was solved
        from a shape whose dihedral angles differ)."""
        if not self.session.features["on"] and (self.sharp_sent is None or not len(self.sharp_sent)):
            return
        sent = self.sharp_sent
        out = self.sharp_frames()
        if sent is None or not np.array_equal(sent, self.sharp_sent):
            for box in list(self.sockets.values()):
                box.put(*out)

    def close_stroke(self) -> None:
        """End a stroke left open (its edits become one undo step)."""
        self.stroke_owner = None
        if self.session.end_stroke() and self.stale and self.lam != 0:
            self.solve()

    def near(self, center, radius: float, op: str) -> None:
        """Refuse a brush far off the model or larger than it by far (both would only burn time)."""
        d = self.diagonal
        if radius > 10.0 * d:
            raise ParameterError(f"{op}: radius {radius:.6g} is more than ten times the model's size ({d:.6g})")
        lo, hi = self.box
        if np.any(np.asarray(center) < lo - 10.0 * d) or np.any(np.asarray(center) > hi + 10.0 * d):
            raise ParameterError(f"{op}: center {center} is far outside the model")


def _extensions() -> list:
    """The file extensions shapeflow reads and writes (PLY first: it keeps the weights)."""
    from ..io.registry import FORMATS

    fmts = FORMATS.values() if isinstance(FORMATS, dict) else FORMATS
    exts = sorted({e.lstrip(".") for f in fmts for e in f.extensions})
    return sorted(exts, key=lambda e: e != "ply")


def field_scale(values: np.ndarray) -> float:
    """The colour range of a field: the 98th percentile of |value| (O(n), no sort), 1 when that is 0."""
    a = np.abs(np.asarray(values, dtype=np.float64))
    if a.size == 0:
        return 1.0
    k = int(0.98 * (a.size - 1))
    v = float(np.partition(a, k)[k])
    return v if v > 0 and np.isfinite(v) else 1.0


def _field_frames(s: StudioSession, name: str, lam) -> list:
    values = s.field(name, lam=lam)
    return [frame(b"FLD0", values, "<f4"),
            {"type": "field", "name": name, "version": s.version, "lam": lam, "scale": field_scale(values)}]


# --- the handlers of the protocol's messages (protocol.MESSAGES) --------------------
async def _in_thread(fn):
    return await asyncio.get_running_loop().run_in_executor(None, fn)


async def _on_lam(hub: Hub, m: dict) -> list:
    s = hub.session
    hub.lam = m["value"]
    if hub.stale:        # the shape or the weights changed since the family was solved: solve again
        hub.solve()
    preview = hub.previewing
    out = [frame(b"POS0", hub.shown(), "<f4")]
    if m["field"] in ("curvature", "displacement"):     # the colours follow the preview
        out += await _in_thread(lambda: _field_frames(s, m["field"], hub.lam if preview else None))
    return out + [hub.state()]


async def _on_field(hub: Hub, m: dict) -> list:
    s = hub.session
    lam = m["lam"] if s.can_preview and m["lam"] else None
    return await _in_thread(lambda: _field_frames(s, m["name"], lam)) + [hub.state()]


async def _on_options(hub: Hub, m: dict) -> list:
    hub.options = dict(m)
    hub.solve()
    return [hub.state()]


async def _on_solve(hub: Hub, m: dict) -> list:
    from ..budget import check_memory
    from ..flow.family import family_bytes

    lams = _family_lams(m)
    check_memory(f"a family of {len(lams):,} members of {hub.n_vertices:,} vertices",
                 family_bytes(len(lams), hub.n_vertices), parameter="lams")
    hub.lams = lams
    hub.solve()
    return [hub.state()]


def _family_lams(m: dict) -> list:
    """The λ of a ``solve`` message: its list, or its range from/to/step as the command line's
    ``family`` makes it (the end included when it lies on the grid); 0, the current shape, always."""
    ranged = [m[k] for k in ("from", "to", "step")]
    if m["lams"] is not None:
        if any(x is not None for x in ranged):
            raise ParameterError("solve: give either lams or from/to/step, not both")
        lams = m["lams"]
    else:
        if any(x is None for x in ranged):
            raise ParameterError("solve: give lams, or from, to and step")
        from types import SimpleNamespace

        from ..commands.family import member_lambdas

        a, b, step = ranged
        if step == 0:
            raise ParameterError("solve: step must not be 0")
        if (b - a) * step < 0:
            raise ParameterError(f"solve: from {a:g} to {b:g} step {step:g} gives no λ "
                                 "(the step must point from 'from' towards 'to')")
        if abs(b - a) / abs(step) >= protocol.MAX_LAMS:
            raise ParameterError(f"solve: from {a:g} to {b:g} step {step:g} gives more than "
                                 f"{protocol.MAX_LAMS} members")
        lams = member_lambdas(SimpleNamespace(lambdas=None, lam_from=a, lam_to=b, lam_step=step))
    return sorted(set(lams) | {0.0}, reverse=True)


async def _on_begin(hub: Hub, m: dict) -> list:
    hub.close_stroke()
    hub.session.begin_stroke()
    hub.stroke_owner = hub.sender
    return [hub.state()]


async def _on_end(hub: Hub, m: dict) -> list:
    hub.close_stroke()
    await _in_thread(hub.session.ready_brush)      # the next stroke starts at once
    return [hub.state()]


async def _on_paint(hub: Hub, m: dict) -> list:
    hub.near(m["center"], m["radius"], "paint")
    s = hub.session
    on = hub.shown() if hub.previewing else None        # the brush touches the shape the tab shows
    await _in_thread(lambda: s.paint(m["center"], m["radius"], value=m["value"], strength=m["strength"], on=on,
                                     mirror=m["mirror"]))
    hub.changed()
    return [frame(b"WGT0", s.weights, "<f4"), hub.state()]


async def _on_dab(hub: Hub, m: dict) -> list:
    hub.near(m["center"], m["radius"], "dab")
    s = hub.session
    applied = hub.previewing
    s.stop_family()            # solved from the positions before this dab: nothing could show it
    hub.lam, lam = 0.0, hub.lam
    hub.stale = True

    def work():
        if applied:            # the previewed shape becomes the current one (its own undo step)
            s.apply_shape(lam)
        return s.dab(m["center"], radius=m["radius"], lam=m["lam"], inflate=m["inflate"], strength=m["strength"],
                     mirror=m["mirror"])

    moved = await _in_thread(work)
    if applied:
        return [frame(b"POS0", s.vertices, "<f4"), hub.state()]
    pos = np.ascontiguousarray(s.vertices_at(moved), "<f4")
    if not np.isfinite(pos).all():
        raise ParameterError("the dab's result cannot be drawn (not finite in float32); undo it")
    # only the vertices the dab moved: a few thousand, not the whole mesh
    part = b"PSUB" + np.uint32(moved.size).tobytes() + np.ascontiguousarray(moved, "<u4").tobytes() + pos.tobytes()
    return [part, hub.state()]


async def _on_apply(hub: Hub, m: dict) -> list:
    await _in_thread(lambda: hub.session.apply_shape(m["value"]))
    hub.lam = 0.0
    hub.changed()
    return [frame(b"POS0", hub.session.vertices, "<f4"), hub.state()]


async def _on_features(hub: Hub, m: dict) -> list:
    s = hub.session
    changed = await _in_thread(lambda: s.set_features(m["on"], m["angle"], m["marked"]))
    out = hub.sharp_frames()
    if changed:               # the family with (or without) the sharp edges; the preview follows when solved
        hub.solve()
    return [*out, hub.state()]


async def _on_undo(hub: Hub, m: dict, *, redo: bool = False) -> list:
    s = hub.session
    (s.redo if redo else s.undo)()
    hub.changed()
    return [frame(b"POS0", hub.shown(), "<f4"), frame(b"WGT0", s.weights, "<f4"), hub.state()]


async def _on_front(hub: Hub, m: dict) -> list:
    s = hub.session
    s.front = m["axis"]                 # ParameterError: along the up axis
    hub.front = m["axis"]
    hub.views = _views(s) if hub.n_vertices else {}
    return [{"type": "orientation", **hub.orientation()}, hub.state()]


HANDLERS = {"lam": _on_lam, "field": _on_field, "options": _on_options, "solve": _on_solve,
            "begin": _on_begin, "end": _on_end, "paint": _on_paint, "dab": _on_dab, "apply": _on_apply,
            "undo": _on_undo, "redo": functools.partial(_on_undo, redo=True), "front": _on_front,
            "features": _on_features}
assert HANDLERS.keys() == protocol.MESSAGES.keys()


async def _watch_family(hub: Hub) -> None:
    """Tell every tab how the background family solve goes, until it ends; when it completes while
    the slider previews, the preview follows (the new shape at the slider's λ)."""
    while True:
        if hub.session.family_status().state != "running":
            async with hub.lock:
                st = hub.session.family_status()
                if st.state == "running":        # a new solve began meanwhile: follow it
                    continue
                out = [frame(b"POS0", hub.shown(), "<f4")] if hub.previewing and st.state == "done" else []
                await hub.broadcast(*out, hub.state())
            return
        await hub.broadcast(hub.state())
        await asyncio.sleep(0.1)
