"""Operators: thin — read the settings, call the app/core stage functions, put the result in the
scene. Each ``<feature>_ops.py`` holds the operators; the ``<feature>.py`` beside it does the work
on the scene with the app's stage functions. Every step is usable from scripts with the UI's
parameters, e.g.::

    bpy.ops.anatomesh.import_scan(filepath="seg.nii.gz", label_table="labels.json", extract=True)
    bpy.ops.anatomesh.smooth(iterations=20)
    bpy.ops.anatomesh.export(directory="/tmp/out", format="STL")

Errors caused by the input (a bad file, a missing label) are reported as ``ERROR`` and the
operator returns ``{'CANCELLED'}``; no exception escapes into Blender.
"""
from . import (decimate_ops, edit_tools_ops, export_ops, fit_ops, look_ops, paint_ops,
               preprocess_ops, print_check_ops, print_parts_ops, recipe_ops, scan_ops, smooth_ops,
               view_ops, web_ops)

CLASSES = (scan_ops.ANATOMESH_OT_import_scan, scan_ops.ANATOMESH_OT_extract,
           scan_ops.ANATOMESH_OT_labels_select, scan_ops.ANATOMESH_OT_level_add,
           scan_ops.ANATOMESH_OT_level_remove, smooth_ops.ANATOMESH_OT_smooth,
           paint_ops.ANATOMESH_OT_paint, decimate_ops.ANATOMESH_OT_decimate_preview,
           decimate_ops.ANATOMESH_OT_decimate_apply, print_check_ops.ANATOMESH_OT_print_check,
           print_check_ops.ANATOMESH_OT_print_select_problem, export_ops.ANATOMESH_OT_export,
           recipe_ops.ANATOMESH_OT_recipe_save, recipe_ops.ANATOMESH_OT_recipe_load,
           web_ops.ANATOMESH_OT_export_web,
           web_ops.ANATOMESH_OT_paint_margins, fit_ops.ANATOMESH_OT_print_fit)
CLASSES += preprocess_ops.CLASSES + print_parts_ops.CLASSES + edit_tools_ops.CLASSES + look_ops.CLASSES
CLASSES += view_ops.CLASSES
