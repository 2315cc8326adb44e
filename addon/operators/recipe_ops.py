"""Anatomesh add-on: save/load the current settings as a recipe TOML file (the same file
``anatomesh mesh --recipe`` reads, see :mod:`anatomesh.app.flow.recipe`).

* ``anatomesh.recipe_save``: the scene's Anatomesh settings (scan, label ticks or isovalues,
  smoothing of the active scan or the defaults, the Decimate panel's target when the active scan
  was decimated, the Print panel's printer when its check was run, export folder and format) →
  a recipe file.
* ``anatomesh.recipe_load``: a recipe file → those settings (a decimation target goes into the
  Decimate panel, the print check's printer into the Print panel); the scan is read so the label list shows the recipe's choice (and, with
  ``extract``, the surfaces are made at once).

Paths in a saved recipe are relative to the recipe's folder when they share one.
"""

import os

from bpy.props import BoolProperty, StringProperty
from bpy.types import Operator
from bpy_extras.io_utils import ExportHelper, ImportHelper

from .common import abspath, guarded
from .recipe import apply_recipe, recipe_from_scene


# ---------------------------------------------------------------------------------------------
# settings ↔ Recipe
# ---------------------------------------------------------------------------------------------


# ---------------------------------------------------------------------------------------------
# operators and panel
# ---------------------------------------------------------------------------------------------
class ANATOMESH_OT_recipe_save(Operator, ExportHelper):
    """Save the current Anatomesh settings as a recipe (TOML) for `anatomesh mesh --recipe`"""

    bl_idname = "anatomesh.recipe_save"
    bl_label = "Save Recipe"
    bl_options = {"REGISTER"}

    filename_ext = ".toml"
    filter_glob: StringProperty(default="*.toml", options={"HIDDEN"})
    filepath: StringProperty(name="File", subtype="FILE_PATH")

    @guarded
    def execute(self, context):
        from ...core.model.errors import AnatomeshError
        from ...app.flow.recipe import dump_recipe

        path = abspath(self.filepath)
        if not path:
            raise AnatomeshError("no recipe file chosen: pass filepath=")
        if not context.scene.anatomesh.filepath:
            raise AnatomeshError("no scan in the Import panel: read a scan before saving its recipe")
        text = dump_recipe(recipe_from_scene(context), base=os.path.dirname(path))
        os.makedirs(os.path.dirname(path) or ".", exist_ok=True)
        with open(path, "w", encoding="utf-8") as fh:
            fh.write(text)
        self.report({"INFO"}, f"Saved recipe {path}")
        return {"FINISHED"}


class ANATOMESH_OT_recipe_load(Operator, ImportHelper):
    """Load a recipe (TOML): scan, labels or isovalues, smoothing and export settings"""

    bl_idname = "anatomesh.recipe_load"
    bl_label = "Load Recipe"
    bl_options = {"REGISTER", "UNDO"}

    filter_glob: StringProperty(default="*.toml", options={"HIDDEN"})
    filepath: StringProperty(name="File", subtype="FILE_PATH")
    extract: BoolProperty(name="Extract now", default=False,
                          description="Create the recipe's surfaces right away")

    @guarded
    def execute(self, context):
        from ...app.flow.recipe import load_recipe

        recipe = load_recipe(abspath(self.filepath))
        apply_recipe(context, recipe, self.extract)
        self.report({"INFO"}, f"Loaded recipe {os.path.basename(self.filepath)}")
        return {"FINISHED"}
