"""The studio's web server: the page, its static files, and a WebSocket to one :class:`StudioSession`.

Stack (aiohttp on the Python side, a small three.js front end served from the package, no
Node.js at install or run time, nothing fetched from the internet): the page needs pointer
events on the surface for painting and sculpting, per-frame updates of every position, and
sliders; three.js gives the first two with a raycaster and a buffer attribute, and the
WebSocket carries positions as raw float32 frames.

Access.  Every request passes :class:`~shapeflow.studio.security.Guard` first: the ``Host``
and ``Origin`` must be the studio's own, and the server's token must come with it (the
``token`` query parameter, the ``X-Shapeflow-Token`` header, or for reading requests the
page's cookie).  docs/robustness.md states the threat model.

Protocol.  The page sends JSON messages, checked against the table of
:mod:`~shapeflow.studio.protocol` before anything changes; a refused message is answered by an
``error`` message and the socket stays open.  The server sends JSON text messages
(``{"type": ...}``: ``mesh``, ``state``, ``field``, ``error``) and binary frames that start with
a 4-byte tag: ``POS0`` float32 positions (n, 3), ``BAS0`` float32 positions of the input (the
split view's "before"), ``TRI0`` uint32 triangles (the faces' fans, for drawing), ``EDG0``
uint32 edge pairs (the real polygon edges, for the wireframe), ``WGT0`` float32 weights (n,),
``FLD0`` float32 values of a colour field (n,), ``PSUB`` some positions (uint32 count k, k
uint32 indices, k × 3 float32: what a dab moved).  No frame holds a value that is not finite in
float32.  A ``mesh`` message starts a new mesh (on connecting, and in every tab when a file is
opened).  Each tab has its own bounded queue (:mod:`~shapeflow.studio.outbox`).

``GET /download/NAME.EXT`` returns the current mesh, on the layout of the file opened, in any
format shapeflow writes; ``POST /open?name=FILE.EXT`` (the file as the body) opens a mesh in
every tab, ``POST /weights?name=FILE.EXT`` reads weights (a mesh's ``weight`` attribute with the
same vertex count, or ``.npy``/``.txt``); uploads above ``max_upload`` bytes are refused (413)
and nothing of them is kept; an upload is read by a child process bounded in time and memory
(:mod:`~shapeflow.studio.upload`).  The server reads and writes no file of the user's: an
upload lives in a temporary folder until it is read.

Every tab shares the server's session: a second tab sees the same shape, a closed tab loses
nothing.  The server binds to 127.0.0.1 unless told otherwise.
"""

from __future__ import annotations

import asyncio
import functools
import os
import tempfile
from pathlib import Path

import numpy as np

from .. import params
from ..errors import OptionalDependencyError, ParameterError, ShapeflowError
from ..geometry.measures import fan_triangles
from ..io.weights import WEIGHT_EXTENSIONS
from . import protocol
from .outbox import LIMIT as OUTBOX_LIMIT
from .outbox import STALL, Outbox
from .security import SAFE_HEADERS, Guard, check_name, content_disposition, new_token
from .session import StudioSession

__all__ = ["make_app", "hub_of", "field_scale", "STATIC", "DEFAULT_LAMS", "MAX_MESSAGE", "MAX_UPLOAD"]

STATIC = Path(__file__).resolve().parent / "static"
#: the family the slider walks by default: λ = 0 … −240 (figure 1 of the paper)
DEFAULT_LAMS = tuple(float(x) for x in np.arange(0.0, -241.0, -10.0))
#: the largest message a page may send (a JSON edit is a few hundred bytes)
MAX_MESSAGE = 1 << 16
#: the largest file a page may open by default (``--max-upload``), bytes
MAX_UPLOAD = 512 << 20
#: largest |coordinate| a page can draw (float32)
FLOAT32_MAX = float(np.finfo(np.float32).max)


def _web():
    try:
        from aiohttp import WSMsgType, web
    except Exception as exc:   # not installed, or installed and broken
        raise OptionalDependencyError("aiohttp", "studio", "the studio's server", exc) from exc
    return web, WSMsgType


def _frame(tag: bytes, arr: np.ndarray, dtype) -> bytes:
    a = np.ascontiguousarray(arr, dtype=dtype)
    if a.dtype.kind == "f" and not np.isfinite(a).all():
        raise ParameterError("the result holds values a page cannot draw (not finite in float32); nothing was sent")
    return tag + a.tobytes()


class _Hub:
    """The session, the family's options and the sockets of the open tabs."""

    def __init__(self, session: StudioSession, lams, name: str = ""):
        self.lams = list(lams)
        self.options: dict = {}
        self.sockets: dict = {}      # WebSocketResponse -> its Outbox
        self.lock = asyncio.Lock()
        self.watcher: asyncio.Task | None = None
        self.use(session, name)

    def use(self, session: StudioSession, name: str = "") -> None:
        """Edit ``session`` (shown as ``name``) from now on: what the page draws is derived here."""
        V = session.vertices
        if V.size and float(np.abs(V).max()) > FLOAT32_MAX / 16:
            raise ParameterError(f"{name or 'the mesh'}: coordinates up to {np.abs(V).max():.3g} cannot be drawn "
                                 "in a browser (float32); scale the model first")
        self.session = session
        mesh = session.base             # what the page draws: the welded mesh
        self.tris = fan_triangles(mesh)
        self.edges = mesh.topology.edges
        self.name = str(name or mesh.metadata.get("name", ""))
        self.n_vertices, self.n_faces = mesh.n_vertices, mesh.n_faces
        self.diagonal = float(mesh.diagonal) or 1.0
        self.box = (V.min(axis=0), V.max(axis=0)) if V.size else (np.zeros(3), np.zeros(3))
        self.lam = 0.0
        self.stale = False

    def mesh_frames(self) -> list:
        """Everything a page needs to draw the session from scratch."""
        s = self.session
        return [{"type": "mesh", "n_vertices": self.n_vertices, "n_faces": self.n_faces, "name": self.name,
                 "formats": _extensions()},
                _frame(b"TRI0", self.tris, "<u4"), _frame(b"EDG0", self.edges, "<u4"),
                _frame(b"BAS0", s.input_vertices, "<f4"), _frame(b"POS0", s.vertices, "<f4"),
                _frame(b"WGT0", s.weights, "<f4"), self.state()]

    def snapshot(self) -> list:
        """The current positions, weights and state (a tab that fell behind gets this instead)."""
        return [_frame(b"POS0", self._shown(), "<f4"), _frame(b"WGT0", self.session.weights, "<f4"),
                {**self.state(), "resync": True}]

    def _shown(self) -> np.ndarray:
        s = self.session
        return s.shape_at(self.lam) if self.lam != 0 and s.family_status().state == "done" else s.vertices

    def solve(self) -> None:
        self.stale = False
        self.session.solve_family(self.lams, **self.options)
        if self.watcher is None or self.watcher.done():     # one watcher follows whichever solve is current
            self.watcher = asyncio.create_task(_watch_family(self))

    def near(self, center, radius: float, op: str) -> None:
        """Refuse a brush far off the model or larger than it by far (both would only burn time)."""
        d = self.diagonal
        if radius > 10.0 * d:
            raise ParameterError(f"{op}: radius {radius:.6g} is more than ten times the model's size ({d:.6g})")
        lo, hi = self.box
        if np.any(np.asarray(center) < lo - 10.0 * d) or np.any(np.asarray(center) > hi + 10.0 * d):
            raise ParameterError(f"{op}: center {center} is far outside the model")

    async def broadcast(self, *messages) -> None:
        """Queue ``messages`` for every open tab (each tab's own writer sends them in order)."""
        for box in list(self.sockets.values()):
            box.put(*messages)

    def state(self) -> dict:
        s = self.session
        st = s.family_status()
        return {"type": "state", "lam": self.lam, "version": s.version, "can_undo": s.can_undo,
                "can_redo": s.can_redo, "lams": self.lams, "options": self.options,
                "family": {"state": st.state, "done": st.done, "total": st.total, "error": st.error}}


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
    return [_frame(b"FLD0", values, "<f4"),
            {"type": "field", "name": name, "version": s.version, "lam": lam, "scale": field_scale(values)}]


# --- the handlers of the protocol's messages (protocol.MESSAGES) --------------------
async def _in_thread(fn):
    return await asyncio.get_running_loop().run_in_executor(None, fn)


async def _on_lam(hub: _Hub, m: dict) -> list:
    s = hub.session
    hub.lam = m["value"]
    if hub.stale:        # the shape or the weights changed since the family was solved: solve again
        hub.solve()
    done = s.family_status().state == "done"
    out = [_frame(b"POS0", s.shape_at(hub.lam) if done else s.vertices, "<f4")]
    if m["field"] in ("curvature", "displacement"):     # the colours follow the preview
        out += await _in_thread(lambda: _field_frames(s, m["field"], hub.lam if done else None))
    return out + [hub.state()]


async def _on_field(hub: _Hub, m: dict) -> list:
    s = hub.session
    lam = m["lam"] if s.family_status().state == "done" else None
    return await _in_thread(lambda: _field_frames(s, m["name"], lam)) + [hub.state()]


async def _on_options(hub: _Hub, m: dict) -> list:
    hub.options = dict(m)
    hub.solve()
    return [hub.state()]


async def _on_solve(hub: _Hub, m: dict) -> list:
    from ..budget import check_memory
    from ..flow.family import family_bytes

    lams = sorted(set(m["lams"]), reverse=True)
    check_memory(f"a family of {len(lams):,} members of {hub.n_vertices:,} vertices",
                 family_bytes(len(lams), hub.n_vertices), parameter="lams")
    hub.lams = lams
    hub.solve()
    return [hub.state()]


async def _on_paint(hub: _Hub, m: dict) -> list:
    hub.near(m["center"], m["radius"], "paint")
    hub.stale = True
    await _in_thread(lambda: hub.session.paint(m["center"], m["radius"], value=m["value"], strength=m["strength"]))
    return [_frame(b"WGT0", hub.session.weights, "<f4"), hub.state()]


async def _on_dab(hub: _Hub, m: dict) -> list:
    hub.near(m["center"], m["radius"], "dab")
    s = hub.session
    hub.stale = True
    moved = await _in_thread(lambda: s.dab(m["center"], radius=m["radius"], lam=m["lam"], inflate=m["inflate"]))
    pos = np.ascontiguousarray(s.vertices_at(moved), "<f4")
    if not np.isfinite(pos).all():
        raise ParameterError("the dab's result cannot be drawn (not finite in float32); undo it")
    # only the vertices the dab moved: a few thousand, not the whole mesh
    part = b"PSUB" + np.uint32(moved.size).tobytes() + np.ascontiguousarray(moved, "<u4").tobytes() + pos.tobytes()
    return [part, hub.state()]


async def _on_apply(hub: _Hub, m: dict) -> list:
    hub.stale = True
    await _in_thread(lambda: hub.session.apply_shape(m["value"]))
    hub.lam = 0.0
    return [_frame(b"POS0", hub.session.vertices, "<f4"), hub.state()]


async def _on_undo(hub: _Hub, m: dict, *, redo: bool = False) -> list:
    s = hub.session
    hub.stale = True
    (s.redo if redo else s.undo)()
    return [_frame(b"POS0", s.vertices, "<f4"), _frame(b"WGT0", s.weights, "<f4"), hub.state()]


HANDLERS = {"lam": _on_lam, "field": _on_field, "options": _on_options, "solve": _on_solve, "paint": _on_paint,
            "dab": _on_dab, "apply": _on_apply, "undo": _on_undo,
            "redo": functools.partial(_on_undo, redo=True)}
assert HANDLERS.keys() == protocol.MESSAGES.keys()


async def _watch_family(hub: _Hub) -> None:
    """Tell every tab how the background family solve goes, until it ends."""
    while True:
        st = hub.session.family_status()
        await hub.broadcast(hub.state())
        if st.state != "running":
            return
        await asyncio.sleep(0.1)


class _Routes:
    """The HTTP and WebSocket handlers of one app (``web``: aiohttp's web module)."""

    def __init__(self, hub: _Hub, web, WSMsgType, *, solve: bool, max_upload: int, outbox: dict):
        self.hub, self.web, self.WSMsgType = hub, web, WSMsgType
        self.solve, self.max_upload, self.outbox = solve, max_upload, outbox

    async def index(self, request):
        guard = request.app[_key(self.web, "guard")]
        resp = self.web.FileResponse(STATIC / "index.html")
        if request.query.get("token") is not None:     # the page's scripts load with the cookie
            resp.set_cookie(guard.cookie, guard.token, httponly=True, samesite="Strict", path="/")
        return resp

    async def socket(self, request):
        hub = self.hub
        ws = self.web.WebSocketResponse(max_msg_size=MAX_MESSAGE, heartbeat=20.0)
        await ws.prepare(request)
        transport = request.transport
        box = hub.sockets[ws] = Outbox(ws, hub.snapshot, lambda: transport is not None and transport.abort(),
                                       **self.outbox)
        box.put(*hub.mesh_frames())
        try:
            async for msg in ws:
                if msg.type != self.WSMsgType.TEXT:
                    box.put({"type": "error", "message": "the studio takes JSON text messages only"})
                    continue
                try:
                    op, fields = protocol.parse(msg.data)
                    async with hub.lock:
                        out = await HANDLERS[op](hub, fields)
                    await hub.broadcast(*out)
                except ShapeflowError as exc:
                    box.put({"type": "error", "message": str(exc)})
        finally:
            hub.sockets.pop(ws, None)
            box.close()
        return ws

    async def download(self, request):
        from ..io import save
        from ..io.registry import format_for

        web, name = self.web, request.match_info["name"]
        why = check_name(name)
        if why:
            raise web.HTTPBadRequest(text=why)
        try:
            format_for(name, None)
        except ShapeflowError as exc:
            raise web.HTTPBadRequest(text=str(exc)) from None
        with tempfile.TemporaryDirectory(prefix="shapeflow-studio-") as tmp:
            path = os.path.join(tmp, name)
            try:
                await _in_thread(lambda: save(path, self.hub.session.mesh))
            except ShapeflowError as exc:       # e.g. the format's optional dependency is missing
                raise web.HTTPBadRequest(text=str(exc).replace(tmp + os.sep, "")) from None
            body = Path(path).read_bytes()
        return web.Response(body=body, content_type="application/octet-stream",
                            headers={"Content-Disposition": content_disposition(name)})

    async def received(self, request, kind: str):
        """The uploaded file, written into a fresh temporary folder under its own base name:
        ``(folder, path, name)``.  Bad names, unknown formats and files above ``max_upload`` are
        refused before anything is kept."""
        from ..io.registry import format_for

        web, limit = self.web, self.max_upload
        name = request.query.get("name", "")
        why = check_name(name) if name else "the upload needs a file name (?name=FILE.EXT)"
        if why:
            raise web.HTTPBadRequest(text=why)
        if not (kind == "weights" and os.path.splitext(name)[1].lower() in WEIGHT_EXTENSIONS):
            try:
                format_for(name, None)
            except ShapeflowError as exc:
                raise web.HTTPBadRequest(text=str(exc)) from None
        too_big = (f"{name}: the file is larger than the studio accepts ({limit / 2**20:,.1f} MiB; "
                   f"start it with --max-upload to change that)")
        if request.content_length is not None and request.content_length > limit:
            raise web.HTTPRequestEntityTooLarge(max_size=limit, actual_size=request.content_length, text=too_big)
        tmp = tempfile.TemporaryDirectory(prefix="shapeflow-studio-")
        path, size = os.path.join(tmp.name, name), 0
        try:
            with open(path, "wb") as f:
                async for chunk in request.content.iter_chunked(1 << 20):
                    size += len(chunk)
                    if size > limit:
                        raise web.HTTPRequestEntityTooLarge(max_size=limit, actual_size=size, text=too_big)
                    f.write(chunk)
        except BaseException:
            tmp.cleanup()
            raise
        return tmp, path, name

    async def open_file(self, request):
        """``POST /open?name=FILE.EXT``: the file becomes the mesh every tab edits."""
        from .upload import read_upload

        hub = self.hub
        tmp, path, name = await self.received(request, "mesh")
        try:
            with tmp:
                mesh = await _in_thread(lambda: read_upload(path, name))
            new = await _in_thread(lambda: StudioSession(mesh))
            async with hub.lock:
                hub.use(new, name)
                if self.solve:
                    hub.solve()
                await hub.broadcast(*hub.mesh_frames())
        except ShapeflowError as exc:
            raise self.web.HTTPBadRequest(text=str(exc)) from None
        return self.web.json_response({"n_vertices": hub.n_vertices, "n_faces": hub.n_faces,
                                       "welded": new.welded})

    async def open_weights(self, request):
        """``POST /weights?name=FILE.EXT``: weights from a mesh's ``weight`` attribute (the vertex
        count of the mesh as opened, or as welded) or a ``.npy``/``.txt`` file, as one undo step."""
        from .upload import read_upload

        hub = self.hub
        tmp, path, name = await self.received(request, "weights")
        s = hub.session
        try:
            with tmp:
                w = await _in_thread(lambda: read_upload(path, name, kind="weights", n_vertices=s.n_input_vertices))
            async with hub.lock:
                hub.session.set_weights(w)
                hub.stale = True
                await hub.broadcast(_frame(b"WGT0", hub.session.weights, "<f4"), hub.state())
        except ShapeflowError as exc:
            raise self.web.HTTPBadRequest(text=str(exc)) from None
        return self.web.json_response({"n_vertices": s.n_input_vertices})


def _guard_middleware(web, guard: Guard):
    @web.middleware
    async def guarded(request, handler):
        refused = guard.refusal(request)
        if refused is not None:
            status, why = refused
            resp = web.Response(status=status, text=why + "\n")
        else:
            try:
                resp = await handler(request)
            except web.HTTPException as exc:
                resp = exc
        for k, v in SAFE_HEADERS.items():
            resp.headers.setdefault(k, v)
        if refused is None and isinstance(resp, web.HTTPException):
            raise resp
        return resp
    return guarded


def make_app(session: StudioSession, *, lams=DEFAULT_LAMS, solve: bool = True, max_upload: int = MAX_UPLOAD,
             name: str = "", token: str | None = None, host: str = "127.0.0.1", port: int = 0,
             allow_hosts=(), outbox_limit: int = OUTBOX_LIMIT, stall_seconds: float = STALL):
    """The aiohttp application serving ``session`` (the family over ``lams`` is solved at start;
    ``name``: what the page calls the mesh, and the stem of downloads).

    ``token`` (a fresh random one by default), ``host`` and ``port`` (where it listens; a server
    that learns its port on binding sets ``guard_of(app).port``) and ``allow_hosts`` configure the
    :class:`~shapeflow.studio.security.Guard` every request passes.  ``max_upload`` is the largest
    file (bytes) a page may open or load weights from; larger uploads are refused with a message
    and nothing is kept.  ``outbox_limit`` (bytes) and ``stall_seconds`` bound what waits for one
    tab and how long one send to it may take (:mod:`~shapeflow.studio.outbox`).
    """
    web, WSMsgType = _web()
    hub = _Hub(session, sorted((float(x) for x in lams), reverse=True), name)
    r = _Routes(hub, web, WSMsgType, solve=solve, max_upload=params.integer("max_upload", max_upload, lo=1),
                outbox={"limit": params.integer("outbox_limit", outbox_limit, lo=1),
                        "stall": params.number("stall_seconds", stall_seconds, lo=0.001)})
    guard = Guard(token or new_token(), host, port, allow_hosts=allow_hosts)

    async def on_startup(app):
        if solve:
            hub.solve()

    app = web.Application(client_max_size=MAX_MESSAGE, middlewares=[_guard_middleware(web, guard)])
    app.router.add_get("/", r.index)
    app.router.add_get("/ws", r.socket)
    app.router.add_get("/download/{name}", r.download)
    app.router.add_post("/open", r.open_file)
    app.router.add_post("/weights", r.open_weights)
    app.router.add_static("/static/", STATIC, follow_symlinks=False)
    app.on_startup.append(on_startup)
    app[_key(web, "hub")] = hub
    app[_key(web, "guard")] = guard
    return app


@functools.cache
def _key(web, what: str):
    """The app key under which an app keeps its hub or guard (made once aiohttp is imported)."""
    return web.AppKey(f"shapeflow_studio_{what}", _Hub if what == "hub" else Guard)


def hub_of(app) -> _Hub:
    """The session holder of an app made by :func:`make_app`."""
    return app[_key(_web()[0], "hub")]


def guard_of(app) -> Guard:
    """The access checks of an app made by :func:`make_app` (its token: ``guard_of(app).token``)."""
    return app[_key(_web()[0], "guard")]
