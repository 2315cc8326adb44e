"""3D-print readiness of all parts together: :func:`check_parts` runs every check for a printer
profile and returns the report (like Blender's 3D Print Toolbox, but across parts, in mm, and
independent of the normals' quality). Units are mm, mm², mm³ throughout.

The checks, each a small function returning offending element indices and values:

* solid (:mod:`.solid`): closed, 2-manifold, consistently oriented
  (:func:`anatomesh.core.geometry.topology.topology`), self-intersections and parts crossing
  each other (Möller 1997, "A fast triangle-triangle intersection test", over a uniform grid),
  sliver faces (minimum angle), degenerate faces, tiny shells;
* wall thickness (:mod:`.thickness`) per vertex: a ray cast inwards cross-checked with the
  shrinking-ball inscribed sphere (Ma, Bae & Kobbelt 2012, "3D medial axis point approximation
  using nearest neighbors and the normal field") and the largest inscribed ball reaching the
  vertex (Hildebrand & Rüegsegger 1997, "A new method for the model-independent assessment of
  thickness in three-dimensional images"); thin vertices grouped into regions;
* gaps (:mod:`.gaps`): minimum distance between every pair of parts away from the seams they
  share (:mod:`.seams`: faces and vertices at identical positions are contact by design).

The printer profiles and limits are in :mod:`.profiles`.
"""
from __future__ import annotations

from typing import Dict, List, Optional, Sequence

import numpy as np

from ..geometry.intersections import crossing_pairs
from ..geometry.spatial import TriangleGrid
from ..geometry.topology import topology
from ..model.errors import AnatomeshError
from ..model.mesh import Mesh, check_arrays, degenerate_faces
from ..model.progress import Progress, report, sub
from .gaps import part_gaps
from .locate import location_text
from .profiles import DEGENERATE_AREA_MM2, GAP_REPORT_MM, resolve_profile
from .seams import seam_neighbourhoods
from .solid import sliver_faces, split_crossings, tiny_shells
from .features import thin_features
from .pinch import pinches
from .thickness import wall_thickness

#: at most this many thin regions are listed per part
_MAX_REGIONS = 50
#: check_parts measures walls up to this thickness (at least 5 x min_wall), mm
_THICK_CAP_MM = 5.0


def _round(x, nd=3):
    """``x`` rounded to ``nd`` decimals for the report; None when missing or not finite."""
    return None if x is None or not np.isfinite(x) else round(float(x), nd)


def check_parts(meshes: Sequence[Mesh], profile="fdm", min_wall: Optional[float] = None,
                min_gap: Optional[float] = None, progress: Optional[Progress] = None) -> Dict:
    """Run every print check on all parts together; returns the report dict.

    Parameters
    ----------
    meshes : sequence of :class:`~anatomesh.core.model.mesh.Mesh` (vertices mm)
    profile : "fdm" | "resin" | dict (see :data:`.profiles.PROFILES`); ``min_wall``/``min_gap``
        override it

    Returns
    -------
    dict with ``profile`` (limits used), ``parts`` (one dict per mesh: name, closed, manifold,
    oriented, self_intersections, degenerate_faces, sliver_faces, tiny_shells, min_wall_mm,
    thin_area_mm2, thin_regions [{location, area_mm2, min_mm}], passed), ``intersections``
    (pairs of parts crossing), ``gaps`` (pairs closer than :data:`.profiles.GAP_REPORT_MM`: a, b, touching,
    seam_area_mm2, min_gap_mm, clearance_mm, location, fuses) and ``passed``.
    """
    prof = resolve_profile(profile, min_wall, min_gap)
    meshes = list(meshes)
    for i, m in enumerate(meshes):
        if not isinstance(m, Mesh):
            raise AnatomeshError(f"check_parts takes Mesh objects; item {i} is {type(m).__name__}")
    parts = [check_arrays(m.vertices, m.faces) for m in meshes]
    names = [m.name or str(i) for i, m in enumerate(meshes)]
    report(progress, 0.0, "intersections")
    grids = [TriangleGrid(v, f) if len(f) else None for v, f in parts]
    self_pairs, cross = split_crossings(meshes, crossing_pairs(parts), grids)
    report(progress, 0.15, "parts")
    out_parts = []
    sp = sub(progress, 0.15, 0.8)
    near_seam = seam_neighbourhoods(parts)
    for i, ((v, f), name) in enumerate(zip(parts, names)):
        report(sp, i / max(len(parts), 1), f"wall thickness {name}")
        out_parts.append(_check_part(v, f, name, grids[i], prof, self_pairs[i], near_seam[i]))
    gaps = part_gaps(meshes, GAP_REPORT_MM, prof["min_gap"], grids=grids,
                     progress=sub(progress, 0.8, 1.0))
    inter = _add_crossings(cross, out_parts, gaps)
    for g in gaps:
        g["min_gap_mm"] = _round(g["min_gap_mm"])
        g["clearance_mm"] = _round(g["clearance_mm"])
        g.setdefault("intersecting", False)
    passed = all(p["passed"] for p in out_parts) and not inter and not any(g["fuses"] for g in gaps)
    report(progress, 1.0, "print checks done")
    return {"profile": prof, "parts": out_parts, "intersections": inter, "gaps": gaps,
            "passed": bool(passed)}


def _check_part(v, f, name, grid, prof, self_pairs, near_seam=None) -> Dict:
    """Checks of one part (the per-part entry of the report).

    Thin regions are judged by :func:`.features.thin_features`: a rim that reaches no farther
    than the profile's ``min_feature`` beyond the part's full-thickness body passes (counted
    under ``rims``); sheets, rods and sharp edges fail with a reason. Failing regions lying
    wholly on or next to a seam with another part (``near_seam``) — the creases where smoothed
    neighbours meet — are backed by that neighbour when the parts print together: they are
    listed with ``seam_backed`` but do not fail the part (separate the parts, e.g.
    ``--clearance``, and they count)."""
    if f.shape[0] == 0:
        return {"name": name, "closed": False, "manifold": True, "oriented": True, "faces": 0,
                "self_intersections": 0, "degenerate_faces": 0, "sliver_faces": 0,
                "tiny_shells": [], "min_wall_mm": None, "thin_area_mm2": 0.0, "thin_regions": [],
                "thin_region_count": 0, "reasons": ["no faces"], "part_intersections": 0,
                "passed": False}
    topo = topology(v, f)
    deg = degenerate_faces(v, f, DEGENERATE_AREA_MM2)
    sliv, _ = sliver_faces(v, f)
    shells = tiny_shells(v, f, prof["min_shell_mm3"])
    thick, det = wall_thickness(v, f, grid=grid, max_thickness=max(_THICK_CAP_MM, 5 * prof["min_wall"]),
                                oriented=bool(topo.closed and topo.manifold and topo.oriented),
                                return_details=True)
    regions = thin_features(v, f, thick, det, prof["min_wall"], prof["min_feature"], grid=grid)
    failing = np.zeros(len(v), bool)
    for r in regions:
        failing[r["vertices"]] |= r["fails"]
    regions += pinches(v, f, det, prof["min_wall"], prof["min_gap"], grid=grid, exclude=failing)
    for r in regions:
        r["seam_backed"] = bool(r["fails"] and near_seam is not None and near_seam[r["vertices"]].all())
    free = [r for r in regions if r["fails"] and not r["seam_backed"]]
    backed = [r for r in regions if r["seam_backed"]]
    rims = [r for r in regions if not r["fails"]]
    n_self = int(np.unique(self_pairs.ravel()).size)
    entry = {
        "name": name, "faces": int(f.shape[0]), "closed": bool(topo.closed),
        "manifold": bool(topo.manifold), "oriented": bool(topo.oriented),
        "components": int(topo.components), "genus": topo.genus,
        "self_intersections": n_self, "degenerate_faces": int(deg.size),
        "sliver_faces": int(sliv.size),
        "tiny_shells": [{"volume_mm3": round(s["volume_mm3"], 4), "faces": int(s["faces"].size),
                         "location": s["location"]} for s in shells],
        "min_wall_mm": _round(_min_wall(thick, rims + backed)),
        "thin_area_mm2": round(float(sum(r["area_mm2"] for r in free)), 3),
        "seam_backed_thin_area_mm2": round(float(sum(r["area_mm2"] for r in backed)), 3),
        "thin_regions": [_region_entry(r) for r in (free + backed)[:_MAX_REGIONS]],
        "thin_region_count": len(free),
        "rims": _rims_entry(rims),
        "warnings": [r["warning"] for r in rims if "warning" in r],
        "part_intersections": 0,
    }
    entry["reasons"] = _reasons(entry, topo, free, prof)
    entry["passed"] = not entry["reasons"]
    return entry


def _rims_entry(rims: List[Dict]) -> Dict:
    """The report's ``rims`` of a part: how many pass, their area and thinnest point, how many a
    printer blunts noticeably (``blunted``, each with a warning) and by how much at most."""
    warned = [r for r in rims if "warning" in r]
    return {"count": len(rims), "area_mm2": round(float(sum(r["area_mm2"] for r in rims)), 3),
            "min_mm": _round(min((r["min_mm"] for r in rims), default=None)),
            "blunted": len(warned), "max_cut_back_mm": _round(max((r["cut_back_mm"] for r in warned), default=None))}


def _min_wall(thick: np.ndarray, passing: List[Dict]) -> Optional[float]:
    """The thinnest wall outside the regions that pass (rims, seam-backed creases), mm."""
    t = np.asarray(thick, np.float64).copy()
    for r in passing:
        t[r["vertices"]] = np.nan
    return float(np.nanmin(t)) if np.any(np.isfinite(t)) else None


def _region_entry(r: Dict) -> Dict:
    """A thin region as listed in the report (JSON-ready)."""
    out = {"kind": r["kind"], "reason": r["reason"], "thickness_mm": round(float(r["thickness_mm"]), 3),
           **{k: round(float(x), 3) for k, x in r["extent"].items()},
           "location": r["location"], "area_mm2": round(r["area_mm2"], 3),
           "reach_area_mm2": round(r["reach_area_mm2"], 3), "min_mm": round(r["min_mm"], 3),
           "median_mm": round(r["median_mm"], 3), "min_location": r["min_location"],
           "vertices": int(r["vertices"].size), "seam_backed": r["seam_backed"]}
    if r["kind"] == "pinch":
        out["gap_mm"] = _round(r["gap_mm"])
    if "angle_deg" in r:
        out.update(angle_deg=r["angle_deg"], cut_back_mm=_round(r["cut_back_mm"]),
                   cut_back_location=r["cut_back_location"])
    return out


def _reasons(entry: Dict, topo, free: List[Dict], prof: Dict) -> List[str]:
    """Why a part fails, one line each (empty: it passes)."""
    out = []
    if not (topo.closed and topo.manifold and topo.oriented):
        what = [w for w, ok in (("open", topo.closed), ("not manifold", topo.manifold),
                                ("inconsistently oriented", topo.oriented)) if not ok]
        out.append("not a solid: " + ", ".join(what))
    if entry["self_intersections"]:
        out.append(f"{entry['self_intersections']} faces cross the part's own surface")
    if entry["degenerate_faces"]:
        out.append(f"{entry['degenerate_faces']} degenerate (zero-area) faces")
    for s in entry["tiny_shells"]:
        out.append(f"loose shell of {s['volume_mm3']:.2f} mm³ (< {prof['min_shell_mm3']:g} mm³) at "
                   + location_text(s['location']))
    out += [r["reason"] for r in free]
    return out


def _add_crossings(cross: List[Dict], out_parts: List[Dict], gaps: List[Dict]) -> List[Dict]:
    """Parts crossing each other (``cross`` of :func:`.solid.split_crossings`) fail both parts
    and fuse at gap 0: mark them in ``out_parts`` and ``gaps`` (in place; a pair the gap search
    did not list is added) and return the report's ``intersections`` entries."""
    inter = []
    for c in cross:
        inter.append({"a": c["a"], "b": c["b"], "faces_a": int(c["faces_a"].size),
                      "faces_b": int(c["faces_b"].size), "location": c["location"]})
        out_parts[c["ia"]]["part_intersections"] += 1
        out_parts[c["ib"]]["part_intersections"] += 1
        out_parts[c["ia"]]["passed"] = out_parts[c["ib"]]["passed"] = False
        for i, j in ((c["ia"], c["ib"]), (c["ib"], c["ia"])):
            out_parts[i]["reasons"].append(f"crosses {out_parts[j]['name']} at {c['location']}")
    known = {(g["ia"], g["ib"]) for g in gaps}
    for c in cross:  # crossing parts are at gap 0 even if the gap search saw nothing
        if (c["ia"], c["ib"]) not in known:
            gaps.append({"a": c["a"], "b": c["b"], "ia": c["ia"], "ib": c["ib"], "touching": False,
                         "seam_area_mm2": 0.0, "min_gap_mm": 0.0, "clearance_mm": 0.0,
                         "location": c["location"], "fuses": True})
        else:
            for g in gaps:
                if (g["ia"], g["ib"]) == (c["ia"], c["ib"]):
                    g["fuses"] = True
                    g["intersecting"] = True
    return inter
