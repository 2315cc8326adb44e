"""The Blender side of Anatomesh: the only package that imports ``bpy``.

Thin by design: properties hold the settings (``props``), operators call ``core`` on numpy arrays
(``operators``), ``bridge`` moves arrays in and out of Blender meshes, ``scene`` makes collections,
objects and materials, ``live`` re-smooths while a slider moves, ``panels`` draw the sidebar tab.
All classes are registered here, from one ``CLASSES`` tuple; registering does no heavy work (numba
kernels compile on first use).
"""
from __future__ import annotations

import bpy

from . import decimate_ui, live, operators, paint, panels, print_ui, props, recipe_ui

#: feature modules with their own ``CLASSES`` and ``register()``/``unregister()`` for their properties
FEATURES = (paint, decimate_ui, print_ui, recipe_ui)
CLASSES = props.CLASSES + operators.CLASSES + panels.CLASSES + \
    tuple(c for m in FEATURES for c in m.CLASSES)


def register():
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    props.register_properties()
    for m in FEATURES:
        m.register()
    bpy.types.TOPBAR_MT_file_import.append(panels.menu_import)
    live.register_handlers()


def unregister():
    live.unregister_handlers()
    bpy.types.TOPBAR_MT_file_import.remove(panels.menu_import)
    for m in reversed(FEATURES):
        m.unregister()
    props.unregister_properties()
    for cls in reversed(CLASSES):
        try:
            bpy.utils.unregister_class(cls)
        except RuntimeError:  # already unregistered (e.g. a failed register)
            pass
    live.forget()
    operators._VOLUMES.clear()
