"""Live isovalue: dragging the isovalue re-extracts the scan's isosurface and redraws
it in place.

Every change extracts the isosurface of the cached volume (:func:`anatomesh.core.extract.isosurface.isosurface`),
builds its edge list in linear time
(:func:`anatomesh.core.extract.edges.unique_edges`: faster than Blender's own edge derivation) and writes vertices, edges and triangles straight into the object's mesh. When a change at
full resolution took longer than :data:`BUDGET_S`, the next changes during the drag extract from
every 2nd voxel (a quarter of the triangles) and a timer puts the full-resolution surface back
:data:`SETTLE_S` after the value stops moving.
"""
from __future__ import annotations

import time
from typing import Optional

import bpy
import numpy as np

from ..scene import bridge
from ..scene import objects as scene

#: seconds one redraw may take before the drag switches to the coarse preview
BUDGET_S = 0.2
#: seconds after the last change at which the full-resolution surface comes back
SETTLE_S = 0.3
LIVE_NAME = "Live isovalue"

_STATE = {"slow": False, "pending": None, "last_s": 0.0}


def set_triangles(me: bpy.types.Mesh, vertices: np.ndarray, faces: np.ndarray) -> None:
    """Replace ``me``'s geometry by triangles, edges computed by the core (no ``calc_edges``)."""
    from ...core.extract.edges import unique_edges

    f = np.ascontiguousarray(faces, np.int32).reshape(-1, 3)
    bridge.set_geometry(me, vertices, f, edges=unique_edges(f, len(vertices)))


def extract(volume, level: float, stride: int = 1):
    """The capped isosurface at ``level`` (mm, the volume's space) on every ``stride``-th voxel."""
    from ...core.extract.isosurface import isosurface
    from ...core.model.volume import Volume

    if stride > 1:
        affine = np.array(volume.affine)
        affine[:3, :3] *= stride
        volume = Volume(volume.data[::stride, ::stride, ::stride], affine, volume.space, volume.meta)
    return isosurface(volume, float(level), cap=True)


def live_object(collection: bpy.types.Collection, volume, level: float) -> bpy.types.Object:
    """The collection's live isosurface object, made (with its material) when missing."""
    obj = next((o for o in collection.objects if o.get("anatomesh_live")), None)
    if obj is not None:
        return obj
    from .scan import object_props

    m = extract(volume, level)
    obj = scene.add_surface(collection, LIVE_NAME, m.vertices, m.faces, object_props(volume, level, LIVE_NAME),
                            (0.93, 0.89, 0.78))
    obj["anatomesh_live"] = 1
    return obj


def update(obj: bpy.types.Object, volume, level: float, stride: Optional[int] = None) -> float:
    """Re-extract ``obj``'s isosurface at ``level`` and redraw; returns the seconds it took.
    ``stride`` None: full resolution unless the last full update was over :data:`BUDGET_S`."""
    t0 = time.perf_counter()
    coarse = stride if stride is not None else (2 if _STATE["slow"] else 1)
    m = extract(volume, level, coarse)
    set_triangles(obj.data, m.vertices, m.faces)
    obj["anatomesh_value"] = float(level)
    obj["anatomesh_live_stride"] = int(coarse)
    dt = time.perf_counter() - t0
    if coarse == 1:
        _STATE["slow"] = dt > BUDGET_S
    _STATE["last_s"] = dt
    return dt


def on_level_changed(settings, context) -> None:
    """Property callback of ``Scene.anatomesh_preprocess.live_level``: redraw the live surface;
    after a coarse redraw, schedule the full-resolution one."""
    from .common import load_volume

    obj = bpy.data.objects.get(settings.live_object) if settings.live_object else None
    s = context.scene.anatomesh
    if obj is None or not s.filepath:
        return
    try:
        volume = load_volume(s.filepath, s.series, s.label_table, s.space)
        update(obj, volume, settings.live_level)
        if obj.get("anatomesh_live_stride", 1) > 1:
            _schedule(obj.name, (s.filepath, s.series, s.label_table, s.space), settings.live_level)
    except Exception as exc:  # an update callback must never raise into the UI
        print(f"Anatomesh: live isovalue failed: {exc}")


def _schedule(name: str, key, level: float) -> None:
    _STATE["pending"] = (name, key, level, time.perf_counter())
    if not bpy.app.timers.is_registered(_settle):
        bpy.app.timers.register(_settle, first_interval=SETTLE_S)


def _settle():
    """Timer: once the value has rested for :data:`SETTLE_S`, redraw at full resolution."""
    from .common import load_volume

    pending = _STATE["pending"]
    if pending is None:
        return None
    name, key, level, when = pending
    wait = SETTLE_S - (time.perf_counter() - when)
    if wait > 0:
        return wait
    _STATE["pending"] = None
    obj = bpy.data.objects.get(name)
    if obj is not None:
        update(obj, load_volume(*key), level, stride=1)
    return None
