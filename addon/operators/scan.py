"""A scan in Blender: fill the Labels panel from a volume, extract its surfaces with the same stage
functions as the command line, and add them to the scene (collection, objects, live-smoothing cache)."""
from __future__ import annotations

from typing import Dict, List, Optional, Sequence, Tuple

import bpy
import numpy as np

from . import smooth as live
from ..scene import materials, render_gap
from ..scene import objects as scene
from .common import parse_list
from . import iso_presets as presets


def fill_lists(settings, volume) -> None:
    """Put the volume's labels (present ones) or its isovalue presets into the scene settings."""
    settings.labels.clear()
    settings.levels.clear()
    settings.modality = str(volume.meta.get("modality", ""))
    shape = "x".join(str(s) for s in volume.shape)
    spacing = "x".join(f"{s:.3g}" for s in volume.spacing)
    settings.info = f"{shape} voxels, {spacing} mm, {volume.orientation()} ({volume.space})"
    if volume.is_label_map:
        from ...core.io.describe import label_facts
        from ...core.model.segmentation import as_layers

        settings.kind = "LABELS"
        for fact in (f for layer in as_layers(volume) for f in label_facts(layer)):
            if fact["voxels"] <= 0:
                continue
            item = settings.labels.add()
            item.name = fact["name"]
            item.value = int(fact["value"])
            info = (volume.labels or {}).get(int(fact["value"]))
            item.color = tuple(info.color if info is not None else (fact["color"] or (0.8, 0.8, 0.8)))[:3]
            item.voxels = int(fact["voxels"])
            item.volume_mm3 = float(fact["volume_mm3"])
            item.include = True
    else:
        settings.kind = "LEVELS"
        for name, value, color, include in presets.level_presets(volume):
            item = settings.levels.add()
            item.name, item.value, item.color, item.include = name, value, color, include


def chosen_labels(settings, volume, text: str) -> List[Tuple[int, str, Tuple[float, float, float]]]:
    """(value, name, colour) of the labels to extract.

    ``text``: "" → the included rows of the label list; "all" → every label present; else values
    and/or names separated by commas (names match case-insensitively).
    """
    from ...core.model.labels import select_labels

    rows = {item.value: item for item in settings.labels}
    table = volume.labels or {}
    from ...core.model.segmentation import as_layers

    if text.strip().lower() == "all" or (not text.strip() and not rows):
        present = set().union(*(np.unique(np.asarray(layer.data)).tolist() for layer in as_layers(volume)))
        values = sorted(int(v) for v in present if v != 0)
    elif text.strip():
        values = select_labels(as_layers(volume)[0] if len(as_layers(volume)) == 1 else _names_only(volume),
                               parse_list(text))
    else:
        values = [v for v, item in rows.items() if item.include]
    out = []
    for v in values:
        if v in rows:
            out.append((v, rows[v].name, tuple(rows[v].color)))
        elif v in table:
            out.append((v, table[v].name, tuple(table[v].color)))
        else:
            out.append((v, f"label_{v}", (0.8, 0.8, 0.8)))
    return out


def _names_only(volume):
    """A data-less label-map Volume holding every structure's name (to resolve a typed list)."""
    from ...core.model.volume import Volume

    first = volume.layers[0]
    return Volume(first.data[:0, :0, :0], first.affine, first.space, dict(volume.meta), volume.labels)


def chosen_levels(settings, text: str) -> List[Tuple[float, str, Tuple[float, float, float]]]:
    """(isovalue, name, colour): ``text`` "" → the included rows of the level list; else numbers."""
    if text.strip():
        out = []
        for t in parse_list(text):
            try:
                v = float(t)
            except ValueError:
                from ...core.model.errors import AnatomeshError

                raise AnatomeshError(f"isovalue {t!r} is not a number; give levels like '300, -500'")
            out.append((v, f"level {v:g}", (0.9, 0.85, 0.75)))
        return out
    return [(item.value, item.name, tuple(item.color)) for item in settings.levels if item.include]


def extraction_recipe(settings, volume, labels_text: str = "", levels_text: str = ""):
    """The Recipe of an extraction from the panel (the ticked rows, or ``labels_text`` /
    ``levels_text``) and the rows' names and colours {value: (name, colour)}; the scene's
    generated settings (the Settings panel) go with it."""
    from .recipe import scene_recipe

    recipe = scene_recipe(settings.id_data)
    recipe.input, recipe.space = str(volume.meta.get("source", "")), volume.space
    if volume.is_label_map:
        chosen = chosen_labels(settings, volume, labels_text)
        if not chosen:
            from ...core.model.errors import AnatomeshError

            raise AnatomeshError("no labels chosen; tick at least one label in the list",
                                 volume.meta.get("source"))
        recipe.labels = [v for v, _, _ in chosen]
    else:
        chosen = chosen_levels(settings, levels_text)
        if not chosen:
            from ...core.model.errors import AnatomeshError

            raise AnatomeshError("no isovalue chosen; tick or add a level", volume.meta.get("source"))
        recipe.levels = [float(v) for v, _, _ in chosen]
        recipe.level_names = [str(name) for _, name, _ in chosen]
    return recipe, {_key(v): (name, _edited_colour(volume, v, color)) for v, name, color in chosen}


def _edited_colour(volume, value, colour):
    """A row's colour when the user changed it, else None: the extraction's styled colour (style
    table, touching structures kept apart) applies, as on the command line."""
    info = (volume.labels or {}).get(value) if volume.is_label_map else None
    if info is not None and np.allclose(tuple(colour)[:3], tuple(info.color)[:3], atol=1e-3):
        return None
    return tuple(colour)


def object_props(volume, value, name) -> dict:
    return {
        "anatomesh_value": float(value) if not float(value).is_integer() else int(value),
        "anatomesh_name": str(name),
        "anatomesh_source": str(volume.meta.get("source", "")),
        "anatomesh_series_uid": str(volume.meta.get("series_uid", "") or ""),
        "anatomesh_space": volume.space,
        "anatomesh_affine": [float(x) for x in np.asarray(volume.affine).ravel()],
        "anatomesh_shape": [int(n) for n in volume.shape],
        "anatomesh_units": "mm",
    }


def frame_viewports(context, collection) -> None:
    """Make the scan visible in every 3D view: far clip plane, then View All (UI only)."""
    if bpy.app.background or context.window_manager is None:
        return
    box = scene.bounds(scene.surface_objects(collection))
    size = float((box[1] - box[0]).max()) if box is not None else 1000.0
    for window in context.window_manager.windows:
        for area in window.screen.areas:
            if area.type != "VIEW_3D":
                continue
            space = area.spaces.active
            space.clip_start = min(space.clip_start, 0.1)
            space.clip_end = max(space.clip_end, 20.0 * size)
            region = next((r for r in area.regions if r.type == "WINDOW"), None)
            if region is not None:
                try:
                    with context.temp_override(window=window, area=area, region=region):
                        bpy.ops.view3d.view_all(center=False)
                except RuntimeError:
                    pass


def extract_to_scene(context, volume, recipe, *, looks: Optional[Dict] = None,
                     render_method: str = "DITHERED", progress=None) -> bpy.types.Collection:
    """Extract the surfaces ``recipe`` asks for (labels or levels) with the command line's stage
    functions (:func:`anatomesh.app.flow.stages.layers_of`, :func:`~anatomesh.app.flow.stages.extract`) and
    add them as objects in a new collection; ``looks`` {value: (name, colour or None)} overrides the
    names and colours (the Labels panel's rows; None: the extraction's styled colour). Not smoothed yet (:func:`live.smooth_collection`)."""
    from ...app.flow import stages
    from ...app.warmup.compile import announce_compiling

    def first_run(note: str) -> None:  # only when a kernel really compiles here
        print(f"Anatomesh: {note}")
        if progress is not None:
            progress(0.0, note)

    with announce_compiling(note="first run: compiling kernels once (numba), later runs are fast",
                            say=first_run):
        layers = [stages.drop_specks(stages.extract(layer, lrecipe, progress))
                  for layer, lrecipe in stages.layers_of(volume, recipe)]
    items = [(m, k) for k, sset in enumerate(layers) for m in stages.output_shells(sset)[0] if m.n_faces]
    warnings = [w for sset in layers for w in sset.warnings]
    if not volume.is_label_map:
        made = {float(m.value) for m, _ in items}
        warnings += [f"isovalue {lv:g} gives no surface: it is outside the data range"
                     for lv in recipe.levels if float(lv) not in made]
    coll = scan_to_scene(context, volume, items, layers, warnings, render_method, looks)
    group_layers(coll, volume)
    return coll


def scan_to_scene(context, volume, items: Sequence, layers: Sequence, warnings: Sequence[str] = (),
                  render_method: str = "DITHERED", looks: Optional[Dict] = None) -> bpy.types.Collection:
    """Add extracted surfaces to the scene: a new collection named after the scan, one object
    per item (its tissue class's material, its cut faces marked, a drawn gap at shared
    interfaces: :mod:`..scene.render_gap`), and the live-smoothing cache.

    ``items``: ``(shell Mesh, layer index)`` with ``meta["vertex_ids"]`` into ``layers[k]`` (the
    unsmoothed SurfaceSets the live smoothing starts from). Used by :func:`extract_to_scene` and
    by the headless pipeline (``addon/headless.py``).
    """
    from ...core.geometry.pinches import shell_label
    from ...core.model.errors import AnatomeshError

    if not items:
        raise AnatomeshError("nothing to show: the chosen labels/levels give no surface",
                             volume.meta.get("source"))
    coll = _scan_collection(context, volume, warnings, render_method)
    members = []
    for m, k in items:
        name, color = (looks or {}).get(_key(m.value), (m.name, None))
        color = tuple(m.color)[:3] if color is None else color
        ids = shared_index(m)
        props = object_props(volume, m.value, name)
        if len(tuple(m.color)) > 3:  # the style's opacity (fuzzy shells: their level's) in RGBA
            props["anatomesh_alpha"] = float(m.color[3])
            props["anatomesh_oriented"] = 1.0 if m.color[3] < 1.0 else 0.0
        obj = scene.add_surface(coll, name, m.vertices, m.faces, props,
                                color, render_method, shared_index=ids, vertex_colors=m.vertex_colors,
                                rest=layers[k].vertices[ids],
                                tissue=materials.tissue_for(name, m.meta.get("material")))
        scene.mark_cut_faces(obj)
        render_gap.add_render_gap([obj], render_gap.gap_mm(volume.spacing))
        obj[live.LAYER_PROPERTY] = k + 1
        live.store([(obj, ids)], k, layers[k])
        members.append((obj.name, k, ids, shell_label(layers[k], m)))
    live.remember(coll, live.LiveScan(list(layers), members))
    context.scene.anatomesh.last_collection = coll.name
    return coll


def _scan_collection(context, volume, warnings, render_method) -> bpy.types.Collection:
    """A new scan collection in mm, named after the scan, with its source, space and warnings."""
    scene.setup_units(context.scene)
    src = volume.meta.get("source", "") or "scan"
    coll = scene.new_collection(scene.scan_name(src))
    coll.anatomesh.is_scan = True
    coll.anatomesh.source = str(src)
    coll.anatomesh.space = volume.space
    coll.anatomesh.render_method = render_method
    coll["anatomesh_space"] = volume.space
    coll["anatomesh_units"] = "mm"
    coll["anatomesh_warnings"] = list(warnings)
    return coll


def _key(value):
    """Label values and isovalues as dictionary keys alike (5 and 5.0 are one key)."""
    v = float(value)
    return int(v) if v.is_integer() else v


def group_layers(coll, volume) -> None:
    """Overlapping structures (a Segmentation's layers): one child collection per layer,
    "<scan> layer N", each object's ``anatomesh_layer`` set; a single layer stays as it is."""
    from ...core.model.segmentation import Segmentation

    if not isinstance(volume, Segmentation):
        return
    layer_of = volume.layer_of()
    children = {}
    for obj in list(coll.objects):
        value = obj.get("anatomesh_value")
        if value is None or int(value) not in layer_of:
            continue
        li = layer_of[int(value)]
        obj["anatomesh_layer"] = li + 1
        if li not in children:
            children[li] = bpy.data.collections.new(f"{coll.name} layer {li + 1}")
            coll.children.link(children[li])
        children[li].objects.link(obj)
        coll.objects.unlink(obj)


def shared_index(mesh) -> np.ndarray:
    """Index of each shell vertex in its surface set's vertex array (``Mesh.meta["vertex_ids"]``)."""
    idx = mesh.meta.get("vertex_ids")
    if idx is None or len(idx) != mesh.n_vertices:
        raise RuntimeError(f"shell {mesh.name!r} lacks meta['vertex_ids'] (core SurfaceSet changed?)")
    return np.asarray(idx, np.int64)
