"""Look operators: a structure's tissue class, and the scan's light preset."""
from __future__ import annotations

import bpy
from bpy.props import EnumProperty, StringProperty

from ..scene import lights, materials
from ..scene import objects as scene
from .common import active_scan, guarded
from .recipe import scene_recipe


class ANATOMESH_OT_set_tissue(bpy.types.Operator):
    """Draw the selected surfaces (or the active one) as this tissue class: their material uses the
    class's shared node group ('Anatomesh <Class>'), with each surface's own colour"""

    bl_idname = "anatomesh.set_tissue"
    bl_label = "Tissue"
    bl_options = {"REGISTER", "UNDO"}

    tissue: EnumProperty(name="Tissue", items=materials.TISSUE_ITEMS, default="other")

    @guarded
    def execute(self, context):
        from ...core.model.errors import AnatomeshError

        chosen = [o for o in context.selected_objects if "anatomesh_value" in o]
        active = context.active_object
        if not chosen and active is not None and "anatomesh_value" in active:
            chosen = [active]
        if not chosen:
            raise AnatomeshError("no Anatomesh surface selected: select the structures to change")
        n = materials.set_tissue(chosen, self.tissue)
        self.report({"INFO"}, f"{n} surface(s) drawn as {self.tissue}")
        return {"FINISHED"}


class ANATOMESH_OT_apply_lights(bpy.types.Operator):
    """Light the scan with a preset, placed from the scene camera: studio (key, fill and rim area
    lights, dark backdrop) or atlas (bright even light, light backdrop); replaces the lights the
    add-on made before"""

    bl_idname = "anatomesh.apply_lights"
    bl_label = "Apply Lights"
    bl_options = {"REGISTER", "UNDO"}

    collection: StringProperty(name="Scan", description="Scan collection (default: the active scan)")
    preset: EnumProperty(name="Light", items=(("SETTINGS", "As set", "The Settings panel's light"),)
                         + tuple((p.upper(), p.capitalize(), "") for p in lights.PRESETS),
                         default="SETTINGS")

    @guarded
    def execute(self, context):
        from ...core.model.errors import AnatomeshError

        coll = bpy.data.collections.get(self.collection) if self.collection else active_scan(context)
        if coll is None:
            raise AnatomeshError("no scan collection to light: extract surfaces first")
        preset = scene_recipe(context.scene).light if self.preset == "SETTINGS" else self.preset.lower()
        made = lights.apply_lights(context.scene, scene.surface_objects(coll), preset)
        self.report({"INFO"}, f"{preset}: {len(made)} lights")
        return {"FINISHED"}


CLASSES = (ANATOMESH_OT_set_tissue, ANATOMESH_OT_apply_lights)
