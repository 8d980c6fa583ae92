"""Keep Sharp Edges: which edges the flow and the brush keep, and the object's setting for them.

An edge is *marked* when Blender marks it: **Mark Sharp** (the boolean EDGE attribute
``sharp_edge``) or an **Edge Crease** above 0 (the float EDGE attribute ``crease_edge``).
With *Keep Sharp Edges* on, the operators pass the marked edges to the library as
``sharp_edges`` (vertex pairs) and/or a feature angle (``feature_angle``, degrees; an edge whose
two faces bend by more is sharp): flat faces stay flat, straight edges straight, corners stay
(:func:`shapeflow.flow`, docs/method.md "Sharp features").  Loose edges (in no face) are left
out: the flow knows only the edges of faces.

Each object carries its own setting (``Object.shapeflow``: Keep Sharp Edges, Marked, Angle),
shown in the sidebar; the sidebar's and the menus' buttons start the operators with it.  An
operator's own properties (the *Adjust Last Operation* panel, or a script) are what a run uses.
"""

import math

import bpy
import numpy as np
from bpy.props import BoolProperty, FloatProperty, PointerProperty
from bpy.types import PropertyGroup

from . import bridge

#: the options an operator takes from the object's setting when a button starts it
SHARP_PROPS = ("keep_sharp", "sharp_marked", "sharp_by_angle", "sharp_angle")


def _props():
    """The four properties, one set per class that declares them."""
    return dict(
        keep_sharp=BoolProperty(
            name="Keep Sharp Edges", default=False,
            description="Flat faces stay flat, straight edges straight and corners in place; "
                        "round parts still smooth or enhance"),
        sharp_marked=BoolProperty(
            name="Marked", default=True,
            description="Edges marked Sharp or with an Edge Crease above 0"),
        sharp_by_angle=BoolProperty(
            name="By Angle", default=True,
            description="Edges whose two faces bend by more than the angle"),
        sharp_angle=FloatProperty(
            name="Angle", subtype="ANGLE", default=math.radians(30.0), min=0.0, max=math.pi, step=100,
            precision=1, description="Faces bending by more than this make a sharp edge"),
    )


class SharpOptions:
    """Operator mixin: Keep Sharp Edges and what makes an edge sharp."""

    __annotations__ = dict(_props())

    def sharp_options(self, me, mesh) -> dict:
        """``feature_angle`` / ``sharp_edges`` keywords for the library; {} when nothing is kept."""
        if not self.keep_sharp:
            return {}
        out = {}
        if self.sharp_by_angle:
            out["feature_angle"] = math.degrees(self.sharp_angle)
        if self.sharp_marked:
            pairs = face_edges(mesh, marked_pairs(me))
            if len(pairs):
                out["sharp_edges"] = pairs
        return out


class SHAPEFLOW_PG_settings(PropertyGroup):
    """An object's ShapeFlow setting: whether its sharp edges are kept, and which."""

    __annotations__ = dict(_props())


def draw_options(layout, op) -> None:
    """An operator's Keep Sharp Edges options in its redo panel."""
    col = layout.column(heading="Sharp")
    col.prop(op, "keep_sharp")
    sub = col.column()
    sub.enabled = op.keep_sharp
    sub.prop(op, "sharp_marked")
    row = sub.row(align=True)
    row.prop(op, "sharp_by_angle")
    ang = row.row(align=True)
    ang.enabled = op.sharp_by_angle
    ang.prop(op, "sharp_angle", text="")


def marked_pairs(me) -> np.ndarray:
    """(k, 2) vertex pairs of the edges marked Sharp or with a crease above 0."""
    mark = bridge.read_sharp_flags(me) | (bridge.read_creases(me) > 0.0)
    if not mark.any():
        return np.zeros((0, 2), dtype=np.int64)
    return bridge.read_edges(me)[mark]


def face_edges(mesh, pairs, values=None):
    """The pairs (and their values) that are edges of the library mesh's faces (loose edges left out)."""
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    t = mesh.topology
    n = np.int64(max(t.n_vertices, 1))
    keys = np.sort(t.edges[:, 0].astype(np.int64) * n + t.edges[:, 1])
    want = np.minimum(pairs[:, 0], pairs[:, 1]) * n + np.maximum(pairs[:, 0], pairs[:, 1])
    ok = np.isin(want, keys)
    return pairs[ok] if values is None else (pairs[ok], np.asarray(values)[ok])


def apply_object_setting(op, ob) -> None:
    """Give an operator button the object's Keep Sharp Edges setting."""
    settings = getattr(ob, "shapeflow", None) if ob is not None else None
    if settings is None:
        return
    for name in SHARP_PROPS:
        setattr(op, name, getattr(settings, name))


def draw_object_setting(layout, ob) -> None:
    """The sidebar's Keep Sharp Edges box for the active object (and how many edges it marks)."""
    settings = ob.shapeflow
    box = layout.column(align=True)
    box.prop(settings, "keep_sharp")
    sub = box.column(align=True)
    sub.enabled = settings.keep_sharp
    row = sub.row(align=True)
    row.prop(settings, "sharp_marked", toggle=True)
    row.prop(settings, "sharp_by_angle", toggle=True)
    ang = sub.row(align=True)
    ang.enabled = settings.sharp_by_angle
    ang.prop(settings, "sharp_angle")
    if ob.mode == "OBJECT" and settings.keep_sharp and settings.sharp_marked:
        sub.label(text=f"{len(marked_pairs(ob.data)):,} marked edges")


def register():
    bpy.types.Object.shapeflow = PointerProperty(type=SHAPEFLOW_PG_settings, name="ShapeFlow")


def unregister():
    del bpy.types.Object.shapeflow


CLASSES = (SHAPEFLOW_PG_settings,)
