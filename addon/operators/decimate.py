"""Decimating a scan's objects with core (seams shared, error measured), and the preview with
Blender's Decimate modifier."""
from __future__ import annotations

from typing import Dict, List, Optional

import numpy as np

from ..scene import bridge
from . import smooth as live
from ..scene import objects as scene
from ..scene.reassemble import object_affine, surface_set_from_objects


#: name of the preview modifier on each surface object
PREVIEW_MODIFIER = "Anatomesh Decimate (preview)"


#: custom properties set on each object by Apply (the report keys of ``anatomesh mesh``)
ERROR_PROPS = (
    "anatomesh_faces_before",                    # faces of the object before decimating
    "anatomesh_decimation_max_error_mm",         # symmetric Hausdorff distance to the input, mm
    "anatomesh_decimation_mean_error_mm",        # mean distance, mm
    "anatomesh_decimation_volume_change_pct",    # enclosed volume change, %
)


def decimation_recipe(target: str, ratio: float, faces: int, max_error: float):
    """The run's decimation settings for the panel's target ("RATIO", "FACES" or "ERROR"): what
    ``anatomesh mesh --decimate RATIO`` / ``--target-faces N`` / ``--max-error MM`` asks for."""
    from ...app.flow.recipe import Recipe

    if target == "RATIO":
        return Recipe(decimate=float(ratio))
    if target == "FACES":
        return Recipe(target_faces=int(faces))
    return Recipe(max_error=float(max_error))


def decimate_collection(collection, target: str, ratio: float = 0.1, faces: int = 50000,
                        max_error: float = 1.0, progress=None) -> Dict[str, Dict]:
    """Decimate the scan's surfaces as ``anatomesh mesh`` does (:func:`decimated`), write them
    back, store the measured errors. Returns ``{object name: shell measures}`` (core's keys:
    ``faces_before``, ``faces_after``, ``hausdorff_mm``, ``mean_mm``, ``volume_change_pct``)."""
    from ...core.model.errors import AnatomeshError

    objs = scene.surface_objects(collection)
    if not objs:
        raise AnatomeshError(f"scan '{collection.name}' has no surface objects to decimate")
    results: Dict[str, Dict] = {}
    recipe = decimation_recipe(target, ratio, faces, max_error)
    for o, m, rest, measures in decimated(objs, recipe, progress, shown_sets(collection, objs)):
        write_surface(o, m.vertices, m.faces, None if rest is None else m.meta["vertex_ids"], rest)
        results[o.name] = measures
        o["anatomesh_faces_before"] = int(measures["faces_before"])
        o["anatomesh_decimation_max_error_mm"] = float(measures["hausdorff_mm"])
        o["anatomesh_decimation_mean_error_mm"] = float(measures["mean_mm"])
        o["anatomesh_decimation_volume_change_pct"] = float(measures["volume_change_pct"])
        if PREVIEW_MODIFIER in o.modifiers:
            o.modifiers.remove(o.modifiers[PREVIEW_MODIFIER])
    collection["anatomesh_decimation_max_error_mm"] = max(r["hausdorff_mm"] for r in results.values())
    # the decimated shape is the new rest shape of live smoothing
    live.forget(collection.name)
    live.bake(collection)
    return results


def shown_sets(collection, objs) -> Optional[List]:
    """The scan's layer sets at the positions its objects show, as extracted and smoothed (the
    sets ``anatomesh mesh`` decimates), each with ``[(object, set label)]``; None when the live
    cache does not hold them or an object was changed since (an edit tool)."""
    scan = live.live_scan(collection)
    if scan.shown is None:
        return None
    shown = scan.pinches_resolved(scan.shown)
    names = {o.name: o for o in objs}
    if set(shown) != set(names) or not all(
            np.array_equal(bridge.positions(names[n].data), p) for n, p in shown.items()):
        return None
    return [(sset.copy_with_vertices(pos), [(names[n], label) for n, k2, _, label in scan.members if k2 == k])
            for k, (sset, pos) in enumerate(zip(scan.layers, scan.shown))]


def decimated(objs, recipe, progress=None, sets: Optional[List] = None):
    """The surface objects ``objs`` decimated by :func:`anatomesh.app.flow.stages.decimate` with the
    run's ``recipe`` and its default cap (one voxel): ``sets`` (:func:`shown_sets`) when given,
    else shells that share vertices (a label map) reassembled into one SurfaceSet, seams
    shared; other surfaces (isosurfaces) one by one. Yields ``(object, Mesh, rest positions or
    None, shell measures)``; a shared shell's mesh has ``meta["vertex_ids"]`` and its rest
    positions are the set's (before the pinch points are moved apart)."""
    from ...app.flow import stages
    from ...core.model.mesh import Mesh
    from ...core.model.surfaceset import SurfaceSet

    shared = [o for o in objs if bridge.SHARED_INDEX_ATTRIBUTE in o.data.attributes]
    if sets is None and shared:
        ss, members = surface_set_from_objects(shared)
        sets = [(ss, [(o, k + 1) for k, o in enumerate(members)])]
    for ss, members in sets or []:
        out, rep = stages.decimate(ss, recipe, stages.one_voxel(ss), progress)
        shells = {m.value: m for m in stages.shells(out, recipe)[0]}  # as files show them, specks dropped
        for o, label in members:
            value = ss.shell_values.get(label, label)
            m = shells[value]
            yield o, m, out.vertices[m.meta["vertex_ids"]], rep["shells"][stages.value_key(value)]
    for o in objs:
        if o not in shared:
            one = SurfaceSet.from_meshes([Mesh(*bridge.arrays(o.data))], object_affine(o))
            out, rep = stages.decimate(one, recipe, stages.one_voxel(one))
            (measures,) = rep["shells"].values()
            yield o, out.shells()[0], None, measures


def write_surface(obj, vertices, faces, vertex_ids=None, rest=None) -> None:
    """New geometry for a surface object (materials and name stay, its cut faces marked again): it
    becomes the rest shape (``rest``, default ``vertices``: the set's positions before the pinch
    points are moved apart); ``vertex_ids`` (N,) its shared-set indices, None when it has none
    any more. The edges come from the core (:func:`anatomesh.addon.operators.isovalue.set_triangles`)."""
    from .isovalue import set_triangles

    me = obj.data
    set_triangles(me, vertices, faces)
    bridge.set_point_attribute(me, bridge.REST_ATTRIBUTE, vertices if rest is None else rest, "vector")
    if live.LATTICE_ATTRIBUTE in me.attributes:  # decimated vertices left their lattice cells
        me.attributes.remove(me.attributes[live.LATTICE_ATTRIBUTE])
    if vertex_ids is not None:
        bridge.set_point_attribute(me, bridge.SHARED_INDEX_ATTRIBUTE, vertex_ids, "int")
    scene.mark_cut_faces(obj)  # the new faces on the scan's field-of-view boundary


def preview_ratios(collection, objs, target, ratio, faces, max_error) -> Dict[str, float]:
    """Decimate-modifier ratio of each object: its faces after / before in the run Apply makes
    (:func:`decimated`, same settings), so the preview shows Apply's face counts."""
    recipe = decimation_recipe(target, ratio, faces, max_error)
    return {o.name: mesh.n_faces / max(m["faces_before"], 1)
            for o, mesh, _, m in decimated(objs, recipe, sets=shown_sets(collection, objs))}


def uniform_ratios(objs, target, ratio, faces) -> Dict[str, float]:
    """An instant preview while a slider moves: the ratio, or the face count / all faces, for
    every object ("ERROR" targets need a core run: :func:`preview_ratios`)."""
    r = ratio if target == "RATIO" else max(faces, 1) / max(sum(len(o.data.polygons) for o in objs), 1)
    return {o.name: float(min(1.0, r)) for o in objs}


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
