"""View operators: frame the camera on a scan."""
from __future__ import annotations

import bpy
from bpy.props import (EnumProperty, FloatProperty,
                       StringProperty)

from ..scene import objects as scene
from .common import active_scan, guarded


class ANATOMESH_OT_frame_camera(bpy.types.Operator):
    """Point the scene camera at the scan from the patient's front, framing every surface"""

    bl_idname = "anatomesh.frame_camera"
    bl_label = "Frame Camera"
    bl_options = {"REGISTER", "UNDO"}

    collection: StringProperty(name="Scan")
    view: EnumProperty(name="View", items=(("ANTERIOR", "Front", "From the patient's front"),
                                           ("POSTERIOR", "Back", "From the patient's back")))
    elevation: FloatProperty(name="Elevation", default=0.0, min=-89.0, max=89.0,
                             description="Degrees above the horizontal plane (toward the head)")
    azimuth: FloatProperty(name="Azimuth", default=0.0, min=-180.0, max=180.0,
                           description="Degrees around the patient's long axis")

    @guarded
    def execute(self, context):
        from ...core.model.errors import AnatomeshError

        coll = bpy.data.collections.get(self.collection) if self.collection else active_scan(context)
        if coll is None:
            raise AnatomeshError("no scan collection to frame")
        scene.frame_camera(context.scene, scene.surface_objects(coll), coll.anatomesh.space, self.view,
                           self.elevation, self.azimuth)
        return {"FINISHED"}
