"""Running the studio: :class:`StudioServer` (a server on a thread of its own) and :func:`studio`."""

from __future__ import annotations

import asyncio
import os
import threading
from typing import Sequence
from urllib.parse import quote, urlencode

from .. import params
from ..errors import OptionalDependencyError, ParameterError
from ..mesh import Mesh
from .security import is_loopback
from .server import DEFAULT_LAMS, MAX_UPLOAD, guard_of, hub_of, make_app
from .session import StudioSession
from .upload import stop_readers

__all__ = ["StudioServer", "studio", "IFRAME_HEIGHT", "KEEPALIVE", "connection_cap", "capped_runner"]

#: seconds a connection may hold without a whole request (aiohttp closes it then)
KEEPALIVE = 15.0


def connection_cap() -> int:
    """Connections the studio keeps open at once: 512, or half the files this process may open."""
    try:
        import resource

        soft = resource.getrlimit(resource.RLIMIT_NOFILE)[0]
        return max(16, min(512, soft // 2)) if soft != resource.RLIM_INFINITY else 512
    except (ImportError, ValueError, OSError):
        return 512


def capped_runner(web, app, keepalive: float):
    """aiohttp's runner for ``app`` whose server closes a connection past :func:`connection_cap` at
    once, and one without a whole request after ``keepalive`` seconds."""
    from aiohttp import web_server

    cap = connection_cap()

    class Capped(web_server.Server):
        def connection_made(self, handler, transport):
            super().connection_made(handler, transport)
            if len(self.connections) > cap:
                transport.abort()

    class Runner(web.AppRunner):
        async def _make_server(self):
            server = await super()._make_server()
            server.__class__ = Capped
            return server

    return Runner(app, access_log=None, shutdown_timeout=1.0, keepalive_timeout=float(keepalive))


def _quiet_handler(loop, context) -> None:
    """The studio loop's handler of errors no task awaited: running out of file descriptors while
    accepting (a flood of connections) and connections reset are dropped; anything else gets one
    line on stderr, never a traceback."""
    import sys

    exc = context.get("exception")
    if isinstance(exc, (OSError, ConnectionError)) or "socket.accept" in str(context.get("message", "")):
        return
    text = f"{type(exc).__name__}: {exc}" if exc is not None else context.get("message", "")
    print(f"shapeflow studio: {' '.join(str(text).split())[:200]}", file=sys.stderr)

#: the height of the page in a notebook, pixels (the panel fits without scrolling from 760)
IFRAME_HEIGHT = 780


class StudioServer:
    """The studio's web server on a background thread (its own asyncio loop).

    ``url`` is where a browser opens it, with the server's token (``?token=…``; see
    :mod:`~shapeflow.studio.security`); :meth:`link` makes the address of any route with it;
    :meth:`stop` ends it.  Binds to 127.0.0.1 unless ``host`` says otherwise (any other address
    still needs the token); ``port=0`` picks a free port.  ``max_upload``: the largest file
    (bytes) a page may open; ``name``: what the page calls the mesh; ``token``: the token (a fresh
    random one by default); ``allow_hosts``: more names a browser may use for this machine;
    ``outbox_limit`` and ``stall_seconds``: as for :func:`~shapeflow.studio.server.make_app`;
    ``keepalive``: seconds a connection may stay without a whole request (a connection that sends
    part of a request and stops, slowloris, is closed then; at most :func:`connection_cap`
    connections are open at once).  ``front``: the axis the model faces (``+x`` … ``-z``), over what
    its ``metadata["front"]`` says; files opened in the page that name none face it too.
    """

    def __init__(self, mesh_or_session, *, host: str = "127.0.0.1", port: int = 0, lams=DEFAULT_LAMS,
                 solve: bool = True, max_upload: int = MAX_UPLOAD, name: str = "", token: str | None = None,
                 allow_hosts=(), keepalive: float = KEEPALIVE, front: str | None = None, **queue):
        try:
            from aiohttp import web
        except Exception as exc:   # not installed, or installed and broken
            raise OptionalDependencyError("aiohttp", "studio", "the studio's server", exc) from exc

        session = mesh_or_session if isinstance(mesh_or_session, StudioSession) else \
            StudioSession(mesh_or_session)
        if front is not None:
            session.front = front         # ParameterError: not an axis, or along the model's up axis
        port = params.integer("port", port, lo=0, hi=65535)
        if token is not None and (not isinstance(token, str) or len(token) < 16 or not token.isprintable()):
            raise ParameterError("token must be a string of at least 16 printable characters")
        self._loop = asyncio.new_event_loop()
        self._loop.set_exception_handler(_quiet_handler)
        # the family is solved once the server listens (a port in use leaves no task behind)
        self._app = make_app(session, lams=lams, solve=solve, solve_at_start=False, max_upload=max_upload, name=name,
                             token=token, host=host, port=port, allow_hosts=allow_hosts, front=front, **queue)
        self._runner = capped_runner(web, self._app, keepalive)
        started = threading.Event()
        failure: list = []

        def main():
            asyncio.set_event_loop(self._loop)
            try:
                self._loop.run_until_complete(self._runner.setup())
                site = web.TCPSite(self._runner, host, port)
                self._loop.run_until_complete(site.start())
                self.port = site._server.sockets[0].getsockname()[1]   # noqa: SLF001 (aiohttp has no getter)
                guard_of(self._app).port = self.port
            except OSError as exc:
                failure.append(exc)
                self._loop.run_until_complete(self._runner.cleanup())
                self._loop.close()
                started.set()
                return
            if solve:                     # under way when the constructor returns

                async def start():
                    hub_of(self._app).solve()

                self._loop.run_until_complete(start())
            started.set()
            self._loop.run_forever()

        self._thread = threading.Thread(target=main, name="shapeflow-studio", daemon=True)
        self._thread.start()
        started.wait(30)
        if failure:
            exc = failure[0]
            why = os.strerror(exc.errno) if exc.errno else (exc.strerror or str(exc))
            raise ParameterError(f"the studio cannot listen on {host}:{port} ({why})")
        self.host = host
        shown = "127.0.0.1" if host in ("0.0.0.0", "", "::") else host
        self.address = f"http://{'[' + shown + ']' if ':' in shown else shown}:{self.port}/"
        self.url = self.link()

    @property
    def token(self) -> str:
        """The token every request needs (also in :attr:`url`)."""
        return guard_of(self._app).token

    @property
    def loopback(self) -> bool:
        """Whether only this machine can reach the server."""
        return is_loopback(self.host)

    def link(self, path: str = "", **query) -> str:
        """The absolute address of ``path`` (e.g. ``"download/shape.ply"``) with the token and
        ``query`` as its query string."""
        return self.address + quote(path.lstrip("/"), safe="/%") + "?" + urlencode({**query, "token": self.token})

    @property
    def session(self) -> StudioSession:
        """The :class:`StudioSession` the pages edit (a new one after a page opened a file)."""
        return hub_of(self._app).session

    def result(self):
        """The mesh as the pages have made it so far (:attr:`StudioSession.mesh`: the layout of the
        file opened, the painted weights as its ``"weight"`` attribute); the server keeps running."""
        return self.session.mesh

    def stop(self) -> None:
        """End the server at once: open pages lose their connection, a page that stopped reading
        included (its socket is aborted, not waited for)."""
        if self._loop.is_closed() or not self._loop.is_running():
            return
        stop_readers()                    # a file being read for a page: its reader is killed, not awaited

        async def shutdown():
            hub = hub_of(self._app)
            if hub.watcher is not None:
                hub.watcher.cancel()
            for ws, box in list(hub.sockets.items()):
                box.close()
                box.abort()
            await self._runner.cleanup()

        fut = asyncio.run_coroutine_threadsafe(shutdown(), self._loop)
        try:
            fut.result(10)
        except Exception:           # noqa: BLE001 - the loop is stopped below whatever happened
            pass
        finally:
            self._loop.call_soon_threadsafe(self._loop.stop)
            self._thread.join(10)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.stop()
        return False

    def _repr_html_(self) -> str:
        """Jupyter shows the page inline: an iframe of :attr:`url`.  The page inside gets no cookie
        from another site's frame (SameSite=Strict), so its scripts load with the token in their
        addresses (the page's import map)."""
        import html

        return (f'<iframe src="{html.escape(self.url, quote=True)}" width="100%" height="{IFRAME_HEIGHT}" '
                'style="border:0" title="ShapeFlow Studio"></iframe>')


def studio(mesh: Mesh | StudioSession, *, port: int = 0, host: str = "127.0.0.1",
           lams: Sequence[float] = DEFAULT_LAMS, max_upload: int = MAX_UPLOAD, name: str = "",
           front: str | None = None) -> StudioServer:
    """Start the studio on ``mesh`` and return its server (``sf.studio(mesh)``); in Jupyter the
    returned object shows the page inline.  ``server.result()`` is the mesh as edited so far,
    ``server.session`` the :class:`StudioSession` the page edits, ``server.stop()`` ends it;
    ``front``: the axis the model faces, when its metadata does not say (e.g. ``"-z"`` for Spot read
    back from a file).

    >>> server = sf.studio(sf.load_example("spot"))     # doctest: +SKIP
    >>> server                                           # doctest: +SKIP
    >>> edited = server.result()                         # doctest: +SKIP
    """
    return StudioServer(mesh, host=host, port=port, lams=lams, max_upload=max_upload, name=name, front=front)
