"""Anatomesh add-on: Edit Mode print tools on the edited mesh (:mod:`anatomesh.addon.operators.edit_tools`).

* ``anatomesh.edit_select_problem`` — select the non-manifold edges, boundary edges,
  self-intersecting faces or thin faces (thinner than the Print panel's minimum wall);
* ``anatomesh.edit_fill_holes`` — fill holes of up to N edges (triangulated);
* ``anatomesh.edit_remove_tiny`` — delete loose parts under a volume (mm³);
* ``anatomesh.edit_relax`` — smooth the selected vertices, none farther than a maximum deviation.

Each runs in Edit Mode on the active mesh, reports what it did, and can be undone.
"""
from __future__ import annotations

import bmesh
from bpy.props import EnumProperty, FloatProperty, IntProperty
from bpy.types import Operator

from . import edit_tools
from . import warmup
from .common import guarded


def _matrix(context):
    """The edited object's transform (measures in world mm)."""
    return [list(r) for r in context.active_object.matrix_world]


class _EditBase:
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        obj = context.active_object
        return obj is not None and obj.type == "MESH" and context.mode == "EDIT_MESH"

    def done(self, context, text: str):
        bmesh.update_edit_mesh(context.active_object.data)
        self.report({"INFO"}, text)
        return {"FINISHED"}


class ANATOMESH_OT_edit_select_problem(_EditBase, Operator):
    """Select the elements of a print problem of the edited mesh"""

    bl_idname = "anatomesh.edit_select_problem"
    bl_label = "Select Problem"

    kind: EnumProperty(name="Problem", items=edit_tools.PROBLEM_ITEMS, default="NON_MANIFOLD")

    @guarded
    def execute(self, context):
        bm = bmesh.from_edit_mesh(context.active_object.data)
        domain, idx = edit_tools.problem_elements(bm, self.kind, context.scene.anatomesh_print.min_wall,
                                                  _matrix(context))
        context.tool_settings.mesh_select_mode = (False, domain == "EDGE", domain == "FACE")
        bm.select_mode = {domain}
        edit_tools.select_elements(bm, domain, idx)
        label = dict((k, n) for k, n, _ in edit_tools.PROBLEM_ITEMS)[self.kind]
        return self.done(context, f"{len(idx)} {label.lower()}" if idx else f"No {label.lower()}")


class ANATOMESH_OT_edit_fill_holes(_EditBase, Operator):
    """Fill the holes of the edited mesh whose rim has at most this many edges"""

    bl_idname = "anatomesh.edit_fill_holes"
    bl_label = "Fill Holes"

    max_edges: IntProperty(name="Max Edges", default=30, min=3, soft_max=500,
                           description="Largest hole to fill, in edges around it")

    @guarded
    def execute(self, context):
        bm = bmesh.from_edit_mesh(context.active_object.data)
        r = edit_tools.fill_holes(bm, self.max_edges)
        more = f", {r['left_open']} left open" if r["left_open"] else ""
        return self.done(context, f"{r['filled']} hole(s) filled ({r['added_faces']} faces){more}")


class ANATOMESH_OT_edit_remove_tiny(_EditBase, Operator):
    """Delete the loose parts of the edited mesh that enclose less than this volume"""

    bl_idname = "anatomesh.edit_remove_tiny"
    bl_label = "Remove Tiny Shells"

    min_volume: FloatProperty(name="Min Volume", default=1.0, min=0.0, soft_max=1000.0,
                              description="Loose parts enclosing less than this are deleted, mm³")

    @guarded
    def execute(self, context):
        bm = bmesh.from_edit_mesh(context.active_object.data)
        r = edit_tools.remove_tiny_shells(bm, self.min_volume, _matrix(context))
        vols = ", ".join(f"{x:g}" for x in r["volumes_mm3"][:5])
        return self.done(context, f"{r['removed']} tiny shell(s) removed" + (f" ({vols} mm³)" if vols else ""))


class ANATOMESH_OT_edit_relax(_EditBase, Operator):
    """Smooth the selected vertices (Laplacian), the others locked, none moving farther than the maximum deviation"""

    bl_idname = "anatomesh.edit_relax"
    bl_label = "Relax Selection"

    max_deviation: FloatProperty(name="Max Deviation", default=0.5, min=0.0, soft_max=5.0, unit="LENGTH",
                                 description="No vertex moves farther than this, mm")
    iterations: IntProperty(name="Iterations", default=10, min=1, soft_max=100)

    @guarded
    def execute(self, context):
        if warmup.defer(self, "smoothing"):  # first run: again when its kernels are compiled
            return {"FINISHED"}
        bm = bmesh.from_edit_mesh(context.active_object.data)
        r = edit_tools.relax_selected(bm, self.max_deviation, self.iterations, _matrix(context))
        return self.done(context, f"{r['moved']} vertices relaxed, at most {r['max_moved_mm']:g} mm")


CLASSES = (ANATOMESH_OT_edit_select_problem, ANATOMESH_OT_edit_fill_holes, ANATOMESH_OT_edit_remove_tiny,
           ANATOMESH_OT_edit_relax)
