"""Paint operator: colour surfaces by curvature, distance to the unsmoothed shape, thickness or gaps."""
from __future__ import annotations

from bpy.props import (EnumProperty, FloatProperty)
from bpy.types import Operator

from . import warmup
from .common import guarded
from .paint import paint_mode, show_vertex_colors, target_objects


class ANATOMESH_OT_paint(Operator):
    """Colour Anatomesh surfaces by curvature, distance to the unsmoothed surface, wall thickness or gap"""

    bl_idname = "anatomesh.paint"
    bl_label = "Paint Heat Map"
    bl_options = {"REGISTER", "UNDO"}

    mode: EnumProperty(name="Values", items=[
        ("CURVATURE", "Curvature", "Mean curvature (1/mm): blue concave, red convex"),
        ("DISTANCE", "Distance", "Distance to the unsmoothed surface (mm)"),
        ("THICKNESS", "Thickness", "Wall thickness (mm): red below the minimum wall"),
        ("GAP", "Gap", "Distance to the nearest other part (mm): red where parts touch"),
    ], default="THICKNESS")
    min_wall: FloatProperty(name="Minimum Wall", default=0.8, min=0.01, unit="LENGTH",
                            description="Thickness maps run red (0) to blue (twice this)")

    @guarded
    def execute(self, context):
        objs = target_objects(context)
        if not objs:
            self.report({"WARNING"}, "No Anatomesh surfaces: select some or import a scan")
            return {"CANCELLED"}
        if warmup.defer(self, warmup.FIXES_STEP):  # first run: again when the kernels are compiled
            return {"FINISHED"}
        paint_mode(objs, self.mode, min_wall=self.min_wall)
        show_vertex_colors(context)
        self.report({"INFO"}, f"Painted {self.mode.lower()} on {len(objs)} object(s)")
        return {"FINISHED"}
