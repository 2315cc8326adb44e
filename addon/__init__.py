"""The Blender side of Anatomesh: the only package that imports ``bpy``.

Thin by design: ``ui/`` holds the settings (property groups) and draws the sidebar tab,
``operators/`` read the settings and call the same app/core stage functions as the command line,
``scan`` adds a scan's surfaces to the scene, ``bridge`` moves arrays in and out of Blender
meshes, ``scene`` makes collections, objects and materials, ``live`` re-smooths while a slider
moves, ``headless`` builds scenes for ``blender -b`` and the CLI's ``.blend``/PNG outputs.
Registering does no heavy work: on a first run the numba kernels compile in a background process
(``warmup``), so Blender never freezes.
"""
from __future__ import annotations

import bpy

from ..app.outputs import register_blender_writer
from . import common, headless, live, operators, warmup
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
