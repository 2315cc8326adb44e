"""Blender tests: select exactly these objects, the first one active (as a user clicks them)."""
import bpy


def select_only(*objs):
    for o in bpy.context.view_layer.objects:
        o.select_set(False)
    for o in objs:
        o.select_set(True)
    bpy.context.view_layer.objects.active = objs[0]
