"""Running the studio: :class:`StudioServer` (a server on a thread of its own) and :func:`studio`."""

from __future__ import annotations

import asyncio
import threading

from .. import params
from ..errors import OptionalDependencyError, ParameterError
from .server import DEFAULT_LAMS, MAX_UPLOAD, hub_of, make_app
from .session import StudioSession

__all__ = ["StudioServer", "studio"]


class StudioServer:
    """The studio's web server on a background thread (its own asyncio loop).

    ``url`` is where a browser opens it; :meth:`stop` ends it.  Binds to 127.0.0.1 unless
    ``host`` says otherwise; ``port=0`` picks a free port.  ``max_upload``: the largest file
    (bytes) a page may open; ``name``: what the page calls the mesh.
    """

    def __init__(self, mesh_or_session, *, host: str = "127.0.0.1", port: int = 0, lams=DEFAULT_LAMS,
                 solve: bool = True, max_upload: int = MAX_UPLOAD, name: str = ""):
        try:
            from aiohttp import web
        except Exception as exc:   # not installed, or installed and broken
            raise OptionalDependencyError("aiohttp", "studio", "the studio's server", exc) from exc

        session = mesh_or_session if isinstance(mesh_or_session, StudioSession) else \
            StudioSession(mesh_or_session)
        port = params.integer("port", port, lo=0, hi=65535)
        self._loop = asyncio.new_event_loop()
        self._app = make_app(session, lams=lams, solve=solve, max_upload=max_upload, name=name)
        self._runner = web.AppRunner(self._app, access_log=None)
        started = threading.Event()
        failure: list = []

        def main():
            asyncio.set_event_loop(self._loop)
            try:
                self._loop.run_until_complete(self._runner.setup())
                site = web.TCPSite(self._runner, host, port)
                self._loop.run_until_complete(site.start())
                self.port = site._server.sockets[0].getsockname()[1]   # noqa: SLF001 (aiohttp has no getter)
            except OSError as exc:
                failure.append(exc)
                started.set()
                return
            started.set()
            self._loop.run_forever()

        self._thread = threading.Thread(target=main, name="shapeflow-studio", daemon=True)
        self._thread.start()
        started.wait(30)
        if failure:
            raise ParameterError(f"the studio cannot listen on {host}:{port} ({failure[0].strerror or failure[0]})")
        self.host = host
        self.url = f"http://{'127.0.0.1' if host in ('0.0.0.0', '') else host}:{self.port}/"

    @property
    def session(self) -> StudioSession:
        """The :class:`StudioSession` the pages edit (a new one after a page opened a file)."""
        return hub_of(self._app).session

    def stop(self) -> None:
        """End the server (open pages lose their connection)."""
        if not self._loop.is_running():
            return
        fut = asyncio.run_coroutine_threadsafe(self._runner.cleanup(), self._loop)
        try:
            fut.result(10)
        finally:
            self._loop.call_soon_threadsafe(self._loop.stop)
            self._thread.join(10)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.stop()
        return False

    def _repr_html_(self) -> str:          # Jupyter: the page in the notebook
        return f'<iframe src="{self.url}" width="100%" height="600" style="border:0"></iframe>'


def studio(mesh, *, port: int = 0, host: str = "127.0.0.1", lams=DEFAULT_LAMS,
           max_upload: int = MAX_UPLOAD) -> StudioServer:
    """Start the studio on ``mesh`` and return its server; in Jupyter the returned object shows
    the page inline.  ``server.session`` is the :class:`StudioSession` the page edits.

    >>> s = sf.studio(sf.load_example("spot"))     # doctest: +SKIP
    >>> s                                           # doctest: +SKIP
    """
    return StudioServer(mesh, host=host, port=port, lams=lams, max_upload=max_upload)
