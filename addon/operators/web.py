"""Anatomesh add-on: the web page and distance colours from the objects in the scene.

* :func:`paint_margins` colours every surface object by its distance to a target object's
  surface (within 2/5/10 mm red/yellow/green, farther the object's own colour), through core
  (:func:`anatomesh.core.geometry.margins.color_by_distance`), as the colour attribute the
  CLI's ``--distance-to`` gives a ``.blend`` (:data:`anatomesh.addon.scene.objects.COLOR_ATTRIBUTE`).
* :func:`export_web` writes the self-contained page of the objects as shown (modifiers applied,
  world mm), with their colour attribute when they have one, through the same writer as
  ``anatomesh web`` (:mod:`anatomesh.app.web.page`): levels of detail per object, one page folder.
"""
from __future__ import annotations

from typing import Dict, List, Optional, Sequence

import bpy
import numpy as np

from ...core.model.labels import linear_to_srgb
from ..scene import objects as scene
from .export import object_meshes


def object_colors(context, obj) -> Optional[np.ndarray]:
    """(N, 3) sRGB colours of ``obj``'s evaluated mesh from its point colour attribute
    :data:`~anatomesh.addon.scene.objects.COLOR_ATTRIBUTE`, or None when it has none."""
    ev = obj.evaluated_get(context.evaluated_depsgraph_get())
    me = ev.to_mesh()
    try:
        attr = me.color_attributes.get(scene.COLOR_ATTRIBUTE)
        if attr is None or attr.domain != "POINT" or len(attr.data) != len(me.vertices):
            return None
        rgba = np.empty(len(me.vertices) * 4, np.float32)
        attr.data.foreach_get("color", rgba)
    finally:
        ev.to_mesh_clear()
    return linear_to_srgb(rgba.reshape(-1, 4)[:, :3]).astype(np.float32)


def paint_margins(context, objects: Sequence, target, margins: Sequence[float]) -> Dict:
    """Colour ``objects`` (surface objects, ``target`` among them) by their distance to
    ``target``; returns core's summary (per object the nearest distance and shares within each
    margin)."""
    from ...core.geometry.margins import color_by_distance

    objects = list(objects)
    meshes = object_meshes(context, objects)
    for m, o in zip(meshes, objects):
        m.name = o.name  # objects are unique by name; labels may repeat
    _, summary = color_by_distance(meshes, target.name, margins)
    for o, m in zip(objects, meshes):
        if m.vertex_colors is not None and len(m.vertex_colors) == len(o.data.vertices):
            scene.set_vertex_colors(o.data, m.vertex_colors)
            o.data.update()
        elif o == target:
            attr = o.data.color_attributes.get(scene.COLOR_ATTRIBUTE)
            if attr is not None:
                o.data.color_attributes.remove(attr)
    return summary


def export_web(context, objects: Sequence, folder: str, *, title: str, levels: int = 2,
               overwrite: bool = False, views: Sequence[Dict[str, str]] = ()) -> Dict:
    """The page of ``objects`` in ``folder`` (``index.html`` + scripts), listing ``views``
    (:func:`anatomesh.app.web.views.read_views`); returns its summary (sizes and triangles per
    level, :func:`anatomesh.app.web.page.write_page`). A structure's opacity on the page is its
    colour's alpha."""
    from ...app.web.page import WebModel, write_page
    from ...app.web.models import mesh_levels

    objects = list(objects)
    meshes = object_meshes(context, objects)
    for m, o in zip(meshes, objects):
        m.vertex_colors = _matching(object_colors(context, o), m.n_vertices)
        m.color = (*m.color[:3], float(o.get("anatomesh_alpha", 1.0)))  # the page's default opacity
    levels_of = mesh_levels(meshes, levels)
    full = levels_of[-1]
    if any(m.vertex_colors is not None for m in full):  # coarse levels: the nearest full vertex's colour
        for level in levels_of[:-1]:
            for coarse, fine in zip(level, full):
                coarse.vertex_colors = _nearest_colors(coarse, fine)
    return write_page([WebModel(title, levels_of)], folder, title=title, overwrite=overwrite, views=views)


def _matching(colors: Optional[np.ndarray], n: int) -> Optional[np.ndarray]:
    return colors if colors is not None and len(colors) == n else None


def _nearest_colors(coarse, fine) -> Optional[np.ndarray]:
    """Colours of ``coarse``'s vertices from the nearest vertex of ``fine`` (None without)."""
    if fine.vertex_colors is None:
        return None
    from ...core.geometry.spatial import TriangleGrid

    pts = np.asarray(fine.vertices, np.float64)
    idx = np.arange(len(pts), dtype=np.int32)
    grid = TriangleGrid(pts, np.stack([idx, idx, idx], axis=1))  # a grid over points
    _, face, _ = grid.closest(coarse.vertices)
    return fine.vertex_colors[np.maximum(face, 0)]


def surface_objects_of(context, selection: str, collection: str = "") -> List[bpy.types.Object]:
    """The objects an export means: the selected meshes, or the surface objects of the scan
    collection named ``collection`` (default: the active scan)."""
    from .common import active_scan

    if selection == "SELECTED":
        return [o for o in context.selected_objects if o.type == "MESH"]
    coll = bpy.data.collections.get(collection) if collection else active_scan(context)
    return scene.surface_objects(coll) if coll is not None else []


def neighbours_of(target) -> List[bpy.types.Object]:
    """The surface objects of the collection holding ``target`` (``target`` among them)."""
    coll = target.users_collection[0] if target.users_collection else None
    objs = scene.surface_objects(coll) if coll is not None else []
    return objs if target in objs else [target] + objs
