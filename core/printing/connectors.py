"""Connectors: pins on one part and matching pockets in its neighbour, across the interface the two
share (the seam of a label map's touching labels), so parts printed separately register when
assembled (liver segments, a heart opened in halves).

The pins stand where the interface has most room (farthest from its rim), at most two, at least
four pin radii apart; each is a cylinder along the interface's normal (from part A into part B),
its diameter the profile's (smaller where the interface is small), its length up to 1.5 diameters
or what B's depth allows under the whole pocket with a wall around it (rays along the axis from
the pocket's centre and around its circle widened by the wall, so a pocket breaks out of B
neither through its bottom nor through its side). B gets a pocket wider by the clearance on every side and deeper by the
clearance. Both parts stay closed and consistently oriented (:mod:`.drill`).
"""
from __future__ import annotations

from typing import Dict, List, Tuple

import numpy as np

from ..geometry.spatial import TriangleGrid
from ..model.errors import AnatomeshError
from ..model.mesh import Mesh, check_arrays, row_keys, weld_ids
from .drill import drill, extrude_loop
from .locate import location

#: the smallest pin worth printing, mm (radius)
_MIN_RADIUS = 0.75
#: a pocket keeps at least this far from the interface's rim, mm
_RIM_MARGIN = 1.0
#: rays around a pocket's circle that measure how deep the part goes under it
_DEPTH_RAYS = 12


def interface_faces(a: Mesh, b: Mesh) -> np.ndarray:
    """Indices of ``a``'s faces that ``b`` has too (same three positions): their interface."""
    va, fa = check_arrays(a.vertices, a.faces)
    vb, fb = check_arrays(b.vertices, b.faces)
    wid = weld_ids(np.concatenate([va, vb]))
    ka = row_keys(np.sort(wid[:len(va)][fa], axis=1))
    kb = row_keys(np.sort(wid[len(va):][fb], axis=1))
    return np.flatnonzero(np.isin(ka, kb))


def add_connectors(a: Mesh, b: Mesh, clearance: float, diameter: float = 5.0, count: int = 2,
                   min_wall: float = 0.8) -> Tuple[Mesh, Mesh, Dict]:
    """Pins on ``a`` and pockets in ``b`` across their shared interface.

    Returns (a, b, info ``{"pairs": [a name, b name], "pins": [{"location", "diameter_mm",
    "length_mm", "pocket_diameter_mm", "pocket_depth_mm"}], "clearance_mm"}``); raises
    :class:`AnatomeshError` when the parts share no interface or it has no room for a pin."""
    if not (np.isfinite(clearance) and clearance >= 0):
        raise AnatomeshError(f"the connector clearance must be >= 0 mm, got {clearance}")
    seam = interface_faces(a, b)
    if seam.size == 0:
        raise AnatomeshError(f"{a.name} and {b.name} share no interface: connectors go across touching "
                             "parts (neighbouring labels of one label map)")
    va, fa = a.vertices.astype(np.float64), a.faces.astype(np.int64)
    vb, fb = b.vertices.astype(np.float64), b.faces.astype(np.int64)
    spots = _spots(va, fa, seam, count, 0.5 * diameter + clearance)
    pins: List[Dict] = []
    grid_b = TriangleGrid(vb, fb)
    for p, room, axis in spots:
        r = min(0.5 * diameter, room - clearance - _RIM_MARGIN)
        if r < _MIN_RADIUS:
            continue
        depth = _solid_depth(grid_b, p, axis, r + clearance + min_wall)
        length = float(min(3 * r, depth - clearance - min_wall))
        if not length >= r:
            continue
        try:
            va2, fa2, vb2, fb2, pin = _pin(va, fa, vb, fb, p, axis, r, length, clearance)
        except AnatomeshError:  # no room on the surface there after all: try the next place
            continue
        va, fa, vb, fb = va2, fa2, vb2, fb2
        pins.append(pin)
    if not pins:
        raise AnatomeshError(f"the interface of {a.name} and {b.name} has no room for a pin of at least "
                             f"{2 * _MIN_RADIUS:g} mm; fuse them or print them together")
    out_a = Mesh(va.astype(np.float32), fa.astype(np.int32), None, name=a.name, value=a.value,
                 color=a.color, space=a.space)
    out_b = Mesh(vb.astype(np.float32), fb.astype(np.int32), None, name=b.name, value=b.value,
                 color=b.color, space=b.space)
    return out_a, out_b, {"pair": [a.name, b.name], "pins": pins, "clearance_mm": float(clearance)}


def _pin(va, fa, vb, fb, p, axis, r, length, clearance):
    """One pin on A (drilled, extruded out along ``axis``, into B's side) and its pocket in B
    (drilled, extruded the same way, into B's material)."""
    va, fa, loop = drill(va, fa, p, axis, r)
    s0 = float(np.max((va[loop] - p) @ axis)) + 0.05 * r
    va, fa = extrude_loop(va, fa, loop, p, axis, r, s0, length)
    vb, fb, loop_b = drill(vb, fb, p, axis, r + clearance)
    s0b = float(np.max((vb[loop_b] - p) @ axis)) + 0.05 * r
    deep = s0 + length + clearance
    vb, fb = extrude_loop(vb, fb, loop_b, p, axis, r + clearance, s0b, deep - s0b)
    return va, fa, vb, fb, {"location": location(p), "diameter_mm": round(2 * r, 3),
                            "length_mm": round(length, 3), "pocket_diameter_mm": round(2 * (r + clearance), 3),
                            "pocket_depth_mm": round(deep, 3)}


def _solid_depth(grid: TriangleGrid, p: np.ndarray, axis: np.ndarray, radius: float) -> float:
    """How deep, mm, the solid of ``grid`` goes along ``axis`` from the plane through ``p``
    across it, under the whole disc of ``radius`` around ``p``: the nearest exit of rays along
    the axis from the centre and :data:`_DEPTH_RAYS` points on the circle (each started a
    radius behind the plane, so a curved interface is entered first). A pocket shallower than
    this less the wall breaks out neither through the bottom nor through the side."""
    helper = [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0]
    e1 = np.cross(axis, helper)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(axis, e1)
    ang = 2 * np.pi * np.arange(_DEPTH_RAYS) / _DEPTH_RAYS
    ring = radius * (np.cos(ang)[:, None] * e1 + np.sin(ang)[:, None] * e2)
    q0 = p + np.vstack([np.zeros(3), ring]) - radius * axis
    d = np.broadcast_to(axis, q0.shape)
    inside = grid.contains(q0)
    t1, _, _, _ = grid.cast(q0, d, t_min=1e-6)
    exit_t = t1.copy()
    enter = np.flatnonzero(~inside & np.isfinite(t1))
    if enter.size:
        t2, _, _, _ = grid.cast(q0[enter] + (t1[enter, None] + 1e-6) * axis, d[enter], t_min=1e-6)
        exit_t[enter] = t1[enter] + t2
    exit_t[~inside & ~np.isfinite(t1)] = 0.0  # a ray that never enters: no room there
    return float(np.min(exit_t)) - radius


def _spots(v, f, seam: np.ndarray, count: int, min_apart_radius: float):
    """Up to ``count`` places on the interface faces ``seam`` with the most room: (point, room
    = distance to the interface's rim mm, unit normal of the interface there, pointing out of
    the part)."""
    c = v[f[seam]].mean(axis=1)
    n = np.cross(v[f[seam, 1]] - v[f[seam, 0]], v[f[seam, 2]] - v[f[seam, 0]])
    in_seam = np.zeros(len(v), bool)
    in_seam[f[seam].ravel()] = True
    other = np.ones(len(f), bool)
    other[seam] = False
    rim = np.unique(f[other].ravel())
    rim = rim[in_seam[rim]]
    room = np.full(len(c), np.inf)
    for k in range(0, len(rim), 512):
        d = np.linalg.norm(c[:, None] - v[rim[k:k + 512]][None], axis=2).min(axis=1)
        room = np.minimum(room, d)
    out = []
    for _ in range(count):
        score = room.copy()
        for p, _, _ in out:
            score[np.linalg.norm(c - p, axis=1) < 4 * min_apart_radius] = -1
        k = int(np.argmax(score))
        if score[k] <= 0:
            break
        near = np.linalg.norm(c - c[k], axis=1) < max(room[k], 1e-6)
        axis = n[near].sum(axis=0)
        out.append((c[k], float(room[k]), axis / np.linalg.norm(axis)))
    return out
