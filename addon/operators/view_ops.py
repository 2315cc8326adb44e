"""View operators: frame the camera on a scan from a view preset, label the selected structures,
render a turntable (frame by frame: progress, Esc stops it)."""
from __future__ import annotations

import bpy
from bpy.props import EnumProperty, FloatProperty, IntProperty, StringProperty

from ...app.flow.recipe import VIEWS
from .common import active_scan, guarded
from . import view as views

VIEW_ITEMS = tuple((v.upper(), v.replace("_", " ").capitalize(), f"From the patient's {v.replace('_', ' ')} side"
                    if v != "oblique" else "From the front-left, 45° around and 20° above") for v in VIEWS)


def _scan(op, context):
    from ...core.model.errors import AnatomeshError

    coll = bpy.data.collections.get(op.collection) if op.collection else active_scan(context)
    if coll is None:
        raise AnatomeshError("no scan collection: extract surfaces first")
    return coll


class ANATOMESH_OT_frame_camera(bpy.types.Operator):
    """Frame the scan with its own camera from a view preset, the visible surfaces filling the frame"""

    bl_idname = "anatomesh.frame_camera"
    bl_label = "Frame Camera"
    bl_options = {"REGISTER", "UNDO"}

    collection: StringProperty(name="Scan")
    view: EnumProperty(name="View", items=VIEW_ITEMS)
    elevation: FloatProperty(name="Elevation", default=0.0, min=-89.0, max=89.0,
                             description="Degrees the camera is raised toward the head from the view")
    azimuth: FloatProperty(name="Azimuth", default=0.0, min=-180.0, max=180.0,
                           description="Degrees the camera turns around the patient's long axis")

    @guarded
    def execute(self, context):
        views.set_view(context, _scan(self, context), self.view.lower(), self.elevation, self.azimuth)
        return {"FINISHED"}


class ANATOMESH_OT_label_selected(bpy.types.Operator):
    """Label the selected structures in the scene camera's view: names beside the anatomy, leader lines to them"""

    bl_idname = "anatomesh.label_selected"
    bl_label = "Label Selected"
    bl_options = {"REGISTER", "UNDO"}

    collection: StringProperty(name="Scan")

    @guarded
    def execute(self, context):
        coll = views.label_selected(context, _scan(self, context))
        hidden = list(coll.get("anatomesh_hidden", []))
        if hidden:
            self.report({"WARNING"}, f"not visible from this view, not labelled: {', '.join(hidden)}")
        return {"FINISHED"}


class ANATOMESH_OT_render_turntable(bpy.types.Operator):
    """Render a turn around the patient's long axis: PNG frames in FOLDER/turntable and turntable.mp4 (Esc stops)"""

    bl_idname = "anatomesh.render_turntable"
    bl_label = "Render Turntable"

    collection: StringProperty(name="Scan")
    frames: IntProperty(name="Frames", default=36, min=2, max=720)
    directory: StringProperty(name="Folder", subtype="DIR_PATH", default="//")

    _job = None
    _timer = None

    @guarded
    def execute(self, context):  # scripts and background: every frame now
        job = views.TurntableJob(context, _scan(self, context), self.frames, self.directory)
        try:
            while job.step():
                pass
        finally:
            video = job.finish()
        self.report({"INFO"}, f"{len(job.written)} frames in {job.folder}" + (f", {video.name}" if video else ""))
        return {"FINISHED"}

    def invoke(self, context, event):
        try:
            self._job = views.TurntableJob(context, _scan(self, context), self.frames, self.directory)
        except Exception as exc:  # the same one-line errors as execute
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        wm = context.window_manager
        wm.progress_begin(0, self.frames)
        self._timer = wm.event_timer_add(0.05, window=context.window)
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        if event.type == "ESC":
            return self._end(context, cancelled=True)
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        if not self._job.step():
            return self._end(context)
        context.window_manager.progress_update(len(self._job.written))
        context.workspace.status_text_set(f"Anatomesh: turntable frame {len(self._job.written)}/{self.frames} (Esc stops)")
        return {"RUNNING_MODAL"}

    def _end(self, context, cancelled: bool = False):
        wm = context.window_manager
        wm.event_timer_remove(self._timer)
        wm.progress_end()
        context.workspace.status_text_set(None)
        video = self._job.finish(cancelled)
        n = len(self._job.written)
        if cancelled:
            self.report({"WARNING"}, f"Turntable stopped after {n} frames ({self._job.folder})")
            return {"CANCELLED"}
        self.report({"INFO"}, f"{n} frames in {self._job.folder}" + (f", {video.name}" if video else ""))
        return {"FINISHED"}


CLASSES = (ANATOMESH_OT_frame_camera, ANATOMESH_OT_label_selected, ANATOMESH_OT_render_turntable)
