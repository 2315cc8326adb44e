"""Smooth operator: re-smooth a scan's surfaces from their extracted shape."""
from __future__ import annotations

import time

import bpy
from bpy.props import (BoolProperty, EnumProperty, FloatProperty,
                       IntProperty, StringProperty)

from .. import live
from ..common import active_scan, guarded
from ..ui import props


class ANATOMESH_OT_smooth(bpy.types.Operator):
    """Smooth a scan's surfaces from their extracted shape (seams between organs stay shared)"""

    bl_idname = "anatomesh.smooth"
    bl_label = "Smooth Surfaces"
    bl_options = {"REGISTER", "UNDO"}

    collection: StringProperty(name="Scan", description="Scan collection (default: the active one)")
    method: EnumProperty(name="Method", items=props.SMOOTH_ITEMS, default="TAUBIN")
    iterations: IntProperty(name="Iterations", default=10, min=0, soft_max=100, max=1000)
    strength: FloatProperty(name="Strength", default=0.5, min=0.0, max=1.0)
    max_deviation: FloatProperty(name="Max deviation", default=0.0, min=0.0, soft_max=5.0, unit="LENGTH",
                                 description="mm; 0: no cap")
    keep_in_cell: BoolProperty(name="Stay in voxel", default=True,
                               description="Keep every vertex inside its voxel cell (Gibson 1998)")
    apply: BoolProperty(name="Apply", default=False,
                        description="Bake: the smoothed shape becomes the new extracted shape")

    def invoke(self, context, event):  # values not given start from the scan's current ones
        coll = bpy.data.collections.get(self.collection) if self.collection else active_scan(context)
        if coll is not None and coll.anatomesh.is_scan:
            s = coll.anatomesh
            for mine, theirs in (("method", "smooth_method"), ("iterations", "smooth_iterations"),
                                 ("strength", "smooth_strength"), ("max_deviation", "smooth_max_deviation"),
                                 ("keep_in_cell", "keep_in_cell")):
                if not self.properties.is_property_set(mine):
                    setattr(self, mine, getattr(s, theirs))
        return self.execute(context)

    @guarded
    def execute(self, context):
        from ...core.model.errors import AnatomeshError

        coll = bpy.data.collections.get(self.collection) if self.collection else active_scan(context)
        if coll is None or not coll.anatomesh.is_scan:
            raise AnatomeshError("no scan collection to smooth: extract surfaces first, or pass "
                                 "collection= with its name")
        live.set_scan_settings(coll, smooth_method=self.method, smooth_iterations=self.iterations,
                               smooth_strength=self.strength, smooth_max_deviation=self.max_deviation,
                               keep_in_cell=self.keep_in_cell)
        t0 = time.perf_counter()
        live.smooth_collection(coll, self.method, self.iterations, self.strength, self.max_deviation,
                               self.keep_in_cell)
        if self.apply:
            live.apply(coll)
        self.report({"INFO"}, f"Smoothed '{coll.name}' ({time.perf_counter() - t0:.2f} s)"
                              + (", applied" if self.apply else ""))
        return {"FINISHED"}
