"""Anatomesh add-on: the Print panel's tools, the command line's print fixes as buttons.

* ``anatomesh.print_fuse`` — the selected surfaces (or ``labels``) become one solid: the labels are
  merged in the label map and the scan is extracted and smoothed again (``anatomesh mesh --fuse``);
* ``anatomesh.print_thicken`` — parts thinner than the minimum wall grow in the label map, the
  scan is extracted again (``--thicken``);
* ``anatomesh.print_clearance`` — touching surfaces of the scan are pulled apart by a clearance
  in mm (``--clearance``);
* ``anatomesh.print_hollow`` — the selected surfaces are hollowed to a wall with drain holes
  (``--hollow``, ``--drain-holes``, ``--drain-diameter``);
* ``anatomesh.print_connectors`` — pins on the active surface and pockets in the other selected
  one (``--connectors A,B``).

Each reports what it did (``self.report``) and appends the report's ``fixes`` entry to the
objects' ``anatomesh_fixes`` property; all can be undone.
"""
from __future__ import annotations

from bpy.props import BoolProperty, FloatProperty, IntProperty, StringProperty
from bpy.types import Operator

from . import print_parts as print_tools
from . import warmup
from .common import ProgressReporter, active_scan, guarded, parse_list
from .print_check import print_objects



def _profile(context):
    s = context.scene.anatomesh_print
    return s.profile.lower(), s.min_wall


def _selected_labels(context):
    """The selected surfaces' label values: the active one first (its value, name first and
    colour are kept, as the first label of ``--fuse``), then by value."""
    objs = print_objects(context, True)
    act = context.active_object
    first = [int(act["anatomesh_value"])] if act in objs else []
    return first + sorted({int(o["anatomesh_value"]) for o in objs} - set(first))


def _scan_or_fail(context):
    coll = active_scan(context)
    if coll is None:
        from ...core.model.errors import AnatomeshError

        raise AnatomeshError("no extracted scan: extract surfaces first (Labels panel)")
    return coll


class ANATOMESH_OT_print_fuse(Operator):
    """Print the selected surfaces as one solid (the active one's name first and colour): merge their labels in the label map and extract the scan again"""

    bl_idname = "anatomesh.print_fuse"
    bl_label = "Fuse"
    bl_options = {"REGISTER", "UNDO"}

    labels: StringProperty(name="Labels", description="Labels to fuse (values or names, commas); "
                                                      "empty: the selected surfaces")

    @guarded
    def execute(self, context):
        coll = _scan_or_fail(context)
        group = parse_list(self.labels) if self.labels.strip() else _selected_labels(context)
        if len(group) < 2:
            self.report({"WARNING"}, "Fuse: select two or more surfaces of the scan (or give labels)")
            return {"CANCELLED"}
        self.labels = ",".join(str(x) for x in group)  # a deferred run fuses these, whatever is selected then
        if warmup.defer(self, "smoothing"):  # speed (first run): again when the kernels are ready
            return {"FINISHED"}
        profile, wall = _profile(context)
        with ProgressReporter(context, "fusing") as progress:
            new, fixes = print_tools.reextract_fixed(context, coll, fuse=[group], profile=profile,
                                                     min_wall=wall, progress=progress)
        fix = fixes[0]
        self.report({"INFO"}, f"Fused {fix['name']}: {fix['voxels']:,} voxels; {len(new.all_objects)} "
                              f"surfaces in '{new.name}'")
        return {"FINISHED"}


class ANATOMESH_OT_print_thicken(Operator):
    """Grow the scan's parts where they are thinner than the minimum wall (in the label map) and extract again"""

    bl_idname = "anatomesh.print_thicken"
    bl_label = "Thicken"
    bl_options = {"REGISTER", "UNDO"}

    @guarded
    def execute(self, context):
        coll = _scan_or_fail(context)
        if warmup.defer(self, "smoothing"):  # speed (first run): again when the kernels are ready
            return {"FINISHED"}
        profile, wall = _profile(context)
        with ProgressReporter(context, "thickening") as progress:
            new, fixes = print_tools.reextract_fixed(context, coll, thicken=True, profile=profile,
                                                     min_wall=wall, progress=progress)
        fix = fixes[-1]
        grown = sum(int(v) for v in fix["labels"].values())
        self.report({"INFO"}, f"Thickened to {fix['min_wall_mm']:g} mm: {grown:,} voxels added; "
                              f"'{new.name}' extracted again")
        return {"FINISHED"}


class ANATOMESH_OT_print_clearance(Operator):
    """Pull touching surfaces of the scan apart along their shared interfaces, so printed parts fit together"""

    bl_idname = "anatomesh.print_clearance"
    bl_label = "Clearance"
    bl_options = {"REGISTER", "UNDO"}

    clearance: FloatProperty(name="Clearance", default=0.2, min=0.001, soft_max=2.0, unit="LENGTH",
                             description="Gap between the parts afterwards, mm")
    selected_only: BoolProperty(name="Selected Only", default=False,
                                description="Only the selected surfaces (else every surface of the scan)")

    @guarded
    def execute(self, context):
        from ..scene import objects as scene

        objs = print_objects(context, True) if self.selected_only else \
            scene.surface_objects(_scan_or_fail(context))
        if warmup.defer(self, warmup.FIXES_STEP):
            return {"FINISHED"}
        entry = print_tools.separate_objects(objs, self.clearance)
        self.report({"INFO"}, f"Clearance {self.clearance:g} mm: {entry['moved_vertices']:,} vertices moved, "
                              f"{len(entry['pairs'])} pair(s) apart")
        return {"FINISHED"}


class ANATOMESH_OT_print_hollow(Operator):
    """Hollow the selected surfaces to a wall of this thickness, with drain holes at their lowest points"""

    bl_idname = "anatomesh.print_hollow"
    bl_label = "Hollow"
    bl_options = {"REGISTER", "UNDO"}

    wall: FloatProperty(name="Wall", default=2.0, min=0.1, soft_max=10.0, unit="LENGTH",
                        description="Wall thickness left, mm")
    drain_holes: IntProperty(name="Drain Holes", default=2, min=0, max=16,
                             description="Holes per cavity, at its lowest points along +z")
    drain_diameter: FloatProperty(name="Drain Diameter", default=0.0, min=0.0, soft_max=10.0,
                                  unit="LENGTH", description="Hole diameter, mm (0: the printer profile's)")

    @guarded
    def execute(self, context):
        objs = print_objects(context, True)
        if not objs:
            self.report({"WARNING"}, "Hollow: select the surfaces to hollow")
            return {"CANCELLED"}
        if warmup.defer(self, warmup.FIXES_STEP):
            return {"FINISHED"}
        profile, _ = _profile(context)
        lines = []
        with ProgressReporter(context, "hollowing") as progress:
            for k, o in enumerate(objs):
                progress(k / len(objs), o.name)
                e = print_tools.hollow_object(o, self.wall, self.drain_holes, self.drain_diameter or None,
                                              profile)
                lines.append(f"{o.name}: {e['saved_pct']:g} % saved ({e['saved_mm3'] / 1000:.1f} cm³), "
                             f"{len(e['drain_holes'])} drain hole(s)")
        self.report({"INFO"}, "; ".join(lines))
        return {"FINISHED"}


class ANATOMESH_OT_print_connectors(Operator):
    """Pins on the active surface and matching pockets in the other selected one, across their shared interface"""

    bl_idname = "anatomesh.print_connectors"
    bl_label = "Connectors"
    bl_options = {"REGISTER", "UNDO"}

    @guarded
    def execute(self, context):
        objs = print_objects(context, True)
        active = context.active_object
        if len(objs) != 2:
            self.report({"WARNING"}, "Connectors: select exactly two touching surfaces (pins go on the active one)")
            return {"CANCELLED"}
        a = active if active in objs else objs[0]
        b = objs[1] if a is objs[0] else objs[0]
        if warmup.defer(self, warmup.FIXES_STEP):
            return {"FINISHED"}
        profile, wall = _profile(context)
        e = print_tools.connect_objects(a, b, profile, wall)
        pins = ", ".join(f"{p['diameter_mm']:g} mm" for p in e["pins"])
        self.report({"INFO"}, f"{len(e['pins'])} pin(s) on {a.name} ({pins}), pockets in {b.name}")
        return {"FINISHED"}


CLASSES = (ANATOMESH_OT_print_fuse, ANATOMESH_OT_print_thicken, ANATOMESH_OT_print_clearance,
           ANATOMESH_OT_print_hollow, ANATOMESH_OT_print_connectors)
