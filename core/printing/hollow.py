"""Hollowing for resin and powder printers: a part becomes a shell of a chosen wall with drain
holes at its lowest points, so uncured resin or loose powder can flow out.

The cavity is the part's inner offset surface (:func:`.offset.inner_offset`), closed, manifold
and ``wall`` mm inside the outer surface everywhere, so it never crosses it. Cavities too small
to drain are left solid. Each cavity gets ``holes`` drain holes (diameter from the profile) at
its lowest points along the build direction (default +z of the patient: the holes go where the
part meets the build plate), at least three hole diameters apart; each hole runs along the
shortest way through the wall (from the cavity point to its closest point on the outer surface)
and is lined with a tube (:mod:`.drill`).
"""
from __future__ import annotations

from typing import Dict, List, Sequence, Tuple

import numpy as np

from ..geometry.spatial import TriangleGrid
from ..geometry.topology import face_components
from ..model.errors import AnatomeshError
from ..model.mesh import Mesh, check_arrays, compact, signed_volume
from .drill import drill, line_hole
from .locate import location
from .offset import inner_offset


def hollow(mesh: Mesh, wall: float, holes: int = 2, hole_diameter: float = 4.0,
           up: Sequence[float] = (0.0, 0.0, 1.0), spacing: float = None) -> Tuple[Mesh, Dict]:
    """``mesh`` hollowed to a shell of ``wall`` mm with ``holes`` drain holes of
    ``hole_diameter`` mm per cavity at its lowest points along ``up`` (the build direction).

    Returns (mesh, info): ``{"wall_mm", "volume_before_mm3", "volume_after_mm3",
    "saved_mm3", "saved_pct", "cavities", "left_solid" (cavities too small to drain),
    "drain_holes": [{"location", "diameter_mm"}], "spacing_mm"}``."""
    v, f = check_arrays(mesh.vertices, mesh.faces)
    v = v.astype(np.float64)
    if holes < 0 or (holes and not hole_diameter > 0):
        raise AnatomeshError(f"drain holes: give a count >= 0 and a diameter > 0 mm, got {holes}, {hole_diameter}")
    up = np.asarray(up, np.float64) / np.linalg.norm(up)
    before = signed_volume(v, f)
    grid = TriangleGrid(v, f)
    vi, fi, h = inner_offset(v, f, wall, spacing, grid=grid)
    cavities, small = _cavities(vi, fi, hole_diameter, wall)
    vv, ff = v, f.astype(np.int64)
    done = []
    for cv, cf in cavities:
        base = len(vv)
        vv, ff = np.concatenate([vv, cv]), np.concatenate([ff, cf + base])
        for p in _low_points(cv, up, holes, 3 * hole_diameter):
            d, _, q = grid.closest(p[None])
            axis = (q[0] - p) / max(float(d[0]), 1e-9)
            vv, ff = _drain(vv, ff, q[0], p, axis, 0.5 * hole_diameter)
            done.append({"location": location(q), "diameter_mm": float(hole_diameter)})
    vv, ff, _, _ = compact(vv, ff)
    out = Mesh(vv.astype(np.float32), ff.astype(np.int32), None, name=mesh.name, value=mesh.value,
               color=mesh.color, space=mesh.space,
               meta={k: x for k, x in mesh.meta.items() if k != "vertex_ids"})  # indices changed
    after = signed_volume(out.vertices, out.faces)
    return out, {"wall_mm": float(wall), "volume_before_mm3": round(before, 3),
                 "volume_after_mm3": round(after, 3), "saved_mm3": round(before - after, 3),
                 "saved_pct": round(100.0 * (before - after) / before, 2) if before > 0 else 0.0,
                 "cavities": len(cavities), "left_solid": small, "drain_holes": done,
                 "spacing_mm": round(h, 4)}


def _cavities(v, f, hole_diameter: float, wall: float) -> Tuple[List, int]:
    """The offset surface's components big enough to drain (enclosing at least
    (2 · (diameter + wall))³ mm³), each as (vertices, faces); and how many were too small."""
    if len(f) == 0:
        return [], 0
    n, lab = face_components(f, len(v))
    out, small = [], 0
    least = (2.0 * (hole_diameter + wall)) ** 3
    for c in range(n):
        cv, cf, _, _ = compact(v, f[lab == c])
        if -signed_volume(cv, cf) >= least:
            out.append((cv, cf.astype(np.int64)))
        else:
            small += 1
    return out, small


def _low_points(v: np.ndarray, up: np.ndarray, count: int, spacing: float) -> List[np.ndarray]:
    """Up to ``count`` vertices lowest along ``up``, each at least ``spacing`` mm from the ones
    chosen before."""
    order = np.argsort(v @ up)
    chosen: List[np.ndarray] = []
    for k in order:
        if len(chosen) == count:
            break
        if all(np.linalg.norm(v[k] - c) >= spacing for c in chosen):
            chosen.append(v[k])
    return chosen


def _drain(v, f, outer_point, inner_point, axis, radius):
    """A drain hole through the wall: holes in the outer surface and the cavity, lined."""
    v, f, loop_out = drill(v, f, outer_point, axis, radius)
    v, f, loop_in = drill(v, f, inner_point, axis, radius)
    return v, line_hole(v, f, loop_out, loop_in, inner_point, axis)
