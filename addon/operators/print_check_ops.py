"""Anatomesh add-on: the Print panel: check all Anatomesh objects at once, list problems,
select/frame them, heat maps.

* Settings (``Scene.anatomesh_print``): printer profile (FDM / resin, from
  :data:`anatomesh.core.printing.profiles.PROFILES`), minimum wall and minimum gap in mm (choosing a
  profile fills in its values; both stay editable), and whether to check the selection only.
* ``anatomesh.print_check`` runs :func:`anatomesh.core.printing.checks.check_parts` on every Anatomesh
  surface object of the file (or the selected ones) together, in world coordinates (mm), and
  stores one row per problem (part, kind, value, location) in ``Scene.anatomesh_print.problems``:
  open or non-manifold surfaces, self-intersections, tiny shells, thin regions (thinnest value
  and where), parts crossing each other and pairs closer than the minimum gap.
* ``anatomesh.print_select_problem`` selects the problem's object, puts the 3D cursor on its
  location and frames it in every 3D view.
* The panel lists the problems (a UIList) and paints thickness and gap heat maps
  (``anatomesh.paint``).
"""
from __future__ import annotations


from bpy.props import (IntProperty)
from bpy.types import Operator

from ..scene import bridge
from . import warmup
from .common import ProgressReporter, guarded
from .print_check import frame_location, print_objects, problems_of


class ANATOMESH_OT_print_check(Operator):
    """Check all Anatomesh objects (or the selection) together for 3D printing: solid, wall thickness, gaps"""

    bl_idname = "anatomesh.print_check"
    bl_label = "Check for Printing"
    bl_options = {"REGISTER"}

    @guarded
    def execute(self, context):
        from ...core.model.mesh import Mesh
        from ...core.printing.checks import check_parts

        s = context.scene.anatomesh_print
        objs = print_objects(context, s.selected_only)
        if not objs:
            self.report({"WARNING"}, "No Anatomesh surfaces to check" +
                        (" among the selected objects" if s.selected_only else ""))
            return {"CANCELLED"}
        if warmup.defer(self, warmup.FIXES_STEP):  # first run: again when its kernels are compiled
            return {"FINISHED"}
        meshes = [Mesh(v, f, name=o.name) for o, (v, f) in zip(objs, bridge.shapes(context, objs))]
        prof = {"name": s.profile.lower(), "min_wall": s.min_wall, "min_gap": s.min_gap}
        with ProgressReporter(context, "print check") as progress:
            rep = check_parts(meshes, prof, progress=progress)
        s.problems.clear()
        for row in problems_of(rep):
            item = s.problems.add()
            item.part, item.other = row["part"], row.get("other", "")
            item.kind, item.value, item.unit = row["kind"], row["value"], row["unit"]
            item.location = row["location"]
        s.problem_index = 0
        s.checked, s.passed = True, bool(rep["passed"])
        n_ok = sum(p["passed"] for p in rep["parts"])
        s.summary = (f"{'Passed' if rep['passed'] else 'Failed'}: {n_ok}/{len(objs)} parts ok, "
                     f"{len(s.problems)} problem(s)")
        for o, p in zip(objs, rep["parts"]):
            o["anatomesh_min_wall_mm"] = -1.0 if p["min_wall_mm"] is None else float(p["min_wall_mm"])
            o["anatomesh_print_passed"] = int(bool(p["passed"]))
        self.report({"INFO"} if rep["passed"] else {"WARNING"}, s.summary)
        return {"FINISHED"}


class ANATOMESH_OT_print_select_problem(Operator):
    """Select the object of a print problem and frame its location"""

    bl_idname = "anatomesh.print_select_problem"
    bl_label = "Show Problem"
    bl_options = {"REGISTER", "UNDO"}

    index: IntProperty(name="Problem", default=-1, description="Row in the problem list (-1: the active row)")

    @guarded
    def execute(self, context):
        s = context.scene.anatomesh_print
        i = s.problem_index if self.index < 0 else self.index
        if not 0 <= i < len(s.problems):
            self.report({"WARNING"}, "No such problem: run the print check first")
            return {"CANCELLED"}
        s.problem_index = i
        prob = s.problems[i]
        obj = context.scene.objects.get(prob.part)
        if obj is None:
            self.report({"WARNING"}, f"{prob.part} is not in the scene any more: check again")
            return {"CANCELLED"}
        for o in context.selected_objects:
            o.select_set(False)
        obj.hide_set(False)
        obj.select_set(True)
        context.view_layer.objects.active = obj
        other = context.scene.objects.get(prob.other) if prob.other else None
        if other is not None:
            other.hide_set(False)
            other.select_set(True)
        loc = tuple(prob.location)
        context.scene.cursor.location = loc
        frame_location(context, loc)
        return {"FINISHED"}
