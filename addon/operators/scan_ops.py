"""Scan operators: read a scan (Import), extract its surfaces (Extract), edit the label and
isovalue lists."""
from __future__ import annotations

import os
import time

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, StringProperty
from bpy_extras.io_utils import ImportHelper

from . import smooth as live
from . import warmup
from .common import ProgressReporter, abspath, guarded, load_volume
from .recipe import scene_recipe
from .scan import extract_to_scene, extraction_recipe, fill_lists, frame_viewports
from . import properties as props


# ---------------------------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------------------------
def extract_and_smooth(context, vol, labels_text: str = "", levels_text: str = "",
                       method: str = "SETTINGS", render_method: str = "DITHERED"):
    """Extract the chosen labels/levels, give the new scan the scene's smoothing settings (or
    ``method``) and smooth it with the command line's driver: the same surfaces as ``anatomesh
    mesh`` with those settings (its default ``organ``, unless "As extracted" is chosen)."""
    settings = context.scene.anatomesh
    recipe, looks = extraction_recipe(settings, vol, labels_text, levels_text)
    with ProgressReporter(context, "extracting") as progress:
        coll = extract_to_scene(context, vol, recipe, looks=looks, render_method=render_method,
                                progress=progress)
    return smooth_new_scan(context, coll, method)


def smooth_new_scan(context, coll, method: str = "SETTINGS"):
    """Give a new scan collection the scene's smoothing settings (or ``method``) and smooth it
    with the command line's driver; returns ``coll``."""
    settings = context.scene.anatomesh
    values = {k: getattr(settings, k) for k in props.smoothing_properties()}
    if method != "SETTINGS":
        values["smooth_method"] = method
    live.set_scan_settings(coll, **values)
    if values["smooth_method"] == "NONE":
        return coll
    with ProgressReporter(context, "smoothing"):  # first run: later, once its kernels are ready
        live.smooth_when_ready(coll)
    return coll


# ---------------------------------------------------------------------------------------------
# operators
# ---------------------------------------------------------------------------------------------
class ANATOMESH_OT_import_scan(bpy.types.Operator, ImportHelper):
    """Read a scan or label map (NIfTI, NRRD, DICOM folder) and list its labels or isovalues"""

    bl_idname = "anatomesh.import_scan"
    bl_label = "Import Scan (Anatomesh)"
    bl_options = {"REGISTER", "UNDO"}

    filter_glob: StringProperty(default="*.nii;*.nii.gz;*.gz;*.nrrd;*.nhdr;*.dcm;*.ima;*", options={"HIDDEN"})
    filepath: StringProperty(name="File", subtype="FILE_PATH",
                             description="NIfTI/NRRD file, a DICOM folder or one file in it")
    series: StringProperty(name="Series", description="DICOM series or segmentation object (number or "
                                                      "UID), when several")
    grid: StringProperty(name="Grid", description="Mask folders: a mask name or 'image'; DICOM "
                                                  "SEG/RTSTRUCT: 'image' or 'native'")
    label_table: StringProperty(name="Label table", subtype="FILE_PATH",
                                description="Label names/colours file (optional; sidecars are found)")
    space: EnumProperty(name="Space", items=props.SPACE_ITEMS, default="RAS")
    extract: BoolProperty(name="Extract now", default=True,
                          description="Create the surfaces of every label (or the default isovalues) now")
    render_method: EnumProperty(name="Transparency", items=props.RENDER_METHOD_ITEMS, default="DITHERED")

    @guarded
    def execute(self, context):
        # speed (first run): while the kernels compile in the background, run again when ready
        if warmup.defer(self, warmup.reading_step(self.filepath)):
            return {"FINISHED"}
        settings = context.scene.anatomesh
        t0 = time.perf_counter()
        with ProgressReporter(context, "reading") as progress:
            vol = load_volume(self.filepath, self.series, self.label_table, self.space, progress=progress,
                              grid=self.grid, volume_index=scene_recipe(context.scene).volume_index)
        if self.extract and warmup.defer(self, warmup.extraction_step(vol)):  # speed (first run)
            return {"FINISHED"}
        settings.filepath = self.filepath
        settings.series = self.series
        settings.grid = self.grid
        settings.label_table = self.label_table
        settings.space = self.space
        fill_lists(settings, vol)
        for note in vol.meta.get("notes") or []:  # segmentations: what was read, on which grid
            self.report({"INFO"}, note)
        for w in vol.warnings:
            self.report({"WARNING"}, w)
        if not self.extract:
            n = len(settings.labels) if vol.is_label_map else len(settings.levels)
            what = "labels" if vol.is_label_map else "isovalue presets"
            self.report({"INFO"}, f"Read {os.path.basename(self.filepath)}: {n} {what}")
            return {"FINISHED"}
        coll = extract_and_smooth(context, vol, render_method=self.render_method)
        return _finish_extraction(self, context, coll, t0)


def _finish_extraction(op, context, coll, t0: float):
    """Frame the new surfaces, pass the reader's warnings on, report count and time."""
    frame_viewports(context, coll)
    for w in coll.get("anatomesh_warnings", []):
        op.report({"WARNING"}, w)
    op.report({"INFO"}, f"{len(coll.objects)} surfaces in '{coll.name}' ({time.perf_counter() - t0:.1f} s)")
    return {"FINISHED"}


class ANATOMESH_OT_extract(bpy.types.Operator):
    """Extract the chosen labels (or isovalues) of the scan as surface objects in a new collection"""

    bl_idname = "anatomesh.extract"
    bl_label = "Extract Surfaces"
    bl_options = {"REGISTER", "UNDO"}

    filepath: StringProperty(name="File", subtype="FILE_PATH",
                             description="Scan to read (default: the one in the Import panel)")
    series: StringProperty(name="Series")
    label_table: StringProperty(name="Label table", subtype="FILE_PATH")
    space: EnumProperty(name="Space", items=(("SETTINGS", "As set", "The Import panel's space"),)
                        + props.SPACE_ITEMS, default="SETTINGS")
    labels: StringProperty(name="Labels", description="'' = ticked rows of the list, 'all', or "
                                                      "values/names separated by commas")
    levels: StringProperty(name="Levels", description="'' = ticked isovalues, or numbers separated "
                                                      "by commas (scalar scans)")
    smooth_method: EnumProperty(name="Smoothing", items=(("SETTINGS", "As set", "The Smooth panel's "
                                                                      "defaults"),) + props.SMOOTH_ITEMS,
                                default="SETTINGS")

    @guarded
    def execute(self, context):
        settings = context.scene.anatomesh
        path = self.filepath or settings.filepath
        if not path:
            from ...core.model.errors import AnatomeshError

            raise AnatomeshError("no scan chosen: set the file in the Import panel or pass filepath=")
        if warmup.defer(self, warmup.reading_step(path)):  # first run: again when they are ready
            return {"FINISHED"}
        space = settings.space if self.space == "SETTINGS" else self.space
        series = self.series or (settings.series if not self.filepath else "")
        table = self.label_table or (settings.label_table if not self.filepath else "")
        t0 = time.perf_counter()
        with ProgressReporter(context, "reading") as progress:
            vol = load_volume(path, series, table, space, progress=progress, grid=settings.grid,
                              volume_index=scene_recipe(context.scene).volume_index)
        if warmup.defer(self, warmup.extraction_step(vol)):  # speed (first run)
            return {"FINISHED"}
        if self.filepath and abspath(self.filepath) != abspath(settings.filepath):
            settings.filepath, settings.series, settings.label_table = self.filepath, series, table
            fill_lists(settings, vol)
        elif (vol.is_label_map and not len(settings.labels)) or (
                not vol.is_label_map and not len(settings.levels)):
            fill_lists(settings, vol)
        coll = extract_and_smooth(context, vol, self.labels if vol.is_label_map else "",
                                  self.levels if not vol.is_label_map else "", self.smooth_method,
                                  settings.render_method)
        return _finish_extraction(self, context, coll, t0)


class ANATOMESH_OT_labels_select(bpy.types.Operator):
    """Tick or untick every label (or isovalue) in the list"""

    bl_idname = "anatomesh.labels_select"
    bl_label = "Select Labels"
    bl_options = {"REGISTER", "UNDO", "INTERNAL"}

    action: EnumProperty(items=(("ALL", "All", ""), ("NONE", "None", ""), ("INVERT", "Invert", "")))

    def execute(self, context):
        settings = context.scene.anatomesh
        rows = settings.labels if settings.kind == "LABELS" else settings.levels
        for r in rows:
            r.include = {"ALL": True, "NONE": False}.get(self.action, not r.include)
        return {"FINISHED"}


class ANATOMESH_OT_level_add(bpy.types.Operator):
    """Add an isovalue to the list"""

    bl_idname = "anatomesh.level_add"
    bl_label = "Add Isovalue"
    bl_options = {"REGISTER", "UNDO", "INTERNAL"}

    value: FloatProperty(name="Isovalue", default=0.0)

    def execute(self, context):
        settings = context.scene.anatomesh
        item = settings.levels.add()
        item.value = self.value
        item.name = f"level {self.value:g}"
        settings.level_index = len(settings.levels) - 1
        return {"FINISHED"}


class ANATOMESH_OT_level_remove(bpy.types.Operator):
    """Remove the active isovalue from the list"""

    bl_idname = "anatomesh.level_remove"
    bl_label = "Remove Isovalue"
    bl_options = {"REGISTER", "UNDO", "INTERNAL"}

    def execute(self, context):
        settings = context.scene.anatomesh
        if 0 <= settings.level_index < len(settings.levels):
            settings.levels.remove(settings.level_index)
            settings.level_index = max(0, settings.level_index - 1)
        return {"FINISHED"}
