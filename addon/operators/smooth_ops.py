"""Smooth operator: re-smooth a scan's surfaces from their extracted shape with the command
line's smoothing driver (the same settings give the same vertices as ``anatomesh mesh``)."""
from __future__ import annotations

import bpy
from bpy.props import BoolProperty, StringProperty

from ...core.model.errors import AnatomeshError
from . import smooth as live
from . import warmup
from .common import active_scan, guarded
from . import properties as props


class ANATOMESH_OT_smooth(bpy.types.Operator):
    """Smooth a scan's surfaces from their extracted shape (seams between organs stay shared)"""

    bl_idname = "anatomesh.smooth"
    bl_label = "Smooth Surfaces"
    bl_options = {"REGISTER", "UNDO"}

    collection: StringProperty(name="Scan", description="Scan collection (default: the active one)")
    apply: BoolProperty(name="Apply", default=False,
                        description="Bake: the smoothed shape becomes the new extracted shape")

    def invoke(self, context, event):  # settings not given start from the scan's current ones
        coll = bpy.data.collections.get(self.collection) if self.collection else active_scan(context)
        if coll is not None and coll.anatomesh.is_scan:
            for name in props.smoothing_properties():
                if not self.properties.is_property_set(name):
                    setattr(self, name, getattr(coll.anatomesh, name))
        return self.execute(context)

    @guarded
    def execute(self, context):
        coll = bpy.data.collections.get(self.collection) if self.collection else active_scan(context)
        if coll is None or not coll.anatomesh.is_scan:
            raise AnatomeshError("no scan collection to smooth: extract surfaces first, or pass "
                                 "collection= with its name")
        if warmup.defer(self, live.smoothing_step(coll)):  # first run: again when compiled
            return {"FINISHED"}
        live.set_scan_settings(coll, **{name: getattr(self, name) for name in props.smoothing_properties()})
        seconds = live.smooth_collection(coll)
        if self.apply:
            live.apply(coll)
        self.report({"INFO"}, f"Smoothed '{coll.name}' ({seconds:.2f} s)" + (", applied" if self.apply else ""))
        return {"FINISHED"}


# the smoothing settings, as in the Smooth panel and the recipe's [smoothing] section
ANATOMESH_OT_smooth.__annotations__.update(props.smoothing_properties())
