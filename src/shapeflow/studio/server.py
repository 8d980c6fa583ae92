"""The studio's web server: the page, its static files, and a WebSocket to one :class:`StudioSession`.

Stack (aiohttp on the Python side, a small three.js front end served from the package, no
Node.js at install or run time, nothing fetched from the internet): the page needs pointer
events on the surface for painting and sculpting, per-frame updates of every position, and
sliders; three.js gives the first two with a raycaster and a buffer attribute, and the
WebSocket carries positions as raw float32 frames.

Protocol.  The server sends JSON text messages (``{"type": ...}``: ``mesh``, ``state``,
``field``, ``error``) and binary frames that start with a 4-byte tag: ``POS0`` float32
positions (n, 3), ``BAS0`` float32 positions of the input (the split view's "before"),
``TRI0`` uint32 triangles (the faces' fans, for drawing), ``EDG0`` uint32 edge pairs (the
real polygon edges, for the wireframe), ``WGT0`` float32 weights (n,), ``FLD0`` float32
values of a colour field (n,), ``PSUB`` some positions (uint32 count k, k uint32 indices,
k × 3 float32: what a dab moved).  A ``mesh`` message starts a new mesh (on connecting, and
in every tab when a file is opened).  The page sends JSON: ``{"op": "lam", "value",
"field"?}`` (the family's shape at λ, and the colour field of that shape), ``{"op": "paint",
"center", "radius", "value"}``, ``{"op": "dab", "center", "radius", "lam", "inflate"}``,
``{"op": "apply", "value"}``, ``{"op": "undo"}``, ``{"op": "redo"}``, ``{"op": "field",
"name", "lam"?}`` (weights, curvature or displacement: :meth:`StudioSession.field`),
``{"op": "options", "lam_border", "iterations", "normalized", "preserve_volume", "compat"}``
(the family is solved again with them).
``GET /download/NAME.EXT`` returns the current mesh in any format shapeflow writes;
``POST /open?name=FILE.EXT`` (the file as the body) opens a mesh in every tab, ``POST
/weights?name=FILE.EXT`` reads weights (a mesh's ``weight`` attribute with the same vertex
count, or ``.npy``/``.txt``); uploads above ``max_upload`` bytes are refused (413) and
nothing of them is kept.  The server reads and writes no file of the user's: an upload
lives in a temporary folder until it is loaded.

Every tab shares the server's session: a second tab sees the same shape, a closed tab loses
nothing.  The server binds to 127.0.0.1 unless told otherwise.
"""

from __future__ import annotations

import asyncio
import functools
import json
import os
import tempfile
from pathlib import Path

import numpy as np

from .. import params
from ..errors import OptionalDependencyError, ParameterError, ShapeflowError
from ..geometry.measures import fan_triangles
from ..io.weights import WEIGHT_EXTENSIONS
from .session import StudioSession

__all__ = ["make_app", "hub_of", "field_scale", "STATIC", "DEFAULT_LAMS", "MAX_MESSAGE", "MAX_UPLOAD"]

STATIC = Path(__file__).resolve().parent / "static"
#: the family the slider walks by default: λ = 0 … −240 (figure 1 of the paper)
DEFAULT_LAMS = tuple(float(x) for x in np.arange(0.0, -241.0, -10.0))
#: the largest message a page may send (a JSON edit is a few hundred bytes)
MAX_MESSAGE = 1 << 16
#: the largest file a page may open by default (``--max-upload``), bytes
MAX_UPLOAD = 512 << 20


def _web():
    try:
        from aiohttp import WSMsgType, web
    except Exception as exc:   # not installed, or installed and broken
        raise OptionalDependencyError("aiohttp", "studio", "the studio's server", exc) from exc
    return web, WSMsgType


def _frame(tag: bytes, arr: np.ndarray, dtype) -> bytes:
    return tag + np.ascontiguousarray(arr, dtype=dtype).tobytes()


class _Hub:
    """The session, the family's options and the sockets of the open tabs."""

    def __init__(self, session: StudioSession, lams, name: str = ""):
        self.lams = list(lams)
        self.options: dict = {}
        self.sockets: dict = {}      # WebSocketResponse -> its _Outbox
        self.lock = asyncio.Lock()
        self.watcher: asyncio.Task | None = None
        self.use(session, name)

    def use(self, session: StudioSession, name: str = "") -> None:
        """Edit ``session`` (shown as ``name``) from now on: what the page draws is derived here."""
        self.session = session
        mesh = session.mesh
        self.tris = fan_triangles(mesh)
        self.edges = mesh.topology.edges
        self.name = str(name or mesh.metadata.get("name", ""))
        self.n_vertices, self.n_faces = mesh.n_vertices, mesh.n_faces
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

    def solve(self) -> None:
        self.stale = False
        self.session.solve_family(self.lams, **self.options)
        if self.watcher is None or self.watcher.done():     # one watcher follows whichever solve is current
            self.watcher = asyncio.create_task(_watch_family(self))

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


class _Outbox:
    """The messages waiting for one tab and the one task that sends them, in order.

    Every send to a socket goes through here: two coroutines writing to one aiohttp WebSocket at
    once (an edit's answer and the family's progress) could leave one of them waiting for a
    drain that never came, and the tab stopped receiving answers; and a slow tab never holds up
    the others or the edits."""

    def __init__(self, ws):
        self.ws = ws
        self.queue: asyncio.Queue = asyncio.Queue()
        self.task = asyncio.create_task(self._send())

    def put(self, *messages) -> None:
        for m in messages:
            self.queue.put_nowait(m)

    def close(self) -> None:
        """The socket closed: nothing more can reach the tab."""
        self.task.cancel()

    async def _send(self) -> None:
        while True:
            m = await self.queue.get()
            try:
                await (self.ws.send_bytes(m) if isinstance(m, bytes) else self.ws.send_str(json.dumps(m)))
            except (ConnectionError, RuntimeError):      # the tab went away: drop what is left
                return


def _family_options(msg: dict) -> dict:
    """The family options a page may set, checked here (the solve runs on a thread of its own)."""
    compat = msg.get("compat", "paper")
    if compat not in ("paper", "blender"):
        raise ParameterError(f"compat must be 'paper' or 'blender', got {compat!r}")
    return {"lam_border": params.number("lam_border", msg.get("lam_border", 0.0)),
            "iterations": params.integer("iterations", msg.get("iterations", 1), lo=1, hi=100),
            "normalized": params.flag("normalized", msg.get("normalized", True)),
            "preserve_volume": params.flag("preserve_volume", msg.get("preserve_volume", False)),
            "compat": compat}


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


async def _handle(hub: _Hub, msg: dict):
    """Carry out one edit; returns the frames and messages every tab needs."""
    s = hub.session
    op = msg.get("op")
    loop = asyncio.get_running_loop()
    if op == "lam":
        hub.lam = float(msg["value"])
        if hub.stale:        # the shape or the weights changed since the family was solved: solve again
            hub.solve()
        done = s.family_status().state == "done"
        V = s.shape_at(hub.lam) if done else s.vertices
        out = [_frame(b"POS0", V, "<f4")]
        if msg.get("field") in ("curvature", "displacement"):     # the colours follow the preview
            out += await loop.run_in_executor(None, lambda: _field_frames(s, msg["field"], hub.lam if done else None))
        return out + [hub.state()]
    if op == "field":
        lam = msg.get("lam")
        lam = float(lam) if lam is not None and s.family_status().state == "done" else None
        return await loop.run_in_executor(None, lambda: _field_frames(s, str(msg["name"]), lam)) + [hub.state()]
    if op == "options":
        hub.options = _family_options(msg)
        hub.solve()
        return [hub.state()]
    if op == "solve":
        hub.lams = sorted((float(x) for x in msg.get("lams", hub.lams)), reverse=True)
        hub.solve()
        return [hub.state()]
    hub.stale = True         # every other operation edits the shape or the weights
    if op == "paint":
        await loop.run_in_executor(None, lambda: s.paint(msg["center"], float(msg["radius"]),
                                                         value=float(msg.get("value", 1.0)),
                                                         strength=float(msg.get("strength", 1.0))))
        return [_frame(b"WGT0", s.weights, "<f4"), hub.state()]
    if op == "dab":
        moved = await loop.run_in_executor(None, lambda: s.dab(msg["center"], radius=float(msg["radius"]),
                                                               lam=float(msg.get("lam", -50.0)),
                                                               inflate=bool(msg.get("inflate", False))))
        # only the vertices the dab moved: a few thousand, not the whole mesh
        part = (b"PSUB" + np.uint32(moved.size).tobytes() + np.ascontiguousarray(moved, "<u4").tobytes()
                + np.ascontiguousarray(s.vertices_at(moved), "<f4").tobytes())
        return [part, hub.state()]
    if op == "apply":
        await loop.run_in_executor(None, lambda: s.apply_shape(float(msg["value"])))
        hub.lam = 0.0
        return [_frame(b"POS0", s.vertices, "<f4"), hub.state()]
    if op in ("undo", "redo"):
        (s.undo if op == "undo" else s.redo)()
        return [_frame(b"POS0", s.vertices, "<f4"), _frame(b"WGT0", s.weights, "<f4"), hub.state()]
    raise ParameterError(f"unknown operation {op!r}")


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

    def __init__(self, hub: _Hub, web, WSMsgType, *, solve: bool, max_upload: int):
        self.hub, self.web, self.WSMsgType = hub, web, WSMsgType
        self.solve, self.max_upload = solve, max_upload

    async def index(self, request):
        return self.web.FileResponse(STATIC / "index.html")

    async def socket(self, request):
        hub = self.hub
        ws = self.web.WebSocketResponse(max_msg_size=MAX_MESSAGE, heartbeat=20.0)
        await ws.prepare(request)
        box = hub.sockets[ws] = _Outbox(ws)
        box.put(*hub.mesh_frames())
        try:
            async for msg in ws:
                if msg.type != self.WSMsgType.TEXT:
                    continue
                try:
                    async with hub.lock:
                        out = await _handle(hub, json.loads(msg.data))
                    await hub.broadcast(*out)
                except (ShapeflowError, KeyError, TypeError, ValueError) as exc:
                    box.put({"type": "error", "message": str(exc)})
        finally:
            hub.sockets.pop(ws, None)
            box.close()
        return ws

    async def download(self, request):
        from ..io import save
        from ..io.registry import format_for

        web, name = self.web, request.match_info["name"]
        try:
            format_for(name, None)
        except ShapeflowError as exc:
            raise web.HTTPBadRequest(text=str(exc)) from None
        loop = asyncio.get_running_loop()
        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, os.path.basename(name))
            try:
                await loop.run_in_executor(None, lambda: save(path, self.hub.session.mesh))
            except ShapeflowError as exc:       # e.g. the format's optional dependency is missing
                raise web.HTTPBadRequest(text=str(exc)) from None
            body = Path(path).read_bytes()
        return web.Response(body=body, content_type="application/octet-stream",
                            headers={"Content-Disposition": f'attachment; filename="{os.path.basename(name)}"'})

    async def received(self, request, kind: str):
        """The uploaded file, written into a fresh temporary folder under its own base name:
        ``(folder, path)``.  Unknown formats and files above ``max_upload`` are refused before
        anything is kept."""
        from ..io.registry import format_for

        web, limit = self.web, self.max_upload
        name = os.path.basename(request.query.get("name", "").replace("\\", "/"))
        if not name or name.startswith("."):
            raise web.HTTPBadRequest(text="the upload needs a file name (?name=FILE.EXT)")
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
        with open(path, "wb") as f:
            async for chunk in request.content.iter_chunked(1 << 20):
                size += len(chunk)
                if size > limit:
                    f.close()
                    tmp.cleanup()
                    raise web.HTTPRequestEntityTooLarge(max_size=limit, actual_size=size, text=too_big)
                f.write(chunk)
        return tmp, path

    async def open_file(self, request):
        """``POST /open?name=FILE.EXT``: the file becomes the mesh every tab edits."""
        from ..io import load

        hub = self.hub
        tmp, path = await self.received(request, "mesh")
        try:
            with tmp:
                new = await asyncio.get_running_loop().run_in_executor(None, lambda: StudioSession(load(path)))
        except ShapeflowError as exc:
            raise self.web.HTTPBadRequest(text=str(exc)) from None
        async with hub.lock:
            hub.use(new, os.path.basename(path))
            if self.solve:
                hub.solve()
            await hub.broadcast(*hub.mesh_frames())
        return self.web.json_response({"n_vertices": hub.n_vertices, "n_faces": hub.n_faces})

    async def open_weights(self, request):
        """``POST /weights?name=FILE.EXT``: weights from a mesh's ``weight`` attribute (same vertex
        count) or a ``.npy``/``.txt`` file, as one undo step."""
        hub = self.hub
        tmp, path = await self.received(request, "weights")
        try:
            with tmp:
                w = await asyncio.get_running_loop().run_in_executor(None, lambda: _read_weights(path, hub.n_vertices))
            async with hub.lock:
                hub.session.set_weights(w)
                hub.stale = True
                await hub.broadcast(_frame(b"WGT0", hub.session.weights, "<f4"), hub.state())
        except ShapeflowError as exc:
            raise self.web.HTTPBadRequest(text=str(exc)) from None
        return self.web.json_response({"n_vertices": hub.n_vertices})


def _read_weights(path: str, n: int) -> np.ndarray:
    from ..io import load
    from ..io.weights import load_weights

    if os.path.splitext(path)[1].lower() in WEIGHT_EXTENSIONS:
        return load_weights(path, n)
    mesh = load(path)
    name = os.path.basename(path)
    if mesh.weights is None:
        raise ParameterError(f'{name} has no per-vertex "weight" attribute')
    if mesh.n_vertices != n:
        raise ParameterError(f"{name} has {mesh.n_vertices:,} vertices, the studio's mesh {n:,}")
    return mesh.weights


def make_app(session: StudioSession, *, lams=DEFAULT_LAMS, solve: bool = True, max_upload: int = MAX_UPLOAD,
             name: str = ""):
    """The aiohttp application serving ``session`` (the family over ``lams`` is solved at start;
    ``name``: what the page calls the mesh, and the stem of downloads).

    ``max_upload`` is the largest file (bytes) a page may open or load weights from; larger
    uploads are refused with a message and nothing is kept.
    """
    web, WSMsgType = _web()
    hub = _Hub(session, sorted((float(x) for x in lams), reverse=True), name)
    r = _Routes(hub, web, WSMsgType, solve=solve, max_upload=params.integer("max_upload", max_upload, lo=1))

    async def on_startup(app):
        if solve:
            hub.solve()

    app = web.Application(client_max_size=MAX_MESSAGE)
    app.router.add_get("/", r.index)
    app.router.add_get("/ws", r.socket)
    app.router.add_get("/download/{name}", r.download)
    app.router.add_post("/open", r.open_file)
    app.router.add_post("/weights", r.open_weights)
    app.router.add_static("/static/", STATIC, follow_symlinks=False)
    app.on_startup.append(on_startup)
    app[_hub_key(web)] = hub
    return app


@functools.cache
def _hub_key(web):
    """The app key under which an app keeps its hub (made once aiohttp is imported)."""
    return web.AppKey("shapeflow_studio_hub", _Hub)


def hub_of(app) -> _Hub:
    """The session holder of an app made by :func:`make_app`."""
    return app[_hub_key(_web()[0])]
