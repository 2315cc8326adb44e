"""Web operators: the self-contained 3D page of the surfaces, and distance colours."""
from __future__ import annotations

import os

import bpy
from bpy.props import BoolProperty, EnumProperty, IntProperty, StringProperty

from ...app.web.views import read_views
from ...core.export.common import file_stem
from ...core.model.errors import AnatomeshError
from . import warmup
from .common import abspath, guarded
from .paint import show_vertex_colors
from . import properties as props
from .web import export_web, neighbours_of, paint_margins, surface_objects_of


class ANATOMESH_OT_export_web(bpy.types.Operator):
    """Write a 3D page (index.html + scripts) that shows the surfaces in any web browser, offline"""

    bl_idname = "anatomesh.export_web"
    bl_label = "Export Web Page"
    bl_options = {"REGISTER"}

    directory: StringProperty(name="Folder", subtype="DIR_PATH",
                              description="The page goes into <folder>/<scan>_web/index.html")
    selection: EnumProperty(name="What", items=props.EXPORT_SELECTION_ITEMS, default="COLLECTION")
    collection: StringProperty(name="Scan", description="Scan collection (default: the active one)")
    levels: IntProperty(name="Levels of Detail", default=2, min=1, max=4,
                        description="The coarsest is shown first, finer ones replace it as they load")
    overwrite: BoolProperty(name="Overwrite", default=False, description="Replace an existing page")
    views: StringProperty(name="Views", subtype="FILE_PATH",
                          description="Saved views the page lists: a TOML or JSON file of name = URL fragment "
                                      "(default: the Settings panel's web views)")

    @guarded
    def execute(self, context):
        folder = abspath(self.directory or context.scene.anatomesh.export_dir)
        if not folder:
            raise AnatomeshError("no output folder; set one in the Export panel or pass directory=")
        objs = surface_objects_of(context, self.selection, self.collection)
        if not objs:
            raise AnatomeshError("nothing to export: select surface objects or choose a scan collection")
        views_file = abspath(self.views or getattr(getattr(context.scene, "anatomesh_recipe", None), "web_views", ""))
        views = read_views(views_file) if views_file else []  # a bad file: one line, nothing written
        if warmup.defer(self, warmup.FIXES_STEP):  # first run: again when the kernels are compiled
            return {"FINISHED"}
        title = objs[0].users_collection[0].name if objs[0].users_collection else "surfaces"
        out = os.path.join(folder, file_stem(title) + "_web")
        summary = export_web(context, objs, out, title=title, levels=self.levels, overwrite=self.overwrite,
                             views=views)
        self.report({"INFO"}, f"Wrote {summary['page']} ({summary['total_bytes'] / 1e6:.2f} MB, "
                              f"{summary['levels'][-1]['triangles']:,} triangles)")
        return {"FINISHED"}


class ANATOMESH_OT_paint_margins(bpy.types.Operator):
    """Colour every surface by its distance to the active object: within the margins red, yellow, green"""

    bl_idname = "anatomesh.paint_margins"
    bl_label = "Distance to Active"
    bl_options = {"REGISTER", "UNDO"}

    target: StringProperty(name="Target", description="Object to measure to (default: the active object)")
    margins: StringProperty(name="Margins (mm)", default="2,5,10",
                            description="Up to three increasing distances in mm: red, yellow, green")

    @guarded
    def execute(self, context):
        from ...core.geometry.margins import check_margins

        target = bpy.data.objects.get(self.target) if self.target else context.active_object
        if target is None or target.type != "MESH":
            raise AnatomeshError("choose the target: make a surface object active (or pass target=)")
        objs = neighbours_of(target)
        if warmup.defer(self, warmup.FIXES_STEP):  # first run: again when the kernels are compiled
            return {"FINISHED"}
        try:
            margins = check_margins([float(x) for x in self.margins.split(",") if x.strip()])
        except ValueError:
            raise AnatomeshError(f"margins must be distances in mm, e.g. 2,5,10; got {self.margins!r}") from None
        summary = paint_margins(context, objs, target, margins)
        show_vertex_colors(context)
        near = sum(1 for s in summary["shells"].values() if s["min_distance_mm"] is not None)
        self.report({"INFO"}, f"{near} surface(s) within {margins[-1]:g} mm of {target.name}")
        return {"FINISHED"}
