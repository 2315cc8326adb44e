"""The 3D Viewport sidebar tab "Anatomesh": Import, Labels, Smooth, Look and Export panels."""

import bpy
from bpy.types import Panel, UIList

from ..scene import objects as scene
from ..operators import warmup
from ..operators.common import active_scan
from ..operators.decimate import PREVIEW_MODIFIER


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
        warmup.draw_status(self.layout)  # speed (first run): background kernel compilation
        col = self.layout.column(align=True)
        col.prop(s, "filepath", text="")
        col.prop(s, "label_table", text="Labels")
        col.prop(s, "series")
        col.prop(s, "grid")  # segmentations
        col.prop(s, "space")
        row = self.layout.row(align=True)
        op = row.operator("anatomesh.import_scan", text="Read", icon="FILE_FOLDER")
        op.filepath, op.series, op.label_table, op.space = s.filepath, s.series, s.label_table, s.space
        op.grid = s.grid
        op.extract = False
        if s.info:
            self.layout.label(text=s.info, icon="INFO")
        _draw_gallery(self, context)


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
            layout.label(text="Defaults for the next extraction:")
            _smoothing_props(layout, context.scene.anatomesh)
            return
        st = coll.anatomesh
        layout.label(text=coll.name, icon="OUTLINER_COLLECTION")
        _smoothing_props(layout, st)
        row = layout.row(align=True)
        row.prop(st, "live")
        _smooth_button(row, coll, "Apply", apply=True)
        if not st.live:
            _smooth_button(layout, coll, "Smooth Now")


def _smoothing_props(layout, settings) -> None:
    """The recipe's smoothing settings: method first, the overrides (0: the method's own) below."""
    layout.prop(settings, "smooth_method")
    if settings.smooth_method == "NONE":
        return
    col = layout.column(align=True)
    for name in ("smooth_iterations", "smooth_strength", "smooth_mu", "smooth_max_deviation",
                 "smooth_damping", "smooth_staircase"):
        col.prop(settings, name)


def _smooth_button(layout, coll, text: str, apply: bool = False) -> None:
    op = layout.operator("anatomesh.smooth", text=text, icon="CHECKMARK" if apply else "NONE")
    op.collection, op.apply = coll.name, apply
    for name in ("smooth_method", "smooth_iterations", "smooth_strength", "smooth_mu",
                 "smooth_max_deviation", "smooth_damping", "smooth_staircase"):
        setattr(op, name, getattr(coll.anatomesh, name))


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
            tissue = str(obj.get("anatomesh_tissue", "other"))
            box.operator_menu_enum("anatomesh.set_tissue", "tissue", text=f"Tissue: {tissue.capitalize()}",
                                   icon="MATERIAL")
            # distance colours: every surface by its distance to this one
            box.operator("anatomesh.paint_margins", icon="DRIVER_DISTANCE").target = obj.name
        _camera_rows(layout, context, coll)
        row = layout.row(align=True)
        row.prop(context.scene.anatomesh_recipe, "light", text="Light")
        row.operator("anatomesh.apply_lights", text="Apply", icon="LIGHT_AREA").collection = coll.name


def _camera_rows(layout, context, coll) -> None:
    """View presets, labels on the selection, the turntable (frames from the recipe's setting)."""
    box = layout.box()
    box.label(text="Camera", icon="CAMERA_DATA")
    box.operator_menu_enum("anatomesh.frame_camera", "view", text="Frame View")  # the active scan
    box.operator("anatomesh.label_selected", icon="FONT_DATA").collection = coll.name
    row = box.row(align=True)
    row.prop(context.scene.anatomesh_recipe, "turntable", text="Frames")
    op = row.operator("anatomesh.render_turntable", text="Turntable", icon="RENDER_ANIMATION")
    op.collection, op.frames = coll.name, context.scene.anatomesh_recipe.turntable or 36
    op.directory = context.scene.anatomesh.export_dir


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
        # the web page
        web = self.layout.operator("anatomesh.export_web", text="Export Web", icon="WORLD")
        web.directory, web.selection = s.export_dir, s.export_selection
        web.collection = coll.name if coll is not None else ""


def menu_import(self, context):
    self.layout.operator("anatomesh.import_scan", text="Medical Scan / Label Map (Anatomesh)")



class ANATOMESH_PT_decimate(_Base, Panel):
    bl_label = "Decimate"
    bl_idname = "ANATOMESH_PT_decimate"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = self.layout
        s = context.scene.anatomesh_decimate
        col = layout.column(align=True)
        col.prop(s, "target")
        col.prop(s, {"RATIO": "ratio", "FACES": "faces", "ERROR": "max_error"}[s.target])
        coll = active_scan(context)
        if coll is None:
            layout.label(text="Extract surfaces first")
            return
        objs = scene.surface_objects(coll)
        faces = sum(len(o.data.polygons) for o in objs)
        layout.label(text=f"{coll.name}: {faces:,} faces", icon="OUTLINER_COLLECTION")
        row = layout.row(align=True)
        previewing = any(PREVIEW_MODIFIER in o.modifiers for o in objs)
        op = row.operator("anatomesh.decimate_preview", text="Preview", icon="HIDE_OFF")
        _fill_decimate(op, s, coll)
        if previewing:
            op = row.operator("anatomesh.decimate_preview", text="", icon="X")
            op.collection, op.clear = coll.name, True
        op = row.operator("anatomesh.decimate_apply", text="Apply", icon="CHECKMARK")
        _fill_decimate(op, s, coll)
        measured = [o for o in objs if "anatomesh_decimation_max_error_mm" in o]
        if not measured:
            return
        box = layout.box()
        box.label(text="Measured error (max / mean mm)")
        obj = context.active_object
        shown = sorted(measured, key=lambda o: -o["anatomesh_decimation_max_error_mm"])
        if obj is not None and obj in measured:
            shown = [obj] + [o for o in shown if o != obj]
        for o in shown[:12]:
            row = box.row()
            row.label(text=o.get("anatomesh_name", o.name), icon="OBJECT_DATA" if o == obj else "NONE")
            row.label(text=f"{o['anatomesh_decimation_max_error_mm']:.2f} / "
                           f"{o['anatomesh_decimation_mean_error_mm']:.2f}")
            row.label(text=f"{o.get('anatomesh_faces_before', 0):,} → {len(o.data.polygons):,}")
        if len(shown) > 12:
            box.label(text=f"... {len(shown) - 12} more (largest error first)")

class ANATOMESH_UL_print_problems(UIList):
    bl_idname = "ANATOMESH_UL_print_problems"

    def draw_item(self, context, layout, data, item, icon, active_data, active_propname, index=0):
        row = layout.row(align=True)
        row.label(text=item.part + (f" – {item.other}" if item.other else ""), icon="ERROR")
        row.label(text=item.kind)
        unit = f" {item.unit}" if item.unit else ""
        row.label(text=f"{item.value:.2f}{unit}" if item.unit == "mm" else
                  (f"{item.value:g}{unit}" if unit else ""))
        op = row.operator("anatomesh.print_select_problem", text="", icon="VIEWZOOM")
        op.index = index


class ANATOMESH_PT_print(_Base, Panel):
    bl_label = "Print"
    bl_idname = "ANATOMESH_PT_print"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        s = context.scene.anatomesh_print
        col = self.layout.column(align=True)
        col.prop(s, "profile", text="")
        col.prop(s, "min_wall")
        col.prop(s, "min_gap")
        col.prop(s, "selected_only")
        self.layout.operator("anatomesh.print_check", icon="CHECKMARK")
        if s.checked:
            self.layout.label(text=s.summary, icon="CHECKMARK" if s.passed else "ERROR")
        if len(s.problems):
            self.layout.template_list("ANATOMESH_UL_print_problems", "", s, "problems", s,
                                      "problem_index", rows=4)
        row = self.layout.row(align=True)
        op = row.operator("anatomesh.paint", text="Thickness", icon="MOD_SOLIDIFY")
        op.mode = "THICKNESS"
        op.min_wall = s.min_wall
        op = row.operator("anatomesh.paint", text="Gaps", icon="MOD_LENGTH")
        op.mode = "GAP"
        # cut to fit
        fit = context.scene.anatomesh_fit
        col = self.layout.column(align=True)
        col.prop(fit, "size", text="")
        col.prop(fit, "connectors")
        op = col.operator("anatomesh.print_fit", icon="MOD_BOOLEAN")
        op.size, op.connectors = tuple(fit.size), fit.connectors


class ANATOMESH_PT_recipe(_Base, Panel):
    bl_label = "Recipe"
    bl_idname = "ANATOMESH_PT_recipe"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        col = self.layout.column(align=True)
        col.operator("anatomesh.recipe_save", text="Save Recipe...", icon="FILE_TICK")
        col.operator("anatomesh.recipe_load", text="Load Recipe...", icon="FILE_FOLDER")
        self.layout.label(text="Runs headless: anatomesh mesh --recipe FILE", icon="CONSOLE")


class ANATOMESH_PT_settings(_Base, Panel):
    """Every recipe setting the other panels do not hold, made from its definition."""
    bl_label = "Settings"
    bl_idname = "ANATOMESH_PT_settings"
    bl_parent_id = "ANATOMESH_PT_recipe"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        draw_settings(self.layout, context.scene.anatomesh_recipe)


def draw_settings(layout, group, recipe_type=None) -> None:
    """A generated settings group (``Scene.anatomesh_recipe``), section by section."""
    from ...app.flow.recipe import Recipe
    from ..operators.setting_props import by_section

    for section, names in by_section(recipe_type or Recipe, group.fields).items():
        box = layout.box()
        box.label(text=section.capitalize())
        col = box.column(align=True)
        for name in names:
            col.prop(group, name)


#: lists and panels, in the sidebar's order
CLASSES = (ANATOMESH_UL_labels, ANATOMESH_UL_print_problems, ANATOMESH_PT_import, ANATOMESH_PT_labels,
           ANATOMESH_PT_smooth, ANATOMESH_PT_look, ANATOMESH_PT_decimate, ANATOMESH_PT_print,
           ANATOMESH_PT_export, ANATOMESH_PT_recipe, ANATOMESH_PT_settings)


def _fill_decimate(op, s, coll):
    """The Decimate panel's target on an operator button."""
    op.collection, op.target, op.ratio = coll.name, s.target, s.ratio
    op.faces, op.max_error = s.faces, s.max_error


# ---------------------------------------------------------------------------------------------
# preprocessing before and around extraction
# ---------------------------------------------------------------------------------------------
class ANATOMESH_PT_preprocess(_Base, Panel):
    bl_label = "Preprocess"
    bl_idname = "ANATOMESH_PT_preprocess"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        from ..operators import preprocess as preprocessing

        s, p = context.scene.anatomesh, context.scene.anatomesh_preprocess
        layout = self.layout
        if s.kind == "NONE":
            layout.label(text="Read a scan first")
            return
        col = layout.column(align=True)
        col.prop(p, "roi")
        if s.kind == "LEVELS":
            col.prop(p, "resample")
            if p.resample > 0:
                col.prop(p, "resample_method")
            col.prop(p, "smooth_volume")
            if p.smooth_volume != "NONE":
                col.prop(p, "smooth_value")
            col.prop(p, "fuzzy")
            if p.fuzzy:
                row = col.row(align=True)
                row.prop(p, "fuzzy_low")
                row.prop(p, "fuzzy_high")
                row.prop(p, "fuzzy_count")
            col.prop(p, "precise")
        else:
            col.prop(p, "interpolate")
            col.prop(p, "fuzzy_boundary")
            col.prop(p, "fill_cavities")
            col.prop(p, "close_handles")
        col.prop(p, "difference_colors")
        layout.operator("anatomesh.preprocess_extract", icon="MOD_SMOOTH")
        for line in preprocessing.summary_lines(active_scan(context)):
            layout.label(text=line)
        if s.kind == "LEVELS":
            box = layout.box()
            row = box.row(align=True)
            row.operator("anatomesh.live_isovalue", text="Live Isovalue", icon="PLAY")
            if p.live_object and p.live_object in bpy.data.objects:
                box.prop(p, "live_level", slider=False)


def _draw_gallery(self, context):
    """Import panel addition: the isovalue gallery button and the picture."""
    from ..operators import preprocess as preprocessing

    if context.scene.anatomesh.kind != "LEVELS":
        return
    layout = self.layout
    layout.operator("anatomesh.preview_gallery", icon="IMAGE_DATA")
    img = bpy.data.images.get(preprocessing.GALLERY_IMAGE)
    if img is not None and img.preview is not None:
        layout.template_icon(icon_value=img.preview.icon_id, scale=12.0)


CLASSES = tuple(c for k in CLASSES for c in ((k, ANATOMESH_PT_preprocess) if k is ANATOMESH_PT_labels else (k,)))


# ---------------------------------------------------------------------------------------------
# print tools (a sub-panel of Print)
# ---------------------------------------------------------------------------------------------
class ANATOMESH_PT_print_tools(_Base, Panel):
    bl_label = "Print Tools"
    bl_idname = "ANATOMESH_PT_print_tools"
    bl_parent_id = "ANATOMESH_PT_print"

    def draw(self, context):
        t = context.scene.anatomesh_print_tools
        layout = self.layout
        row = layout.row(align=True)
        row.operator("anatomesh.print_fuse", icon="AUTOMERGE_ON")
        row.operator("anatomesh.print_thicken", icon="MOD_SOLIDIFY")
        row = layout.row(align=True)
        row.prop(t, "clearance")
        row.operator("anatomesh.print_clearance", text="Apply").clearance = t.clearance
        col = layout.column(align=True)
        col.prop(t, "hollow_wall")
        col.prop(t, "drain_holes")
        col.prop(t, "drain_diameter")
        op = col.operator("anatomesh.print_hollow", icon="MESH_UVSPHERE")
        op.wall, op.drain_holes, op.drain_diameter = t.hollow_wall, t.drain_holes, t.drain_diameter
        layout.operator("anatomesh.print_connectors", icon="SNAP_PEEL_OBJECT")


# ---------------------------------------------------------------------------------------------
# edit-mode tools (a sub-panel of Print, shown in Edit Mode)
# ---------------------------------------------------------------------------------------------
class ANATOMESH_PT_edit_tools(_Base, Panel):
    bl_label = "Edit Mode"
    bl_idname = "ANATOMESH_PT_edit_tools"
    bl_parent_id = "ANATOMESH_PT_print"

    @classmethod
    def poll(cls, context):
        return context.mode == "EDIT_MESH"

    def draw(self, context):
        t = context.scene.anatomesh_print_tools
        layout = self.layout
        row = layout.row(align=True)
        row.prop(t, "problem", text="")
        row.operator("anatomesh.edit_select_problem", text="Select", icon="RESTRICT_SELECT_OFF").kind = t.problem
        row = layout.row(align=True)
        row.prop(t, "hole_edges")
        row.operator("anatomesh.edit_fill_holes", text="Fill Holes").max_edges = t.hole_edges
        row = layout.row(align=True)
        row.prop(t, "tiny_volume")
        row.operator("anatomesh.edit_remove_tiny", text="Remove Tiny").min_volume = t.tiny_volume
        col = layout.column(align=True)
        col.prop(t, "relax_deviation")
        col.prop(t, "relax_iterations")
        op = col.operator("anatomesh.edit_relax", icon="MOD_SMOOTH")
        op.max_deviation, op.iterations = t.relax_deviation, t.relax_iterations


CLASSES = CLASSES + (ANATOMESH_PT_print_tools, ANATOMESH_PT_edit_tools)
