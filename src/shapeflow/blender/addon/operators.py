"""Operators: Enhance / Smooth Shape, Shape Family, Subdivide and Enhance.

Every operator is registered with ``{'REGISTER', 'UNDO'}``: one undo step per
run, and the *Adjust Last Operation* panel re-runs it as a property changes
(the mesh topology and, for the same positions and weights, the operator at
those positions are cached between re-runs, see :mod:`.bridge`).

Property names follow the keywords of :func:`shapeflow.flow`: ``lam``,
``lam_border``, ``iterations``, ``normalized``, ``preserve_volume``,
``axes``, ``invert_weights``, ``update``; ``vertex_group`` names the group
that supplies ``weights``, and ``scheme`` picks ``compat``: ``'PAPER'`` (the
paper's TQLBO flow, ``compat=None``) or ``'BLENDER'`` (``compat="blender"``,
the exact result of Blender's own Laplacian Smooth modifier with
``lambda_factor = lam``).  ``keep_sharp`` with ``sharp_marked`` /
``sharp_by_angle`` + ``sharp_angle`` give ``sharp_edges`` / ``feature_angle``
(:mod:`.sharp`).  Subdivide and Enhance subdivides with the object's edge
creases (``use_creases``, as Blender's Subdivision Surface) and writes the
sub-edges' creases and sharp flags onto the new mesh.
"""

import time

import bpy
import numpy as np
from bpy.props import (
    BoolProperty,
    BoolVectorProperty,
    EnumProperty,
    FloatProperty,
    FloatVectorProperty,
    IntProperty,
    StringProperty,
)
from bpy.types import Operator

from . import bridge, sharp
from .sharp import SharpOptions, face_edges

SCHEME_ITEMS = [
    ("PAPER", "Paper", "The paper's flow with the hybrid quad/triangle Laplacian (TQLBO weights)"),
    ("BLENDER", "Blender", "Blender-compatible: exactly what Blender's Laplacian Smooth modifier computes "
                           "with Lambda Factor = λ"),
]
UPDATE_ITEMS = [
    ("FIXED", "Fixed", "Keep the operator of the first iteration (what Blender's modifier does)"),
    ("RECOMPUTE", "Recompute", "Rebuild the operator from the current shape at every iteration (a true flow)"),
]

#: seconds spent in the last Enhance / Smooth run, by stage: read, compute, write, total
LAST_TIMING: dict = {}


def _sf():
    import shapeflow

    return shapeflow


def _errors():
    from shapeflow.errors import ShapeflowError

    return (ShapeflowError, KeyError)


# --------------------------------------------------------------------------
# shared properties
# --------------------------------------------------------------------------

class FlowOptions(SharpOptions):
    """The flow() options shared by every operator (λ itself is per operator)."""

    def execute(self, context):
        """Run ``self._run``; a library error becomes a report, not a traceback."""
        try:
            return self._run(context)
        except _errors() as exc:
            self.report({"ERROR"}, f"ShapeFlow: {exc}")
            return {"CANCELLED"}

    lam_border: FloatProperty(
        name="λ Border", default=0.0, soft_min=-500.0, soft_max=500.0, step=10, precision=3,
        description="λ_b for the boundary vertices of open meshes (own sign); 0 keeps them fixed")
    iterations: IntProperty(
        name="Iterations", default=1, min=0, soft_max=20, max=1000,
        description="Number of implicit steps")
    normalized: BoolProperty(
        name="Normalized", default=True,
        description="L = I − D⁻¹W (eq. 10, independent of the model's size); off: area-normalised (eq. 9)")
    preserve_volume: BoolProperty(
        name="Preserve Volume", default=False,
        description="Rescale about the centroid after each step to keep the enclosed volume")
    axes: BoolVectorProperty(
        name="Axes", size=3, default=(True, True, True), subtype="XYZ",
        description="Coordinates that may change")
    vertex_group: StringProperty(
        name="Vertex Group", default="",
        description="Per-vertex factor in [0, 1] (0 = untouched); empty: every vertex 1")
    invert_weights: BoolProperty(
        name="Invert", default=False, description="Use 1 − the vertex group's weights")
    scheme: EnumProperty(name="Scheme", items=SCHEME_ITEMS, default="PAPER")
    update: EnumProperty(name="Operator", items=UPDATE_ITEMS, default="FIXED",
                         description="Fixed or recomputed operator over the iterations (Paper scheme)")

    def solver_options(self) -> dict:
        return dict(lam_border=self.lam_border, normalized=self.normalized,
                    compat="blender" if self.scheme == "BLENDER" else None)

    def run_options(self) -> dict:
        return dict(iterations=int(self.iterations), preserve_volume=self.preserve_volume,
                    axes=tuple(bool(a) for a in self.axes),
                    update="fixed" if self.scheme == "BLENDER" else self.update.lower())

    def weights(self, context, ob, mask=None):
        """Weights from the vertex group (inverted if asked) times an optional selection mask."""
        w = None
        if self.vertex_group:
            w = np.clip(bridge.read_vertex_group(context, ob, self.vertex_group), 0.0, 1.0)
            if self.invert_weights:
                w = 1.0 - w
        if mask is not None:
            w = mask.astype(np.float64) if w is None else w * mask
        return w

    def draw_flow_options(self, layout, ob, *, lam_props=("lam",)):
        layout.use_property_split = True
        layout.use_property_decorate = False
        col = layout.column()
        col.prop(self, "scheme", expand=True)
        for p in lam_props:
            col.prop(self, p)
        col.prop(self, "lam_border")
        col.prop(self, "iterations")
        col.prop(self, "normalized")
        col.prop(self, "preserve_volume")
        row = col.row(heading="Axes", align=True)
        row.prop(self, "axes", toggle=True, text="")
        if ob is not None and ob.type == "MESH":
            row = col.row(align=True)
            row.prop_search(self, "vertex_group", ob, "vertex_groups")
            row.prop(self, "invert_weights", text="", icon="ARROW_LEFTRIGHT")
        sub = col.column()
        sub.enabled = self.scheme == "PAPER"
        sub.prop(self, "update")
        sharp.draw_options(layout, self)


def _active_mesh(context):
    ob = context.active_object
    return ob if ob is not None and ob.type == "MESH" else None


def _mesh_in_object_mode(context) -> bool:
    ob = _active_mesh(context)
    return ob is not None and ob.mode == "OBJECT"


def _read(ob):
    V = bridge.read_object_positions(ob)
    sizes, corners = bridge.read_faces(ob.data)
    return V, sizes, corners


# --------------------------------------------------------------------------
# Enhance / Smooth Shape
# --------------------------------------------------------------------------

class OBJECT_OT_shapeflow_flow(FlowOptions, Operator):
    """Smooth (λ > 0) or enhance (λ < 0) the shape of the active mesh with the implicit curvature flow.
    In Edit Mode only the selected vertices move"""

    bl_idname = "object.shapeflow_flow"
    bl_label = "Enhance / Smooth Shape"
    bl_options = {"REGISTER", "UNDO"}

    lam: FloatProperty(
        name="λ", default=-10.0, soft_min=-500.0, soft_max=500.0, step=100, precision=3,
        description="Flow factor: < 0 enhances the shape, > 0 smooths it (the paper's figures use +90 … −400)")

    @classmethod
    def poll(cls, context):
        ob = _active_mesh(context)
        return ob is not None and ob.mode in {"OBJECT", "EDIT"}

    def draw(self, context):
        self.draw_flow_options(self.layout, _active_mesh(context))

    def execute(self, context):
        ob = _active_mesh(context)
        edit = ob.mode == "EDIT"
        if edit:
            bpy.ops.object.mode_set(mode="OBJECT")  # the edit BMesh is written to the mesh
        try:
            return self._run(context, ob, edit)
        except _errors() as exc:
            self.report({"ERROR"}, f"ShapeFlow: {exc}")
            return {"CANCELLED"}
        finally:
            if edit:
                bpy.ops.object.mode_set(mode="EDIT")

    def _run(self, context, ob, edit):
        t0 = time.perf_counter()
        me = ob.data
        V, sizes, corners = _read(ob)
        if sizes.size == 0:
            self.report({"WARNING"}, "ShapeFlow: the mesh has no faces")
            return {"CANCELLED"}
        mask = None
        if edit:
            mask = bridge.read_selection(me)
            if not mask.any():
                self.report({"WARNING"}, "ShapeFlow: no vertex selected")
                return {"CANCELLED"}
        w = self.weights(context, ob, mask)
        t1 = time.perf_counter()
        mesh = bridge.shapeflow_mesh(V, sizes, corners)
        solver = bridge.flow_solver(mesh, w, **self.solver_options(), **self.sharp_options(me, mesh))
        out = solver.run(self.lam, **self.run_options())
        X = out.vertices
        if mask is not None:  # volume rescaling is global: keep the unselected part exactly in place
            X = np.where(mask[:, None], X, V)
        t2 = time.perf_counter()
        bridge.write_object_positions(ob, X)
        t3 = time.perf_counter()
        LAST_TIMING.clear()
        LAST_TIMING.update(read=t1 - t0, compute=t2 - t1, write=t3 - t2, total=t3 - t0)
        self.report({"INFO"}, f"ShapeFlow: {out.report.summary()}")
        return {"FINISHED"}


# --------------------------------------------------------------------------
# Shape Family
# --------------------------------------------------------------------------

def _ramp(c0, c1, t):
    c0 = np.asarray(c0, dtype=np.float64)
    c1 = np.asarray(c1, dtype=np.float64)
    return tuple(float(x) for x in (1.0 - t) * c0 + t * c1)


def _member_material(name, rgba):
    mat = bpy.data.materials.new(name)
    mat.diffuse_color = rgba
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    tree = mat.node_tree
    if tree is not None:
        for node in tree.nodes:
            if node.type == "BSDF_PRINCIPLED":
                node.inputs["Base Color"].default_value = rgba
    return mat


class OBJECT_OT_shapeflow_family(FlowOptions, Operator):
    """Create a family of shapes for a range of λ (figure 1 of the paper), side by side, coloured along a ramp"""

    bl_idname = "object.shapeflow_family"
    bl_label = "Shape Family"
    bl_options = {"REGISTER", "UNDO"}

    lam_start: FloatProperty(name="λ Start", default=0.0, soft_min=-500.0, soft_max=500.0, step=100,
                             description="λ of the first member")
    lam_end: FloatProperty(name="λ End", default=-240.0, soft_min=-500.0, soft_max=500.0, step=100,
                           description="λ of the last member")
    count: IntProperty(name="Count", default=8, min=1, soft_max=24, max=256, description="Number of members")
    gap: FloatProperty(name="Gap", default=0.15, min=0.0, soft_max=2.0,
                       description="Space between members, as a fraction of the object's width")
    color_start: FloatVectorProperty(name="Color Start", subtype="COLOR", size=4, min=0.0, max=1.0,
                                     default=(0.12, 0.36, 0.85, 1.0), description="Colour of the first member")
    color_end: FloatVectorProperty(name="Color End", subtype="COLOR", size=4, min=0.0, max=1.0,
                                   default=(0.95, 0.42, 0.10, 1.0), description="Colour of the last member")
    use_materials: BoolProperty(name="Materials", default=True,
                                description="Give each member a material of its colour (else only the object colour)")

    @classmethod
    def poll(cls, context):
        return _mesh_in_object_mode(context)

    def draw(self, context):
        layout = self.layout
        self.draw_flow_options(layout, _active_mesh(context), lam_props=("lam_start", "lam_end", "count"))
        col = layout.column()
        col.prop(self, "gap")
        col.prop(self, "color_start")
        col.prop(self, "color_end")
        col.prop(self, "use_materials")

    def _run(self, context):
        sf = _sf()
        ob = _active_mesh(context)
        V, sizes, corners = _read(ob)
        if sizes.size == 0:
            self.report({"WARNING"}, "ShapeFlow: the mesh has no faces")
            return {"CANCELLED"}
        w = self.weights(context, ob)
        mesh = bridge.shapeflow_mesh(V, sizes, corners)
        lams = np.linspace(self.lam_start, self.lam_end, self.count)
        opts = self.run_options()
        shapes, report = sf.family(mesh, lams, weights=w, return_report=True, **self.solver_options(),
                                   **self.sharp_options(ob.data, mesh), **opts)

        # lay the members out along world X, right of the object's world bounding box
        mw = ob.matrix_world
        corners_w = np.array([tuple(mw @ _vec(c)) for c in ob.bound_box])
        width = float(corners_w[:, 0].max() - corners_w[:, 0].min()) or 1.0
        step = width * (1.0 + self.gap)
        coll = bpy.data.collections.new(f"{ob.name} family")
        (ob.users_collection[0] if ob.users_collection else context.scene.collection).children.link(coll)
        members = []
        for i, (lam, X) in enumerate(zip(lams, shapes)):
            t = i / (len(lams) - 1) if len(lams) > 1 else 0.0
            rgba = _ramp(self.color_start, self.color_end, t)
            label = f"{ob.name} λ={lam:g}"
            me = ob.data.copy()
            me.name = label
            bridge.write_positions(me, X)
            if self.use_materials:
                me.materials.clear()
                me.materials.append(_member_material(label, rgba))
                me.polygons.foreach_set("material_index", np.zeros(len(me.polygons), dtype=np.int32))
            member = bpy.data.objects.new(label, me)
            if me.shape_keys is not None:  # the member is the flowed shape itself
                member.shape_key_clear()
                bridge.write_positions(me, X)
            member.matrix_world = mw.copy()
            member.location = (mw.translation.x + (i + 1) * step, mw.translation.y, mw.translation.z)
            member.color = rgba
            member["shapeflow_lam"] = float(lam)
            coll.objects.link(member)
            members.append(member)
        self.report({"INFO"}, f"ShapeFlow: {report.summary()}")
        return {"FINISHED"}


def _vec(c):
    from mathutils import Vector

    return Vector(tuple(c))


# --------------------------------------------------------------------------
# Subdivide and Enhance
# --------------------------------------------------------------------------

BOUNDARY_ITEMS = [
    ("SMOOTH", "All", "Smooth boundaries, corners included (Blender's Subdivision Surface: All)"),
    ("KEEP_CORNERS", "Keep Corners", "Boundary vertices with two edges stay put (Blender's Keep Corners)"),
]
WEIGHTS_RULE_ITEMS = [
    ("SMOOTH", "Smooth", "Vertex-group weights follow the Catmull–Clark stencil: smoother influence zones"),
    ("LINEAR", "Linear", "Weights are interpolated linearly, as Blender's Subdivision Surface modifier does"),
]


def corner_data_subdivided(sizes, data, levels):
    """Face-corner data (UVs) after ``levels`` subdivision steps, interpolated linearly.

    Face ``f`` of size ``s`` becomes ``s`` quads ``[c, edge(c→next), centre,
    edge(prev→c)]`` corner after corner (the face order of
    :func:`shapeflow.subdivide`); their corner values are the corner's own, the
    two edge midpoints and the face mean.
    """
    sizes = np.asarray(sizes, dtype=np.int64)
    data = np.asarray(data, dtype=np.float64)
    for _ in range(levels):
        m, nl = sizes.size, data.shape[0]
        start = np.zeros(m, dtype=np.int64)
        np.cumsum(sizes[:-1], out=start[1:])
        face = np.repeat(np.arange(m), sizes)
        k = np.arange(nl)
        pos = k - start[face]
        nxt = np.where(pos + 1 == sizes[face], start[face], k + 1)
        prv = np.where(pos == 0, start[face] + sizes[face] - 1, k - 1)
        centre = np.add.reduceat(data, start, axis=0) / sizes[:, None]
        data = np.stack([data, 0.5 * (data + data[nxt]), centre[face], 0.5 * (data[prv] + data)], axis=1)
        data = data.reshape(-1, data.shape[-1])
        sizes = np.full(nl, 4, dtype=np.int64)
    return data


def face_data_subdivided(sizes, values, levels):
    """Per-face values after ``levels`` steps (each face's quads inherit its value)."""
    sizes = np.asarray(sizes, dtype=np.int64)
    for _ in range(levels):
        values = np.repeat(values, sizes)
        sizes = np.full(values.size, 4, dtype=np.int64)
    return values


class OBJECT_OT_shapeflow_subdivide_enhance(FlowOptions, Operator):
    """Catmull–Clark subdivision carrying the vertex groups to the new mesh, then the flow
    weighted by the chosen vertex group (figure 5 of the paper)"""

    bl_idname = "object.shapeflow_subdivide_enhance"
    bl_label = "Subdivide and Enhance"
    bl_options = {"REGISTER", "UNDO"}

    levels: IntProperty(name="Levels", default=1, min=0, soft_max=4, max=6, description="Subdivision steps")
    boundary: EnumProperty(name="Boundary", items=BOUNDARY_ITEMS, default="SMOOTH")
    weights_rule: EnumProperty(name="Weights", items=WEIGHTS_RULE_ITEMS, default="SMOOTH",
                               description="How vertex-group weights are carried to the new vertices")
    use_creases: BoolProperty(
        name="Use Creases", default=True,
        description="Subdivide with the object's edge creases, as the Subdivision Surface modifier's Use Creases; "
                    "the new mesh carries the sub-edges' creases, so subdividing it again continues the surface")
    lam: FloatProperty(
        name="λ", default=-60.0, soft_min=-500.0, soft_max=500.0, step=100, precision=3,
        description="Flow factor on the subdivided mesh: < 0 enhances, > 0 smooths, 0 subdivides only")

    @classmethod
    def poll(cls, context):
        return _mesh_in_object_mode(context)

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        col = layout.column()
        col.prop(self, "levels")
        col.prop(self, "boundary")
        col.prop(self, "weights_rule")
        col.prop(self, "use_creases")
        self.draw_flow_options(layout, _active_mesh(context))

    def _run(self, context):
        sf = _sf()
        ob = _active_mesh(context)
        old = ob.data
        V, sizes, corners = _read(ob)
        if sizes.size == 0:
            self.report({"WARNING"}, "ShapeFlow: the mesh has no faces")
            return {"CANCELLED"}
        levels = int(self.levels)
        boundary = self.boundary.lower().replace("_", "-")
        rule = self.weights_rule.lower()
        names = [g.name for g in ob.vertex_groups]
        active_group = ob.vertex_groups.active.name if ob.vertex_groups.active else None
        if self.vertex_group and self.vertex_group not in names:
            raise KeyError(f"object '{ob.name}' has no vertex group {self.vertex_group!r}")
        groups = dict(zip(names, bridge.read_vertex_groups(context, ob, names)))

        coarse = sf.Mesh.from_csr(V, sizes, corners)
        edges = bridge.read_edges(old)
        creases = None
        if self.use_creases:
            pairs, values = face_edges(coarse, edges, bridge.read_creases(old))
            if (values > 0).any():
                creases = (pairs[values > 0], values[values > 0])
        sharp = face_edges(coarse, edges[bridge.read_sharp_flags(old)])
        if self.vertex_group:
            coarse = coarse.with_weights(np.clip(groups[self.vertex_group], 0.0, 1.0))
        fine = sf.subdivide(coarse, levels, boundary=boundary, weights_rule=rule, creases=creases)
        fine_groups = {}
        others = [nm for nm in names if nm != self.vertex_group]
        if others and levels > 0:
            scheme = "simple" if rule == "linear" else "catmull-clark"
            S, _ = sf.subdivision_matrix(coarse, levels=levels, boundary=boundary, scheme=scheme,
                                         creases=creases if scheme == "catmull-clark" else None)
            for nm in others:
                fine_groups[nm] = np.clip(S @ groups[nm], 0.0, 1.0)
        elif others:
            fine_groups.update({nm: groups[nm] for nm in others})
        if self.vertex_group:
            fine_groups[self.vertex_group] = np.asarray(fine.weights)

        # the new mesh, with the sub-edges' creases and sharp flags, is what Keep Sharp Edges reads
        me = bridge.new_mesh(old.name, fine.vertices, fine.face_sizes, fine.face_indices)
        self._carry(old, me, sizes, levels)
        if creases is not None:
            bridge.write_edge_values(me, "crease_edge", "FLOAT", *fine.creases)
        if len(sharp):
            halves = sf.subdivide(sf.Mesh.from_csr(V, sizes, corners), levels, boundary=boundary,
                                  creases=(sharp, 1.0)).creases[0]   # an infinite crease's halves stay
            bridge.write_edge_values(me, "sharp_edge", "BOOLEAN", halves, True)
        X = fine.vertices
        summary = "subdivided only (λ = 0)"
        if self.lam != 0.0 or self.lam_border != 0.0:
            w = None
            if self.vertex_group:
                w = fine_groups[self.vertex_group]
                if self.invert_weights:
                    w = 1.0 - w
            out = sf.flow(fine, self.lam, weights=w, **self.solver_options(), **self.run_options(),
                          **self.sharp_options(me, fine))
            X = out.vertices
            bridge.write_positions(me, X)
            summary = out.report.summary()

        old_name = old.name
        ob.data = me
        for nm in names:  # vertex group names live on the mesh: recreate them in the old order
            bridge.write_vertex_group(ob, nm, fine_groups[nm])
        if active_group is not None:
            ob.vertex_groups.active_index = ob.vertex_groups[active_group].index
        if old.users == 0:
            bpy.data.meshes.remove(old)
            me.name = old_name
        self.report({"INFO"}, f"ShapeFlow: {len(V)} → {len(X)} vertices; {summary}")
        return {"FINISHED"}

    @staticmethod
    def _carry(old, me, sizes, levels):
        """Materials, per-face material index and smooth flag, and UV maps (linear)."""
        for mat in old.materials:
            me.materials.append(mat)
        m = len(old.polygons)
        if m:
            mi = np.empty(m, dtype=np.int32)
            old.polygons.foreach_get("material_index", mi)
            me.polygons.foreach_set("material_index", face_data_subdivided(sizes, mi, levels).astype(np.int32))
            sm = np.empty(m, dtype=bool)
            old.polygons.foreach_get("use_smooth", sm)
            me.polygons.foreach_set("use_smooth", face_data_subdivided(sizes, sm, levels).astype(bool))
        if len(old.uv_layers):
            starts = np.empty(m, dtype=np.int32)
            old.polygons.foreach_get("loop_start", starts)
            order = bridge.corner_order(starts, sizes)
            active = old.uv_layers.active.name if old.uv_layers.active else None
            for layer in old.uv_layers:
                uv = np.empty(2 * len(old.loops), dtype=np.float32)
                layer.data.foreach_get("uv", uv)
                uv = corner_data_subdivided(sizes, uv.reshape(-1, 2)[order], levels)
                new = me.uv_layers.new(name=layer.name)
                new.data.foreach_set("uv", np.ascontiguousarray(uv.astype(np.float32).ravel()))
            if active is not None:
                me.uv_layers.active = me.uv_layers[active]


CLASSES = (OBJECT_OT_shapeflow_flow, OBJECT_OT_shapeflow_family, OBJECT_OT_shapeflow_subdivide_enhance)
