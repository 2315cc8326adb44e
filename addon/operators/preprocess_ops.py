"""Preprocessing operators: extract with the Preprocess panel's settings, show the
isovalue gallery, start the live isovalue."""
from __future__ import annotations

import time

import bpy
from bpy.props import FloatProperty, StringProperty

from . import isovalue as live_iso, preprocess as preprocessing
from . import warmup
from .common import ProgressReporter, active_scan, guarded, load_volume
from .recipe import preprocess_to_recipe, recipe_from_scene
from .scan import frame_viewports
from .scan_ops import smooth_new_scan


def _volume(context):
    from ...core.model.errors import AnatomeshError

    s = context.scene.anatomesh
    if not s.filepath:
        raise AnatomeshError("read a scan first (Import panel)")
    return load_volume(s.filepath, s.series, s.label_table, s.space)


class ANATOMESH_OT_preprocess_extract(bpy.types.Operator):
    """Preprocess the scan as the Preprocess panel says, extract its surfaces and report each
    step's effect on them (mm)"""

    bl_idname = "anatomesh.preprocess_extract"
    bl_label = "Extract with Preprocessing"
    bl_options = {"REGISTER", "UNDO"}

    @guarded
    def execute(self, context):
        t0 = time.perf_counter()
        vol = _volume(context)
        recipe = recipe_from_scene(context)
        preprocess_to_recipe(context.scene.anatomesh_preprocess, recipe)
        with ProgressReporter(context, "preprocessing") as progress:
            coll = preprocessing.extract_preprocessed(context, vol, recipe, progress)
        smooth_new_scan(context, coll)
        frame_viewports(context, coll)
        for line in preprocessing.summary_lines(coll):
            self.report({"INFO"}, line)
        self.report({"INFO"}, f"{len(coll.objects)} surfaces in '{coll.name}' "
                              f"({time.perf_counter() - t0:.1f} s)")
        return {"FINISHED"}


class ANATOMESH_OT_preview_gallery(bpy.types.Operator):
    """Render small pictures of the isosurface at the preset levels (or the given ones) into one
    image shown in the Import panel, to pick an isovalue by looking"""

    bl_idname = "anatomesh.preview_gallery"
    bl_label = "Isovalue Gallery"
    bl_options = {"REGISTER"}

    levels: StringProperty(name="Levels", description="VALUE or NAME:VALUE, comma separated "
                                                      "(empty: the presets)")

    @guarded
    def execute(self, context):
        from ...app.pictures.gallery import parse_levels

        vol = _volume(context)
        levels = parse_levels([self.levels]) if self.levels.strip() else None
        img = preprocessing.show_gallery(vol, levels)
        self.report({"INFO"}, f"gallery: {img.size[0]}x{img.size[1]} px in image '{img.name}'")
        return {"FINISHED"}


class ANATOMESH_OT_live_isovalue(bpy.types.Operator):
    """Add a live isosurface to the active scan (or a new collection): dragging the Live isovalue
    re-extracts and redraws it"""

    bl_idname = "anatomesh.live_isovalue"
    bl_label = "Live Isovalue"
    bl_options = {"REGISTER", "UNDO"}

    level: FloatProperty(name="Isovalue", default=float("nan"),
                         description="Start value (default: the panel's)")

    @guarded
    def execute(self, context):
        from ...core.model.errors import AnatomeshError
        from ..scene.objects import new_collection, scan_name, setup_units

        vol = _volume(context)
        if vol.is_label_map:
            raise AnatomeshError("the live isovalue is for scalar scans; this is a label map")
        if warmup.defer(self, "isosurfaces"):  # first run: again when the scans' kernels are compiled
            return {"FINISHED"}
        p = context.scene.anatomesh_preprocess
        level = p.live_level if self.level != self.level else self.level  # NaN: the panel's
        coll = active_scan(context)
        if coll is None:
            setup_units(context.scene)
            coll = new_collection(scan_name(context.scene.anatomesh.filepath))
            coll.anatomesh.is_scan, coll.anatomesh.space = True, vol.space
            context.scene.anatomesh.last_collection = coll.name
        obj = live_iso.live_object(coll, vol, level)
        p.live_object = obj.name
        p.live_level = level  # redraws through the update callback
        self.report({"INFO"}, f"live isovalue {level:g}: {len(obj.data.polygons):,} triangles")
        return {"FINISHED"}


CLASSES = (ANATOMESH_OT_preprocess_extract, ANATOMESH_OT_preview_gallery, ANATOMESH_OT_live_isovalue)
