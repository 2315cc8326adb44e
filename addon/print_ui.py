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

from typing import Dict, List

import bpy
from bpy.props import (BoolProperty, CollectionProperty, EnumProperty, FloatProperty,
                       FloatVectorProperty, IntProperty, PointerProperty, StringProperty)
from bpy.types import Operator, Panel, PropertyGroup, UIList

from . import bridge
from .operators import ProgressReporter, guarded
from .panels import _Base

#: how close a framed problem is shown (view distance, mm)
FRAME_DISTANCE_MM = 60.0


def _profile_changed(self, context):
    from ..core.printing.profiles import PROFILES

    prof = PROFILES[self.profile.lower()]
    self.min_wall, self.min_gap = prof["min_wall"], prof["min_gap"]


class ANATOMESH_PG_print_problem(PropertyGroup):
    part: StringProperty(name="Part", description="Object the problem is on")
    other: StringProperty(name="Other Part", description="The other object of a gap or crossing")
    kind: StringProperty(name="Problem")
    value: FloatProperty(name="Value", description="Thinnest wall, gap (mm) or count")
    unit: StringProperty(name="Unit", default="mm")
    location: FloatVectorProperty(name="Location", size=3, subtype="XYZ", unit="LENGTH")


class ANATOMESH_PG_print(PropertyGroup):
    profile: EnumProperty(name="Printer", items=[
        ("FDM", "FDM (0.4 mm nozzle)", "Filament printer: min wall 0.8 mm, min gap 0.5 mm"),
        ("RESIN", "Resin", "Resin printer: min wall 0.4 mm, min gap 0.2 mm"),
    ], default="FDM", update=_profile_changed)
    min_wall: FloatProperty(name="Min Wall", default=0.8, min=0.01, soft_max=5.0, unit="LENGTH",
                            description="Thinnest wall the printer makes (mm)")
    min_gap: FloatProperty(name="Min Gap", default=0.5, min=0.0, soft_max=5.0, unit="LENGTH",
                           description="Narrowest gap between parts that stays open (mm)")
    selected_only: BoolProperty(name="Selected Only", default=False,
                                description="Check the selected objects instead of all Anatomesh objects")
    problems: CollectionProperty(type=ANATOMESH_PG_print_problem)
    problem_index: IntProperty(name="Problem", default=0)
    checked: BoolProperty(default=False)
    passed: BoolProperty(default=False)
    summary: StringProperty(name="Summary")


def print_objects(context, selected_only: bool) -> list:
    """The Anatomesh surface objects to check: the selected ones, or all in the file's scene."""
    pool = context.selected_objects if selected_only else context.scene.objects
    return [o for o in pool if o.type == "MESH" and "anatomesh_value" in o and len(o.data.polygons)]


def problems_of(report: Dict) -> List[Dict]:
    """Rows ``{part, other, kind, value, unit, location}`` from a check_parts report."""
    rows = []
    for p in report["parts"]:
        name = p["name"]
        loc = [0.0, 0.0, 0.0]
        if not p["closed"]:
            rows.append(dict(part=name, kind="not closed", value=0.0, unit="", location=loc))
        if not p["manifold"]:
            rows.append(dict(part=name, kind="not manifold", value=0.0, unit="", location=loc))
        if p["self_intersections"]:
            rows.append(dict(part=name, kind="self-intersecting faces",
                             value=float(p["self_intersections"]), unit="faces", location=loc))
        for s in p.get("tiny_shells", []):
            rows.append(dict(part=name, kind="tiny shell", value=float(s["volume_mm3"]), unit="mm³",
                             location=s["location"]))
        for r in p.get("thin_regions", []):
            kind = "thin wall (at a seam)" if r.get("seam_backed") else "thin wall"
            rows.append(dict(part=name, kind=kind, value=float(r["min_mm"]), unit="mm",
                             location=r["min_location"]))
    for c in report.get("intersections", []):
        rows.append(dict(part=c["a"], other=c["b"], kind="parts cross", value=float(c["faces_a"]),
                         unit="faces", location=c["location"]))
    for g in report["gaps"]:
        if g["fuses"] and not g.get("intersecting"):
            rows.append(dict(part=g["a"], other=g["b"], kind="gap below minimum",
                             value=float(g["clearance_mm"] or 0.0), unit="mm",
                             location=g.get("clearance_location", g["location"])))
    return rows


class ANATOMESH_OT_print_check(Operator):
    """Check all Anatomesh objects (or the selection) together for 3D printing: solid, wall thickness, gaps"""

    bl_idname = "anatomesh.print_check"
    bl_label = "Check for Printing"
    bl_options = {"REGISTER"}

    @guarded
    def execute(self, context):
        from ..core.model.mesh import Mesh
        from ..core.printing.checks import check_parts

        s = context.scene.anatomesh_print
        objs = print_objects(context, s.selected_only)
        if not objs:
            self.report({"WARNING"}, "No Anatomesh surfaces to check" +
                        (" among the selected objects" if s.selected_only else ""))
            return {"CANCELLED"}
        meshes = []
        for o in objs:
            v, f = bridge.world_arrays(o, context.evaluated_depsgraph_get())
            meshes.append(Mesh(v, f, name=o.name))
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


def frame_location(context, location, distance: float = FRAME_DISTANCE_MM) -> int:
    """Centre every 3D view on ``location`` at ``distance`` mm; returns how many views."""
    n = 0
    wm = context.window_manager
    for window in (wm.windows if wm else []):
        for area in window.screen.areas:
            if area.type != "VIEW_3D":
                continue
            for space in area.spaces:
                if space.type == "VIEW_3D" and space.region_3d is not None:
                    space.region_3d.view_location = location
                    space.region_3d.view_distance = distance
                    n += 1
    return n


class ANATOMESH_UL_print_problems(UIList):
    bl_idname = "ANATOMESH_UL_print_problems"

    def draw_item(self, context, layout, data, item, icon, active_data, active_propname, index=0):
        row = layout.row(align=True)
        row.label(text=item.part + (f" – {item.other}" if item.other else ""), icon="ERROR")
        row.label(text=item.kind)
        unit = f" {item.unit}" if item.unit else ""
        row.label(text=f"{item.value:.2f}{unit}" if item.unit == "mm" else
                  (f"{item.value:g}{unit}" if unit else ""))
        op = row.operator("anatomesh.print_select_problem", text="", icon="VIEWZOOM")
        op.index = index


class ANATOMESH_PT_print(_Base, Panel):
    bl_label = "Print"
    bl_idname = "ANATOMESH_PT_print"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        s = context.scene.anatomesh_print
        col = self.layout.column(align=True)
        col.prop(s, "profile", text="")
        col.prop(s, "min_wall")
        col.prop(s, "min_gap")
        col.prop(s, "selected_only")
        self.layout.operator("anatomesh.print_check", icon="CHECKMARK")
        if s.checked:
            self.layout.label(text=s.summary, icon="CHECKMARK" if s.passed else "ERROR")
        if len(s.problems):
            self.layout.template_list("ANATOMESH_UL_print_problems", "", s, "problems", s,
                                      "problem_index", rows=4)
        row = self.layout.row(align=True)
        op = row.operator("anatomesh.paint", text="Thickness", icon="MOD_SOLIDIFY")
        op.mode = "THICKNESS"
        op.min_wall = s.min_wall
        op = row.operator("anatomesh.paint", text="Gaps", icon="MOD_LENGTH")
        op.mode = "GAP"


CLASSES = (ANATOMESH_PG_print_problem, ANATOMESH_PG_print, ANATOMESH_OT_print_check,
           ANATOMESH_OT_print_select_problem, ANATOMESH_UL_print_problems, ANATOMESH_PT_print)


def register() -> None:
    """Register properties this module owns (classes are registered from CLASSES by the package)."""
    bpy.types.Scene.anatomesh_print = PointerProperty(type=ANATOMESH_PG_print)


def unregister() -> None:
    """Remove what :func:`register` added."""
    if hasattr(bpy.types.Scene, "anatomesh_print"):
        del bpy.types.Scene.anatomesh_print
