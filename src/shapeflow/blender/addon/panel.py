"""The sidebar panel (View3D ▸ N ▸ ShapeFlow) and menu entries."""

import bpy
from bpy.types import Menu, Panel


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
        col = layout.column(align=True)
        col.operator("object.shapeflow_flow", icon="MOD_SMOOTH")
        if ob.mode == "EDIT":
            col.label(text="Only selected vertices move", icon="INFO")
            return
        col.operator("object.shapeflow_family", icon="MOD_ARRAY")
        col.operator("object.shapeflow_subdivide_enhance", icon="MOD_SUBSURF")
        col.separator()
        col.operator("object.shapeflow_brush", icon="SCULPTMODE_HLT").stroke_method = "DRAG_DOT"
        layout.label(text="Settings: Adjust Last Operation (F9)", icon="PREFERENCES")
        layout.label(text=f"{len(ob.data.vertices):,} vertices, {len(ob.data.polygons):,} faces")


class VIEW3D_MT_shapeflow(Menu):
    bl_label = "ShapeFlow"
    bl_idname = "VIEW3D_MT_shapeflow"

    def draw(self, context):
        layout = self.layout
        layout.operator("object.shapeflow_flow", icon="MOD_SMOOTH")
        layout.operator("object.shapeflow_family", icon="MOD_ARRAY")
        layout.operator("object.shapeflow_subdivide_enhance", icon="MOD_SUBSURF")
        layout.operator_context = "INVOKE_REGION_WIN"
        layout.operator("object.shapeflow_brush", icon="SCULPTMODE_HLT")


def _object_menu(self, context):
    self.layout.separator()
    self.layout.menu(VIEW3D_MT_shapeflow.bl_idname)


def _edit_mesh_menu(self, context):
    self.layout.separator()
    self.layout.operator("object.shapeflow_flow", icon="MOD_SMOOTH")


MENUS = ((bpy.types.VIEW3D_MT_object, _object_menu), (bpy.types.VIEW3D_MT_edit_mesh_vertices, _edit_mesh_menu))
CLASSES = (VIEW3D_MT_shapeflow, VIEW3D_PT_shapeflow)
