"""The sculpt-style brush operator (``object.shapeflow_brush``, section 4.3 of the paper).

Interactive (``INVOKE_DEFAULT``, e.g. from the sidebar): hovering the mesh
shows the brush radius as a circle on the surface under the mouse (ray cast on
the object); left-click-drag applies dabs of :class:`shapeflow.Brush`:

* *Drag Dot* (default): the dab is previewed under the mouse and follows it
  while the button is held; it is applied on release;
* *Space*: dabs every ``spacing × radius`` along the mouse path, applied as
  the mouse moves.

``[`` / ``]`` shrink / grow the radius, holding Ctrl inverts λ (smooth instead
of enhance), Enter or Space finishes (one undo step), Esc or right click
cancels and restores the mesh.  The dab centres of a finished session are kept
in the ``stroke`` property, so *Adjust Last Operation* replays the stroke with
other settings.

Scripted (``EXEC_DEFAULT``, the default of ``bpy.ops``)::

    bpy.ops.object.shapeflow_brush(lam=-50.0, radius=0.2, spacing=0.25,
                                   stroke=[{"name": "", "location": p} for p in points])

(Blender wants every key of a collection item, ``name`` included, as for its
own ``sculpt.brush_stroke``.)

applies the stroke through the given world-space points, dabbing every
``spacing × radius`` of arc length (``spacing=0``: exactly at the points):
the same as ``shapeflow.Brush(mesh, lam=..., radius=...).stroke(points,
spacing)`` in object space.  ``keep_sharp=True`` (with ``sharp_marked``,
``sharp_by_angle``, ``sharp_angle``; :mod:`.sharp`) makes the dabs keep the
sharp edges: a dab never drags a vertex across one.

The interactive state lives in :class:`BrushSession` (no ``bpy`` events), so it
can be driven and tested without a window.
"""

import math

import bpy
import numpy as np
from bpy.props import BoolProperty, CollectionProperty, EnumProperty, FloatProperty, FloatVectorProperty, StringProperty
from bpy.types import Operator, PropertyGroup

from . import bridge, sharp
from .sharp import SharpOptions

FALLOFF_ITEMS = [
    ("SMOOTH", "Smooth", "Weights fall off as (1 − t²)² towards the rim (t = distance / radius)"),
    ("CONSTANT", "Constant", "Every vertex inside the sphere has its full weight (the paper)"),
]
METHOD_ITEMS = [
    ("DRAG_DOT", "Drag Dot", "Preview one dab under the mouse while dragging, apply it on release"),
    ("SPACE", "Space", "Apply dabs along the mouse path, every Spacing × Radius"),
]
HELP = ("ShapeFlow brush: LMB drag apply · [ ] radius · Ctrl invert λ · "
        "Enter/Space finish · Esc/RMB cancel")


class SHAPEFLOW_PG_stroke_point(PropertyGroup):
    """One point of a scripted or recorded stroke (world space)."""

    location: FloatVectorProperty(name="Location", size=3, subtype="XYZ")


# --------------------------------------------------------------------------
# geometry helpers
# --------------------------------------------------------------------------

def _matrix(ob) -> np.ndarray:
    return np.array([list(row) for row in ob.matrix_world], dtype=np.float64)


def uniform_scale(M) -> float:
    """Mean length of the matrix's axis columns (the brush assumes a near-uniform scale)."""
    M = np.asarray(M, dtype=np.float64)
    return float(np.mean(np.linalg.norm(M[:3, :3], axis=0))) or 1.0


def ray_cast_object(ob, origin, direction):
    """First hit of a world-space ray on the object's (evaluated) surface: (location, normal) or None."""
    mw = ob.matrix_world
    inv = mw.inverted()
    from mathutils import Vector

    o = inv @ Vector(origin)
    d = (inv.to_3x3() @ Vector(direction)).normalized()
    hit, loc, normal, _index = ob.ray_cast(o, d)
    if not hit:
        return None
    n = (mw.to_3x3().inverted().transposed() @ normal).normalized()
    return np.array(mw @ loc, dtype=np.float64), np.array(n, dtype=np.float64)


def circle_points(center, normal, radius, segments=64) -> np.ndarray:
    """(segments + 1, 3) points of a closed circle around ``center`` in the plane ⟂ ``normal``."""
    c = np.asarray(center, dtype=np.float64)
    n = np.asarray(normal, dtype=np.float64)
    n = n / (np.linalg.norm(n) or 1.0)
    a = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(n, a)
    u /= np.linalg.norm(u)
    v = np.cross(n, u)
    t = np.linspace(0.0, 2.0 * math.pi, segments + 1)
    return c + radius * (np.cos(t)[:, None] * u + np.sin(t)[:, None] * v)


# --------------------------------------------------------------------------
# the interactive state
# --------------------------------------------------------------------------

class BrushSession:
    """One interactive brush session on a mesh object: hover, press, drag, release, cancel.

    Points are world space; the :class:`shapeflow.Brush` works in object space
    (radius divided by the object's scale).  Every change of the shape (preview
    or applied dab) is written to the mesh at once with ``foreach_set``.
    """

    def __init__(self, brush, ob, *, lam, radius, method="DRAG_DOT", spacing=0.25):
        self.brush = brush
        self.ob = ob
        self.M = _matrix(ob)
        self.Minv = np.linalg.inv(self.M)
        self.scale = uniform_scale(self.M)
        self.lam = float(lam)
        self.method = method
        self.spacing = float(spacing)
        self.radius = float(radius)
        self.pressed = False
        self.invert = False
        self.hover = None            # (location, normal), world space
        self.dabs = []               # applied dab centres: (world location, inverted)
        self._last = None            # centre of the last Space dab (object space)

    # --- coordinates -------------------------------------------------------------
    def to_local(self, p) -> np.ndarray:
        p = np.asarray(p, dtype=np.float64)
        return self.Minv[:3, :3] @ p + self.Minv[:3, 3]

    def to_world(self, p) -> np.ndarray:
        p = np.asarray(p, dtype=np.float64)
        return self.M[:3, :3] @ p + self.M[:3, 3]

    @property
    def radius(self) -> float:
        """World-space radius."""
        return self._radius

    @radius.setter
    def radius(self, r) -> None:
        self._radius = float(r)
        self.brush.radius = self._radius / self.scale

    # --- events --------------------------------------------------------------------
    def set_hover(self, hit) -> None:
        self.hover = hit

    def press(self, point, invert=False) -> None:
        self.pressed = True
        self.invert = bool(invert)
        self._set_lam()
        c = self.to_local(point)
        if self.method == "DRAG_DOT":
            self.brush.preview(c)
            self._show()
        else:
            self._dab(c)
            self._last = c

    def drag(self, point, invert=None) -> None:
        if not self.pressed:
            return
        if invert is not None and bool(invert) != self.invert:
            self.invert = bool(invert)
            self._set_lam()
        c = self.to_local(point)
        if self.method == "DRAG_DOT":
            self.brush.preview(c)
            self._show()
            return
        step = max(self.spacing, 0.05) * self.brush.radius
        last = self._last if self._last is not None else c
        d = float(np.linalg.norm(c - last))
        moved = False
        while d >= step:
            last = last + (c - last) * (step / d)
            self._dab(last, show=False)
            moved = True
            d -= step
        self._last = last
        if moved:
            self._show()

    def release(self) -> None:
        if self.pressed and self.method == "DRAG_DOT" and self.brush.pending is not None:
            c = self.brush.pending.center
            self.brush.commit()
            self.dabs.append((self.to_world(c), self.invert))
        self.pressed = False
        self._last = None
        self._show()

    def cancel(self) -> None:
        """Drop any preview and put the mesh back as it was when the session started."""
        self.brush.discard()
        self.pressed = False
        bridge.write_object_positions(self.ob, self.brush.original.vertices)

    # --- internals -----------------------------------------------------------------
    def _set_lam(self) -> None:
        self.brush.lam = -self.lam if self.invert else self.lam

    def _dab(self, c, show=True) -> None:
        self.brush.dab(c)
        self.dabs.append((self.to_world(c), self.invert))
        if show:
            self._show()

    def _show(self) -> None:
        V = self.brush.preview_mesh.vertices if self.brush.pending is not None else self.brush.vertices
        bridge.write_object_positions(self.ob, V)


# --------------------------------------------------------------------------
# drawing
# --------------------------------------------------------------------------

def _draw_callback(session):
    if session.hover is None:
        return
    try:
        import gpu
        from gpu_extras.batch import batch_for_shader
    except ImportError:  # no GPU module (background)
        return
    center, normal = session.hover
    pts = circle_points(center, normal, session.radius).astype(np.float32)
    color = (1.0, 0.45, 0.2, 0.9) if session.invert else (1.0, 1.0, 1.0, 0.9)
    gpu.state.blend_set("ALPHA")
    try:
        shader = gpu.shader.from_builtin("POLYLINE_UNIFORM_COLOR")
        batch = batch_for_shader(shader, "LINE_STRIP", {"pos": pts.tolist()})
        shader.uniform_float("viewportSize", gpu.state.viewport_get()[2:])
        shader.uniform_float("lineWidth", 2.0)
        shader.uniform_float("color", color)
        batch.draw(shader)
        dot = gpu.shader.from_builtin("UNIFORM_COLOR")
        gpu.state.point_size_set(5.0)
        batch = batch_for_shader(dot, "POINTS", {"pos": [tuple(float(x) for x in center)]})
        dot.uniform_float("color", color)
        batch.draw(dot)
    finally:
        gpu.state.blend_set("NONE")


# --------------------------------------------------------------------------
# the operator
# --------------------------------------------------------------------------

def _window_region(area):
    for region in area.regions:
        if region.type == "WINDOW":
            return region
    return None


class OBJECT_OT_shapeflow_brush(SharpOptions, Operator):
    """Sculpt with the shape-enhancement brush: dabs of the implicit flow restricted to a sphere
    under the mouse (λ < 0 enhances, > 0 smooths)"""

    bl_idname = "object.shapeflow_brush"
    bl_label = "ShapeFlow Brush"
    bl_options = {"REGISTER", "UNDO", "BLOCKING"}

    lam: FloatProperty(name="λ", default=-50.0, soft_min=-500.0, soft_max=500.0, step=100, precision=2,
                       description="λ of each dab: < 0 enhances, > 0 smooths (Ctrl inverts while sculpting)")
    radius: FloatProperty(name="Radius", default=0.25, min=1e-6, soft_max=10.0, subtype="DISTANCE",
                          description="Brush radius in world units")
    falloff: EnumProperty(name="Falloff", items=FALLOFF_ITEMS, default="SMOOTH")
    stroke_method: EnumProperty(name="Stroke", items=METHOD_ITEMS, default="DRAG_DOT")
    spacing: FloatProperty(name="Spacing", default=0.25, min=0.0, soft_max=2.0,
                           description="Dab spacing along a stroke, × radius; 0: dab exactly at the stroke points")
    lam_border: FloatProperty(name="λ Border", default=0.0, soft_min=-500.0, soft_max=500.0, step=10,
                              description="λ_b for boundary vertices of open meshes; 0 keeps them fixed")
    normalized: BoolProperty(name="Normalized", default=True,
                             description="L = I − D⁻¹W (eq. 10); off: area-normalised (eq. 9)")
    vertex_group: StringProperty(name="Vertex Group", default="",
                                 description="Per-vertex factor in [0, 1] (0 = untouched)")
    invert_weights: BoolProperty(name="Invert", default=False, description="Use 1 − the vertex group's weights")
    stroke: CollectionProperty(type=SHAPEFLOW_PG_stroke_point, options={"SKIP_SAVE"},
                               description="World-space stroke points (scripted use, and the recorded stroke)")
    replay_exact: BoolProperty(options={"HIDDEN", "SKIP_SAVE"}, default=False)
    #: per recorded dab, "1" where it was applied with Ctrl held (−λ), else "0"
    stroke_invert: StringProperty(options={"HIDDEN", "SKIP_SAVE"}, default="")

    @classmethod
    def poll(cls, context):
        ob = context.active_object
        return ob is not None and ob.type == "MESH" and ob.mode == "OBJECT"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        col = layout.column()
        for p in ("lam", "radius", "falloff", "stroke_method", "spacing", "lam_border", "normalized"):
            col.prop(self, p)
        ob = context.active_object
        if ob is not None and ob.type == "MESH":
            row = col.row(align=True)
            row.prop_search(self, "vertex_group", ob, "vertex_groups")
            row.prop(self, "invert_weights", text="", icon="ARROW_LEFTRIGHT")
        sharp.draw_options(layout, self)

    # --- building the library brush ----------------------------------------------------
    def make_brush(self, context, ob):
        import shapeflow as sf

        V = bridge.read_object_positions(ob)
        sizes, corners = bridge.read_faces(ob.data)
        if sizes.size == 0:
            raise ValueError("the mesh has no faces")
        mesh = bridge.shapeflow_mesh(V, sizes, corners)
        w = None
        if self.vertex_group:
            w = np.clip(bridge.read_vertex_group(context, ob, self.vertex_group), 0.0, 1.0)
            if self.invert_weights:
                w = 1.0 - w
        scale = uniform_scale(_matrix(ob))
        return sf.Brush(mesh, lam=self.lam, radius=self.radius / scale,
                        falloff="smooth" if self.falloff == "SMOOTH" else None,
                        lam_border=self.lam_border, weights=w, normalized=self.normalized,
                        **self.sharp_options(ob.data, mesh))

    # --- scripted / replay ----------------------------------------------------------------
    def execute(self, context):
        ob = context.active_object
        if not len(self.stroke):
            self.report({"ERROR"}, "ShapeFlow brush: give stroke points (stroke=[{'location': (x, y, z)}, ...]) "
                                   "or run it interactively")
            return {"CANCELLED"}
        from shapeflow.errors import ShapeflowError

        try:
            brush = self.make_brush(context, ob)
            session = BrushSession(brush, ob, lam=self.lam, radius=self.radius)
            P = np.array([tuple(p.location) for p in self.stroke], dtype=np.float64)
            local = np.array([session.to_local(p) for p in P])
            if self.replay_exact or self.spacing == 0.0:
                flags = self.stroke_invert.ljust(len(local), "0")
                for c, flag in zip(local, flags):
                    brush.lam = -self.lam if flag == "1" else self.lam
                    brush.dab(c)
            else:
                brush.stroke(local, spacing=self.spacing)
        except (ShapeflowError, KeyError, ValueError) as exc:
            self.report({"ERROR"}, f"ShapeFlow brush: {exc}")
            return {"CANCELLED"}
        bridge.write_object_positions(ob, brush.vertices)
        self.report({"INFO"}, f"ShapeFlow brush: {len(P)} stroke points")
        return {"FINISHED"}

    # --- interactive ------------------------------------------------------------------------
    def invoke(self, context, event):
        if len(self.stroke):
            return self.execute(context)
        area = context.area
        if area is None or area.type != "VIEW_3D" or _window_region(area) is None:
            self.report({"WARNING"}, "ShapeFlow brush: run it from a 3D Viewport")
            return {"CANCELLED"}
        ob = context.active_object
        try:
            brush = self.make_brush(context, ob)
        except Exception as exc:  # noqa: BLE001 - reported to the user
            self.report({"ERROR"}, f"ShapeFlow brush: {exc}")
            return {"CANCELLED"}
        self._session = BrushSession(brush, ob, lam=self.lam, radius=self.radius,
                                     method=self.stroke_method, spacing=self.spacing)
        self._area = area
        self._handle = bpy.types.SpaceView3D.draw_handler_add(_draw_callback, (self._session,), "WINDOW",
                                                              "POST_VIEW")
        area.header_text_set(HELP)
        context.window.cursor_modal_set("CROSSHAIR")
        context.window_manager.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def _hit(self, context, event):
        from bpy_extras import view3d_utils

        region = _window_region(self._area)
        rv3d = self._area.spaces.active.region_3d
        x, y = event.mouse_x - region.x, event.mouse_y - region.y
        if not (0 <= x < region.width and 0 <= y < region.height):
            return None, False
        origin = view3d_utils.region_2d_to_origin_3d(region, rv3d, (x, y))
        direction = view3d_utils.region_2d_to_vector_3d(region, rv3d, (x, y))
        return ray_cast_object(context.active_object, origin, direction), True

    def _end(self, context):
        bpy.types.SpaceView3D.draw_handler_remove(self._handle, "WINDOW")
        self._area.header_text_set(None)
        context.window.cursor_modal_restore()
        self._area.tag_redraw()

    def modal(self, context, event):
        s = self._session
        self._area.tag_redraw()
        if event.type in {"ESC", "RIGHTMOUSE"} and event.value == "PRESS":
            s.cancel()
            self._end(context)
            return {"CANCELLED"}
        if event.type in {"RET", "NUMPAD_ENTER", "SPACE"} and event.value == "PRESS":
            s.release()
            self._end(context)
            self.stroke.clear()
            for p, _inv in s.dabs:
                self.stroke.add().location = tuple(p)
            self.stroke_invert = "".join("1" if inv else "0" for _p, inv in s.dabs)
            self.replay_exact = True
            self.radius = s.radius
            return {"FINISHED"}
        if event.type in {"LEFT_BRACKET", "RIGHT_BRACKET"} and event.value == "PRESS":
            s.radius = s.radius * (1.0 / 1.1 if event.type == "LEFT_BRACKET" else 1.1)
            return {"RUNNING_MODAL"}
        if event.type == "MOUSEMOVE":
            hit, inside = self._hit(context, event)
            if not inside and not s.pressed:
                s.set_hover(None)
                return {"PASS_THROUGH"}
            s.set_hover(hit)
            if s.pressed and hit is not None:
                s.drag(hit[0], invert=event.ctrl)
            return {"RUNNING_MODAL"}
        if event.type == "LEFTMOUSE":
            if event.value == "PRESS":
                hit, inside = self._hit(context, event)
                if not inside:
                    return {"PASS_THROUGH"}
                if hit is not None:
                    s.set_hover(hit)
                    s.press(hit[0], invert=event.ctrl)
                return {"RUNNING_MODAL"}
            if event.value == "RELEASE":
                s.release()
                return {"RUNNING_MODAL"}
        if event.type in {"MIDDLEMOUSE", "WHEELUPMOUSE", "WHEELDOWNMOUSE", "TRACKPADPAN", "TRACKPADZOOM"} \
                or event.type.startswith("NDOF") or event.type.startswith("NUMPAD"):
            return {"PASS_THROUGH"}
        return {"RUNNING_MODAL"}


CLASSES = (SHAPEFLOW_PG_stroke_point, OBJECT_OT_shapeflow_brush)
