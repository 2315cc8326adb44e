"""Operators: thin — read the settings, call the app/core stage functions, put the result in the
scene. Every step is usable from scripts with the UI's parameters, e.g.::

    bpy.ops.anatomesh.import_scan(filepath="seg.nii.gz", label_table="labels.json", extract=True)
    bpy.ops.anatomesh.smooth(iterations=20)
    bpy.ops.anatomesh.export(directory="/tmp/out", format="STL")

Errors caused by the input (a bad file, a missing label) are reported as ``ERROR`` and the
operator returns ``{'CANCELLED'}``; no exception escapes into Blender.
"""
from . import decimate, export, paint, printing, recipe, scan, smooth, view
from . import web
from . import preprocess

CLASSES = (scan.ANATOMESH_OT_import_scan, scan.ANATOMESH_OT_extract, scan.ANATOMESH_OT_labels_select,
           scan.ANATOMESH_OT_level_add, scan.ANATOMESH_OT_level_remove, smooth.ANATOMESH_OT_smooth,
           paint.ANATOMESH_OT_paint, decimate.ANATOMESH_OT_decimate_preview,
           decimate.ANATOMESH_OT_decimate_apply, printing.ANATOMESH_OT_print_check,
           printing.ANATOMESH_OT_print_select_problem, export.ANATOMESH_OT_export,
           recipe.ANATOMESH_OT_recipe_save, recipe.ANATOMESH_OT_recipe_load, view.ANATOMESH_OT_frame_camera)
# the web page and distance colours
CLASSES += (web.ANATOMESH_OT_export_web, web.ANATOMESH_OT_paint_margins)
CLASSES = CLASSES + preprocess.CLASSES
from . import fit  # cut to fit
CLASSES = CLASSES + (fit.ANATOMESH_OT_print_fit,)
# print tools
from . import print_tools  # noqa: E402
CLASSES = CLASSES + print_tools.CLASSES
# edit-mode tools
from . import edit_tools  # noqa: E402
CLASSES = CLASSES + edit_tools.CLASSES
