"""The Print panel's tools, with the command line's functions on the scene's objects:

* :func:`reextract_fixed` — fuse labels / thicken thin parts in the label map before extraction
  (:func:`anatomesh.app.flow.stages.prepare_volume`), then extract and smooth the scan again as
  ``anatomesh mesh --fuse/--thicken`` does, replacing the scan's objects;
* :func:`separate_objects` — pull touching parts apart by a clearance
  (:func:`anatomesh.core.printing.fixes.separate_parts`, ``--clearance``);
* :func:`hollow_object` — hollow a part with drain holes (:func:`anatomesh.app.flow.print_parts.hollow_part`,
  ``--hollow``);
* :func:`connect_objects` — pins on one part and pockets in the other
  (:func:`anatomesh.core.printing.connectors.add_connectors`, ``--connectors``).

Results go back into the same objects (name, material and custom properties stay; the new
shape becomes the rest shape, live smoothing of the scan is off afterwards, as after
decimating); each tool's report entry is appended to the object's ``anatomesh_fixes`` (a JSON
list, the entries of the CLI report's ``fixes``). Coordinates are world coordinates in mm.
"""
from __future__ import annotations

import json
from typing import Dict, List, Optional, Sequence

import bpy
import numpy as np

from ..scene import bridge
from . import smooth as live
from ..scene import objects as scene
from .decimate import write_surface

#: custom property holding the tools' report entries (JSON list)
FIXES_PROPERTY = "anatomesh_fixes"


def object_mesh(obj):
    """A core Mesh of ``obj`` in world coordinates (mm), named after the object."""
    from ...core.model.mesh import Mesh

    v, f = bridge.world_arrays(obj)
    value = obj.get("anatomesh_value")
    return Mesh(v, f, name=obj.name, value=value)


def write_world(obj, mesh, vertex_ids=None) -> None:
    """Write ``mesh`` (world coordinates, mm) into ``obj`` (back to its own coordinates)."""
    v = np.asarray(mesh.vertices, np.float64)
    m = np.array(obj.matrix_world, dtype=np.float64)
    if not np.allclose(m, np.eye(4)):
        inv = np.linalg.inv(m)
        v = v @ inv[:3, :3].T + inv[:3, 3]
    write_surface(obj, v.astype(np.float32), mesh.faces, vertex_ids)
    if vertex_ids is None and bridge.SHARED_INDEX_ATTRIBUTE in obj.data.attributes:
        obj.data.attributes.remove(obj.data.attributes[bridge.SHARED_INDEX_ATTRIBUTE])


def record(obj, entry: Dict) -> None:
    """Append a report entry to the object's :data:`FIXES_PROPERTY`."""
    entries = json.loads(obj.get(FIXES_PROPERTY, "[]"))
    entries.append(entry)
    obj[FIXES_PROPERTY] = json.dumps(entries)


def detach_live(objs: Sequence) -> None:
    """The objects' scans no longer smooth live (their shapes are new rest shapes)."""
    for coll in {c for o in objs for c in o.users_collection}:
        for c in [coll] + [p for p in bpy.data.collections if coll.name in p.children]:
            if c.anatomesh.is_scan:
                live.forget(c.name)
                live.bake(c)


def hollow_object(obj, wall: float, holes: int, diameter: Optional[float], profile: str) -> Dict:
    """Hollow ``obj`` to a shell of ``wall`` mm with drain holes (the CLI's ``--hollow``);
    returns the report entry (volumes before/after, saved, cavities, hole locations)."""
    from ...app.flow.print_parts import hollow_part

    out, info = hollow_part(object_mesh(obj), wall, holes, diameter, profile)
    write_world(obj, out)
    entry = {"fix": "hollow", "part": obj.name, **info}
    record(obj, entry)
    detach_live([obj])
    return entry


def connect_objects(a, b, profile: str, min_wall: float) -> Dict:
    """Pins on ``a`` and pockets in ``b`` across their interface (the CLI's ``--connectors``),
    the clearance from the printer ``profile``; returns the report entry."""
    from ...core.printing.connectors import add_connectors
    from ...core.printing.profiles import resolve_profile

    prof = resolve_profile(profile, min_wall)
    ma, mb, info = add_connectors(object_mesh(a), object_mesh(b), prof["connector_clearance"],
                                  min_wall=prof["min_wall"])
    write_world(a, ma)
    write_world(b, mb)
    entry = {"fix": "connectors", **info}
    record(a, entry)
    record(b, entry)
    detach_live([a, b])
    return entry


def separate_objects(objs: Sequence, clearance: float) -> Dict:
    """Pull touching surfaces of one scan apart by ``clearance`` mm along their shared
    interfaces (the CLI's ``--clearance``, on the shapes shown); returns the report entry with
    the object names of each separated pair.

    As :func:`anatomesh.app.flow.stages.shells` does: the scan's set as smoothed (the live
    cache's, before the pinch points are moved apart; :func:`.decimate.shown_sets`) is separated,
    then its pinch points are resolved as the files show them. Without that cache (or for some
    of the scan's objects only) the objects' shells are reassembled as shown."""
    from ...core.geometry.pinches import pinch_gap_mm, separate_shells
    from ...core.printing.fixes import separate_parts
    from ..scene.reassemble import surface_set_from_objects

    shared = [o for o in objs if bridge.SHARED_INDEX_ATTRIBUTE in o.data.attributes]
    if len(shared) < 2:
        from ...core.model.errors import AnatomeshError

        raise AnatomeshError("clearance: needs two or more surfaces of one extracted scan (they share "
                             "their interface vertices)")
    sets = _scan_set(shared)
    if sets is not None:
        sset, members = sets
        meshes, info = separate_parts(sset, clearance)
        separate_shells(sset, meshes, pinch_gap_mm(sset.affine))  # as `anatomesh mesh` writes them
    else:
        sset, order = surface_set_from_objects(shared)
        members = [(o, k + 1) for k, o in enumerate(order)]
        meshes, info = separate_parts(sset, clearance)
    by_value = {m.value: m for m in meshes}
    of_value = {sset.shell_values.get(label, label): o for o, label in members}
    for value, o in of_value.items():
        write_world(o, by_value[value])
    order = [o for o, _ in members]
    entry = {"fix": "clearance", "clearance_mm": info["clearance_mm"],
             "moved_vertices": info["moved_vertices"],
             "pairs": [[of_value[a].name, of_value[b].name] for a, b in info["pairs"]]}
    for o in order:
        record(o, entry)
    detach_live(order)
    return entry


def _scan_set(objs):
    """``(SurfaceSet, [(object, set label)])``: the one smoothed set of the scan holding exactly
    ``objs`` at the positions shown (:func:`.decimate.shown_sets`), or None."""
    from .decimate import shown_sets

    colls = {c for o in objs for c in o.users_collection if c.anatomesh.is_scan}
    if len(colls) != 1:
        return None
    coll = colls.pop()
    if {o.name for o in scene.surface_objects(coll)} != {o.name for o in objs}:
        return None
    sets = shown_sets(coll, objs)
    return sets[0] if sets is not None and len(sets) == 1 else None


def reextract_fixed(context, coll, fuse: Sequence[Sequence[int]] = (), thicken: bool = False,
                    profile: str = "fdm", min_wall: Optional[float] = None, progress=None):
    """Extract ``coll``'s scan again with the label-map fixes (``fuse``: groups of label values;
    ``thicken``) applied by :func:`anatomesh.app.flow.stages.prepare_volume`, smoothed with the
    scan's settings: the surfaces of ``anatomesh mesh --fuse ... / --thicken`` for the same
    labels and settings. The new collection replaces ``coll`` (and takes its name).

    Returns ``(collection, fixes)``."""
    from ...app.flow import stages
    from ...app.flow.recipe import Recipe
    from .common import load_volume
    from .scan import extract_to_scene

    settings = context.scene.anatomesh
    objs = scene.surface_objects(coll)
    src = coll.anatomesh.source
    same = bpy.path.abspath(settings.filepath) == bpy.path.abspath(src)
    vol = load_volume(src, settings.series if same else "", settings.label_table if same else "",
                      coll.anatomesh.space, grid=settings.grid if same else "")
    _one_label_map(vol)
    recipe = Recipe(input=str(src), space=vol.space, labels=sorted({int(o["anatomesh_value"]) for o in objs}),
                    fuse=[list(g) for g in fuse], thicken=bool(thicken), profile=profile,
                    min_wall=min_wall)
    fixed, fixes = stages.prepare_volume(vol, recipe)
    looks = {int(o["anatomesh_value"]): (o.get("anatomesh_name", o.name), _colour(o)) for o in objs}
    materials = {int(o["anatomesh_value"]): o.data.materials[0] for o in objs if len(o.data.materials)}
    for fix in fixes:
        if fix["fix"] == "fuse":
            looks[fix["into"]] = (fix["name"], looks.get(fix["into"], ("", (0.8, 0.8, 0.8)))[1])
    smoothing = {k: getattr(coll.anatomesh, k) for k in _smoothing_keys()}
    name, render = coll.name, coll.anatomesh.render_method
    new = extract_to_scene(context, fixed, recipe, looks=looks, render_method=render, progress=progress)
    cached = live.live_scan(new)
    remove_scan(coll)
    new.name = name
    live.remember(new, cached)
    context.scene.anatomesh.last_collection = new.name
    live.set_scan_settings(new, **smoothing)
    if smoothing["smooth_method"] != "NONE":
        live.smooth_collection(new)
    for o in scene.surface_objects(new):
        o.name = o.data.name = str(o["anatomesh_name"])  # the old objects are gone: their names are free
        _keep_material(o, materials.get(int(o["anatomesh_value"])))
        for fix in fixes:
            record(o, fix)
    return new, fixes


def _one_label_map(vol) -> None:
    """Fuse and Thicken change one label map (overlapping structures are meshed layer by layer)."""
    from ...core.model.errors import AnatomeshError
    from ...core.model.segmentation import as_layers

    if not vol.is_label_map or len(as_layers(vol)) > 1:
        raise AnatomeshError("Fuse and Thicken work on one label map; this scan is a scalar scan or has "
                             "overlapping structures", vol.meta.get("source"))


def _colour(obj):
    """The object's label colour, sRGB (its viewport colour is linear)."""
    from ...core.model.labels import linear_to_srgb

    return tuple(float(c) for c in linear_to_srgb(np.asarray(obj.color[:3], float)))


def _keep_material(obj, material) -> None:
    """Give a re-extracted object the material its label had (the new one is dropped)."""
    if material is None or not len(obj.data.materials) or obj.data.materials[0] == material:
        return
    made = obj.data.materials[0]
    obj.data.materials[0] = material
    if made.users == 0:
        bpy.data.materials.remove(made)


def _smoothing_keys() -> List[str]:
    from .properties import smoothing_properties

    return list(smoothing_properties())


def remove_scan(coll) -> None:
    """Delete a scan collection, its child collections and its objects (and their meshes)."""
    live.forget(coll.name)
    for o in list(coll.all_objects):
        me = o.data
        bpy.data.objects.remove(o)
        if me is not None and me.users == 0:
            bpy.data.meshes.remove(me)
    for c in list(coll.children_recursive):
        bpy.data.collections.remove(c)
    bpy.data.collections.remove(coll)
