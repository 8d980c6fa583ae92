"""The sidebar panel (View3D ▸ N ▸ ShapeFlow) and menu entries."""

import bpy
from bpy.types import Menu, Panel

from .sharp import apply_object_setting, draw_object_setting


class VIEW3D_PT_shapeflow(Panel):
    """ShapeFlow: enhance, smooth, shape family, subdivide-and-enhance, brush"""

    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "ShapeFlow"
    bl_label = "ShapeFlow"

    def draw(self, context):
        layout = self.layout
        ob = context.active_object
        if ob is None or ob.type != "MESH":
            layout.label(text="Select a mesh object", icon="INFO")
            return
        draw_object_setting(layout, ob)
        layout.separator()
        col = layout.column(align=True)
        apply_object_setting(col.operator("object.shapeflow_flow", icon="MOD_SMOOTH"), ob)
        if ob.mode == "EDIT":
            col.label(text="Only selected vertices move", icon="INFO")
            return
        apply_object_setting(col.operator("object.shapeflow_family", icon="MOD_ARRAY"), ob)
        apply_object_setting(col.operator("object.shapeflow_subdivide_enhance", icon="MOD_SUBSURF"), ob)
        col.separator()
        brush = col.operator("object.shapeflow_brush", icon="SCULPTMODE_HLT")
        brush.stroke_method = "DRAG_DOT"
        apply_object_setting(brush, ob)
        layout.label(text="Settings: Adjust Last Operation (F9)", icon="PREFERENCES")
        layout.label(text=f"{len(ob.data.vertices):,} vertices, {len(ob.data.polygons):,} faces")


class VIEW3D_MT_shapeflow(Menu):
    bl_label = "ShapeFlow"
    bl_idname = "VIEW3D_MT_shapeflow"

    def draw(self, context):
        layout = self.layout
        ob = context.active_object
        apply_object_setting(layout.operator("object.shapeflow_flow", icon="MOD_SMOOTH"), ob)
        apply_object_setting(layout.operator("object.shapeflow_family", icon="MOD_ARRAY"), ob)
        apply_object_setting(layout.operator("object.shapeflow_subdivide_enhance", icon="MOD_SUBSURF"), ob)
        layout.operator_context = "INVOKE_REGION_WIN"
        apply_object_setting(layout.operator("object.shapeflow_brush", icon="SCULPTMODE_HLT"), ob)


def _object_menu(self, context):
    self.layout.separator()
    self.layout.menu(VIEW3D_MT_shapeflow.bl_idname)


def _edit_mesh_menu(self, context):
    self.layout.separator()
    apply_object_setting(self.layout.operator("object.shapeflow_flow", icon="MOD_SMOOTH"), context.active_object)


MENUS = ((bpy.types.VIEW3D_MT_object, _object_menu), (bpy.types.VIEW3D_MT_edit_mesh_vertices, _edit_mesh_menu))
CLASSES = (VIEW3D_MT_shapeflow, VIEW3D_PT_shapeflow)
