"""Decimating a scan's objects with core (seams shared, error measured), and the preview with
Blender's Decimate modifier."""
from __future__ import annotations

from typing import Dict

import numpy as np

from . import bridge, live, scene
from .reassemble import surface_set_from_objects


#: name of the preview modifier on each surface object
PREVIEW_MODIFIER = "Anatomesh Decimate (preview)"


#: custom properties set on each object by Apply (the report keys of ``anatomesh mesh``)
ERROR_PROPS = (
    "anatomesh_faces_before",                    # faces of the object before decimating
    "anatomesh_decimation_max_error_mm",         # symmetric Hausdorff distance to the input, mm
    "anatomesh_decimation_mean_error_mm",        # mean distance, mm
    "anatomesh_decimation_volume_change_pct",    # enclosed volume change, %
)


def _core_target(target: str, ratio: float, faces: int, max_error: float, total_faces: int) -> Dict:
    if target == "RATIO":
        return {"ratio": float(ratio)}
    if target == "FACES":
        return {"ratio": float(min(1.0, max(faces, 1) / max(total_faces, 1)))}
    return {"max_error": float(max_error)}


def decimate_collection(collection, target: str, ratio: float = 0.1, faces: int = 50000,
                        max_error: float = 1.0, progress=None) -> Dict[str, Dict]:
    """Decimate the scan's surfaces with core, write them back, store the measured errors.

    Shells that share vertices (a label map) are decimated together as one SurfaceSet; other
    surfaces (isosurfaces) one by one. Returns ``{object name: shell measures}`` (core's keys:
    ``faces_before``, ``faces_after``, ``hausdorff_mm``, ``mean_mm``, ``volume_change_pct``).
    """
    from ..app.stages import output_shells
    from ..core.decimate.qem import decimate_mesh, decimate_surfaces
    from ..core.model.errors import AnatomeshError
    from ..core.model.mesh import Mesh

    objs = scene.surface_objects(collection)
    if not objs:
        raise AnatomeshError(f"scan '{collection.name}' has no surface objects to decimate")
    total = sum(len(o.data.polygons) for o in objs)
    kwargs = _core_target(target, ratio, faces, max_error, total)
    shared = [o for o in objs if bridge.SHARED_INDEX_ATTRIBUTE in o.data.attributes]
    alone = [o for o in objs if o not in shared]
    results: Dict[str, Dict] = {}
    if shared:
        ss, members = surface_set_from_objects(shared)
        out, rep = decimate_surfaces(ss, progress=progress, **kwargs)
        shells = {int(m.value): m for m in output_shells(out)[0]}
        for k, o in enumerate(members):
            m = shells[k + 1]
            write_surface(o, m.vertices, m.faces, m.meta["vertex_ids"], out.vertices[m.meta["vertex_ids"]])
            results[o.name] = rep["shells"][k + 1]
    for o in alone:
        v, f = bridge.arrays(o.data)
        out, rep = decimate_mesh(Mesh(v, f), **kwargs)
        write_surface(o, out.vertices, out.faces, None)
        results[o.name] = rep["shells"][None]
    for o in objs:
        r = results[o.name]
        o["anatomesh_faces_before"] = int(r["faces_before"])
        o["anatomesh_decimation_max_error_mm"] = float(r["hausdorff_mm"])
        o["anatomesh_decimation_mean_error_mm"] = float(r["mean_mm"])
        o["anatomesh_decimation_volume_change_pct"] = float(r["volume_change_pct"])
        if PREVIEW_MODIFIER in o.modifiers:
            o.modifiers.remove(o.modifiers[PREVIEW_MODIFIER])
    collection["anatomesh_decimation_max_error_mm"] = max(r["hausdorff_mm"] for r in results.values())
    # the decimated shape is the new rest shape of live smoothing
    live.forget(collection.name)
    live.set_scan_settings(collection, smooth_method="NONE")
    return results


def write_surface(obj, vertices, faces, vertex_ids=None, rest=None) -> None:
    """New geometry for a surface object (materials and name stay): it becomes the rest shape
    (``rest``, default ``vertices``: the set's positions before the pinch points are moved
    apart); ``vertex_ids`` (N,) its shared-set indices, None when it has none any more. The
    edges come from the core (:func:`anatomesh.addon.live_iso.set_triangles`)."""
    from .live_iso import set_triangles

    me = obj.data
    set_triangles(me, vertices, faces)
    bridge.set_point_attribute(me, bridge.REST_ATTRIBUTE, vertices if rest is None else rest, "vector")
    if live.LATTICE_ATTRIBUTE in me.attributes:  # decimated vertices left their lattice cells
        me.attributes.remove(me.attributes[live.LATTICE_ATTRIBUTE])
    if vertex_ids is not None:
        bridge.set_point_attribute(me, bridge.SHARED_INDEX_ATTRIBUTE, vertex_ids, "int")


def preview_ratios(objs, target, ratio, faces, max_error) -> Dict[str, float]:
    """Decimate-modifier ratio of each object: the ratio, face count / all faces, or (max error)
    each organ's faces after / before in a core run on the current shapes."""
    if target != "ERROR":
        total = sum(len(o.data.polygons) for o in objs)
        r = _core_target(target, ratio, faces, max_error, total)["ratio"]
        return {o.name: r for o in objs}
    from ..core.decimate.qem import decimate_mesh, decimate_surfaces
    from ..core.model.mesh import Mesh

    out = {}
    shared = [o for o in objs if bridge.SHARED_INDEX_ATTRIBUTE in o.data.attributes]
    if shared:
        ss, members = surface_set_from_objects(shared)
        _, rep = decimate_surfaces(ss, max_error=max_error)
        for k, o in enumerate(members):
            s = rep["shells"][k + 1]
            out[o.name] = s["faces_after"] / max(s["faces_before"], 1)
    for o in objs:
        if o.name not in out:
            v, f = bridge.arrays(o.data)
            _, rep = decimate_mesh(Mesh(v, f), max_error=max_error, measure=False)
            out[o.name] = rep["faces_after"] / max(rep["faces_before"], 1)
    return out


def set_preview(objs, ratios: Dict[str, float]) -> None:
    for o in objs:
        mod = o.modifiers.get(PREVIEW_MODIFIER) or o.modifiers.new(PREVIEW_MODIFIER, "DECIMATE")
        mod.decimate_type = "COLLAPSE"
        mod.use_collapse_triangulate = True
        mod.ratio = float(min(1.0, max(0.0, ratios[o.name])))


def clear_preview(objs) -> int:
    n = 0
    for o in objs:
        mod = o.modifiers.get(PREVIEW_MODIFIER)
        if mod is not None:
            o.modifiers.remove(mod)
            n += 1
    return n
