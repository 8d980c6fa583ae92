"""ShapeFlow Studio: shape enhancement, weight painting and the brush in a web browser.

``shapeflow studio MESH`` on the command line, ``sf.studio(mesh)`` (:func:`studio`) in Python or
Jupyter (the ``studio`` extra: aiohttp; the page's three.js ships in the package).
:class:`StudioSession` is the model a page edits; :mod:`~shapeflow.studio.server` serves it.
Guide: docs/studio.md.
"""

import sys
import types

from .session import FamilyStatus, StudioSession, smooth_falloff

__all__ = ["StudioSession", "FamilyStatus", "smooth_falloff", "StudioServer", "studio"]


def __getattr__(name):            # the server needs aiohttp: imported on first use
    if name in ("StudioServer", "studio"):
        from ..errors import OptionalDependencyError

        try:
            from . import run
        except Exception as exc:   # not installed, or installed and broken
            raise OptionalDependencyError("aiohttp", "studio", "the studio's server", exc) from exc
        return getattr(run, name)
    raise AttributeError(name)


class _CallableModule(types.ModuleType):
    """``sf.studio(mesh)`` starts the studio: once this package is imported, ``shapeflow.studio`` is
    the package itself (Python binds a subpackage to its parent's attribute), so calling the
    package calls :func:`studio`."""

    def __call__(self, mesh, **kw):
        return __getattr__("studio")(mesh, **kw)


sys.modules[__name__].__class__ = _CallableModule
