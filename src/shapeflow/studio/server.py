"""The studio's web server: the page, its static files, and a WebSocket to one :class:`StudioSession`.

Stack (aiohttp on the Python side, a small three.js front end served from the package, no
Node.js at install or run time, nothing fetched from the internet): the page needs pointer
events on the surface for painting and sculpting, per-frame updates of every position, and
sliders; three.js gives the first two with a raycaster and a buffer attribute, and the
WebSocket carries positions as raw float32 frames.

Protocol.  The server sends JSON text messages (``{"type": ...}``) and binary frames that
start with a 4-byte tag: ``POS0`` float32 positions (n, 3), ``TRI0`` uint32 triangles (the
faces' fans, for drawing), ``EDG0`` uint32 edge pairs (the real polygon edges, for the
wireframe), ``WGT0`` float32 weights (n,), ``FLD0`` float32 values of a colour field (n,),
``PSUB`` some positions (uint32 count k, k uint32 indices, k × 3 float32: what a dab moved).
The page sends JSON: ``{"op": "lam", "value"}``, ``{"op": "paint", "center", "radius",
"value"}``, ``{"op": "dab", "center", "radius", "lam", "inflate"}``, ``{"op": "apply",
"value"}``, ``{"op": "undo"}``, ``{"op": "redo"}``, ``{"op": "field", "name"}`` (weights,
curvature or displacement: :meth:`StudioSession.field`).
``GET /download/NAME.EXT`` returns the current mesh in any format shapeflow writes.

Every tab shares the server's session: a second tab sees the same shape, a closed tab loses
nothing.  The server binds to 127.0.0.1 unless told otherwise.
"""

from __future__ import annotations

import asyncio
import json
import os
import tempfile
from pathlib import Path

import numpy as np

from ..errors import OptionalDependencyError, ParameterError, ShapeflowError
from ..geometry.measures import fan_triangles
from .session import StudioSession

__all__ = ["make_app", "STATIC", "DEFAULT_LAMS", "MAX_MESSAGE"]

STATIC = Path(__file__).resolve().parent / "static"
#: the family the slider walks by default: λ = 0 … −240 (figure 1 of the paper)
DEFAULT_LAMS = tuple(float(x) for x in np.arange(0.0, -241.0, -10.0))
#: the largest message a page may send (a JSON edit is a few hundred bytes)
MAX_MESSAGE = 1 << 16


def _web():
    try:
        from aiohttp import WSMsgType, web
    except ImportError as exc:
        raise OptionalDependencyError("aiohttp", "studio", "the studio's server") from exc
    return web, WSMsgType


def _frame(tag: bytes, arr: np.ndarray, dtype) -> bytes:
    return tag + np.ascontiguousarray(arr, dtype=dtype).tobytes()


class _Hub:
    """The session and the sockets of the open tabs."""

    def __init__(self, session: StudioSession, lams):
        self.session = session
        self.lams = list(lams)
        self.sockets: set = set()
        self.lam = 0.0
        self.stale = False
        self.lock = asyncio.Lock()

    async def broadcast(self, *messages) -> None:
        for ws in list(self.sockets):
            try:
                for m in messages:
                    await (ws.send_bytes(m) if isinstance(m, bytes) else ws.send_str(json.dumps(m)))
            except (ConnectionError, RuntimeError):      # a tab that went away meanwhile
                self.sockets.discard(ws)

    def state(self) -> dict:
        s = self.session
        st = s.family_status()
        return {"type": "state", "lam": self.lam, "version": s.version, "can_undo": s.can_undo,
                "can_redo": s.can_redo, "family": {"state": st.state, "done": st.done, "total": st.total},
                "lams": self.lams}


async def _handle(hub: _Hub, msg: dict):
    """Carry out one edit; returns the frames and messages every tab needs."""
    s = hub.session
    op = msg.get("op")
    loop = asyncio.get_running_loop()
    if op == "lam":
        hub.lam = float(msg["value"])
        if hub.stale:        # the shape or the weights changed since the family was solved: solve again
            hub.stale = False
            s.solve_family(hub.lams)
            asyncio.create_task(_watch_family(hub))
        st = s.family_status()
        V = s.shape_at(hub.lam) if st.state == "done" else s.vertices
        return [_frame(b"POS0", V, "<f4"), hub.state()]
    if op != "field":
        hub.stale = True     # every other operation edits the shape or the weights
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
    if op == "field":
        values = await loop.run_in_executor(None, lambda: s.field(str(msg["name"])))
        return [_frame(b"FLD0", values, "<f4"), {"type": "field", "name": str(msg["name"]),
                                                  "version": s.version}]
    if op == "solve":
        lams = [float(x) for x in msg.get("lams", hub.lams)]
        hub.lams = sorted(lams, reverse=True)
        hub.stale = False
        s.solve_family(hub.lams)
        asyncio.create_task(_watch_family(hub))
        return [hub.state()]
    raise ParameterError(f"unknown operation {op!r}")


async def _watch_family(hub: _Hub) -> None:
    """Tell every tab how the background family solve goes, until it ends."""
    while True:
        st = hub.session.family_status()
        await hub.broadcast(hub.state())
        if st.state != "running":
            return
        await asyncio.sleep(0.1)


def make_app(session: StudioSession, *, lams=DEFAULT_LAMS, solve: bool = True):
    """The aiohttp application serving ``session`` (the family over ``lams`` is solved at start)."""
    web, WSMsgType = _web()
    hub = _Hub(session, sorted((float(x) for x in lams), reverse=True))
    mesh0 = session.mesh
    tris = fan_triangles(mesh0)
    edges = mesh0.topology.edges

    async def index(request):
        return web.FileResponse(STATIC / "index.html")

    async def socket(request):
        ws = web.WebSocketResponse(max_msg_size=MAX_MESSAGE, heartbeat=20.0)
        await ws.prepare(request)
        hub.sockets.add(ws)
        V = session.vertices
        await ws.send_str(json.dumps({"type": "mesh", "n_vertices": int(V.shape[0]),
                                      "n_faces": mesh0.n_faces, "name": mesh0.metadata.get("name", "")}))
        for frame in (_frame(b"TRI0", tris, "<u4"), _frame(b"EDG0", edges, "<u4"),
                      _frame(b"POS0", V, "<f4"), _frame(b"WGT0", session.weights, "<f4")):
            await ws.send_bytes(frame)
        await ws.send_str(json.dumps(hub.state()))
        try:
            async for msg in ws:
                if msg.type != WSMsgType.TEXT:
                    continue
                try:
                    async with hub.lock:
                        out = await _handle(hub, json.loads(msg.data))
                    await hub.broadcast(*out)
                except (ShapeflowError, KeyError, TypeError, ValueError) as exc:
                    await ws.send_str(json.dumps({"type": "error", "message": str(exc)}))
        finally:
            hub.sockets.discard(ws)
        return ws

    async def download(request):
        from ..io import save
        from ..io.registry import format_for

        name = request.match_info["name"]
        try:
            format_for(name, None)
        except ShapeflowError as exc:
            raise web.HTTPBadRequest(text=str(exc)) from None
        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, os.path.basename(name))
            save(path, session.mesh)
            body = Path(path).read_bytes()
        return web.Response(body=body, content_type="application/octet-stream",
                            headers={"Content-Disposition": f'attachment; filename="{os.path.basename(name)}"'})

    async def on_startup(app):
        if solve:
            session.solve_family(hub.lams)
            app["watch"] = asyncio.create_task(_watch_family(hub))

    app = web.Application(client_max_size=MAX_MESSAGE)
    app.router.add_get("/", index)
    app.router.add_get("/ws", socket)
    app.router.add_get("/download/{name}", download)
    app.router.add_static("/static/", STATIC, follow_symlinks=False)
    app.on_startup.append(on_startup)
    app["hub"] = hub
    return app
