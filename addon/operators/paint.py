"""Anatomesh add-on: colour attributes (curvature, distance to the unsmoothed surface, wall
thickness, gaps) selectable as viewport colour.

* :func:`paint_values` writes per-vertex values as a colour attribute (``FLOAT_COLOR`` on points)
  through a colormap, makes it the active and default colour attribute, and records the range on
  the object (``<name>_min`` / ``<name>_max`` custom properties) for a legend.
* The values come from core, on numpy arrays: mean curvature
  (:func:`anatomesh.core.geometry.measure.vertex_curvatures`, Meyer et al. 2003), distance to the
  unsmoothed surface (the ``anatomesh_rest`` attribute every surface object keeps, see
  :mod:`.live`), wall thickness (:func:`anatomesh.core.printing.thickness.wall_thickness`) and the gap to
  the nearest other part (:class:`anatomesh.core.geometry.spatial.TriangleGrid`), all in mm, in world
  coordinates.
* ``anatomesh.paint`` paints the selected Anatomesh objects (or the active scan's) and switches
  every 3D view's solid shading to show the attribute (``shading.color_type = 'VERTEX'``).
"""
from __future__ import annotations

from typing import Dict, List, Optional, Sequence, Tuple

import bpy
import numpy as np

from ..scene import bridge
from .common import active_scan

#: colormaps: control points (position 0..1, r, g, b), linear in between
COLORMAPS: Dict[str, np.ndarray] = {
    # thin/near = red, thick/far = blue: "heat" for thickness and gaps
    "heat": np.array([[0.0, 0.80, 0.05, 0.05], [0.25, 0.95, 0.45, 0.05], [0.5, 0.95, 0.90, 0.20],
                      [0.75, 0.45, 0.80, 0.45], [1.0, 0.15, 0.35, 0.85]]),
    # sequential, perceptually ordered (viridis-like)
    "viridis": np.array([[0.0, 0.267, 0.005, 0.329], [0.25, 0.230, 0.322, 0.546],
                         [0.5, 0.128, 0.567, 0.551], [0.75, 0.369, 0.789, 0.383],
                         [1.0, 0.993, 0.906, 0.144]]),
    # signed values around 0 (curvature): blue - white - red
    "diverging": np.array([[0.0, 0.15, 0.25, 0.80], [0.5, 0.95, 0.95, 0.95], [1.0, 0.80, 0.10, 0.10]]),
}
#: colour of vertices without a value (NaN): mid grey
NO_VALUE = (0.5, 0.5, 0.5, 1.0)

#: attribute names per paint mode
ATTRIBUTES = {"CURVATURE": "anatomesh_curvature", "DISTANCE": "anatomesh_distance",
              "THICKNESS": "anatomesh_thickness", "GAP": "anatomesh_gap"}


def map_colors(values: np.ndarray, vmin: float, vmax: float, name: str = "heat") -> np.ndarray:
    """RGBA (N, 4) float32 for ``values`` (N,) mapped from [vmin, vmax] through ``name``."""
    if name not in COLORMAPS:
        raise ValueError(f"unknown colormap {name!r}; use one of {', '.join(COLORMAPS)}")
    cm = COLORMAPS[name]
    x = np.asarray(values, np.float64)
    t = np.clip((x - vmin) / (vmax - vmin), 0.0, 1.0) if vmax > vmin else np.zeros_like(x)
    rgba = np.empty((x.size, 4), np.float32)
    for k in range(3):
        rgba[:, k] = np.interp(t, cm[:, 0], cm[:, k + 1])
    rgba[:, 3] = 1.0
    rgba[~np.isfinite(x)] = NO_VALUE
    return rgba


def paint_values(obj: bpy.types.Object, values: np.ndarray, name: str, vmin: Optional[float] = None,
                 vmax: Optional[float] = None, colormap: str = "heat") -> Tuple[float, float]:
    """Store per-vertex ``values`` (N,) as colour attribute ``name`` on ``obj``'s mesh.

    The range defaults to the values' finite min/max; NaN values are grey. The attribute becomes
    the active and default (render) colour attribute. Returns the range (vmin, vmax) used, also
    kept on the object as ``<name>_min`` / ``<name>_max``. ``colormap`` is one of
    :data:`COLORMAPS`."""
    me = obj.data
    vals = np.asarray(values, np.float64).reshape(-1)
    if vals.size != len(me.vertices):
        raise ValueError(f"{obj.name}: {vals.size} values for {len(me.vertices)} vertices")
    fin = vals[np.isfinite(vals)]
    lo = float(fin.min()) if vmin is None and fin.size else float(vmin or 0.0)
    hi = float(fin.max()) if vmax is None and fin.size else float(vmax if vmax is not None else 1.0)
    rgba = map_colors(vals, lo, hi, colormap)
    attr = me.color_attributes.get(name)
    if attr is not None and (attr.domain != "POINT" or attr.data_type != "FLOAT_COLOR"):
        me.color_attributes.remove(attr)
        attr = None
    if attr is None:
        attr = me.color_attributes.new(name, "FLOAT_COLOR", "POINT")
    if rgba.size:
        attr.data.foreach_set("color", rgba.ravel())
    me.color_attributes.active_color = attr
    me.color_attributes.default_color_name = name
    obj[f"{name}_min"], obj[f"{name}_max"] = lo, hi
    me.update()
    return lo, hi


def show_vertex_colors(context) -> int:
    """Switch every 3D view's solid shading to the colour attribute; returns how many views."""
    n = 0
    screens = [w.screen for w in context.window_manager.windows] if context.window_manager else []
    for screen in screens:
        for area in screen.areas:
            if area.type != "VIEW_3D":
                continue
            for space in area.spaces:
                if space.type == "VIEW_3D":
                    space.shading.color_type = "VERTEX"
                    n += 1
    return n


# ---------------------------------------------------------------------------------------------
# values (numpy, via core)
# ---------------------------------------------------------------------------------------------
def curvature_values(obj) -> np.ndarray:
    """Mean curvature per vertex, 1/mm (> 0 convex)."""
    from ...core.geometry.measure import vertex_curvatures

    v, f = bridge.world_arrays(obj)
    return vertex_curvatures(v, f)[0]


def distance_values(obj) -> np.ndarray:
    """Distance (mm) of each vertex to the object's unsmoothed surface (its ``anatomesh_rest``
    positions with the same faces), in world units; NaN without the attribute."""
    from ...core.geometry.spatial import TriangleGrid

    v, f = bridge.arrays(obj.data)
    rest = bridge.point_attribute(obj.data, bridge.REST_ATTRIBUTE, "vector")
    if rest is None or not len(f):
        return np.full(len(v), np.nan)
    m = np.array(obj.matrix_world, np.float64)
    scale = float(np.cbrt(abs(np.linalg.det(m[:3, :3])))) or 1.0
    d, _, _ = TriangleGrid(rest, f).closest(v)
    return d * scale


def thickness_values(obj, max_thickness: float = 5.0) -> np.ndarray:
    """Wall thickness per vertex, mm (capped at ``max_thickness``)."""
    from ...core.printing.thickness import wall_thickness

    v, f = bridge.world_arrays(obj)
    return wall_thickness(v, f, max_thickness=max_thickness)


def gap_values(objs: Sequence, max_distance: float = 5.0) -> List[np.ndarray]:
    """Per object, the distance (mm) of each vertex to the nearest other object of ``objs``
    (capped at ``max_distance``; 0 on shared seams)."""
    from ...core.geometry.spatial import TriangleGrid

    arrays = [bridge.world_arrays(o) for o in objs]
    grids = [TriangleGrid(v, f) if len(f) else None for v, f in arrays]
    out = []
    for i, (v, _) in enumerate(arrays):
        best = np.full(len(v), float(max_distance))
        for j, g in enumerate(grids):
            if j != i and g is not None:
                d, _, _ = g.closest(v, max_distance)
                best = np.minimum(best, d)
        out.append(best)
    return out


def paint_mode(objs: Sequence, mode: str, min_wall: float = 0.8, max_distance: float = 5.0) -> Dict:
    """Compute and paint ``mode`` on ``objs``; returns {object name: (vmin, vmax)}."""
    name = ATTRIBUTES[mode]
    ranges = {}
    if mode == "GAP":
        for o, vals in zip(objs, gap_values(objs, max_distance)):
            ranges[o.name] = paint_values(o, vals, name, 0.0, max_distance, colormap="heat")
        return ranges
    for o in objs:
        if mode == "CURVATURE":
            vals = curvature_values(o)
            fin = np.abs(vals[np.isfinite(vals)])
            lim = float(np.percentile(fin, 95)) if fin.size else 1.0
            ranges[o.name] = paint_values(o, vals, name, -lim, lim, colormap="diverging")
        elif mode == "DISTANCE":
            vals = distance_values(o)
            hi = float(np.nanmax(vals)) if np.any(np.isfinite(vals)) else 1.0
            ranges[o.name] = paint_values(o, vals, name, 0.0, max(hi, 1e-3), colormap="viridis")
        else:
            vals = thickness_values(o)
            ranges[o.name] = paint_values(o, vals, name, 0.0, 2.0 * min_wall, colormap="heat")
    return ranges


def target_objects(context) -> list:
    """Selected Anatomesh surface objects, else the active scan's."""
    from ..scene import objects as scene

    sel = [o for o in context.selected_objects if o.type == "MESH" and "anatomesh_value" in o]
    if sel:
        return sel
    coll = active_scan(context)
    return scene.surface_objects(coll) if coll is not None else []
