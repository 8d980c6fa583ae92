"""ShapeFlow for Blender: shape enhancement and smoothing with the hybrid quad/triangle Laplacian.

A Blender 4.2+ extension (see ``blender_manifest.toml``); ``shapeflow`` and
``scipy`` come as bundled wheels, numpy is Blender's own.  Operators:

``object.shapeflow_flow``
    Enhance / Smooth Shape — :func:`shapeflow.flow` on the active mesh, Object
    or Edit Mode (selected vertices only).
``object.shapeflow_family``
    Shape Family — :func:`shapeflow.family` for a λ range, one object per λ,
    side by side, coloured along a ramp.
``object.shapeflow_subdivide_enhance``
    Subdivide and Enhance — :func:`shapeflow.subdivide` carrying the vertex
    groups, then the flow weighted by one of them.
``object.shapeflow_brush``
    ShapeFlow Brush — :class:`shapeflow.Brush`, modal (Drag Dot preview) or
    scripted with a list of stroke points.

All are in the sidebar (N ▸ ShapeFlow) and in Object ▸ ShapeFlow.  Keep Sharp
Edges (the object's marked edges and/or a feature angle, :mod:`.sharp`) is an
option of each, and a setting of each object shown in the sidebar.
"""

import bpy
from bpy.app.handlers import persistent

from . import bridge, brush_op, operators, panel, sharp

_CLASSES = (*sharp.CLASSES, *operators.CLASSES, *brush_op.CLASSES, *panel.CLASSES)


@persistent
def _clear_caches(*_args):
    bridge.clear_caches()


def _warm_import():
    """Import shapeflow and scipy once Blender is idle, not on the first click (~0.5 s)."""
    try:
        import scipy.sparse.linalg  # noqa: F401

        import shapeflow.flow  # noqa: F401
        import shapeflow.sculpt  # noqa: F401
        import shapeflow.subdivision  # noqa: F401
    except Exception:  # noqa: BLE001 - the operators report import problems themselves
        pass
    return None  # run once


def register():
    for cls in _CLASSES:
        bpy.utils.register_class(cls)
    sharp.register()
    for menu, fn in panel.MENUS:
        menu.append(fn)
    bpy.app.handlers.load_post.append(_clear_caches)
    if not bpy.app.background:
        bpy.app.timers.register(_warm_import, first_interval=1.0)


def unregister():
    if _clear_caches in bpy.app.handlers.load_post:
        bpy.app.handlers.load_post.remove(_clear_caches)
    for menu, fn in reversed(panel.MENUS):
        menu.remove(fn)
    sharp.unregister()
    for cls in reversed(_CLASSES):
        bpy.utils.unregister_class(cls)
    bridge.clear_caches()
