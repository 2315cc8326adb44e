"""The Print panel's helpers: which objects to check, the report's problems as list rows, framing
a problem's location in the view."""
from __future__ import annotations

from typing import Dict, List




#: how close a framed problem is shown (view distance, mm)
FRAME_DISTANCE_MM = 60.0
#: the list's wording of the kinds of thin features (core.printing.features)
THIN_KINDS = {"sheet": "thin sheet", "rod": "thin rod", "edge": "sharp edge"}


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
            kind = THIN_KINDS.get(r.get("kind"), "thin wall")
            kind += " (at a seam)" if r.get("seam_backed") else ""
            rows.append(dict(part=name, kind=kind, value=float(r.get("thickness_mm", r["min_mm"])),
                             unit="mm", location=r["location"]))
    for c in report.get("intersections", []):
        rows.append(dict(part=c["a"], other=c["b"], kind="parts cross", value=float(c["faces_a"]),
                         unit="faces", location=c["location"]))
    for g in report["gaps"]:
        if g["fuses"] and not g.get("intersecting"):
            rows.append(dict(part=g["a"], other=g["b"], kind="gap below minimum",
                             value=float(g["clearance_mm"] or 0.0), unit="mm",
                             location=g.get("clearance_location", g["location"])))
    return rows


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
