"""The 3D Viewport sidebar tab "Anatomesh": Import, Labels, Smooth, Look and Export panels."""

from bpy.types import Panel, UIList

from .operators import active_scan


class ANATOMESH_UL_labels(UIList):
    """Label rows: include tick, colour, name, value (the filter box filters by name)."""

    def draw_item(self, context, layout, data, item, icon, active_data, active_propname, index=0):
        row = layout.row(align=True)
        row.prop(item, "include", text="")
        sub = row.row(align=True)
        sub.scale_x = 0.35
        sub.prop(item, "color", text="")
        row.label(text=item.name)
        val = row.row()
        val.alignment = "RIGHT"
        val.label(text=f"{item.value:g}" if isinstance(item.value, float) else str(item.value))


class _Base:
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Anatomesh"


class ANATOMESH_PT_import(_Base, Panel):
    bl_label = "Import"
    bl_idname = "ANATOMESH_PT_import"

    def draw(self, context):
        s = context.scene.anatomesh
        col = self.layout.column(align=True)
        col.prop(s, "filepath", text="")
        col.prop(s, "label_table", text="Labels")
        col.prop(s, "series")
        col.prop(s, "space")
        row = self.layout.row(align=True)
        op = row.operator("anatomesh.import_scan", text="Read", icon="FILE_FOLDER")
        op.filepath, op.series, op.label_table, op.space = s.filepath, s.series, s.label_table, s.space
        op.extract = False
        if s.info:
            self.layout.label(text=s.info, icon="INFO")


class ANATOMESH_PT_labels(_Base, Panel):
    bl_label = "Labels"
    bl_idname = "ANATOMESH_PT_labels"

    def draw(self, context):
        s = context.scene.anatomesh
        layout = self.layout
        if s.kind == "NONE":
            layout.label(text="Read a scan first")
            return
        row = layout.row()
        if s.kind == "LABELS":
            row.template_list("ANATOMESH_UL_labels", "labels", s, "labels", s, "label_index", rows=8)
        else:
            row.template_list("ANATOMESH_UL_labels", "levels", s, "levels", s, "level_index", rows=5)
            col = row.column(align=True)
            col.operator("anatomesh.level_add", text="", icon="ADD")
            col.operator("anatomesh.level_remove", text="", icon="REMOVE")
            if 0 <= s.level_index < len(s.levels):
                layout.prop(s.levels[s.level_index], "value")
        row = layout.row(align=True)
        for action, text in (("ALL", "All"), ("NONE", "None"), ("INVERT", "Invert")):
            row.operator("anatomesh.labels_select", text=text).action = action
        layout.operator("anatomesh.extract", text="Extract Surfaces", icon="MESH_ICOSPHERE")


class ANATOMESH_PT_smooth(_Base, Panel):
    bl_label = "Smooth"
    bl_idname = "ANATOMESH_PT_smooth"

    def draw(self, context):
        layout = self.layout
        coll = active_scan(context)
        if coll is None:
            s = context.scene.anatomesh
            layout.label(text="Defaults for the next extraction:")
            col = layout.column(align=True)
            for p in ("smooth_method", "smooth_iterations", "smooth_strength", "smooth_max_deviation",
                      "keep_in_cell"):
                col.prop(s, p)
            return
        st = coll.anatomesh
        layout.label(text=coll.name, icon="OUTLINER_COLLECTION")
        col = layout.column(align=True)
        col.prop(st, "smooth_method")
        col.prop(st, "smooth_iterations")
        col.prop(st, "smooth_strength")
        col.prop(st, "smooth_max_deviation")
        col.prop(st, "keep_in_cell")
        row = layout.row(align=True)
        row.prop(st, "live")
        op = row.operator("anatomesh.smooth", text="Apply", icon="CHECKMARK")
        op.collection, op.method, op.iterations = coll.name, st.smooth_method, st.smooth_iterations
        op.strength, op.max_deviation, op.apply = st.smooth_strength, st.smooth_max_deviation, True
        op.keep_in_cell = st.keep_in_cell
        if not st.live:
            op = layout.operator("anatomesh.smooth", text="Smooth Now")
            op.collection, op.method, op.iterations = coll.name, st.smooth_method, st.smooth_iterations
            op.strength, op.max_deviation = st.smooth_strength, st.smooth_max_deviation
            op.keep_in_cell = st.keep_in_cell


class ANATOMESH_PT_look(_Base, Panel):
    bl_label = "Look"
    bl_idname = "ANATOMESH_PT_look"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = self.layout
        coll = active_scan(context)
        if coll is None:
            layout.prop(context.scene.anatomesh, "render_method")
            return
        st = coll.anatomesh
        col = layout.column(align=True)
        col.prop(st, "alpha", slider=True)
        col.prop(st, "oriented")
        col.prop(st, "render_method")
        obj = context.active_object
        if obj is not None and "anatomesh_alpha" in obj:
            box = layout.box()
            box.label(text=obj.name, icon="OBJECT_DATA")
            box.prop(obj, '["anatomesh_alpha"]', text="Opacity", slider=True)
            box.prop(obj, "color", text="Viewport colour")
        layout.operator("anatomesh.frame_camera", icon="CAMERA_DATA").collection = coll.name


class ANATOMESH_PT_export(_Base, Panel):
    bl_label = "Export"
    bl_idname = "ANATOMESH_PT_export"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        s = context.scene.anatomesh
        col = self.layout.column(align=True)
        col.prop(s, "export_dir", text="")
        col.prop(s, "export_format")
        col.prop(s, "export_selection")
        op = self.layout.operator("anatomesh.export", icon="EXPORT")
        op.directory, op.format, op.selection = s.export_dir, s.export_format, s.export_selection
        coll = active_scan(context)
        op.collection = coll.name if coll is not None else ""


def menu_import(self, context):
    self.layout.operator("anatomesh.import_scan", text="Medical Scan / Label Map (Anatomesh)")


CLASSES = (
    ANATOMESH_UL_labels,
    ANATOMESH_PT_import,
    ANATOMESH_PT_labels,
    ANATOMESH_PT_smooth,
    ANATOMESH_PT_look,
    ANATOMESH_PT_export,
)
