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

Protocol. The page sends JSON messages, checked against the table of
:mod:`~shapeflow.studio.protocol` before anything changes; a refused message is answered by an
``error`` message and the socket stays open; each request is answered to its tab by a ``done`` (or
that ``error``) message carrying the request's ``id``. The server sends JSON text messages
(``{"type": ...}``: ``mesh``, ``state``, ``field``, ``orientation``, ``done``, ``error``) and binary
frames that start with a 4-byte tag: ``POS0`` float32 positions (n, 3), ``BAS0`` float32 positions
of the input (the split view's "before"), ``TRI0`` uint32 triangles (the faces' fans, for drawing),
``EDG0`` uint32 edge pairs (the real polygon edges, for the wireframe), ``WGT0`` float32 weights
(n,), ``FLD0`` float32 values of a colour field (n,), ``PSUB`` some positions (uint32 count k, k
uint32 indices, k × 3 float32: what a dab moved). No frame holds a value that is not finite in
float32. A ``mesh`` message starts a new mesh (on connecting, and in every tab when a file is
opened). Each tab has its own bounded queue (:mod:`~shapeflow.studio.outbox`). What the messages do,
and the editing model, is :mod:`~shapeflow.studio.hub`'s.

``GET /`` is the page, with an import map that gives every script's address with the token the
page was opened with (a page in another site's frame, e.g. a notebook's, gets no cookie).

``GET /download/NAME.EXT`` returns the current mesh, on the layout of the file opened, in any format
shapeflow writes, with what that format drops of it (the writer's
:class:`~shapeflow.errors.DataLossWarning` messages) in the header ``X-Shapeflow-Warnings`` (a JSON
list of strings, ASCII); ``GET /losses/NAME.EXT`` says the same without downloading (JSON
``{"format": ..., "losses": [...]}``: the writer run on the current mesh into memory);
``POST /open?name=FILE.EXT`` (the file as the body) opens a mesh in every tab,
``POST /weights?name=FILE.EXT`` reads weights (a mesh's ``weight`` attribute with the same vertex
count, or ``.npy``/``.txt``); uploads above ``max_upload`` bytes are refused (413) and nothing of them is
kept; an upload is read by a child process bounded in time and memory
(:mod:`~shapeflow.studio.upload`). The server reads and writes no file of the user's: an upload
lives in a temporary folder until it is read.

Every tab shares the server's session: a second tab sees the same shape, a closed tab loses
nothing.  The server binds to 127.0.0.1 unless told otherwise.
"""

from __future__ import annotations

import asyncio
import functools
import io
import json
import os
import tempfile
import threading
from pathlib import Path
from urllib.parse import urlencode

import numpy as np

from .. import params
from ..errors import OptionalDependencyError, ShapeflowError
from ..io.weights import WEIGHT_EXTENSIONS
from . import protocol
from .hub import HANDLERS, STROKE_OPS, Hub, field_scale, frame  # noqa: F401 (field_scale: the tests' name)
from .outbox import LIMIT as OUTBOX_LIMIT
from .outbox import STALL, Outbox
from .security import SAFE_HEADERS, Guard, check_name, content_disposition, new_token
from .session import StudioSession

__all__ = ["make_app", "hub_of", "guard_of", "field_scale", "STATIC", "DEFAULT_LAMS", "MAX_MESSAGE",
           "MAX_UPLOAD", "WARNINGS_HEADER"]

STATIC = Path(__file__).resolve().parent / "static"
#: the family the slider walks by default: λ = +60 … −240 in steps of 10 (smoothing and enhancement
#: share one solve: +λ and −λ are one shift of the multi-shift solve)
DEFAULT_LAMS = tuple(float(x) for x in np.arange(60.0, -241.0, -10.0))
#: the largest message a page may send (a JSON edit is a few hundred bytes)
MAX_MESSAGE = 1 << 16
#: the largest file a page may open by default (``--max-upload``), bytes
MAX_UPLOAD = 512 << 20
#: the download's header that lists what its format dropped (a JSON list of strings)
WARNINGS_HEADER = "X-Shapeflow-Warnings"


def _web():
    try:
        from aiohttp import WSMsgType, web
    except Exception as exc:   # not installed, or installed and broken
        raise OptionalDependencyError("aiohttp", "studio", "the studio's server", exc) from exc
    return web, WSMsgType


async def _in_thread(fn):
    return await asyncio.get_running_loop().run_in_executor(None, fn)


class _Routes:
    """The HTTP and WebSocket handlers of one app (``web``: aiohttp's web module)."""

    def __init__(self, hub: Hub, web, WSMsgType, *, solve: bool, max_upload: int, outbox: dict):
        self.hub, self.web, self.WSMsgType = hub, web, WSMsgType
        self.solve, self.max_upload, self.outbox = solve, max_upload, outbox

    async def index(self, request):
        guard = request.app[_key(self.web, "guard")]
        given = request.query.get("token")
        token = given if given is not None and guard.token_is(given) else None
        resp = self.web.Response(text=page(token), content_type="text/html", charset="utf-8")
        if token is not None:     # the page's scripts load with the cookie, or with the token in their URLs
            resp.set_cookie(guard.cookie, guard.cookie_value, httponly=True, samesite="Strict", path="/")
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
                rid = None
                try:
                    op, fields = protocol.parse(msg.data)
                    rid = fields.pop("id")
                    async with hub.lock:
                        hub.sender = ws
                        if op not in STROKE_OPS:        # a stroke left open ends at any other message
                            hub.close_stroke()
                        out = await HANDLERS[op](hub, fields)
                    await hub.broadcast(*out)
                    box.put({"type": "done", "id": rid, "op": op})
                except ShapeflowError as exc:
                    rid = getattr(exc, "request_id", rid)
                    box.put({"type": "error", "message": str(exc), "id": rid})
        finally:
            hub.sockets.pop(ws, None)
            box.close()
            if hub.stroke_owner is ws:                  # the tab that began a stroke went away: it ends
                async with hub.lock:
                    hub.close_stroke()
                    await hub.broadcast(hub.state())
        return ws

    def _format(self, request):
        """The file name a download or losses request names, and its format (400: a bad name, no format)."""
        from ..io.registry import format_for

        web, name = self.web, request.match_info["name"]
        why = check_name(name)
        if why:
            raise web.HTTPBadRequest(text=why)
        try:
            return name, format_for(name, None)
        except ShapeflowError as exc:
            raise web.HTTPBadRequest(text=str(exc)) from None

    async def download(self, request):
        from ..io import save

        web, (name, _) = self.web, self._format(request)
        hub = self.hub
        async with hub.lock:
            hub.close_stroke()
            session = hub.session
            mesh, mark = session.saved_mesh()
        try:
            with tempfile.TemporaryDirectory(prefix="shapeflow-studio-") as tmp:
                path = os.path.join(tmp, name)
                try:
                    lost = await _in_thread(lambda: _data_losses(lambda: save(path, mesh)))
                    body = Path(path).read_bytes()
                except Exception as exc:        # noqa: BLE001 - every failure is one line for the page
                    raise _refusal(web, name, exc, tmp) from None
        except OSError as exc:                  # the temporary folder itself: full or not writable
            raise _refusal(web, name, exc, None) from None
        session.mark_saved(mark)                        # downloaded: no unsaved changes from here
        await hub.broadcast(hub.state())
        return web.Response(body=body, content_type="application/octet-stream",
                            headers={"Content-Disposition": content_disposition(name),
                                     WARNINGS_HEADER: json.dumps(lost, ensure_ascii=True)})

    async def losses(self, request):
        """``GET /losses/NAME.EXT``: what a download in that format would drop of the current mesh."""
        web, (name, fmt) = self.web, self._format(request)
        mesh = self.hub.session.mesh
        try:
            lost = await _in_thread(lambda: _data_losses(lambda: fmt.writer(io.BytesIO(), mesh, binary=None)))
        except Exception as exc:                # noqa: BLE001 - every failure is one line for the page
            raise _refusal(web, name, exc, None) from None
        return web.json_response({"format": fmt.name, "losses": lost})

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
        try:
            tmp = tempfile.TemporaryDirectory(prefix="shapeflow-studio-")
        except OSError as exc:
            raise _refusal(web, name, exc, None) from None
        path, size = os.path.join(tmp.name, name), 0
        try:
            with open(path, "wb") as f:
                async for chunk in request.content.iter_chunked(1 << 20):
                    size += len(chunk)
                    if size > limit:
                        raise web.HTTPRequestEntityTooLarge(max_size=limit, actual_size=size, text=too_big)
                    f.write(chunk)
        except OSError as exc:                  # a full temporary folder
            tmp.cleanup()
            raise _refusal(web, name, exc, tmp.name) from None
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
        except Exception as exc:                # noqa: BLE001 - every failure is one line for the page
            raise _refusal(self.web, name, exc, os.path.dirname(path)) from None
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
                hub.close_stroke()
                hub.session.set_weights(w)
                hub.changed()
                await hub.broadcast(frame(b"WGT0", hub.session.weights, "<f4"), hub.state())
        except Exception as exc:                # noqa: BLE001 - every failure is one line for the page
            raise _refusal(self.web, name, exc, os.path.dirname(path)) from None
        return self.web.json_response({"n_vertices": s.n_input_vertices})


_WARNINGS_LOCK = threading.Lock()     # warnings.catch_warnings changes the process's filters: one at a time


def _data_losses(write) -> list:
    """Run ``write()`` and return the messages of the :class:`~shapeflow.errors.DataLossWarning` it
    gave (each once, in order); they are the page's to show, not the server's terminal's."""
    import warnings

    from ..errors import DataLossWarning

    with _WARNINGS_LOCK, warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", DataLossWarning)
        write()
    out = []
    for w in caught:
        text = " ".join(str(w.message).split())
        if issubclass(w.category, DataLossWarning) and text not in out:
            out.append(text)
    return out


def _refusal(web, name: str, exc: BaseException, tmp: str | None):
    """The one-line answer to a failed upload or download: 400 for what the file or the request holds
    (a :class:`ShapeflowError`), 507 for a full or unwritable temporary folder, 500 for anything
    else (also said on the server's stderr in one line); never a temporary path, never a traceback."""
    import sys

    if isinstance(exc, web.HTTPException):
        return exc
    text = " ".join(str(exc).split())
    if tmp:
        text = text.replace(tmp + os.sep, "").replace(tmp, "")
    if isinstance(exc, ShapeflowError) and not isinstance(exc, OSError):
        return web.HTTPBadRequest(text=text if text.startswith(name) else f"{name}: {text}")
    if isinstance(exc, OSError):
        why = exc.strerror or text or type(exc).__name__
        return web.HTTPInsufficientStorage(text=f"{name}: the studio's temporary folder cannot hold it ({why})")
    print(f"shapeflow studio: internal error on {name}: {type(exc).__name__}: {text[:200]}", file=sys.stderr)
    return web.HTTPInternalServerError(text=f"{name}: internal error ({type(exc).__name__}: {text[:200]})")


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
             allow_hosts=(), outbox_limit: int = OUTBOX_LIMIT, stall_seconds: float = STALL,
             solve_at_start: bool | None = None, front: str | None = None):
    """The aiohttp application serving ``session`` (the family over ``lams`` is solved at start;
    ``name``: what the page calls the mesh, and the stem of downloads).

    ``token`` (a fresh random one by default), ``host`` and ``port`` (where it listens; a server
    that learns its port on binding sets ``guard_of(app).port``) and ``allow_hosts`` configure the
    :class:`~shapeflow.studio.security.Guard` every request passes.  ``max_upload`` is the largest
    file (bytes) a page may open or load weights from; larger uploads are refused with a message
    and nothing is kept.  ``outbox_limit`` (bytes) and ``stall_seconds`` bound what waits for one
    tab and how long one send to it may take (:mod:`~shapeflow.studio.outbox`).  ``solve`` solves
    the family of every mesh the server shows; ``solve_at_start`` (default: ``solve``) whether the
    app does it for the first mesh when it starts (:class:`StudioServer` does it once it listens).
    ``front``: the axis a file opened in the page faces when it names none (``--front``).
    """
    web, WSMsgType = _web()
    hub = Hub(session, sorted((float(x) for x in lams), reverse=True), name, front)
    r = _Routes(hub, web, WSMsgType, solve=solve, max_upload=params.integer("max_upload", max_upload, lo=1),
                outbox={"limit": params.integer("outbox_limit", outbox_limit, lo=1),
                        "stall": params.number("stall_seconds", stall_seconds, lo=0.001)})
    guard = Guard(token or new_token(), host, port, allow_hosts=allow_hosts)

    async def on_startup(app):
        if solve if solve_at_start is None else solve_at_start:
            hub.solve()

    app = web.Application(client_max_size=MAX_MESSAGE, middlewares=[_guard_middleware(web, guard)])
    app.router.add_get("/", r.index)
    app.router.add_get("/ws", r.socket)
    app.router.add_get("/download/{name}", r.download)
    app.router.add_get("/losses/{name}", r.losses)
    app.router.add_post("/open", r.open_file)
    app.router.add_post("/weights", r.open_weights)
    app.router.add_static("/static/", STATIC, follow_symlinks=False)
    app.on_startup.append(on_startup)
    app[_key(web, "hub")] = hub
    app[_key(web, "guard")] = guard
    return app


def page(token: str | None) -> str:
    """The page (index.html) with its import map: every script of the package mapped to its address,
    with ``?token=`` when the page was opened with the token, so that its scripts load without the
    cookie too (a page in another site's frame, e.g. a notebook's, gets no SameSite=Strict cookie)."""
    q = "" if token is None else "?" + urlencode({"token": token})
    imports = {f"/static/{p.relative_to(STATIC).as_posix()}": f"/static/{p.relative_to(STATIC).as_posix()}{q}"
               for p in sorted(STATIC.rglob("*.js"))}
    imports["three"] = imports["/static/vendor/three/three.module.js"]
    text = json.dumps({"imports": imports}).replace("</", "<\\/")
    return (STATIC / "index.html").read_text(encoding="utf-8").replace(
        "<!--importmap-->", f'<script type="importmap">{text}</script>', 1)


@functools.cache
def _key(web, what: str):
    """The app key under which an app keeps its hub or guard (made once aiohttp is imported)."""
    return web.AppKey(f"shapeflow_studio_{what}", Hub if what == "hub" else Guard)


def hub_of(app) -> Hub:
    """The session holder of an app made by :func:`make_app`."""
    return app[_key(_web()[0], "hub")]


def guard_of(app) -> Guard:
    """The access checks of an app made by :func:`make_app` (its token: ``guard_of(app).token``)."""
    return app[_key(_web()[0], "guard")]
