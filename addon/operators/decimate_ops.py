"""Anatomesh add-on: the Decimate panel: targets, preview with Blender's Decimate modifier, Apply
with the core result, measured error per organ.

* Target (``Scene.anatomesh_decimate``): a ratio of faces to keep, a face count (all surfaces of
  the scan together) or a maximum error in mm.
* Preview (``anatomesh.decimate_preview``): a Decimate modifier (collapse) on every surface object
  of the scan — non-destructive, quick, but each organ on its own: seams may open in the preview.
  For a max-error target the ratio of each organ comes from a core run.
* Apply (``anatomesh.decimate_apply``): core's quadric decimation (:mod:`anatomesh.core.decimate.qem`)
  on the whole scan at once. For a label map the objects' shells are put back together into one
  SurfaceSet (shared vertices from the ``anatomesh_vid`` attribute, interface triangles once, pinch
  copies as split rows), so every interface is decimated once for both organs and seams stay
  shared; shells stay closed and manifold. The shown (possibly smoothed) shape is decimated and
  becomes the new rest shape (smoothing iterations go back to 0). The measured error of every
  organ is stored on its object (:data:`ERROR_PROPS`) and listed in the panel. Undo restores the
  objects.
"""
from __future__ import annotations


import bpy
from bpy.props import EnumProperty, FloatProperty, IntProperty, StringProperty
from bpy.types import Operator

from ..scene import objects as scene
from . import warmup
from .common import ProgressReporter, active_scan, guarded
from .decimate import clear_preview, decimate_collection, preview_ratios, set_preview
from .properties import TARGET_ITEMS


# ---------------------------------------------------------------------------------------------
# the scan's surfaces as core arrays
# ---------------------------------------------------------------------------------------------


# ---------------------------------------------------------------------------------------------
# apply and preview
# ---------------------------------------------------------------------------------------------


def _scan(op, context):
    from ...core.model.errors import AnatomeshError

    coll = bpy.data.collections.get(op.collection) if op.collection else active_scan(context)
    if coll is None or not coll.anatomesh.is_scan:
        raise AnatomeshError("no scan collection to decimate: extract surfaces first, or pass "
                             "collection= with its name")
    return coll


class _TargetProps:
    collection: StringProperty(name="Scan", description="Scan collection (default: the active one)")
    target: EnumProperty(name="Target", items=TARGET_ITEMS, default="RATIO")
    ratio: FloatProperty(name="Ratio", default=0.1, min=0.001, max=1.0)
    faces: IntProperty(name="Faces", default=50000, min=4)
    max_error: FloatProperty(name="Max error", default=1.0, min=0.0, unit="LENGTH",
                             description="mm")

    def invoke(self, context, event):  # values not given come from the panel's settings
        s = context.scene.anatomesh_decimate
        for name in ("target", "ratio", "faces", "max_error"):
            if not self.properties.is_property_set(name):
                setattr(self, name, getattr(s, name))
        return self.execute(context)


class ANATOMESH_OT_decimate_preview(_TargetProps, Operator):
    """Preview the decimation with Blender's Decimate modifier on each surface (non-destructive;
    Apply uses core's result, which keeps the seams between organs shared)"""

    bl_idname = "anatomesh.decimate_preview"
    bl_label = "Preview Decimation"
    bl_options = {"REGISTER", "UNDO"}

    clear: bpy.props.BoolProperty(name="Clear", default=False, description="Remove the preview")

    @guarded
    def execute(self, context):
        coll = _scan(self, context)
        objs = scene.surface_objects(coll)
        if self.clear:
            self.report({"INFO"}, f"Removed the preview from {clear_preview(objs)} surface(s)")
            return {"FINISHED"}
        if warmup.defer(self, warmup.DECIMATION_STEP):  # first run: again when its kernels are compiled
            return {"FINISHED"}
        with ProgressReporter(context, "decimation preview"):
            set_preview(objs, preview_ratios(coll, objs, self.target, self.ratio, self.faces,
                                               self.max_error))
        self.report({"INFO"}, f"Decimate preview on {len(objs)} surface(s) of '{coll.name}'")
        return {"FINISHED"}


class ANATOMESH_OT_decimate_apply(_TargetProps, Operator):
    """Decimate all surfaces of the scan at once with core's quadric decimation: shells stay
    closed, seams between organs stay shared, the error in mm is measured per organ"""

    bl_idname = "anatomesh.decimate_apply"
    bl_label = "Apply Decimation"
    bl_options = {"REGISTER", "UNDO"}

    @guarded
    def execute(self, context):
        import time

        coll = _scan(self, context)
        if warmup.defer(self, warmup.DECIMATION_STEP):  # first run: again when its kernels are compiled
            return {"FINISHED"}
        t0 = time.perf_counter()
        before = sum(len(o.data.polygons) for o in scene.surface_objects(coll))
        with ProgressReporter(context, "decimating") as progress:
            results = decimate_collection(coll, self.target, self.ratio, self.faces, self.max_error,
                                          progress=progress)
        after = sum(len(o.data.polygons) for o in scene.surface_objects(coll))
        worst = max(r["hausdorff_mm"] for r in results.values())
        self.report({"INFO"}, f"Decimated '{coll.name}': {before:,} → {after:,} faces, largest "
                              f"error {worst:.2f} mm ({time.perf_counter() - t0:.1f} s)")
        return {"FINISHED"}
