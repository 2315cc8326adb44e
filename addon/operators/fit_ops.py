"""Cut to Fit: the Print panel's button. Every Anatomesh surface (or the selected ones)
too big for the printer's build volume is cut into closed pieces that fit
(:func:`anatomesh.app.flow.fit.fit_parts`, the same function as ``anatomesh mesh --fit``), optionally
with pins and pockets across the cuts. The pieces ``<part>_1``, ``<part>_2``, ... join the part's
collections with its material and properties (``anatomesh_fit_of`` names the part); the part is
hidden, not deleted (Undo, or unhide it, to go back)."""
from __future__ import annotations

import bpy
from bpy.props import BoolProperty, FloatVectorProperty

from ..scene import bridge
from . import warmup
from ..scene import objects as scene
from .common import ProgressReporter, guarded
from .print_check import print_objects


class ANATOMESH_OT_print_fit(bpy.types.Operator):
    """Cut the Anatomesh surfaces (or the selected ones) that are too big for the printer into
    closed pieces that fit its build volume, with optional pins and pockets across the cuts"""

    bl_idname = "anatomesh.print_fit"
    bl_label = "Cut to Fit"
    bl_options = {"REGISTER", "UNDO"}

    size: FloatVectorProperty(name="Build Volume", size=3, default=(180.0, 180.0, 180.0), min=1.0,
                              soft_max=1000.0, unit="LENGTH", description="The printer's build volume X, Y, Z (mm)")
    connectors: BoolProperty(name="Pins", default=False,
                             description="Pins on one piece and pockets in the other across each cut")

    @guarded
    def execute(self, context):
        from ...app.flow.fit import PART_INDEX, fit_parts, summary
        from ...core.model.mesh import Mesh

        s = context.scene.anatomesh_print
        objs = print_objects(context, s.selected_only)
        if not objs:
            self.report({"WARNING"}, "No Anatomesh surfaces to cut")
            return {"CANCELLED"}
        if warmup.defer(self, warmup.FIXES_STEP):  # first run: again when the kernels are compiled
            return {"FINISHED"}
        meshes = [Mesh(v, f, name=o.name) for o, (v, f) in zip(objs, bridge.shapes(context, objs))]
        with ProgressReporter(context, "cut to fit") as progress:
            pieces, fixes = fit_parts(meshes, tuple(self.size), self.connectors, s.profile.lower(),
                                      s.min_wall, progress)
        cut = 0
        for k, obj in enumerate(objs):
            mine = [p for p in pieces if p.meta[PART_INDEX] == k]
            if len(mine) > 1:
                _replace(obj, mine)
                cut += 1
        for info in fixes:
            self.report({"INFO"}, summary(info))
        self.report({"INFO"}, f"{cut} of {len(objs)} part(s) cut to fit "
                              f"{' x '.join(f'{x:g}' for x in self.size)} mm")
        return {"FINISHED"}


def _replace(obj, pieces) -> None:
    """Piece objects beside ``obj`` (its collections, material, properties); ``obj`` hidden."""
    props = {k: obj[k] for k in obj.keys() if k.startswith("anatomesh_") and k != "anatomesh_fit_of"}
    colls = list(obj.users_collection)
    for p in pieces:
        new = scene.add_surface(colls[0], p.name, p.vertices, p.faces, props)
        new.data.materials.clear()
        if obj.active_material is not None:
            new.data.materials.append(obj.active_material)
        new.color = obj.color
        new["anatomesh_fit_of"] = obj.name
        for c in colls[1:]:
            c.objects.link(new)
    obj.hide_set(True)
    obj.hide_render = True
