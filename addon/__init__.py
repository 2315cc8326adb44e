"""The Blender side of Anatomesh: the only package that imports ``bpy``.

Thin by design, in rooms: ``scene/`` moves arrays in and out of Blender meshes (``bridge``) and
makes collections, objects and materials; ``operators/`` holds each ``<feature>_ops.py`` (the
operators, reading the settings) beside its ``<feature>.py``, which calls the same app/core stage
functions as the command line (extraction, live smoothing, decimation, print tools, export);
``ui/`` holds the settings as property groups and draws the sidebar tab; ``headless`` builds
scenes for ``blender -b`` and the CLI's ``.blend``/PNG outputs. Registering does no heavy work:
on a first run the numba kernels compile in a background process (``operators/warmup``), so
Blender never freezes.
"""
from __future__ import annotations

import bpy

from ..app.flow.outputs import register_blender_writer
from .operators import common, smooth as live
from . import headless, operators
from .operators import warmup
from .ui import panels, props

CLASSES = props.CLASSES + operators.CLASSES + panels.CLASSES


def register():
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    props.register_properties()
    bpy.types.TOPBAR_MT_file_import.append(panels.menu_import)
    live.register_handlers()
    register_blender_writer(headless.write_blend)
    if not bpy.app.background:  # speed (first run): compile the kernels in the background
        warmup.start()


def unregister():
    warmup.stop()
    live.unregister_handlers()
    bpy.types.TOPBAR_MT_file_import.remove(panels.menu_import)
    props.unregister_properties()
    for cls in reversed(CLASSES):
        try:
            bpy.utils.unregister_class(cls)
        except RuntimeError:  # already unregistered (e.g. a failed register)
            pass
    live.forget()
    common.forget_volumes()
